"""Host-normalised time of benchmarks/glint_table_size_ab_s37.sh runs (session 37, glinttable37).
usage: python3 glint_table_size_ab_norm_s37.py <ab out dir> "twin base a1 h2 q4 e8"
Per run, from each <variant>.<round>.txt profile: plugin-DSO on-CPU s, everything else ("host": glimmer, embree, libs)
and f_cos_and_pdf s; per variant the medians of plugin/host and f_cos_and_pdf/host. The host does the same work in
every variant, so these ratios cancel the machine-speed swings between runs under load."""
import collections, os, re, statistics as st, sys
d0=sys.argv[1]; vs=sys.argv[2].split()
res=collections.defaultdict(list)
for v in vs:
    for r in range(1,40):
        p=f'{d0}/{v}.{r}.txt'
        if not os.path.exists(p): continue
        plug=host=fcp=0.0
        for line in open(p):
            m=re.match(r'\s*([0-9.]+)\s+([0-9.]+)\s+([+-][0-9.]+)\s+(\S+): (.*)$',line)
            if not m: continue
            x=float(m.group(1)) if v!='twin' else float(m.group(2))
            if 'closures' in m.group(4) or 'plugin' in m.group(4): plug+=x
            else: host+=x
            if 'f_cos_and_pdf' in m.group(5): fcp+=x
        res[v].append((plug,host,fcp))
for v in vs:
    xs=res[v]
    if not xs: continue
    print(f"{v:5s} n={len(xs)} plugin s {st.median(x[0] for x in xs):.3f} host s {st.median(x[1] for x in xs):.3f} "
          f"plugin/host {st.median(x[0]/x[1] for x in xs):.4f} f_cos/host {st.median(x[2]/x[1] for x in xs):.4f}")
# Per round: host-normalised overhead (1 + plugin/host) / (1 + twin's plugin/host) - 1 against the same round's twin;
# medians, and each variant's difference in points to base and to a1 (the A/A control) per round.
def ratio(v, r):
    p = f'{d0}/{v}.{r}.txt'
    if not os.path.exists(p):
        return None
    plug = host = 0.0
    for line in open(p):
        m = re.match(r'\s*([0-9.]+)\s+([0-9.]+)\s+([+-][0-9.]+)\s+(\S+): (.*)$', line)
        if not m:
            continue
        x = float(m.group(1)) if v != 'twin' else float(m.group(2))
        if 'closures' in m.group(4) or 'plugin' in m.group(4):
            plug += x
        else:
            host += x
    return plug / host
if 'twin' in vs:
    rounds = [r for r in range(1, 40) if all(ratio(v, r) is not None for v in vs)]
    ov = {v: [100 * ((1 + ratio(v, r)) / (1 + ratio('twin', r)) - 1) for r in rounds] for v in vs if v != 'twin'}
    for v in ov:
        print(f"{v:5s} per-round host-normalised overhead median {st.median(ov[v]):+.1f} %")
    for v in ov:
        for b in ('base', 'a1'):
            if b in ov and v != b and not (v == 'base' and b == 'a1'):
                dd = sorted(x - y for x, y in zip(ov[v], ov[b]))
                print(f"{v}-{b} points per round: median {st.median(dd):+.1f} range {dd[0]:+.1f}..{dd[-1]:+.1f} "
                      f"({sum(x < 0 for x in dd)}/{len(dd)} below 0)")
