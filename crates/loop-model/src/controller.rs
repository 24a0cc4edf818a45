//! The controller of a run as the design side sees it: its linear realisation for the
//! pre-run stability check, its description, and the runtime's [`ControllerSpec`] it runs as
//! (built and ticked by `servo_runtime`).

use nalgebra::{DMatrix, SMatrix};
use run_config::{ConfigError, ControllerKind, Origin, RunConfig};
use servo_config::{accel_shaping, kg_of, position_pid, ControllerSpec, SsMatrices, Stage};
use servo_core::IirCoeffs;

/// A run's controller: what the runtime runs, and its linear model.
#[derive(Debug, Clone)]
pub struct RunController {
    /// What the runtime runs (a state-space controller's matrices included).
    pub spec: ControllerSpec,
    /// Linear realisation on inputs `[gap_v, accel_v]` with zero reference (for stability).
    pub linear: LinearController,
    /// Output limit in V.
    pub limit_v: f64,
    /// Human-readable description for the summary.
    pub description: String,
    /// The position PID actually used (after Kg scaling), for analysis.
    pub pid: servo_core::PidConfig,
}

/// `x⁺ = A x + B y`, `u = C x + D y` with `y = [gap_v, accel_v]` and zero reference.
#[derive(Debug, Clone)]
pub struct LinearController {
    /// State matrix.
    pub a: DMatrix<f64>,
    /// Input matrix (n × 2).
    pub b: DMatrix<f64>,
    /// Output matrix (1 × n).
    pub c: DMatrix<f64>,
    /// Feed-through (1 × 2).
    pub d: DMatrix<f64>,
}

impl LinearController {
    /// No controller: output 0 (the open loop, with the injection as the only command).
    pub fn none() -> Self {
        LinearController {
            a: DMatrix::zeros(0, 0),
            b: DMatrix::zeros(0, 2),
            c: DMatrix::zeros(1, 0),
            d: DMatrix::zeros(1, 2),
        }
    }

    /// The realisation as an [`lti::StateSpace`] (inputs `[gap_v, accel_v]`, output the
    /// command, all V).
    pub fn state_space(&self) -> lti::StateSpace {
        lti::StateSpace {
            a: self.a.clone(),
            b: self.b.clone(),
            c: self.c.clone(),
            d: self.d.clone(),
        }
    }
}

/// A fixed-size servo-core matrix as a dynamic one.
pub fn dm<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> DMatrix<f64> {
    DMatrix::from_fn(R, C, |i, j| m[(i, j)])
}

/// Places a SISO realisation on input channel `ch` (0 gap, 1 accel) scaled by `gain`.
fn on_channel(
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    c: DMatrix<f64>,
    d: f64,
    ch: usize,
    gain: f64,
) -> LinearController {
    let n = a.nrows();
    let mut b2 = DMatrix::zeros(n, 2);
    b2.column_mut(ch).copy_from(&(b.column(0) * gain));
    let mut d2 = DMatrix::zeros(1, 2);
    d2[(0, ch)] = d * gain;
    LinearController { a, b: b2, c, d: d2 }
}

/// Two controllers summed on the output.
fn parallel(p: LinearController, q: LinearController) -> LinearController {
    let (n, m) = (p.a.nrows(), q.a.nrows());
    let mut a = DMatrix::zeros(n + m, n + m);
    a.view_mut((0, 0), (n, n)).copy_from(&p.a);
    a.view_mut((n, n), (m, m)).copy_from(&q.a);
    let mut b = DMatrix::zeros(n + m, 2);
    b.view_mut((0, 0), (n, 2)).copy_from(&p.b);
    b.view_mut((n, 0), (m, 2)).copy_from(&q.b);
    let mut c = DMatrix::zeros(1, n + m);
    c.view_mut((0, 0), (1, n)).copy_from(&p.c);
    c.view_mut((0, n), (1, m)).copy_from(&q.c);
    LinearController {
        a,
        b,
        c,
        d: p.d + q.d,
    }
}

fn invalid(at: &Origin, key: &str, e: impl std::fmt::Display) -> ConfigError {
    at.invalid(key, e, "a valid value (see the message)")
}

/// The stage numbers of `config`'s plant, as the runtime uses them.
pub fn stage_of(config: &RunConfig) -> Stage {
    let p = &config.plant;
    Stage {
        gap_sensitivity_v_per_m: p.capa.sensitivity_v_per_m,
        accel_sensitivity_v_per_m_s2: p.accel.sensitivity_v_per_m_s2,
        suspended_mass_kg: p.stage.suspended_mass_kg(),
        damping_n_s_per_m: p.stage.c2_n_s_per_m,
        stiffness_n_per_m: p.stage.k2_n_per_m,
        current_gain_a_per_v: p.actuator.current_gain_a_per_v,
        kt_n_per_a: p.actuator.kt_n_per_a,
        dc_gain_m_per_v: p.dc_gain_m_per_v(),
    }
}

impl RunController {
    /// The controller of `config` (the plant section gives the rate, and the mass for Kg
    /// scaling; a state-space controller's matrices are `ss`, read from
    /// `controller.ss_file`). Errors are located in `at`.
    pub fn build(
        config: &RunConfig,
        at: &Origin,
        ss: Option<SsMatrices>,
    ) -> Result<Self, ConfigError> {
        let c = &config.controller;
        let period = 1.0 / config.plant.timing.servo_rate_hz;
        let spec = c.spec(ss);
        let stage = stage_of(config);
        let pid_cfg = position_pid(&spec, &stage).map_err(|e| at.located(&e))?;
        let pid = pid_cfg.try_build(period).map_err(|e| match e {
            servo_core::Error::OutOfRange {
                param,
                value,
                min,
                max,
            } => at.invalid(
                &format!("controller.pid.{param}"),
                value,
                &format!("[{min}, {max}]"),
            ),
            servo_core::Error::NotFinite { param } => at.invalid(
                &format!("controller.pid.{param}"),
                f64::NAN,
                "a finite number",
            ),
            other => invalid(at, "controller.pid", other),
        })?;
        let (pa, pb, pc, pd) = pid.coeffs().realization();
        // The PID sees e = −gap (zero reference): gain −1 on the gap channel.
        let pid_linear = on_channel(dm(&pa), dm(&pb), dm(&pc), pd, 0, -1.0);
        let gains = format!(
            "Kp {} Ki {} Kd {} Tf {}",
            short(pid_cfg.kp),
            short(pid_cfg.ki),
            short(pid_cfg.kd),
            short(pid_cfg.tf_s)
        );
        let (linear, description) = match c.kind {
            ControllerKind::Pid => (pid_linear, format!("PID ({gains})")),
            ControllerKind::Accel => {
                let ha = match accel_shaping(&spec) {
                    Some(d) => d
                        .try_coeffs(period)
                        .map_err(|e| invalid(at, "controller.accel_filter_hz", e))?,
                    None => IirCoeffs::<2>::IDENTITY,
                };
                let (ha_a, ha_b, ha_c, ha_d) = ha.realization();
                // u = PID(−gap) − Ha(Ka·accel)
                let accel_linear = on_channel(dm(&ha_a), dm(&ha_b), -dm(&ha_c), -ha_d, 1, c.ka);
                let scaling = if c.kg_scaling {
                    format!(", PID gains ×{:.3} (1/Kg)", 1.0 / kg_of(&spec, &stage))
                } else {
                    String::new()
                };
                (
                    parallel(pid_linear, accel_linear),
                    format!("PID ({gains}) + acceleration feedback Ka {}{scaling}", c.ka),
                )
            }
            ControllerKind::Ss => {
                let path = c.ss_file.clone().unwrap_or_default();
                let m = spec.ss.as_ref().ok_or_else(|| {
                    at.invalid(
                        "controller.ss_file",
                        path.display(),
                        "a controller file that was read",
                    )
                })?;
                let n = m.order();
                let block = |r0: usize, c0: usize, rows: usize, cols: usize| {
                    DMatrix::from_fn(rows, cols, |i, j| m.entry(r0 + i, c0 + j))
                };
                (
                    on_channel(
                        block(0, 0, n, n),
                        block(0, n, n, 1),
                        block(n, 0, 1, n),
                        m.entry(n, n),
                        0,
                        -1.0,
                    ),
                    format!("state space, {n} states ({})", path.display()),
                )
            }
        };
        Ok(RunController {
            spec,
            linear,
            limit_v: c.limit_v,
            description,
            pid: pid_cfg,
        })
    }
}

/// `x` to four significant digits, trailing zeros dropped, in e-notation below 0.01 or from
/// 1e5 (`1.65`, `562`, `0.1194`, `9.5e-4`, `7.507e-4`).
fn short(x: f64) -> String {
    let trim = |t: String| {
        if t.contains('.') {
            t.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            t
        }
    };
    if x == 0.0 || !x.is_finite() {
        return x.to_string();
    }
    if x.abs() < 1e-2 || x.abs() >= 1e5 {
        let text = format!("{x:.3e}");
        match text.split_once('e') {
            Some((mantissa, exp)) => format!("{}e{exp}", trim(mantissa.to_string())),
            None => text,
        }
    } else {
        let decimals = (3 - libm::log10(x.abs()).floor() as i32).clamp(0, 6) as usize;
        trim(format!("{x:.decimals$}"))
    }
}

#[cfg(test)]
mod tests {
    use super::short;

    #[test]
    fn gains_print_to_four_significant_digits() {
        let cases = [
            (1.65, "1.65"),
            (562.0, "562"),
            (0.11939859668622438, "0.1194"),
            (380.6313145801348, "380.6"),
            (9.5e-4, "9.5e-4"),
            (7.506682896438059e-4, "7.507e-4"),
            (0.0, "0"),
            (-2.5, "-2.5"),
            (123456.0, "1.235e5"),
        ];
        for (x, text) in cases {
            assert_eq!(short(x), text, "{x}");
        }
    }
}
