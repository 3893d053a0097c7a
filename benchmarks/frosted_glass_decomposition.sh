#!/bin/bash
# The caustic bench's sphere glass (glass_L: the camera-seen sphere, pixels x 19..30, y 9..20 of the 64x40 image)
# decomposed by light source and by the floor bounce (issue 12, session 23, frostedglass23;
# docs/history/frosted_glass_sessions.md "Session 23 (frostedglass23)"). Light transport is linear in the emitters and
# in the floor's albedo's contribution, so four scene variants split each method's image exactly:
#   full       the scene
#   black      the floor's colour 0: only what the camera sees on / through the sphere directly (front reflection,
#              the lamp and the world through the exit lobe, light after internal reflections)
#   black_lamp the floor black and the world 0: the lamp seen on / through the sphere
#   lamp       the world 0: everything the lamp lights
#   world, black_world  the lamp off (and the floor black): the uniform world alone, which tests a class's energy
#              whatever its directions
# A variant <v>:<c> renders <v> with GLIMMER_DIAG_CLASS=<c>: only the camera paths whose events on the sphere are of
# class c (100 the front reflection, 0 light that left after no internal reflection, 1 after one or more); it needs
# a diagnostic build with benchmarks/frosted_glass_event_split.patch applied (never committed in the code).
# GLIMMER_DIAG_SKIP=1 (exported) classifies from the path's second vertex (the camera sees the floor: the light that
# reached the floor's point through / off the sphere; the first vertex's own contributions are dropped).
# Each variant is rendered on the crop (--region 19,9,31,21) by path (2 seeds x <path_spp>, the reference) and by
# the method (2 seeds x <spp>), then frosted_variance_per_region.py compares them (per region with the references'
# own noise taken out).
#   benchmarks/frosted_glass_decomposition.sh build/glimmer /tmp/out label [spp] [path_spp] [method] [variants]
# The environment passes through (GLIMMER_FROSTED_CURVED_* for a before / after with one build). Path references
# are reused when present (delete $out/ref_* to redo them).
set -euo pipefail
glimmer=$1 out=$2 label=$3 spp=${4:-16384} path_spp=${5:-65536} method=${6:-sg}
variants=${7:-full black black_lamp lamp}
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$out"
region=${REGION:-19,9,31,21}  # REGION=14,17,29,28: the sphere's shadow (shadow_L), with SKIP=1 below
show=${SHOW:-glass_L}
scene_for() {  # variant method -> scene file
  local v=$1 m=$2 f="$out/scene_${1}_$2.xml"
  local e=(-e "s|frosted_glass_bsdf name=\"g\"|frosted_glass_bsdf name=\"g\" method=\"$m\"|"
           -e "s|../../examples/sphere.obj|$here/../examples/sphere.obj|")
  case $v in
    full) ;;
    black) e+=(-e 's|diffuse_bsdf name="d" color="0.6 0.6 0.6"|diffuse_bsdf name="d" color="0 0 0"|') ;;
    black_lamp) e+=(-e 's|diffuse_bsdf name="d" color="0.6 0.6 0.6"|diffuse_bsdf name="d" color="0 0 0"|'
                    -e 's|color="0.05 0.05 0.06" strength="1"|color="0.05 0.05 0.06" strength="0"|') ;;
    lamp) e+=(-e 's|color="0.05 0.05 0.06" strength="1"|color="0.05 0.05 0.06" strength="0"|') ;;
    world) e+=(-e 's|strength="120 100 80"|strength="0 0 0"|') ;;
    black_world) e+=(-e 's|diffuse_bsdf name="d" color="0.6 0.6 0.6"|diffuse_bsdf name="d" color="0 0 0"|'
                     -e 's|strength="120 100 80"|strength="0 0 0"|') ;;
    *) echo "unknown variant $v" >&2; exit 1 ;;
  esac
  sed "${e[@]}" "$here/scenes/frosted_fair_caustic.xml" > "$f"
  echo "$f"
}
for vc in $variants; do
  v=${vc%%:*} cls=-1 name=$vc
  if [ "$vc" != "$v" ]; then cls=${vc#*:} name=${v}_c$cls; fi
  for seed in 7919 8932; do
    ref="$out/ref_${name}_$seed.exr"
    [ -f "$ref" ] || GLIMMER_DIAG_CLASS=$cls "$glimmer" render "$(scene_for "$v" path)" -o "$ref" \
        --samples "$path_spp" --seed "$seed" --strategy mis --width 64 --height 40 --threads 1 --region $region --quiet
  done
  for seed in 11 12; do
    GLIMMER_DIAG_CLASS=$cls "$glimmer" render "$(scene_for "$v" "$method")" -o "$out/${label}_${name}_$seed.exr" \
        --samples "$spp" --seed "$seed" --strategy mis --width 64 --height 40 --threads 1 --region $region --quiet
  done
  echo "== $vc ($method $spp spp x 2 against path $path_spp spp x 2)"
  python3 "$here/frosted_variance_per_region.py" variance "$spp" "$out/${label}_${name}_11.exr" \
      "$out/${label}_${name}_12.exr" --mask "$here/scenes/frosted_fair_caustic_mask_64x40.png" \
      --references "$out/ref_${name}_7919.exr,$out/ref_${name}_8932.exr" --split-x 32 | grep -E "^(region|$show) "
done
