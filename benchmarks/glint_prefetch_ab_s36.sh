#!/usr/bin/env bash
# Interleaved time A/B (session 36, glinthook36; docs/history/glints_sessions.md "Session 36 (glinthook36)"):
# per round, GI glint
# time profiles (benchmarks/glint_gi_time_profile.sh: 320x200 16 spp, 1 thread, perf cpu-clock) in a rotating order:
#   new  = the patched host + plugin (benchmarks/glint_prefetch_cheap_s36.patch; a copy in $NEW), the prefetch on;
#   off  = the same host + plugin with --no-closure-prefetch;
#   base = d95ecb6's host + plugin (in $BASE).
# Prints per run: on-CPU s of the render window, f_cos_and_pdf s, the adapter's prefetch s, trace_path s, load.
# usage: NEW=<dir> BASE=<dir> glint_prefetch_ab_s36.sh <rounds> <out dir> [variants, default "new off base"]
set -u
rounds=$1 out=$2 variants=${3:-new off base}
mkdir -p "$out"
wt=$(cd "$(dirname "$0")/.." && pwd)  # this repository (for benchmarks/glint_gi_time_profile.sh)
NEW=${NEW:?set NEW: a directory holding the new glimmer and libglimmer_closures.so}
BASE=${BASE:?set BASE: a directory holding the baseline glimmer and libglimmer_closures.so}
export GI_ONLY=glint  # GLIMMER_CACHE_DIR: set by the caller
one() {  # variant round
  local v=$1 r=$2 dir=$NEW args=""
  [ "$v" = base ] && dir=$BASE
  [ "$v" = off ] && args=--no-closure-prefetch
  local d=$out/$v.$r
  GI_OUT=$d GI_ARGS=$args GI_TOP=400 bash $wt/benchmarks/glint_gi_time_profile.sh "$dir" "$dir/libglimmer_closures.so" > $d.txt 2>&1
  local cpu fcp pf tp
  cpu=$(grep -o 'glint: render window [0-9.]* s, [0-9.]* s on CPU' $d.txt | awk '{print $6}')
  fcp=$(awk '/f_cos_and_pdf/ {s += $1} END {printf "%.3f", s}' $d.txt)
  pf=$(awk '/::prefetch\(/ {s += $1} END {printf "%.3f", s}' $d.txt)
  tp=$(awk '/trace_path/ {s += $1} END {printf "%.3f", s}' $d.txt)
  md5=$(md5sum $d/glint.exr | cut -c1-8)
  echo "$r $v cpu $cpu f_cos_and_pdf $fcp prefetch $pf trace_path $tp md5 $md5 load $(cut -d' ' -f1 /proc/loadavg)"
}
set -- $variants
n=$#
vs=("$@")
for r in $(seq 1 "$rounds"); do
  order=""
  for k in $(seq 0 $((n - 1))); do order="$order ${vs[$(((k + r) % n))]}"; done
  for v in $order; do one "$v" "$r"; done
done
