#!/usr/bin/python3
"""Plots the CSV of `glimmer bench error-vs-time --material frosted` (method,samples,seconds,rmse): RMSE against
time on log-log axes, one line per method, each point labelled with its samples per pixel, and the RMSE the path
reference method reaches at --at-seconds (log-log interpolation, as the bench's summary) as a dashed line.

    python3 benchmarks/plot_frosted_error_vs_time.py docs/frosted_error_vs_time.csv \
        -o docs/frosted_error_vs_time.png --at-seconds 8 --title "..."

A `<name>_regions.csv` (bench --regions: method,samples,seconds,region,pixels,rmse,rmse_raw) is plotted one panel
per region given with --region (repeatable; default every region). When the reference method's ladder ends before
--at-seconds, its RMSE there is extrapolated as the bench does (MSE x time constant over its last 3 rungs: an
unbiased method) and drawn dotted.
"""
import argparse
import csv
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_rows(path):
    """{region: {method: [(seconds, rmse, samples)]}}; a plain CSV is the one region "all"."""
    regions = {}
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            rows = regions.setdefault(r.get("region", "all"), {})
            rows.setdefault(r["method"], []).append((float(r["seconds"]), float(r["rmse"]), int(r["samples"])))
    return regions


def extrapolated_error(points, seconds):
    """The bench's extrapolation beyond the ladder: mean of rmse^2 x seconds over the last 3 rungs."""
    last = [p for p in points if p[0] > 0 and p[1] > 0][-3:]
    if not last or last[-1][0] >= seconds:
        return None
    return math.sqrt(sum(e * e * t for t, e, _ in last) / len(last) / seconds)


def error_at_time(points, seconds):
    """Log-log interpolation between the ladder points around `seconds`; None outside the ladder."""
    for (t0, e0, _), (t1, e1, _) in zip(points, points[1:]):
        if t0 <= seconds <= t1 and t1 > t0:
            f = (math.log(seconds) - math.log(t0)) / (math.log(t1) - math.log(t0))
            return math.exp(math.log(e0) + f * (math.log(e1) - math.log(e0)))
    return None


def plot_region(ax, rows, a, region, colours):
    for method, points in rows.items():
        ax.plot([p[0] for p in points], [p[1] for p in points], "o-", label=method, ms=3, color=colours[method])
        for t, e, spp in points:
            ax.annotate(str(spp), (t, e), textcoords="offset points", xytext=(3, 3), fontsize=6)
    if a.at_seconds and a.reference in rows:
        target = error_at_time(rows[a.reference], a.at_seconds)
        style = "--"
        if target is None:
            target, style = extrapolated_error(rows[a.reference], a.at_seconds), ":"
            if target is not None:
                last = rows[a.reference][-1]
                ax.plot([last[0], a.at_seconds], [last[1], target], style, color="gray", lw=0.8)
        if target is not None:
            ax.axhline(target, ls=style, color="gray", lw=0.8)
            ax.annotate("%s at %g s: %.4g" % (a.reference, a.at_seconds, target), (a.at_seconds, target),
                        textcoords="offset points", xytext=(-90, -12), fontsize=7, color="gray")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(a.xlabel)
    ax.set_ylabel("RMSE vs the path reference")
    if region:
        ax.set_title(region, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv")
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--at-seconds", type=float, default=None)
    ap.add_argument("--reference", default="path")
    ap.add_argument("--title", default="frosted glass: RMSE vs time")
    ap.add_argument("--xlabel", default="seconds")
    ap.add_argument("--region", action="append", help="regions CSV: a region to plot (repeatable; default all)")
    a = ap.parse_args()
    regions = read_rows(a.csv)
    names = a.region or list(regions)
    fig, axes = plt.subplots(1, len(names), figsize=(7 if len(names) == 1 else 4.2 * len(names), 4.5), dpi=110,
                             squeeze=False)
    methods = list(dict.fromkeys(m for name in names for m in regions[name]))
    colours = {m: "C%d" % k for k, m in enumerate(methods)}  # one colour per method in every panel
    for ax, name in zip(axes[0], names):
        plot_region(ax, regions[name], a, name if len(names) > 1 or name != "all" else None, colours)
    fig.suptitle(a.title, fontsize=10)
    fig.tight_layout()
    fig.savefig(a.output)
    print("wrote", a.output)


if __name__ == "__main__":
    main()
