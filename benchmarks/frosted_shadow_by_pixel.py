"""The caustic bench's sphere shadow (shadow_L: the mask's shadow pixels with x < 32), per pixel: the reference value
and the relative error of the mean of the given sg renders against the two 65536-spp references (issue 12, session
24, frostedskew24: where the shadow's bias sits, e.g. main's 2 x 8192 spp: the caustic's peak pixel (22, 20) -7 %,
its neighbours +2 / +4 %, a halo 3 pixels out +12..+27 %).
    python3 benchmarks/frosted_shadow_by_pixel.py REFS_DIR a_11.exr a_12.exr ...     (from the repository root)
REFS_DIR holds ref_7919.exr and ref_8932.exr (e.g. /tmp/frostedcost20/refs).
Then (session 29, frostedshadow29) the whole shadow's (both sides) pixels ranked by their share of the region's b^2
(noise-corrected as frosted_variance_per_region.py's bias_rms: offset^2 - var / n - the references' var, per channel,
summed): a large relative error on a dim pixel (the halo's +20 %) can weigh less than -3 % on the caustic's peak.
Needs >= 2 renders (their spread is the noise taken out).
"""
import sys
sys.path.insert(0, 'benchmarks')
import frosted_variance_per_region as fv

refs, images = sys.argv[1], sys.argv[2:]
reg = fv.regions('benchmarks/scenes/frosted_fair_caustic_mask_64x40.png', ['lit', 'glass', 'shadow'])
ra, rb = fv.combined(refs + '/ref_7919.exr'), fv.combined(refs + '/ref_8932.exr')
imgs = [fv.combined(p) for p in images]


def avg(ims, k):
    return sum(sum(i[k]) / 3 for i in ims) / len(ims)


sh = {k for k, r in reg.items() if r == 'shadow' and k[0] < 32}
xs = sorted({k[0] for k in sh})
ys = sorted({k[1] for k in sh})
print('shadow_L per pixel, reference : (sg - ref) / ref in %%; rows y %d..%d, columns x %d..%d' %
      (ys[0], ys[-1], xs[0], xs[-1]))
for y in ys:
    line = '%2d ' % y
    for x in range(xs[0], xs[-1] + 1):
        if (x, y) in sh:
            ref = avg([ra, rb], (x, y))
            line += '%5.2f:%+4.0f ' % (ref, 100 * (avg(imgs, (x, y)) - ref) / max(ref, 1e-9))
        else:
            line += ' ' * 11
    print(line)


TOP = 12
if len(imgs) >= 2:
    rows, total, values = [], 0.0, 0
    for k, r in reg.items():
        if r != 'shadow' or any(k not in i for i in imgs):
            continue
        b2 = off = 0.0
        for c in range(3):
            v = [i[k][c] for i in imgs]
            mean = sum(v) / len(v)
            var = sum((x - mean) ** 2 for x in v) / (len(v) - 1)
            rm = (ra[k][c] + rb[k][c]) / 2
            rvar = ((ra[k][c] - rm) ** 2 + (rb[k][c] - rm) ** 2) / 2
            b2 += (mean - rm) ** 2 - var / len(v) - rvar
            off += (mean - rm) / 3
        rows.append((b2, k, avg([ra, rb], k), off))
        total, values = total + b2, values + 3
    rows.sort(reverse=True)
    print('shadow (all %d values): rms bias %.5f; pixels by their share of b^2 (top %d):' %
          (values, max(total / max(values, 1), 0.0) ** 0.5, TOP))
    acc = 0.0
    for b2, k, ref, off in rows[:TOP]:
        acc += b2
        print('  (%2d,%2d) ref %6.3f offset %+.4f (%+5.1f %%) share %5.1f %% cumulative %5.1f %%' %
              (k[0], k[1], ref, off, 100 * off / max(ref, 1e-9), 100 * b2 / total, 100 * acc / total))
