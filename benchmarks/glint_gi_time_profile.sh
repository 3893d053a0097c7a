#!/usr/bin/env bash
# Where the GI scene's TIME goes (issue 10): `perf record -e cpu-clock` of `glimmer render` of examples/glint.xml
# and of its GGX twin (made as glint/gi_scene_overhead makes it), at the benchmark's settings (320x200, 16 spp,
# 1 thread). Prints, per function, the on-CPU seconds inside the render phase for both scenes and their difference.
#
# Why a time profile beside benchmarks/glint_gi_instructions.sh: the overhead in time (+48 %) was twice the one in
# instructions (+24 %) in session 30, and callgrind cannot see memory latency (its simulated last level is the host's
# whole cache). cpu-clock sampling needs no hardware counters (this project's machines have none), so it works in
# VMs. The render phase is taken as the span between the first and the last sample in Renderer::Impl::trace_path.
#
# usage: benchmarks/glint_gi_time_profile.sh [build dir] [plugin .so]
# Env: GI_TWIN_ARGS=--same-distribution (the twin keeps each glint's distribution),
#   GLIMMER_CACHE_DIR (tables), GI_OUT (output dir, default a temp dir, kept), GI_ONLY=glint|twin,
#   GI_SAMPLES / GI_WIDTH / GI_HEIGHT (16 / 320 / 200), GI_TOP (rows, 30), GI_PERIOD_US (sampling period, 200),
#   GI_ARGS (more `glimmer render` options for both scenes, e.g. --no-aovs; A/B of one option in one build).
# Needs perf (Debian: linux-perf). Per-instruction detail afterwards:
#   perf annotate -i <out>/glint.perf --stdio -s '<symbol>'
set -euo pipefail
build=$(cd "${1:-build}" && pwd)
plugin=${2:-$build/libglimmer_closures.so}
command -v perf > /dev/null || { echo "glint_gi_time_profile.sh: perf not found (apt-get install linux-perf)" >&2; exit 2; }
src=$(cd "$(dirname "$0")/.." && pwd)/examples/glint.xml
out=${GI_OUT:-$(mktemp -d /tmp/glint_gi_time.XXXXXX)}
mkdir -p "$out"
period_us=${GI_PERIOD_US:-200}
twin=$(dirname "$src")/.glint_gi_time_twin.$$.xml
trap 'rm -f "$twin"' EXIT
# shellcheck disable=SC2086
python3 "$(dirname "$0")/glint_gi_twin.py" ${GI_TWIN_ARGS:-} "$src" "$twin"
run() {  # name scene
  local name=$1 scene=$2
  (cd "$build" && perf record -q -e cpu-clock -c $((period_us * 1000)) -o "$out/$name.perf" \
     ./glimmer --plugin "$plugin" render "$scene" -o "$out/$name.exr" --samples "${GI_SAMPLES:-16}" --threads 1 \
     --width "${GI_WIDTH:-320}" --height "${GI_HEIGHT:-200}" --quiet --stats ${GI_ARGS:-} > "$out/$name.log" 2>&1)
  perf script -i "$out/$name.perf" -F time,ip,sym,dso 2> /dev/null > "$out/$name.samples"
  echo "$name: $(grep -o 'render=[0-9.]*s' "$out/$name.log")"
}
echo "GI time profile, plugin $plugin, output $out"
[ "${GI_ONLY:-}" = glint ] || run twin "$twin"
[ "${GI_ONLY:-}" = twin ] || run glint "$src"
python3 - "$out" "$period_us" "${GI_TOP:-30}" <<'PY'
import collections, os, re, sys
out, period, top = sys.argv[1], float(sys.argv[2]) * 1e-6, int(sys.argv[3])
line = re.compile(r'^\s*([0-9]+\.[0-9]+):\s+[0-9a-f]+\s+(.*?)\s+\((\S+)\)\s*$')
def profile(name):
    path = os.path.join(out, name + '.samples')
    if not os.path.exists(path):
        return None
    rows = []
    for text in open(path, errors='replace'):
        m = line.match(text)
        if m:
            sym = m.group(2).strip() or '[unknown]'
            rows.append((float(m.group(1)), sym, os.path.basename(m.group(3))))
    inside = [r[0] for r in rows if 'Renderer::Impl::trace_path' in r[1]]
    if not inside:
        sys.exit(f'{name}: no sample in Renderer::Impl::trace_path (render phase not found)')
    t0, t1 = min(inside), max(inside)
    counts = collections.Counter()
    for t, sym, dso in rows:
        if t0 <= t <= t1:
            counts[(dso, sym[:110])] += 1
    return t1 - t0, counts
profiles = {n: profile(n) for n in ('twin', 'glint')}
for n, p in profiles.items():
    if p:
        print(f'{n}: render window {p[0]:.3f} s, {sum(p[1].values()) * period:.3f} s on CPU')
keys = set()
for p in profiles.values():
    if p:
        keys |= set(p[1])
def sec(n, k):
    p = profiles[n]
    return p[1][k] * period if p else 0.0
order = sorted(keys, key=lambda k: -max(sec('glint', k), sec('twin', k)))
print(f"{'glint s':>8} {'twin s':>8} {'diff s':>8}  function")
for k in order[:top]:
    g, t = sec('glint', k), sec('twin', k)
    print(f'{g:8.3f} {t:8.3f} {g - t:+8.3f}  {k[0]}: {k[1]}')
if profiles['twin'] and profiles['glint']:
    g = sum(profiles['glint'][1].values()) * period
    t = sum(profiles['twin'][1].values()) * period
    print(f'total {g:.3f} s vs {t:.3f} s: {100 * (g / t - 1):+.1f} %')
PY
