#!/usr/bin/env python3
"""Cosine-weighted mean albedo Ebar of a white GGX metal (F = 1), the anchor of the metal furnace
in tests/furnace.rs, integrated here with numpy independently of Trayecto's code.

    python3 scripts/references/ggx_metal_mean_albedo.py

f(o, i) = D(h) G2(o, i) / (4 cos_o cos_i), GGX D (Walter et al. 2007), height-correlated Smith
G2 = 1 / (1 + Lambda(o) + Lambda(i)), Lambda = (-1 + sqrt(1 + alpha^2 tan^2)) / 2 (Heitz 2014,
eqs. 72, 99). E(mu) = int f cos_i d omega_i by the midpoint rule on a 2048 x 512 grid in
(cos theta_i, phi_i) (f is symmetric about the plane of o, so phi in [0, pi] doubled), and
Ebar = 2 int E(mu) mu dmu on 64 midpoints. Trayecto's alpha = roughness^2.

Output (numpy 1.26 / 2.x, float64):
  roughness 0.5 (alpha 0.25): Ebar = 0.88232
  roughness 1.0 (alpha 1.0):  Ebar = 0.40915
The test integrates the same formulas with another change of variables (half vectors, GGX
inverse-CDF spacing) and gets 0.88237 and 0.40916.
"""
import numpy as np


def ebar(alpha, n_mu=64, n_c=2048, n_p=512):
    def lam(c):
        return (-1 + np.sqrt(1 + alpha ** 2 * (1 - c * c) / (c * c))) / 2

    c = (np.arange(n_c) + 0.5) / n_c
    p = np.pi * (np.arange(n_p) + 0.5) / n_p
    C, P = np.meshgrid(c, p, indexing="ij")
    S = np.sqrt(1 - C * C)
    i = np.stack([S * np.cos(P), S * np.sin(P), C], -1)
    a2 = alpha ** 2
    total = 0.0
    for a in range(n_mu):
        mu = (a + 0.5) / n_mu
        o = np.array([np.sqrt(1 - mu * mu), 0.0, mu])
        h = i + o
        h /= np.linalg.norm(h, axis=-1, keepdims=True)
        ch = h[..., 2]
        d = a2 / (np.pi * (ch * ch * (a2 - 1) + 1) ** 2)
        g2 = 1 / (1 + lam(mu) + lam(C))
        f = d * g2 / (4 * mu * C)
        e = (f * C).sum() * (1 / n_c) * (2 * np.pi / n_p)
        total += 2 * e * mu / n_mu
    return total


if __name__ == "__main__":
    for r in (0.5, 1.0):
        print(f"roughness {r} (alpha {r * r}): Ebar = {ebar(r * r):.5f}")
