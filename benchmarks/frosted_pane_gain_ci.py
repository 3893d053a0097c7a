#!/usr/bin/python3
"""The pane crop's variance ratio between two plugins with a bootstrap interval over seeds (session 38,
frostedpane38; docs/history/frosted_glass_sessions.md "Session 38 (frostedpane38)"). Reads <dir>/A.<seed>.exr and
<dir>/B.<seed>.exr
(benchmarks/frosted_pane_crop_plugins.sh's renders, any number of seeds), takes one region of the mask (default
glass_R: glass at x >= 32, the camera-seen rough pane), and prints each plugin's variance per sample there (the mean
over the region's pixel values of their sample variance over the seeds x spp, as frosted_variance_per_region.py),
the ratio B / A, and with --cost-ratio (B's instructions per camera path / A's) the gain 1 / (var ratio x cost
ratio), each with a 90 % percentile bootstrap interval (seeds resampled with replacement, the same seeds for A and
B: their images share nothing but the seed, so the pairing only keeps the resample's size).
  python3 benchmarks/frosted_pane_gain_ci.py <dir> <spp> "<seeds>" [--cost-ratio R] [--boot 2000]
"""
import argparse
import random
import sys
import os

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from frosted_variance_per_region import combined, regions  # noqa: E402


def region_var(imgs, keys, spp):
    n = len(imgs)
    tot = 0.0
    for k in keys:
        for c in range(3):
            vals = [im[k][c] for im in imgs]
            m = sum(vals) / n
            tot += sum((v - m) ** 2 for v in vals) / (n - 1)
    return tot / (3 * len(keys)) * spp


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir")
    ap.add_argument("spp", type=float)
    ap.add_argument("seeds")
    ap.add_argument("--cost-ratio", type=float, default=0.0)
    ap.add_argument("--boot", type=int, default=2000)
    ap.add_argument("--mask", default=os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                   "scenes/frosted_fair_caustic_mask_64x40.png"))
    a = ap.parse_args()
    seeds = a.seeds.split()
    reg = regions(a.mask, ["lit", "glass", "shadow"])
    A = [combined(os.path.join(a.dir, "A.%s.exr" % s)) for s in seeds]
    B = [combined(os.path.join(a.dir, "B.%s.exr" % s)) for s in seeds]
    keys = [k for k, r in reg.items() if r == "glass" and k[0] >= 32 and all(k in im for im in A + B)]
    va, vb = region_var(A, keys, a.spp), region_var(B, keys, a.spp)
    rng = random.Random(38)
    ratios = []
    for _ in range(a.boot):
        idx = [rng.randrange(len(seeds)) for _ in seeds]
        if len(set(idx)) < 2:
            continue
        ra = region_var([A[i] for i in idx], keys, a.spp)
        rb = region_var([B[i] for i in idx], keys, a.spp)
        ratios.append(rb / ra)
    ratios.sort()
    lo, hi = ratios[int(0.05 * len(ratios))], ratios[int(0.95 * len(ratios)) - 1]
    print("glass_R %d values, %d seeds x %g spp: var/sample A %.5f B %.5f, ratio B/A %.4f (90 %% bootstrap %.4f .. "
          "%.4f)" % (3 * len(keys), len(seeds), a.spp, va, vb, vb / va, lo, hi))
    if a.cost_ratio > 0:
        c = a.cost_ratio
        print("cost ratio B/A %.4f: gain 1/(var x cost) %.3f (90 %%: %.3f .. %.3f)" % (
            c, 1 / (vb / va * c), 1 / (hi * c), 1 / (lo * c)))


if __name__ == "__main__":
    main()
