//! The controllers `servo run` can drive, built from the configuration, and their linear
//! realisations for the pre-run stability check.

use crate::config::{ConfigError, ControllerConfig, ControllerKind, Loaded};
use nalgebra::{DMatrix, SMatrix};
use serde::Deserialize;
use servo_core::{
    kg, AccelCascade, AccelCascadeConfig, BiquadDesign, Block, CascadeInput, Iir, IirCoeffs,
    Limits, Pid, PidConfig, StateSpace, StateSpaceConfig,
};

/// Largest state-space controller order `servo run` accepts (the thesis's full order is 27).
pub const MAX_SS_ORDER: usize = 40;

/// A controller file: the discrete controller `x⁺ = A x + B e`, `u = C x + D e` from the
/// position error `e = reference − measurement` in sensor volts to the command in volts.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SsFile {
    /// The sample rate the matrices were designed for, in Hz (must equal the servo rate).
    pub sample_rate_hz: f64,
    /// n × n.
    pub a: Vec<Vec<f64>>,
    /// n × 1.
    pub b: Vec<Vec<f64>>,
    /// 1 × n.
    pub c: Vec<Vec<f64>>,
    /// 1 × 1.
    pub d: Vec<Vec<f64>>,
}

/// One tick of a state-space controller of run-time order (dispatched to the const-generic
/// servo-core block of that order).
trait SsTick: Send {
    fn tick(&mut self, e: f64) -> f64;
    fn faulted(&self) -> bool;
}

impl<const N: usize> SsTick for StateSpace<N, 1, 1> {
    fn tick(&mut self, e: f64) -> f64 {
        self.update([e])[0]
    }
    fn faulted(&self) -> bool {
        Block::faulted(self)
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

/// A built controller: the tick plus its linear model.
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
pub(crate) fn dm<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> DMatrix<f64> {
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

fn invalid(cfg: &Loaded, key: &str, e: impl std::fmt::Display) -> ConfigError {
    cfg.invalid(key, e, "a valid value (see the message)")
}

impl Controller {
    /// Builds the controller of `cfg` (the plant section gives the mass for Kg scaling).
    pub fn build(cfg: &Loaded) -> Result<Self, ConfigError> {
        let c = &cfg.config.controller;
        let period = 1.0 / cfg.config.plant.timing.servo_rate_hz;
        let limits = Limits::try_new(-c.limit_v, c.limit_v)
            .map_err(|e| invalid(cfg, "controller.limit_v", e))?;
        let mut pid_cfg = PidConfig {
            kp: c.pid.kp,
            ki: c.pid.ki,
            kd: c.pid.kd,
            tf_s: c.pid.tf_s,
            limits,
        };
        let mut description = String::new();
        if c.kind == ControllerKind::Accel && c.kg_scaling {
            let p = &cfg.config.plant;
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
            } => cfg.invalid(
                &format!("controller.pid.{param}"),
                value,
                &format!("[{min}, {max}]"),
            ),
            other => invalid(cfg, "controller.pid", other),
        })?;
        let (pa, pb, pc, pd) = pid.coeffs().realization();
        // The PID sees e = −gap (zero reference): gain −1 on the gap channel.
        let pid_linear = on_channel(dm(&pa), dm(&pb), dm(&pc), pd, 0, -1.0);
        let gains = format!(
            "Kp {} Ki {} Kd {:e} Tf {:e}",
            pid_cfg.kp, pid_cfg.ki, pid_cfg.kd, pid_cfg.tf_s
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
                        .map_err(|e| invalid(cfg, "controller.accel_filter_hz", e))?,
                    None => IirCoeffs::<2>::IDENTITY,
                };
                let cascade = AccelCascadeConfig {
                    pid: pid_cfg,
                    ka: c.ka,
                    limits,
                }
                .try_build(period, Iir::new(ha))
                .map_err(|e| invalid(cfg, "controller.ka", e))?;
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
                let file = c.ss_file.as_ref().expect("validated: ss needs ss_file");
                let path = cfg.resolve(file);
                let (m, n) = load_ss(&path, cfg.config.plant.timing.servo_rate_hz)?;
                let tick = boxed_ss(&m, n, period, limits).ok_or_else(|| ConfigError::Invalid {
                    path: Some(path.clone()),
                    line: None,
                    key: "a".into(),
                    value: format!("{n} states"),
                    range: format!("1..={MAX_SS_ORDER} states, finite entries"),
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

/// Loads a controller file into `[[A, B], [C, D]]` and its order, checking shapes and rate.
fn load_ss(
    path: &std::path::Path,
    servo_rate_hz: f64,
) -> Result<(DMatrix<f64>, usize), ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
        path: path.to_owned(),
        source,
    })?;
    let file: SsFile = toml::from_str(&text).map_err(|e| ConfigError::Parse {
        path: path.to_owned(),
        message: e.to_string(),
    })?;
    let at = Loaded {
        path: Some(path.to_owned()),
        text: Some(text),
        ..Default::default()
    };
    let n = file.a.len();
    let shape = |key: &str, rows: &Vec<Vec<f64>>, r: usize, c: usize| {
        let ok = rows.len() == r
            && rows
                .iter()
                .all(|row| row.len() == c && row.iter().all(|x| x.is_finite()));
        if ok {
            Ok(())
        } else {
            let got = format!("{}×{}", rows.len(), rows.first().map_or(0, |x| x.len()));
            Err(at.invalid(
                key,
                got,
                &format!("{r}×{c} finite numbers (controller order {n}, one input, one output)"),
            ))
        }
    };
    if n == 0 || n > MAX_SS_ORDER {
        return Err(at.invalid(
            "a",
            format!("{n} states"),
            &format!("1..={MAX_SS_ORDER} states"),
        ));
    }
    shape("a", &file.a, n, n)?;
    shape("b", &file.b, n, 1)?;
    shape("c", &file.c, 1, n)?;
    shape("d", &file.d, 1, 1)?;
    if (file.sample_rate_hz - servo_rate_hz).abs() > 1e-6 * servo_rate_hz {
        return Err(at.invalid(
            "sample_rate_hz",
            file.sample_rate_hz,
            &format!("{servo_rate_hz} Hz (the run's plant.timing.servo_rate_hz)"),
        ));
    }
    let mut m = DMatrix::zeros(n + 1, n + 1);
    for i in 0..n {
        for j in 0..n {
            m[(i, j)] = file.a[i][j];
        }
        m[(i, n)] = file.b[i][0];
        m[(n, i)] = file.c[0][i];
    }
    m[(n, n)] = file.d[0][0];
    Ok((m, n))
}
