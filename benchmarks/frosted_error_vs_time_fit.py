#!/usr/bin/python3
"""The speed-up S of `glimmer bench error-vs-time --material frosted` when a method's ladder ends before the RMSE
the reference method (path) reaches in --at-seconds (docs/history/frosted_glass_sessions.md, "Thirteenth session:
the fair bench").

Per method and region, MSE(t) = b^2 + k / t (b: its bias, k / t: its noise) fitted to its ladder by least squares
on the relative error (each rung weighted by 1 / MSE); path's RMSE at --at-seconds e as the bench extrapolates it
(the mean of RMSE^2 x seconds over its last 3 rungs: an unbiased method). Then

    G = k_path / k_method                 (efficiency per unit of variance, bias aside)
    S = T / t(e) = G (1 - b^2 / e^2)      (0 when b >= e: the method never gets there)

    python3 benchmarks/frosted_error_vs_time_fit.py docs/frosted_error_vs_time_caustic_regions.csv --at-seconds 60

Input: a bench CSV (method,samples,seconds,rmse) or a regions CSV (…,region,pixels,rmse,rmse_raw). The fit of b is
not meaningful for heavy-tailed noise (path's MIS fireflies): read b next to the curves. The bench's rmse already
has each region's own reference noise taken out (not the whole image's); "ref noise" prints it (from rmse_raw).

A regions CSV of a multi-seed bench (--seed S --seeds N >= 2, session 31: columns seeds,variance,bias2 per rung)
also gives the split directly ("direct:"): k = the mean over the rungs of variance x t (one image's noise x its
time), b^2 = the rungs' bias2 weighted by t^2 (its estimate's noise falls as 1 / t), with the standard error of
that weighted mean from the rungs' scatter (+-); G and S as above with path's own direct k. b is significant only
when b^2 is well above its +-.

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


def direct(points):
    """(k, b^2, standard error of b^2) from rungs (t, variance, bias2): k = mean(variance x t), b^2 = the t^2-weighted
    mean of bias2 and its standard error from the weighted scatter (None with fewer than 2 rungs)."""
    k = sum(v * t for t, v, _ in points) / len(points)
    w = [t * t for t, _, _ in points]
    b2 = sum(wi * b for wi, (_, _, b) in zip(w, points)) / sum(w)
    se = None
    if len(points) >= 2:
        var = sum(wi * (b - b2) ** 2 for wi, (_, _, b) in zip(w, points)) / sum(w) / (len(points) - 1)
        se = math.sqrt(var * sum(wi * wi for wi in w) / sum(w) ** 2 * len(points))
    return k, b2, se


def direct_line(rows, reference, at_seconds):
    """The region's "direct:" figures (multi-seed CSV), or "" when the CSV has no bias2 column."""
    if not rows.get(reference) or any(len(p) < 4 for ps in rows.values() for p in ps):
        return ""
    path = direct([(t, v, b) for t, _, v, b in rows[reference] if t > 0])
    e2 = path[0] / at_seconds
    line = " direct: %s b^2 %.3g +- %.2g |" % (reference, path[1], path[2] or 0.0)
    for method, points in rows.items():
        if method == reference:
            continue
        k, b2, se = direct([(t, v, b) for t, _, v, b in points if t > 0])
        g = path[0] / k if k > 0 else float("inf")
        s = g * (1.0 - max(b2, 0.0) / e2) if b2 < e2 else 0.0
        line += " %s: b %.5f (%.2f x), b^2 %.3g +- %.2g, G %.2f, S %.2f |" % (
            method, math.sqrt(max(b2, 0.0)), math.sqrt(max(b2, 0.0) / e2), b2, se or 0.0, g, s)
    return line


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
            point = (seconds, float(r["rmse"]))
            if r.get("bias2"):  # a multi-seed bench: one image's noise variance and the mean squared bias
                point += (float(r["variance"]), float(r["bias2"]))
            rows.setdefault(r["method"], []).append(point)
            if r["method"] == a.reference and r.get("rmse_raw"):  # the references' noise the bench took out
                noise.setdefault(r.get("region", "all"), []).append(float(r["rmse_raw"]) ** 2 - float(r["rmse"]) ** 2)
    for region, rows in regions.items():
        path = [p[:2] for p in rows.get(a.reference, []) if p[0] > 0 and p[1] > 0]
        if not path:
            continue
        last = path[-3:]
        k_path = sum(e * e * t for t, e in last) / len(last)
        e = math.sqrt(k_path / a.at_seconds)
        line = "%-12s %s %g-s RMSE %.5f |" % (region, a.reference, a.at_seconds, e)
        if region in noise:  # each region's own (bench_error.h region_errors), not the whole image's
            line += " ref noise %.5f |" % math.sqrt(max(sum(noise[region]) / len(noise[region]), 0.0))
        for method, points in rows.items():
            points = [p[:2] for p in points if p[0] > 0 and p[1] > 0]
            if method == a.reference or len(points) < 3:
                continue
            b2, k = fit(points)
            g = k_path / k if k > 0 else float("inf")
            s = g * (1.0 - b2 / (e * e)) if b2 < e * e else 0.0
            line += " %s: b %.5f (%.2f x), G %.2f, S %.2f |" % (method, math.sqrt(b2), math.sqrt(b2) / e, g, s)
        print(line + direct_line(rows, a.reference, a.at_seconds))


if __name__ == "__main__":
    main()
