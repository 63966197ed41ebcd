#!/bin/sh
# Install the peer tools of `lopcook bench` (pinned) into $LOPCOOK_PEERS (default <repo>/.peers),
# where lopcook/bench/peers.py looks for them first; DracoPy and matplotlib come with the
# `bench` extra. Usage: sh benchmarks/install_peers.sh
set -eu
repo=$(cd "$(dirname "$0")/.." && pwd)
dest=${LOPCOOK_PEERS:-$repo/.peers}
mkdir -p "$dest"
printf '*\n' > "$dest/.gitignore"   # keep node_modules out of git
npm install --prefix "$dest" gltfpack@1.3.0 @gltf-transform/cli@4.5.1
"$repo/.venv/bin/pip" install -e "$repo[bench]" 2>/dev/null || pip install -e "$repo[bench]"
echo "peers installed in $dest/node_modules/.bin"
