#!/bin/bash
# The caustic bench's ladders (docs/history/frosted_glass_sessions.md "Seventeenth session" and "Eighteenth /
# nineteenth session"):
# path, sg, auto at 512..8192 spp on benchmarks/scenes/frosted_fair_caustic.xml (64x40, one thread, --strategy mis,
# CPU clock) against two 65536-spp path references, per region of the shadow-zone mask, then the fit at 60 s.
#   benchmarks/frosted_caustic_bench.sh <glimmer> <out dir> <name> <ref_7919.exr> <ref_8932.exr> [spp list]
# The references:
#   glimmer render benchmarks/scenes/frosted_fair_caustic.xml -o ref_7919.exr --samples 65536 --seed 7919 \
#       --strategy mis --width 64 --height 40 --threads 1        (and --seed 8932)
# The environment passes through (e.g. GLIMMER_FROSTED_CURVED_TAIL=0: the sphere's unsplit single SG, the
# nineteenth session's "before" with the same build).
# SEEDS="11 12 13 14" (consecutive seeds; session 31) renders every rung on those seeds (bench --seed 11 --seeds 4):
# each rung's MSE is the mean of the 4 images', and the log / regions CSV split it into noise and bias^2, which the
# fit then also reads directly ("direct:"). Default: one image per rung on the scene's seed, as before.
set -e
G=$1; OUT=$2; NAME=$3; R1=$4; R2=$5; SPP=${6:-512,1024,2048,4096,8192}
HERE=$(cd "$(dirname "$0")" && pwd)
SEED_ARGS=()
if [ -n "${SEEDS:-}" ]; then
  read -r -a S <<< "$SEEDS"
  for k in "${!S[@]}"; do
    [ "${S[$k]}" -eq $((S[0] + k)) ] || { echo "SEEDS must be consecutive (got '$SEEDS')" >&2; exit 1; }
  done
  SEED_ARGS=(--seed "${S[0]}" --seeds "${#S[@]}")
fi
mkdir -p "$OUT"
"$G" bench error-vs-time "$HERE/scenes/frosted_fair_caustic.xml" --material frosted --path-strategy mis \
    --methods path,sg,auto --samples "$SPP" --reference-images "$R1,$R2" "${SEED_ARGS[@]}" \
    --regions "$HERE/scenes/frosted_fair_caustic_mask_64x40.png" --width 64 --height 40 --threads 1 \
    --clock cpu --at-seconds 60 --out-dir "$OUT" --name "$NAME" 2>&1 | grep -v "^Sample " | tee "$OUT/$NAME.log"
python3 "$HERE/frosted_error_vs_time_fit.py" "$OUT/${NAME}_regions.csv" --at-seconds 60 | tee -a "$OUT/$NAME.log"
