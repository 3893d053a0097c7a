#!/bin/bash
# The caustic bench's pane crop (--region 34,9,46,16: glass_R, the camera-seen rough pane, method=sg) with the pane at
# a chosen IOR, rendered with two plugin builds interleaved per seed (one glimmer host, GLIMMER_PLUGIN_PATH), then each
# plugin's variance per sample per region (frosted_variance_per_region.py variance) and its mean against plugin A's
# images (docs/history/frosted_glass_sessions.md "Session 37 (frostedwalk37)"; frosted_pane_crop.sh does the same for a
# knob's levels).
#   benchmarks/frosted_pane_crop_plugins.sh <glimmer> <out> <spp> "<seeds>" <pane ior> <plugin A.so> <plugin B.so>
#   e.g. ... build/glimmer /tmp/crop24 4096 "11 12 13 14" 2.4 /work/notes/s37/2397f6c_plugin.so \
#        build/libglimmer_closures.so
# 64x40, --strategy mis, one thread; set GLIMMER_CACHE_DIR to a warm table cache first. The scene copy is written
# once to <out>/caustic_sg.xml (md5s depend on the copy's absolute paths: compare within one <out>).
set -euo pipefail
G=$1 OUT=$2 SPP=$3 SEEDS=$4 IOR=$5 PA=$6 PB=$7
HERE=$(cd "$(dirname "$0")" && pwd)
MASK="$HERE/scenes/frosted_fair_caustic_mask_64x40.png"
mkdir -p "$OUT"
sed -e "s|frosted_glass_bsdf name=\"g\"|frosted_glass_bsdf name=\"g\" method=\"sg\"|" \
    -e "s|../../examples/sphere.obj|$HERE/../examples/sphere.obj|" \
    -e "s|roughness=\"0.5\" ior=\"1.5\" thin=\"1\"|roughness=\"0.5\" ior=\"$IOR\" thin=\"1\"|" \
    "$HERE/scenes/frosted_fair_caustic.xml" > "$OUT/caustic_sg.xml"
echo "panes at ior $IOR: $(grep -c "ior=\"$IOR\" thin=\"1\"" "$OUT/caustic_sg.xml")"
for s in $SEEDS; do
  for p in A B; do
    so=$PA
    [ "$p" = B ] && so=$PB
    GLIMMER_PLUGIN_PATH=$so "$G" render "$OUT/caustic_sg.xml" -o "$OUT/$p.$s.exr" --region 34,9,46,16 \
        --samples "$SPP" --seed "$s" --strategy mis --width 64 --height 40 --threads 1 --quiet
  done
done
refs=$(for s in $SEEDS; do printf '%s,' "$OUT/A.$s.exr"; done)
for p in A B; do
  echo "== plugin $p (md5 $(for s in $SEEDS; do md5sum "$OUT/$p.$s.exr" | cut -c1-8; done | tr '\n' ' '))"
  imgs=$(for s in $SEEDS; do printf '%s ' "$OUT/$p.$s.exr"; done)
  # shellcheck disable=SC2086
  python3 "$HERE/frosted_variance_per_region.py" variance "$SPP" $imgs --mask "$MASK" --split-x 32 \
      --references "${refs%,}" | grep -E "region|glass_R"
done
