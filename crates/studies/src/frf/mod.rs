//! Frequency responses measured on the running simulator by stepped sine (thesis §5.5.1:
//! amplitude ramp, settling, integer periods, DFT at the exact bin), open loop (DAC → sensor)
//! or closed loop (disturbance added to the controller output, §5.7.5), beside the model's
//! response from the same sampled loop.

pub mod report;

use crate::error::StudyError;
use lti::spectral::h1_at_bin;
use num_complex::Complex64;
use plant_sim::{SensorSample, Simulator};
use runner::closed_loop::ClosedLoop;
use runner::controller::{Controller, LinearController};
use runner::Plan;
use serde::Serialize;
use servo_core::{Block, SteppedSineConfig};

/// Which loop is measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum FrfLoop {
    /// No controller: DAC command → measured position.
    Open,
    /// Controller running; injection added to its output → measured position.
    Closed,
}

impl FrfLoop {
    /// The quantity measured: `P` (the plant, open loop) or `PS` (the process sensitivity
    /// P/(1 + PC), closed loop).
    pub fn quantity(self) -> &'static str {
        match self {
            FrfLoop::Open => "P",
            FrfLoop::Closed => "PS",
        }
    }

    /// What the quantity is, for people.
    pub fn describe(self) -> &'static str {
        match self {
            FrfLoop::Open => "the plant P, open loop: DAC command → measured position",
            FrfLoop::Closed => {
                "the process sensitivity P/(1 + PC), closed loop: injection at the controller output → measured position"
            }
        }
    }
}

/// One measured frequency.
#[derive(Debug, Clone, Serialize)]
pub struct FrfPoint {
    /// Excitation frequency in Hz (nudged onto an exact bin).
    pub freq_hz: f64,
    /// Measured response, m/V: magnitude.
    pub magnitude: f64,
    /// Measured phase in degrees.
    pub phase_deg: f64,
    /// Magnitude-squared coherence across the measurement blocks.
    pub coherence: f64,
    /// Model magnitude, m/V.
    pub model_magnitude: f64,
    /// Model phase in degrees.
    pub model_phase_deg: f64,
    /// The ADC clipped during the measurement (the point is not linear: lower the amplitude).
    pub clipped: bool,
    /// Amplitude of the excitation at this frequency, V (stepped sine: per frequency; chirp:
    /// constant).
    pub excitation_v: f64,
}

impl FrfPoint {
    /// Measured over model, in dB.
    pub fn error_db(&self) -> f64 {
        20.0 * (self.magnitude / self.model_magnitude).log10()
    }

    /// Measured minus model phase, in degrees wrapped to (−180, 180].
    pub fn error_deg(&self) -> f64 {
        let d = (self.phase_deg - self.model_phase_deg) % 360.0;
        if d > 180.0 {
            d - 360.0
        } else if d <= -180.0 {
            d + 360.0
        } else {
            d
        }
    }
}

/// Measurement settings.
#[derive(Debug, Clone, Copy)]
pub struct FrfSettings {
    /// Excitation amplitude in V up to `knee_hz`; above it the amplitude rises as `(f/knee)²`
    /// (the stage response falls as 1/f²), capped at `max_amplitude_v`.
    pub amplitude_v: f64,
    /// Where the amplitude starts to rise, Hz.
    pub knee_hz: f64,
    /// Largest amplitude in V.
    pub max_amplitude_v: f64,
    /// Settling time per frequency in s (the suspension mode rings ≈ 70 ms in open loop).
    pub settle_s: f64,
    /// Blocks averaged (coherence needs ≥ 2).
    pub blocks: usize,
    /// Minimum length of a block in s.
    pub block_s: f64,
}

impl FrfSettings {
    /// The excitation amplitude at `f_hz`, V.
    pub fn amplitude_at(&self, f_hz: f64) -> f64 {
        (self.amplitude_v * (f_hz / self.knee_hz).powi(2).max(1.0)).min(self.max_amplitude_v)
    }

    /// Defaults per loop: 2 mV open loop (the 82 Hz suspension resonance, Q ≈ 18, must stay
    /// inside the ±4.096 V ADC), 10 mV closed loop.
    pub fn for_loop(which: FrfLoop) -> Self {
        FrfSettings {
            amplitude_v: if which == FrfLoop::Open { 0.002 } else { 0.01 },
            knee_hz: 150.0,
            max_amplitude_v: 5.0,
            settle_s: 0.3,
            blocks: 8,
            block_s: 0.02,
        }
    }
}

/// How the FRF is measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum FrfMethod {
    /// One frequency at a time, exact-bin DFT, block coherence (§5.5.1).
    Stepped,
    /// Repeated exponential chirps, H1 and coherence per bin.
    Chirp,
}

/// The chirp of [`FrfMethod::Chirp`]: one sweep's length in s and the sweeps averaged (one
/// more runs first to settle).
pub const CHIRP_S: f64 = 0.2;
/// Chirps averaged.
pub const CHIRP_REPEATS: usize = 16;

/// Default chirp amplitude in V: 2 mV open loop (as the stepped sine's, for the suspension
/// resonance), 0.2 V closed loop (the loop rejects most of it).
pub fn chirp_amplitude_v(which: FrfLoop) -> f64 {
    match which {
        FrfLoop::Open => 0.002,
        FrfLoop::Closed => 0.2,
    }
}

/// Simulator, controller and model of one measurement, and the drive tick.
struct Rig {
    sim: Simulator,
    ctrl: Controller,
    model: ClosedLoop,
    which: FrfLoop,
    sample: SensorSample,
    sensitivity: f64,
}

impl Rig {
    /// The rig of `plan`'s stage (seeded; a scenario's cutting force acts as it would on the
    /// machine) and controller.
    fn new(plan: &Plan, which: FrfLoop) -> Result<Self, StudyError> {
        let c = &plan.config;
        let sim = plan.sim.clone();
        let ctrl = plan.controller.clone();
        let linear = sim
            .linear_tick()
            .ok_or(StudyError::NeedsLinearPlant { what: "the FRF" })?;
        let model_ctrl = match which {
            FrfLoop::Open => LinearController::none(),
            FrfLoop::Closed => ctrl.linear.clone(),
        };
        let sensitivity = c.plant.capa.sensitivity_v_per_m;
        let model = ClosedLoop::new(&linear, &model_ctrl, sensitivity, sim.period_s());
        Ok(Rig {
            sim,
            ctrl,
            model,
            which,
            sample: SensorSample::default(),
            sensitivity,
        })
    }

    /// One tick with injection `d` (V) added to the controller output (or alone, open loop);
    /// returns the measured position (m) the tick started from, paired with `d` as the model
    /// pairs them.
    #[inline]
    fn tick(&mut self, d: f64) -> f64 {
        let u = match self.which {
            FrfLoop::Open => 0.0,
            FrfLoop::Closed => self.ctrl.update(-self.sample.gap_v, self.sample.accel_v),
        } + d;
        let measured = self.sample.gap_v / self.sensitivity;
        self.sample = self.sim.step(u).0;
        measured
    }

    fn clipped(&self) -> bool {
        self.sample.flags & daq_io::flags::GAP_CLIPPED != 0
    }

    fn model_at(&self, f_hz: f64) -> Result<Complex64, StudyError> {
        Ok(self.model.command_response(f_hz)?)
    }

    fn point(
        &self,
        f_hz: f64,
        h: Complex64,
        coherence: f64,
        clipped: bool,
        excitation_v: f64,
    ) -> Result<FrfPoint, StudyError> {
        let m = self.model_at(f_hz)?;
        Ok(FrfPoint {
            freq_hz: f_hz,
            magnitude: h.norm(),
            phase_deg: h.arg().to_degrees(),
            coherence,
            model_magnitude: m.norm(),
            model_phase_deg: m.arg().to_degrees(),
            clipped,
            excitation_v,
        })
    }
}

/// The model's response (m/V) on `n` log-spaced frequencies from `from_hz` to `to_hz`.
pub fn model_curve(
    plan: &Plan,
    which: FrfLoop,
    from_hz: f64,
    to_hz: f64,
    n: usize,
) -> Result<Vec<(f64, Complex64)>, StudyError> {
    let rig = Rig::new(plan, which)?;
    lti::spectral::log_space(from_hz, to_hz, n)
        .into_iter()
        .map(|f| Ok((f, rig.model_at(f)?)))
        .collect()
}

/// Measures the loop of `plan` with an exponential chirp from `from_hz` to `to_hz` (amplitude
/// `amplitude_v`, `duration_s` long, repeated `repeats` times after one settling pass) and a
/// Welch H1 estimate with coherence; returns the bins between the two frequencies.
pub fn chirp(
    plan: &Plan,
    which: FrfLoop,
    (from_hz, to_hz): (f64, f64),
    amplitude_v: f64,
    duration_s: f64,
    repeats: usize,
) -> Result<Vec<FrfPoint>, StudyError> {
    use lti::spectral::{h1_welch, WelchConfig, Window};
    let mut rig = Rig::new(plan, which)?;
    let fs = plan.config.plant.timing.servo_rate_hz;
    let chirp_cfg = servo_core::ChirpConfig {
        amplitude: amplitude_v,
        f_start_hz: from_hz,
        f_end_hz: to_hz,
        duration_s,
        sweep: servo_core::Sweep::Exponential,
    };
    let per = (duration_s * fs).round() as usize;
    let (mut u_rec, mut y_rec) = (
        Vec::with_capacity(per * repeats),
        Vec::with_capacity(per * repeats),
    );
    let mut clipped = false;
    for pass in 0..=repeats {
        let mut gen = chirp_cfg.try_build(1.0 / fs).map_err(|e| {
            plan.origin
                .invalid("chirp", e, &format!("(0, {}) Hz", fs / 2.0))
        })?;
        for _ in 0..per {
            let d = gen.update(()).position;
            let y = rig.tick(d);
            if pass > 0 {
                u_rec.push(d);
                y_rec.push(y);
                clipped |= rig.clipped();
            }
        }
    }
    // One segment per chirp (a periodic excitation): rectangular window, no leakage.
    let welch = WelchConfig {
        segment_len: per,
        overlap: 0.0,
        window: Window::Rectangular,
    };
    let frf = h1_welch(&u_rec, &y_rec, fs, &welch)?;
    (0..frf.freq_hz.len())
        .filter(|&k| (from_hz..=to_hz).contains(&frf.freq_hz[k]))
        .map(|k| {
            rig.point(
                frf.freq_hz[k],
                frf.h[k],
                frf.coherence[k],
                clipped,
                amplitude_v,
            )
        })
        .collect()
}

/// Measures the loop of `plan` at `freqs_hz` by stepped sine; `progress` gets (done, total).
pub fn stepped_sine(
    plan: &Plan,
    which: FrfLoop,
    freqs_hz: &[f64],
    s: &FrfSettings,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Vec<FrfPoint>, StudyError> {
    let mut rig = Rig::new(plan, which)?;
    let fs = plan.config.plant.timing.servo_rate_hz;
    let mut out = Vec::new();
    for (i, &f) in freqs_hz.iter().enumerate() {
        progress(i, freqs_hz.len());
        let periods_per_block = ((s.block_s * f).ceil() as u32).max(4);
        let one = [f];
        let sweep_cfg = SteppedSineConfig {
            frequencies_hz: &one,
            amplitude: s.amplitude_at(f),
            ramp_periods: ((0.2 * s.settle_s * f).ceil() as u32).max(3),
            settle_periods: ((s.settle_s * f).ceil() as u32).max(10),
            measure_periods: periods_per_block * s.blocks as u32,
        };
        let mut gen = sweep_cfg.try_build(1.0 / fs).map_err(|e| {
            plan.origin
                .invalid("frf frequency", e, &format!("(0, {}) Hz", fs / 2.0))
        })?;
        let seg = gen.segment(0).expect("one segment");
        let (mut u_rec, mut y_rec) = (
            Vec::with_capacity(seg.measure_len as usize),
            Vec::with_capacity(seg.measure_len as usize),
        );
        let mut clipped = false;
        for k in 0..seg.end() {
            let d = gen.update(()).position;
            let y = rig.tick(d);
            if k >= seg.measure_start {
                u_rec.push(d);
                y_rec.push(y);
                clipped |= rig.clipped();
            }
        }
        let (h, coherence) = h1_at_bin(&u_rec, &y_rec, periods_per_block as usize, s.blocks);
        out.push(rig.point(seg.frequency_hz, h, coherence, clipped, sweep_cfg.amplitude)?);
    }
    progress(freqs_hz.len(), freqs_hz.len());
    Ok(out)
}
