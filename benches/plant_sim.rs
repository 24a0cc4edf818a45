//! Simulator steps per second with every noise source on (heavy stage, intermittent cut), as a
//! multiple of real time at 199.6 kHz, against a straightforward dense nalgebra step of the same
//! discretised model measured in the same run. `python3 benches/report.py` prints the ratios.
#![allow(missing_docs)] // criterion_group! generates undocumented items.

use criterion::{criterion_group, criterion_main, Criterion};
use lti::DelayedZoh;
use nalgebra::{DMatrix, DVector};
use plant_sim::cutting::CuttingProfile;
use plant_sim::{PlantModel, PlantParams, Simulator};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::hint::black_box;

fn sim_step(c: &mut Criterion) {
    let p = PlantParams::heavy();
    let cut = CuttingProfile::IntermittentCut {
        force_n: plant_sim::cutting::TABLE_7_3_FORCE_N,
        spindle_rpm: 250.0,
    };
    let mut group = c.benchmark_group("sim_step");
    let mut sim = Simulator::new(&p, 1, &cut).unwrap();
    let mut k = 0u64;
    group.bench_function("plant_sim", |b| {
        b.iter(|| {
            k += 1;
            sim.step(black_box(1e-3 * ((k & 1023) as f64 - 512.0) / 512.0))
        })
    });
    // Baseline: x ← Φx + Γp·u[k−1] + Γn·u[k], y = C·x with nalgebra's dynamic matrices, one
    // output evaluation per ADC conversion, the same three noise draws, and per conversion the
    // sensor noise's two draws through its two-state step.
    let model = PlantModel::new(&p).unwrap();
    let sys = model.sys.balanced();
    let z = DelayedZoh::new(&sys.a, &sys.b, p.period_s(), p.timing.delay_s).unwrap();
    let (phi, gp, gn, cm) = (z.phi, z.gamma_prev, z.gamma_now, sys.c.clone());
    let mut x = DVector::<f64>::zeros(phi.nrows());
    let mut u_prev = DVector::<f64>::zeros(5);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(1);
    let (noise_phi, noise_root) = (
        DMatrix::<f64>::identity(2, 2) * 0.9,
        DMatrix::<f64>::identity(2, 2) * 1e-4,
    );
    let mut xi = DVector::<f64>::zeros(2);
    group.bench_function("nalgebra_baseline", |b| {
        b.iter(|| {
            let mut u = DVector::<f64>::zeros(5);
            u[0] = black_box(1e-3);
            for i in 2..5 {
                u[i] = StandardNormal.sample(&mut rng);
            }
            let mut gap = 0.0;
            for _ in 0..4 {
                let g = DVector::from_fn(2, |_, _| StandardNormal.sample(&mut rng));
                xi = &noise_phi * &xi + &noise_root * g;
                gap += (&cm * &x)[0] + xi[0];
            }
            x = &phi * &x + &gp * &u_prev + &gn * &u;
            u_prev = u;
            gap
        })
    });
    group.finish();
}

criterion_group!(benches, sim_step);
criterion_main!(benches);
