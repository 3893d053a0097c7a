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
not meaningful for heavy-tailed noise (path's MIS fireflies): read b next to the curves. The bench's rmse already
has each region's own reference noise taken out (not the whole image's); "ref noise" prints it (from rmse_raw).

--instruction-time path=1,sg=1.98,auto=1.47 --seconds-per-sample 0.0024628 (seventeenth session) replaces every rung's
seconds by samples x the method's cost per sample relative to path's (e.g. callgrind instructions per camera path) x
path's seconds per sample: time that the machine's load does not move.
"""
import argparse
import csv
import math


def fit(points):
    """(b^2, k) of MSE = b^2 + k / t, weighted by 1 / MSE, by least squares (its 2x2 normal equations: no numpy);
    b^2 clamped at 0."""
    s11 = s12 = s22 = r1 = r2 = 0.0
    for t, e in points:
        x1, x2 = 1.0 / (e * e), 1.0 / (t * e * e)  # the row of MSE = b^2 + k / t divided by MSE; its target is 1
        s11, s12, s22, r1, r2 = s11 + x1 * x1, s12 + x1 * x2, s22 + x2 * x2, r1 + x1, r2 + x2
    det = s11 * s22 - s12 * s12
    b2, k = (r1 * s22 - s12 * r2) / det, (s11 * r2 - s12 * r1) / det
    return max(b2, 0.0), k


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv")
    ap.add_argument("--at-seconds", type=float, default=60.0)
    ap.add_argument("--reference", default="path")
    ap.add_argument("--instruction-time", default="", help="method=cost relative to path's, comma list (see above)")
    ap.add_argument("--seconds-per-sample", type=float, default=0.0, help="path's, with --instruction-time")
    a = ap.parse_args()
    cost = {m: float(v) for m, v in (x.split("=") for x in a.instruction_time.split(",") if x)}
    regions = {}
    noise = {}
    with open(a.csv, newline="") as f:
        for r in csv.DictReader(f):
            rows = regions.setdefault(r.get("region", "all"), {})
            seconds = float(r["seconds"])
            if cost:
                seconds = int(r["samples"]) * cost[r["method"]] * a.seconds_per_sample
            rows.setdefault(r["method"], []).append((seconds, float(r["rmse"])))
            if r["method"] == a.reference and r.get("rmse_raw"):  # the references' noise the bench took out
                noise.setdefault(r.get("region", "all"), []).append(float(r["rmse_raw"]) ** 2 - float(r["rmse"]) ** 2)
    for region, rows in regions.items():
        path = [p for p in rows.get(a.reference, []) if p[0] > 0 and p[1] > 0]
        if not path:
            continue
        last = path[-3:]
        k_path = sum(e * e * t for t, e in last) / len(last)
        e = math.sqrt(k_path / a.at_seconds)
        line = "%-12s %s %g-s RMSE %.5f |" % (region, a.reference, a.at_seconds, e)
        if region in noise:  # each region's own (bench_error.h region_errors), not the whole image's
            line += " ref noise %.5f |" % math.sqrt(max(sum(noise[region]) / len(noise[region]), 0.0))
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
