#!/usr/bin/python3
"""Per-row means of one region of the caustic bench: a method's renders (mean of its seeds) against references
(mean of theirs), for the pane's gradient by row (issue 12, session 24, frostedpane24;
docs/history/frosted_glass_sessions.md "Session 24 (frostedpane24)").
  python3 tools/frosted_rows.py --mask benchmarks/scenes/frosted_fair_caustic_mask_64x40.png --region glass \\
      --min-x 32 --images a_11.exr,a_12.exr --references ref_7919.exr,ref_8932.exr
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "benchmarks"))
import frosted_variance_per_region as fv  # noqa: E402


def mean_of(paths):
    imgs = [fv.combined(p) for p in paths]
    return {k: [sum(i[k][c] for i in imgs) / len(imgs) for c in range(3)] for k in imgs[0]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mask", required=True)
    ap.add_argument("--region", default="glass")
    ap.add_argument("--names", default="lit,glass,shadow")
    ap.add_argument("--min-x", type=int, default=32)
    ap.add_argument("--images", required=True)
    ap.add_argument("--references", required=True)
    a = ap.parse_args()
    names = a.names.split(",")
    reg = fv.regions(a.mask, names)
    m = mean_of(a.images.split(","))
    r = mean_of(a.references.split(","))
    rows = {}
    for (x, y), name in reg.items():
        if name != a.region or x < a.min_x or (x, y) not in m or (x, y) not in r:
            continue
        rows.setdefault(y, []).append((sum(m[(x, y)]) / 3, sum(r[(x, y)]) / 3))
    print("row  pixels  method_mean  ref_mean  ratio")
    for y in sorted(rows):
        mm = sum(v[0] for v in rows[y]) / len(rows[y])
        rr = sum(v[1] for v in rows[y]) / len(rows[y])
        print("%3d  %6d  %11.5f  %8.5f  %5.3f" % (y, len(rows[y]), mm, rr, mm / rr if rr else float("nan")))


if __name__ == "__main__":
    main()
