//! The controller's half of a tick: reference (with preview and smoothing) + feedforward +
//! controller → command and telemetry, machine protection on every sample, bumpless handover
//! of a new controller and bumpless re-arm after a trip. Allocation-free, `no_std`.

use crate::feedforward::Feedforward;
use crate::preview::Window;
use crate::protection::{Observation, Protection, TripCause};
use crate::reference::Reference;
use daq_io::{flags, Command, Sensor, Telemetry};
use servo_config::Controller;
use servo_config::{Allowed, Invalid};
use servo_config::{Deployment, MAX_PREVIEW};

/// A controller on its way into the loop (loads need the standard library): boxed, as it
/// crosses threads and the one it replaces is freed off the ticking thread.
#[cfg(feature = "std")]
pub(crate) type Slot = std::boxed::Box<Controller>;

/// Time constant of a bumpless handover (s): the difference between the old and the new
/// controller's output at the swap tick fades with it (5 ms: slower than the loop's 1–3 kHz
/// bandwidth, so the new controller's own states take over without a kick).
pub(crate) const HANDOVER_TIME_CONSTANT_S: f64 = 5e-3;

/// What the preview window holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Primed {
    /// Nothing yet: the next tick fills it.
    No,
    /// Tick 0's view of the deployment's own reference, filled when the loop was built (so
    /// that the first tick costs what every other does).
    ForTickZero,
    /// The last tick's view: the next tick slides it on.
    Yes,
}

/// The controller's half of a tick: reads tick k's sample, returns tick k's command and its
/// telemetry (the tick's reference with the reading it acted on). A non-finite reading latches
/// the controller's fault: [`flags::FAULT_CONTROLLER`] on the command and telemetry, and a
/// trip.
/// Machine protection checks every sample; once tripped, the command is the configured safe
/// state and carries [`flags::TRIPPED`] with the cause's bit (0 V on a fault when protection
/// is disabled).
// What every tick touches first, the large storage last (see `Servo`).
#[derive(Debug, Clone)]
#[repr(C)]
pub(crate) struct ServoLoop {
    primed: Primed,
    /// The sample tick expected next (`seq` of the last one + 1).
    next_seq: u64,
    last_u: f64,
    /// `last_u` was at the controller's output limit.
    last_saturated: bool,
    /// The command came out non-finite once (latched like a block fault).
    output_fault: bool,
    protection: Protection,
    gain_scale: f64,
    sensitivity: f64,
    accel_scale: f64,
    period_s: f64,
    /// A controller handed over, taking the loop at the next tick.
    #[cfg(feature = "std")]
    incoming: Option<Slot>,
    /// The controller the last handover replaced, to be freed off the ticking thread.
    #[cfg(feature = "std")]
    replaced: Option<Slot>,
    /// The tick the last handover took effect.
    #[cfg(feature = "std")]
    handed_over_at: Option<u64>,
    /// Handovers that took effect.
    handovers: u64,
    /// Re-armed after a trip: the next tick starts from the safe state's command.
    rearm: bool,
    /// Bumpless handover: the old output minus the new one's at the swap tick (V, after the
    /// gain scale), added to the output and decaying by `handover_decay` a tick.
    handover_v: f64,
    handover_decay: f64,
    window: Window,
    feedforward: Feedforward,
    controller: Controller,
}

impl ServoLoop {
    /// No loop yet: storage for [`ServoLoop::rebuild`].
    pub(crate) const UNBUILT: ServoLoop = ServoLoop {
        controller: Controller::UNBUILT,
        feedforward: Feedforward::UNBUILT,
        window: Window::EMPTY,
        primed: Primed::No,
        next_seq: 0,
        last_u: 0.0,
        last_saturated: false,
        output_fault: false,
        protection: Protection::OFF,
        gain_scale: 1.0,
        sensitivity: 1.0,
        accel_scale: 1.0,
        period_s: 0.0,
        #[cfg(feature = "std")]
        incoming: None,
        #[cfg(feature = "std")]
        replaced: None,
        #[cfg(feature = "std")]
        handed_over_at: None,
        handovers: 0,
        rearm: false,
        handover_v: 0.0,
        handover_decay: 0.0,
    };

    /// The loop of `d` in its initial state (`d` checked by the caller).
    #[cfg(all(test, feature = "serve"))]
    pub(crate) fn new(d: &Deployment) -> Result<Self, Invalid> {
        let mut built = ServoLoop::UNBUILT;
        built.rebuild(d)?;
        Ok(built)
    }

    /// The loop of `d` in its initial state, written where `self` lies (`d` checked by the
    /// caller). Refused, naming the key, with `self` partly rebuilt:
    /// rebuild it before it ticks.
    pub(crate) fn rebuild(&mut self, d: &Deployment) -> Result<(), Invalid> {
        let period = d.period_s();
        self.controller.rebuild(&d.controller, &d.stage, period)?;
        self.feedforward
            .rebuild(&d.feedforward, &d.stage, d.controller.limit_v)?;
        let lead = d.feedforward.preview();
        if !self.window.reset(lead, d.smoothing_half()) {
            return Err(Invalid::new(
                "",
                "smoothing_hz",
                d.smoothing_hz,
                Allowed::OffOrAtLeast {
                    low: d.servo_rate_hz / (2.0 * (MAX_PREVIEW.saturating_sub(lead)) as f64 + 1.0),
                    unit: "Hz (the preview holds 62 ticks, the feedforward takes its share)",
                },
            ));
        }
        (self.primed, self.next_seq) = (Primed::No, 0);
        (self.last_u, self.last_saturated) = (0.0, false);
        self.output_fault = false;
        self.protection = Protection::new(&d.protection, d.servo_rate_hz, d.stage.dc_gain_m_per_v);
        self.gain_scale = 1.0;
        self.sensitivity = d.stage.gap_sensitivity_v_per_m;
        self.accel_scale = 1.0 / d.stage.accel_sensitivity_v_per_m_s2;
        self.period_s = period;
        #[cfg(feature = "std")]
        {
            (self.incoming, self.replaced, self.handed_over_at) = (None, None, None);
        }
        (self.handovers, self.rearm, self.handover_v) = (0, false, 0.0);
        self.handover_decay = libm::exp(-period / HANDOVER_TIME_CONSTANT_S);
        Ok(())
    }

    /// Hands the loop to `controller` at the next tick, bumplessly; returns the controller a
    /// handover not yet taken up held (None when the slot was free).
    #[cfg(feature = "std")]
    pub(crate) fn hand_over(&mut self, controller: Slot) -> Option<Slot> {
        self.handed_over_at = None;
        self.incoming.replace(controller)
    }

    /// The controller the last handover replaced (to free off the ticking thread).
    #[cfg(feature = "std")]
    pub(crate) fn take_replaced(&mut self) -> Option<Slot> {
        self.replaced.take()
    }

    /// Controllers handed over so far.
    pub(crate) fn handovers(&self) -> u64 {
        self.handovers
    }

    /// The tick the last handover took effect, once it has.
    #[cfg(feature = "serve")]
    pub(crate) fn handed_over_at(&self) -> Option<u64> {
        self.handed_over_at
    }

    /// Multiplies the controller output by `scale` from the next tick (checked by the caller).
    pub(crate) fn set_gain_scale(&mut self, scale: f64) {
        self.gain_scale = scale;
    }

    /// The cause and tick of the machine-protection trip, if the loop tripped.
    pub(crate) fn trip(&self) -> Option<(TripCause, u64)> {
        self.protection.trip()
    }

    /// Trips since the start, re-armed ones included.
    pub(crate) fn trips(&self) -> u64 {
        self.protection.trips()
    }

    /// Tripped, and the safe state has been held for `protection.after_trip_s` at tick `seq`.
    pub(crate) fn trip_settled(&self, seq: u64) -> bool {
        self.protection.run_over(seq)
    }

    /// Re-arms after a trip: protection cleared, the controller and the feedforward back to
    /// their initial state; the next command starts from the safe state's and the difference
    /// fades like a handover.
    pub(crate) fn rearm(&mut self) {
        self.protection.clear();
        self.controller.reset();
        self.feedforward.reset();
        self.output_fault = false;
        self.rearm = true;
    }

    /// The fault a block latched, as a trip cause (None: no fault). A controller's latch
    /// shows as a NaN output ([`Controller::update`]), caught in `output_fault`.
    fn fault(&self, source_faulted: bool) -> Option<TripCause> {
        if self.output_fault {
            Some(TripCause::NotFinite)
        } else if source_faulted || self.feedforward.faulted() {
            Some(TripCause::ReferenceFault)
        } else {
            None
        }
    }

    /// Reads this tick's reference into the window. The first tick fills it, and so does a
    /// sample that skipped ticks (a loop that fell behind takes the newest sample): the
    /// trajectory stays on the plant's time instead of lagging by the ticks skipped.
    #[inline]
    fn advance<R: Reference + ?Sized>(&mut self, s: &Sensor, source: &mut R) {
        let p = self.window.preview();
        let skipped = s.seq > self.next_seq;
        // Wraps only past 2^64 ticks; a wrapped count reads as ticks skipped (a refill).
        self.next_seq = s.seq.wrapping_add(1);
        if self.primed == Primed::Yes && !skipped {
            let ahead = source.next(s, p);
            self.window.push(ahead);
            self.feedforward.follow(&self.window, false);
        } else if self.primed == Primed::ForTickZero && s.seq == 0 {
            self.primed = Primed::Yes;
        } else {
            self.prime(s, source);
        }
    }

    /// Fills the window with `source`'s view from sample `s` on (and the feedforward's state
    /// with it).
    #[cold]
    #[inline(never)]
    fn prime<R: Reference + ?Sized>(&mut self, s: &Sensor, source: &mut R) {
        self.primed = Primed::Yes;
        self.window.prime(|ahead| source.prime(s, ahead));
        self.feedforward.follow(&self.window, true);
    }

    /// Fills the window with tick 0's view of `source` (the deployment's own reference) now,
    /// at build time; the first tick of `source` then costs what every other does.
    pub(crate) fn prime_for_tick_zero<R: Reference + ?Sized>(&mut self, source: &mut R) {
        self.prime(&Sensor::default(), source);
        self.primed = Primed::ForTickZero;
    }

    /// Forgets a window filled at build time (a host's own reference is about to be ticked:
    /// the first tick fills the window from it).
    #[inline]
    pub(crate) fn forget_tick_zero(&mut self) {
        if self.primed == Primed::ForTickZero {
            self.primed = Primed::No;
        }
    }

    /// One tick for sample `s` with the trajectory `source`: the command, the tick's telemetry
    /// (its reference with the reading it acted on) written into `telemetry`; when `s` closes
    /// the run, 0 V with [`flags::END`] and `telemetry` untouched.
    #[inline]
    pub(crate) fn tick<R: Reference + ?Sized>(
        &mut self,
        s: &Sensor,
        source: &mut R,
        telemetry: &mut Telemetry,
    ) -> Command {
        if s.flags & flags::END != 0 {
            return Command {
                seq: s.seq,
                dac_v: 0.0,
                flags: flags::END,
                reserved: 0,
            };
        }
        let measured = s.gap_v / self.sensitivity;
        self.advance(s, source);
        let desired = self.window.at(0);
        let following = desired - measured;
        let seen = Observation {
            following_error_m: following,
            measured_m: measured,
            gap_clipped: s.flags & flags::GAP_CLIPPED != 0,
            // The previous command: at its limit, or clipped at the DAC (this sample's bit).
            saturated: s.seq > 0 && (self.last_saturated || s.flags & flags::DAC_CLIPPED != 0),
        };
        self.protection.watch(s.seq, &seen, self.last_u);
        // The controller runs until the loop trips; a fault it latches trips it now.
        let raw = self.protection.trip().is_none().then(|| {
            let (u, shaped) = self.control(s);
            // Clamped to the finite limit: only NaN is left to catch.
            if u.is_nan() {
                self.output_fault = true;
            }
            (u, shaped)
        });
        let fault = self.fault(source.faulted());
        if let (Some(cause), Some(_)) = (fault, raw) {
            self.protection.fault(cause, s.seq, self.last_u);
        }
        let u = match raw {
            Some((u, _)) if fault.is_none() => u,
            _ if self.protection.trip().is_some() => self.protection.safe_command(),
            _ => 0.0, // a fault with protection disabled
        };
        let faulted = fault.is_some();
        self.last_u = u;
        let controller_flags =
            if faulted { flags::FAULT_CONTROLLER } else { 0 } | self.protection.flags();
        let saturated = libm::fabs(u) >= self.controller.limit_v();
        self.last_saturated = saturated;
        *telemetry = Telemetry {
            seq: s.seq,
            time_s: s.time_s,
            reference_m: desired,
            measured_m: measured,
            following_error_m: following,
            controller_error_m: raw.map_or(following, |(_, shaped)| shaped - measured),
            control_v: u,
            accel_m_s2: s.accel_v * self.accel_scale,
            flags: (s.flags & !flags::END)
                | if saturated { flags::SATURATED } else { 0 }
                | controller_flags,
            reserved: 0,
        };
        Command {
            seq: s.seq,
            dac_v: u,
            flags: controller_flags,
            reserved: 0,
        }
    }

    /// The handover at tick `seq`: `new` takes the loop, both having seen this tick's errors
    /// (`raw` the old one's output); returns the new one's output, the difference left to fade.
    #[cfg(feature = "std")]
    #[cold]
    #[inline(never)]
    fn take_over(&mut self, mut new: Slot, raw: f64, error_v: f64, accel_v: f64, seq: u64) -> f64 {
        // A controller that faulted as it was replaced leaves no bump to fade.
        let raw = if raw.is_nan() { 0.0 } else { raw };
        core::mem::swap(&mut self.controller, &mut *new);
        self.replaced = Some(new);
        let raw_new = self.controller.update(error_v, accel_v);
        self.handover_v = (raw - raw_new) * self.gain_scale;
        self.handed_over_at = Some(seq);
        self.handovers += 1;
        raw_new
    }

    /// The controller's command for sample `s` (feedback on the smoothed reference plus the
    /// feedforward, scaled and clamped to the output limit), in V, and the shaped reference the
    /// feedback followed, in m.
    #[inline]
    fn control(&mut self, s: &Sensor) -> (f64, f64) {
        let (reference, u_ff) = self.feedforward.evaluate(&self.window, self.period_s);
        let (error_v, accel_v) = (reference * self.sensitivity - s.gap_v, s.accel_v);
        let raw = self.controller.update(error_v, accel_v);
        #[cfg(feature = "std")]
        let raw = match self.incoming.take() {
            Some(new) => self.take_over(new, raw, error_v, accel_v, s.seq),
            None => raw,
        };
        if self.rearm {
            // Re-armed: this tick's command is the safe state's; the difference fades.
            self.rearm = false;
            self.handover_v = self.last_u - (raw * self.gain_scale + u_ff);
        }
        let handover = self.handover_v;
        self.handover_v *= self.handover_decay;
        let limit = self.controller.limit_v();
        (
            (raw * self.gain_scale + handover + u_ff).clamp(-limit, limit),
            reference,
        )
    }
}
