//! PID tuning by convex-concave programming against an exhaustive search on the classic
//! benchmark plant P(s) = 1/(s + 1)³ (Åström & Hägglund; Hast et al. 2013), continuous PID
//! C(s) = kp + ki/s + kd·s/(1 + Tf·s).

use design::tune::PidTuning;
use num_complex::Complex64;

const TF: f64 = 0.05;

fn problem(ms: f64, mt: f64, bandwidth_hz: f64) -> PidTuning {
    let freq_hz: Vec<f64> = (0..400)
        .map(|i| libm::pow(10f64, -3.0 + 4.0 * i as f64 / 399.0))
        .collect();
    let s = |f: f64| Complex64::new(0.0, 2.0 * std::f64::consts::PI * f);
    PidTuning {
        plant: freq_hz
            .iter()
            .map(|&f| 1.0 / (s(f) + 1.0).powi(3))
            .collect(),
        basis: freq_hz
            .iter()
            .map(|&f| {
                let s = s(f);
                [Complex64::new(1.0, 0.0), 1.0 / s, s / (1.0 + TF * s)]
            })
            .collect(),
        freq_hz,
        ms,
        mt,
        bandwidth_hz,
        upper: [10.0, 10.0, 10.0],
    }
}

/// Closed-loop stability from the characteristic polynomial
/// s(1 + Tf s)(s + 1)³ + kp s(1 + Tf s) + ki (1 + Tf s) + kd s² (roots of its companion matrix).
fn stable(k: &[f64; 3]) -> bool {
    let [kp, ki, kd] = *k;
    // (s + 1)³ = s³ + 3s² + 3s + 1; times s(1 + Tf s) = Tf s² + s. Coefficients, highest first.
    let cubic = [1.0, 3.0, 3.0, 1.0];
    let mut c = [0.0; 6];
    for (i, a) in cubic.iter().enumerate() {
        c[i] += TF * a; // Tf s² · s^(3−i)
        c[i + 1] += a; // s · s^(3−i)
    }
    c[3] += kp * TF + kd;
    c[4] += kp + ki * TF;
    c[5] += ki;
    let n = 5;
    let companion = nalgebra::DMatrix::from_fn(n, n, |i, j| {
        if i == 0 {
            -c[j + 1] / c[0]
        } else if j + 1 == i {
            1.0
        } else {
            0.0
        }
    });
    companion.complex_eigenvalues().iter().all(|z| z.re < 0.0)
}

/// The largest feasible ki for fixed (kp, kd): scanned on a log grid (feasibility need not be
/// monotonic in ki), then refined by bisection above the best grid point.
fn best_ki(p: &PidTuning, kp: f64, kd: f64) -> f64 {
    let ok = |ki: f64| {
        let (s, t, tb) = p.evaluate(&[kp, ki, kd]);
        s <= p.ms && t <= p.mt && tb >= std::f64::consts::FRAC_1_SQRT_2 && stable(&[kp, ki, kd])
    };
    let grid: Vec<f64> = (0..=120)
        .map(|i| libm::pow(10f64, -3.0 + 4.0 * i as f64 / 120.0))
        .collect();
    let Some(i) = (0..grid.len()).rev().find(|&i| ok(grid[i])) else {
        return 0.0;
    };
    let (mut lo, mut hi) = (grid[i], grid.get(i + 1).copied().unwrap_or(grid[i]));
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if ok(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

#[test]
fn reaches_the_exhaustive_search_optimum_and_keeps_every_bound() {
    let p = problem(1.4, 1.3, 0.05);
    let tuned = p.solve([0.1, 0.05, 0.0], 200).unwrap();
    let [kp, ki, kd] = tuned.gains;
    let (s, t, tb) = p.evaluate(&tuned.gains);
    assert!(
        s <= 1.4 * (1.0 + 1e-6) && t <= 1.3 * (1.0 + 1e-6),
        "|S| {s}, |T| {t}"
    );
    assert!(tb >= std::f64::consts::FRAC_1_SQRT_2 * (1.0 - 1e-6));
    assert!(stable(&tuned.gains), "the tuned loop is stable");
    // Exhaustive search over kp ∈ [0, 4], kd ∈ [0, 6] on a 41 × 41 grid.
    let mut best = (0.0, 0.0, 0.0);
    for i in 0..=40 {
        for j in 0..=40 {
            let (kp, kd) = (4.0 * i as f64 / 40.0, 6.0 * j as f64 / 40.0);
            let ki = best_ki(&p, kp, kd);
            if ki > best.0 {
                best = (ki, kp, kd);
            }
        }
    }
    assert!(
        ki >= 0.99 * best.0,
        "convex-concave ki {ki} (kp {kp}, kd {kd}) vs exhaustive {best:?}"
    );
    // The grid search cannot beat the optimum by more than its resolution allows.
    assert!(ki <= 1.05 * best.0, "ki {ki} vs exhaustive {best:?}");
}

#[test]
fn an_unreachable_bandwidth_is_reported_not_faked() {
    // 1/(s+1)³ cannot close a loop at 2 Hz (12.6 rad/s) with |S| ≤ 1.4.
    let p = problem(1.4, 1.3, 2.0);
    let e = p.solve([0.1, 0.05, 0.0], 200).unwrap_err();
    assert!(
        matches!(e, design::tune::TuneError::Unreachable(db) if db < -3.0),
        "{e}"
    );
}

#[test]
fn a_start_outside_the_bounds_is_refused() {
    let p = problem(1.4, 1.3, 0.05);
    assert!(matches!(
        p.solve([5.0, 5.0, 0.0], 10),
        Err(design::tune::TuneError::InfeasibleStart(..))
    ));
}
