#!/usr/bin/env bash
# Interleaved time A/B of level 0's size (session 37, glinttable37; docs/history/glints_sessions.md "Session 37
# (glinttable37)"): per round, GI time profiles (benchmarks/glint_gi_time_profile.sh: 320x200 16 spp, 1 thread, perf
# cpu-clock) in a rotating order of variants:
#   twin = the GGX twin (GI_ONLY=twin) with the new plugin;  base = $BASE_PLUGIN (2397f6c's plugin) in the same host;
#   a1   = the scratch plugin with level 0 as on main (A/A control: same bits as base);
#   h2 / q4 / e8 / any "name=si,so,sp" = the scratch plugin with GLIMMER_SCRATCH_L0=si,so,sp (level 0 subsampled at
#   those steps: 1/2, 1/4, 1/8 of the bytes for 2,1,1 / 2,1,2 / 2,2,2).
# usage: BUILD=<dir> BASE_PLUGIN=<so> glint_table_size_ab_s37.sh <rounds> <out dir> [variants]
# Prints per run: on-CPU s of the render window, f_cos_and_pdf s, trace_path s, md5, load.
set -u
rounds=$1 out=$2 variants=${3:-twin base a1 h2=2,1,1 q4=2,1,2 e8=2,2,2}
mkdir -p "$out"
wt=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${BUILD:?set BUILD: the scratch build dir} BASE_PLUGIN=${BASE_PLUGIN:?set BASE_PLUGIN}
one() {  # variant round
  local spec=$1 r=$2 v=${1%%=*} steps="" plugin=$BUILD/libglimmer_closures.so only=glint
  [[ $spec == *=* ]] && steps=${spec#*=}
  [ "$v" = base ] && plugin=$BASE_PLUGIN
  [ "$v" = twin ] && only=twin
  local d=$out/$v.$r
  GLIMMER_SCRATCH_L0=$steps GI_ONLY=$only GI_OUT=$d GI_TOP=400 \
    bash "$wt/benchmarks/glint_gi_time_profile.sh" "$BUILD" "$plugin" > "$d.txt" 2>&1
  local cpu fcp tp md5
  cpu=$(grep -o "$only: render window [0-9.]* s, [0-9.]* s on CPU" "$d.txt" | awk '{print $6}')
  fcp=$(awk '/f_cos_and_pdf/ {s += $1} END {printf "%.3f", s}' "$d.txt")
  tp=$(awk '/trace_path/ {s += $1} END {printf "%.3f", s}' "$d.txt")
  md5=$(md5sum "$d/$only.exr" | cut -c1-8)
  echo "$r $v cpu $cpu f_cos_and_pdf $fcp trace_path $tp md5 $md5 load $(cut -d' ' -f1 /proc/loadavg)"
}
set -- $variants
n=$#
vs=("$@")
for r in $(seq 1 "$rounds"); do
  for k in $(seq 0 $((n - 1))); do one "${vs[$(((k + r) % n))]}" "$r"; done
done
