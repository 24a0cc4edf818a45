//! The controller's half of a tick, shared by the in-process run and the HIL controller
//! process so both compute bit-identical results: reference (generator or machined surface,
//! with preview) + feedforward + controller → command and telemetry.

use crate::config::{ConfigError, Scenario};
use crate::controller::Controller;
use crate::feedforward::Feedforward;
use crate::machining::SurfaceReference;
use crate::plan::Plan;
use crate::preview::{Window, MAX_PREVIEW};
use crate::protection::{Observation, Protection, TripCause};
use daq_io::{flags, Command, Sensor, Telemetry};
use servo_core::{Block, ChirpConfig, SineConfig, StepConfig, Sweep};

/// Where the desired trajectory comes from (m, one sample per tick).
enum Source {
    Zero,
    Gen(Box<dyn Block<Input = (), Output = servo_core::Setpoint> + Send>),
    Surface(Box<SurfaceReference>),
}

impl Source {
    fn new(plan: &Plan) -> Result<Self, ConfigError> {
        let c = &plan.config;
        let (period, duration) = (c.plant.period_s(), c.run.duration_s);
        let scenario = |e: servo_core::Error| plan.origin.invalid("scenario", e, "see the message");
        Ok(match &c.scenario {
            Scenario::Hold | Scenario::IntermittentCut { .. } => Source::Zero,
            Scenario::Sine {
                amplitude_m,
                frequency_hz,
            } => Source::Gen(Box::new(
                SineConfig {
                    amplitude: *amplitude_m,
                    frequency_hz: *frequency_hz,
                    phase_rad: 0.0,
                    offset: 0.0,
                }
                .try_build(period)
                .map_err(scenario)?,
            )),
            Scenario::Step { amplitude_m, at_s } => Source::Gen(Box::new(
                StepConfig {
                    amplitude: *amplitude_m,
                    delay_s: *at_s,
                }
                .try_build(period)
                .map_err(scenario)?,
            )),
            Scenario::Chirp {
                amplitude_m,
                f_start_hz,
                f_end_hz,
            } => Source::Gen(Box::new(
                ChirpConfig {
                    amplitude: *amplitude_m,
                    f_start_hz: *f_start_hz,
                    f_end_hz: *f_end_hz,
                    duration_s: duration,
                    sweep: Sweep::Exponential,
                }
                .try_build(period)
                .map_err(scenario)?,
            )),
            Scenario::Machine(m) => {
                let surface = plan
                    .surface
                    .clone()
                    .expect("a machining plan has its surface");
                Source::Surface(Box::new(
                    SurfaceReference::new(m, surface, period).map_err(scenario)?,
                ))
            }
        })
    }

    /// The desired position `ahead` ticks after this one (generators are sequential: they
    /// are simply run `ahead` ticks early).
    #[inline]
    fn ahead(&mut self, s: &Sensor, ahead: usize) -> f64 {
        match self {
            Source::Zero => 0.0,
            Source::Gen(g) => g.update(()).position,
            Source::Surface(r) => {
                r.track(s.encoder_count);
                r.height_m(ahead)
            }
        }
    }

    /// The trajectory from this tick to `out.len() − 1` ticks ahead, at the first tick.
    fn prime(&mut self, s: &Sensor, out: &mut [f64]) {
        match self {
            Source::Zero => out.iter_mut().for_each(|v| *v = 0.0),
            Source::Gen(g) => out.iter_mut().for_each(|v| *v = g.update(()).position),
            Source::Surface(r) => {
                r.track(s.encoder_count);
                for (j, v) in out.iter_mut().enumerate() {
                    *v = r.height_m(j);
                }
            }
        }
    }

    fn faulted(&self) -> bool {
        match self {
            Source::Zero => false,
            Source::Gen(g) => g.faulted(),
            Source::Surface(r) => r.faulted(),
        }
    }
}

/// The controller's half of a tick: reads tick k's sample, returns tick k's command and the
/// telemetry of tick k−1 (what the sample at its end showed). A non-finite reading latches the
/// controller's fault: [`flags::FAULT_CONTROLLER`] on the command and telemetry, and a trip.
/// Machine protection ([`Protection`]) checks every sample; once tripped, the command is the
/// configured safe state and carries [`flags::TRIPPED`] with the cause's bit (0 V on a fault
/// when protection is disabled).
pub struct ServoLoop {
    /// The controller.
    pub controller: Controller,
    source: Source,
    feedforward: Feedforward,
    window: Window,
    primed: bool,
    r: f64,
    last_u: f64,
    /// Whether any block had latched a fault after the last command.
    last_fault: bool,
    /// The command came out non-finite once (latched like a block fault).
    output_fault: bool,
    /// The protection flags of the last command.
    last_trip_flags: u32,
    protection: Protection,
    gain_scale: f64,
    sensitivity: f64,
    accel_scale: f64,
    period_s: f64,
    /// A controller handed over, taking the loop at the next tick.
    incoming: Option<Controller>,
    /// The controller it replaced, to be dropped off the ticking thread.
    replaced: Option<Controller>,
    /// The tick the last handover took effect.
    handed_over_at: Option<u64>,
    /// Bumpless handover: the old controller's output minus the new one's at the swap tick
    /// (V, after the gain scale), added to the output and decaying by `handover_decay` a tick.
    handover_v: f64,
    handover_decay: f64,
}

/// Time constant of a bumpless handover (s): the difference between the old and the new
/// controller's output at the swap tick fades with it (5 ms: slower than the loop's 1–3 kHz
/// bandwidth, so the new controller's own states take over without a kick).
pub const HANDOVER_TIME_CONSTANT_S: f64 = 5e-3;

impl ServoLoop {
    /// The controller, reference and feedforward of `plan`, in their initial state.
    pub fn new(plan: &Plan) -> Result<Self, ConfigError> {
        let c = &plan.config;
        let controller = plan.controller.clone();
        let source = Source::new(plan)?;
        let feedforward = plan.feedforward.clone();
        let preview = feedforward.preview();
        let rate = c.plant.timing.servo_rate_hz;
        let smoothing = c.controller.smoothing_hz;
        let half = if smoothing > 0.0 {
            (rate / smoothing / 2.0).round() as usize
        } else {
            0
        };
        let window = Window::new(preview, half).ok_or_else(|| {
            plan.origin.invalid(
                "controller.smoothing_hz",
                smoothing,
                &format!(
                    "0 (off) or ≥ {:.0} Hz (the preview holds {MAX_PREVIEW} ticks; the feedforward needs {preview})",
                    rate / (2.0 * (MAX_PREVIEW - preview) as f64 + 1.0)
                ),
            )
        })?;
        Ok(ServoLoop {
            controller,
            source,
            feedforward,
            window,
            primed: false,
            r: 0.0,
            last_u: 0.0,
            last_fault: false,
            output_fault: false,
            last_trip_flags: 0,
            protection: Protection::new(&c.protection, &c.plant),
            gain_scale: 1.0,
            sensitivity: c.plant.capa.sensitivity_v_per_m,
            accel_scale: 1.0 / c.plant.accel.sensitivity_v_per_m_s2,
            period_s: c.plant.period_s(),
            incoming: None,
            replaced: None,
            handed_over_at: None,
            handover_v: 0.0,
            handover_decay: (-c.plant.period_s() / HANDOVER_TIME_CONSTANT_S).exp(),
        })
    }

    /// Hands the loop to `controller` at the next tick, bumplessly: at that tick the command
    /// is the old controller's, and the difference to the new one's fades with
    /// [`HANDOVER_TIME_CONSTANT_S`]. Built off the ticking thread (this only moves it).
    pub fn hand_over(&mut self, controller: Controller) {
        self.incoming = Some(controller);
        self.handed_over_at = None;
    }

    /// The scale on the controller output (`servo ctl gain`), dimensionless.
    pub fn gain_scale(&self) -> f64 {
        self.gain_scale
    }

    /// The tick the last handover took effect, once it has.
    pub fn handed_over_at(&self) -> Option<u64> {
        self.handed_over_at
    }

    /// The controller the last handover replaced, to drop off the ticking thread.
    pub fn take_replaced(&mut self) -> Option<Controller> {
        self.replaced.take()
    }

    /// Multiplies the controller output (all gains of a linear controller) by `scale`
    /// (dimensionless), clamped to the output limit. Takes effect at the next tick.
    pub fn set_gain_scale(&mut self, scale: f64) {
        self.gain_scale = scale;
    }

    /// The fault a block latched, as a trip cause (None: no fault).
    fn fault(&self) -> Option<TripCause> {
        if self.controller.faulted() || self.output_fault {
            Some(TripCause::NotFinite)
        } else if self.source.faulted() || self.feedforward.faulted() {
            Some(TripCause::ReferenceFault)
        } else {
            None
        }
    }

    /// The cause and tick of the machine-protection trip, if the loop tripped.
    pub fn trip(&self) -> Option<(TripCause, u64)> {
        self.protection.trip()
    }

    /// Whether the run should end after tick `seq`: the loop tripped and has held the safe
    /// state for `protection.after_trip_s`.
    #[inline]
    pub fn run_over(&self, seq: u64) -> bool {
        self.protection.run_over(seq)
    }

    /// Reads this tick's reference into the window (the first tick fills it).
    #[inline]
    fn advance(&mut self, s: &Sensor) {
        let p = self.window.preview();
        if !self.primed {
            self.primed = true;
            let mut ahead = [0.0; MAX_PREVIEW + 1];
            self.source.prime(s, &mut ahead[..=p]);
            self.window.prime(&ahead);
            return;
        }
        let ahead = self.source.ahead(s, p);
        self.window.push(ahead);
    }

    /// One tick for sample `s`: the command (None when `s` closes the run) and the telemetry
    /// of the previous tick (None for the first sample). Allocation-free.
    #[inline]
    pub fn tick(&mut self, s: &Sensor) -> (Option<Command>, Option<Telemetry>) {
        let faulted = self.last_fault;
        let telemetry = (s.seq > 0).then(|| {
            let measured = s.gap_v / self.sensitivity;
            let saturated =
                self.last_u.abs() >= self.controller.limit_v || s.flags & flags::DAC_CLIPPED != 0;
            Telemetry {
                seq: s.seq - 1,
                time_s: s.time_s,
                reference_m: self.r,
                measured_m: measured,
                following_error_m: self.r - measured,
                control_v: self.last_u,
                accel_m_s2: s.accel_v * self.accel_scale,
                flags: (s.flags & !flags::END)
                    | if saturated { flags::SATURATED } else { 0 }
                    | if faulted { flags::FAULT_CONTROLLER } else { 0 }
                    | self.last_trip_flags,
                reserved: 0,
            }
        });
        if s.flags & flags::END != 0 {
            return (None, telemetry);
        }
        if let Some(t) = &telemetry {
            let seen = Observation {
                following_error_m: t.following_error_m,
                measured_m: t.measured_m,
                gap_clipped: s.flags & flags::GAP_CLIPPED != 0,
                saturated: t.flags & flags::SATURATED != 0,
            };
            self.protection.watch(s.seq, &seen, self.last_u);
        }
        self.advance(s);
        let desired = self.window.at(0);
        // The controller runs until the loop trips; a fault it latches trips it now.
        let raw = self.protection.trip().is_none().then(|| {
            let u = self.control(s);
            self.output_fault |= !u.is_finite();
            u
        });
        let fault = self.fault();
        if let (Some(cause), Some(_)) = (fault, raw) {
            self.protection.fault(cause, s.seq, self.last_u);
        }
        let u = match raw {
            Some(u) if fault.is_none() => u,
            _ if self.protection.trip().is_some() => self.protection.safe_command(),
            _ => 0.0, // a fault with protection disabled
        };
        let faulted = fault.is_some();
        self.last_u = u;
        self.last_fault = faulted;
        self.last_trip_flags = self.protection.flags();
        self.r = desired;
        let command = Command {
            seq: s.seq,
            dac_v: u,
            flags: if faulted { flags::FAULT_CONTROLLER } else { 0 } | self.last_trip_flags,
            reserved: 0,
        };
        (Some(command), telemetry)
    }

    /// The controller's command for sample `s` (feedback on the smoothed reference plus the
    /// feedforward, scaled and clamped to the output limit), in V.
    #[inline]
    fn control(&mut self, s: &Sensor) -> f64 {
        let w = &self.window;
        let (reference, u_ff) = match &mut self.feedforward {
            Feedforward::None => (w.smooth(0), 0.0),
            Feedforward::Model(ff) => {
                let t = self.period_s;
                let (prev, now, next) = (w.smooth(-1), w.smooth(0), w.smooth(1));
                let sp = servo_core::Setpoint {
                    position: now,
                    velocity: (next - prev) / (2.0 * t),
                    acceleration: (next - 2.0 * now + prev) / (t * t),
                };
                (now, ff.update(sp))
            }
            Feedforward::Zpetc(z) => (z.update(w.smooth(z.preview() as isize)), 0.0),
        };
        let (error_v, accel_v) = (reference * self.sensitivity - s.gap_v, s.accel_v);
        let mut raw = self.controller.update(error_v, accel_v);
        if let Some(new) = self.incoming.take() {
            // The swap: both see this tick; the command stays the old one's.
            let old = std::mem::replace(&mut self.controller, new);
            let raw_new = self.controller.update(error_v, accel_v);
            self.handover_v = (raw - raw_new) * self.gain_scale;
            raw = raw_new;
            self.replaced = Some(old);
            self.handed_over_at = Some(s.seq);
        }
        let handover = self.handover_v;
        self.handover_v *= self.handover_decay;
        let limit = self.controller.limit_v;
        (raw * self.gain_scale + handover + u_ff).clamp(-limit, limit)
    }
}
