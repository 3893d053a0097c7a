#!/usr/bin/env bash
# The f/pdf hash of every glint row of benchmarks/glint_eval_instructions.cpp, run natively (no callgrind:
# seconds, not minutes), with the AVX2 walk and with GLIMMER_GLINT_WALK=sse2 (issue 10, session 22). Two
# plugins that keep the particles print the same lines.
# usage: benchmarks/glint_eval_hashes.sh [build dir] [plugin .so]   (env GLIMMER_CACHE_DIR as for the driver)
set -euo pipefail
build=${1:-build}
plugin=${2:-}
driver="$build/glint_eval_instructions"
[ -x "$driver" ] || { echo "no $driver (cmake --build $build --target glint_eval_instructions)" >&2; exit 1; }
export GLIMMER_CACHE_DIR=${GLIMMER_CACHE_DIR:-/tmp/glint_eval_instructions_cache}
mkdir -p "$GLIMMER_CACHE_DIR"
printf '%-10s %-16s %-16s\n' row avx2 sse2
for row in r04_a-8 r04_a-6 r04_a-4 r04_asp4 r04_asp16 r04_asp64 r02_a-8 r02_a-6 r02_a-4 r02_asp4 r02_asp16 r02_asp64; do
  # shellcheck disable=SC2086
  a=$("$driver" "$row" $plugin | awk '{print $6}')
  # shellcheck disable=SC2086
  b=$(GLIMMER_GLINT_WALK=sse2 "$driver" "$row" $plugin | awk '{print $6}')
  printf '%-10s %-16s %-16s\n' "$row" "$a" "$b"
done
