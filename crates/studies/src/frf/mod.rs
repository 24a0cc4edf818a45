//! Frequency responses measured by stepped sine (thesis §5.5.1: amplitude ramp, settling,
//! integer periods, DFT at the exact bin) or chirp, open loop (DAC → sensor) or closed loop
//! (disturbance added to the controller output, §5.7.5), beside the model's response from the
//! same sampled loop — on the simulator in this process, or on any plant served on a prefix
//! (the simulator process or a DAQ daemon, [`FrfPlant`]), this process taking the controller's
//! place and injecting the excitation.

use crate::error::StudyError;
use daq_io::{Backend, Sensor};
use loop_model::closed_loop::ClosedLoop;
use loop_model::controller::LinearController;
use lti::spectral::h1_at_bin;
use num_complex::Complex64;
use run_config::SimBackend;
use runner::remote_plant::RemotePlant;
use runner::Plan;
use serde::Serialize;
use servo_core::{Block, SteppedSineConfig};

/// Which loop is measured.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "kebab-case")]
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
    #[serde(rename = "magnitude_m_per_v")]
    pub magnitude: f64,
    /// Measured phase in degrees.
    pub phase_deg: f64,
    /// Magnitude-squared coherence across the measurement blocks.
    pub coherence: f64,
    /// The measurement's uncertainty, m/V: the radius of the disk around the measured response
    /// that holds the true one with a complex Gaussian 1σ disk's probability (63 %): from the
    /// noise in the bins beside the excited one (stepped sine,
    /// [`lti::spectral::periodic_uncertainty`]) or from the coherence over the sweeps (chirp,
    /// [`lti::spectral::h1_uncertainty`]).
    #[serde(rename = "uncertainty_m_per_v")]
    pub uncertainty: f64,
    /// Model magnitude, m/V.
    #[serde(rename = "model_magnitude_m_per_v")]
    pub model_magnitude: f64,
    /// Model phase in degrees.
    pub model_phase_deg: f64,
    /// The ADC clipped during the measurement (the point is not linear: lower the amplitude).
    pub clipped: bool,
    /// Amplitude of the excitation at this frequency, V (stepped sine: per frequency; chirp:
    /// constant).
    pub excitation_v: f64,
    /// The accelerometer reading's response to the same excitation, V/V: magnitude (what
    /// tells a mode of the stage, which the accelerometer on m2 feels, from one on the gap
    /// reading, which it does not).
    #[serde(rename = "accel_magnitude_v_per_v")]
    pub accel_magnitude: f64,
    /// Its phase in degrees.
    pub accel_phase_deg: f64,
    /// Its uncertainty, V/V (the radius of its 63 % disk, as `uncertainty`).
    #[serde(rename = "accel_uncertainty_v_per_v")]
    pub accel_uncertainty: f64,
}

impl FrfPoint {
    /// Measured over model, in dB.
    pub fn error_db(&self) -> f64 {
        20.0 * libm::log10(self.magnitude / self.model_magnitude)
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
    /// Least settling time per frequency in s.
    pub settle_s: f64,
    /// Settling time, in time constants of the slowest mode the model's command response shows
    /// ([`ClosedLoop::slowest_command_pole`]; the suspension mode rings 72 ms in open loop on
    /// the 0.074 kg stage, 160 ms on the 0.174 kg one), of the frequencies below four times
    /// its natural frequency, when longer than `settle_s`: a
    /// transient left after `n` of them is `e^−n` of its start. 8 by default: on the 0.174 kg
    /// stage near its resonance, noise off, the measurement then lies within 2·10⁻⁵ of the
    /// model (6: 4·10⁻⁴, 4: 3·10⁻³; 0.3 s: 2 %).
    pub settle_time_constants: f64,
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
            settle_time_constants: 8.0,
            blocks: 8,
            block_s: 0.02,
        }
    }
}

/// How the FRF is measured.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "kebab-case")]
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

/// Where a measurement's excitation goes and its readings come from.
pub trait FrfPlant {
    /// The readings before the first command.
    fn initial(&mut self) -> Sensor;
    /// Holds `dac_v` (V) for one tick; the readings at its end.
    fn step(&mut self, dac_v: f64) -> Result<Sensor, StudyError>;
    /// Whether a clipped reading or command aborts the measurement (a real stage is not driven
    /// on into its limits) rather than only marking the point.
    fn aborts_on_clip(&self) -> bool;
    /// The excitation is over: a plant served by another process is let go (its run ended at
    /// 0 V) before the estimate, which takes longer than its peer timeout allows a tick.
    fn release(&mut self) {}
}

/// The simulated stage in this process: clipped points are marked, not aborted.
impl FrfPlant for SimBackend {
    fn initial(&mut self) -> Sensor {
        Backend::initial(self)
    }

    fn step(&mut self, dac_v: f64) -> Result<Sensor, StudyError> {
        Ok(Backend::step(self, dac_v))
    }

    fn aborts_on_clip(&self) -> bool {
        false
    }
}

/// The practice stage alone (measured as a lab measures its stage, for judging against its
/// truth): clipped points are marked, not aborted.
impl FrfPlant for plant_sim::practice::PracticeStage {
    fn initial(&mut self) -> Sensor {
        Backend::initial(self)
    }

    fn step(&mut self, dac_v: f64) -> Result<Sensor, StudyError> {
        Ok(Backend::step(self, dac_v))
    }

    fn aborts_on_clip(&self) -> bool {
        false
    }
}

/// A plant served on a prefix: a clip aborts to 0 V and the run is closed.
impl FrfPlant for RemotePlant {
    fn initial(&mut self) -> Sensor {
        RemotePlant::initial(self)
    }

    fn step(&mut self, dac_v: f64) -> Result<Sensor, StudyError> {
        Ok(RemotePlant::step(self, dac_v)?)
    }

    fn aborts_on_clip(&self) -> bool {
        true
    }

    fn release(&mut self) {
        self.close();
    }
}

/// Plant, controller and model of one measurement, and the drive tick.
struct Rig<'p> {
    plant: &'p mut dyn FrfPlant,
    ctrl: servo_config::Controller,
    model: ClosedLoop,
    which: FrfLoop,
    sample: Sensor,
    sensitivity: f64,
    dac: plant_sim::convert::Quantizer,
}

/// The model of the loop `which` of `plan` (no controller open loop) on the stage `sim`
/// simulates (the plan's own, or the same with its noise off).
fn model_loop(
    plan: &Plan,
    which: FrfLoop,
    sim: &plant_sim::Simulator,
) -> Result<ClosedLoop, StudyError> {
    let linear = sim
        .linear_tick()
        .ok_or(StudyError::NeedsLinearPlant { what: "the FRF" })?;
    let model_ctrl = match which {
        FrfLoop::Open => LinearController::none(),
        FrfLoop::Closed => plan.controller.linear.clone(),
    };
    Ok(ClosedLoop::new(
        &linear,
        &model_ctrl,
        plan.config.plant.capa.sensitivity_v_per_m,
        plan.sim.period_s(),
    ))
}

impl<'p> Rig<'p> {
    /// The rig of `plan`'s controller and model driving `plant`.
    fn new(plan: &Plan, which: FrfLoop, plant: &'p mut dyn FrfPlant) -> Result<Self, StudyError> {
        let ctrl = servo_config::Controller::build(
            &plan.controller.spec,
            &plan.deployment.stage,
            plan.period_s(),
        )
        .map_err(|e| runner::RunError::from(plan.origin.located(&e)))?;
        Ok(Rig {
            sample: plant.initial(),
            plant,
            ctrl,
            model: model_loop(plan, which, &plan.sim)?,
            which,
            sensitivity: plan.config.plant.capa.sensitivity_v_per_m,
            dac: *plan.sim.dac(),
        })
    }

    /// One tick at frequency `f_hz` with injection `d` (V) added to the controller output (or
    /// alone, open loop): the excitation as applied (open loop, the DAC's output: the
    /// quantised command is what the plant responds to — a few dozen steps of a small sine
    /// are 0.04 % short of it), and the measured position (m) and accelerometer reading (V)
    /// the tick started from, paired with it as the model pairs them. On a plant that aborts
    /// on a clip, a clipped reading or command ends the measurement.
    #[inline]
    fn tick(&mut self, f_hz: f64, d: f64) -> Result<(f64, f64, f64), StudyError> {
        let (u, d) = match self.which {
            FrfLoop::Open => {
                let applied = self.dac.convert(d).0;
                (applied, applied)
            }
            FrfLoop::Closed => (
                self.ctrl.update(-self.sample.gap_v, self.sample.accel_v) + d,
                d,
            ),
        };
        let (y, a) = (self.sample.gap_v / self.sensitivity, self.sample.accel_v);
        self.sample = self.plant.step(u)?;
        let clip = self.sample.flags & (daq_io::flags::GAP_CLIPPED | daq_io::flags::DAC_CLIPPED);
        if clip != 0 && self.plant.aborts_on_clip() {
            return Err(StudyError::FrfAborted {
                freq_hz: f_hz,
                what: if clip & daq_io::flags::GAP_CLIPPED != 0 {
                    "the sensor reading clipped at the ADC range"
                } else {
                    "the command clipped at the DAC range"
                },
            });
        }
        Ok((d, y, a))
    }

    fn clipped(&self) -> bool {
        self.sample.flags & daq_io::flags::GAP_CLIPPED != 0
    }

    fn model_at(&self, f_hz: f64) -> Result<Complex64, StudyError> {
        Ok(self.model.command_response(f_hz)?)
    }

    /// The point at `f_hz`: the position's response `h` (m/V), the accelerometer's `(h, its
    /// uncertainty)` (V/V).
    fn point(
        &self,
        f_hz: f64,
        h: Complex64,
        (coherence, uncertainty): (f64, f64),
        (accel, accel_uncertainty): (Complex64, f64),
        clipped: bool,
        excitation_v: f64,
    ) -> Result<FrfPoint, StudyError> {
        let m = self.model_at(f_hz)?;
        Ok(FrfPoint {
            accel_magnitude: accel.norm(),
            accel_phase_deg: accel.arg().to_degrees(),
            accel_uncertainty,
            freq_hz: f_hz,
            magnitude: h.norm(),
            phase_deg: h.arg().to_degrees(),
            coherence,
            uncertainty,
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
    let mut sim = plan.stage();
    let rig = Rig::new(plan, which, &mut sim)?;
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
    band: (f64, f64),
    amplitude_v: f64,
    duration_s: f64,
    repeats: usize,
) -> Result<Vec<FrfPoint>, StudyError> {
    let chirp = Chirp {
        band,
        amplitude_v,
        duration_s,
        repeats,
    };
    chirp_on(plan, which, &chirp, &mut plan.stage())
}

/// A repeated exponential chirp: the band in Hz, amplitude in V, one sweep's length in s and
/// the sweeps averaged (one more runs first to settle).
#[derive(Debug, Clone, Copy)]
pub struct Chirp {
    /// From and to, Hz.
    pub band: (f64, f64),
    /// Amplitude, V.
    pub amplitude_v: f64,
    /// One sweep, s.
    pub duration_s: f64,
    /// Sweeps averaged.
    pub repeats: usize,
}

impl Chirp {
    /// Ticks the measurement takes at `fs_hz`.
    pub fn ticks(&self, fs_hz: f64) -> u64 {
        (self.duration_s * fs_hz).round() as u64 * (self.repeats as u64 + 1)
    }
}

/// [`chirp`] on `plant`.
pub fn chirp_on(
    plan: &Plan,
    which: FrfLoop,
    c: &Chirp,
    plant: &mut dyn FrfPlant,
) -> Result<Vec<FrfPoint>, StudyError> {
    use lti::spectral::{h1_welch, WelchConfig, Window};
    let Chirp {
        band: (from_hz, to_hz),
        amplitude_v,
        duration_s,
        repeats,
    } = *c;
    let mut rig = Rig::new(plan, which, plant)?;
    let fs = plan.config.plant.timing.servo_rate_hz;
    let chirp_cfg = servo_core::ChirpConfig {
        amplitude: amplitude_v,
        f_start_hz: from_hz,
        f_end_hz: to_hz,
        duration_s,
        sweep: servo_core::Sweep::Exponential,
    };
    let per = (duration_s * fs).round() as usize;
    let (mut u_rec, mut y_rec, mut a_rec) = (
        Vec::with_capacity(per * repeats),
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
            let (d, y, a) = rig.tick(from_hz, gen.update(()).position)?;
            if pass > 0 {
                u_rec.push(d);
                y_rec.push(y);
                a_rec.push(a);
                clipped |= rig.clipped();
            }
        }
    }
    rig.plant.release();
    // One segment per chirp (a periodic excitation): rectangular window, no leakage.
    let welch = WelchConfig {
        segment_len: per,
        overlap: 0.0,
        window: Window::Rectangular,
    };
    let frf = h1_welch(&u_rec, &y_rec, fs, &welch)?;
    let accel = h1_welch(&u_rec, &a_rec, fs, &welch)?;
    (0..frf.freq_hz.len())
        .filter(|&k| (from_hz..=to_hz).contains(&frf.freq_hz[k]))
        .map(|k| {
            rig.point(
                frf.freq_hz[k],
                frf.h[k],
                (
                    frf.coherence[k],
                    lti::spectral::h1_uncertainty(frf.h[k], frf.coherence[k], repeats),
                ),
                (
                    accel.h[k],
                    lti::spectral::h1_uncertainty(accel.h[k], accel.coherence[k], repeats),
                ),
                clipped,
                amplitude_v,
            )
        })
        .collect()
}

/// Bins on each side of a stepped sine's own whose noise gives its uncertainty.
const NEIGHBOURS: usize = 4;

/// Measures the loop of `plan` at `freqs_hz` by stepped sine; `progress` gets (done, total).
pub fn stepped_sine(
    plan: &Plan,
    which: FrfLoop,
    freqs_hz: &[f64],
    s: &FrfSettings,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Vec<FrfPoint>, StudyError> {
    stepped_sine_on(plan, which, freqs_hz, s, &mut plan.stage(), progress)
}

/// How far above its natural frequency a slow mode needs its long settling: a raised-cosine
/// ramp at a frequency beyond it leaves less than 10⁻⁵ of the response ringing in the mode
/// after `settle_s` (measured on the 0.174 kg stage: 9·10⁻⁵ at 3 times, 0 at 6).
const SLOW_MODE_REACH: f64 = 4.0;

/// The settling time of a stepped sine on one loop.
#[derive(Debug, Clone, Copy)]
struct Settling {
    /// At every frequency, s.
    least_s: f64,
    /// Near the slow mode, s.
    slow_s: f64,
    /// Up to where the slow mode's settling applies, Hz.
    slow_below_hz: f64,
}

impl Settling {
    /// The settling of the loop `which` of `plan` with settings `s`, from the model's
    /// dynamics alone (its noise off: the noise shaping's slow states, which the command
    /// does not excite, are then not in the loop to be mistaken for it).
    fn of(plan: &Plan, which: FrfLoop, s: &FrfSettings) -> Result<Self, StudyError> {
        let t = plan.sim.period_s();
        let mut quiet = plan.config.plant;
        let n = &mut quiet.noise;
        (n.sensor, n.current, n.base, n.accel) = (false, false, false, false);
        let sim = plant_sim::Simulator::new(&quiet, 0, &Default::default())
            .map_err(|e| StudyError::from(runner::RunError::Sim(e)))?;
        let (slow_s, natural_hz) = match model_loop(plan, which, &sim)?.slowest_command_pole()? {
            Some(p) if p.norm() < 1.0 => (
                -s.settle_time_constants * t / libm::log(p.norm()),
                p.ln().norm() / (2.0 * std::f64::consts::PI * t),
            ),
            _ => (0.0, 0.0),
        };
        Ok(Settling {
            least_s: s.settle_s,
            slow_s,
            slow_below_hz: SLOW_MODE_REACH * natural_hz,
        })
    }

    /// The settling time at `f_hz`, s.
    fn at(&self, f_hz: f64) -> f64 {
        if f_hz < self.slow_below_hz {
            self.least_s.max(self.slow_s)
        } else {
            self.least_s
        }
    }
}

/// The excitation of the one stepped-sine frequency in `one` (Hz), its periods per block and
/// its amplitude (V). The amplitude ramps up over a fifth of the settling time and down as
/// long after the window.
fn one_frequency<'f>(
    plan: &Plan,
    one: &'f [f64; 1],
    s: &FrfSettings,
    settling: &Settling,
) -> Result<(servo_core::SteppedSine<'f>, u32, f64), StudyError> {
    let fs = plan.config.plant.timing.servo_rate_hz;
    let f_hz = one[0];
    let settle_s = settling.at(f_hz);
    let periods_per_block = ((s.block_s * f_hz).ceil() as u32).max(4);
    let amplitude = s.amplitude_at(f_hz);
    let ramp_periods = ((0.2 * settle_s * f_hz).ceil() as u32).max(3);
    let sweep_cfg = SteppedSineConfig {
        frequencies_hz: one,
        amplitude,
        ramp_periods,
        settle_periods: ((settle_s * f_hz).ceil() as u32).max(10),
        measure_periods: periods_per_block * s.blocks as u32,
        ramp_down_periods: ramp_periods,
    };
    let gen = sweep_cfg.try_build(1.0 / fs).map_err(|e| {
        plan.origin
            .invalid("frf frequency", e, &format!("(0, {}) Hz", fs / 2.0))
    })?;
    Ok((gen, periods_per_block, amplitude))
}

/// Ticks the stepped sine of the loop `which` of `plan` at `freqs_hz` takes.
pub fn stepped_sine_ticks(
    plan: &Plan,
    which: FrfLoop,
    freqs_hz: &[f64],
    s: &FrfSettings,
) -> Result<u64, StudyError> {
    let settling = Settling::of(plan, which, s)?;
    freqs_hz.iter().try_fold(0u64, |sum, &f| {
        let one = [f];
        let (gen, _, _) = one_frequency(plan, &one, s, &settling)?;
        Ok(sum + gen.segment(0).expect("one segment").end())
    })
}

/// [`stepped_sine`] on `plant`.
pub fn stepped_sine_on(
    plan: &Plan,
    which: FrfLoop,
    freqs_hz: &[f64],
    s: &FrfSettings,
    plant: &mut dyn FrfPlant,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Vec<FrfPoint>, StudyError> {
    let mut rig = Rig::new(plan, which, plant)?;
    let settling = Settling::of(plan, which, s)?;
    let mut out = Vec::new();
    for (i, &f) in freqs_hz.iter().enumerate() {
        progress(i, freqs_hz.len());
        let one = [f];
        let (mut gen, periods_per_block, amplitude) = one_frequency(plan, &one, s, &settling)?;
        let seg = gen.segment(0).expect("one segment");
        let (mut u_rec, mut y_rec, mut a_rec) = (
            Vec::with_capacity(seg.measure_len as usize),
            Vec::with_capacity(seg.measure_len as usize),
            Vec::with_capacity(seg.measure_len as usize),
        );
        let mut clipped = false;
        for k in 0..seg.end() {
            let (d, y, a) = rig.tick(seg.frequency_hz, gen.update(()).position)?;
            if (seg.measure_start..seg.measure_end()).contains(&k) {
                u_rec.push(d);
                y_rec.push(y);
                a_rec.push(a);
                clipped |= rig.clipped();
            }
        }
        let (h, coherence) = h1_at_bin(&u_rec, &y_rec, periods_per_block as usize, s.blocks);
        let cycles = periods_per_block as usize * s.blocks;
        let uncertainty = lti::spectral::periodic_uncertainty(&u_rec, &y_rec, cycles, NEIGHBOURS);
        let (accel, _) = h1_at_bin(&u_rec, &a_rec, periods_per_block as usize, s.blocks);
        let accel_uncertainty =
            lti::spectral::periodic_uncertainty(&u_rec, &a_rec, cycles, NEIGHBOURS);
        out.push(rig.point(
            seg.frequency_hz,
            h,
            (coherence, uncertainty),
            (accel, accel_uncertainty),
            clipped,
            amplitude,
        )?);
    }
    progress(freqs_hz.len(), freqs_hz.len());
    Ok(out)
}
