#!/usr/bin/env python3
"""Clearcoat: Glimmer's GGX coat vs Cycles 3.4's GTR1 coat, measured on a sphere.

A sphere seen orthographically under a uniform white environment (a furnace): a pixel
sees the surface at mu = cos(theta_o) with density 2 mu on [0, 1]. For each model the
coat's directional albedo R(mu) is estimated by Monte Carlo with half-vectors drawn from
the model's own NDF (the estimator F G (v.h) / (mu_o cos_h) has no D in it, so the tiny
alphas of clearcoat roughness are no problem), then averaged over the sphere.

  Glimmer (render/principled.cpp): colour 0.25 * clearcoat * F_dielectric(mu_o; 1.5) on a GGX
    lobe (alpha = clearcoat_roughness^2, no Fresnel inside: the glossy node is a conductor of
    that colour; height-correlated Smith G2) added on top; the base is not attenuated.
  Cycles 3.4 (kernel/closure/bsdf_microfacet.h, svm_closure.h): weight 0.25 * clearcoat,
    F_dielectric(v.h; 1.5) (cspec0 0.04 = F0 of 1.5), GTR1 D (Burley 2012 eq. 4) with
    alpha = clearcoat_roughness^2, separable Smith G with a fixed alpha of 0.25; the base
    is not attenuated.
Facts (constants, formulas) from those sources; the code is written here.
Usage: tools/clearcoat_gtr1_vs_ggx.py [samples per mu]
"""
import math
import random
import sys


def fresnel_dielectric(cos_i, eta=1.5):
    c = abs(cos_i)
    g2 = eta * eta - 1.0 + c * c
    if g2 <= 0.0:
        return 1.0
    g = math.sqrt(g2)
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return 0.5 * a * a * (1.0 + b * b)


def smith_lambda(mu, alpha):  # GGX Smith Lambda (Walter et al. 2007; Heitz 2014 eq. 72)
    mu = min(max(mu, 1e-7), 1.0)
    tan2 = (1.0 - mu * mu) / (mu * mu)
    return 0.5 * (-1.0 + math.sqrt(1.0 + alpha * alpha * tan2))


def sample_cos_h(gtr1, a2, u):
    if not gtr1:  # D_GGX: tan^2 theta = a2 u / (1 - u)
        return math.sqrt(1.0 / (1.0 + a2 * u / (1.0 - u)))
    # GTR1 (Burley 2012, appendix B): cos^2 theta = (1 - a2^(1-u)) / (1 - a2)
    return math.sqrt(max(0.0, (1.0 - a2 ** (1.0 - u)) / (1.0 - a2)))


def albedo(mu_o, cycles, rough, n, rng):
    alpha = rough * rough
    a2 = alpha * alpha
    vx, vz = math.sqrt(max(0.0, 1.0 - mu_o * mu_o)), mu_o
    total = 0.0
    for _ in range(n):
        ch = sample_cos_h(cycles, a2, rng.random())
        sh = math.sqrt(max(0.0, 1.0 - ch * ch))
        phi = 2.0 * math.pi * rng.random()
        hx, hz = sh * math.cos(phi), ch
        vh = vx * hx + vz * hz
        if vh <= 0.0:
            continue
        mu_i = 2.0 * vh * hz - vz
        if mu_i <= 0.0:
            continue
        if cycles:
            g = 1.0 / (1.0 + smith_lambda(mu_o, 0.25)) / (1.0 + smith_lambda(mu_i, 0.25))
            f = 0.25 * fresnel_dielectric(vh)
        else:
            g = 1.0 / (1.0 + smith_lambda(mu_o, alpha) + smith_lambda(mu_i, alpha))
            f = 1.0
        total += f * g * vh / (mu_o * ch)
    r = total / n
    return r if cycles else 0.25 * r * fresnel_dielectric(mu_o)  # Glimmer's colour 0.25 clearcoat F(N.I)


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 4000
    rng = random.Random(1)
    k = 32  # density 2 mu d mu = d(mu^2): midpoints in mu^2
    mus = [math.sqrt((i + 0.5) / k) for i in range(k)]
    print("sphere (orthographic) under a white furnace, clearcoat = 1, %d samples per mu, %d mu" % (n, k))
    print("both keep the whole base (the coat is added on top)")
    print("%9s %13s %13s %9s %11s" % ("roughness", "glimmer_coat", "cycles_coat", "g/c", "g/c mu=1"))
    for rough in (0.03, 0.1, 0.3, 0.6):
        g = sum(albedo(m, False, rough, n, rng) for m in mus) / k
        c = sum(albedo(m, True, rough, n, rng) for m in mus) / k
        g1, c1 = albedo(1.0, False, rough, n, rng), albedo(1.0, True, rough, n, rng)
        print("%9.2f %13.5f %13.5f %9.3f %11.3f" % (rough, g, c, g / c, g1 / c1))


if __name__ == "__main__":
    main()
