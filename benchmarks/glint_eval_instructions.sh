#!/usr/bin/env bash
# Instructions per glint eval (issue 10), counted by callgrind in the driver
# benchmarks/glint_eval_instructions.cpp (only its eval_loop: 2 x 4096 evals
# per row), with the ratio to the GGX conductor of the same roughness and the
# driver's hash of every f and pdf bit (equal hashes: same values).
# usage: benchmarks/glint_eval_instructions.sh [build dir] [plugin .so] [rows...]
#   build dir default ./build; plugin default the build's glimmer_closures.
# Env GLIMMER_CACHE_DIR: where lazily-built tables are cached (default /tmp/glint_eval_instructions_cache).
set -euo pipefail
build=${1:-build}
plugin=${2:-}
shift $(( $# > 2 ? 2 : $# )) || true
rows=("$@")
if [ ${#rows[@]} -eq 0 ]; then
  rows=(ggx04 r04_a-8 r04_a-6 r04_a-4 r04_asp4 r04_asp16 r04_asp64 ggx02 r02_a-8 r02_a-6 r02_a-4 r02_asp4 r02_asp16
        r02_asp64)
fi
driver="$build/glint_eval_instructions"
[ -x "$driver" ] || { echo "no $driver (cmake --build $build --target glint_eval_instructions)" >&2; exit 1; }
export GLIMMER_CACHE_DIR=${GLIMMER_CACHE_DIR:-/tmp/glint_eval_instructions_cache}
mkdir -p "$GLIMMER_CACHE_DIR"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
printf '%-10s %8s %12s %8s  %s\n' row evals instr/eval x_ggx hash
ggx04="" ; ggx02=""
for row in "${rows[@]}"; do
  out="$tmp/$row.out"
  # shellcheck disable=SC2086
  valgrind --tool=callgrind --collect-atstart=no --toggle-collect='*eval_loop*' \
    --callgrind-out-file="$tmp/cg.$row" "$driver" "$row" $plugin > "$out" 2> "$tmp/$row.err" || {
      cat "$tmp/$row.err" >&2; exit 1; }
  evals=$(awk '{print $4}' "$out")
  hash=$(awk '{print $6}' "$out")
  total=$(grep -m1 '^summary:' "$tmp/cg.$row" | awk '{print $2}')
  per=$(awk -v t="$total" -v n="$evals" 'BEGIN{printf "%.1f", t/n}')
  case $row in
    ggx04) ggx04=$per ;;
    ggx02) ggx02=$per ;;
  esac
  base=""
  case $row in
    r04_*) base=$ggx04 ;;
    r02_*) base=$ggx02 ;;
  esac
  ratio="-"
  [ -n "$base" ] && ratio=$(awk -v a="$per" -v b="$base" 'BEGIN{printf "%.2f", a/b}')
  printf '%-10s %8s %12s %8s  %s\n' "$row" "$evals" "$per" "$ratio" "$hash"
done
