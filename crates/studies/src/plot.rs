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

/// A tick label as a plain number: up to four significant digits without trailing zeros
/// ("350", "0.25", "−12.5"), scientific only far from 1 ("1e-9", "2.5e6").
pub fn plain(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v == 0.0 { "0".into() } else { format!("{v}") };
    }
    let a = v.abs();
    let text = if (1e-3..1e6).contains(&a) {
        let digits = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        let t = format!("{a:.digits$}");
        if t.contains('.') {
            t.trim_end_matches('0').trim_end_matches('.').to_owned()
        } else {
            t
        }
    } else {
        let t = format!("{a:.3e}");
        let (m, e) = t.split_once('e').unwrap_or((&t, "0"));
        let m = if m.contains('.') {
            m.trim_end_matches('0').trim_end_matches('.')
        } else {
            m
        };
        format!("{m}e{e}")
    };
    if v < 0.0 {
        format!("−{text}")
    } else {
        text
    }
}

/// Whether `v` is a power of ten (to rounding).
fn is_decade(v: f64) -> bool {
    v > 0.0 && (v.log10() - v.log10().round()).abs() < 1e-9
}

/// The label of tick `v` on an axis over `(lo, hi)`: log axes spanning two decades or more
/// are labelled at decades only; linear axes with as many decimals as their span needs
/// (a 0.05 mm band reads 31.795, not 31.8 three times).
fn tick_label(v: f64, log: bool, (lo, hi): (f64, f64)) -> String {
    if log {
        return if hi / lo >= 100.0 && !is_decade(v) {
            String::new()
        } else {
            plain(v)
        };
    }
    let a = v.abs();
    if v == 0.0 || !(1e-3..1e6).contains(&a) {
        return plain(v);
    }
    let decimals = (2 - (hi - lo).abs().max(1e-12).log10().floor() as i32).clamp(0, 12) as usize;
    let t = format!("{a:.decimals$}");
    let t = if t.contains('.') {
        t.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        t
    };
    if v < 0.0 && t != "0" {
        format!("−{t}")
    } else {
        t
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
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let width = root.dim_in_pixel().0;
    let (plot, side) = root.split_horizontally(width - SIDE_PX);
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

/// Writes `stem.png` and `stem.svg` of two stacked charts; returns their paths.
pub fn write_stacked(fig: &Stacked, stem: &Path) -> Result<Vec<PathBuf>, PlotError> {
    write_png_svg(fig, stem)
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
/// symmetric about zero (blue below, red above, white at 0; cells without data grey) and a
/// colour bar with its unit beside it. Remove an offset before (and say so in the title):
/// the scale spans the largest |value|.
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
    /// The values' quantity and unit, for the colour bar (e.g. "form error (nm)").
    pub value_label: String,
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
    let width = root.dim_in_pixel().0;
    let (plot, side) = root.split_horizontally(width - SIDE_PX);
    let mut chart = ChartBuilder::on(&plot)
        .caption(&map.title, ("sans-serif", 20))
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
        .x_label_formatter(&|v| tick_label(*v, false, map.x))
        .y_label_formatter(&|v| tick_label(*v, false, map.y))
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
    draw_colour_bar(&side, scale, &map.value_label)?;
    root.present().map_err(|e| e.to_string())
}

/// The colour bar of [`diverging`] from −`scale` to `scale` in `area`, labelled.
fn draw_colour_bar<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    scale: f64,
    label: &str,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let h = area.dim_in_pixel().1 as i32;
    let (top, bottom, x0, x1) = (60, h - 60, 20, 50);
    let steps = 200;
    for k in 0..steps {
        let y0 = bottom - (bottom - top) * k / steps;
        let y1 = bottom - (bottom - top) * (k + 1) / steps;
        let v = scale * (2.0 * (k as f64 + 0.5) / steps as f64 - 1.0);
        area.draw(&Rectangle::new(
            [(x0, y1), (x1, y0)],
            diverging(v, scale).filled(),
        ))
        .map_err(|e| e.to_string())?;
    }
    area.draw(&Rectangle::new(
        [(x0, top), (x1, bottom)],
        BLACK.stroke_width(1),
    ))
    .map_err(|e| e.to_string())?;
    let font = ("sans-serif", 14).into_font().color(&BLACK);
    for k in 0..=4 {
        let v = scale * (k as f64 / 2.0 - 1.0);
        let y = bottom - (bottom - top) * k / 4;
        area.draw(&PathElement::new(
            vec![(x1, y), (x1 + 6, y)],
            BLACK.stroke_width(1),
        ))
        .map_err(|e| e.to_string())?;
        area.draw(&Text::new(plain(v), (x1 + 10, y - 7), font.clone()))
            .map_err(|e| e.to_string())?;
    }
    for (i, line) in wrap(label, 30).into_iter().enumerate() {
        area.draw(&Text::new(line, (x0, 20 + 18 * i as i32), font.clone()))
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

impl Drawing for Map {
    const SIZE: (u32, u32) = (1470, 500);
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

    #[test]
    fn tick_labels_are_plain_numbers_with_the_decimals_their_axis_needs() {
        assert_eq!(plain(-350.0), "−350");
        assert_eq!(plain(0.25), "0.25");
        assert_eq!(plain(1e-9), "1e-9");
        assert_eq!(plain(2.5e6), "2.5e6");
        assert_eq!(plain(1000.0), "1000");
        // Log axes over two decades or more: decades only.
        assert_eq!(tick_label(100.0, true, (10.0, 1e4)), "100");
        assert_eq!(tick_label(200.0, true, (10.0, 1e4)), "");
        assert_eq!(tick_label(200.0, true, (150.0, 900.0)), "200");
        // A narrow linear axis keeps its distinguishing digits.
        assert_eq!(tick_label(31.795, false, (31.78, 31.83)), "31.795");
        assert_eq!(tick_label(31.8, false, (31.78, 31.83)), "31.8");
        assert_eq!(tick_label(-350.0, false, (-400.0, 400.0)), "−350");
    }
}
