//! The feedforward of a run, designed once from its plan: the stage-model inverse (evaluated by
//! the runtime from the stage's numbers), the ZPETC designed from the run's sampled closed
//! loop (reference → tool, or reference → sensor reading for `zpetc-sensor`), or the FIR
//! fitted to the loop closed on a measured FRF ([`MeasuredLoop`]), handed to the runtime as
//! coefficients.

use crate::closed_loop::{input, output, ClosedLoop};
use crate::measured_loop::MeasuredLoop;
use design::fir::{FirError, FirProblem};
use design::zpetc::{design, ZpetcDesign, ZpetcError};
use lti::StateSpace;
use run_config::{FeedforwardKind, RunConfig};
use servo_config::{
    FeedforwardSpec, FirSpec, ZpetcSpec, MAX_FIR_TAPS, MAX_PREVIEW, ZPETC_SECTIONS,
};

/// Largest reduced order tried.
const MAX_ORDER: usize = 2 * ZPETC_SECTIONS - 4;

/// Relative accuracy the reduced loop model must reach up to [`check_band_hz`].
pub const MODEL_TOLERANCE: f64 = 1e-3;

/// The band over which the reduced model is checked: up to a fifth of Nyquist (Hz).
pub fn check_band_hz(period_s: f64) -> f64 {
    0.1 / period_s
}

/// Why no ZPETC could be built for a loop.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FeedforwardError {
    /// The design failed.
    #[error("ZPETC feedforward: {0}")]
    Design(#[from] ZpetcError),
    /// The FIR fit failed.
    #[error("FIR feedforward on {source_file}: {error}")]
    Fir {
        /// The measured FRF it was fitted to.
        source_file: String,
        /// Why.
        error: FirError,
    },
    /// The design does not fit the loop's fixed-size filter or preview.
    #[error("ZPETC feedforward needs {sections} sections and {preview} ticks of preview (at most {ZPETC_SECTIONS} and {MAX_PREVIEW})")]
    TooLarge {
        /// Sections needed.
        sections: usize,
        /// Preview needed, ticks.
        preview: usize,
    },
}

/// The feedforward `config` asks for, on the loop `cl` (the model's) or, for an FIR, the loop
/// closed on the measured FRF (`measured`, required then).
pub fn feedforward_spec(
    config: &RunConfig,
    cl: &ClosedLoop,
    measured: Option<&MeasuredLoop>,
) -> Result<(FeedforwardSpec, Option<FirFit>), FeedforwardError> {
    Ok(match config.controller.feedforward {
        FeedforwardKind::None => (FeedforwardSpec::None, None),
        FeedforwardKind::Model => (FeedforwardSpec::Model, None),
        kind @ (FeedforwardKind::Zpetc | FeedforwardKind::ZpetcSensor) => {
            (FeedforwardSpec::Zpetc(zpetc(cl, kind)?), None)
        }
        FeedforwardKind::Fir => {
            let measured = measured.expect("a plan with an FIR feedforward measures its loop");
            let fit = fir(config, cl, measured)?;
            (FeedforwardSpec::Fir(fit.spec), Some(fit))
        }
    })
}

/// An FIR feedforward fitted to a measured loop, and how well it flattens it.
#[derive(Debug, Clone, PartialEq)]
pub struct FirFit {
    /// The taps as the runtime takes them.
    pub spec: FirSpec,
    /// The measured FRF (file and SHA-256).
    pub source: String,
    /// Measured bins fitted (at or below the band).
    pub bins: usize,
    /// The band made flat, Hz.
    pub band_hz: f64,
    /// Largest `|T·H − 1|` over the fitted bins, at the measured `T` (m/m).
    pub worst_residual: f64,
    /// Largest over the bins and over each bin's uncertainty disk: `|T·H − 1| + σ·|H|`.
    pub worst_residual_in_disk: f64,
    /// Where the worst over the disks lies, Hz.
    pub worst_hz: f64,
}

impl std::fmt::Display for FirFit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "FIR feedforward: {} taps {} ticks apart, {} ticks of preview, fitted on {} measured bins up to {} Hz of {}; \
             reference → tool within {:.2} % of flat (within {:.2} % over each bin's uncertainty, worst at {:.0} Hz)",
            self.spec.taps_used,
            self.spec.stride,
            self.spec.preview,
            self.bins,
            self.band_hz,
            self.source,
            100.0 * self.worst_residual,
            100.0 * self.worst_residual_in_disk,
            self.worst_hz
        )
    }
}

/// The FIR of `config.controller.fir` fitted to `measured` so that reference → tool is flat,
/// each bin weighted by its coherence; the DC gain is the model's
/// loop's (`cl` at 0 Hz: the integrator's 1, times the sensor path's static gain).
pub fn fir(
    config: &RunConfig,
    cl: &ClosedLoop,
    measured: &MeasuredLoop,
) -> Result<FirFit, FeedforwardError> {
    let c = &config.controller.fir;
    let failed = |error| FeedforwardError::Fir {
        source_file: measured.source.clone(),
        error,
    };
    let dc_gain = cl
        .response(output::TOOL_M, input::REFERENCE_M, 0.0)
        .map_err(|e| {
            failed(FirError::Invalid {
                what: e.to_string(),
            })
        })?
        .re;
    // Each bin as much as its coherence (a log-spaced measurement puts its bins where the
    // loop's response changes fastest: per bin, not per hertz).
    let d = design::fir::design(&FirProblem {
        freq_hz: &measured.freq_hz,
        path: &measured.reference_to_tool,
        weight: &measured.coherence,
        dc_gain,
        period_s: cl.period_s,
        taps: c.taps,
        preview: c.preview_ticks,
        stride: c.stride_ticks,
        band_hz: c.band_hz,
        max_gain_above_band: c.max_gain,
    })
    .map_err(failed)?;
    let mut spec = FirSpec {
        taps: [0.0; MAX_FIR_TAPS],
        taps_used: d.taps.len(),
        preview: d.preview,
        stride: d.stride,
    };
    spec.taps[..d.taps.len()].copy_from_slice(&d.taps);
    let (mut worst, mut worst_disk, mut worst_hz) = (0.0f64, 0.0f64, 0.0);
    for ((&k, &centre), &gain) in d.bins.iter().zip(&d.residual).zip(&d.gain) {
        let disk = centre + measured.uncertainty[k] * gain;
        worst = worst.max(centre);
        if disk > worst_disk {
            (worst_disk, worst_hz) = (disk, measured.freq_hz[k]);
        }
    }
    Ok(FirFit {
        spec,
        source: measured.source.clone(),
        bins: d.bins.len(),
        band_hz: c.band_hz,
        worst_residual: worst,
        worst_residual_in_disk: worst_disk,
        worst_hz,
    })
}

/// The ZPETC design for the loop `cl`: reference in m → tool position in m (or the measured
/// position in m for [`FeedforwardKind::ZpetcSensor`]).
pub fn design_for(cl: &ClosedLoop, kind: FeedforwardKind) -> Result<ZpetcDesign, ZpetcError> {
    let sys = &cl.sys;
    let out = match kind {
        FeedforwardKind::ZpetcSensor => output::MEASURED_M,
        _ => output::TOOL_M,
    };
    let siso = StateSpace {
        a: sys.a.clone(),
        b: sys.b.columns(input::REFERENCE_M, 1).into_owned(),
        c: sys.c.rows(out, 1).into_owned(),
        d: sys.d.view((out, input::REFERENCE_M), (1, 1)).into_owned(),
    };
    let period = cl.period_s;
    design(
        &siso,
        period,
        MAX_ORDER,
        check_band_hz(period),
        MODEL_TOLERANCE,
    )
}

/// The ZPETC coefficients for the loop `cl`. The loop model's outputs at tick k are what the
/// runtime pairs with the reference of tick k: the tool at the tick's end, and the measured
/// sample the tick starts with (the sensor design needs no advance of its own: with one, the
/// sensor trails the reference by a tick, 22 nm RMS on the grid's edge).
pub fn zpetc(cl: &ClosedLoop, kind: FeedforwardKind) -> Result<ZpetcSpec, FeedforwardError> {
    let d = design_for(cl, kind)?;
    if d.sections.len() > ZPETC_SECTIONS || d.preview > MAX_PREVIEW {
        return Err(FeedforwardError::TooLarge {
            sections: d.sections.len(),
            preview: d.preview,
        });
    }
    let mut sections = [[1.0, 0.0, 0.0, 0.0, 0.0]; ZPETC_SECTIONS];
    sections[..d.sections.len()].copy_from_slice(&d.sections);
    Ok(ZpetcSpec {
        gain: d.gain,
        preview: d.preview,
        sections,
        sections_used: d.sections.len(),
    })
}
