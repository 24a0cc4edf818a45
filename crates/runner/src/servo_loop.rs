//! The two halves of a tick, shared by the in-process run and the HIL processes so both
//! compute bit-identical results: [`SimBackend`] (plant-sim behind daq-io's [`Backend`]) and
//! [`ServoLoop`] (reference + controller → command and telemetry).

use crate::config::{ConfigError, FeedforwardKind, Loaded, Scenario};
use crate::controller::Controller;
use crate::machine::{SurfaceReference, Workpiece};
use crate::preview::{Window, MAX_PREVIEW};
use crate::run::RunError;
use crate::summary::SATURATED;
use daq_io::{flags, Backend, Command, Sensor, Telemetry, Truth};
use plant_sim::Simulator;
use recorder::Frame;
use servo_core::{Block, ChirpConfig, SineConfig, StepConfig, Sweep};

/// The simulated stage as a daq-io backend (keeps the last step's truth), with the part on
/// the spindle when machining.
pub struct SimBackend {
    sim: Simulator,
    truth: Truth,
    workpiece: Option<Workpiece>,
    tick: u64,
}

impl SimBackend {
    /// Wraps `sim` (no spindle).
    pub fn new(sim: Simulator) -> Self {
        SimBackend {
            sim,
            truth: Truth::default(),
            workpiece: None,
            tick: 0,
        }
    }

    /// The stage of a run of `cfg`: its seed and cutting profile, and the spindle and part of
    /// a machining scenario.
    pub fn for_run(cfg: &Loaded) -> Result<Self, RunError> {
        let c = &cfg.config;
        let sim = Simulator::new(&c.plant, c.run.seed, &c.scenario.cutting())
            .map_err(|e| crate::run::plant_error(e, cfg))?;
        let workpiece = match &c.scenario {
            Scenario::Machine(m) => Some(Workpiece::new(m, m.surface.load(cfg)?, sim.period_s())),
            _ => None,
        };
        Ok(SimBackend {
            workpiece,
            ..SimBackend::new(sim)
        })
    }

    /// The simulator.
    pub fn sim(&self) -> &Simulator {
        &self.sim
    }
}

impl Backend for SimBackend {
    #[inline]
    fn step(&mut self, dac_v: f64) -> Sensor {
        let force = self
            .workpiece
            .as_ref()
            .map_or(0.0, |w| w.cutting_force_n(self.tick));
        let (s, t) = self.sim.step_with_force(dac_v, force);
        self.tick += 1;
        self.truth = Truth {
            seq: 0,
            time_s: s.time_s,
            tool_m: t.tool_m,
            gap_m: t.gap_m,
            motor_force_n: t.motor_force_n,
            cutting_force_n: t.cutting_force_n,
            coil_current_a: t.coil_current_a,
            current_noise_a: t.current_noise_a,
            base_m: t.base_m,
            sensor_noise_v: t.sensor_noise_v,
            dac_v: t.dac_v,
            flags: 0,
            reserved: 0,
        };
        Sensor {
            seq: 0,
            time_s: s.time_s,
            gap_v: s.gap_v,
            accel_v: s.accel_v,
            encoder_count: self
                .workpiece
                .as_ref()
                .map_or(0, |w| w.encoder_count(self.tick)),
            flags: s.flags,
            reserved: 0,
        }
    }

    fn truth(&self) -> Option<Truth> {
        Some(self.truth)
    }
}

/// Where the desired trajectory comes from (m, one sample per tick).
enum Source {
    Zero,
    Gen(Box<dyn Block<Input = (), Output = servo_core::Setpoint> + Send>),
    Surface(Box<SurfaceReference>),
}

impl Source {
    fn new(cfg: &Loaded) -> Result<Self, ConfigError> {
        let c = &cfg.config;
        let (period, duration) = (c.plant.period_s(), c.run.duration_s);
        let scenario = |e: servo_core::Error| cfg.invalid("scenario", e, "see the message");
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
            Scenario::Machine(m) => Source::Surface(Box::new(
                SurfaceReference::new(m, m.surface.load(cfg)?, period).map_err(scenario)?,
            )),
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

/// Sections of the largest ZPETC filter the loop runs.
pub const ZPETC_SECTIONS: usize = 12;

/// The feedforward of [`ServoLoop`].
enum Feedforward {
    None,
    /// Stage-model inverse on finite differences of the window (V).
    Model(servo_core::Feedforward),
    /// Reshaped reference (m).
    Zpetc(Box<servo_core::Zpetc<ZPETC_SECTIONS>>),
}

impl Feedforward {
    fn new(cfg: &Loaded) -> Result<(Self, usize), RunError> {
        let c = &cfg.config;
        Ok(match c.controller.feedforward {
            FeedforwardKind::None => (Feedforward::None, 0),
            FeedforwardKind::Model => {
                let (st, a) = (&c.plant.stage, &c.plant.actuator);
                let ff = servo_core::FeedforwardConfig {
                    mass_kg: st.suspended_mass_kg(),
                    damping_n_s_per_m: st.c2_n_s_per_m,
                    stiffness_n_per_m: st.k2_n_per_m,
                    newton_per_unit: a.current_gain_a_per_v * a.kt_n_per_a,
                    limits: servo_core::Limits::try_new(
                        -c.controller.limit_v,
                        c.controller.limit_v,
                    )
                    .map_err(|e| cfg.invalid("controller.limit_v", e, "(0, 10] V"))?,
                }
                .try_build()
                .map_err(|e| cfg.invalid("plant", e, "a valid stage for feedforward"))?;
                (Feedforward::Model(ff), 1)
            }
            FeedforwardKind::Zpetc | FeedforwardKind::ZpetcSensor => {
                let z = crate::feedforward::zpetc(cfg)?;
                let preview = z.preview();
                (Feedforward::Zpetc(Box::new(z)), preview)
            }
        })
    }

    fn faulted(&self) -> bool {
        match self {
            Feedforward::None => false,
            Feedforward::Model(f) => f.faulted(),
            Feedforward::Zpetc(z) => z.faulted(),
        }
    }
}

/// The controller's half of a tick: reads tick k's sample, returns tick k's command and the
/// telemetry of tick k−1 (what the sample at its end showed). A non-finite reading latches the
/// controller's fault: 0 V out and [`flags::FAULT_CONTROLLER`] on the command and telemetry.
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
    gain_scale: f64,
    sensitivity: f64,
    accel_scale: f64,
    period_s: f64,
}

impl ServoLoop {
    /// Builds the controller, reference and feedforward of `cfg`.
    pub fn new(cfg: &Loaded) -> Result<Self, RunError> {
        let c = &cfg.config;
        let controller = Controller::build(cfg)?;
        let source = Source::new(cfg)?;
        let (feedforward, preview) = Feedforward::new(cfg)?;
        let rate = c.plant.timing.servo_rate_hz;
        let smoothing = c.controller.smoothing_hz;
        let half = if smoothing > 0.0 {
            (rate / smoothing / 2.0).round() as usize
        } else {
            0
        };
        let window = Window::new(preview, half).ok_or_else(|| {
            cfg.invalid(
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
            gain_scale: 1.0,
            sensitivity: c.plant.capa.sensitivity_v_per_m,
            accel_scale: 1.0 / c.plant.accel.sensitivity_v_per_m_s2,
            period_s: c.plant.period_s(),
        })
    }

    /// Multiplies the controller output (all gains of a linear controller) by `scale`
    /// (dimensionless), clamped to the output limit. Takes effect at the next tick.
    pub fn set_gain_scale(&mut self, scale: f64) {
        self.gain_scale = scale;
    }

    fn any_fault(&self) -> bool {
        self.controller.faulted() || self.source.faulted() || self.feedforward.faulted()
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
            let saturated = self.last_u.abs() >= self.controller.limit_v
                || s.flags & plant_sim::sim::flags::DAC_CLIPPED != 0;
            Telemetry {
                seq: s.seq - 1,
                time_s: s.time_s,
                reference_m: self.r,
                measured_m: measured,
                following_error_m: self.r - measured,
                control_v: self.last_u,
                accel_m_s2: s.accel_v * self.accel_scale,
                flags: (s.flags & !flags::END)
                    | if saturated { SATURATED } else { 0 }
                    | if faulted { flags::FAULT_CONTROLLER } else { 0 },
                reserved: 0,
            }
        });
        if s.flags & flags::END != 0 {
            return (None, telemetry);
        }
        self.advance(s);
        let w = &self.window;
        let desired = w.at(0);
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
        let raw = self
            .controller
            .update(reference * self.sensitivity - s.gap_v, s.accel_v);
        let limit = self.controller.limit_v;
        let faulted = self.any_fault();
        let u = if faulted {
            0.0
        } else {
            (raw * self.gain_scale + u_ff).clamp(-limit, limit)
        };
        self.last_u = u;
        self.last_fault = faulted;
        self.r = desired;
        let command = Command {
            seq: s.seq,
            dac_v: u,
            flags: if faulted { flags::FAULT_CONTROLLER } else { 0 },
            reserved: 0,
        };
        (Some(command), telemetry)
    }
}

/// The recorded frame of one tick: the controller's telemetry joined with the plant's truth.
pub fn frame(t: &Telemetry, truth: &Truth) -> Frame {
    Frame {
        time_ns: (t.time_s * 1e9).round() as u64,
        telemetry: recorder::Telemetry {
            reference_m: t.reference_m as f32,
            measured_m: t.measured_m as f32,
            following_error_m: t.following_error_m as f32,
            control_v: t.control_v as f32,
            accel_m_s2: t.accel_m_s2 as f32,
            flags: (t.flags | truth.flags) as f32,
        },
        truth: recorder::Truth {
            tool_m: truth.tool_m as f32,
            true_error_m: (truth.tool_m - t.reference_m) as f32,
            gap_m: truth.gap_m as f32,
            motor_force_n: truth.motor_force_n as f32,
            cutting_force_n: truth.cutting_force_n as f32,
            coil_current_a: truth.coil_current_a as f32,
            current_noise_a: truth.current_noise_a as f32,
            base_m: truth.base_m as f32,
            sensor_noise_v: truth.sensor_noise_v as f32,
        },
    }
}
