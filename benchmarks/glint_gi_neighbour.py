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
import statistics
import subprocess
import sys
import tempfile
import time

from glint_gi_alternate import render  # the same render command and render-phase reading

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUILD = os.environ.get('GLIMMER_BUILD', os.path.join(ROOT, 'build'))
host = os.path.join(BUILD, 'glimmer')
thrasher = os.path.join(BUILD, 'cache_thrash')


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    rounds, mb = int(sys.argv[1]), sys.argv[2]
    plugins = [os.path.abspath(p) for p in sys.argv[3:]]
    if not os.access(thrasher, os.X_OK):
        sys.exit(f'no {thrasher}: cc -O2 -o {thrasher} benchmarks/cache_thrash.c')
    scene = os.path.join(ROOT, 'examples', 'glint.xml')
    twin = os.path.join(ROOT, 'examples', f'.glint_gi_neighbour_twin.{os.getpid()}.xml')
    out = os.path.join(tempfile.gettempdir(), f'glint_gi_neighbour.{os.getpid()}.exr')
    variants = [('twin', plugins[0], twin)] + [(f'g{i}', p, scene) for i, p in enumerate(plugins)]
    t = {c: {n: [] for n, _, _ in variants} for c in ('quiet', 'thrash')}
    try:
        subprocess.run([sys.executable, os.path.join(ROOT, 'benchmarks', 'glint_gi_twin.py'), scene, twin], check=True)
        for r in range(rounds):
            for c in (['quiet', 'thrash'] if r % 2 == 0 else ['thrash', 'quiet']):
                th = subprocess.Popen(['taskset', '-c', '1', thrasher, mb]) if c == 'thrash' else None
                try:
                    if th:
                        time.sleep(0.5)
                    k = r % len(variants)
                    for n, p, sc in variants[k:] + variants[:k]:
                        t[c][n].append(render(host, p, sc, out, cpu=0))
                finally:  # a failed render must not leave the neighbour running
                    if th:
                        th.kill()
                        th.wait()
            print(r, ' '.join(f'{c}:{n}={t[c][n][-1]:.3f}' for c in t for n, _, _ in variants), flush=True)
    finally:
        for f in (twin, out):
            if os.path.exists(f):
                os.remove(f)
    for c in t:
        for n, _, _ in variants[1:]:
            ov = [g / w - 1 for g, w in zip(t[c][n], t[c]['twin'])]
            print(f'{c:6s} {n}: twin median {statistics.median(t[c]["twin"]):.3f} s, glint '
                  f'{statistics.median(t[c][n]):.3f} s, overhead per round median {100 * statistics.median(ov):+.1f} % '
                  f'(range {100 * min(ov):+.1f}..{100 * max(ov):+.1f})')


if __name__ == '__main__':
    main()
