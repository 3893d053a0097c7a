#!/bin/bash
# The cost of method=sg / auto / path per camera path on the caustic bench's scene
# (docs/history/frosted_glass_sessions.md "Twentieth session"):
# benchmarks/scenes/frosted_fair_caustic.xml with every frosted_glass_bsdf's method set, its mesh path made
# absolute, rendered under callgrind (64x40, 64 spp, seed 11, mis, one thread: 163840 camera paths), then
# Renderer::Impl::trace_path inclusive / 163840 and the sg functions' table (tools/callgrind_fn_costs.py).
#   benchmarks/frosted_sg_cost.sh <glimmer> <out dir> [methods, default sg]   e.g. ... build/glimmer /tmp/cost sg,auto,path
# Also writes each method's EXR outside callgrind (<out>/<method>.exr; md5 printed) for bit-identity checks. Use a -g
# build (-DCMAKE_CXX_FLAGS=-g) for line-level annotation; set GLIMMER_CACHE_DIR to a warm table cache first.
set -e
G=$1; OUT=$2; METHODS=${3:-sg}
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/.." && pwd)
mkdir -p "$OUT"
for m in ${METHODS//,/ }; do
  sed -e "/<frosted_glass_bsdf /s#ior=\"\\([^\"]*\\)\"#ior=\"\\1\" method=\"$m\"#" \
      -e "s#\\.\\./\\.\\./examples/#$ROOT/examples/#g" "$HERE/scenes/frosted_fair_caustic.xml" > "$OUT/caustic_$m.xml"
  ARGS=(render "$OUT/caustic_$m.xml" --samples 64 --seed 11 --strategy mis --width 64 --height 40 --threads 1 --quiet)
  "$G" "${ARGS[@]}" -o "$OUT/$m.exr"
  md5sum "$OUT/$m.exr"
  nice -n 5 valgrind --tool=callgrind --dump-instr=yes --callgrind-out-file="$OUT/cg_$m.out" "$G" "${ARGS[@]}" \
      -o "$OUT/cg_$m.exr" > "$OUT/cg_$m.log" 2>&1
  echo "== $m (per camera path: Ir / 163840)"
  python3 "$ROOT/tools/callgrind_fn_costs.py" "$OUT/cg_$m.out" --per 163840 --top 14 \
      --match 'Impl::trace_path|integrate_exit_lobe|lamp_through_lobe<|FrostedGlassClosure::sample|trace_exit_lobe|trace_interior|table_lobe|SgTable::lookup|sample_pane_sg_split|^exp@|__sincos_fma$|^log@' \
      | cut -c1-170
done
