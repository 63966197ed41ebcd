#!/usr/bin/env bash
# sha256 of the containers `lopcook cook` writes for every corpus asset and fixture: the default
# cook, --lods auto and --nearest 0.5, and --target-bytes 1/6 on the bunny. Run it on two checkouts and diff the lists to show a change keeps the bytes.
#   usage: benchmarks/cook_hashes.sh OUTDIR   (from the repository root; LOPCOOK_CORPUS or ../shared/corpus)
set -u
OUT=${1:?usage: cook_hashes.sh OUTDIR}
mkdir -p "$OUT"
C=${LOPCOOK_CORPUS:-../shared/corpus}
PY=${PYTHON:-python3}
assets="$C/CesiumMilkTruck.glb $C/DamagedHelmet/DamagedHelmet.gltf $C/Duck.glb $C/UtahTeapot.usd
        $C/chess_set_flat.usdc $C/fandisk.obj $C/spot.obj $C/stanford-bunny.obj"
fixtures=$(ls fixtures/*.glb fixtures/*.gltf fixtures/*.obj fixtures/*.usda fixtures/*.usdc 2>/dev/null)
cook() { "$PY" -m lopcook cook "$1" -o "$OUT/$2" -q "${@:3}" || echo "FAIL $2" >> "$OUT/errors.txt"; }
for a in $assets $fixtures; do
  b=$(basename "$a")
  cook "$a" "$b.default.lop"
  cook "$a" "$b.nearest.lop" --nearest 0.5
  cook "$a" "$b.lods.lop" --lods auto
done
cook "$C/stanford-bunny.obj" bunny.budget.lop --target-bytes 1/6
(cd "$OUT" && sha256sum -- *.lop > sha256.txt)
echo "$OUT/sha256.txt"
