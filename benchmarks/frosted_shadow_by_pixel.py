"""The caustic bench's sphere shadow (shadow_L: the mask's shadow pixels with x < 32), per pixel: the reference value
and the relative error of the mean of the given sg renders against the two 65536-spp references (issue 12, session
24, frostedskew24: where the shadow's bias sits, e.g. main's 2 x 8192 spp: the caustic's peak pixel (22, 20) -7 %,
its neighbours +2 / +4 %, a halo 3 pixels out +12..+27 %).
    python3 benchmarks/frosted_shadow_by_pixel.py REFS_DIR a_11.exr a_12.exr ...     (from the repository root)
REFS_DIR holds ref_7919.exr and ref_8932.exr (e.g. /tmp/frostedcost20/refs).
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
