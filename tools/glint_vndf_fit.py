#!/usr/bin/env python3
"""Coefficients of the polynomials in plugin/tables/glint_beckmann_vndf.h.

Each is a Chebyshev interpolant at n + 1 nodes on [-1, 1] of a mapped variable,
converted to monomials exactly (fractions) and printed lowest degree first
(the coefficient arrays that glimmer::horner evaluates), with the maximum relative error of the double Horner form on a
fine grid. Pure Python (math.erfc), no numpy.
  erfcx  : erfcx(z) = exp(z^2) erfc(z), z in [0, 8], variable s = 12 / (4 + z) - 2
           (t = 4 / (4 + z) in [1/3, 1]); degree 14.
  erfinv1: erfinv(x) / x with w = -log(1 - x^2) in [0, 6.25], variable w / 3.125 - 1; degree 16.
  erfinv2: the same with r = sqrt(w) in [2.5, 4.5] (w <= 20.25: 1 - |x| >= 2e-9), variable r - 3.5; degree 14.
For erfinv the printed error is also that of erfc(|y|) against the tail mass 1 - |x| (what the sampler's
CDF sees).
usage: tools/glint_vndf_fit.py erfcx|erfinv1|erfinv2 [degree]
"""
import math
import sys
from fractions import Fraction


def erfcx(z):
    return math.exp(z * z) * math.erfc(z)


def erfinv_tail(w):
    """(|y|, |x|) with erfc(|y|) = 1 - |x| and w = -log(1 - x^2)."""
    r = math.sqrt(-math.expm1(-w))           # |x|
    tail = math.exp(-w) / (1.0 + r)          # 1 - |x| without cancellation
    lo, hi = 0.0, 30.0
    for _ in range(200):                     # bisection, then Newton to the last bit
        mid = 0.5 * (lo + hi)
        if math.erfc(mid) > tail:
            lo = mid
        else:
            hi = mid
    y = 0.5 * (lo + hi)
    for _ in range(3):
        y += (math.erfc(y) - tail) / (2.0 / math.sqrt(math.pi) * math.exp(-y * y))
    return y, r


def erfinv_ratio(w):
    if w < 1e-300:
        return math.sqrt(math.pi) / 2.0
    y, r = erfinv_tail(w)
    return y / r


CASES = {
    # name: (f of the mapped variable v in [-1, 1], default degree, grid of v -> check value)
    "erfcx": (lambda v: erfcx(4.0 * (1.0 - (v + 2.0) / 3.0) / ((v + 2.0) / 3.0)), 14),
    "erfinv1": (lambda v: erfinv_ratio(3.125 * (v + 1.0)), 16),
    "erfinv2": (lambda v: erfinv_ratio((v + 3.5) ** 2), 14),
}


def monomials(f, n):
    nodes = n + 1
    xs = [math.cos(math.pi * (j + 0.5) / nodes) for j in range(nodes)]
    fs = [f(x) for x in xs]
    cheb = [2.0 / nodes * sum(fs[j] * math.cos(math.pi * k * (j + 0.5) / nodes) for j in range(nodes))
            for k in range(nodes)]
    cheb[0] /= 2
    t = [[Fraction(1)], [Fraction(0), Fraction(1)]]
    for k in range(2, n + 1):
        a = [Fraction(0)] + [2 * c for c in t[k - 1]]
        b = t[k - 2] + [Fraction(0)] * (len(a) - len(t[k - 2]))
        t.append([a[i] - b[i] for i in range(len(a))])
    mono = [Fraction(0)] * (n + 1)
    for k in range(n + 1):
        for i, c in enumerate(t[k]):
            mono[i] += Fraction(cheb[k]) * c
    return [float(c) for c in mono]


def main():
    name = sys.argv[1]
    f, n = CASES[name]
    if len(sys.argv) > 2:
        n = int(sys.argv[2])
    coef = monomials(f, n)
    err = tail_err = 0.0
    for i in range(4001):
        v = -1.0 + 2.0 * i / 4000
        p = 0.0
        for a in reversed(coef):
            p = p * v + a
        ref = f(v)
        err = max(err, abs(p / ref - 1.0))
        if name != "erfcx":
            w = 3.125 * (v + 1.0) if name == "erfinv1" else (v + 3.5) ** 2
            if w > 0.0:
                y, r = erfinv_tail(w)
                tail_err = max(tail_err, abs(math.erfc(p * r) / math.erfc(y) - 1.0))
    extra = f", erfc(|y|) relative {tail_err:.3g}" if name != "erfcx" else ""
    print(f"{name} degree {n}: max relative error {err:.3g}{extra}")
    print(", ".join(repr(a) for a in coef))


if __name__ == "__main__":
    main()
