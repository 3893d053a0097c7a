"""Summary of benchmarks/glint_table_size_ab_s37.sh's output (session 37, glinttable37).
usage: python3 glint_table_size_ab_summary_s37.py ab.txt
Per variant: medians of on-CPU s, f_cos_and_pdf s, trace_path s (and min..max, cv); per round the overhead over the twin
of the same round (v / twin - 1) and the ratio to base of the same round: medians and ranges."""
import collections
import statistics as st
import sys

rows = collections.defaultdict(dict)
for line in open(sys.argv[1]):
    f = line.split()
    if len(f) < 12 or f[2] != 'cpu':
        continue
    rows[int(f[0])][f[1]] = dict(cpu=float(f[3]), fcp=float(f[5]), tp=float(f[7]), md5=f[9], load=float(f[11]))
vs = []
for r in sorted(rows):
    for v in rows[r]:
        if v not in vs:
            vs.append(v)
for v in vs:
    xs = [rows[r][v] for r in rows if v in rows[r]]
    cpus = [x['cpu'] for x in xs]
    print(f"{v:5s} n={len(xs)} on-CPU median {st.median(cpus):.3f} ({min(cpus):.3f}..{max(cpus):.3f}, cv "
          f"{st.pstdev(cpus) / st.mean(cpus) * 100:.0f} %) f_cos_and_pdf {st.median(x['fcp'] for x in xs):.3f} "
          f"trace_path {st.median(x['tp'] for x in xs):.3f} md5 {sorted({x['md5'] for x in xs})}")
full = [r for r in rows if all(v in rows[r] for v in vs)]
for v in vs:
    if v == 'twin':
        continue
    line = f"{v:5s}"
    if 'twin' in vs:
        ov = sorted(100 * (rows[r][v]['cpu'] / rows[r]['twin']['cpu'] - 1) for r in full)
        line += f" overhead vs twin per round: median {st.median(ov):+.1f} % ({ov[0]:+.1f}..{ov[-1]:+.1f})"
    if 'base' in vs and v != 'base':
        rb = sorted(rows[r][v]['cpu'] / rows[r]['base']['cpu'] for r in full)
        fb = sorted(rows[r][v]['fcp'] - rows[r]['base']['fcp'] for r in full)
        below = sum(x < 1 for x in rb)
        line += (f"; / base: median {st.median(rb):.3f} ({rb[0]:.3f}..{rb[-1]:.3f}, {below}/{len(rb)} below 1)"
                 f"; f_cos_and_pdf - base: median {st.median(fb):+.3f} s")
    print(line)
loads = [x['load'] for r in rows.values() for x in r.values()]
print(f"rounds {len(full)}; load average {min(loads):.1f}..{max(loads):.1f}")
