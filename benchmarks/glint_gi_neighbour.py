#!/usr/bin/env python3
"""GI overhead (glint / GGX twin) with and without a cache-thrashing neighbour on the other core (issue 10, session 45;
docs/history/glints_sessions.md "Session 45").

Renders examples/glint.xml and its GGX twin (glint_gi_twin.py) at 320 x 200, 16 spp, 1 thread, pinned to CPU 0
(taskset); in every other block of renders benchmarks/cache_thrash (cc -O2 -o build/cache_thrash
benchmarks/cache_thrash.c) runs pinned to CPU 1. Rounds alternate the conditions' order and rotate the renders' order;
prints each glint plugin's per-round overhead (median, range) in each condition.

usage: benchmarks/glint_gi_neighbour.py ROUNDS THRASH_MB PLUGIN [PLUGIN2 ...]  (the twin with the first plugin)
Env: GLIMMER_BUILD (default ./build: its glimmer and cache_thrash), GLIMMER_CACHE_DIR (tables)."""
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUILD = os.environ.get('GLIMMER_BUILD', os.path.join(ROOT, 'build'))
host = os.path.join(BUILD, 'glimmer')
thrasher = os.path.join(BUILD, 'cache_thrash')
if len(sys.argv) < 4:
    sys.exit(__doc__)
rounds, mb = int(sys.argv[1]), sys.argv[2]
plugins = [os.path.abspath(p) for p in sys.argv[3:]]
if not os.access(thrasher, os.X_OK):
    sys.exit(f'no {thrasher}: cc -O2 -o {thrasher} benchmarks/cache_thrash.c')
scene = os.path.join(ROOT, 'examples', 'glint.xml')
twin = os.path.join(ROOT, 'examples', f'.glint_gi_neighbour_twin.{os.getpid()}.xml')
subprocess.run([sys.executable, os.path.join(ROOT, 'benchmarks', 'glint_gi_twin.py'), scene, twin], check=True)
out = os.path.join(tempfile.gettempdir(), f'glint_gi_neighbour.{os.getpid()}.exr')


def render(plugin, sc):
    r = subprocess.run(['taskset', '-c', '0', host, '--plugin', plugin, 'render', sc, '-o', out,
                        '--samples', '16', '--threads', '1', '--width', '320', '--height', '200', '--quiet', '--stats'],
                       capture_output=True, text=True)
    m = re.search(r'render=([0-9.]+)s', r.stdout + r.stderr)
    assert r.returncode == 0 and m, r.stderr
    return float(m.group(1))
variants = [('twin', plugins[0], twin)] + [(f'g{i}', p, scene) for i, p in enumerate(plugins)]
t = {c: {n: [] for n, _, _ in variants} for c in ('quiet', 'thrash')}
try:
    for r in range(rounds):
        conds = ['quiet', 'thrash'] if r % 2 == 0 else ['thrash', 'quiet']
        for c in conds:
            th = None
            if c == 'thrash':
                th = subprocess.Popen(['taskset', '-c', '1', thrasher, mb])
                time.sleep(0.5)
            k = r % len(variants)
            for n, p, sc in variants[k:] + variants[:k]:
                t[c][n].append(render(p, sc))
            if th:
                th.kill(); th.wait()
        print(r, ' '.join(f'{c}:{n}={t[c][n][-1]:.3f}' for c in t for n, _, _ in variants), flush=True)
finally:
    os.remove(twin)
    if os.path.exists(out):
        os.remove(out)
for c in t:
    for n, _, _ in variants:
        if n == 'twin':
            continue
        ov = [g / w - 1 for g, w in zip(t[c][n], t[c]['twin'])]
        print(f'{c:6s} {n}: twin median {statistics.median(t[c]["twin"]):.3f} s, glint {statistics.median(t[c][n]):.3f} s,'
              f' overhead per round median {100 * statistics.median(ov):+.1f} % (range {100 * min(ov):+.1f}..{100 * max(ov):+.1f})')
