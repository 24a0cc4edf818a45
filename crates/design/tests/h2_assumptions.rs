//! H2 synthesis on every plant meeting the textbook assumptions (Zhou, Doyle & Glover §14.5:
//! (A, B2) stabilisable, (C2, A) detectable, D12 and D21 of full rank, no unseen/undriven mode on
//! the stability boundary) — including the ones the Riccati equations find hard: an unstable
//! mode that z does not weight, and one that w does not drive — and the assumption named, with
//! its mode, when a plant does not meet them.

use design::h2::{h2_norm_discrete, h2syn_continuous, h2syn_discrete, GeneralizedPlant, H2Error};
use nalgebra::DMatrix;

fn m(r: usize, c: usize, v: &[f64]) -> DMatrix<f64> {
    DMatrix::from_row_slice(r, c, v)
}

/// Two decoupled modes, `a1` and `a2` (per sample, or rad/s), one input and one measurement
/// reaching both; z weights mode 1 only (`c1z`) or both, w drives mode 2 only (`b1w`) or both.
fn plant(a1: f64, a2: f64, weights: [f64; 2], drives: [f64; 2]) -> GeneralizedPlant {
    GeneralizedPlant {
        a: m(2, 2, &[a1, 0.0, 0.0, a2]),
        b1: m(2, 2, &[drives[0], 0.0, drives[1], 0.0]),
        b2: m(2, 1, &[1.0, 1.0]),
        c1: m(2, 2, &[weights[0], weights[1], 0.0, 0.0]),
        c2: m(1, 2, &[1.0, 1.0]),
        d12: m(2, 1, &[0.0, 0.5]),
        d21: m(1, 2, &[0.0, 0.1]),
    }
}

/// Random controller perturbations never lower the closed-loop norm (the optimum is one).
fn is_optimal(p: &GeneralizedPlant, k: &lti::StateSpace, norm: f64) {
    let mut seed = 11u64;
    let mut rnd = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut compared = 0;
    for _ in 0..200 {
        let mut q = k.clone();
        for v in q.a.iter_mut().chain(q.b.iter_mut()).chain(q.c.iter_mut()) {
            *v += 1e-3 * rnd();
        }
        q.d.iter_mut().for_each(|v| *v += 1e-3 * rnd());
        let cl = p.close(&q);
        if cl.poles().iter().all(|z| z.norm() < 1.0) {
            let n = h2_norm_discrete(&cl).unwrap();
            assert!(n >= norm * (1.0 - 1e-9), "perturbed {n} < optimal {norm}");
            compared += 1;
        }
    }
    assert!(compared > 100, "{compared}");
}

/// An unstable mode (1.2 per sample) that z does not weight, and one that w does not drive:
/// both plants meet the assumptions; both syntheses stabilise and are optimal.
#[test]
fn unweighted_and_undriven_unstable_modes_are_designed_for() {
    for (name, p) in [
        ("unweighted", plant(1.2, 0.5, [0.0, 1.0], [1.0, 1.0])),
        ("undriven", plant(1.2, 0.5, [1.0, 1.0], [0.0, 1.0])),
    ] {
        let c = h2syn_discrete(&p).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(c.spectral_radius < 1.0, "{name}: {}", c.spectral_radius);
        is_optimal(&p, &c.k, c.h2_norm);
        // The continuous version (modes at +0.2 and −0.5 rad/s) as well.
        let pc = plant(
            0.2,
            -0.5,
            p.c1.row(0)
                .iter()
                .copied()
                .collect::<Vec<_>>()
                .try_into()
                .unwrap(),
            [p.b1[(0, 0)], p.b1[(1, 0)]],
        );
        let cc = h2syn_continuous(&pc).unwrap_or_else(|e| panic!("{name}, continuous: {e}"));
        assert!(
            cc.spectral_abscissa < 0.0,
            "{name}: {}",
            cc.spectral_abscissa
        );
    }
}

/// Each assumption broken names itself and its mode.
#[test]
fn a_broken_assumption_is_named_with_its_mode() {
    // u cannot move the unstable mode: (A, B2) not stabilisable.
    let mut p = plant(1.2, 0.5, [1.0, 1.0], [1.0, 1.0]);
    p.b2 = m(2, 1, &[0.0, 1.0]);
    match h2syn_discrete(&p) {
        Err(H2Error::Unstabilisable { mode }) => assert!((mode.re - 1.2).abs() < 1e-12),
        other => panic!("{other:?}"),
    }
    // y does not see it: (C2, A) not detectable.
    let mut p = plant(1.2, 0.5, [1.0, 1.0], [1.0, 1.0]);
    p.c2 = m(1, 2, &[0.0, 1.0]);
    match h2syn_discrete(&p) {
        Err(H2Error::Undetectable { mode }) => assert!((mode.re - 1.2).abs() < 1e-12),
        other => panic!("{other:?}"),
    }
    // A mode on the unit circle that z does not see, or that w does not drive.
    match h2syn_discrete(&plant(1.0, 0.5, [0.0, 1.0], [1.0, 1.0])) {
        Err(H2Error::UnpenalisedBoundaryMode { mode }) => assert!((mode.re - 1.0).abs() < 1e-12),
        other => panic!("{other:?}"),
    }
    match h2syn_discrete(&plant(1.0, 0.5, [1.0, 1.0], [0.0, 1.0])) {
        Err(H2Error::UndrivenBoundaryMode { mode }) => assert!((mode.re - 1.0).abs() < 1e-12),
        other => panic!("{other:?}"),
    }
    // And continuously: an integrator z does not see.
    match h2syn_continuous(&plant(0.0, -0.5, [0.0, 1.0], [1.0, 1.0])) {
        Err(H2Error::UnpenalisedBoundaryMode { mode }) => assert!(mode.re.abs() < 1e-12),
        other => panic!("{other:?}"),
    }
}
