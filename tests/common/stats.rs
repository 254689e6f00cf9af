//! Pearson's chi-square test of sample counts against expected counts, with the regularised
//! incomplete gamma function for its p-value (Numerical Recipes 3rd ed. §6.2, §14.3.1).

/// ln Γ(x) by the Lanczos approximation (g = 7, n = 9).
pub fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised upper incomplete gamma Q(a, x): series below a + 1, Lentz continued fraction above.
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let lg = ln_gamma(a);
    if x < a + 1.0 {
        let (mut sum, mut term, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..10_000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * (-x + a * x.ln() - lg).exp()
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (-x + a * x.ln() - lg).exp() * h
    }
}

/// Pearson's statistic over `(expected, observed)` cells and its p-value. Cells expecting
/// nothing are left out (the caller bounds what lands there); cells expecting fewer than 5
/// samples are pooled into one, so the statistic's chi-square law holds. Returns
/// (statistic, degrees of freedom, p).
pub fn pearson(cells: &[(f64, f64)]) -> (f64, usize, f64) {
    let mut cells: Vec<(f64, f64)> = cells.iter().copied().filter(|c| c.0 > 0.0).collect();
    cells.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap());
    let (mut pool_e, mut pool_o, mut stat, mut dof) = (0.0, 0.0, 0.0, 0usize);
    for &(e, o) in &cells {
        if e < 5.0 {
            pool_e += e;
            pool_o += o;
        } else {
            stat += (o - e) * (o - e) / e;
            dof += 1;
        }
    }
    if pool_e > 0.0 {
        stat += (pool_o - pool_e) * (pool_o - pool_e) / pool_e.max(5.0);
        dof += 1;
    }
    let dof = dof.saturating_sub(1).max(1);
    (stat, dof, gamma_q(dof as f64 / 2.0, stat / 2.0))
}
