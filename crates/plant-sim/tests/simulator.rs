//! The running simulator against independent references: the alias-sum discrete frequency
//! response of the continuous model with a delayed hold, the analytic current-loop step, and
//! determinism.

use crate::common;

use num_complex::Complex64 as C;
use plant_sim::cutting::CuttingProfile;
use plant_sim::model::{input, output};
use plant_sim::params::PlantParams;
use plant_sim::{PlantModel, Simulator};
use std::f64::consts::PI;

fn quiet_ideal() -> PlantParams {
    common::quiet_ideal(PlantParams::default())
}

/// Discrete response from the command sequence u[k] to the averaged ADC sample closing tick k:
/// `(e^{jωT}/T)·Σ_m G(jΩm)·(1 − e^{−jΩmT})/(jΩm)·e^{−jΩm·τ}·mean_j e^{−jΩm·jδ}`, Ωm = ω + mωs.
fn alias_sum(p: &PlantParams, model: &PlantModel, out: usize, f_hz: f64) -> C {
    let t = p.period_s();
    let ws = 2.0 * PI / t;
    let w = 2.0 * PI * f_hz;
    let os = p.adc.oversampling;
    let delta = 1.0 / p.adc.conversion_rate_hz;
    let mut sum = C::new(0.0, 0.0);
    for m in -60..=60 {
        let om = w + m as f64 * ws;
        let g = model.sys.freq_response(om).unwrap()[(out, input::COMMAND_V)];
        let jw = C::new(0.0, om);
        let hold = (1.0 - (-jw * t).exp()) / jw;
        let sampling: C = (0..os).map(|j| (-jw * (j as f64 * delta)).exp()).sum::<C>() / os as f64;
        sum += g * hold * (-jw * p.timing.delay_s).exp() * sampling;
    }
    sum * (C::new(0.0, w * t)).exp() / t
}

/// Steady-state ratio output/command at an exact DFT bin from a running simulator.
fn measured(
    p: &PlantParams,
    f_cycles: usize,
    n: usize,
    settle: usize,
    channel: fn(&daq_io::Sensor) -> f64,
) -> C {
    let mut sim = Simulator::new(p, 1, &CuttingProfile::None).unwrap();
    let w = 2.0 * PI * f_cycles as f64 / n as f64;
    let (mut yu, mut uu) = (C::new(0.0, 0.0), C::new(0.0, 0.0));
    for k in 0..settle + n {
        let u = libm::sin(w * k as f64);
        let (s, _) = sim.step(u);
        if k >= settle {
            let e = C::from_polar(1.0, -w * k as f64);
            yu += channel(&s) * e;
            uu += u * e;
        }
    }
    yu / uu
}

#[test]
fn running_simulator_matches_delayed_zoh_equivalent() {
    let p = quiet_ideal();
    let model = PlantModel::new(&p).unwrap();
    let n = 8192;
    let fs = p.timing.servo_rate_hz;
    // 24 Hz … 0.3·fs, on exact bins.
    for cycles in [1usize, 7, 41, 140, 420, 1100, 2000, 2457] {
        let f = cycles as f64 * fs / n as f64;
        let want = alias_sum(&p, &model, output::SENSOR_V, f);
        let got = measured(&p, cycles, n, 200_000, |s| s.gap_v);
        let db = 20.0 * libm::log10(got.norm() / want.norm());
        let deg = (got / want).arg().to_degrees();
        assert!(
            db.abs() < 0.01 && deg.abs() < 0.1,
            "{f:.1} Hz: {db:.4} dB, {deg:.4}°"
        );
    }
}

/// The DAC value reaches the coil exactly τ after its tick: the coil current at the end of the
/// first tick is the current loop's analytic step response at T − τ.
#[test]
fn dac_step_reaches_the_coil_after_the_delay() {
    for delay in [3.159e-6, 1.0e-6, 4.5e-6] {
        let mut p = quiet_ideal();
        p.timing.delay_s = delay;
        let mut sim = Simulator::new(&p, 1, &CuttingProfile::None).unwrap();
        let (_, truth) = sim.step(1.0);
        let a = p.actuator;
        let (w, z) = (2.0 * PI * a.current_bandwidth_hz, a.current_damping);
        let wd = w * (1.0 - z * z).sqrt();
        let t = p.period_s() - delay;
        let step = 1.0
            - libm::exp(-z * w * t)
                * (libm::cos(wd * t) + z / (1.0 - z * z).sqrt() * libm::sin(wd * t));
        let want = a.current_gain_a_per_v * step;
        assert!(
            (truth.coil_current_a - want).abs() < 1e-12,
            "τ = {delay}: {} vs {want}",
            truth.coil_current_a
        );
        assert_eq!(truth.dac_v, 1.0);
    }
}

/// The masses' motion is in metres despite the internal balancing: under a constant force the
/// stage settles to the static deflection, and x1 − x3 … agree with the truth's outputs.
#[test]
fn the_masses_motion_is_physical() {
    let p = quiet_ideal();
    let mut sim = Simulator::new(&p, 1, &CuttingProfile::None).unwrap();
    let mut last = None;
    for _ in 0..400_000 {
        last = Some(sim.step(0.1).1);
    }
    let (t, m) = (last.unwrap(), sim.motion());
    let s = p.stage;
    let force = 0.1 * p.actuator.current_gain_a_per_v * p.actuator.kt_n_per_a;
    let x2 = force * (1.0 / s.k2_n_per_m + 1.0 / s.k3_n_per_m);
    assert!((m.x_m[1] - x2).abs() < 1e-4 * x2, "{} vs {x2}", m.x_m[1]);
    assert!((m.x_m[0] - t.tool_m).abs() < 1e-15 && (m.x_m[1] - t.gap_m).abs() < 1e-15);
    assert!((m.x_m[2] - force / s.k3_n_per_m).abs() < 1e-4 * force / s.k3_n_per_m);
    assert!(m.v_m_s.iter().all(|v| v.abs() < 1e-9));
    assert!(m.accel_m2_m_s2.abs() < 1e-6);
}

#[test]
fn quantised_dac_and_nonfinite_command() {
    let p = PlantParams::default();
    let mut sim = Simulator::new(&p, 1, &CuttingProfile::None).unwrap();
    let lsb = sim.dac().lsb_v();
    let (_, t) = sim.step(0.3 * lsb);
    assert_eq!(t.dac_v, 0.0);
    let (_, t) = sim.step(0.7 * lsb);
    assert_eq!(t.dac_v, lsb);
    let (s, t) = sim.step(25.0);
    assert_eq!(t.dac_v, 131071.0 * lsb);
    assert_ne!(s.flags & daq_io::flags::DAC_CLIPPED, 0);
    let (s, t) = sim.step(f64::NAN);
    assert_eq!(t.dac_v, 0.0);
    assert_ne!(s.flags & daq_io::flags::COMMAND_NOT_FINITE, 0);
}

#[test]
fn same_seed_same_run_bit_for_bit() {
    let p = PlantParams::heavy();
    let cut = CuttingProfile::IntermittentCut {
        force_n: 1.0,
        spindle_rpm: 250.0,
    };
    let run = |seed| {
        let mut sim = Simulator::new(&p, seed, &cut).unwrap();
        (0..20_000)
            .map(|k| sim.step(libm::sin(k as f64 * 1e-3) * 0.01))
            .collect::<Vec<_>>()
    };
    let (a, b, c) = (run(42), run(42), run(43));
    assert!(
        a == b,
        "same seed must reproduce every sample and truth exactly"
    );
    assert!(a != c);
}

/// The linear tick reproduces the running simulator exactly (ideal converters, noise off
/// except what is fed in by hand through the cutting force input).
#[test]
fn linear_tick_matches_the_simulator() {
    let p = quiet_ideal();
    let cut = CuttingProfile::Lenslet {
        peak_force_n: 2.0,
        frequency_hz: 300.0,
    };
    let mut sim = Simulator::new(&p, 1, &cut).unwrap();
    let mut force = plant_sim::cutting::CuttingForce::new(&cut).unwrap();
    let lin = sim.linear_tick().unwrap();
    let mut x = nalgebra::DMatrix::<f64>::zeros(lin.phi.nrows(), 1);
    let mut u_prev = 0.0;
    for k in 0..2000 {
        let u = libm::sin((k as f64) * 0.01);
        let f = force.at(k as f64 * p.period_s());
        let inputs = nalgebra::DMatrix::from_column_slice(6, 1, &[u_prev, u, f, 0.0, 0.0, 0.0]);
        let y = &lin.y_x * &x + &lin.y_in * &inputs;
        let t = &lin.t_x * &x + &lin.t_in * &inputs;
        x = &lin.phi * &x + &lin.g * &inputs;
        u_prev = u;
        let (s, truth) = sim.step(u);
        assert!(
            (s.gap_v - y[0]).abs() < 1e-9 * (1.0 + y[0].abs()),
            "tick {k}"
        );
        assert!(
            (s.accel_v - y[1]).abs() < 1e-9 * (1.0 + y[1].abs()),
            "tick {k}"
        );
        assert!(
            (truth.tool_m - t[0]).abs() < 1e-12 * (1.0 + t[0].abs()),
            "tick {k}"
        );
        assert!(
            (truth.motor_force_n - t[2]).abs() < 1e-9 * (1.0 + t[2].abs()),
            "tick {k}"
        );
    }
    assert_eq!(lin.white_variance, [0.0; 3]);
}
