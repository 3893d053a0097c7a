import sys, re, statistics as st, collections, glob, os
# usage: summ.py ab.txt ab_dir : medians per variant of on-CPU, f_cos_and_pdf, prefetch adapter, trace_path; per-round ratios
rows = collections.defaultdict(dict)
for line in open(sys.argv[1]):
    f = line.split()
    if len(f) < 14: continue
    r, v = int(f[0]), f[1]
    d = dict(cpu=float(f[3]), fcp=float(f[5]), tp=float(f[9]), md5=f[11], load=float(f[13]))
    pf = 0.0
    p = os.path.join(sys.argv[2], f'{v}.{r}.txt')
    for t in open(p):
        if 'ClosureAdapter<glimmer::plugin::GlintClosure>::prefetch' in t:
            pf += float(t.split()[0])
    d['pf'] = pf
    rows[r][v] = d
vs = sorted({v for r in rows.values() for v in r})
for v in vs:
    xs = [rows[r][v] for r in rows if v in rows[r]]
    def m(k): return st.median([x[k] for x in xs])
    cpus = [x['cpu'] for x in xs]
    print(f"{v:5s} n={len(xs)} on-CPU median {m('cpu'):.3f} (min {min(cpus):.3f} max {max(cpus):.3f}, cv {st.pstdev(cpus)/st.mean(cpus)*100:.0f} %) "
          f"f_cos_and_pdf {m('fcp'):.3f} prefetch {m('pf'):.3f} trace_path {m('tp'):.3f} md5 {sorted({x['md5'] for x in xs})}")
for a, b in [('new', 'off'), ('new', 'base'), ('off', 'base'), ('s35', 'base'), ('new', 's35')]:
    if a in vs and b in vs:
        rs = sorted(rows[r][a]['cpu'] / rows[r][b]['cpu'] for r in rows if a in rows[r] and b in rows[r])
        print(f"{a}/{b} per round: median {st.median(rs):.3f} range {rs[0]:.3f}..{rs[-1]:.3f} ({' '.join(f'{x:.3f}' for x in rs)})")
loads = [x['load'] for r in rows.values() for x in r.values()]
print(f"load average {min(loads):.1f}..{max(loads):.1f}")
