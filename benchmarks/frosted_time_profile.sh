#!/usr/bin/env bash
# Where frosted glass's TIME goes (issue 12): `perf record -e cpu-clock` of `glimmer render` of the caustic bench's
# scene (benchmarks/scenes/frosted_fair_caustic.xml, every frosted_glass_bsdf's method set as frosted_sg_cost.sh
# sets it) for each method, 1 thread, seed 11, mis. Prints, per function, the on-CPU time inside the render phase in
# nanoseconds per camera path (width x height x spp), side by side for the methods, and the totals' ratios to the
# first method's. Beside the instruction count (frosted_sg_cost.sh) this shows memory stalls callgrind cannot see.
#
# usage: benchmarks/frosted_time_profile.sh [build dir] [methods, default path,sg,auto] [plugin .so]
# Env: FT_OUT (output dir, default a temp dir, kept), FT_SAMPLES / FT_WIDTH / FT_HEIGHT (128 / 64 / 40), FT_SEED (11),
#   FT_REPS (renders per method, alternated path sg auto path sg auto ...; 2), FT_TOP (rows, 30),
#   FT_PERIOD_US (sampling period, 200), FT_PLUGIN_B (a second plugin: each method is also rendered with it,
#   as method@B, alternated with the first: an A/B of two plugins on the same glimmer binary and scene copies).
# The render phase of a run is the span between its first and last sample in Renderer::Impl::trace_path. The
# machine is shared: cpu-clock counts on-CPU time only, but caches are shared too; alternate and repeat.
# Per-instruction detail afterwards: perf annotate -i <out>/<method>.1.perf --stdio -s '<symbol>'
set -euo pipefail
build=$(cd "${1:-build}" && pwd)
methods=${2:-path,sg,auto}
plugin=${3:-$build/libglimmer_closures.so}
command -v perf > /dev/null || { echo "frosted_time_profile.sh: perf not found (apt-get install linux-perf)" >&2; exit 2; }
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
out=${FT_OUT:-$(mktemp -d /tmp/frosted_time.XXXXXX)}
mkdir -p "$out"
period_us=${FT_PERIOD_US:-200}
spp=${FT_SAMPLES:-128}; w=${FT_WIDTH:-64}; h=${FT_HEIGHT:-40}
variants=()
for m in ${methods//,/ }; do
  sed -e "/<frosted_glass_bsdf /s#ior=\"\\([^\"]*\\)\"#ior=\"\\1\" method=\"$m\"#" \
      -e "s#\\.\\./\\.\\./examples/#$root/examples/#g" "$here/scenes/frosted_fair_caustic.xml" > "$out/caustic_$m.xml"
  variants+=("$m")
  [ -z "${FT_PLUGIN_B:-}" ] || variants+=("$m@B")
done
run() {  # variant rep
  local v=$1 rep=$2 m=${1%@B} so=$plugin
  [ "$v" = "$m" ] || so=$FT_PLUGIN_B
  (cd "$build" && perf record -q -e cpu-clock -c $((period_us * 1000)) -o "$out/$v.$rep.perf" \
     ./glimmer --plugin "$so" render "$out/caustic_$m.xml" -o "$out/$v.$rep.exr" --samples "$spp" --seed "${FT_SEED:-11}" \
     --strategy mis --width "$w" --height "$h" --threads 1 --quiet --stats > "$out/$v.$rep.log" 2>&1)
  perf script -i "$out/$v.$rep.perf" -F time,ip,sym,dso 2> /dev/null > "$out/$v.$rep.samples"
  echo "$v.$rep: $(grep -o 'render=[0-9.]*s' "$out/$v.$rep.log") md5 $(md5sum < "$out/$v.$rep.exr" | cut -c1-8)"
}
echo "frosted time profile: plugin $plugin${FT_PLUGIN_B:+ (B: $FT_PLUGIN_B)}, ${w}x${h} ${spp} spp, output $out"
for rep in $(seq 1 "${FT_REPS:-2}"); do
  for v in "${variants[@]}"; do run "$v" "$rep"; done
done
python3 - "$out" "$period_us" "${FT_TOP:-30}" "$((w * h * spp))" "${FT_REPS:-2}" "${variants[@]}" <<'PY'
import collections, os, re, sys
out, period, top, paths, reps = sys.argv[1], float(sys.argv[2]) * 1e-6, int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])
variants = sys.argv[6:]
line = re.compile(r'^\s*([0-9]+\.[0-9]+):\s+[0-9a-f]+\s+(.*?)\s+\((\S+)\)\s*$')
def one(path):
    rows = []
    for text in open(path, errors='replace'):
        m = line.match(text)
        if m:
            rows.append((float(m.group(1)), m.group(2).strip() or '[unknown]', os.path.basename(m.group(3))))
    inside = [r[0] for r in rows if 'Renderer::Impl::trace_path' in r[1]]
    if not inside:
        sys.exit(f'{path}: no sample in Renderer::Impl::trace_path (render phase not found)')
    t0, t1 = min(inside), max(inside)
    return collections.Counter((d, s[:100]) for t, s, d in rows if t0 <= t <= t1)
prof, per_rep = {}, {}
for v in variants:
    prof[v] = collections.Counter()
    per_rep[v] = []
    for r in range(1, reps + 1):
        c = one(os.path.join(out, f'{v}.{r}.samples'))
        prof[v] += c
        per_rep[v].append(sum(c.values()) * period / paths * 1e9)
ns = lambda v, k: prof[v][k] * period / paths / reps * 1e9   # ns per camera path, mean over the reps
tot = {v: sum(prof[v].values()) * period / paths / reps * 1e9 for v in variants}
print(f'on-CPU ns per camera path ({paths} camera paths per render, {reps} renders each):')
for v in variants:
    print(f'  {v:>8}: {tot[v]:8.1f}  (renders: {" ".join(f"{x:.1f}" for x in per_rep[v])})'
          f'  ratio to {variants[0]}: {tot[v] / tot[variants[0]]:.3f}')
keys = set().union(*[set(p) for p in prof.values()])
order = sorted(keys, key=lambda k: -max(ns(v, k) for v in variants))
print(' '.join(f'{v:>8}' for v in variants) + '  function (ns per camera path)')
for k in order[:top]:
    print(' '.join(f'{ns(v, k):8.1f}' for v in variants) + f'  {k[0]}: {k[1]}')
PY
