//! Synthesis time of the full-order H2 controller (27 states at 20 kHz, thesis §6.4.1) from the
//! simulator's exact model, with one DARE of the same plant as the same-run baseline.
#![allow(missing_docs)] // criterion_group! generates undocumented items.

use criterion::{criterion_group, criterion_main, Criterion};
use lti::riccati::dare;
use nalgebra::DMatrix;
use runner::config::Loaded;

fn synthesis(c: &mut Criterion) {
    let mut cfg = Loaded::default();
    cfg.config.plant = plant_sim::PlantParams::heavy();
    cfg.config.plant.noise.accel = false;
    cfg.config.plant.timing.servo_rate_hz = 20_000.0;
    let plan = runner::Plan::new(&cfg).unwrap();
    let mut group = c.benchmark_group("synthesis");
    group.sample_size(10);
    group.bench_function("h2_27_states", |b| {
        b.iter(|| studies::synth::h2_design(&plan, 1.0).unwrap())
    });
    // Baseline: one control DARE of the same (25-state) plant.
    let sim = plant_sim::Simulator::new(&cfg.config.plant, 0, &Default::default()).unwrap();
    let t = sim.linear_tick().unwrap();
    let b2 = t.g.columns(1, 1).into_owned();
    let q = t.t_start.rows(0, 1).transpose() * t.t_start.rows(0, 1) * 1e18;
    let r = DMatrix::from_element(1, 1, 1.0);
    group.bench_function("dare_baseline", |b| {
        b.iter(|| dare(&t.phi, &b2, &q, &r, None).unwrap())
    });
    group.finish();
}

criterion_group!(benches, synthesis);
criterion_main!(benches);
