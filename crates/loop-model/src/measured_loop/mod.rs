//! The run's loop closed on a **measured** plant instead of the model: from an open-loop FRF
//! of the stage (DAC → measured position, `servo frf --loop open`) and the run's controller,
//! the response from the reference to the tool at each measured bin, with its uncertainty.
//!
//! The FRF measures the sensor's reading, not the tool: the tool's response per DAC volt is
//! the measured one times the model's ratio of tool to reading (the sensor path — its filter
//! and converter delay, ≈ 4.3 ticks at 199.6 kHz). An accelerometer's reading, where the
//! controller uses one, is the accelerometer's own FRF when the file has it (`servo frf`
//! measures it with the gap's: a stage mode the model lacks shows in it), else the measured
//! position's times the model's ratio of accelerometer to reading.
//! What the sensor path model misses (a mount resonance between gap and reading) stays in the
//! tool's estimate; below a few kHz it changes the phase by tenths of a degree.

use crate::closed_loop::{input, output, ClosedLoop};
use crate::controller::LinearController;
use lti::{FrequencyResponse, LtiError};
use num_complex::Complex64;
use run_config::frf_file::MeasuredFrf;

mod extended;
mod stability;
pub use extended::Extended;
pub use stability::{MeasuredStability, Verdict};

/// Reference → tool (m/m) at each bin of a measured FRF, the loop closed on the measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasuredLoop {
    /// Bin frequencies, Hz.
    pub freq_hz: Vec<f64>,
    /// Reference → tool position at each bin (m/m).
    pub reference_to_tool: Vec<Complex64>,
    /// Each bin's uncertainty radius (m/m, the FRF's propagated to first order; 0 where the
    /// file states none).
    pub uncertainty: Vec<f64>,
    /// Reference → measured position at each bin (m/m), and its uncertainty radius.
    pub reference_to_reading: Vec<(Complex64, f64)>,
    /// A command added to the controller's output (a feedforward's volts) → measured
    /// position at each bin (m/V), and its uncertainty radius.
    pub command_to_reading: Vec<(Complex64, f64)>,
    /// The loop gain broken at the DAC, `L = −(K_gap·S·P + K_acc·P_acc)` (negative feedback,
    /// `1 + L`; as [`ClosedLoop::loop_gain`]) at each bin, and its uncertainty radius.
    pub loop_gain: Vec<(Complex64, f64)>,
    /// The FRF's coherence at each bin.
    pub coherence: Vec<f64>,
    /// The feedback loop's stability on the measurement.
    pub stability: MeasuredStability,
    /// The FRF file and its SHA-256.
    pub source: String,
}

impl MeasuredLoop {
    /// The loop of controller `ctrl` closed on `frf`, the sensor path from the open-loop model
    /// `open` ([`ClosedLoop::open`]); `sensitivity_v_per_m` converts the measured position to
    /// the gap reading the controller takes.
    pub fn new(
        frf: &MeasuredFrf,
        open: &ClosedLoop,
        ctrl: &LinearController,
        sensitivity_v_per_m: f64,
    ) -> Result<Self, LtiError> {
        let model = FrequencyResponse::new(&open.subsystem(
            &[
                (output::MEASURED_M, 1.0),
                (output::TOOL_M, 1.0),
                (output::ACCEL_READING_V, 1.0),
            ],
            input::CONTROL_DISTURBANCE_V,
        ));
        let controller = FrequencyResponse::new(&ctrl.state_space());
        let period = open.period_s;
        let s = sensitivity_v_per_m;
        // At `f`: the model's reading and tool per DAC volt, the controller's gap gain and its
        // loop factor κ. The loop is u = K_g·S·(m − r) + K_a·a with m = P·u,
        // a = P·(accel/reading), tool = P·(tool/reading)·u, so u = κ·m − K_g·S·r with
        // κ = K_g·S + K_a·accel/reading, and the loop gain broken at the DAC is L = −κ·P.
        // With the accelerometer's FRF A measured too, κ·P is K_g·S·P + K_a·A.
        let at = |f: f64| -> Result<[Complex64; 5], LtiError> {
            let m = model.discrete(f, period)?;
            let (reading, tool, accel) = (m[(0, 0)], m[(1, 0)], m[(2, 0)]);
            let kc = controller.discrete(f, period)?;
            let (k_gap, k_accel) = (kc[(0, 0)], kc[(0, 1)]);
            Ok([
                reading,
                tool,
                k_gap,
                k_gap * s + k_accel * accel / reading,
                k_accel,
            ])
        };
        let n = frf.freq_hz.len();
        let (mut reference_to_tool, mut uncertainty) =
            (Vec::with_capacity(n), Vec::with_capacity(n));
        let mut reference_to_reading = Vec::with_capacity(n);
        let (mut command_to_reading, mut loop_gain) =
            (Vec::with_capacity(n), Vec::with_capacity(n));
        for (k, (&f, &measured)) in frf.freq_hz.iter().zip(&frf.response).enumerate() {
            let [reading, tool, k_gap, kappa, k_accel] = at(f)?;
            let feed = -k_gap * s * (tool / reading);
            let sigma = frf.uncertainty.as_ref().map_or(0.0, |u| u[k]);
            // κ·P and its uncertainty radius.
            let (kappa_p, kappa_p_sigma) = match &frf.accel {
                Some(a) => (
                    k_gap * s * measured + k_accel * a.response[k],
                    (k_gap * s).norm() * sigma + k_accel.norm() * a.uncertainty[k],
                ),
                None => (kappa * measured, kappa.norm() * sigma),
            };
            let denominator = 1.0 - kappa_p;
            reference_to_tool.push(feed * measured / denominator);
            // d/dP of a·P/(1 − κP) is a/(1 − κP)².
            let spread = sigma / denominator.norm_sqr();
            uncertainty.push(feed.norm() * spread);
            let to_reading = -k_gap * s;
            reference_to_reading.push((
                to_reading * measured / denominator,
                to_reading.norm() * spread,
            ));
            command_to_reading.push((measured / denominator, spread));
            loop_gain.push((-kappa_p, kappa_p_sigma));
        }
        // The model's loop gain, by the same κ: L = −κ·P_reading.
        let model_at = |f: f64| at(f).map_or_else(|_| Complex64::default(), |m| -m[3] * m[0]);
        Ok(MeasuredLoop {
            stability: MeasuredStability::of(&frf.freq_hz, &loop_gain, &model_at, 0.499 / period),
            freq_hz: frf.freq_hz.clone(),
            reference_to_tool,
            uncertainty,
            reference_to_reading,
            command_to_reading,
            loop_gain,
            coherence: frf.coherence.clone(),
            source: frf.source.clone(),
        })
    }
}
