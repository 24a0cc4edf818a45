//! Dynamic compliance X/dF at the tool (the inverse of the dynamic stiffness, thesis eq 7-9,
//! Table 7-1) with acceleration feedback, two ways:
//!
//! * analytic — eq 7-9's control terms as an impedance at the coil carrier,
//!   `Z_c = [PID(s)·H_capa(s) + Ka·Ha(s)·H_acc(s)·s²]·H_I(s)·K_T·e^{−sτ_eff}`, on the stage's
//!   mechanical impedances (plant-sim `impedance`, so the tool mode and the parasitic mass are
//!   in, where eq 7-9 lumps one mass), with the loop's effective delay
//!   `τ_eff = τ + T/2 + (N−1)/(2·f_adc)` (transport, hold, mean ADC sampling advance);
//! * sampled loop — the simulator's exact discretisation, cutting force → tool position.

use crate::error::StudyError;
use loop_model::closed_loop::{input, output};
use num_complex::Complex64 as C;
use plant_sim::impedance::Impedances;
use run_config::{ControllerConfig, ControllerKind};
use runner::Plan;
use serde::Serialize;
use servo_config::accel_shaping;
use std::f64::consts::{PI, SQRT_2};

/// One Ka's compliance curves.
#[derive(Debug, Clone, Serialize)]
pub struct ComplianceCurve {
    /// Acceleration gain (V/V).
    #[serde(rename = "ka_v_per_v")]
    pub ka: f64,
    /// Factor on the PID gains (1/Kg when scaled, §7.4.1).
    pub pid_scale: f64,
    /// Frequencies in Hz.
    pub freq_hz: Vec<f64>,
    /// Analytic |X/dF| in m/N.
    pub analytic_m_per_n: Vec<f64>,
    /// Sampled-loop |X/dF| in m/N.
    pub sampled_m_per_n: Vec<f64>,
    /// Sampled-loop compliance at the coil carrier m2 (what the sensor sees), m/N: the servo's
    /// own compliance, without the tool shank's 1/k1 in series.
    pub sampled_m2_m_per_n: Vec<f64>,
    /// Largest closed-loop pole magnitude: ≥ 1 means the loop is unstable and the curves are
    /// only formal frequency functions.
    pub spectral_radius: f64,
}

impl ComplianceCurve {
    /// Whether the loop is stable.
    pub fn stable(&self) -> bool {
        self.spectral_radius < 1.0
    }
}

fn second_order(w: f64, zeta: f64, s: C) -> C {
    w * w / (s * s + 2.0 * zeta * w * s + w * w)
}

/// Compliance curves for each Ka in `kas` (the `accel` controller of `plan`, with its PID
/// gains scaled by 1/Kg when `kg_scaling`), on log-spaced `freqs_hz`.
pub fn compliance(
    plan: &Plan,
    kas: &[f64],
    kg_scaling: bool,
    freqs_hz: &[f64],
) -> Result<Vec<ComplianceCurve>, StudyError> {
    let mut curves = Vec::new();
    for &ka in kas {
        let c = plan.with_controller(ControllerConfig {
            kind: ControllerKind::Accel,
            ka,
            kg_scaling,
            ..plan.config.controller.clone()
        })?;
        let (cl, ctrl) = (&c.closed_loop, &c.controller);
        let p = &c.config.plant;
        let (act, capa, acc) = (&p.actuator, &p.capa, &p.accel);
        let period = 1.0 / p.timing.servo_rate_hz;
        let tau = p.timing.delay_s
            + period / 2.0
            + (p.adc.oversampling as f64 - 1.0) / 2.0 / p.adc.conversion_rate_hz;
        let pid = ctrl.pid;
        let mut analytic = Vec::with_capacity(freqs_hz.len());
        let mut sampled = Vec::with_capacity(freqs_hz.len());
        let mut sampled_m2 = Vec::with_capacity(freqs_hz.len());
        for &f in freqs_hz {
            let imp = Impedances::new(&p.stage, f);
            let s = imp.s();
            let h_i = act.current_gain_a_per_v
                * second_order(2.0 * PI * act.current_bandwidth_hz, act.current_damping, s);
            let h_capa = capa.sensitivity_v_per_m
                * second_order(2.0 * PI * capa.bandwidth_hz, SQRT_2 / 2.0, s);
            let wr = 2.0 * PI * acc.resonance_hz;
            let h_acc = acc.sensitivity_v_per_m_s2
                * second_order(wr, 1.0 / (2.0 * acc.resonance_q), s)
                * (s / (s + 1.0 / acc.highpass_time_constant_s))
                * second_order(2.0 * PI * acc.lowpass_hz, SQRT_2 / 2.0, s);
            let h_a =
                accel_shaping(&c.config.controller.spec(None)).map_or(C::new(1.0, 0.0), |d| {
                    let (num, den) = d.analog();
                    let at = |p: [f64; 3]| p[0] * s * s + p[1] * s + p[2];
                    at(num) / at(den)
                });
            let pid_s = pid.kp + pid.ki / s + pid.kd * s / (pid.tf_s * s + 1.0);
            let z_ctrl = (pid_s * h_capa + ka * h_a * h_acc * s * s)
                * h_i
                * act.kt_n_per_a
                * (-s * tau).exp();
            analytic.push(imp.x1_per_cut_force(z_ctrl).norm());
            let h = cl.response(output::TOOL_M, input::CUTTING_FORCE_N, f)?;
            sampled.push(h.norm());
            let h2 = cl.response(output::MEASURED_M, input::CUTTING_FORCE_N, f)?;
            sampled_m2.push(h2.norm());
        }
        curves.push(ComplianceCurve {
            ka,
            pid_scale: pid.kp / plan.config.controller.pid.kp,
            freq_hz: freqs_hz.to_vec(),
            analytic_m_per_n: analytic,
            sampled_m_per_n: sampled,
            sampled_m2_m_per_n: sampled_m2,
            spectral_radius: cl.spectral_radius(),
        });
    }
    Ok(curves)
}
