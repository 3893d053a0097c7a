#!/usr/bin/env bash
# `make fuzz`: runs every libFuzzer target of the fuzz build for RUNS
# executions or at most SECONDS, whichever comes first, and prints, per
# target, the executions, crashes, hangs (> 5 s) and sanitizer reports.
# Usage: tools/run_fuzz.sh BUILD_DIR [SECONDS_PER_TARGET [RUNS_PER_TARGET]]
# Exit status 1 when any target crashed, hung or reported.
set -uo pipefail
build=${1:?build folder}
seconds=${2:-600}
runs=${3:-1000000}
source_dir=$(cd "$(dirname "$0")/.." && pwd)
work="$build/fuzz-runs"
mkdir -p "$work"

# Seed corpora: the scenes of examples/, tests and the Cycles example corpus; hand-made meshes and parameters.
seed_dir() {
  local target=$1 dir="$work/seeds-$1"
  rm -rf "$dir"; mkdir -p "$dir"
  case $target in
    fuzz_xml_loader)
      cp "$source_dir"/examples/*.xml "$source_dir"/tests/bridge/data/*.xml "$dir"/ 2>/dev/null
      for f in "$source_dir"/../shared/corpus/cycles-examples/*.xml "$source_dir"/../../shared/corpus/cycles-examples/*.xml; do
        [[ -f $f ]] && cp "$f" "$dir"/
      done ;;
    fuzz_obj_reader) cp "$source_dir"/fuzz/seeds/obj/* "$dir"/ ;;
    fuzz_ply_reader) cp "$source_dir"/fuzz/seeds/ply/* "$dir"/ ;;
    fuzz_closure_params) cp "$source_dir"/fuzz/seeds/params/* "$dir"/ ;;
  esac
  echo "$dir"
}

status=0
printf '%-22s %12s %10s %8s %8s %10s\n' target executions exec/s crashes hangs sanitizer
for target in fuzz_xml_loader fuzz_obj_reader fuzz_ply_reader fuzz_closure_params; do
  exe="$build/$target"
  [[ -x $exe ]] || { echo "missing $exe (build the fuzz targets first)"; exit 1; }
  corpus="$work/corpus-$target"; artifacts="$work/artifacts-$target"
  mkdir -p "$corpus" "$artifacts"
  seeds=$(seed_dir "$target")
  log="$work/$target.log"
  # -timeout=5: an input running > 5 s is a hang (reported as a timeout artifact).
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    "$exe" "$corpus" "$seeds" -runs="$runs" -max_total_time="$seconds" -timeout=5 -rss_limit_mb=2048 -max_len=65536 \
    -print_final_stats=1 -artifact_prefix="$artifacts/" > "$log" 2>&1
  executions=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
  rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
  crashes=$(find "$artifacts" -name 'crash-*' -o -name 'oom-*' -o -name 'leak-*' | wc -l)
  hangs=$(find "$artifacts" -name 'timeout-*' | wc -l)
  reports=$(grep -c -E '^==[0-9]+==ERROR|runtime error:' "$log")
  printf '%-22s %12s %10s %8s %8s %10s\n' "$target" "${executions:-0}" "${rate:-0}" "$crashes" "$hangs" "$reports"
  if [[ $crashes -ne 0 || $hangs -ne 0 || $reports -ne 0 || -z ${executions:-} ]]; then
    status=1
    echo "  see $log and $artifacts"
  fi
done
exit $status
