//! The controllers `servo run` can drive, built from the configuration, and their linear
//! realisations for the pre-run stability check.

use crate::config::{ConfigError, ControllerConfig, ControllerKind, Origin, RunConfig};
use crate::controller_file::ControllerFile;
use nalgebra::{DMatrix, SMatrix};
use servo_core::{
    kg, AccelCascade, AccelCascadeConfig, BiquadDesign, Block, CascadeInput, Iir, IirCoeffs,
    Limits, Pid, PidConfig, StateSpace, StateSpaceConfig,
};

/// One tick of a state-space controller of run-time order (dispatched to the const-generic
/// servo-core block of that order).
trait SsTick: Send {
    fn tick(&mut self, e: f64) -> f64;
    fn faulted(&self) -> bool;
    fn boxed_clone(&self) -> Box<dyn SsTick>;
}

impl<const N: usize> SsTick for StateSpace<N, 1, 1> {
    fn tick(&mut self, e: f64) -> f64 {
        self.update([e])[0]
    }
    fn faulted(&self) -> bool {
        Block::faulted(self)
    }
    fn boxed_clone(&self) -> Box<dyn SsTick> {
        Box::new(self.clone())
    }
}

/// Builds `StateSpace<N,1,1>` for the run-time `n`.
fn boxed_ss(m: &DMatrix<f64>, n: usize, period_s: f64, limits: Limits) -> Option<Box<dyn SsTick>> {
    fn build<const N: usize>(
        m: &DMatrix<f64>,
        period_s: f64,
        limits: Limits,
    ) -> Option<Box<dyn SsTick>> {
        let cfg = StateSpaceConfig::<N, 1, 1> {
            a: SMatrix::from_fn(|i, j| m[(i, j)]),
            b: SMatrix::from_fn(|i, _| m[(i, N)]),
            c: SMatrix::from_fn(|_, j| m[(N, j)]),
            d: SMatrix::from_element(m[(N, N)]),
            limits,
        };
        Some(Box::new(cfg.try_build(period_s).ok()?))
    }
    macro_rules! dispatch {
        ($($n:literal)+) => {
            match n {
                $($n => build::<$n>(m, period_s, limits),)+
                _ => None,
            }
        };
    }
    dispatch!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29 30 31 32 33 34 35 36 37 38 39 40)
}

enum Kind {
    Pid(Pid),
    Accel(AccelCascade<Iir<2>>),
    Ss(Box<dyn SsTick>),
}

impl Clone for Kind {
    fn clone(&self) -> Self {
        match self {
            Kind::Pid(p) => Kind::Pid(p.clone()),
            Kind::Accel(a) => Kind::Accel(a.clone()),
            Kind::Ss(s) => Kind::Ss(s.boxed_clone()),
        }
    }
}

/// A built controller: the tick plus its linear model. Cloning copies its state.
#[derive(Clone)]
pub struct Controller {
    kind: Kind,
    /// Linear realisation on inputs `[gap_v, accel_v]` with zero reference (for stability).
    pub linear: LinearController,
    /// Output limit in V.
    pub limit_v: f64,
    /// Human-readable description for the summary.
    pub description: String,
    /// The position PID actually used (after Kg scaling), for analysis.
    pub pid: PidConfig,
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

/// The acceleration shaping filter Ha of `c` (None: no filter): a first-order low pass or a
/// Butterworth at `accel_filter_hz`, by `accel_filter_order`.
pub fn accel_shaping(c: &ControllerConfig) -> Option<BiquadDesign> {
    let f0_hz = c.accel_filter_hz;
    (f0_hz > 0.0).then_some(match c.accel_filter_order {
        1 => BiquadDesign::FirstOrderLowPass { f0_hz },
        _ => BiquadDesign::LowPass {
            f0_hz,
            q: std::f64::consts::FRAC_1_SQRT_2,
        },
    })
}

fn invalid(at: &Origin, key: &str, e: impl std::fmt::Display) -> ConfigError {
    at.invalid(key, e, "a valid value (see the message)")
}

impl Controller {
    /// Builds the controller of `config` (the plant section gives the rate, and the mass for
    /// Kg scaling; a state-space controller's matrices come from `file`, the loaded
    /// `controller.ss_file`). Errors are located in `at`.
    pub fn build(
        config: &RunConfig,
        at: &Origin,
        file: Option<&ControllerFile>,
    ) -> Result<Self, ConfigError> {
        let c = &config.controller;
        let period = 1.0 / config.plant.timing.servo_rate_hz;
        let limits = Limits::try_new(-c.limit_v, c.limit_v)
            .map_err(|e| invalid(at, "controller.limit_v", e))?;
        let mut pid_cfg = PidConfig {
            kp: c.pid.kp,
            ki: c.pid.ki,
            kd: c.pid.kd,
            tf_s: c.pid.tf_s,
            limits,
        };
        let mut description = String::new();
        if c.kind == ControllerKind::Accel && c.kg_scaling {
            let p = &config.plant;
            let (a, mass) = (&p.actuator, p.stage.suspended_mass_kg());
            let k = kg(
                mass,
                c.ka,
                p.accel.sensitivity_v_per_m_s2,
                a.current_gain_a_per_v,
                a.kt_n_per_a,
            );
            pid_cfg = pid_cfg.with_gain_scale(1.0 / k);
            description = format!(", PID gains ×{:.3} (1/Kg)", 1.0 / k);
        }
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
        Ok(match c.kind {
            ControllerKind::Pid => Controller {
                kind: Kind::Pid(pid),
                linear: pid_linear,
                limit_v: c.limit_v,
                description: format!("PID ({gains})"),
                pid: pid_cfg,
            },
            ControllerKind::Accel => {
                let ha = match accel_shaping(c) {
                    Some(d) => d
                        .try_coeffs(period)
                        .map_err(|e| invalid(at, "controller.accel_filter_hz", e))?,
                    None => IirCoeffs::<2>::IDENTITY,
                };
                let cascade = AccelCascadeConfig {
                    pid: pid_cfg,
                    ka: c.ka,
                    limits,
                }
                .try_build(period, Iir::new(ha))
                .map_err(|e| invalid(at, "controller.ka", e))?;
                let (ha_a, ha_b, ha_c, ha_d) = ha.realization();
                // u = PID(−gap) − Ha(Ka·accel)
                let accel_linear = on_channel(dm(&ha_a), dm(&ha_b), -dm(&ha_c), -ha_d, 1, c.ka);
                Controller {
                    kind: Kind::Accel(cascade),
                    linear: parallel(pid_linear, accel_linear),
                    limit_v: c.limit_v,
                    pid: pid_cfg,
                    description: format!(
                        "PID ({gains}) + acceleration feedback Ka {}{description}",
                        c.ka
                    ),
                }
            }
            ControllerKind::Ss => {
                let path = c.ss_file.clone().unwrap_or_default();
                let ControllerFile { m, n } = file.ok_or_else(|| {
                    at.invalid(
                        "controller.ss_file",
                        path.display(),
                        "a controller file that was read",
                    )
                })?;
                let (m, n) = (m.clone(), *n);
                let tick = boxed_ss(&m, n, period, limits).ok_or_else(|| ConfigError::Invalid {
                    path: Some(path.clone()),
                    line: None,
                    key: "a".into(),
                    value: format!("{n} states"),
                    range: format!(
                        "1..={} states, finite entries",
                        crate::controller_file::MAX_SS_ORDER
                    ),
                })?;
                let linear = on_channel(
                    m.view((0, 0), (n, n)).into_owned(),
                    m.view((0, n), (n, 1)).into_owned(),
                    m.view((n, 0), (1, n)).into_owned(),
                    m[(n, n)],
                    0,
                    -1.0,
                );
                Controller {
                    kind: Kind::Ss(tick),
                    linear,
                    limit_v: c.limit_v,
                    pid: pid_cfg,
                    description: format!("state space, {n} states ({})", path.display()),
                }
            }
        })
    }

    /// The controller latched a fault (a non-finite input or state): its output is 0 V until
    /// it is rebuilt.
    pub fn faulted(&self) -> bool {
        match &self.kind {
            Kind::Pid(p) => p.faulted(),
            Kind::Accel(a) => a.faulted(),
            Kind::Ss(s) => s.faulted(),
        }
    }

    /// One tick: position error and accelerometer reading in V → command in V.
    #[inline]
    pub fn update(&mut self, error_v: f64, accel_v: f64) -> f64 {
        match &mut self.kind {
            Kind::Pid(p) => p.update(error_v),
            Kind::Accel(a) => a.update(CascadeInput {
                error: error_v,
                accel: accel_v,
            }),
            Kind::Ss(s) => s.tick(error_v),
        }
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
        let decimals = (3 - x.abs().log10().floor() as i32).clamp(0, 6) as usize;
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
