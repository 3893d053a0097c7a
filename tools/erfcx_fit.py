#!/usr/bin/env python3
"""Coefficients of glint's erfcx polynomial (plugin/tables/glint_beckmann_vndf.h).

erfcx(z) = exp(z^2) erfc(z) on z in [0, 8] as a polynomial in s = 12 / (4 + z) - 2
(t = 4 / (4 + z) in [1/3, 1] mapped to [-1, 1]): Chebyshev interpolation at n + 1
nodes, converted to monomials exactly (fractions), printed highest degree first
(Horner order) with the maximum relative error of the double Horner form on a
20001-point grid of z. Pure Python (math.erfc), no numpy.
usage: tools/erfcx_fit.py [degree, default 14]
"""
import math
import sys
from fractions import Fraction


def erfcx(z):
    return math.exp(z * z) * math.erfc(z)


def z_of_s(s):
    t = 1.0 / 3.0 + (s + 1.0) / 3.0
    return 4.0 * (1.0 - t) / t


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 14
    nodes = n + 1
    xs = [math.cos(math.pi * (j + 0.5) / nodes) for j in range(nodes)]
    fs = [erfcx(z_of_s(x)) for x in xs]
    cheb = [2.0 / nodes * sum(fs[j] * math.cos(math.pi * k * (j + 0.5) / nodes) for j in range(nodes))
            for k in range(nodes)]
    cheb[0] /= 2
    # T_k as exact monomial coefficient lists.
    t = [[Fraction(1)], [Fraction(0), Fraction(1)]]
    for k in range(2, n + 1):
        a = [Fraction(0)] + [2 * c for c in t[k - 1]]
        b = t[k - 2] + [Fraction(0)] * (len(a) - len(t[k - 2]))
        t.append([a[i] - b[i] for i in range(len(a))])
    mono = [Fraction(0)] * (n + 1)
    for k in range(n + 1):
        for i, c in enumerate(t[k]):
            mono[i] += Fraction(cheb[k]) * c
    coef = [float(c) for c in mono]

    def horner(s):
        v = 0.0
        for a in reversed(coef):
            v = v * s + a
        return v

    err = 0.0
    for i in range(20001):
        z = 8.0 * i / 20000
        s = 12.0 / (4.0 + z) - 2.0
        err = max(err, abs(horner(s) / erfcx(z) - 1.0))
    print(f"degree {n}: max relative error {err:.3g} on z in [0, 8]")
    for a in reversed(coef):
        print(f"{a!r},")


if __name__ == "__main__":
    main()
