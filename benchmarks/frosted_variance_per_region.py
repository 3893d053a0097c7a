#!/usr/bin/python3
"""Per-region variance per sample of glimmer renders, and the total-effect variance of one random decision
(docs/history/frosted_glass_sessions.md, "Seventeenth session: sg's noise gain"). Pure Python; reads the EXRs and the
region mask
with `oiiotool --dumpdata`. Regions: a mask image whose pixels are 0 or 1 per channel (id = R + 2 G + 4 B, named
by --names; anything else 'edges'), as `glimmer bench error-vs-time --regions <mask>`.

  variance: the same scene and spp on two or more seeds (A.exr B.exr ...): per region the mean over its pixel
            values (Combined RGB) of their sample variance x spp (one sample's variance), and, with --references,
            the mean offset and the rms bias (the renders' mean against the references' mean, both noises taken
            out) as bench_error.h does, with the standard error of bias^2 (session 31: the spread over the region's
            pixels of each pixel's bias^2 estimate / sqrt(pixels)) and z = bias^2 / its standard error: a bias_rms
            with z < 2 is not told apart from the noise (the references' noise, estimated from 2 images, dominates
            the small glass regions); off_z: the mean offset / its standard error (the same spread of the per-pixel
            offsets), the more sensitive test of a bias of one sign over the region
      python3 benchmarks/frosted_variance_per_region.py variance 1024 sg_11.exr sg_12.exr \\
          --mask benchmarks/scenes/frosted_fair_caustic_mask_64x40.png --references ref_7919.exr,ref_8932.exr
  pairs:    one seed rendered twice, the second time with one decision re-drawn (the diagnostic build of
            benchmarks/frosted_decomposition_salts.patch, GLIMMER_DECOMP_SALT=<bit>): mean((A - B)^2) / 2 x spp per
            region, that decision's total-effect variance E[Var(X | every other number)]
      python3 benchmarks/frosted_variance_per_region.py pairs 1024 base.exr walk=salt4.exr front=salt8.exr --mask M
            --split-x also splits the pairs' regions (session 32); --share prints each region's part of the frame's
            figure (its values' sum over all values' sum: the pixel-weighted budget). Bits of the patch (refreshed in
            session 34 for main f95e614): 1 the exit direction (the solid's leftover number not used), 2 the solid's
            walk inside (its first roulette number re-drawn too), 4 the pane's walks, 8 the closure's numbers, 16 the
            host's light sample / lamp integral at the exit, 32 path's exit trials, 64 z alone, 128 x, y alone, 256
            the split's face pick, 512 the split's extra front samples and walks, 1024 the floor view's origin jitter
"""
import argparse
import re
import subprocess


def dump(path, channels=None):
    """{(x, y): [values]} of `channels` (all when None) of an image, through oiiotool."""
    out = subprocess.run(["oiiotool", "--dumpdata", path], check=True, capture_output=True, text=True).stdout
    idx = None
    if channels:
        info = subprocess.run(["oiiotool", "--info", "-v", path], check=True, capture_output=True, text=True).stdout
        names = [c.strip() for c in re.search(r"channel list: (.*)", info).group(1).split(",")]
        idx = [names.index(c) for c in channels]
    px = {}
    for m in re.finditer(r"Pixel \((\d+), (\d+)\): (.*)", out):
        text = m.group(3)
        v = text.split("(")[-1].rstrip(")").split() if "(" in text else text.split()  # 8-bit: the floats in ()
        v = [float(x) for x in v]
        px[(int(m.group(1)), int(m.group(2)))] = [v[i] for i in idx] if idx else v[:3]
    return px


def combined(path):
    return dump(path, ["ViewLayer.Combined." + c for c in "RGB"])


def regions(mask, names):
    reg = {}
    for k, v in dump(mask).items():
        if all(abs(c) < 1e-3 or abs(c - 1) < 1e-3 for c in v):
            i = sum(1 << j for j, c in enumerate(v) if abs(c - 1) < 1e-3)
            reg[k] = names[i] if i < len(names) else "id%d" % i
        else:
            reg[k] = "edges"
    return reg


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=["variance", "pairs"])
    ap.add_argument("spp", type=float)
    ap.add_argument("images", nargs="+")
    ap.add_argument("--mask", required=True)
    ap.add_argument("--names", default="lit,glass,shadow", help="names of the mask ids 0, 1, 2, ...")
    ap.add_argument("--references", default="", help="comma list of reference EXRs (variance mode: bias)")
    ap.add_argument("--split-x", type=int, default=0,
                    help="also report each region's pixels left (<name>_L) and right (<name>_R) of this column "
                         "(frosted_fair_caustic at 64x40: 32 separates the sphere's side from the pane's)")
    ap.add_argument("--share", action="store_true",
                    help="pairs: also print each region's share of the frame's figure (pixel-weighted: its values' "
                         "sum over all values' sum; session 32)")
    a = ap.parse_args()
    reg = regions(a.mask, a.names.split(","))
    order = ["all"] + sorted(set(reg.values()) - {"edges"}) + ["edges"]
    side = {}
    if a.split_x > 0:
        names = sorted(set(reg.values()) - {"edges"})
        order += [n + s for n in names for s in ("_L", "_R")]
        side = {k: r + ("_L" if k[0] < a.split_x else "_R") for k, r in reg.items() if r != "edges"}
    if a.mode == "pairs":
        base = combined(a.images[0])
        print("%-12s" % "decision" + "".join("%11s" % n for n in order))
        for lab in a.images[1:]:
            label, path = lab.split("=", 1)
            other = combined(path)
            acc = {n: [0.0, 0] for n in order}
            for k, r in reg.items():
                if k not in base or k not in other:
                    continue
                for c in range(3):
                    d = (base[k][c] - other[k][c]) ** 2 / 2
                    for n in ("all", r) + ((side[k],) if k in side else ()):
                        acc[n][0] += d
                        acc[n][1] += 1
            print("%-12s" % label + "".join("%11.5f" % (acc[n][0] / acc[n][1] * a.spp) if acc[n][1] else "%11s" % "-"
                                            for n in order))
            if a.share:  # each region's part of the frame's ("all") figure: its sum over all's values
                print("%-12s" % (label + "%") + "".join(
                    "%10.1f%%" % (100 * acc[n][0] / acc["all"][0]) if acc["all"][0] else "%11s" % "-" for n in order))
        return
    imgs = [combined(p) for p in a.images]
    refs = [combined(p) for p in a.references.split(",")] if a.references else []
    n = len(imgs)
    acc = {r: [0.0, 0.0, 0.0, 0, 0.0] for r in order}  # variance, offset, bias^2, values, reference sum
    per_pixel = {r: [] for r in order}  # each pixel's bias^2 estimate (mean over its channels): the standard error
    per_pixel_off = {r: [] for r in order}  # each pixel's offset (mean over its channels)
    for k, r in reg.items():
        if any(k not in im for im in imgs + refs):  # crops (--region renders): only the pixels they hold
            continue
        pixel_b2 = pixel_off = 0.0
        for c in range(3):
            vals = [im[k][c] for im in imgs]
            mean = sum(vals) / n
            var = sum((v - mean) ** 2 for v in vals) / (n - 1)
            off = b2 = rm = 0.0
            if refs:
                rv = [ref[k][c] for ref in refs]
                rm = sum(rv) / len(rv)
                rvar = sum((v - rm) ** 2 for v in rv) / (len(rv) - 1) / len(rv) if len(rv) > 1 else 0.0
                off = mean - rm
                b2 = off * off - var / n - rvar
                pixel_b2 += b2 / 3
                pixel_off += off / 3
            for name in ("all", r) + ((side[k],) if k in side else ()):
                s = acc[name]
                s[0] += var
                s[1] += off
                s[2] += b2
                s[3] += 1
                s[4] += rm
        for name in ("all", r) + ((side[k],) if k in side else ()):
            per_pixel[name].append(pixel_b2)
            per_pixel_off[name].append(pixel_off)
    print("%-8s %7s %12s %10s %10s %10s %10s %9s %6s %6s" % ("region", "values", "var/sample", "offset", "bias_rms",
                                                             "ref_mean", "bias^2", "b^2_se", "z", "off_z"))

    def mean_se(p):
        m = sum(p) / len(p)
        return m, (sum((x - m) ** 2 for x in p) / (len(p) - 1) / len(p)) ** 0.5 if len(p) > 1 else 0.0
    for r in order:
        s = acc[r]
        if s[3]:
            _, se = mean_se(per_pixel[r])
            off, off_se = mean_se(per_pixel_off[r])
            z = "%6.2f" % (s[2] / s[3] / se) if refs and se > 0 else "%6s" % "-"
            off_z = "%6.2f" % (off / off_se) if refs and off_se > 0 else "%6s" % "-"
            print("%-8s %7d %12.5f %10.5f %10.5f %10.5f %10.3g %9.2g %s %s" % (
                r, s[3], s[0] / s[3] * a.spp, s[1] / s[3], max(s[2] / s[3], 0.0) ** 0.5, s[4] / s[3], s[2] / s[3],
                se, z, off_z))


if __name__ == "__main__":
    main()
