//! The stall a real-time loop survives: how long its controller may go silent (a descheduled
//! process, a hypervisor's pause) before the stage leaves the protection limits — predicted
//! from the sampled closed loop, checked against the host's measured stalls, and simulated.
//!
//! What a stall does in a real-time run ([`daq_io::serve`]): the plant keeps its time, the DAC
//! holds the last command, the controller's state stays as it was; when the controller comes
//! back it takes the newest sample (the ones between are skipped) and the loop closes again —
//! unless the silence reached the peer timeout, after which the plant drives 0 V and ends the
//! run (`peer-lost`). So a loop survives a stall when it is shorter than the peer timeout and
//! the stage stays within the limits through the stall and the recovery after it.
//!
//! The prediction ([`survivable`]) runs the loop's two linear models — [`ClosedLoop::new`]
//! and [`ClosedLoop::held`] — through a stall of `m` ticks and the recovery after it, from
//! the worst state the run's scenario puts the loop in (every phase of a sine, each frequency
//! of a chirp, a step or a cut starting with the stall, the settled state after it), plus
//! three standard deviations of the loop's noise propagated through the same ticks (its
//! stationary covariance at the start, the noise that enters during the stall and after). The
//! protected quantities are the following error and the measured position (the
//! `[protection]` limits and the gap sensor's range), every tick, and after the stall the time
//! the command spends at `controller.limit_v` (`protection.saturation_s`). The recovery's
//! command is clamped at that limit as the runtime does it; the controller's state does not see
//! the clamp (a PID's conditional integration winds up less, so for it the prediction errs on
//! the safe side). The longest `m` that keeps all of them within their limits is found by
//! doubling, then bisection.
//!
//! The limits are checked on every tick, the stalled ones too, though the runtime's protection
//! only sees the samples the controller takes: the tool must not leave them while nobody looks
//! either. A chirp is tried at 8 frequencies over its sweep, which can miss a narrow resonance
//! between them. Not modelled (refused by name): a loop with feedforward and a machining run's
//! surface reference. Nor is a controller that answers every sample but too late (the overrun
//! budget's case, not a stall), or one descheduled between reading a sample and sending its
//! command (its state is then a tick further on).

use crate::error::RunError;
use crate::hil::{serve_options, PlantOptions};
use crate::plan::{linear_tick_of, Plan};
use crate::plan_loop::PlanLoop;
use daq_io::serve::Pacing;
use daq_io::watchdog::{Verdict, Watchdog};
use daq_io::{Backend, Sensor};
use loop_model::closed_loop::{input, output, ClosedLoop, SOURCES};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use run_config::Scenario;
use servo_runtime::TripCause;

mod qualification;
pub(crate) mod verdict;
pub use qualification::{preflight, HostCheck, Measurement, Percentiles, Qualification, QUALIFY_S};
pub use verdict::{advice, HostStalls, Limit, Refusal, Survivable, MAX_STALL_S, STALL_MARGIN};

/// Phases of a sine reference at which a stall is tried (10° apart).
const PHASES: usize = 36;
/// Frequencies of a chirp at which its sine is tried (log-spaced over the sweep).
const CHIRP_FREQUENCIES: usize = 8;
/// The noise's coverage: three standard deviations.
const SIGMAS: f64 = 3.0;
/// After the stall, the recovery is followed until the loop's slowest pole has decayed to
/// this fraction, at most [`MAX_RECOVERY_S`].
const RECOVERY_DECAY: f64 = 1e-3;
/// The longest recovery followed, in s.
const MAX_RECOVERY_S: f64 = 0.02;

/// The longest stall of `plan`'s loop in a real-time run with peer timeout `peer_timeout_s`
/// (s; the run's `realtime.peer_timeout_s` unless overridden). Errors: a loop that is not
/// stable, a machining run (its reference is the surface, not predicted here).
pub fn survivable(plan: &Plan, peer_timeout_s: f64) -> Result<Survivable, RunError> {
    plan.check_stable()?;
    let c = &plan.config;
    let cases = Cases::of(plan)?;
    let tick = linear_tick_of(c, &plan.origin, &plan.sim)?;
    let s = c.plant.capa.sensitivity_v_per_m;
    let held = ClosedLoop::held(&tick, &plan.controller.linear, s, plan.period_s());
    let model = Model::new(&plan.closed_loop, &held, plan)?;
    let period = plan.period_s();
    let max_ticks = (MAX_STALL_S / period).round() as u64;
    let survives = |m: u64| model.worst(&cases, m as usize);
    // Doubling, then bisection between the last stall survived and the first one not.
    let (mut ok, mut bad, mut limit) = (0u64, None, None);
    let mut m = 1u64;
    loop {
        match survives(m) {
            None => ok = m,
            Some(l) => {
                bad = Some(m);
                limit = Some(l);
                break;
            }
        }
        if m == max_ticks {
            break;
        }
        // The last try is the longest stall searched itself.
        m = (2 * m).min(max_ticks);
    }
    if let Some(mut hi) = bad {
        while hi - ok > 1 {
            let mid = ok + (hi - ok) / 2;
            match survives(mid) {
                None => ok = mid,
                Some(l) => {
                    hi = mid;
                    limit = Some(l);
                }
            }
        }
    }
    Ok(Survivable {
        physics_ticks: bad.map(|_| ok),
        physics_limit: limit,
        watchdog_ticks: watchdog_ticks(plan, peer_timeout_s),
        period_s: period,
    })
}

/// The longest stall (ticks) the plant's watchdog lets pass with peer timeout `timeout_s`: the
/// run's own fault policy judging a silent controller on an injected clock, with the times
/// `daq_io::serve` gives it — a silent tick k is published at k·T and judged when its command
/// deadline, (k + 1)·T, passes.
fn watchdog_ticks(plan: &Plan, timeout_s: f64) -> u64 {
    let period_ns = period_ns(plan);
    let policy = policy(plan, timeout_s);
    // After the grace window (where the timeout alone judges silence), a controller heard at
    // tick 0 of the count, then silent.
    let start = policy.grace_ns / period_ns + 1;
    let mut watchdog = Watchdog::new(policy);
    let mut m = 0;
    while watchdog.tick((start + m + 1) * period_ns, start * period_ns, true, false) == Verdict::Ok
    {
        m += 1;
    }
    m
}

/// The run's fault policy in real time with peer timeout `timeout_s`.
fn policy(plan: &Plan, timeout_s: f64) -> daq_io::watchdog::FaultPolicy {
    let opts = PlantOptions {
        pacing: Pacing::RealTime,
        wait_for_recorder: false,
        wait_for_start: false,
        peer_timeout: Some(std::time::Duration::from_secs_f64(timeout_s)),
    };
    serve_options(plan, &opts).fault_policy()
}

/// The servo period in ns, as the plant counts it.
fn period_ns(plan: &Plan) -> u64 {
    (plan.period_s() * 1e9).round() as u64
}

/// The deterministic states a stall may start from, as columns: the loop's state at the
/// stall's first tick, and the reference and cutting force from then on.
struct Cases {
    x0: Vec<DVector<f64>>,
    /// `reference(case, j)`: the reference at the stall's tick `j`, m.
    reference: Vec<Trajectory>,
    /// Cutting force from the stall's first tick on, N.
    force: Vec<f64>,
}

/// A reference from the stall's first tick on.
#[derive(Clone, Copy)]
enum Trajectory {
    Constant(f64),
    /// `amplitude · sin(ω·T·j + phase)`.
    Sine {
        amplitude: f64,
        w_t: f64,
        phase: f64,
    },
}

impl Trajectory {
    fn at(&self, j: usize) -> f64 {
        match *self {
            Trajectory::Constant(r) => r,
            Trajectory::Sine {
                amplitude,
                w_t,
                phase,
            } => amplitude * libm::sin(w_t * j as f64 + phase),
        }
    }
}

impl Cases {
    /// The worst starts the scenario of `plan` offers.
    fn of(plan: &Plan) -> Result<Self, RunError> {
        if plan.config.controller.feedforward != run_config::FeedforwardKind::None {
            return Err(RunError::StallAnalysis(
                "a loop with feedforward (controller.feedforward): the model is the feedback loop's".into(),
            ));
        }
        let sys = &plan.closed_loop.sys;
        let n = sys.a.nrows();
        let period = plan.period_s();
        let mut cases = Cases {
            x0: Vec::new(),
            reference: Vec::new(),
            force: Vec::new(),
        };
        let mut add = |x0: DVector<f64>, r: Trajectory, f: f64| {
            cases.x0.push(x0);
            cases.reference.push(r);
            cases.force.push(f);
        };
        let zero = DVector::zeros(n);
        // The settled state under a constant reference r and force f.
        let settled = |r: f64, f: f64| -> Result<DVector<f64>, RunError> {
            let rhs =
                sys.b.column(input::REFERENCE_M) * r + sys.b.column(input::CUTTING_FORCE_N) * f;
            (DMatrix::identity(n, n) - &sys.a)
                .lu()
                .solve(&rhs)
                .ok_or_else(|| RunError::StallAnalysis("the loop has a pole at 1".into()))
        };
        let mut sines = |amplitude: f64, f_hz: f64| -> Result<(), RunError> {
            let w_t = std::f64::consts::TAU * f_hz * period;
            let z = Complex64::from_polar(1.0, w_t);
            let a = sys.a.map(Complex64::from);
            let m = DMatrix::<Complex64>::identity(n, n) * z - a;
            let b = sys
                .b
                .column(input::REFERENCE_M)
                .map(|v| Complex64::from(v * amplitude));
            let x = m.lu().solve(&b).ok_or_else(|| {
                RunError::StallAnalysis("the loop has a pole on the unit circle".into())
            })?;
            for i in 0..PHASES {
                let phase = std::f64::consts::TAU * i as f64 / PHASES as f64;
                let rot = Complex64::from_polar(1.0, phase);
                add(
                    x.map(|v| (v * rot).im),
                    Trajectory::Sine {
                        amplitude,
                        w_t,
                        phase,
                    },
                    0.0,
                );
            }
            Ok(())
        };
        match &plan.config.scenario {
            Scenario::Hold => add(zero, Trajectory::Constant(0.0), 0.0),
            Scenario::Sine {
                amplitude_m,
                frequency_hz,
            } => sines(*amplitude_m, *frequency_hz)?,
            Scenario::Chirp {
                amplitude_m,
                f_start_hz,
                f_end_hz,
            } => {
                let (lo, hi) = (f_start_hz.min(*f_end_hz), f_start_hz.max(*f_end_hz));
                for i in 0..CHIRP_FREQUENCIES {
                    let f = lo * libm::pow(hi / lo, i as f64 / (CHIRP_FREQUENCIES - 1) as f64);
                    sines(*amplitude_m, f)?;
                }
            }
            Scenario::Step { amplitude_m, .. } => {
                let r = *amplitude_m;
                // The step while the controller is frozen, and the stall after it settled.
                add(zero, Trajectory::Constant(r), 0.0);
                add(settled(r, 0.0)?, Trajectory::Constant(r), 0.0);
            }
            Scenario::IntermittentCut { force_n, .. } => {
                let f = *force_n;
                // The cut starting, and ending, while the controller is frozen.
                add(zero.clone(), Trajectory::Constant(0.0), f);
                add(settled(0.0, f)?, Trajectory::Constant(0.0), 0.0);
            }
            Scenario::Machine(_) => {
                return Err(RunError::StallAnalysis(
                    "a machining run (scenario.kind = \"machine\"): its reference is the surface under the tool".into(),
                ))
            }
        }
        Ok(cases)
    }
}

/// A protected quantity: an output row of the loops and its limit.
struct Protected {
    what: Limit,
    row: usize,
    limit: f64,
}

/// The two loops' matrices and what they protect.
struct Model {
    normal: Mode,
    held: Mode,
    c: DMatrix<f64>,
    d: DMatrix<f64>,
    p0: DMatrix<f64>,
    protected: Vec<Protected>,
    /// How a change of the running loop's command enters its state (the DAC disturbance).
    b_command: DVector<f64>,
    recovery: usize,
    /// `controller.limit_v`, V.
    limit_v: f64,
    /// `protection.saturation_s` in ticks (`u64::MAX`: off).
    saturation_ticks: u64,
}

/// One loop's matrices, split into the noise inputs and the deterministic ones.
struct Mode {
    a: DMatrix<f64>,
    /// Covariance of the noise entering per tick.
    q: DMatrix<f64>,
    b_ref: DVector<f64>,
    b_force: DVector<f64>,
}

impl Mode {
    fn of(cl: &ClosedLoop, variance: &DVector<f64>) -> Self {
        let b = &cl.sys.b;
        let b_noise = DMatrix::from_fn(b.nrows(), SOURCES.len(), |i, j| b[(i, SOURCES[j].1)]);
        let q = &b_noise * DMatrix::from_diagonal(variance) * b_noise.transpose();
        Mode {
            a: cl.sys.a.clone(),
            q,
            b_ref: b.column(input::REFERENCE_M).into_owned(),
            b_force: b.column(input::CUTTING_FORCE_N).into_owned(),
        }
    }
}

impl Model {
    fn new(normal: &ClosedLoop, held: &ClosedLoop, plan: &Plan) -> Result<Self, RunError> {
        let c = &plan.config;
        let variance = DVector::from_column_slice(&normal.noise_variance);
        let (normal_mode, held_mode) = (Mode::of(normal, &variance), Mode::of(held, &variance));
        let (p0, _) = lti::dlyap(&normal_mode.a, &normal_mode.q)
            .map_err(|e| RunError::StallAnalysis(format!("the loop's noise covariance: {e}")))?;
        let range_m = c.plant.adc.range_v / c.plant.capa.sensitivity_v_per_m;
        let mut protected = vec![Protected {
            what: Limit::SensorRange,
            row: output::MEASURED_M,
            limit: c
                .protection
                .position_limit_m
                .unwrap_or(range_m)
                .min(range_m),
        }];
        if c.protection.following_error_m > 0.0 {
            protected.insert(
                0,
                Protected {
                    what: Limit::FollowingError,
                    row: output::FOLLOWING_ERROR_M,
                    limit: c.protection.following_error_m,
                },
            );
        }
        let radius = normal.spectral_radius();
        let decay_ticks = (libm::log(RECOVERY_DECAY) / libm::log(radius)).ceil();
        let recovery = decay_ticks.min(MAX_RECOVERY_S / plan.period_s()).max(1.0) as usize;
        Ok(Model {
            normal: normal_mode,
            held: held_mode,
            c: normal.sys.c.clone(),
            d: normal.sys.d.clone(),
            p0,
            protected,
            b_command: normal
                .sys
                .b
                .column(input::CONTROL_DISTURBANCE_V)
                .into_owned(),
            recovery,
            limit_v: c.controller.limit_v,
            saturation_ticks: if c.protection.saturation_s > 0.0 {
                (c.protection.saturation_s / plan.period_s()).round() as u64
            } else {
                u64::MAX
            },
        })
    }

    /// The first limit a stall of `m` ticks exceeds in any case (None: it survives).
    fn worst(&self, cases: &Cases, m: usize) -> Option<Limit> {
        let k = cases.x0.len();
        let mut x = DMatrix::from_columns(&cases.x0);
        let mut p = self.p0.clone();
        let force = DMatrix::from_row_slice(1, k, &cases.force);
        let mut r = DMatrix::zeros(1, k);
        let mut saturated = vec![0u64; k];
        let command = self.c.row(output::CONTROL_V);
        let command_ref = self.d[(output::CONTROL_V, input::REFERENCE_M)];
        for j in 0..m + self.recovery {
            let stalled = j < m;
            let mode = if stalled { &self.held } else { &self.normal };
            for (i, t) in cases.reference.iter().enumerate() {
                r[(0, i)] = t.at(j);
            }
            for q in &self.protected {
                let c = self.c.row(q.row);
                let d_ref = self.d[(q.row, input::REFERENCE_M)];
                let sigma = (c * &p).dot(&c).max(0.0).sqrt();
                let worst = (c * &x + &r * d_ref)
                    .iter()
                    .fold(0.0f64, |w, v| w.max(v.abs()));
                if worst + SIGMAS * sigma > q.limit {
                    return Some(q.what);
                }
            }
            let mut next = &mode.a * &x + &mode.b_ref * &r + &mode.b_force * &force;
            if !stalled {
                // The command is clamped at the output limit: the excess comes off as a
                // disturbance on it (the controller's state does not see it — a PID's
                // conditional integration would wind up less: this errs on the safe side).
                let u = command * &x + &r * command_ref;
                for (i, u) in u.iter().enumerate() {
                    let clamped = u.clamp(-self.limit_v, self.limit_v);
                    saturated[i] = if clamped != *u { saturated[i] + 1 } else { 0 };
                    if saturated[i] > self.saturation_ticks {
                        return Some(Limit::Saturation);
                    }
                    next.column_mut(i).axpy(clamped - u, &self.b_command, 1.0);
                }
            }
            x = next;
            p = &mode.a * &p * mode.a.transpose() + &mode.q;
        }
        None
    }
}

/// How a simulated stall went ([`simulate`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StallRun {
    /// The machine-protection trip (cause, tick), if the loop tripped.
    pub trip: Option<(TripCause, u64)>,
    /// The tick at which the plant's watchdog declared the controller lost (0 V, run over).
    pub peer_lost_at: Option<u64>,
    /// The largest |measured position| over every sample, stall included, m.
    pub peak_measured_m: f64,
}

impl StallRun {
    /// The run rode the stall out: no trip, no lost peer.
    pub fn survived(&self) -> bool {
        self.trip.is_none() && self.peer_lost_at.is_none()
    }
}

/// `plan`'s run in lockstep on an injected clock, with its controller silent for the
/// `stall_ticks` ticks from `start_tick` — as a real-time run does it: the DAC holds the last
/// command, the plant's watchdog (peer timeout `peer_timeout_s`, s) judges the silence on the
/// simulated clock, and the controller then takes the newest sample. Runs the plan's
/// duration, or until the loop trips and holds its safe state, or the watchdog ends it.
pub fn simulate(
    plan: &Plan,
    start_tick: u64,
    stall_ticks: u64,
    peer_timeout_s: f64,
) -> Result<StallRun, RunError> {
    let mut backend = plan.stage();
    let mut servo = PlanLoop::new(plan)?;
    let mut watchdog = Watchdog::new(policy(plan, peer_timeout_s));
    let period_ns = period_ns(plan);
    let sensitivity = plan.config.plant.capa.sensitivity_v_per_m;
    let mut out = StallRun {
        trip: None,
        peer_lost_at: None,
        peak_measured_m: 0.0,
    };
    let mut sample = Sensor {
        seq: 0,
        ..backend.initial()
    };
    let mut dac_v = 0.0;
    let stall = start_tick..start_tick.saturating_add(stall_ticks);
    for k in 0..plan.ticks() {
        out.peak_measured_m = out.peak_measured_m.max((sample.gap_v / sensitivity).abs());
        let silent = stall.contains(&k);
        if !silent {
            if let (Some(c), _) = servo.tick(&sample) {
                dac_v = c.dac_v;
            }
            if servo.run_over() {
                break;
            }
        }
        if k > 0 {
            // Published at k·T; answered at once, or silent until the next deadline.
            let now = if silent {
                (k + 1) * period_ns
            } else {
                k * period_ns
            };
            if watchdog.tick(now, k * period_ns, silent, !silent) != Verdict::Ok {
                out.peer_lost_at = Some(k);
                break;
            }
        }
        let s = backend.step(dac_v);
        sample = Sensor { seq: k + 1, ..s };
    }
    out.trip = servo.trip();
    Ok(out)
}

/// Refuses a real-time run whose loop does not survive [`STALL_MARGIN`] × the host's worst
/// stall.
pub fn check_host(survivable: &Survivable, host: &HostStalls) -> Result<(), RunError> {
    if host.worst_s * STALL_MARGIN > survivable.stall_s() {
        return Err(RunError::HostTooSlow(Box::new(Refusal {
            host: host.clone(),
            survivable: *survivable,
        })));
    }
    Ok(())
}
