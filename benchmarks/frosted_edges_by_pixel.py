"""The caustic bench's 'edges' pixels (the mask's mixed pixels), per pixel: the 2-seed mean of two sg variants against
the two 65536-spp references, sorted by how much the second variant's |error| is below the first's (issue 12, session 23,
frostedexit23: the exit-axis rules smooth vs moment at 2 x 8192 spp; paths below are that session's, edit them).
    python3 benchmarks/frosted_edges_by_pixel.py     (run from the repository root)
"""
import sys
sys.path.insert(0, 'benchmarks')
import frosted_variance_per_region as fv
reg = fv.regions('benchmarks/scenes/frosted_fair_caustic_mask_64x40.png', ['lit', 'glass', 'shadow'])
R = '/tmp/frostedexit23/refs/'
ra, rb = fv.combined(R+'ref_7919.exr'), fv.combined(R+'ref_8932.exr')
C = '/tmp/frostedexit23/caustic8k/'
S = [fv.combined(C+'smooth_8k_11.exr'), fv.combined(C+'smooth_8k_12.exr')]
M = [fv.combined(C+'moment_8k_11.exr'), fv.combined(C+'moment_8k_12.exr')]
def avg(imgs, k): return sum(sum(i[k]) / 3 for i in imgs) / len(imgs)
rows = []
for k, r in reg.items():
    if r != 'edges': continue
    ref, s, mo = avg([ra, rb], k), avg(S, k), avg(M, k)
    rows.append((abs(s - ref) - abs(mo - ref), k, ref, s, mo))
rows.sort(reverse=True)
print(len(rows), 'edge pixels; top by |smooth-ref| - |moment-ref|: (x,y) ref smooth moment')
for r in rows[:10]: print(r[1], '%.4f %.4f %.4f' % (r[2], r[3], r[4]))
xs = [r[1][0] for r in rows[:10]]; print('x of the top 10:', xs)
