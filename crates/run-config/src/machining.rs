//! The machining scenario as configured (`[scenario] kind = "machine"`, thesis Ch. 8): the
//! surface, the spindle and the tool path. Data and range checks only; the surface is loaded
//! by `crate::surface` and cut by `crate::machining`.

use super::{ConfigError, Origin, RepetitiveSection};
use serde::{Deserialize, Serialize};
use servo_core::Spiral;
use std::f64::consts::TAU;
use std::path::PathBuf;

/// A surface as configured (`[scenario.surface]`, `kind = …`). Heights in m, positive away
/// from the workpiece (the tool follows the height).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum SurfaceConfig {
    /// A flat face (§8.5.1, Table 8-2: the roughness test, Ra 1.2 nm).
    Flat,
    /// `z = Ax sin(2πx/λx) + Ay sin(2πy/λy)` (§8.5.4; Table 8-5: ±5 µm, 1 mm).
    SinusoidalGrid {
        /// Amplitude along X in m.
        ax_m: f64,
        /// Amplitude along Y in m.
        ay_m: f64,
        /// Wavelength along X in m.
        lambda_x_m: f64,
        /// Wavelength along Y in m.
        lambda_y_m: f64,
    },
    /// Square array of concave spherical lenslets (§8.5.3; Table 8-4: R 100 mm, L 2 mm).
    BeamIntegrator {
        /// Sphere radius in m.
        radius_m: f64,
        /// Cell pitch in m.
        pitch_m: f64,
    },
    /// `z = A sin(nθ)` (§8.5.2).
    MicroLenslet {
        /// Amplitude in m.
        amplitude_m: f64,
        /// Oscillations per revolution.
        per_revolution: f64,
    },
    /// A greyscale image (PNG) as a height map, centred on the spindle axis (§8.5.5).
    Image {
        /// PNG file, relative to the config file.
        path: PathBuf,
        /// Pixel edge in m.
        pixel_m: f64,
        /// Height of a white pixel in m (Table 8-6: 5 µm).
        depth_range_m: f64,
    },
    /// An optical prescription (TOML in Zemax's conventions, lengths in mm: a base conic with
    /// even-asphere terms, Zernike, XY polynomial and sag-grid departures; see the book's
    /// prescription page), cut as its nose-compensated tool path less the rotationally
    /// symmetric part the Z slide cuts. `start_radius_m` must lie within its aperture.
    Prescription {
        /// Prescription file, relative to the config file.
        path: PathBuf,
        /// Offset the tool along the profile's normal by its nose radius (true); false cuts
        /// with the tool tip on the surface (the error the compensation removes).
        #[serde(default = "compensate_by_default")]
        nose_compensation: bool,
        /// Clearance angle of the tool's flank in rad (★ 0.1222: 7°, a common diamond
        /// tool's); the surface's slope along the cut must stay below it.
        #[serde(default = "default_clearance_rad")]
        clearance_angle_rad: f64,
    },
}

fn compensate_by_default() -> bool {
    true
}

/// ★ 7° in rad.
fn default_clearance_rad() -> f64 {
    7f64.to_radians()
}

impl SurfaceConfig {
    /// The file the surface is read from (an image or a prescription), if any.
    pub fn path_mut(&mut self) -> Option<&mut PathBuf> {
        match self {
            SurfaceConfig::Image { path, .. } | SurfaceConfig::Prescription { path, .. } => {
                Some(path)
            }
            _ => None,
        }
    }

    /// The sinusoidal grid of Table 8-5.
    pub const THESIS_GRID: SurfaceConfig = SurfaceConfig::SinusoidalGrid {
        ax_m: 5e-6,
        ay_m: 5e-6,
        lambda_x_m: 1e-3,
        lambda_y_m: 1e-3,
    };

    /// The beam integrator of Table 8-4.
    pub const THESIS_BEAM: SurfaceConfig = SurfaceConfig::BeamIntegrator {
        radius_m: 0.1,
        pitch_m: 2e-3,
    };
}

/// Radius of the grid part's edge in m: where Table 8-5's 1 mm wavelength at 60 rpm moves the
/// tool at §8.5.4's "about 200 Hz" (200 Hz · 1 mm / 2π).
pub const GRID_EDGE_RADIUS_M: f64 = 200.0 * 1e-3 / TAU;

/// The machining scenario (`[scenario] kind = "machine"`): a facing spiral over a freeform
/// surface at constant spindle speed. Defaults: thesis Table 8-5 at the part's edge.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct Machining {
    /// The surface.
    pub surface: SurfaceConfig,
    /// Spindle speed in rpm (Table 8-5: 60).
    pub spindle_rpm: f64,
    /// Encoder pulses per revolution (§8.3: 80 000).
    pub pulses_per_rev: u64,
    /// Radial feed per revolution in m (5e-6).
    pub feed_m_per_rev: f64,
    /// Radius where the cut starts, in m (the tool moves inward; ★ 31.8e-3, the part's edge:
    /// its size is not printed, but §8.5.4's "about 200 Hz at the edge" with Table 8-5's 1 mm
    /// wavelength at 60 rpm puts the edge at 200 Hz · 1 mm / 2π = 31.8 mm).
    pub start_radius_m: f64,
    /// Tool nose radius in m (Tables 7-3 and 8-2: 0.5 mm): the feed marks' shape.
    pub tool_nose_radius_m: f64,
    /// The simulated machine's tool centre height: the tool's tip above the spindle axis, m
    /// (0; ±100e-6). Geometry alone — the servo does not see it: the simulated cut and
    /// `servo measure` carry it, `servo toolpath` reports what 1 µm of it does. A practice
    /// stage adds a hidden one.
    pub tool_centre_height_m: f64,
    /// The simulated machine's tool X offset: the tool cutting further out than the slide's
    /// reading, m (0; ±100e-6); as `tool_centre_height_m`.
    pub tool_x_offset_m: f64,
    /// Thrust force per unit uncut chip area (feed × depth of cut) in N/m²
    /// (`plant_sim::cutting::SPECIFIC_THRUST_N_PER_M2`, ★ 5e9).
    pub specific_thrust_n_per_m2: f64,
    /// Depth of cut of a finishing pass over a part a roughing pass already shaped, in m
    /// (★ 2e-6: a constant chip, so a constant force). Absent: a single pass from a flat blank
    /// whose face is the surface's highest point, so the depth of cut (and the force) follows
    /// the surface — the worst case for the servo.
    pub finish_depth_m: Option<f64>,
    /// Bandwidth of the controller's encoder tracking loop in Hz (10).
    pub tracker_bandwidth_hz: f64,
    /// Amplitude of a slow sinusoidal variation of the spindle's speed, relative to
    /// `spindle_rpm` (0: none; 0.01 is ±1 %). The controller sees it only through the encoder.
    pub spindle_drift_fraction: f64,
    /// Period of that variation in s (10).
    pub spindle_drift_period_s: f64,
    /// A step of the spindle's speed, relative to `spindle_rpm`, at `spindle_step_time_s`
    /// (0: none; −0.01 slows it by 1 %).
    pub spindle_step_fraction: f64,
    /// When the speed steps, in s from the start of the run (0).
    pub spindle_step_time_s: f64,
    /// Repetitive control on the spindle angle (absent: none).
    pub repetitive: Option<Box<RepetitiveSection>>,
}

impl Default for Machining {
    fn default() -> Self {
        Machining {
            surface: SurfaceConfig::THESIS_GRID,
            spindle_rpm: 60.0,
            pulses_per_rev: 80_000,
            feed_m_per_rev: 5e-6,
            start_radius_m: GRID_EDGE_RADIUS_M,
            tool_nose_radius_m: 0.5e-3,
            tool_centre_height_m: 0.0,
            tool_x_offset_m: 0.0,
            specific_thrust_n_per_m2: plant_sim::cutting::SPECIFIC_THRUST_N_PER_M2,
            finish_depth_m: Some(2e-6),
            tracker_bandwidth_hz: 10.0,
            spindle_drift_fraction: 0.0,
            spindle_drift_period_s: 10.0,
            spindle_step_fraction: 0.0,
            spindle_step_time_s: 0.0,
            repetitive: None,
        }
    }
}

impl Machining {
    /// The simulated machine's tool centre height and X offset, m: the configured ones plus,
    /// on the practice stage of `run`, its hidden ones.
    pub fn tool_setting_m(&self, run: &super::RunSection) -> [f64; 2] {
        let hidden = run.practice_seed.map_or([0.0; 2], |seed| {
            plant_sim::practice::PracticeDraw::draw(
                seed,
                &plant_sim::PlantParams::default().stage,
                run.practice_effects,
            )
            .tool_setting_m()
        });
        [
            self.tool_centre_height_m + hidden[0],
            self.tool_x_offset_m + hidden[1],
        ]
    }

    /// Spindle speed in rad/s.
    pub fn rad_per_s(&self) -> f64 {
        self.spindle_rpm * TAU / 60.0
    }

    /// The tool path.
    pub fn spiral(&self) -> Spiral {
        Spiral {
            start_radius_m: self.start_radius_m,
            feed_m_per_rev: self.feed_m_per_rev,
        }
    }

    /// The band cut when none is asked, `(inner, outer)` radius in m: from `start_radius_m`
    /// inward, ten revolutions at `feed_m_per_rev` — 150 for the flat face, whose roughness
    /// field is 0.27 mm across.
    pub fn default_band_m(&self) -> (f64, f64) {
        let turns = if self.surface == SurfaceConfig::Flat {
            150.0
        } else {
            10.0
        };
        (
            self.start_radius_m - turns * self.feed_m_per_rev,
            self.start_radius_m,
        )
    }

    /// Seconds to cut from `start_radius_m` in to `end_radius_m`.
    pub fn duration_to(&self, end_radius_m: f64) -> f64 {
        (self.start_radius_m - end_radius_m) / self.feed_m_per_rev * 60.0 / self.spindle_rpm
    }

    /// Checks the values (the surface is checked when loaded).
    pub fn validate(&self, at: &Origin) -> Result<(), ConfigError> {
        let check = |key: &str, v: f64, lo: f64, hi: f64, unit: &str| {
            if v > lo && v <= hi {
                Ok(())
            } else {
                Err(at.invalid(
                    &format!("scenario.{key}"),
                    v,
                    &format!("({lo}, {hi}] {unit}"),
                ))
            }
        };
        check("spindle_rpm", self.spindle_rpm, 0.0, 1e4, "rpm")?;
        check(
            "pulses_per_rev",
            self.pulses_per_rev as f64,
            0.0,
            1e9,
            "pulses",
        )?;
        check("feed_m_per_rev", self.feed_m_per_rev, 0.0, 1e-3, "m")?;
        check("start_radius_m", self.start_radius_m, 0.0, 1.0, "m")?;
        check("tool_nose_radius_m", self.tool_nose_radius_m, 0.0, 0.1, "m")?;
        check(
            "tracker_bandwidth_hz",
            self.tracker_bandwidth_hz,
            0.0,
            1e3,
            "Hz",
        )?;
        check(
            "spindle_drift_period_s",
            self.spindle_drift_period_s,
            0.0,
            1e4,
            "s",
        )?;
        let within = |key: &str, v: f64, lo: f64, hi: f64, unit: &str| {
            if (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(at.invalid(
                    &format!("scenario.{key}"),
                    v,
                    &format!("[{lo}, {hi}] {unit}"),
                ))
            }
        };
        within(
            "spindle_drift_fraction",
            self.spindle_drift_fraction,
            0.0,
            0.2,
            "(relative)",
        )?;
        within(
            "spindle_step_fraction",
            self.spindle_step_fraction,
            -0.2,
            0.2,
            "(relative)",
        )?;
        within(
            "spindle_step_time_s",
            self.spindle_step_time_s,
            0.0,
            1e6,
            "s",
        )?;
        within(
            "tool_centre_height_m",
            self.tool_centre_height_m,
            -100e-6,
            100e-6,
            "m",
        )?;
        within(
            "tool_x_offset_m",
            self.tool_x_offset_m,
            -100e-6,
            100e-6,
            "m",
        )?;
        if let Some(r) = &self.repetitive {
            r.validate(at)?;
        }
        if let Some(d) = self.finish_depth_m {
            if !(0.0..=1e-3).contains(&d) {
                return Err(at.invalid("scenario.finish_depth_m", d, "[0, 1e-3] m"));
            }
        }
        if !(self.specific_thrust_n_per_m2 >= 0.0 && self.specific_thrust_n_per_m2 <= 1e12) {
            return Err(at.invalid(
                "scenario.specific_thrust_n_per_m2",
                self.specific_thrust_n_per_m2,
                "[0, 1e12] N/m²",
            ));
        }
        Ok(())
    }
}
