#!/bin/bash
# The caustic bench's pane crop (--region 34,9,46,16: glass_R, the camera-seen rough pane) for method=sg, several
# levels of one measurement knob rendered interleaved per seed with one glimmer build, then each level's variance per
# sample per region (frosted_variance_per_region.py variance) and its mean against the first level's images (docs/
# frosted_glass.md "Session 33 (frostedface33)"; session 30 rendered the same crop by hand).
#   benchmarks/frosted_pane_crop.sh <glimmer> <out> <spp> "<seeds>" <KNOB> "<levels>"
#   e.g. ... build/glimmer /tmp/crop 8192 "11 12 13 14" GLIMMER_FROSTED_PANE_BOTH_FACES "0 1 2"
# 64x40, --strategy mis, one thread; set GLIMMER_CACHE_DIR to a warm table cache first.
set -euo pipefail
G=$1 OUT=$2 SPP=$3 SEEDS=$4 KNOB=$5 LEVELS=$6
HERE=$(cd "$(dirname "$0")" && pwd)
MASK="$HERE/scenes/frosted_fair_caustic_mask_64x40.png"
mkdir -p "$OUT"
sed -e "s|frosted_glass_bsdf name=\"g\"|frosted_glass_bsdf name=\"g\" method=\"sg\"|" \
    -e "s|../../examples/sphere.obj|$HERE/../examples/sphere.obj|" "$HERE/scenes/frosted_fair_caustic.xml" \
    > "$OUT/caustic_sg.xml"
for s in $SEEDS; do
  for l in $LEVELS; do
    env "$KNOB=$l" "$G" render "$OUT/caustic_sg.xml" -o "$OUT/l${l}_$s.exr" --region 34,9,46,16 --samples "$SPP" \
        --seed "$s" --strategy mis --width 64 --height 40 --threads 1 --quiet
  done
done
first=${LEVELS%% *}
refs=$(for s in $SEEDS; do printf '%s,' "$OUT/l${first}_$s.exr"; done)
for l in $LEVELS; do
  echo "== $KNOB=$l (md5 $(for s in $SEEDS; do md5sum "$OUT/l${l}_$s.exr" | cut -c1-8; done | tr '\n' ' '))"
  imgs=$(for s in $SEEDS; do printf '%s ' "$OUT/l${l}_$s.exr"; done)
  # shellcheck disable=SC2086
  python3 "$HERE/frosted_variance_per_region.py" variance "$SPP" $imgs --mask "$MASK" --split-x 32 \
      --references "${refs%,}" | grep -E "region|glass_R"
done
