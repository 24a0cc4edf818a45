//! The front door: one [`Servo`] a daemon holds and ticks.

use crate::reference::{Generator, Reference};
use crate::servo_loop::ServoLoop;
use crate::status::{GainRefused, Status, Trip};
use daq_io::{flags, Command, Sensor, Telemetry};
use servo_config::Invalid;
#[cfg(feature = "std")]
use servo_config::Stage;
use servo_config::{Deployment, Stability};

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
// In declaration order, what every tick touches first and the loop's large storage last: a
// microcontroller reaches a field within a few KiB of the loop's address in one instruction.
#[repr(C)]
pub struct Servo {
    /// The last tick's telemetry, written in place by the tick; valid when `has_last`.
    last: Telemetry,
    has_last: bool,
    status: Status,
    period_s: f64,
    stability: Option<Stability>,
    generator: Generator,
    #[cfg(feature = "std")]
    stage: Stage,
    core: ServoLoop,
    #[cfg(feature = "std")]
    host: crate::host::Host,
    #[cfg(feature = "serve")]
    link: Option<crate::serve::Link>,
}

/// What a loop has done when it starts.
const STARTED: Status = Status {
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
};

/// The telemetry before a first tick.
const NO_TELEMETRY: Telemetry = Telemetry {
    seq: 0,
    time_s: 0.0,
    reference_m: 0.0,
    measured_m: 0.0,
    following_error_m: 0.0,
    controller_error_m: 0.0,
    control_v: 0.0,
    accel_m_s2: 0.0,
    flags: 0,
    reserved: 0,
};

impl Servo {
    /// The loop of `deployment`, checked ([`Deployment::check`]) and built, in its initial
    /// state.
    pub fn new(deployment: &Deployment) -> Result<Self, Invalid> {
        let mut servo = Servo {
            last: NO_TELEMETRY,
            has_last: false,
            status: STARTED,
            period_s: 0.0,
            stability: None,
            generator: Generator::HOLD,
            #[cfg(feature = "std")]
            stage: deployment.stage,
            core: ServoLoop::UNBUILT,
            #[cfg(feature = "std")]
            host: crate::host::Host::new(deployment),
            #[cfg(feature = "serve")]
            link: None,
        };
        servo.build(deployment)?;
        Ok(servo)
    }

    /// Checks `deployment` and builds its loop where `self` lies, in its initial state (the
    /// standard library's parts aside): what [`Servo::new`] and, without it,
    /// `Servo::rebuild` do. Refused, naming the key, with the loop partly rebuilt.
    fn build(&mut self, deployment: &Deployment) -> Result<(), Invalid> {
        deployment.check()?;
        self.core.rebuild(deployment)?;
        self.generator = Generator::build(&deployment.reference, deployment.period_s())?;
        self.period_s = deployment.period_s();
        self.stability = deployment.stability;
        (self.last, self.has_last, self.status) = (NO_TELEMETRY, false, STARTED);
        self.core.prime_for_tick_zero(&mut self.generator);
        Ok(())
    }

    /// One tick on the deployment's own reference: reads sample `k`, returns command `k`.
    /// A sample flagged [`flags::END`] closes the run: its command is 0 V with `END`.
    #[inline]
    pub fn tick(&mut self, sample: &Sensor) -> Command {
        #[cfg(feature = "std")]
        let started = self.host.start(sample);
        let command = self.core.tick(sample, &mut self.generator, &mut self.last);
        self.close_tick(&command);
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
        self.core.forget_tick_zero();
        let command = self.core.tick(sample, reference, &mut self.last);
        self.close_tick(&command);
        #[cfg(feature = "std")]
        self.after_tick(sample, started);
        command
    }

    /// Counts what tick `command` closed: the ticks and the saturated ones (the rest of
    /// [`Status`] is read from the loop when asked for). A closing sample's command (0 V with
    /// [`flags::END`]) leaves no telemetry.
    #[inline]
    fn close_tick(&mut self, command: &Command) {
        self.has_last = command.flags & flags::END == 0;
        if self.has_last {
            let st = &mut self.status;
            st.saturated_ticks += u64::from(self.last.flags & flags::SATURATED != 0);
            st.ticks += 1;
        }
    }

    /// The last tick's telemetry: its reference, the reading it acted on, the following error
    /// and the feedback's own error, its command and flags. None before the first tick and
    /// after a closing sample.
    pub fn telemetry(&self) -> Option<&Telemetry> {
        self.has_last.then_some(&self.last)
    }

    /// What the loop has done so far.
    pub fn status(&self) -> Status {
        let status = Status {
            trip: self.core.trip().map(|(cause, tick)| Trip { cause, tick }),
            // The last tick's sample (a closing sample leaves its telemetry in place).
            trip_settled: self.core.trip_settled(self.last.seq),
            handovers: self.core.handovers(),
            trips: self.core.trips(),
            ..self.status
        };
        #[cfg(feature = "std")]
        {
            #[cfg(feature = "serve")]
            let dropped = self.host.dropped + self.link.as_ref().map_or(0, |l| l.dropped());
            #[cfg(not(feature = "serve"))]
            let dropped = 0;
            Status {
                overruns: self.host.overruns(),
                telemetry_dropped: dropped,
                ..status
            }
        }
        #[cfg(not(feature = "std"))]
        {
            status
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
        self.core.set_gain_scale(scale);
        self.status.gain_scale = scale;
        Ok(())
    }

    /// Re-arms the loop after a trip: protection cleared, the controller and feedforward back
    /// to their initial state; the first command starts from the safe state's and the
    /// difference fades in 5 ms. A stop request is cleared too.
    pub fn reset(&mut self) {
        self.core.rearm();
        self.status.stop = None;
    }

    /// The servo period in s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// After the tick of `sample` (started at `started_ns`): its timing and, when served, the
    /// exchange with the service thread.
    #[cfg(feature = "std")]
    #[inline]
    fn after_tick(&mut self, sample: &Sensor, started_ns: u64) {
        self.host.record(sample, started_ns);
        #[cfg(feature = "serve")]
        if let Some(link) = &mut self.link {
            crate::serve::after_tick(
                link,
                sample,
                crate::serve::TickView {
                    core: &mut self.core,
                    status: &mut self.status,
                    stability: &mut self.stability,
                    telemetry: self.has_last.then_some(&self.last),
                    host: &self.host,
                },
            );
        }
    }
}

/// Without the standard library: a loop built where it runs (a microcontroller's `static`).
#[cfg(not(feature = "std"))]
impl Servo {
    /// No loop yet: its commands are 0 V. The initial value of a `static` that
    /// [`Servo::rebuild`] builds the loop in, so that building needs a few KiB of stack
    /// instead of the loop's size several times over.
    pub const UNBUILT: Servo = Servo {
        core: ServoLoop::UNBUILT,
        generator: Generator::HOLD,
        period_s: 0.0,
        stability: None,
        last: NO_TELEMETRY,
        has_last: false,
        status: STARTED,
    };

    /// [`Servo::new`] in place: the loop of `deployment`, checked and built where `self`
    /// lies, in its initial state (the same loop, tick for tick). Refused, naming the key, as
    /// `new` refuses; `self` is then partly rebuilt: rebuild it before it ticks.
    pub fn rebuild(&mut self, deployment: &Deployment) -> Result<(), Invalid> {
        self.build(deployment)
    }
}

/// With the standard library: deployment files, loads, timing.
#[cfg(feature = "std")]
impl Servo {
    /// The loop of the deployment `text` (TOML, as `servo deploy` writes it), checked and built.
    pub fn from_toml(text: &str) -> Result<Self, crate::ConfigError> {
        Self::from_text(text, &crate::Origin::default())
    }

    /// The loop of the deployment file `path` (a regular file of at most 4 MiB), checked and
    /// built; errors name the file, line, key and allowed range.
    pub fn from_file(path: impl AsRef<std::path::Path>) -> Result<Self, crate::ConfigError> {
        let path = path.as_ref();
        let text = crate::read_text(path)?;
        Self::from_text(
            &text,
            &crate::Origin {
                path: Some(path.to_owned()),
                text: None,
            },
        )
    }

    fn from_text(text: &str, at: &crate::Origin) -> Result<Self, crate::ConfigError> {
        let at = crate::Origin {
            text: Some(text.to_owned()),
            ..at.clone()
        };
        let d = crate::parse_deployment(text, &at)?;
        let mut servo = Servo::new(&d.deployment).map_err(|e| at.located(&e))?;
        servo.host.made_for = d.made_for;
        Ok(servo)
    }

    /// Loads the controller file `file` (UTF-8 TOML: a `[controller]` table, or a state-space
    /// file as `servo synth` writes it) into the running loop: checked by the deployment's rule
    /// (made for this plant and rate, carrying its offline stability check, whose range allows
    /// the output scale in force), built, and handed over bumplessly at the next tick. Parses
    /// and allocates on the calling thread: call it between ticks from a thread that may — or
    /// prepare the load on another thread ([`Servo::loader`]) and [`Servo::swap`] it in here,
    /// or let [`Servo::serve`] take loads (`servo ctl load`) on its own thread.
    pub fn load(&mut self, file: &[u8]) -> Result<(), crate::LoadError> {
        let mut prepared = self.loader().prepare(file)?;
        self.swap(&mut prepared)
    }

    /// The check this loop's controller files pass, owned: [`crate::Loader::prepare`] it on
    /// any thread while the loop ticks. Allocates: call it between ticks.
    pub fn loader(&self) -> crate::Loader {
        crate::Loader {
            check: crate::CarriedCheck {
                made_for: self.host.made_for.clone(),
                servo_rate_hz: self.host.servo_rate_hz,
                stage: self.stage,
                running: self.host.spec.clone(),
            },
            stage: self.stage,
            period_s: self.period_s,
        }
    }

    /// Hands the loop to the prepared controller at the next tick, bumplessly — on the ticking
    /// thread between ticks: no allocation, parse, lock or free (the controller it replaces,
    /// and one a handover not yet taken up held, move into `prepared`; drop it off the ticking
    /// thread). Refused, `prepared` untouched, when the output scale in force lies outside the
    /// prepared loop's stable range, when `prepared` was swapped in already, or when it was
    /// prepared for another loop (another stage or rate).
    pub fn swap(&mut self, prepared: &mut crate::Prepared) -> Result<(), crate::LoadError> {
        if prepared.stage != self.stage || prepared.period_s != self.period_s {
            return Err(crate::LoadError::OtherLoop);
        }
        let scale = self.status.gain_scale;
        if !prepared.stability.allows(scale) {
            return Err(crate::LoadError::Margin {
                scale,
                low: prepared.stability.low(),
                high: prepared.stability.high(),
            });
        }
        let Some(controller) = prepared.controller.take() else {
            return Err(crate::LoadError::Spent);
        };
        prepared.retired = [self.core.take_replaced(), self.core.hand_over(controller)];
        self.stability = Some(prepared.stability);
        core::mem::swap(&mut self.host.spec, &mut prepared.spec);
        Ok(())
    }

    /// Percentiles of the tick timing so far (ticks whose sample carried
    /// [`Sensor::published_ns`]; nothing is timed otherwise).
    pub fn timing(&self) -> crate::Timing {
        self.host.timing()
    }
}

/// Serving the loop (feature `serve`).
#[cfg(feature = "serve")]
impl Servo {
    /// Serves this loop on run `prefix` as an embedding daemon
    /// ([`crate::ServeOptions::default`]): telemetry, health and the control plane over
    /// iceoryx2 from a thread of its own.
    pub fn serve(&mut self, prefix: &str) -> Result<(), crate::ServeError> {
        self.serve_with(prefix, crate::ServeOptions::default())
    }

    /// [`Servo::serve`] with `options`. Returns once the service is up (the run's roles held,
    /// the ports open, a recorder subscribed if asked to wait for one).
    pub fn serve_with(
        &mut self,
        prefix: &str,
        options: crate::ServeOptions,
    ) -> Result<(), crate::ServeError> {
        if self.link.is_some() {
            return Err(crate::ServeError::AlreadyServed);
        }
        let vet = options.vet.unwrap_or_else(|| {
            Box::new(crate::CarriedCheck {
                made_for: self.host.made_for.clone(),
                servo_rate_hz: self.host.servo_rate_hz,
                stage: self.stage,
                running: self.host.spec.clone(),
            })
        });
        let setup = crate::serve::Setup {
            prefix: prefix.to_owned(),
            serves_plant: options.serves_plant,
            wait_for_recorder: options.wait_for_recorder,
            linger: options.linger,
            vet,
            stage: self.stage,
            period_s: self.period_s,
            stability: self.stability,
            scale: self.status.gain_scale,
        };
        self.link = Some(crate::serve::start(setup)?);
        Ok(())
    }

    /// Ends the service of a served loop: the last telemetry is published with the run's end,
    /// then a final health report (done, or faulted with `faults`, a [`daq_io::flags`] set, and
    /// the stop cause), and the service waits for subscribers to take them. Nothing to do for
    /// a loop that is not served.
    pub fn close(&mut self, faults: u32) {
        let Some(link) = self.link.take() else {
            return;
        };
        let status = self.status();
        self.host.dropped += crate::serve::close(
            link,
            crate::serve::End {
                ticks: status.ticks,
                overruns: status.overruns,
                timing: self.host.timing(),
                faults,
                stop_cause: status.stop.unwrap_or(0),
            },
        );
    }
}

#[cfg(feature = "serve")]
impl Drop for Servo {
    /// A served loop ends its service ([`Servo::close`] with no faults) when dropped.
    fn drop(&mut self) {
        self.close(0);
    }
}
