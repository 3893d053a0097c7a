#!/usr/bin/env bash
# GI overhead of glints in instructions (issue 10): callgrind of `glimmer
# render` of examples/glint.xml and of its GGX twin, made as
# glint/gi_scene_overhead makes it (bench_glint.cpp: every glint_bsdf a
# glossy_bsdf GGX of the same roughness), counting only the render phase
# (Renderer::render*), 1 thread. Prints both counts, the overhead, and the md5
# of each EXR (equal md5: the same image, bit for bit).
# usage: benchmarks/glint_gi_instructions.sh [build dir] [width height spp] [plugin .so]
#   defaults: ./build 160 100 4 (issue 10's figure is 320 200 8: ~15-30 min per render)
# The glimmer binary loads its image modules (libglimmer_exr_io.so) from beside it.
# Env: GI_TWIN_ARGS=--same-distribution (the twin keeps each glint's distribution),
#   GLIMMER_CACHE_DIR (tables), GI_OUT (output dir, default a temp dir, kept), GI_ONLY=glint|twin,
#   GI_CALLGRIND_OPTS (more callgrind options, e.g. --dump-instr=yes for callgrind_annotate of a -g build),
#   GI_PLUGIN_TWIN (the twin's plugin, default the same as the glint's).
set -euo pipefail
build=$(cd "${1:-build}" && pwd)
width=${2:-160}
height=${3:-100}
spp=${4:-4}
plugin=${5:-$build/libglimmer_closures.so}
src=$(cd "$(dirname "$0")/.." && pwd)/examples/glint.xml
out=${GI_OUT:-$(mktemp -d /tmp/glint_gi.XXXXXX)}
mkdir -p "$out"
export GLIMMER_CACHE_DIR=${GLIMMER_CACHE_DIR:-/tmp/glint_eval_instructions_cache}
mkdir -p "$GLIMMER_CACHE_DIR"
# The twin beside the original (relative paths in the scene resolve the same).
twin=$(dirname "$src")/.glint_gi_twin.$$.xml
trap 'rm -f "$twin"' EXIT
# shellcheck disable=SC2086
python3 "$(dirname "$0")/glint_gi_twin.py" ${GI_TWIN_ARGS:-} "$src" "$twin"
run() {  # name scene plugin
  local name=$1 scene=$2 lib=$3
  # shellcheck disable=SC2086
  (cd "$build" && valgrind --tool=callgrind --collect-atstart=no ${GI_CALLGRIND_OPTS:-} \
     --toggle-collect='glimmer::render::Renderer::render*' --callgrind-out-file="$out/cg.$name" \
     ./glimmer --plugin "$lib" render "$scene" -o "$out/$name.exr" --samples "$spp" --threads 1 \
     --width "$width" --height "$height" --quiet > "$out/$name.log" 2>&1)
  grep -m1 '^summary:' "$out/cg.$name" | awk '{print $2}'
}
echo "GI ${width}x${height} ${spp} spp, plugin $plugin, output $out"
t="" g=""
if [ "${GI_ONLY:-}" != glint ]; then
  t=$(run twin "$twin" "${GI_PLUGIN_TWIN:-$plugin}")
  printf 'twin  %10.1f M  md5 %s\n' "$(awk -v x="$t" 'BEGIN{print x/1e6}')" "$(md5sum < "$out/twin.exr" | cut -c1-32)"
fi
if [ "${GI_ONLY:-}" != twin ]; then
  g=$(run glint "$src" "$plugin")
  printf 'glint %10.1f M  md5 %s\n' "$(awk -v x="$g" 'BEGIN{print x/1e6}')" "$(md5sum < "$out/glint.exr" | cut -c1-32)"
fi
if [ -n "$t" ] && [ -n "$g" ]; then
  awk -v t="$t" -v g="$g" 'BEGIN{printf "overhead %+.1f %%\n", 100 * (g / t - 1)}'
fi
