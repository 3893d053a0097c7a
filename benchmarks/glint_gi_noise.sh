#!/usr/bin/env bash
# Mean and RMSE of the GI scene's render (examples/glint.xml, Combined RGB)
# against a high-spp reference, for the sampler changes that move samples
# (issue 10): a change must not raise the RMSE beyond what two seeds show.
# usage: benchmarks/glint_gi_noise.sh glimmer plugin.so reference.exr out_dir [width height spp seeds...]
#   defaults 160 100 4, seeds 1 2. Prints per seed: mean R G B, RMSE (all three channels) vs the reference.
# The reference: the same script's render command with e.g. --samples 1024 --seed 99.
set -euo pipefail
glimmer=$1 plugin=$2 ref=$3 out=$4
width=${5:-160} height=${6:-100} spp=${7:-4}
shift $(( $# > 7 ? 7 : $# ))
seeds=("$@")
[ ${#seeds[@]} -eq 0 ] && seeds=(1 2)
src=$(cd "$(dirname "$0")/.." && pwd)/examples/glint.xml
mkdir -p "$out"
rgb() { oiiotool "$1" --ch ViewLayer.Combined.R,ViewLayer.Combined.G,ViewLayer.Combined.B -o "$2"; }
rgb "$ref" "$out/ref_rgb.exr"
for s in "${seeds[@]}"; do
  img="$out/s${s}_n${spp}.exr"
  "$glimmer" --plugin "$plugin" render "$src" -o "$img" --samples "$spp" --seed "$s" --threads 1 \
    --width "$width" --height "$height" --quiet
  rgb "$img" "$out/s${s}_rgb.exr"
  mean=$(oiiotool "$out/s${s}_rgb.exr" --printstats 2>&1 | awk -F: '/Stats Avg/{print $2; exit}' | sed 's/ (float)//')
  # --diff exits non-zero when the images differ (they do): its status is not an error here.
  rmse=$( (oiiotool "$out/s${s}_rgb.exr" "$out/ref_rgb.exr" --diff 2>&1 || true) | awk -F= '/RMS error/{print $2}')
  printf 'seed %s %s spp: mean %s  RMSE vs reference %s  md5 %s\n' "$s" "$spp" "$mean" "$rmse" \
    "$(md5sum < "$img" | cut -c1-12)"
done
