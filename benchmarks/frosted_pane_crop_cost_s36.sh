#!/bin/bash
# Instructions per camera path on the caustic bench's pane crop (session 36, frostedtail36;
# docs/history/frosted_glass_sessions.md "Session 36 (frostedtail36)"):
# callgrind Ir of a render of the crop (--region 34,9,46,16: 12 x 7 = 84 pixels) at
# 64 and at 192 spp, (Ir(192) - Ir(64)) / (84 x 128), so that the fixed costs (scene load, tables) cancel.
# usage: frosted_pane_crop_cost_s36.sh <glimmer> <caustic_sg.xml> <out dir>   (environment knobs pass through)
set -eu
G=$1 scene=$2 out=$3
mkdir -p "$out"
ir=()
for spp in 64 192; do
  f=$out/crop_$spp.callgrind
  valgrind --tool=callgrind --callgrind-out-file="$f" "$G" render "$scene" -o "$out/crop.exr" --region 34,9,46,16 \
      --samples $spp --seed 11 --strategy mis --width 64 --height 40 --threads 1 --quiet > /dev/null 2>&1
  ir+=($(grep -m1 "^summary:\|^totals:" "$f" | awk '{print $2}'))
done
echo "Ir 64 spp ${ir[0]} 192 spp ${ir[1]} per camera path $(( (ir[1] - ir[0]) / (84 * 128) ))"
