//! Calibration of the noise gains (README "Calibration"): finds the PID gain scale that gives
//! the 468 Hz closed-loop bandwidth of thesis §5.7.3 on the 0.175 kg stage, then runs the closed
//! loop with one noise source at a time and prints each source's RMS contribution to the
//! following error (sensor reading) and to the true tool error.
//!
//! `cargo run --release -p plant-sim --example calibrate`

use num_complex::Complex64 as C;
use plant_sim::cutting::CuttingProfile;
use plant_sim::params::{NoiseParams, PlantParams};
use plant_sim::{PlantModel, Simulator};
use servo_core::{Block, PidConfig};
use std::f64::consts::PI;

/// Closed-loop |T(jω)| from reference to sensor with the PID scaled by `alpha`; the discrete
/// effects enter as the delay τ plus half a period (hold) plus the mean ADC sampling advance.
fn closed_loop(p: &PlantParams, model: &PlantModel, pid: &PidConfig, f: f64) -> C {
    let w = 2.0 * PI * f;
    let s = C::new(0.0, w);
    let plant = model.sys.freq_response(w).unwrap()[(0, 0)];
    let os = p.adc.oversampling as f64;
    let lag = p.timing.delay_s + p.period_s() / 2.0 + (os - 1.0) / 2.0 / p.adc.conversion_rate_hz;
    let c = pid.kp + pid.ki / s + pid.kd * s / (pid.tf_s * s + 1.0);
    let l = c * plant * (-s * lag).exp();
    l / (1.0 + l)
}

/// −3 dB bandwidth in Hz (first crossing of |T| = 1/√2 from below… searched upward).
fn bandwidth(p: &PlantParams, model: &PlantModel, pid: &PidConfig) -> f64 {
    let dc = closed_loop(p, model, pid, 0.01).norm();
    let mut f = 1.0;
    while closed_loop(p, model, pid, f).norm() > dc / 2f64.sqrt() {
        f *= 1.001;
        if f > 50e3 {
            break;
        }
    }
    f
}

fn rms(x: &[f64]) -> f64 {
    let m = x.iter().sum::<f64>() / x.len() as f64;
    (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
}

/// Closed loop for `seconds`: returns (following error RMS, true error RMS) in m.
pub fn run(p: &PlantParams, pid: &PidConfig, seconds: f64, seed: u64) -> (f64, f64) {
    let mut sim = Simulator::new(p, seed, &CuttingProfile::None).unwrap();
    let mut ctrl = pid.try_build(p.period_s()).unwrap();
    let n = (seconds * p.timing.servo_rate_hz) as usize;
    let skip = n / 5;
    let (mut follow, mut truth) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut u = 0.0;
    for k in 0..n {
        let (s, t) = sim.step(u);
        u = ctrl.update(-s.gap_v);
        if k >= skip {
            follow.push(-s.gap_v / p.capa.sensitivity_v_per_m);
            truth.push(t.tool_m);
        }
    }
    (rms(&follow), rms(&truth))
}

/// The Ch7 PID scaled to a closed-loop bandwidth of `bw_hz` (bisection on the gain scale).
fn pid_for_bandwidth(p: &PlantParams, bw_hz: f64) -> PidConfig {
    let model = PlantModel::new(p).unwrap();
    let base = PidConfig::THESIS_CH7;
    let (mut lo, mut hi) = (0.01f64, 20.0f64);
    for _ in 0..50 {
        let mid = (lo * hi).sqrt();
        if bandwidth(p, &model, &base.with_gain_scale(mid)) < bw_hz {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    base.with_gain_scale((lo * hi).sqrt())
}

/// Per-source (following, true) RMS in m with the given noise parameters. Converters are ideal
/// here: without the sensor noise to dither it, the 16-bit ADC (0.78 nm LSB) makes the
/// integrator limit-cycle and that would be counted as the source's contribution.
fn contributions(p: &PlantParams, pid: &PidConfig) -> [(f64, f64); 3] {
    [
        [true, false, false],
        [false, true, false],
        [false, false, true],
    ]
    .map(|[s, c, b]| {
        let mut q = *p;
        q.adc.bits = 0;
        q.dac.bits = 0;
        q.noise = NoiseParams {
            sensor: s,
            current: c,
            base: b,
            accel: false,
            ..p.noise
        };
        run(&q, pid, 2.0, 7)
    })
}

fn main() {
    let thesis = PlantParams::heavy();
    let pid = pid_for_bandwidth(&thesis, 468.0);
    let model = PlantModel::new(&thesis).unwrap();
    println!(
        "468 Hz PID on 0.175 kg: Kp {:.4}, Ki {:.2}, Kd {:.4e}, Tf {:.2e} (bandwidth {:.1} Hz)",
        pid.kp,
        pid.ki,
        pid.kd,
        pid.tf_s,
        bandwidth(&thesis, &model, &pid)
    );
    // Unit runs at the thesis gains; every contribution scales linearly with its gain.
    let mut unit = thesis;
    unit.noise.sensor_v_per_rt_hz = 1.36e-6;
    unit.noise.current_a_per_rt_hz = 1.64e-7;
    unit.noise.base_m_per_rt_hz = 2.83e-9;
    let [(fs, ts), (fi, ti), (fg, tg)] = contributions(&unit, &pid);
    for (name, f, t) in [("sensor", fs, ts), ("current", fi, ti), ("base", fg, tg)] {
        println!(
            "thesis gain, {name:>7} alone: following {:.3} nm, true {:.3} nm",
            f * 1e9,
            t * 1e9
        );
    }
    // Targets: following 0.83 nm; sensor and current equal in it; base 10 % of the true power.
    let k = fg / tg / 3.0 * ((ts / fs).powi(2) + (ti / fi).powi(2)).sqrt();
    let a = 0.83e-9 / (2.0 + k * k).sqrt();
    let (r_s, r_i) = (a / fs, a / fi);
    let r_g = a * k / fg;
    let mut cal = thesis;
    cal.noise.sensor_v_per_rt_hz = 1.36e-6 * r_s;
    cal.noise.current_a_per_rt_hz = 1.64e-7 * r_i;
    cal.noise.base_m_per_rt_hz = 2.83e-9 * r_g;
    println!(
        "calibrated: sensor {:.4e} V/√Hz (×{r_s:.4}), current {:.4e} A/√Hz (×{r_i:.3}), base {:.4e} m/√Hz (×{r_g:.3e})",
        cal.noise.sensor_v_per_rt_hz, cal.noise.current_a_per_rt_hz, cal.noise.base_m_per_rt_hz
    );
    let defaults = PlantParams::heavy();
    let [(fs, ts), (fi, ti), (fg, tg)] = contributions(&defaults, &pid);
    for (name, f, t) in [("sensor", fs, ts), ("current", fi, ti), ("base", fg, tg)] {
        println!(
            "defaults, {name:>7} alone: following {:.3} nm, true {:.3} nm",
            f * 1e9,
            t * 1e9
        );
    }
    let mut all = defaults;
    all.noise.accel = false;
    let (f, t) = run(&all, &pid, 4.0, 11);
    println!(
        "defaults, all on: following {:.3} nm RMS, true {:.3} nm RMS (thesis §5.7.4: 0.83 / 0.23)",
        f * 1e9,
        t * 1e9
    );
    // Fig 5-14: following error against bandwidth for both masses.
    for (label, stage) in [
        ("0.075 kg", PlantParams::default()),
        ("0.175 kg", PlantParams::heavy()),
    ] {
        let mut q = stage;
        q.noise.accel = false;
        let mut best = (f64::MAX, 0.0);
        let mut line = String::new();
        for bw in [
            300.0, 400.0, 468.0, 550.0, 650.0, 750.0, 874.0, 1000.0, 1200.0, 1450.0,
        ] {
            let (f, _) = run(&q, &pid_for_bandwidth(&q, bw), 2.0, 3);
            line += &format!(" {bw:.0}:{:.3}", f * 1e9);
            if f < best.0 {
                best = (f, bw);
            }
        }
        println!("{label} sweep (Hz:nm):{line}  → optimum {:.0} Hz", best.1);
    }
}
