"""frostedsolid36: per region (sphere crop), the variance per sample of k1 over main's, summed over the region's
pixel channels, with a paired bootstrap over the seeds (the same seeds for both: resampled together).
usage: python3 paired_ratio.py <spp> <seeds...>   (crop/m_<seed>.exr, crop/k1_<seed>.exr)"""
import importlib.util, os, random, sys
spec = importlib.util.spec_from_file_location(
    "v", os.path.join(os.path.dirname(os.path.abspath(__file__)), "frosted_variance_per_region.py"))
v = importlib.util.module_from_spec(spec); spec.loader.exec_module(v)
spp, seeds = int(sys.argv[1]), sys.argv[2:]
reg = v.regions(os.path.join(os.path.dirname(os.path.abspath(__file__)), "scenes/frosted_fair_caustic_mask_64x40.png"),
                ["lit", "glass", "shadow"])
imgs = {l: [v.combined(f"crop/{l}_{s}.exr") for s in seeds] for l in ("m", "k1")}
keys = sorted(imgs["m"][0])
def name(k):
    n = reg.get(k, "edges")
    return n + ("_L" if k[0] < 32 else "_R")
def varsum(l, idx, region):
    tot = 0.0
    for k in keys:
        if region != "all" and name(k) != region: continue
        for c in range(3):
            xs = [imgs[l][i][k][c] for i in idx]
            m = sum(xs) / len(xs)
            tot += sum((x - m) ** 2 for x in xs) / (len(xs) - 1) * spp
    return tot
random.seed(36)
n = len(seeds)
for region in ("glass_L", "edges_L", "all"):
    full = list(range(n))
    r0 = varsum("k1", full, region) / varsum("m", full, region)
    boots = []
    for _ in range(200):
        idx = [random.randrange(n) for _ in range(n)]
        if len(set(idx)) < 2: continue
        boots.append(varsum("k1", idx, region) / varsum("m", idx, region))
    boots.sort()
    lo, hi = boots[int(0.05 * len(boots))], boots[int(0.95 * len(boots)) - 1]
    print(f"{region:8s} k1/main variance {r0:.3f}  (paired bootstrap over {n} seeds, 90 %: {lo:.3f} .. {hi:.3f})")
