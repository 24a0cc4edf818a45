//! The run's loop closed on a **measured** plant instead of the model: from an open-loop FRF
//! of the stage (DAC → measured position, `servo frf --loop open`) and the run's controller,
//! the response from the reference to the tool at each measured bin, with its uncertainty.
//!
//! The FRF measures the sensor's reading, not the tool: the tool's response per DAC volt is
//! the measured one times the model's ratio of tool to reading (the sensor path — its filter
//! and converter delay, ≈ 4.3 ticks at 199.6 kHz), and an accelerometer's reading, where the
//! controller uses one, the measured one times the model's ratio of accelerometer to reading.
//! What the sensor path model misses (a mount resonance between gap and reading) stays in the
//! tool's estimate; below a few kHz it changes the phase by tenths of a degree.

use crate::closed_loop::{input, output, ClosedLoop};
use crate::controller::LinearController;
use lti::{FrequencyResponse, LtiError};
use num_complex::Complex64;
use run_config::frf_file::MeasuredFrf;

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
    /// The FRF's coherence at each bin.
    pub coherence: Vec<f64>,
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
        let mut out = MeasuredLoop {
            freq_hz: frf.freq_hz.clone(),
            reference_to_tool: Vec::with_capacity(frf.freq_hz.len()),
            uncertainty: Vec::with_capacity(frf.freq_hz.len()),
            reference_to_reading: Vec::with_capacity(frf.freq_hz.len()),
            command_to_reading: Vec::with_capacity(frf.freq_hz.len()),
            coherence: frf.coherence.clone(),
            source: frf.source.clone(),
        };
        for (k, (&f, &measured)) in frf.freq_hz.iter().zip(&frf.response).enumerate() {
            let m = model.discrete(f, period)?;
            let (reading, tool, accel) = (m[(0, 0)], m[(1, 0)], m[(2, 0)]);
            let kc = controller.discrete(f, period)?;
            let (k_gap, k_accel) = (kc[(0, 0)], kc[(0, 1)]);
            let s = sensitivity_v_per_m;
            let to_tool = tool / reading;
            // u = K_g·S·(m − r) + K_a·a with m = P·u, a = P·(accel/reading), tool = P·(tool/reading)·u.
            let feed = -k_gap * s * to_tool;
            let loop_gain = k_gap * s + k_accel * accel / reading;
            let denominator = 1.0 - loop_gain * measured;
            out.reference_to_tool.push(feed * measured / denominator);
            let sigma = frf.uncertainty.as_ref().map_or(0.0, |u| u[k]);
            // d/dP of a·P/(1 − κP) is a/(1 − κP)².
            let spread = sigma / denominator.norm_sqr();
            out.uncertainty.push(feed.norm() * spread);
            let to_reading = -k_gap * s;
            out.reference_to_reading.push((
                to_reading * measured / denominator,
                to_reading.norm() * spread,
            ));
            out.command_to_reading
                .push((measured / denominator, spread));
        }
        Ok(out)
    }
}

/// Smallest relative uncertainty assumed for the model beyond the measured band.
const MIN_BEYOND: f64 = 0.05;

/// Bins at the top of the band whose disagreement with the model sets the allowance beyond it.
const TOP_BINS: usize = 10;

/// A loop response known at every frequency from a measured one: at the measured bins the
/// measurement, between them the model times the measured-to-model ratio interpolated (in log
/// frequency), below the first bin that ratio held; beyond the last bin the model, known within
/// `beyond` of its magnitude — the largest relative disagreement between measurement and model
/// (plus the measurement's own uncertainty) over the band's top bins, at least 5 %:
/// an FRF stops where it was measured, and a check beyond it errs safe.
#[derive(Debug, Clone)]
pub struct Extended {
    freq_hz: Vec<f64>,
    /// Measured over model at each bin, and the measurement's radius over the model's magnitude.
    ratio: Vec<(Complex64, f64)>,
    /// Relative radius assumed beyond the last bin.
    pub beyond: f64,
    /// The last measured frequency, Hz.
    pub top_hz: f64,
}

impl Extended {
    /// The measured `(response, radius)` at `freq_hz` beside the model's `model(f)`.
    pub fn new(
        freq_hz: &[f64],
        measured: &[(Complex64, f64)],
        model: &dyn Fn(f64) -> Complex64,
    ) -> Self {
        let ratio: Vec<(Complex64, f64)> = freq_hz
            .iter()
            .zip(measured)
            .map(|(&f, &(g, sigma))| {
                let m = model(f);
                (g / m, sigma / m.norm())
            })
            .collect();
        let beyond = ratio
            .iter()
            .rev()
            .take(TOP_BINS)
            .map(|(r, rho)| (r - 1.0).norm() + rho)
            .fold(MIN_BEYOND, f64::max);
        Extended {
            freq_hz: freq_hz.to_vec(),
            top_hz: freq_hz.last().copied().unwrap_or(0.0),
            ratio,
            beyond,
        }
    }

    /// The response and the radius it is known within at `f_hz`, the model there `model_at`.
    pub fn at(&self, f_hz: f64, model_at: Complex64) -> (Complex64, f64) {
        let f = &self.freq_hz;
        let (r, rho) = match f.iter().position(|&x| x >= f_hz) {
            None => return (model_at, self.beyond * model_at.norm()),
            Some(0) => self.ratio[0],
            Some(k) => {
                let ln = libm::log;
                let t = (ln(f_hz) - ln(f[k - 1])) / (ln(f[k]) - ln(f[k - 1]));
                let (a, b) = (self.ratio[k - 1], self.ratio[k]);
                (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t)
            }
        };
        (model_at * r, model_at.norm() * rho)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Plan;
    use run_config::{ControllerKind, Loaded};

    /// Closed on the model's own open-loop response, the measured loop is the model's closed
    /// loop (reference → tool) to rounding: the PID, and the acceleration loop whose
    /// accelerometer path comes from the model.
    #[test]
    fn on_the_models_own_frf_it_is_the_models_loop() {
        for (kind, ka) in [(ControllerKind::Pid, 0.0), (ControllerKind::Accel, 1.0)] {
            let mut loaded = Loaded::default();
            loaded.config.controller.kind = kind;
            loaded.config.controller.ka = ka;
            let plan = Plan::new(&loaded).unwrap();
            let s = plan.config.plant.capa.sensitivity_v_per_m;
            let open = ClosedLoop::open(&plan.sim, s).unwrap();
            let freq_hz = lti::spectral::log_space(10.0, 20_000.0, 40);
            let frf = MeasuredFrf {
                response: freq_hz
                    .iter()
                    .map(|&f| open.command_response(f).unwrap())
                    .collect(),
                coherence: vec![1.0; freq_hz.len()],
                uncertainty: None,
                source: "the model".into(),
                freq_hz,
            };
            let m = MeasuredLoop::new(&frf, &open, &plan.controller.linear, s).unwrap();
            for (f, t) in m.freq_hz.iter().zip(&m.reference_to_tool) {
                let want = plan
                    .closed_loop
                    .response(output::TOOL_M, input::REFERENCE_M, *f)
                    .unwrap();
                assert!(
                    (t / want - 1.0).norm() < 1e-8,
                    "{kind:?} {f} Hz: {t} vs {want}"
                );
            }
            assert!(m.uncertainty.iter().all(|u| *u == 0.0));
        }
    }
}
