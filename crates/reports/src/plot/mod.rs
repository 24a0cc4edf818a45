//! Pictures beside the data: line plots (log axes optional) written as PNG and SVG.
//!
//! Values are plotted as given: pass engineering units (nm, nm²/Hz) — plotters drops the tick
//! labels of log axes whose values are below ~1e-15. Legends and colour bars sit beside the
//! data, never on it; log axes are labelled at decades (when they span two or more), every
//! tick label is a plain number ("350", "0.25", "1e-9"). Text uses the typeface bundled with
//! the binary.

use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Builds `$builder`'s chart over `$xs × $ys` (tuples of f64), each axis logarithmic or linear
/// as `$log` (a pair of bools) says, and expands the macro `$body!` on it (plotters gives the
/// four combinations four types).
macro_rules! on_axes {
    ($builder:expr, $log:expr, $xs:expr, $ys:expr, $body:ident) => {
        match $log {
            (true, true) => $body!($builder
                .build_cartesian_2d(($xs.0..$xs.1).log_scale(), ($ys.0..$ys.1).log_scale())
                .map_err(|e| e.to_string())?),
            (true, false) => $body!($builder
                .build_cartesian_2d(($xs.0..$xs.1).log_scale(), $ys.0..$ys.1)
                .map_err(|e| e.to_string())?),
            (false, true) => $body!($builder
                .build_cartesian_2d($xs.0..$xs.1, ($ys.0..$ys.1).log_scale())
                .map_err(|e| e.to_string())?),
            (false, false) => $body!($builder
                .build_cartesian_2d($xs.0..$xs.1, $ys.0..$ys.1)
                .map_err(|e| e.to_string())?),
        }
    };
}

mod bars;
mod contour;
mod map;
mod ticks;

pub use bars::Bars;
pub use contour::Contour;
pub use map::{Map, SquareMap};
pub use ticks::plain;
use ticks::tick_label;

/// Plotting errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlotError {
    /// The bundled font could not be registered (a bug if it happens).
    #[error("the bundled plot font could not be registered; plots skipped")]
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

/// The plots' typeface, shipped inside the binary (Ubuntu Light, Ubuntu Font Licence 1.0, via
/// the `epaint_default_fonts` crate): no plot depends on a font package of the machine.
fn font_ready() -> bool {
    static READY: OnceLock<bool> = OnceLock::new();
    *READY.get_or_init(|| {
        register_font(
            "sans-serif",
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        )
        .is_ok()
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

/// Most rings drawn for one curve of points.
const MAX_RINGS: usize = 60;

/// Width of the legend (or colour bar) panel right of the data, px.
const SIDE_PX: u32 = 270;

/// Draws one chart of `fig` in `area` (no caption when `title` is false).
fn draw_chart<DB: DrawingBackend>(
    fig: &Figure,
    area: &DrawingArea<DB, plotters::coord::Shift>,
    x_range: (f64, f64),
    caption: Option<&str>,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let xs = x_range;
    let ys = range(
        fig.series.iter().flat_map(|s| s.y.iter().copied()),
        fig.log_y,
    );
    let mut builder = ChartBuilder::on(area);
    if let Some(c) = caption {
        builder.caption(c, ("sans-serif", 22));
    }
    builder
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
                .x_labels(12)
                .y_labels(10)
                .x_label_formatter(&|v| tick_label(*v, fig.log_x, xs))
                .y_label_formatter(&|v| tick_label(*v, fig.log_y, ys))
                .draw()
                .map_err(|e| e.to_string())?;
            // Measured points first, as rings (at most MAX_RINGS per curve: the CSV has them
            // all), so the model lines stay visible through them.
            let finite = |s: &Series| {
                s.x.iter()
                    .zip(&s.y)
                    .map(|(&x, &y)| (x, y))
                    .filter(|(x, y)| x.is_finite() && y.is_finite())
                    .collect::<Vec<_>>()
            };
            for (i, s) in fig.series.iter().enumerate().filter(|(_, s)| s.points) {
                let color = COLORS[i % COLORS.len()];
                let pts = finite(s);
                let step = pts.len().div_ceil(MAX_RINGS).max(1);
                chart
                    .draw_series(
                        pts.into_iter()
                            .step_by(step)
                            .map(|p| Circle::new(p, 4, color.stroke_width(2))),
                    )
                    .map_err(|e| e.to_string())?;
            }
            for (i, s) in fig.series.iter().enumerate().filter(|(_, s)| !s.points) {
                let color = COLORS[i % COLORS.len()];
                chart
                    .draw_series(LineSeries::new(finite(s), color.stroke_width(2)))
                    .map_err(|e| e.to_string())?;
            }
        }};
    }
    on_axes!(builder, (fig.log_x, fig.log_y), xs, ys, body);
    Ok(())
}

/// Splits `text` into lines of at most `width` characters at spaces.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = vec![String::new()];
    for word in text.split_whitespace() {
        let last = lines.last_mut().expect("one line");
        if !last.is_empty() && last.chars().count() + 1 + word.chars().count() > width {
            lines.push(word.to_owned());
        } else {
            if !last.is_empty() {
                last.push(' ');
            }
            last.push_str(word);
        }
    }
    lines
}

/// An area and its side panel, each a plotters drawing area.
type Split<DB> = (
    DrawingArea<DB, plotters::coord::Shift>,
    DrawingArea<DB, plotters::coord::Shift>,
);

/// Fills `root` white and splits it into the data's area and the side panel right of it
/// (legend or colour bar, [`SIDE_PX`] wide).
fn with_side_panel<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
) -> Result<Split<DB>, String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let width = root.dim_in_pixel().0;
    Ok(root.split_horizontally(width - SIDE_PX))
}

/// A vertical colour bar in the side panel `area` between `top` and `bottom` px: `steps` cells,
/// each coloured `colour(t)` at its middle `t` in [0, 1] (bottom to top), outlined, and the
/// `ticks` (t, label) right of it.
fn draw_colour_bar<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    (top, bottom): (i32, i32),
    steps: i32,
    colour: &dyn Fn(f64) -> RGBColor,
    ticks: &[(f64, String)],
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let (x0, x1) = (20, 50);
    let at = |t: f64| bottom - ((bottom - top) as f64 * t).round() as i32;
    for k in 0..steps {
        let (t0, t1) = (k as f64 / steps as f64, (k + 1) as f64 / steps as f64);
        let fill = colour((k as f64 + 0.5) / steps as f64).filled();
        area.draw(&Rectangle::new([(x0, at(t1)), (x1, at(t0))], fill))
            .map_err(e)?;
    }
    area.draw(&Rectangle::new(
        [(x0, top), (x1, bottom)],
        BLACK.stroke_width(1),
    ))
    .map_err(e)?;
    let font = ("sans-serif", 14).into_font().color(&BLACK);
    for (t, label) in ticks {
        let y = at(*t);
        area.draw(&PathElement::new(
            vec![(x1, y), (x1 + 6, y)],
            BLACK.stroke_width(1),
        ))
        .map_err(e)?;
        area.draw(&Text::new(label.as_str(), (x1 + 10, y - 7), font.clone()))
            .map_err(e)?;
    }
    Ok(())
}

/// Draws `text` wrapped at `width` characters in `area` from (`x`, `y`) down; returns the y
/// below it.
fn draw_wrapped<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    text: &str,
    width: usize,
    (x, mut y): (i32, i32),
) -> Result<i32, String>
where
    DB::ErrorType: 'static,
{
    let font = ("sans-serif", 14).into_font().color(&BLACK);
    for line in wrap(text, width) {
        area.draw(&Text::new(line, (x, y), font.clone()))
            .map_err(|e| e.to_string())?;
        y += 18;
    }
    Ok(y)
}

/// The legend of `series` in the side panel `area`, from `top` px down.
fn draw_legend<DB: DrawingBackend>(
    series: &[Series],
    area: &DrawingArea<DB, plotters::coord::Shift>,
    top: i32,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let font = ("sans-serif", 14).into_font().color(&BLACK);
    let mut y = top;
    for (i, s) in series.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        let mark = (12, y + 8);
        let drawn = if s.points {
            area.draw(&Circle::new(mark, 4, color.stroke_width(2)))
        } else {
            area.draw(&PathElement::new(
                vec![(4, mark.1), (26, mark.1)],
                color.stroke_width(3),
            ))
        };
        drawn.map_err(|e| e.to_string())?;
        for line in wrap(&s.label, 30) {
            area.draw(&Text::new(line, (34, y), font.clone()))
                .map_err(|e| e.to_string())?;
            y += 18;
        }
        y += 8;
    }
    Ok(())
}

/// The x range of the curves of `figs` together.
fn x_range(figs: &[&Figure]) -> (f64, f64) {
    let log = figs.first().is_some_and(|f| f.log_x);
    range(
        figs.iter()
            .flat_map(|f| f.series.iter())
            .flat_map(|s| s.x.iter().copied()),
        log,
    )
}

fn draw<DB: DrawingBackend>(
    fig: &Figure,
    root: DrawingArea<DB, plotters::coord::Shift>,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let (plot, side) = with_side_panel(&root)?;
    draw_chart(fig, &plot, x_range(&[fig]), Some(&fig.title))?;
    draw_legend(&fig.series, &side, 60)?;
    root.present().map_err(|e| e.to_string())
}

/// Two charts over one frequency axis in one picture (a Bode plot: magnitude above phase),
/// one legend beside them; the legend is the top chart's.
#[derive(Debug, Clone)]
pub struct Stacked {
    /// Title of the picture.
    pub title: String,
    /// The upper chart (its own title is not drawn).
    pub top: Figure,
    /// The lower chart (same x axis; its own title is not drawn).
    pub bottom: Figure,
}

impl Drawing for Stacked {
    const SIZE: (u32, u32) = (1270, 900);
    fn draw_on<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root
            .titled(&self.title, ("sans-serif", 22))
            .map_err(|e| e.to_string())?;
        let (w, h) = root.dim_in_pixel();
        let (plots, side) = root.split_horizontally(w - SIDE_PX);
        let (upper, lower) = plots.split_vertically(h / 2);
        let xs = x_range(&[&self.top, &self.bottom]);
        draw_chart(&self.top, &upper, xs, None)?;
        draw_chart(&self.bottom, &lower, xs, None)?;
        draw_legend(&self.top.series, &side, 30)?;
        root.present().map_err(|e| e.to_string())
    }
}

/// Something drawn on any plotters backend, at a fixed picture size: a [`Figure`], a
/// [`Stacked`] pair, a [`Map`].
pub trait Drawing {
    /// Picture size in pixels.
    const SIZE: (u32, u32);
    /// Draws it on `root`.
    fn draw_on<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static;
}

impl Drawing for Figure {
    const SIZE: (u32, u32) = (1270, 620);
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
pub fn write<D: Drawing>(item: &D, stem: &Path) -> Result<Vec<PathBuf>, PlotError> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_png_and_svg_with_the_bundled_font() {
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
        for p in write(&fig, &dir.join("p")).unwrap() {
            assert!(std::fs::metadata(&p).unwrap().len() > 1000, "{p:?}");
        }
    }
}
