//! One servo tick of the servo-core controllers (thesis Table 6-1 sizes), with a plain
//! nalgebra state-space product and the tick forced to the baseline instruction set as the
//! same-run baselines, and the whole runtime tick (`servo_runtime::Servo`: reference,
//! protection, telemetry around the law) of the PID and of 13- and 27-state controllers (`benches/fma_compare.sh` adds a native FMA build beside it). `python3 benches/report.py` turns
//! the criterion estimates into the README's ratios.

#![allow(missing_docs)] // criterion_group! generates undocumented items.

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::{SMatrix, SVector};
use servo_core::*;
use std::hint::black_box;

const T: f64 = 1.0 / 199_600.0;

/// A stable pseudo-random realisation of order `N` (the numbers do not change the cost).
fn realisation<const N: usize>() -> StateSpaceConfig<N, 1, 1> {
    let mut seed = 0x2545f4914f6cdd1du64;
    let mut rnd = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let scale = 1.8 / N as f64;
    StateSpaceConfig {
        a: SMatrix::from_fn(|_, _| rnd() * scale),
        b: SMatrix::from_fn(|_, _| rnd()),
        c: SMatrix::from_fn(|_, _| rnd()),
        d: SMatrix::from_fn(|_, _| rnd()),
        limits: Limits::DAC_10V,
    }
}

fn state_space<const N: usize>(c: &mut Criterion) {
    let cfg = realisation::<N>();
    let mut group = c.benchmark_group(format!("state_space_{N}"));
    let mut ss = cfg.try_build(5e-5).unwrap();
    // The tick as it runs (vector width chosen at run time), and forced to the baseline ISA.
    group.bench_function("servo_core", |b| b.iter(|| ss.update([black_box(1e-3)])));
    group.bench_function("servo_core_baseline_isa", |b| {
        b.iter(|| ss.update_with(simd::Simd::Baseline, [black_box(1e-3)]))
    });
    // Baseline: the textbook nalgebra expression of the same update.
    let (a, bm, cm, d) = (cfg.a, cfg.b, cfg.c, cfg.d);
    let mut x = SVector::<f64, N>::zeros();
    group.bench_function("nalgebra_baseline", |b| {
        b.iter(|| {
            let e = SVector::<f64, 1>::new(black_box(1e-3));
            let y = cm * x + d * e;
            x = a * x + bm * e;
            y[0].clamp(-10.0, 10.0)
        })
    });
    group.finish();
}

/// The runtime's tick (`Servo::tick`) of the thesis prototype's deployment with its PID, or
/// with the order-`N` realisation as a state-space controller.
fn servo_tick<const N: usize>(c: &mut Criterion) {
    use servo_runtime::deployment::{ControllerKind, SsMatrices};
    let mut d = servo_runtime::Deployment::thesis_prototype();
    let name = if N == 0 {
        "servo_tick/pid".to_string()
    } else {
        let cfg = realisation::<N>();
        d.controller.kind = ControllerKind::Ss;
        d.controller.ss = SsMatrices::from_fn(N, |i, j| match (i < N, j < N) {
            (true, true) => cfg.a[(i, j)],
            (true, false) => cfg.b[(i, 0)],
            (false, true) => cfg.c[(0, j)],
            (false, false) => cfg.d[(0, 0)],
        });
        d.stability = None;
        format!("servo_tick/state_space_{N}")
    };
    let mut servo = servo_runtime::Servo::new(&d).unwrap();
    let mut sample = daq_io::Sensor::default();
    c.bench_function(&name, |b| {
        b.iter(|| {
            // A zero-mean reading: the loop stays in its range, never trips.
            sample.seq += 1;
            sample.gap_v = black_box(if sample.seq % 2 == 0 { 1e-6 } else { -1e-6 });
            servo.tick(&sample)
        })
    });
}

fn pid(c: &mut Criterion) {
    let mut pid = PidConfig::THESIS_CH7.try_build(T).unwrap();
    c.bench_function("pid/servo_core", |b| b.iter(|| pid.update(black_box(1e-3))));
}

fn cascade(c: &mut Criterion) {
    let lp = BiquadDesign::LowPass {
        f0_hz: 10e3,
        q: core::f64::consts::FRAC_1_SQRT_2,
    }
    .try_coeffs(T)
    .unwrap();
    let cfg = AccelCascadeConfig {
        pid: PidConfig::THESIS_CH7,
        ka: 1.0,
        limits: Limits::DAC_10V,
    };
    let mut cas = cfg.try_build(T, BiquadCascade::new([lp, lp])).unwrap();
    c.bench_function("cascade/servo_core", |b| {
        b.iter(|| {
            cas.update(CascadeInput {
                error: black_box(1e-3),
                accel: black_box(2e-3),
            })
        })
    });
}

fn biquad(c: &mut Criterion) {
    let notch = BiquadDesign::Notch {
        f0_hz: 1600.0,
        q: 5.0,
    }
    .try_coeffs(T)
    .unwrap();
    let mut bq = Iir::new(notch);
    c.bench_function("biquad/servo_core", |b| {
        b.iter(|| bq.update(black_box(1e-3)))
    });
}

/// Per-tick depth command (§8.3, §8.5.3, §8.5.4) as `servo machine` runs it: encoder count →
/// tracked angle → spiral radius → surface height; baseline in the same run: the tracker and
/// spiral alone.
fn surface(c: &mut Criterion) {
    use servo_core::surface::{BeamIntegrator, SinusoidalGrid, Surface};
    use servo_core::{SpindleTrackerConfig, Spiral};
    let mut tracker = SpindleTrackerConfig {
        pulses_per_rev: 80_000,
        speed_rpm: 60.0,
        bandwidth_hz: 10.0,
    }
    .try_build(T)
    .unwrap();
    let spiral = Spiral {
        start_radius_m: 25e-3,
        feed_m_per_rev: 5e-6,
    };
    let grid = SinusoidalGrid {
        ax_m: 5e-6,
        ay_m: 5e-6,
        lambda_x_m: 1e-3,
        lambda_y_m: 1e-3,
    };
    let beam = BeamIntegrator {
        radius_m: 0.1,
        pitch_m: 2e-3,
    };
    let mut k = 0u64;
    let mut tick = move || {
        k += 1;
        tracker.update(k * 2 / 5); // 60 rpm at 199.6 kHz: 0.4 pulses per tick
        let theta = tracker.predict_rad(1.0);
        (spiral.radius_m(theta), theta)
    };
    c.bench_function("surface/sinusoidal_grid", |b| {
        b.iter(|| {
            let (r, th) = tick();
            grid.depth_m(black_box(r), black_box(th))
        })
    });
    c.bench_function("surface/beam_integrator", |b| {
        b.iter(|| {
            let (r, th) = tick();
            beam.depth_m(black_box(r), black_box(th))
        })
    });
    c.bench_function("surface/tracker_baseline", |b| {
        b.iter(|| {
            let (r, th) = tick();
            black_box(r) + black_box(th)
        })
    });
}

/// The ZPETC of the default loop (12 sections, as `servo run --feedforward zpetc` runs it);
/// baseline in the same run: one biquad (`biquad/servo_core`).
fn zpetc(c: &mut Criterion) {
    let cfg = run_config::Loaded {
        config: run_config::RunConfig {
            controller: run_config::ControllerConfig {
                feedforward: run_config::FeedforwardKind::Zpetc,
                ..Default::default()
            },
            ..Default::default()
        },
        ..Default::default()
    };
    let plan = runner::Plan::new(&cfg).unwrap();
    let mut z =
        loop_model::feedforward::zpetc(&plan.closed_loop, run_config::FeedforwardKind::Zpetc)
            .unwrap()
            .build()
            .unwrap();
    let mut y = 0.0;
    c.bench_function("zpetc/12_sections", |b| {
        b.iter(|| {
            y += 1e-9;
            z.update(black_box(y))
        })
    });
}

/// Repetitive control at the grid cut's speed (60 rpm: 199 600 ticks per revolution, 8192
/// bins, learning on): accumulate the error, learn a bin when the angle leaves it, interpolate
/// the output. Baseline in the same run: the PID (`pid/servo_core`).
fn repetitive(c: &mut Criterion) {
    let mut rc: Box<Repetitive<8192>> = Box::new(
        RepetitiveConfig {
            bins_per_rev: 8192,
            ..RepetitiveConfig::DEFAULT
        }
        .try_build(T)
        .unwrap(),
    );
    rc.set_enabled(true);
    let rate = std::f64::consts::TAU / 199_600.0;
    let mut angle = 0.0;
    c.bench_function("repetitive/servo_core", |b| {
        b.iter(|| {
            angle += rate;
            rc.update(RepetitiveInput {
                angle_rad: angle,
                error_m: black_box(1e-9),
                output_angle_rad: angle + 2.0 * rate,
                rate_rad_per_tick: rate,
            })
        })
    });
}

criterion_group!(
    benches,
    pid,
    repetitive,
    cascade,
    biquad,
    surface,
    zpetc,
    state_space::<8>,
    state_space::<13>,
    state_space::<27>,
    servo_tick::<0>,
    servo_tick::<13>,
    servo_tick::<27>
);
criterion_main!(benches);
