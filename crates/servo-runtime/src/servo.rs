//! The front door: one [`Servo`] a daemon holds and ticks.

use crate::check::Invalid;
#[cfg(feature = "std")]
use crate::deployment::Stage;
use crate::deployment::{Deployment, Stability};
use crate::protection::TripCause;
use crate::reference::{Generator, Reference};
use crate::servo_loop::ServoLoop;
use daq_io::{flags, Command, Sensor, Telemetry};

/// A machine-protection trip: why, and the tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Trip {
    /// Which limit (or latched fault) tripped the loop.
    pub cause: TripCause,
    /// The tick whose command was the first in the safe state.
    pub tick: u64,
}

/// What a [`Servo`] has done so far ([`Servo::status`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Status {
    /// Ticks run (commands given).
    pub ticks: u64,
    /// The trip the loop is in, if any (until [`Servo::reset`]).
    pub trip: Option<Trip>,
    /// Tripped, and the safe state has been held for `protection.after_trip_s`: a run may end.
    pub trip_settled: bool,
    /// A stop the control plane asked for ([`daq_io::stop_cause`]), if any.
    pub stop: Option<u32>,
    /// The output scale in force (dimensionless, 1 as deployed).
    pub gain_scale: f64,
    /// Ticks whose command was at the output limit.
    pub saturated_ticks: u64,
    /// Controllers handed over while running ([`Servo::load`], `servo ctl load`).
    pub handovers: u64,
    /// Trips since the start (each re-arm clears one).
    pub trips: u64,
    /// Ticks that started a whole period or more after their sample was taken
    /// ([`Sensor::published_ns`]; `std` only, 0 otherwise).
    pub overruns: u64,
    /// Telemetry records a served loop dropped because its service thread fell behind (the
    /// tick never waits; feature `serve`, 0 otherwise).
    pub telemetry_dropped: u64,
}

/// Why a gain change was refused ([`Servo::set_gain`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GainRefused {
    /// The deployment carries no checked stability range.
    NotChecked,
    /// Outside `low..=high` (the stable range with the margin), or not a number.
    OutOfRange {
        /// The requested scale.
        scale: f64,
        /// The lowest scale allowed.
        low: f64,
        /// The highest scale allowed.
        high: f64,
    },
}

impl core::fmt::Display for GainRefused {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            GainRefused::NotChecked => f.write_str(
                "gain change refused: the deployment carries no [stability] record (check the loop offline with `servo deploy`)",
            ),
            GainRefused::OutOfRange { scale, low, high } => write!(
                f,
                "gain scale {scale} refused: allowed {low:.4}..={high:.4} (the stable range with a 2× margin on each side)"
            ),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for GainRefused {}

/// The controller a daemon embeds: reference with preview, feedforward, the feedback
/// controller, machine protection and its safe state, bumpless controller swap and checked gain
/// changes — built once from a [`Deployment`], ticked once per sample.
///
/// [`Servo::tick`] never allocates, locks, logs or panics; a non-finite reading, a saturated
/// command held too long, a following error or a reading beyond the sensor's range trips the
/// loop to its safe state, which it keeps until [`Servo::reset`].
///
/// ```
/// use servo_runtime::{Deployment, Servo};
/// let mut servo = Servo::new(&Deployment::thesis_prototype())?;
/// let mut sample = daq_io::Sensor::default();
/// for k in 0..1000 {
///     sample.seq = k;
///     sample.gap_v = 0.0; // read the ADC here
///     let command = servo.tick(&sample);
///     assert!(command.dac_v.abs() <= 10.0); // write the DAC here
/// }
/// assert_eq!(servo.status().ticks, 1000);
/// # Ok::<(), servo_runtime::Invalid>(())
/// ```
pub struct Servo {
    core: ServoLoop,
    generator: Generator,
    #[cfg(feature = "std")]
    stage: Stage,
    period_s: f64,
    stability: Option<Stability>,
    last: Option<Telemetry>,
    status: Status,
    #[cfg(feature = "std")]
    pub(crate) host: crate::host::Host,
}

impl Servo {
    /// The loop of `deployment`, checked ([`Deployment::check`]) and built, in its initial
    /// state.
    pub fn new(deployment: &Deployment) -> Result<Self, Invalid> {
        deployment.check()?;
        Ok(Servo {
            core: ServoLoop::new(deployment)?,
            generator: Generator::build(&deployment.reference, deployment.period_s())?,
            #[cfg(feature = "std")]
            stage: deployment.stage,
            period_s: deployment.period_s(),
            stability: deployment.stability,
            last: None,
            status: Status {
                ticks: 0,
                trip: None,
                trip_settled: false,
                stop: None,
                gain_scale: 1.0,
                saturated_ticks: 0,
                handovers: 0,
                trips: 0,
                overruns: 0,
                telemetry_dropped: 0,
            },
            #[cfg(feature = "std")]
            host: crate::host::Host::new(deployment),
        })
    }

    /// One tick on the deployment's own reference: reads sample `k`, returns command `k`.
    /// A sample flagged [`flags::END`] closes the run: its command is 0 V with `END`.
    #[inline]
    pub fn tick(&mut self, sample: &Sensor) -> Command {
        #[cfg(feature = "std")]
        let started = self.host.start(sample);
        let (command, telemetry) = self.core.tick(sample, &mut self.generator);
        let command = self.close_tick(sample, command, telemetry);
        #[cfg(feature = "std")]
        self.after_tick(sample, started);
        command
    }

    /// One tick on the host's trajectory `reference` (a tool path, a spindle-synchronised
    /// surface), read ahead by the loop's preview.
    #[inline]
    pub fn tick_with<R: Reference + ?Sized>(
        &mut self,
        sample: &Sensor,
        reference: &mut R,
    ) -> Command {
        #[cfg(feature = "std")]
        let started = self.host.start(sample);
        let (command, telemetry) = self.core.tick(sample, reference);
        let command = self.close_tick(sample, command, telemetry);
        #[cfg(feature = "std")]
        self.after_tick(sample, started);
        command
    }

    /// Keeps tick `sample`'s telemetry and counts what it did; the command (0 V with
    /// [`flags::END`] for a closing sample).
    #[inline]
    fn close_tick(
        &mut self,
        sample: &Sensor,
        command: Option<Command>,
        telemetry: Option<Telemetry>,
    ) -> Command {
        self.last = telemetry;
        let command = command.unwrap_or(Command {
            seq: sample.seq,
            dac_v: 0.0,
            flags: flags::END,
            reserved: 0,
        });
        self.account(sample, &command);
        command
    }

    /// Counts what tick `sample` did.
    #[inline]
    fn account(&mut self, sample: &Sensor, command: &Command) {
        let st = &mut self.status;
        if command.flags & flags::END != 0 {
            return;
        }
        if let Some(t) = &self.last {
            st.saturated_ticks += u64::from(t.flags & flags::SATURATED != 0);
        }
        st.ticks += 1;
        let trip = self.core.trip().map(|(cause, tick)| Trip { cause, tick });
        if trip.is_some() && st.trip.is_none() {
            st.trips += 1;
        }
        st.trip = trip;
        st.handovers = self.core.handovers();
        st.trip_settled = self.core.trip_settled(sample.seq);
    }

    /// The last tick's telemetry: its reference, the reading it acted on, the following error
    /// and the feedback's own error, its command and flags. None before the first tick and
    /// after a closing sample.
    pub fn telemetry(&self) -> Option<&Telemetry> {
        self.last.as_ref()
    }

    /// What the loop has done so far.
    pub fn status(&self) -> Status {
        #[cfg(feature = "std")]
        {
            Status {
                overruns: self.host.overruns(),
                telemetry_dropped: self.host.telemetry_dropped(),
                ..self.status
            }
        }
        #[cfg(not(feature = "std"))]
        {
            self.status
        }
    }

    /// The checked stability range the loop carries (None: not checked offline).
    pub fn stability(&self) -> Option<Stability> {
        self.stability
    }

    /// Scales the controller output by `scale` (dimensionless) from the next tick — refused
    /// unless the offline check ([`Stability`]) allows it with its margin.
    pub fn set_gain(&mut self, scale: f64) -> Result<(), GainRefused> {
        let s = self.stability.ok_or(GainRefused::NotChecked)?;
        if !s.allows(scale) {
            return Err(GainRefused::OutOfRange {
                scale,
                low: s.low(),
                high: s.high(),
            });
        }
        self.apply_gain(scale);
        Ok(())
    }

    /// Sets the output scale (checked by the caller).
    pub(crate) fn apply_gain(&mut self, scale: f64) {
        self.core.set_gain_scale(scale);
        self.status.gain_scale = scale;
    }

    /// Re-arms the loop after a trip: protection cleared, the controller and feedforward back
    /// to their initial state; the first command starts from the safe state's and the
    /// difference fades in 5 ms. A stop request is cleared too.
    pub fn reset(&mut self) {
        self.core.rearm();
        self.status.trip = None;
        self.status.trip_settled = false;
        self.status.stop = None;
    }

    /// Asks the daemon to end the run ([`Status::stop`]), with a [`daq_io::stop_cause`].
    pub fn request_stop(&mut self, cause: u32) {
        self.status.stop.get_or_insert(cause);
    }

    /// The servo period in s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// The stage numbers the loop was deployed with.
    #[cfg(feature = "std")]
    pub(crate) fn stage(&self) -> &Stage {
        &self.stage
    }

    /// The loop core (for the host layer: handovers).
    #[cfg(feature = "std")]
    pub(crate) fn core_mut(&mut self) -> &mut ServoLoop {
        &mut self.core
    }

    /// Replaces the checked stability range (a loaded controller brings its own).
    #[cfg(feature = "std")]
    pub(crate) fn set_stability(&mut self, s: Stability) {
        self.stability = Some(s);
    }
}
