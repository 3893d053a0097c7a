#!/usr/bin/python3
"""Plots the CSV of `glimmer bench error-vs-time --material frosted` (method,samples,seconds,rmse): RMSE against
time on log-log axes, one line per method, each point labelled with its samples per pixel, and the RMSE the path
reference method reaches at --at-seconds (log-log interpolation, as the bench's summary) as a dashed line.

    python3 benchmarks/plot_frosted_error_vs_time.py docs/frosted_error_vs_time.csv \
        -o docs/frosted_error_vs_time.png --at-seconds 8 --title "..."
"""
import argparse
import csv
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_rows(path):
    rows = {}
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            rows.setdefault(r["method"], []).append((float(r["seconds"]), float(r["rmse"]), int(r["samples"])))
    return rows


def error_at_time(points, seconds):
    """Log-log interpolation between the ladder points around `seconds`; None outside the ladder."""
    for (t0, e0, _), (t1, e1, _) in zip(points, points[1:]):
        if t0 <= seconds <= t1 and t1 > t0:
            f = (math.log(seconds) - math.log(t0)) / (math.log(t1) - math.log(t0))
            return math.exp(math.log(e0) + f * (math.log(e1) - math.log(e0)))
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv")
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--at-seconds", type=float, default=None)
    ap.add_argument("--reference", default="path")
    ap.add_argument("--title", default="frosted glass: RMSE vs time")
    ap.add_argument("--xlabel", default="seconds")
    a = ap.parse_args()
    rows = read_rows(a.csv)
    fig, ax = plt.subplots(figsize=(7, 4.5), dpi=110)
    for method, points in rows.items():
        ax.plot([p[0] for p in points], [p[1] for p in points], "o-", label=method)
        for t, e, spp in points:
            ax.annotate(str(spp), (t, e), textcoords="offset points", xytext=(4, 4), fontsize=7)
    if a.at_seconds and a.reference in rows:
        target = error_at_time(rows[a.reference], a.at_seconds)
        if target is not None:
            ax.axhline(target, ls="--", color="gray", lw=0.8)
            ax.annotate("%s at %g s: RMSE %.4f" % (a.reference, a.at_seconds, target), (a.at_seconds, target),
                        textcoords="offset points", xytext=(4, -12), fontsize=8, color="gray")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(a.xlabel)
    ax.set_ylabel("RMSE vs the path reference")
    ax.set_title(a.title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(a.output)
    print("wrote", a.output)


if __name__ == "__main__":
    main()
