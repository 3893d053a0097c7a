#!/bin/bash
# The caustic bench's bias per region for method=sg (issue 12, session 22, frostedexit22;
# docs/history/frosted_glass_sessions.md "Eighteenth / nineteenth session" for the commands it wraps):
# frosted_fair_caustic.xml with every frosted shader method="sg", two seeds (11, 12) x <spp> (default 1024), 64x40,
# --strategy mis, one thread, then frosted_variance_per_region.py against the two 65536-spp path references (--split-x
# 32: the sphere's side x < 32, the pane's x >= 32). The environment passes through (GLIMMER_FROSTED_CURVED_TAIL /
# _SHAPE for a before / after with one build).
#   benchmarks/frosted_caustic_bias.sh build/glimmer /tmp/out label ref_7919.exr ref_8932.exr [spp] [method]
# (method: sg by default; auto renders every frosted shader with method="auto")
# SEEDS="11 12 13 14" renders more seeds (default "11 12"). Session 23: at 1024 spp two seeds do not resolve the
# shadow's bias (heavy-tailed noise): seeds 11/12 0.0031, 13/14 0.0084, all four 0.0070, 2 x 8192 spp 0.0092.
set -euo pipefail
glimmer=$1 out=$2 label=$3 ref_a=$4 ref_b=$5 spp=${6:-1024} method=${7:-sg}
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$out"
scene="$out/caustic_$method.xml"
sed -e "s|frosted_glass_bsdf name=\"g\"|frosted_glass_bsdf name=\"g\" method=\"$method\"|" \
    -e "s|../../examples/sphere.obj|$here/../examples/sphere.obj|" "$here/scenes/frosted_fair_caustic.xml" > "$scene"
seeds=${SEEDS:-11 12}
images=()
for seed in $seeds; do
  images+=("$out/${label}_$seed.exr")
  "$glimmer" render "$scene" -o "$out/${label}_$seed.exr" --samples "$spp" --seed "$seed" --strategy mis \
      --width 64 --height 40 --threads 1 > "$out/${label}_$seed.log" 2>&1
done
md5sum "${images[@]}"
python3 "$here/frosted_variance_per_region.py" variance "$spp" "${images[@]}" \
    --mask "$here/scenes/frosted_fair_caustic_mask_64x40.png" --references "$ref_a,$ref_b" --split-x 32
