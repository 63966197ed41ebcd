#!/usr/bin/env bash
# libFuzzer on runtime/c/lop.h for SECONDS (default 600), seeded with fixtures/conformance.
# The target (runtime/c/fuzz/fuzz_lop.c) opens each input whole and as a prefix and uses every
# query and decode on what opens, under AddressSanitizer and UndefinedBehaviorSanitizer;
# checksums are not compared in this build, so mutations reach the parser and the validator.
# Prints libFuzzer's final statistics; exit status 0 when nothing was found. Needs clang and
# libclang-rt-14-dev (.ci/run installs them).
#
#   benchmarks/fuzz_c_reader.sh [SECONDS] [WORKDIR]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-600}"
mkdir -p "${2:-bench-out/fuzz_c_reader}/corpus"
work="$(cd "${2:-bench-out/fuzz_c_reader}" && pwd)"
make -s -C runtime/c BUILD="$work/build" fuzz
status=0
nice "$work/build/fuzz/fuzz_lop" -max_total_time="$seconds" -print_final_stats=1 -artifact_prefix="$work/" \
  "$work/corpus" fixtures/conformance > "$work/fuzz.log" 2>&1 || status=$?
grep -E "^(stat::|Done)|ERROR|SUMMARY" "$work/fuzz.log" || true
if [ "$status" -ne 0 ] || ls "$work"/crash-* "$work"/leak-* "$work"/timeout-* >/dev/null 2>&1; then
  echo "fuzz_c_reader: libFuzzer exited $status; findings in $work" >&2
  exit 1
fi
echo "fuzz_c_reader: ${seconds} s, no crash, leak or timeout ($work/fuzz.log)"
