#!/usr/bin/env python3
"""Independent thin-film reflectances for the spectral KHR_materials_iridescence test
(src/material/iridescence.rs `spectral_film_is_the_airy_reflectance`).

Two computations, neither sharing code with the renderer:

* normal incidence: the textbook reflectance of one dielectric film (Born & Wolf §1.6.4),
  r = (r12 + r23 e^{2iβ}) / (1 + r12 r23 e^{2iβ}), r_ij = (n_i − n_j)/(n_i + n_j),
  β = 2π n2 d / λ. At normal incidence the extension's Schlick interfaces are exact, so its
  model must equal this;
* oblique incidence: the extension's own model (glTF KHR_materials_iridescence, Belcour &
  Barla 2017) written as the complex amplitude sum
  r = r12 + T121 r23 e^{iδ} / (1 − r21 r23 e^{iδ}) with Schlick interface reflectances,
  phase shifts 0 or π, δ = 2π · 2 n2 d cos θ2 / λ, the base IOR from its F0.

Run: python3 scripts/references/thin_film_airy.py  (a Python with numpy; prints the Rust table).
"""
import numpy as np


def normal_incidence(n2, n3, d, lam):
    r12 = (1.0 - n2) / (1.0 + n2)
    r23 = (n2 - n3) / (n2 + n3)
    e = np.exp(2j * 2.0 * np.pi * n2 * d / lam)
    return abs((r12 + r23 * e) / (1.0 + r12 * r23 * e)) ** 2


def extension_model(n2, f0_base, d, cos1, lam):
    schlick = lambda f0, c: f0 + (1.0 - f0) * (1.0 - c) ** 5
    f0 = lambda a, b: ((a - b) / (a + b)) ** 2
    cos2 = np.sqrt(1.0 - (1.0 - cos1 ** 2) / n2 ** 2)
    R12 = schlick(f0(n2, 1.0), cos1)
    n3 = (1.0 + np.sqrt(f0_base)) / (1.0 - np.sqrt(f0_base))
    R23 = schlick(f0(n3, n2), cos2)
    p12 = np.pi if n2 < 1.0 else 0.0
    p21 = np.pi - p12
    p23 = np.pi if n3 < n2 else 0.0
    delta = 2.0 * np.pi * 2.0 * n2 * d * cos2 / lam
    r12 = np.sqrt(R12) * np.exp(1j * p12)
    r21 = np.sqrt(R12) * np.exp(1j * p21)
    r23 = np.sqrt(R23) * np.exp(1j * p23)
    e = np.exp(1j * delta)
    return abs(r12 + (1.0 - R12) * r23 * e / (1.0 - r21 * r23 * e)) ** 2


# (film IOR, base F0, thickness nm, cos θ1, wavelengths nm)
CASES = [
    (1.33, 0.04, 300.0, 1.0, (420.0, 530.0, 640.0)),
    (2.0, 0.04, 200.0, 1.0, (400.0, 470.0, 610.0)),
    (1.8, ((1.5 - 1.0) / 2.5) ** 2, 650.0, 1.0, (450.0, 500.0, 700.0)),
    (1.6, 0.3, 400.0, 0.6, (450.0, 550.0, 650.0)),
    (1.5, 0.9, 250.0, 0.3, (380.0, 555.0, 780.0)),
    (1.2, 0.5, 900.0, 0.8, (411.0, 512.0, 733.0)),
]

for n2, fb, d, c, lams in CASES:
    if c == 1.0:
        n3 = (1.0 + np.sqrt(fb)) / (1.0 - np.sqrt(fb))
        vals = [normal_incidence(n2, n3, d, l) for l in lams]
        # the two computations agree where both apply
        assert all(abs(v - extension_model(n2, fb, d, 1.0, l)) < 1e-12 for v, l in zip(vals, lams))
    else:
        vals = [extension_model(n2, fb, d, c, l) for l in lams]
    print(f"    ({n2!r}, {round(fb, 9)!r}, {d!r}, {c!r}, [{', '.join(f'{l!r}' for l in lams)}], "
          f"[{', '.join(f'{v:.7f}' for v in vals)}]),")
