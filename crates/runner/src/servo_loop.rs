//! The two halves of a tick, shared by the in-process run and the HIL processes so both
//! compute bit-identical results: [`SimBackend`] (plant-sim behind daq-io's [`Backend`]) and
//! [`ServoLoop`] (reference + controller → command and telemetry).

use crate::config::{ConfigError, Loaded, Scenario};
use crate::controller::Controller;
use crate::summary::SATURATED;
use daq_io::{flags, Backend, Command, Sensor, Telemetry, Truth};
use plant_sim::Simulator;
use recorder::Frame;
use servo_core::{Block, ChirpConfig, SineConfig, StepConfig, Sweep};

/// The simulated stage as a daq-io backend (keeps the last step's truth).
pub struct SimBackend {
    sim: Simulator,
    truth: Truth,
}

impl SimBackend {
    /// Wraps `sim`.
    pub fn new(sim: Simulator) -> Self {
        SimBackend {
            sim,
            truth: Truth::default(),
        }
    }
}

impl Backend for SimBackend {
    #[inline]
    fn step(&mut self, dac_v: f64) -> Sensor {
        let (s, t) = self.sim.step(dac_v);
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
            encoder_count: 0,
            flags: s.flags,
            reserved: 0,
        }
    }

    fn truth(&self) -> Option<Truth> {
        Some(self.truth)
    }
}

/// The reference trajectory in m, one sample per tick.
enum Reference {
    Zero,
    Gen(Box<dyn Block<Input = (), Output = servo_core::Setpoint> + Send>),
}

impl Reference {
    fn new(s: &Scenario, period: f64, duration: f64) -> Result<Self, servo_core::Error> {
        Ok(match *s {
            Scenario::Hold | Scenario::IntermittentCut { .. } => Reference::Zero,
            Scenario::Sine {
                amplitude_m,
                frequency_hz,
            } => Reference::Gen(Box::new(
                SineConfig {
                    amplitude: amplitude_m,
                    frequency_hz,
                    phase_rad: 0.0,
                    offset: 0.0,
                }
                .try_build(period)?,
            )),
            Scenario::Step { amplitude_m, at_s } => Reference::Gen(Box::new(
                StepConfig {
                    amplitude: amplitude_m,
                    delay_s: at_s,
                }
                .try_build(period)?,
            )),
            Scenario::Chirp {
                amplitude_m,
                f_start_hz,
                f_end_hz,
            } => Reference::Gen(Box::new(
                ChirpConfig {
                    amplitude: amplitude_m,
                    f_start_hz,
                    f_end_hz,
                    duration_s: duration,
                    sweep: Sweep::Exponential,
                }
                .try_build(period)?,
            )),
        })
    }

    #[inline]
    fn next(&mut self) -> f64 {
        match self {
            Reference::Zero => 0.0,
            Reference::Gen(g) => g.update(()).position,
        }
    }
}

/// The controller's half of a tick: reads tick k's sample, returns tick k's command and the
/// telemetry of tick k−1 (what the sample at its end showed). A non-finite reading latches the
/// controller's fault: 0 V out and [`flags::FAULT_CONTROLLER`] on the command and telemetry.
pub struct ServoLoop {
    /// The controller.
    pub controller: Controller,
    reference: Reference,
    r: f64,
    last_u: f64,
    gain_scale: f64,
    sensitivity: f64,
    accel_scale: f64,
}

impl ServoLoop {
    /// Builds the controller and reference of `cfg`.
    pub fn new(cfg: &Loaded) -> Result<Self, ConfigError> {
        let c = &cfg.config;
        let controller = Controller::build(cfg)?;
        let mut reference = Reference::new(&c.scenario, c.plant.period_s(), c.run.duration_s)
            .map_err(|e| cfg.invalid("scenario", e, "see the message"))?;
        let r = reference.next();
        Ok(ServoLoop {
            controller,
            reference,
            r,
            last_u: 0.0,
            gain_scale: 1.0,
            sensitivity: c.plant.capa.sensitivity_v_per_m,
            accel_scale: 1.0 / c.plant.accel.sensitivity_v_per_m_s2,
        })
    }

    /// Multiplies the controller output (all gains of a linear controller) by `scale`
    /// (dimensionless), clamped to the output limit. Takes effect at the next tick.
    pub fn set_gain_scale(&mut self, scale: f64) {
        self.gain_scale = scale;
    }

    /// One tick for sample `s`: the command (None when `s` closes the run) and the telemetry
    /// of the previous tick (None for the first sample). Allocation-free.
    #[inline]
    pub fn tick(&mut self, s: &Sensor) -> (Option<Command>, Option<Telemetry>) {
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
                    | if self.controller.faulted() {
                        flags::FAULT_CONTROLLER
                    } else {
                        0
                    },
                reserved: 0,
            }
        });
        if s.flags & flags::END != 0 {
            return (None, telemetry);
        }
        let raw = self
            .controller
            .update(self.r * self.sensitivity - s.gap_v, s.accel_v);
        let limit = self.controller.limit_v;
        let u = (raw * self.gain_scale).clamp(-limit, limit);
        self.last_u = u;
        self.r = self.reference.next();
        let command = Command {
            seq: s.seq,
            dac_v: u,
            flags: if self.controller.faulted() {
                flags::FAULT_CONTROLLER
            } else {
                0
            },
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
