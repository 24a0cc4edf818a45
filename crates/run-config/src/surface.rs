//! Surfaces ready for the tick: the configured surface checked and its image decoded once.

use crate::{ConfigError, Machining, Origin, SurfaceConfig};
use optics::toolpath::ToolPath;
use optics::Prescription;
use servo_core::surface::{BeamIntegrator, HeightMap, MicroLenslet, SinusoidalGrid, Surface};

/// Largest height map, pixels (64 M: 64 MB of luminance).
pub const MAX_PIXELS: u64 = 1 << 26;

/// A PNG as row-major 8-bit luminance (Rec. 601 weights for colour images).
fn decode_grey_png(bytes: &[u8]) -> Result<(Vec<u8>, usize, usize), String> {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder.read_info().map_err(|e| e.to_string())?;
    let (w, h) = (reader.info().width as u64, reader.info().height as u64);
    if w * h > MAX_PIXELS {
        return Err(format!("{w} × {h} pixels: at most {MAX_PIXELS}"));
    }
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
    /// §8.5.1.
    Flat,
    /// §8.5.4.
    Grid(SinusoidalGrid),
    /// §8.5.3.
    Beam(BeamIntegrator),
    /// §8.5.2.
    Lenslet(MicroLenslet),
    /// §8.5.5.
    Image(ImageSurface),
    /// An optical prescription's FTS path (nose-compensated, the Z slide's part removed).
    Prescription(Box<ToolPath>),
}

impl Surface for LoadedSurface {
    #[inline]
    fn depth_m(&self, r_m: f64, theta_rad: f64) -> f64 {
        match self {
            LoadedSurface::Flat => 0.0,
            LoadedSurface::Grid(s) => s.depth_m(r_m, theta_rad),
            LoadedSurface::Beam(s) => s.depth_m(r_m, theta_rad),
            LoadedSurface::Lenslet(s) => s.depth_m(r_m, theta_rad),
            LoadedSurface::Image(s) => s.view().depth_m(r_m, theta_rad),
            LoadedSurface::Prescription(p) => p.fts_m(r_m, theta_rad),
        }
    }

    fn peak_m(&self) -> f64 {
        match self {
            LoadedSurface::Flat => 0.0,
            LoadedSurface::Grid(s) => s.peak_m(),
            LoadedSurface::Beam(s) => s.peak_m(),
            LoadedSurface::Lenslet(s) => s.peak_m(),
            LoadedSurface::Image(s) => s.view().peak_m(),
            LoadedSurface::Prescription(p) => p.fts_range_m().1,
        }
    }
}

impl LoadedSurface {
    /// Checks the values of `m`'s surface and decodes its file from `file` (the bytes, read
    /// by the caller: the plan from the resolved path, a reader from the recording — an image
    /// as it is, a prescription as JSON in SI).
    pub fn load(m: &Machining, at: &Origin, file: Option<&[u8]>) -> Result<Self, ConfigError> {
        let config = &m.surface;
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
        Ok(match config {
            SurfaceConfig::Flat => LoadedSurface::Flat,
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
                let bytes = file.ok_or_else(|| {
                    at.invalid(&key("path"), path.display(), "an image file that was read")
                })?;
                let (pixels, width, height_px) = decode_grey_png(bytes).map_err(|e| {
                    at.invalid(
                        &key("path"),
                        path.display(),
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
            SurfaceConfig::Prescription {
                path,
                nose_compensation,
                clearance_angle_rad,
            } => {
                if !(*clearance_angle_rad > 0.0 && *clearance_angle_rad < 1.5) {
                    return Err(at.invalid(
                        &key("clearance_angle_rad"),
                        clearance_angle_rad,
                        "(0, 1.5) rad",
                    ));
                }
                // A file read by the plan was checked there; a recording's copy is checked here.
                let p: Prescription = match file.map(serde_json::from_slice::<Prescription>) {
                    Some(Ok(p)) => p,
                    Some(Err(e)) => {
                        return Err(at.invalid(
                            &key("path"),
                            path.display(),
                            &format!("a prescription as a run embeds it ({e})"),
                        ))
                    }
                    None => {
                        return Err(at.invalid(
                            &key("path"),
                            path.display(),
                            "a prescription that was read",
                        ))
                    }
                };
                p.validate().map_err(|(part, allowed)| {
                    at.invalid(
                        &key("path"),
                        path.display(),
                        &format!("a valid prescription ({part}: {allowed})"),
                    )
                })?;
                // The aperture as written in mm may land an ulp below the same radius in m.
                if m.start_radius_m > p.aperture_radius_m * (1.0 + 1e-12) {
                    return Err(at.invalid(
                        "scenario.start_radius_m",
                        m.start_radius_m,
                        &format!(
                            "(0, {}] m: within the prescription's aperture",
                            p.aperture_radius_m
                        ),
                    ));
                }
                let nose = if *nose_compensation {
                    m.tool_nose_radius_m
                } else {
                    0.0
                };
                let path = ToolPath::new(p, nose).map_err(|e| {
                    at.invalid(
                        "scenario.tool_nose_radius_m",
                        m.tool_nose_radius_m,
                        &format!(
                            "a nose that finds the surface (no contact at r = {:.4} mm, θ = {:.1}°: a concave region tighter than the nose, or a surface undefined there)",
                            e.radius_m * 1e3,
                            e.theta_rad.to_degrees()
                        ),
                    )
                })?;
                LoadedSurface::Prescription(Box::new(path))
            }
        })
    }
}
