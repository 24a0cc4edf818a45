//! Freeform machining (thesis Ch. 8): the workpiece on the spindle (plant side: the exact
//! spindle angle, the encoder count, the cutting force of the surface being cut), the surface
//! reference the controller computes per tick from the tracked encoder angle (§8.3), and the
//! form error of the machined part (true tool position minus design surface).

use crate::config::{ConfigError, Loaded};
use serde::{Deserialize, Serialize};
use servo_core::surface::{BeamIntegrator, HeightMap, MicroLenslet, SinusoidalGrid, Surface};
use servo_core::{Block, Encoder, SpindleTracker, SpindleTrackerConfig, Spiral};
use std::f64::consts::TAU;
use std::path::PathBuf;

/// A surface as configured (`[scenario.surface]`, `kind = …`). Heights in m, positive away
/// from the workpiece (the tool follows the height).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum SurfaceConfig {
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
}

impl SurfaceConfig {
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

    /// Checks the values and loads the image, if any.
    pub fn load(&self, at: &Loaded) -> Result<LoadedSurface, ConfigError> {
        let key = |k: &str| format!("scenario.surface.{k}");
        let positive = |k: &str, v: f64, max: f64| {
            if v > 0.0 && v <= max {
                Ok(v)
            } else {
                Err(at.invalid(&key(k), v, &format!("(0, {max}] m")))
            }
        };
        let height = |k: &str, v: f64| {
            if v.is_finite() && v.abs() <= 1e-3 {
                Ok(v)
            } else {
                Err(at.invalid(&key(k), v, "[-1e-3, 1e-3] m"))
            }
        };
        Ok(match self {
            SurfaceConfig::SinusoidalGrid {
                ax_m,
                ay_m,
                lambda_x_m,
                lambda_y_m,
            } => LoadedSurface::Grid(SinusoidalGrid {
                ax_m: height("ax_m", *ax_m)?,
                ay_m: height("ay_m", *ay_m)?,
                lambda_x_m: positive("lambda_x_m", *lambda_x_m, 1.0)?,
                lambda_y_m: positive("lambda_y_m", *lambda_y_m, 1.0)?,
            }),
            SurfaceConfig::BeamIntegrator { radius_m, pitch_m } => {
                let pitch = positive("pitch_m", *pitch_m, 1.0)?;
                if !(*radius_m > pitch / 2f64.sqrt() && *radius_m <= 10.0) {
                    return Err(at.invalid(
                        &key("radius_m"),
                        radius_m,
                        &format!(
                            "({}, 10] m (larger than half the cell diagonal)",
                            pitch / 2f64.sqrt()
                        ),
                    ));
                }
                LoadedSurface::Beam(BeamIntegrator {
                    radius_m: *radius_m,
                    pitch_m: pitch,
                })
            }
            SurfaceConfig::MicroLenslet {
                amplitude_m,
                per_revolution,
            } => {
                if !(*per_revolution > 0.0 && *per_revolution <= 1e6) {
                    return Err(at.invalid(&key("per_revolution"), per_revolution, "(0, 1e6]"));
                }
                LoadedSurface::Lenslet(MicroLenslet {
                    amplitude_m: height("amplitude_m", *amplitude_m)?,
                    per_revolution: *per_revolution,
                })
            }
            SurfaceConfig::Image {
                path,
                pixel_m,
                depth_range_m,
            } => {
                let file = at.resolve(path);
                let (pixels, width, height_px) = read_grey_png(&file).map_err(|e| {
                    at.invalid(
                        &key("path"),
                        file.display(),
                        &format!("a readable PNG ({e})"),
                    )
                })?;
                LoadedSurface::Image(ImageSurface {
                    pixels,
                    width,
                    height: height_px,
                    pixel_m: positive("pixel_m", *pixel_m, 1.0)?,
                    depth_range_m: height("depth_range_m", *depth_range_m)?,
                })
            }
        })
    }
}

/// A PNG as row-major 8-bit luminance (Rec. 601 weights for colour images).
fn read_grey_png(path: &std::path::Path) -> Result<(Vec<u8>, usize, usize), String> {
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder.read_info().map_err(|e| e.to_string())?;
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).map_err(|e| e.to_string())?;
    let channels = info.color_type.samples();
    let (w, h) = (info.width as usize, info.height as usize);
    let grey = buf[..info.buffer_size()]
        .chunks(channels)
        .map(|p| match *p {
            [g] | [g, _] => g,
            [r, g, b] | [r, g, b, _] => {
                (0.299 * r as f64 + 0.587 * g as f64 + 0.114 * b as f64).round() as u8
            }
            _ => 0,
        })
        .collect();
    Ok((grey, w, h))
}

/// Pixels of an image height map, owned (the tick borrows them as a [`HeightMap`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ImageSurface {
    pixels: Vec<u8>,
    width: usize,
    height: usize,
    pixel_m: f64,
    depth_range_m: f64,
}

impl ImageSurface {
    fn view(&self) -> HeightMap<'_> {
        HeightMap {
            pixels: &self.pixels,
            width: self.width,
            height: self.height,
            pixel_m: self.pixel_m,
            depth_range_m: self.depth_range_m,
        }
    }
}

/// A surface ready for the tick (static dispatch, nothing allocated per call).
#[derive(Debug, Clone, PartialEq)]
pub enum LoadedSurface {
    /// §8.5.4.
    Grid(SinusoidalGrid),
    /// §8.5.3.
    Beam(BeamIntegrator),
    /// §8.5.2.
    Lenslet(MicroLenslet),
    /// §8.5.5.
    Image(ImageSurface),
}

impl Surface for LoadedSurface {
    #[inline]
    fn depth_m(&self, r_m: f64, theta_rad: f64) -> f64 {
        match self {
            LoadedSurface::Grid(s) => s.depth_m(r_m, theta_rad),
            LoadedSurface::Beam(s) => s.depth_m(r_m, theta_rad),
            LoadedSurface::Lenslet(s) => s.depth_m(r_m, theta_rad),
            LoadedSurface::Image(s) => s.view().depth_m(r_m, theta_rad),
        }
    }

    fn peak_m(&self) -> f64 {
        match self {
            LoadedSurface::Grid(s) => s.peak_m(),
            LoadedSurface::Beam(s) => s.peak_m(),
            LoadedSurface::Lenslet(s) => s.peak_m(),
            LoadedSurface::Image(s) => s.view().peak_m(),
        }
    }
}

/// The machining scenario (`[scenario] kind = "machine"`): a facing spiral over a freeform
/// surface at constant spindle speed. Defaults: thesis Table 8-5 at the edge of the 50 mm part.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
    /// Radius where the cut starts, in m (the tool moves inward; 25e-3: the part's edge).
    pub start_radius_m: f64,
    /// Cutting force per metre of depth of cut in N/m (★ 4e5: 2 N at 5 µm, §5.7.5/§3.2).
    pub cutting_n_per_m: f64,
    /// Depth of cut of a finishing pass over a part a roughing pass already shaped, in m
    /// (★ 2e-6: a constant chip, so a constant force). Absent: a single pass from a flat blank
    /// whose face is the surface's highest point, so the depth of cut (and the force) follows
    /// the surface — the worst case for the servo.
    pub finish_depth_m: Option<f64>,
    /// Bandwidth of the controller's encoder tracking loop in Hz (10).
    pub tracker_bandwidth_hz: f64,
}

impl Default for Machining {
    fn default() -> Self {
        Machining {
            surface: SurfaceConfig::THESIS_GRID,
            spindle_rpm: 60.0,
            pulses_per_rev: 80_000,
            feed_m_per_rev: 5e-6,
            start_radius_m: 25e-3,
            cutting_n_per_m: 4e5,
            finish_depth_m: Some(2e-6),
            tracker_bandwidth_hz: 10.0,
        }
    }
}

impl Machining {
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

    /// Seconds to cut from `start_radius_m` in to `end_radius_m`.
    pub fn duration_to(&self, end_radius_m: f64) -> f64 {
        (self.start_radius_m - end_radius_m) / self.feed_m_per_rev * 60.0 / self.spindle_rpm
    }

    /// Checks the values (the surface is checked when loaded).
    pub fn validate(&self, at: &Loaded) -> Result<(), ConfigError> {
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
        check(
            "tracker_bandwidth_hz",
            self.tracker_bandwidth_hz,
            0.0,
            1e3,
            "Hz",
        )?;
        if let Some(d) = self.finish_depth_m {
            if !(0.0..=1e-3).contains(&d) {
                return Err(at.invalid("scenario.finish_depth_m", d, "[0, 1e-3] m"));
            }
        }
        if !(self.cutting_n_per_m >= 0.0 && self.cutting_n_per_m <= 1e9) {
            return Err(at.invalid(
                "scenario.cutting_n_per_m",
                self.cutting_n_per_m,
                "[0, 1e9] N/m",
            ));
        }
        Ok(())
    }
}

/// A surface cut along the facing spiral: the design height under the tool at each unwrapped
/// spindle angle (what the plant cuts, the controller follows and the form is judged against).
#[derive(Debug, Clone)]
pub struct SpiralCut {
    surface: LoadedSurface,
    spiral: Spiral,
}

impl SpiralCut {
    /// `surface` along the spiral of `m`.
    pub fn new(m: &Machining, surface: LoadedSurface) -> Self {
        SpiralCut {
            surface,
            spiral: m.spiral(),
        }
    }

    /// X radius in m at the unwrapped spindle angle `theta_rad`.
    #[inline]
    pub fn radius_m(&self, theta_rad: f64) -> f64 {
        self.spiral.radius_m(theta_rad)
    }

    /// Design height in m under the tool at spindle angle `theta_rad`.
    #[inline]
    pub fn height_m(&self, theta_rad: f64) -> f64 {
        self.surface.depth_m(self.radius_m(theta_rad), theta_rad)
    }
}

/// The plant side: the part on a spindle turning at exactly the configured speed from angle 0,
/// cut along the spiral.
#[derive(Debug, Clone)]
pub struct Workpiece {
    cut: SpiralCut,
    rad_per_tick: f64,
    encoder: Encoder,
    cutting_n_per_m: f64,
    peak_m: f64,
    finish_depth_m: Option<f64>,
}

impl Workpiece {
    /// The workpiece of `m` at servo period `period_s` (s).
    pub fn new(m: &Machining, surface: LoadedSurface, period_s: f64) -> Self {
        Workpiece {
            peak_m: surface.peak_m(),
            cut: SpiralCut::new(m, surface),
            rad_per_tick: m.rad_per_s() * period_s,
            encoder: Encoder {
                pulses_per_rev: m.pulses_per_rev,
            },
            cutting_n_per_m: m.cutting_n_per_m,
            finish_depth_m: m.finish_depth_m,
        }
    }

    /// Spindle angle in rad at the start of tick `k` (unwrapped).
    #[inline]
    pub fn angle_rad(&self, k: u64) -> f64 {
        k as f64 * self.rad_per_tick
    }

    /// The encoder count at the start of tick `k`.
    #[inline]
    pub fn encoder_count(&self, k: u64) -> u64 {
        self.encoder.count_at(self.angle_rad(k))
    }

    /// Cutting force on the tool in N during tick `k` (positive away from the part): the
    /// depth of cut at the tool's design position times the cutting stiffness (the force the
    /// thesis applied as a known disturbance, §5.7.5; the few-nm deflection's effect on the
    /// chip is neglected).
    #[inline]
    pub fn cutting_force_n(&self, k: u64) -> f64 {
        let depth = match self.finish_depth_m {
            Some(d) => d,
            None => (self.peak_m - self.cut.height_m(self.angle_rad(k))).max(0.0),
        };
        self.cutting_n_per_m * depth
    }
}

/// The controller side: the surface height the tool should be at, from the tracked encoder
/// angle, `ahead` ticks after the end of the current tick (for preview).
#[derive(Debug, Clone)]
pub struct SurfaceReference {
    cut: SpiralCut,
    tracker: SpindleTracker,
}

impl SurfaceReference {
    /// The reference of `m` at servo period `period_s`.
    pub fn new(
        m: &Machining,
        surface: LoadedSurface,
        period_s: f64,
    ) -> Result<Self, servo_core::Error> {
        Ok(SurfaceReference {
            cut: SpiralCut::new(m, surface),
            tracker: SpindleTrackerConfig {
                pulses_per_rev: m.pulses_per_rev,
                speed_rpm: m.spindle_rpm,
                bandwidth_hz: m.tracker_bandwidth_hz,
            }
            .try_build(period_s)?,
        })
    }

    /// Reads the encoder count of this tick's sample.
    #[inline]
    pub fn track(&mut self, encoder_count: u64) {
        self.tracker.update(encoder_count);
    }

    /// The height at the end of tick `k + ahead` (k: the last tracked tick).
    #[inline]
    pub fn height_m(&self, ahead: usize) -> f64 {
        self.cut
            .height_m(self.tracker.predict_rad(ahead as f64 + 1.0))
    }

    /// Whether the tracker lost the encoder.
    pub fn faulted(&self) -> bool {
        self.tracker.faulted()
    }
}
