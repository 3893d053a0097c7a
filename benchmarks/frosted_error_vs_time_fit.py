#!/usr/bin/python3
"""The speed-up S of `glimmer bench error-vs-time --material frosted` when a method's ladder ends before the RMSE
the reference method (path) reaches in --at-seconds (docs/frosted_glass.md, "Thirteenth session: the fair bench").

Per method and region, MSE(t) = b^2 + k / t (b: its bias, k / t: its noise) fitted to its ladder by least squares
on the relative error (each rung weighted by 1 / MSE); path's RMSE at --at-seconds e as the bench extrapolates it
(the mean of RMSE^2 x seconds over its last 3 rungs: an unbiased method). Then

    G = k_path / k_method                 (efficiency per unit of variance, bias aside)
    S = T / t(e) = G (1 - b^2 / e^2)      (0 when b >= e: the method never gets there)

    python3 benchmarks/frosted_error_vs_time_fit.py docs/frosted_error_vs_time_caustic_regions.csv --at-seconds 60

Input: a bench CSV (method,samples,seconds,rmse) or a regions CSV (…,region,pixels,rmse,rmse_raw). The fit of b is
not meaningful for heavy-tailed noise (path's MIS fireflies): read b next to the curves.
"""
import argparse
import csv
import math

import numpy as np


def fit(points):
    """(b^2, k) of MSE = b^2 + k / t, weighted by 1 / MSE; b^2 clamped at 0."""
    t = np.array([p[0] for p in points])
    e2 = np.array([p[1] ** 2 for p in points])
    a = np.stack([np.ones_like(t), 1.0 / t], 1) / e2[:, None]
    (b2, k), *_ = np.linalg.lstsq(a, np.ones_like(t), rcond=None)
    return max(float(b2), 0.0), float(k)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv")
    ap.add_argument("--at-seconds", type=float, default=60.0)
    ap.add_argument("--reference", default="path")
    a = ap.parse_args()
    regions = {}
    with open(a.csv, newline="") as f:
        for r in csv.DictReader(f):
            rows = regions.setdefault(r.get("region", "all"), {})
            rows.setdefault(r["method"], []).append((float(r["seconds"]), float(r["rmse"])))
    for region, rows in regions.items():
        path = [p for p in rows.get(a.reference, []) if p[0] > 0 and p[1] > 0]
        if not path:
            continue
        last = path[-3:]
        k_path = sum(e * e * t for t, e in last) / len(last)
        e = math.sqrt(k_path / a.at_seconds)
        line = "%-12s %s %g-s RMSE %.5f |" % (region, a.reference, a.at_seconds, e)
        for method, points in rows.items():
            points = [p for p in points if p[0] > 0 and p[1] > 0]
            if method == a.reference or len(points) < 3:
                continue
            b2, k = fit(points)
            g = k_path / k if k > 0 else float("inf")
            s = g * (1.0 - b2 / (e * e)) if b2 < e * e else 0.0
            line += " %s: b %.5f (%.2f x), G %.2f, S %.2f |" % (method, math.sqrt(b2), math.sqrt(b2) / e, g, s)
        print(line)


if __name__ == "__main__":
    main()
