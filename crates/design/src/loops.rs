//! Feedback-loop quantities from frequency responses: gain and phase margins with their
//! crossover frequencies, and the closed-loop functions of thesis eq 5-1..5-3 and 6-9.

use num_complex::Complex64 as C;

/// The four closed-loop functions of plant `P` and controller `K` at one frequency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosedLoopFunctions {
    /// Sensitivity `S = 1/(1 + PK)` (eq 5-1): disturbance at the output → error.
    pub s: C,
    /// Complementary sensitivity `T = PK/(1 + PK)` (eq 5-2): reference → output.
    pub t: C,
    /// Input sensitivity `D = P/(1 + PK)` (eq 5-3): disturbance at the plant input → output.
    pub d: C,
    /// Control sensitivity `R = K/(1 + PK)` (eq 6-9): reference → controller output.
    pub r: C,
}

impl ClosedLoopFunctions {
    /// From `P(jω)` and `K(jω)`.
    pub fn new(p: C, k: C) -> Self {
        let s = 1.0 / (1.0 + p * k);
        ClosedLoopFunctions {
            s,
            t: p * k * s,
            d: p * s,
            r: k * s,
        }
    }
}

/// Stability margins of a loop gain `L` (negative feedback, `1 + L`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Margins {
    /// Frequency of the gain crossover with the smallest phase margin, Hz.
    pub gain_crossover_hz: Option<f64>,
    /// Smallest `180° + ∠L` over all gain crossovers (`|L| = 1`), degrees in (−180, 180].
    pub phase_margin_deg: Option<f64>,
    /// Frequency of the −180° crossing that sets the (upper) gain margin, Hz.
    pub phase_crossover_hz: Option<f64>,
    /// Gain increase to instability: the smallest `−20·log10|L|` over −180° crossings with
    /// `|L| < 1`, dB.
    pub gain_margin_db: Option<f64>,
    /// Gain *reduction* to instability for conditionally stable loops: the largest
    /// `−20·log10|L|` (negative) over −180° crossings with `|L| > 1`, dB.
    pub lower_gain_margin_db: Option<f64>,
}

/// Points of the log grid between `f_lo` and `f_hi` on which the margins look for crossings.
const GRID_POINTS: usize = 4000;

/// The log grid from `f_lo` to `f_hi` (both included) with `loop_gain` at each point, so
/// that each crossing search reads the same evaluations.
fn sampled(loop_gain: &impl Fn(f64) -> C, f_lo: f64, f_hi: f64) -> Vec<(f64, C)> {
    let ratio = libm::pow(f_hi / f_lo, 1.0 / GRID_POINTS as f64);
    let mut f = f_lo;
    (0..=GRID_POINTS)
        .map(|_| {
            let at = (f, loop_gain(f));
            f *= ratio;
            at
        })
        .collect()
}

/// All roots of `g` (a function of `L`) between the points of `grid` where it changes sign,
/// refined by bisection on `loop_gain`.
fn roots(grid: &[(f64, C)], loop_gain: &impl Fn(f64) -> C, g: impl Fn(C) -> f64) -> Vec<f64> {
    let mut out = Vec::new();
    for pair in grid.windows(2) {
        let ((a, la), (b, lb)) = (pair[0], pair[1]);
        let (ga, gb) = (g(la), g(lb));
        if ga.signum() != gb.signum() && ga.is_finite() && gb.is_finite() {
            let (mut lo, mut hi, mut glo) = (a, b, ga);
            for _ in 0..80 {
                let mid = (lo * hi).sqrt();
                let gm = g(loop_gain(mid));
                if gm.signum() == glo.signum() {
                    (lo, glo) = (mid, gm);
                } else {
                    hi = mid;
                }
            }
            out.push((lo * hi).sqrt());
        }
    }
    out
}

/// Margins of `loop_gain(f_hz)` between `f_lo` and `f_hi` Hz: every gain crossover and every
/// −180° crossing (`L` real and negative) is found, so resonances and conditionally stable
/// loops are handled.
pub fn margins(loop_gain: impl Fn(f64) -> C, f_lo: f64, f_hi: f64) -> Margins {
    let db = |f: f64| -20.0 * libm::log10(loop_gain(f).norm());
    let pm = |f: f64| 180.0 + loop_gain(f).arg().to_degrees();
    let pm_wrapped = |f: f64| {
        let p = pm(f);
        if p > 180.0 {
            p - 360.0
        } else {
            p
        }
    };
    let grid = sampled(&loop_gain, f_lo, f_hi);
    let gain_cross = roots(&grid, &loop_gain, |l| libm::log(l.norm()));
    let worst_pm = gain_cross
        .iter()
        .map(|&f| (f, pm_wrapped(f)))
        .min_by(|a, b| a.1.total_cmp(&b.1));
    let phase_cross: Vec<f64> = roots(&grid, &loop_gain, |l| l.im)
        .into_iter()
        .filter(|&f| loop_gain(f).re < 0.0)
        .collect();
    let upper = phase_cross
        .iter()
        .map(|&f| (f, db(f)))
        .filter(|x| x.1 > 0.0)
        .min_by(|a, b| a.1.total_cmp(&b.1));
    let lower = phase_cross
        .iter()
        .map(|&f| db(f))
        .filter(|x| *x < 0.0)
        .max_by(f64::total_cmp);
    Margins {
        gain_crossover_hz: worst_pm.map(|x| x.0),
        phase_margin_deg: worst_pm.map(|x| x.1),
        phase_crossover_hz: upper.map(|x| x.0),
        gain_margin_db: upper.map(|x| x.1),
        lower_gain_margin_db: lower,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// Textbook loop L(s) = 2/(s(s+1)(s+2)): phase crossover at ω = √2 with |L| = 1/3
    /// (gain margin 20·log10 3 = 9.542 dB); gain crossover at the root of
    /// ω²(ω²+1)(ω²+4) = 4, phase margin 180° − 90° − atan ω − atan(ω/2).
    #[test]
    fn margins_of_a_textbook_loop() {
        let l = |f: f64| {
            let s = C::new(0.0, 2.0 * PI * f);
            2.0 / (s * (s + 1.0) * (s + 2.0))
        };
        let m = margins(l, 1e-3, 100.0);
        let wpc = 2f64.sqrt();
        assert!((m.phase_crossover_hz.unwrap() - wpc / (2.0 * PI)).abs() < 1e-9);
        assert!((m.gain_margin_db.unwrap() - 20.0 * libm::log10(3f64)).abs() < 1e-9);
        // ω² = x: x(x+1)(x+4) = 4 → solve by bisection independently.
        let (mut lo, mut hi) = (0.1f64, 1.0f64);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if mid * (mid + 1.0) * (mid + 4.0) < 4.0 {
                lo = mid
            } else {
                hi = mid
            }
        }
        let wgc = lo.sqrt();
        assert!((m.gain_crossover_hz.unwrap() - wgc / (2.0 * PI)).abs() < 1e-9);
        let pm = 90.0 - libm::atan(wgc).to_degrees() - libm::atan(wgc / 2.0).to_degrees();
        assert!(
            (m.phase_margin_deg.unwrap() - pm).abs() < 1e-6,
            "{:?} vs {pm}",
            m.phase_margin_deg
        );
    }

    #[test]
    fn closed_loop_functions_identities() {
        let (p, k) = (C::new(0.3, -2.0), C::new(1.5, 0.7));
        let f = ClosedLoopFunctions::new(p, k);
        assert!((f.s + f.t - 1.0).norm() < 1e-15);
        assert!((f.d - p * f.s).norm() < 1e-15 && (f.r * p - f.t).norm() < 1e-15);
    }
}
