//! Synthesis time of the full-order H2 controller (29 states at 20 kHz: the thesis's 27 of §6.4.1
//! and the sensor noise's two) from the
//! simulator's exact model, with one DARE of the same order (DAREX 15, 29 states) as the
//! same-run baseline.
#![allow(missing_docs)] // criterion_group! generates undocumented items.

use criterion::{criterion_group, criterion_main, Criterion};
use lti::riccati::dare;
use nalgebra::DMatrix;
use run_config::Loaded;

fn synthesis(c: &mut Criterion) {
    let mut cfg = Loaded::default();
    cfg.config.plant = plant_sim::PlantParams::heavy();
    cfg.config.plant.noise.accel = false;
    cfg.config.plant.timing.servo_rate_hz = 20_000.0;
    let plan = runner::Plan::new(&cfg).unwrap();
    let mut group = c.benchmark_group("synthesis");
    group.sample_size(10);
    group.bench_function("h2_29_states", |b| {
        b.iter(|| studies::synth::h2_design(&plan, 1.0).unwrap())
    });
    // Baseline: one DARE of the controller's order (29 states): DAREX 15, a delay line with
    // Q = I, R = 1 (X = diag(1 … 29)).
    let n = 29;
    let phi = DMatrix::from_fn(n, n, |i, j| if j == i + 1 { 1.0 } else { 0.0 });
    let mut b2 = DMatrix::zeros(n, 1);
    b2[(n - 1, 0)] = 1.0;
    let q = DMatrix::identity(n, n);
    let r = DMatrix::from_element(1, 1, 1.0);
    group.bench_function("dare_baseline", |b| {
        b.iter(|| dare(&phi, &b2, &q, &r, None).unwrap())
    });
    group.finish();
}

criterion_group!(benches, synthesis);
criterion_main!(benches);
