//! The ZPETC feedforward of a run, designed from its sampled closed loop (reference → tool, or
//! reference → sensor reading for `zpetc-sensor`).

use crate::analysis::{input, output};
use crate::config::{FeedforwardKind, Loaded};
use crate::preview::MAX_PREVIEW;
use crate::run::{closed_loop, RunError};
use crate::servo_loop::ZPETC_SECTIONS;
use design::lti::StateSpace;
use design::zpetc::{design, ZpetcDesign};
use servo_core::{IirCoeffs, Zpetc, ZpetcConfig};

/// Largest reduced order tried.
const MAX_ORDER: usize = 2 * ZPETC_SECTIONS - 4;

/// Relative accuracy the reduced loop model must reach up to [`check_band_hz`].
pub const MODEL_TOLERANCE: f64 = 1e-3;

/// The band over which the reduced model is checked: up to a fifth of Nyquist (Hz).
pub fn check_band_hz(period_s: f64) -> f64 {
    0.1 / period_s
}

/// The ZPETC design for the loop of `cfg`: reference in m → tool position in m (or the
/// measured position in m for `zpetc-sensor`).
pub fn design_for(cfg: &Loaded) -> Result<ZpetcDesign, RunError> {
    let (cl, _) = closed_loop(cfg)?;
    let sys = &cl.sys;
    let out = match cfg.config.controller.feedforward {
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
    .map_err(|e| RunError::Plant(format!("ZPETC feedforward: {e}")))
}

/// The servo-core ZPETC block for the loop of `cfg`. The tool output of tick k is the tool at
/// the tick's end; the measured output is the sample the tick *starts* with, so the sensor
/// design is advanced by one tick (its preview shrinks by one) to make the sample closing
/// tick k follow the trajectory at that time, as the telemetry pairs them.
pub fn zpetc(cfg: &Loaded) -> Result<Zpetc<ZPETC_SECTIONS>, RunError> {
    let mut d = design_for(cfg)?;
    if cfg.config.controller.feedforward == FeedforwardKind::ZpetcSensor {
        d.preview = d.preview.checked_sub(1).ok_or_else(|| {
            RunError::Plant("ZPETC feedforward: the sensor loop has no delay to advance".into())
        })?;
    }
    if d.sections.len() > ZPETC_SECTIONS || d.preview > MAX_PREVIEW {
        return Err(RunError::Plant(format!(
            "ZPETC feedforward needs {} sections and {} ticks of preview (at most {ZPETC_SECTIONS} and {MAX_PREVIEW})",
            d.sections.len(),
            d.preview
        )));
    }
    let mut sections = [IirCoeffs::<2>::IDENTITY; ZPETC_SECTIONS];
    for (s, &[b0, b1, b2, a1, a2]) in sections.iter_mut().zip(&d.sections) {
        *s = IirCoeffs::new(b0, [b1, b2], [a1, a2]);
    }
    ZpetcConfig {
        gain: d.gain,
        sections,
        preview: d.preview,
    }
    .try_build()
    .map_err(|e| RunError::Plant(format!("ZPETC feedforward: {e}")))
}
