//! Thesis presets a user picks by name: the two stage masses, the reference scenarios and the
//! machined surfaces of Chapter 8 with the spindle speed each was cut at. Each serializes as
//! its kebab-case name (`intermittent-cut`), the name the command line takes.

use super::{Machining, Scenario, SurfaceConfig};
use plant_sim::params::StageParams;
use std::path::PathBuf;

/// The stage masses of the thesis.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "kebab-case")]
pub enum StagePreset {
    /// 0.074 kg moving mass (Table 5-2).
    Light,
    /// 0.174 kg: +0.100 kg on the coil carrier (§5.7.3).
    Heavy,
}

impl StagePreset {
    /// The stage parameters.
    pub fn params(self) -> StageParams {
        match self {
            StagePreset::Light => StageParams::THESIS,
            StagePreset::Heavy => StageParams::THESIS_HEAVY,
        }
    }
}

/// Scenario kinds, each with thesis defaults for the values not given.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "kebab-case")]
pub enum ScenarioKind {
    /// Hold position (§5.7.3).
    Hold,
    /// Sine reference (amplitude, frequency).
    Sine,
    /// Step reference (amplitude) at 20 % of the run.
    Step,
    /// Exponential chirp over the run (amplitude, start and end frequency).
    Chirp,
    /// Hold during the §7.6 intermittent cut (force, spindle speed).
    IntermittentCut,
    /// Cut the default freeform surface (Table 8-5; spindle speed).
    Machine,
}

/// Values a scenario preset takes from the user; unset ones take the preset's default.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ScenarioValues {
    /// Reference amplitude in m (default 1e-6).
    pub amplitude_m: Option<f64>,
    /// Sine frequency, or chirp start frequency, in Hz (100 Hz sine, 10 Hz chirp).
    pub frequency_hz: Option<f64>,
    /// Chirp end frequency in Hz (2000).
    pub f_end_hz: Option<f64>,
    /// Cutting force in N (intermittent cut: 0.08 N, Table 7-3's cut).
    pub force_n: Option<f64>,
    /// Spindle speed in rpm (intermittent cut: 250, Table 7-3; machining: the surface's).
    pub spindle_rpm: Option<f64>,
}

/// Default cutting force of the intermittent cut in N: Table 7-3's cut
/// ([`plant_sim::cutting::TABLE_7_3_FORCE_N`]).
pub const INTERMITTENT_FORCE_N: f64 = plant_sim::cutting::TABLE_7_3_FORCE_N;
/// Spindle speed of the intermittent cut in rpm (Table 7-3).
pub const INTERMITTENT_RPM: f64 = 250.0;

impl ScenarioKind {
    /// Every kind.
    pub const ALL: [ScenarioKind; 6] = [
        ScenarioKind::Hold,
        ScenarioKind::Sine,
        ScenarioKind::Step,
        ScenarioKind::Chirp,
        ScenarioKind::IntermittentCut,
        ScenarioKind::Machine,
    ];

    /// The scenario of this kind over a run of `duration_s` seconds.
    pub fn scenario(self, v: &ScenarioValues, duration_s: f64) -> Scenario {
        let a = v.amplitude_m.unwrap_or(1e-6);
        match self {
            ScenarioKind::Hold => Scenario::Hold,
            ScenarioKind::Sine => Scenario::Sine {
                amplitude_m: a,
                frequency_hz: v.frequency_hz.unwrap_or(100.0),
            },
            ScenarioKind::Step => Scenario::Step {
                amplitude_m: a,
                at_s: 0.2 * duration_s,
            },
            ScenarioKind::Chirp => Scenario::Chirp {
                amplitude_m: a,
                f_start_hz: v.frequency_hz.unwrap_or(10.0),
                f_end_hz: v.f_end_hz.unwrap_or(2000.0),
            },
            ScenarioKind::IntermittentCut => Scenario::IntermittentCut {
                force_n: v.force_n.unwrap_or(INTERMITTENT_FORCE_N),
                spindle_rpm: v.spindle_rpm.unwrap_or(INTERMITTENT_RPM),
            },
            ScenarioKind::Machine => Scenario::Machine(Machining::default()),
        }
    }
}

/// The surfaces machined in the thesis (Tables 8-3 … 8-6).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "kebab-case")]
pub enum SurfacePreset {
    /// Flat face, 2 µm/rev (Table 8-2; 250 rpm): the roughness test of §8.5.1.
    Flat,
    /// Sinusoidal grid, ±5 µm, 1 mm wavelengths (Table 8-5; 60 rpm).
    SinusoidalGrid,
    /// Beam integrator: R 100 mm lenslets on a 2 mm pitch (Table 8-4; 120 rpm).
    BeamIntegrator,
    /// Single-path micro-lenslets, 10 µm, 375 per revolution (Table 8-3; 16 rpm).
    MicroLenslet,
    /// Greyscale PNG height map (Table 8-6; 30 rpm).
    Image,
}

/// An image height map for [`SurfacePreset::Image`].
#[derive(Debug, Clone, PartialEq)]
pub struct ImageMap {
    /// PNG file.
    pub path: PathBuf,
    /// Pixel edge in m.
    pub pixel_m: f64,
    /// Height of a white pixel in m (Table 8-6: 5 µm).
    pub depth_range_m: f64,
}

impl SurfacePreset {
    /// Every surface.
    pub const ALL: [SurfacePreset; 5] = [
        SurfacePreset::Flat,
        SurfacePreset::SinusoidalGrid,
        SurfacePreset::BeamIntegrator,
        SurfacePreset::MicroLenslet,
        SurfacePreset::Image,
    ];

    /// The surface (`image` for [`SurfacePreset::Image`]).
    pub fn surface(self, image: ImageMap) -> SurfaceConfig {
        match self {
            SurfacePreset::Flat => SurfaceConfig::Flat,
            SurfacePreset::SinusoidalGrid => SurfaceConfig::THESIS_GRID,
            SurfacePreset::BeamIntegrator => SurfaceConfig::THESIS_BEAM,
            SurfacePreset::MicroLenslet => SurfaceConfig::MicroLenslet {
                amplitude_m: 10e-6,
                per_revolution: 375.0,
            },
            SurfacePreset::Image => SurfaceConfig::Image {
                path: image.path,
                pixel_m: image.pixel_m,
                depth_range_m: image.depth_range_m,
            },
        }
    }

    /// The spindle speed the thesis cut it at, in rpm.
    pub fn spindle_rpm(self) -> f64 {
        match self {
            SurfacePreset::Flat => 250.0,
            SurfacePreset::SinusoidalGrid => 60.0,
            SurfacePreset::BeamIntegrator => 120.0,
            SurfacePreset::MicroLenslet => 16.0,
            SurfacePreset::Image => 30.0,
        }
    }

    /// The radial feed the thesis cut it at, in m per revolution (Table 8-2: 2 µm; Tables
    /// 8-3..8-6: 5 µm).
    pub fn feed_m_per_rev(self) -> f64 {
        match self {
            SurfacePreset::Flat => 2e-6,
            _ => 5e-6,
        }
    }
}
