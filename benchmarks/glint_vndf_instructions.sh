#!/usr/bin/env bash
# Instructions per Beckmann visible-normal sample (issue 10): callgrind of
# benchmarks/glint_vndf_instructions.cpp's two loops (the shared libm sampler
# and glint's library-free one, same 20000 inputs), each counted inclusively.
# usage: benchmarks/glint_vndf_instructions.sh [build dir]
set -euo pipefail
build=${1:-build}
driver="$build/glint_vndf_instructions"
[ -x "$driver" ] || { echo "no $driver (cmake --build $build --target glint_vndf_instructions)" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$driver" | tee "$tmp/out"
n=$(awk '{print $2}' "$tmp/out")
for loop in shared_loop glint_loop; do
  valgrind --tool=callgrind --collect-atstart=no --toggle-collect="*${loop}*" \
    --callgrind-out-file="$tmp/cg.$loop" "$driver" > /dev/null 2> "$tmp/$loop.err"
  total=$(grep -m1 '^summary:' "$tmp/cg.$loop" | awk '{print $2}')
  awk -v l="$loop" -v t="$total" -v n="$n" 'BEGIN{printf "%-12s %10.1f instructions per sample\n", l, t / n}'
done
