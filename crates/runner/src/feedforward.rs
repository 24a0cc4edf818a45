//! The feedforward of a run, designed once from its plan: the stage-model inverse (evaluated by
//! the runtime from the stage's numbers), or the ZPETC designed from the run's sampled closed
//! loop (reference → tool, or reference → sensor reading for `zpetc-sensor`), handed to the
//! runtime as coefficients.

use crate::closed_loop::{input, output, ClosedLoop};
use design::zpetc::{design, ZpetcDesign, ZpetcError};
use lti::StateSpace;
use run_config::{FeedforwardKind, RunConfig};
use servo_config::{FeedforwardSpec, ZpetcSpec, MAX_PREVIEW, ZPETC_SECTIONS};

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
    /// The design does not fit the loop's fixed-size filter or preview.
    #[error("ZPETC feedforward needs {sections} sections and {preview} ticks of preview (at most {ZPETC_SECTIONS} and {MAX_PREVIEW})")]
    TooLarge {
        /// Sections needed.
        sections: usize,
        /// Preview needed, ticks.
        preview: usize,
    },
}

/// The feedforward `config` asks for, on the loop `cl`.
pub fn feedforward_spec(
    config: &RunConfig,
    cl: &ClosedLoop,
) -> Result<FeedforwardSpec, FeedforwardError> {
    Ok(match config.controller.feedforward {
        FeedforwardKind::None => FeedforwardSpec::None,
        FeedforwardKind::Model => FeedforwardSpec::Model,
        kind @ (FeedforwardKind::Zpetc | FeedforwardKind::ZpetcSensor) => {
            FeedforwardSpec::Zpetc(zpetc(cl, kind)?)
        }
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
