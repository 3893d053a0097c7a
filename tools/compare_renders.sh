#!/bin/bash
# Renders scenes with two glimmer builds (fixed seed, 8 samples, 2 threads) and compares every channel of every
# pixel (oiiotool --dumpdata, float32 printed exactly): "IDENTICAL" or "DIFFERENT" per scene.
#   tools/compare_renders.sh OLD_GLIMMER NEW_GLIMMER OUT_DIR scene.xml...
# The plugin is the one next to each executable (copy libglimmer_closures.so, and libglimmer_image_io.so and
# libglimmer_exr_io.so where the build has them, along with an old build).
set -u
old=$1 new=$2 out=$3
shift 3
mkdir -p "$out/old" "$out/new"
status=0
for scene in "$@"; do
  name=$(basename "$scene" .xml)
  for side in old new; do
    bin=$old; [ $side = new ] && bin=$new
    "$bin" render "$scene" -o "$out/$side/$name.exr" --samples 8 --seed 3 --threads 2 --quiet > "$out/$side/$name.log" 2>&1 ||
      echo "$name: $side render failed (exit $?)"
  done
  a=$(oiiotool --dumpdata "$out/old/$name.exr" 2>&1 | tail -n +2 | sha1sum | cut -c1-12)
  b=$(oiiotool --dumpdata "$out/new/$name.exr" 2>&1 | tail -n +2 | sha1sum | cut -c1-12)
  if [ "$a" = "$b" ]; then echo "$name IDENTICAL ($a)"; else echo "$name DIFFERENT ($a vs $b)"; status=1; fi
done
exit $status
