//! A measured part against its design: the map read ([`metrology::read_map`]), registered
//! against the prescription of a machining configuration ([`metrology::register`]), the
//! residual in the part's frame (what the next cut's `[compensation]` is made from) and the
//! tool-setting correction the fit implies.

pub mod compensate;
mod files;
pub mod simulate;

use crate::error::StudyError;
use metrology::{ApertureMap, MeasuredMap, ReadOptions, RegisterOptions, Registration};
use optics::toolpath::ToolPath;
use optics::Prescription;
use run_config::surface::LoadedSurface;
use run_config::{Loaded, Scenario};
use serde::Serialize;
use std::path::Path;

pub use files::{write_compensation, write_data};

/// Nodes per side of the residual's map in the part's frame (as `servo toolpath`'s maps).
pub const PART_NODES: usize = crate::toolpath::MAP_NODES;

/// Where the map came from and what it was registered against.
#[derive(Debug, Clone, Serialize)]
pub struct Provenance {
    /// The map file.
    pub map_file: String,
    /// Its format.
    pub format: metrology::MapFormat,
    /// Its size, pixels (rows, columns), and pitch, m.
    pub pixels: [usize; 2],
    /// Pixel pitch along x and y, m.
    pub pitch_m: [f64; 2],
    /// The configuration whose prescription is the design.
    pub config_file: Option<String>,
    /// The tool nose radius the setting errors' signatures were computed with, m.
    pub nose_radius_m: f64,
}

/// The tool-setting change the fit asks for before the next cut.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct SettingCorrection {
    /// Move the tool's centre height by this, m (the fitted centre height's negative).
    pub centre_height_m: f64,
    /// Move the tool's X offset by this, m.
    pub x_offset_m: f64,
}

/// A measured map registered against its design.
#[derive(Debug, Clone, Serialize)]
pub struct MeasuredStudy {
    /// Where it came from.
    pub provenance: Provenance,
    /// The fit and the residual's form.
    pub registration: Registration,
    /// The setting change (None: the setting errors were not fitted).
    pub setting_correction: Option<SettingCorrection>,
    /// The residual in the part's frame, m toward the tool.
    #[serde(skip)]
    pub part_map: ApertureMap,
    /// The map as read, m.
    #[serde(skip)]
    pub measured: MeasuredMap,
}

/// The design of a machining configuration: its prescription without `[compensation]` (a
/// part is judged against the design, not against the path that compensated it) and the
/// nose it is cut with.
pub fn design_of(loaded: &Loaded) -> Result<ToolPath, StudyError> {
    let mut config = loaded.config.clone();
    config.resolve_paths(&loaded.origin);
    let Scenario::Machine(m) = &config.scenario else {
        return Err(loaded
            .origin
            .invalid(
                "scenario.kind",
                "(not machine)",
                "\"machine\" with a prescription",
            )
            .into());
    };
    // The prescription as a run embeds it (JSON), its compensation dropped before the tool
    // path is built: the design alone.
    let file =
        run_config::surface_file(&m.surface, &loaded.origin)?.map(
            |f| match serde_json::from_slice::<Prescription>(&f.bytes) {
                Ok(p) => serde_json::to_vec(&Prescription {
                    compensation: None,
                    ..p
                })
                .unwrap_or(f.bytes),
                Err(_) => f.bytes,
            },
        );
    match LoadedSurface::load(m, &loaded.origin, file.as_deref())? {
        LoadedSurface::Prescription(path) => Ok(*path),
        _ => Err(loaded
            .origin
            .invalid(
                "scenario.surface.kind",
                "(not a prescription)",
                "\"prescription\": a measured part is registered against its prescription",
            )
            .into()),
    }
}

/// Reads `map_file` and registers it against the design of `loaded`.
pub fn register_map(
    loaded: &Loaded,
    map_file: &Path,
    read: &ReadOptions,
    options: &RegisterOptions,
) -> Result<MeasuredStudy, StudyError> {
    let design = design_of(loaded)?;
    let measured = metrology::read_map(map_file, read)?;
    let registration =
        metrology::register(&measured, &design, options).map_err(|e| StudyError::Registration {
            path: map_file.to_path_buf(),
            reason: e.0,
        })?;
    let setting_correction = match (registration.centre_height_m, registration.x_offset_m) {
        (Some(h), Some(e)) => Some(SettingCorrection {
            centre_height_m: -h.value,
            x_offset_m: -e.value,
        }),
        _ => None,
    };
    Ok(MeasuredStudy {
        provenance: Provenance {
            map_file: map_file.display().to_string(),
            format: measured.format,
            pixels: [measured.rows, measured.cols],
            pitch_m: measured.pitch_m,
            config_file: loaded.origin.path.as_ref().map(|p| p.display().to_string()),
            nose_radius_m: design.nose_radius_m(),
        },
        part_map: registration.part_map(PART_NODES),
        setting_correction,
        registration,
        measured,
    })
}
