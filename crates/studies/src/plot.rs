//! Pictures beside the data: line plots (log axes optional) written as PNG and SVG.
//!
//! Values are plotted as given: pass engineering units (nm, nm²/Hz) — plotters drops the tick
//! labels of log axes whose values are below ~1e-15. Text is drawn with DejaVu Sans (or another sans TTF) found on the system; without one the
//! plot is skipped with [`PlotError::NoFont`] — the CSV/JSON data are what count.

use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Plotting errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlotError {
    /// No usable font on this machine (install `fonts-dejavu-core`).
    #[error("no TTF font found for plot text (install fonts-dejavu-core); plots skipped")]
    NoFont,
    /// Drawing or writing failed.
    #[error("plot {path}: {message}")]
    Draw {
        /// Output file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}

/// One curve.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Abscissae.
    pub x: Vec<f64>,
    /// Ordinates.
    pub y: Vec<f64>,
    /// Draw points instead of a line (measured data over a model line).
    pub points: bool,
}

impl Series {
    /// A line through the points `(x, y)`.
    pub fn line(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Series {
            label: label.into(),
            x,
            y,
            points: false,
        }
    }
}

/// A figure.
#[derive(Debug, Clone)]
pub struct Figure {
    /// Title (say which thesis figure it corresponds to, where one does).
    pub title: String,
    /// X label with unit.
    pub x_label: String,
    /// Y label with unit.
    pub y_label: String,
    /// Logarithmic x axis.
    pub log_x: bool,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// The curves.
    pub series: Vec<Series>,
}

const FONT_CANDIDATES: [&str; 3] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
];

fn font_ready() -> bool {
    static READY: OnceLock<bool> = OnceLock::new();
    *READY.get_or_init(|| {
        FONT_CANDIDATES
            .iter()
            .find_map(|p| std::fs::read(p).ok())
            .is_some_and(|bytes| {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                register_font("sans-serif", FontStyle::Normal, bytes).is_ok()
            })
    })
}

const COLORS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 23, 23),
];

fn range(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && (!log || *v > 0.0))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return (if log { 1e-3 } else { 0.0 }, 1.0);
    }
    if log {
        // Ten decades are plenty to read a spectrum; deeper values are clipped.
        ((lo / 1.5).max(hi * 1e-10), hi * 1.5)
    } else {
        let pad = if hi > lo {
            0.05 * (hi - lo)
        } else {
            0.05 * hi.abs().max(1e-30)
        };
        (lo - pad, hi + pad)
    }
}

fn draw<DB: DrawingBackend>(
    fig: &Figure,
    root: DrawingArea<DB, plotters::coord::Shift>,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let xs = range(
        fig.series.iter().flat_map(|s| s.x.iter().copied()),
        fig.log_x,
    );
    let ys = range(
        fig.series.iter().flat_map(|s| s.y.iter().copied()),
        fig.log_y,
    );
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(&fig.title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(80);
    macro_rules! body {
        ($chart:expr) => {{
            let mut chart = $chart;
            chart
                .configure_mesh()
                .x_desc(&fig.x_label)
                .y_desc(&fig.y_label)
                .label_style(("sans-serif", 14))
                .y_label_formatter(&|v| {
                    if fig.log_y {
                        format!("{v:.0e}")
                    } else {
                        format!("{v:.3}")
                    }
                })
                .draw()
                .map_err(|e| e.to_string())?;
            for (i, s) in fig.series.iter().enumerate() {
                let color = COLORS[i % COLORS.len()];
                let pts =
                    s.x.iter()
                        .zip(&s.y)
                        .map(|(&x, &y)| (x, y))
                        .filter(|(x, y)| x.is_finite() && y.is_finite());
                if s.points {
                    chart
                        .draw_series(pts.map(|p| Circle::new(p, 3, color.filled())))
                        .map_err(|e| e.to_string())?
                        .label(&s.label)
                        .legend(move |(x, y)| Circle::new((x, y), 3, color.filled()));
                } else {
                    chart
                        .draw_series(LineSeries::new(pts, color.stroke_width(2)))
                        .map_err(|e| e.to_string())?
                        .label(&s.label)
                        .legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                        });
                }
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 14))
                .draw()
                .map_err(|e| e.to_string())?;
        }};
    }
    match (fig.log_x, fig.log_y) {
        (true, true) => body!(builder
            .build_cartesian_2d((xs.0..xs.1).log_scale(), (ys.0..ys.1).log_scale())
            .map_err(|e| e.to_string())?),
        (true, false) => body!(builder
            .build_cartesian_2d((xs.0..xs.1).log_scale(), ys.0..ys.1)
            .map_err(|e| e.to_string())?),
        (false, true) => body!(builder
            .build_cartesian_2d(xs.0..xs.1, (ys.0..ys.1).log_scale())
            .map_err(|e| e.to_string())?),
        (false, false) => body!(builder
            .build_cartesian_2d(xs.0..xs.1, ys.0..ys.1)
            .map_err(|e| e.to_string())?),
    }
    root.present().map_err(|e| e.to_string())
}

/// Something drawn on any plotters backend, at a fixed picture size.
trait Drawing {
    /// Picture size in pixels.
    const SIZE: (u32, u32);
    fn draw_on<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static;
}

impl Drawing for Figure {
    const SIZE: (u32, u32) = (1000, 620);
    fn draw_on<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        draw(self, root)
    }
}

/// Writes `stem.png` and `stem.svg` of `item`; returns their paths.
fn write_png_svg<D: Drawing>(item: &D, stem: &Path) -> Result<Vec<PathBuf>, PlotError> {
    if !font_ready() {
        return Err(PlotError::NoFont);
    }
    let (png, svg) = (stem.with_extension("png"), stem.with_extension("svg"));
    let size = D::SIZE;
    let err = |path: &PathBuf| {
        let path = path.clone();
        move |message| PlotError::Draw { path, message }
    };
    item.draw_on(BitMapBackend::new(&png, size).into_drawing_area())
        .map_err(err(&png))?;
    item.draw_on(SVGBackend::new(&svg, size).into_drawing_area())
        .map_err(err(&svg))?;
    Ok(vec![png, svg])
}

/// Writes `stem.png` and `stem.svg`; returns their paths.
pub fn write(fig: &Figure, stem: &Path) -> Result<Vec<PathBuf>, PlotError> {
    write_png_svg(fig, stem)
}

/// A map of values on a regular grid (a form-error map), drawn with a diverging colour scale
/// symmetric about zero (blue below, red above, white at 0; cells without data grey).
#[derive(Debug, Clone)]
pub struct Map {
    /// Title.
    pub title: String,
    /// X label with unit.
    pub x_label: String,
    /// Y label with unit.
    pub y_label: String,
    /// X extent (first column's left edge, last column's right edge).
    pub x: (f64, f64),
    /// Y extent (first row's lower edge, last row's upper edge).
    pub y: (f64, f64),
    /// Columns.
    pub cols: usize,
    /// Row-major values, `rows × cols` (NaN: no data), row 0 at the bottom.
    pub values: Vec<f64>,
}

/// Blue–white–red for `v / scale` in [−1, 1].
fn diverging(v: f64, scale: f64) -> RGBColor {
    if !v.is_finite() {
        return RGBColor(200, 200, 200);
    }
    let t = (v / scale).clamp(-1.0, 1.0);
    let fade = |c: u8, t: f64| (255.0 - (255.0 - c as f64) * t).round() as u8;
    if t >= 0.0 {
        RGBColor(fade(180, t), fade(20, t), fade(30, t))
    } else {
        RGBColor(fade(30, -t), fade(60, -t), fade(180, -t))
    }
}

fn draw_map<DB: DrawingBackend>(
    map: &Map,
    root: DrawingArea<DB, plotters::coord::Shift>,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let rows = map.values.len() / map.cols.max(1);
    let scale = map
        .values
        .iter()
        .filter(|v| v.is_finite())
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(1e-300);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{} (colour scale ±{scale:.4})", map.title),
            ("sans-serif", 20),
        )
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(map.x.0..map.x.1, map.y.0..map.y.1)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(&map.x_label)
        .y_desc(&map.y_label)
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| e.to_string())?;
    let (dx, dy) = (
        (map.x.1 - map.x.0) / map.cols as f64,
        (map.y.1 - map.y.0) / rows.max(1) as f64,
    );
    chart
        .draw_series(map.values.iter().enumerate().map(|(i, &v)| {
            let (r, c) = (i / map.cols, i % map.cols);
            let x0 = map.x.0 + c as f64 * dx;
            let y0 = map.y.0 + r as f64 * dy;
            Rectangle::new([(x0, y0), (x0 + dx, y0 + dy)], diverging(v, scale).filled())
        }))
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())
}

impl Drawing for Map {
    const SIZE: (u32, u32) = (1200, 500);
    fn draw_on<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        draw_map(self, root)
    }
}

/// Writes `stem.png` and `stem.svg` of a map; returns their paths.
pub fn write_map(map: &Map, stem: &Path) -> Result<Vec<PathBuf>, PlotError> {
    write_png_svg(map, stem)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_png_and_svg_when_a_font_exists() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let x: Vec<f64> = (1..100).map(|i| i as f64 * 10.0).collect();
        let fig = Figure {
            title: "test".into(),
            x_label: "frequency (Hz)".into(),
            y_label: "PSD (m²/Hz)".into(),
            log_x: true,
            log_y: true,
            series: vec![Series {
                label: "a".into(),
                y: x.iter().map(|f| 1e-2 / f).collect(),
                x,
                points: false,
            }],
        };
        match write(&fig, &dir.join("p")) {
            Ok(paths) => {
                for p in paths {
                    assert!(std::fs::metadata(&p).unwrap().len() > 1000, "{p:?}");
                }
            }
            Err(PlotError::NoFont) => eprintln!("no font on this machine: plot test skipped"),
            Err(e) => panic!("{e}"),
        }
    }
}
