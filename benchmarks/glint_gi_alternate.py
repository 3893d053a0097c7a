#!/usr/bin/env python3
"""GI time of glint plugins by alternating renders (issue 10; docs/history/glints_sessions.md "Session 43").

Renders examples/glint.xml and its GGX twin (benchmarks/glint_gi_twin.py) with several plugins in rotating order,
round after round (320 x 200, 16 spp, 1 thread: glint/gi_scene_overhead's settings), and reads the render phase
(`--stats`' render=). On a noisy VM one render moves by 10 % or more between runs, so a comparison is made per round
(both renders a few seconds apart) and summarised by the median of the per-round ratios with a bootstrap 95 %
interval; min / q25 / median per variant are printed too.

usage: benchmarks/glint_gi_alternate.py [--build DIR] [--rounds N] NAME=PLUGIN[:twin][@VAR=VALUE] ...
  NAME=PLUGIN        the glint scene with that plugin .so
  NAME=PLUGIN:twin   the GGX twin with that plugin
  ...@VAR=VALUE      that variant's renders with VAR=VALUE in their environment (a scratch build's switch, so the
                     same .so is compared with itself: session 44's A/B of a scratch plugin)
  Every pair of variants is compared; a glint variant's overhead is given over each twin variant.
Env: GLIMMER_CACHE_DIR (tables). Alternating plugin builds re-run the tables' energy check at each load (its stamp
is per build), which costs start-up time, not render time.
"""
import argparse
import os
import random
import re
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def median_ci(x, n=2000, seed=1):
    rng = random.Random(seed)
    m = sorted(statistics.median(rng.choice(x) for _ in x) for _ in range(n))
    return m[int(0.025 * n)], m[int(0.975 * n)]


def render(host, plugin, scene, out, env=None, cpu=None):
    """The render phase's seconds of one render at the benchmark's settings (on CPU `cpu` when given: taskset)."""
    pin = ['taskset', '-c', str(cpu)] if cpu is not None else []
    r = subprocess.run(pin + [host, '--plugin', plugin, 'render', scene, '-o', out, '--samples', '16', '--threads',
                              '1', '--width', '320', '--height', '200', '--quiet', '--stats'],
                       capture_output=True, text=True, env=env)
    m = re.search(r'render=([0-9.]+)s', r.stdout + r.stderr)
    if r.returncode != 0 or not m:
        sys.exit(f"glint_gi_alternate: render failed ({plugin}, {scene}):\n{r.stderr}")
    return float(m.group(1))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--build', default=os.path.join(ROOT, 'build'))
    ap.add_argument('--rounds', type=int, default=30)
    ap.add_argument('variants', nargs='+')
    a = ap.parse_args()
    if a.rounds < 1:
        ap.error('--rounds must be at least 1')
    vs, envs = [], {}
    for v in a.variants:
        name, eq, rest = v.partition('=')
        if not eq or not name or not rest:
            ap.error(f'{v!r}: expected NAME=PLUGIN[:twin][@VAR=VALUE]')
        env = None
        head, at, setting = rest.rpartition('@')  # a path may hold '@': the setting is after the last one
        if at and not os.path.isfile(rest) and not (rest.endswith(':twin') and os.path.isfile(rest[:-len(':twin')])):
            var, eq2, value = setting.partition('=')
            if not eq2 or not re.fullmatch(r'[A-Za-z_][A-Za-z0-9_]*', var) or value.endswith(':twin'):
                ap.error(f'{v!r}: expected NAME=PLUGIN[:twin]@VAR=VALUE (one setting, after :twin)')
            env = dict(os.environ, **{var: value})
            rest = head
        plugin, kind = (rest[:-len(':twin')], 'twin') if rest.endswith(':twin') else (rest, '')
        if not os.path.isfile(plugin):
            ap.error(f'{v!r}: no plugin file {plugin!r}')
        if name in (n for n, _, _ in vs):
            ap.error(f'{v!r}: the name {name!r} is used twice')
        vs.append((name, os.path.abspath(plugin), kind == 'twin'))
        envs[name] = env
    host = os.path.join(a.build, 'glimmer')
    scene = os.path.join(ROOT, 'examples', 'glint.xml')
    with tempfile.TemporaryDirectory() as tmp:
        # The twin beside the scene (its relative paths resolve the same), removed at the end (.gitignore'd).
        twin = os.path.join(ROOT, 'examples', f'.glint_gi_alternate_twin.{os.getpid()}.xml')
        try:
            subprocess.run([sys.executable, os.path.join(ROOT, 'benchmarks', 'glint_gi_twin.py'), scene, twin],
                           check=True)
            t = {n: [] for n, _, _ in vs}
            for r in range(a.rounds):
                k = r % len(vs)
                for name, plugin, is_twin in vs[k:] + vs[:k]:
                    t[name].append(render(host, plugin, twin if is_twin else scene, os.path.join(tmp, 'x.exr'),
                                          envs[name]))
                print(r, ' '.join(f'{n}={t[n][-1]:.3f}' for n, _, _ in vs), flush=True)
        finally:
            if os.path.exists(twin):
                os.remove(twin)

    def q25(x):
        return sorted(x)[int(0.25 * (len(x) - 1))]

    print('variant   min     q25     median  (render phase, s)')
    for n, _, _ in vs:
        print(f'{n:9s} {min(t[n]):.4f}  {q25(t[n]):.4f}  {statistics.median(t[n]):.4f}')
    names = [n for n, _, _ in vs]
    twins = [n for n, _, w in vs if w]
    for i, x in enumerate(names):
        for y in names[i + 1:]:
            r = [p / q for p, q in zip(t[x], t[y])]
            lo, hi = median_ci(r)
            print(f'{x}/{y}: per-round median {statistics.median(r):.4f} (95 % {lo:.4f}..{hi:.4f}), '
                  f'below 1 in {sum(v < 1 for v in r)} of {len(r)}')
    for x, _, w in vs:
        if w:
            continue
        for y in twins:
            r = [p / q - 1 for p, q in zip(t[x], t[y])]
            lo, hi = median_ci(r)
            print(f'overhead of {x} over {y}: {100 * statistics.median(r):+.1f} % (95 % {100 * lo:+.1f}..{100 * hi:+.1f})')


if __name__ == '__main__':
    main()
