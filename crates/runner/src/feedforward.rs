//! The feedforward of a run, built once from its plan: the stage-model inverse, or the ZPETC
//! designed from the run's sampled closed loop (reference → tool, or reference → sensor
//! reading for `zpetc-sensor`).

use crate::closed_loop::{input, output, ClosedLoop};
use crate::config::{ConfigError, FeedforwardKind, Origin, RunConfig};
use crate::preview::MAX_PREVIEW;
use design::zpetc::{design, ZpetcDesign, ZpetcError};
use lti::StateSpace;
use servo_core::{Block, IirCoeffs, Zpetc, ZpetcConfig};

/// Sections of the largest ZPETC filter the loop runs.
pub const ZPETC_SECTIONS: usize = 12;

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
    /// The reference → sensor loop has no delay to advance by one tick.
    #[error("ZPETC feedforward: the sensor loop has no delay to advance")]
    NoSensorDelay,
    /// The design does not fit the loop's fixed-size filter or preview.
    #[error("ZPETC feedforward needs {sections} sections and {preview} ticks of preview (at most {ZPETC_SECTIONS} and {MAX_PREVIEW})")]
    TooLarge {
        /// Sections needed.
        sections: usize,
        /// Preview needed, ticks.
        preview: usize,
    },
    /// servo-core refused the filter.
    #[error("ZPETC feedforward: {0}")]
    Block(servo_core::Error),
}

/// The feedforward of a loop, ready to run (cloned into each [`crate::ServoLoop`]).
#[derive(Debug, Clone)]
pub enum Feedforward {
    /// Feedback only.
    None,
    /// Stage-model inverse on finite differences of the window (V).
    Model(servo_core::Feedforward),
    /// Reshaped reference (m).
    Zpetc(Box<Zpetc<ZPETC_SECTIONS>>),
}

impl Feedforward {
    /// The feedforward `config` asks for, on the loop `cl` (errors located in `at`).
    pub fn build(
        config: &RunConfig,
        at: &Origin,
        cl: &ClosedLoop,
    ) -> Result<Self, crate::RunError> {
        let c = &config.controller;
        Ok(match c.feedforward {
            FeedforwardKind::None => Feedforward::None,
            FeedforwardKind::Model => Feedforward::Model(model(config, at)?),
            FeedforwardKind::Zpetc | FeedforwardKind::ZpetcSensor => {
                Feedforward::Zpetc(Box::new(zpetc(cl, c.feedforward)?))
            }
        })
    }

    /// Ticks of reference preview it needs.
    pub fn preview(&self) -> usize {
        match self {
            Feedforward::None => 0,
            Feedforward::Model(_) => 1,
            Feedforward::Zpetc(z) => z.preview(),
        }
    }

    /// A block latched a fault.
    pub fn faulted(&self) -> bool {
        match self {
            Feedforward::None => false,
            Feedforward::Model(f) => f.faulted(),
            Feedforward::Zpetc(z) => z.faulted(),
        }
    }
}

/// `m·r̈ + c·ṙ + k·r` of the configured stage, in V.
fn model(config: &RunConfig, at: &Origin) -> Result<servo_core::Feedforward, ConfigError> {
    let (st, a) = (&config.plant.stage, &config.plant.actuator);
    let limit = config.controller.limit_v;
    servo_core::FeedforwardConfig {
        mass_kg: st.suspended_mass_kg(),
        damping_n_s_per_m: st.c2_n_s_per_m,
        stiffness_n_per_m: st.k2_n_per_m,
        newton_per_unit: a.current_gain_a_per_v * a.kt_n_per_a,
        limits: servo_core::Limits::try_new(-limit, limit)
            .map_err(|e| at.invalid("controller.limit_v", e, "(0, 10] V"))?,
    }
    .try_build()
    .map_err(|e| at.invalid("plant", e, "a valid stage for feedforward"))
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

/// The servo-core ZPETC block for the loop `cl`. The tool output of tick k is the tool at the
/// tick's end; the measured output is the sample the tick *starts* with, so the sensor design
/// is advanced by one tick (its preview shrinks by one) to make the sample closing tick k
/// follow the trajectory at that time, as the telemetry pairs them.
pub fn zpetc(
    cl: &ClosedLoop,
    kind: FeedforwardKind,
) -> Result<Zpetc<ZPETC_SECTIONS>, FeedforwardError> {
    let mut d = design_for(cl, kind)?;
    if kind == FeedforwardKind::ZpetcSensor {
        d.preview = d
            .preview
            .checked_sub(1)
            .ok_or(FeedforwardError::NoSensorDelay)?;
    }
    if d.sections.len() > ZPETC_SECTIONS || d.preview > MAX_PREVIEW {
        return Err(FeedforwardError::TooLarge {
            sections: d.sections.len(),
            preview: d.preview,
        });
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
    .map_err(FeedforwardError::Block)
}
