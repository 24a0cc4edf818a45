//! Filled contours of a positive quantity over a two-parameter grid (thesis Fig 6-17: the RMS
//! following error over flexure stiffness and damping), with the optimum marked and its value
//! written beside the chart, and a colour bar with the quantity's unit.

use super::ticks::{plain, tick_label};
use super::{draw_colour_bar, draw_wrapped, with_side_panel, Drawing};
use plotters::prelude::*;

/// A positive quantity on a grid of two parameters.
#[derive(Debug, Clone)]
pub struct Contour {
    /// Title.
    pub title: String,
    /// X label with unit.
    pub x_label: String,
    /// Y label with unit.
    pub y_label: String,
    /// The quantity and its unit, for the colour bar (e.g. "RMS following error (nm)").
    pub value_label: String,
    /// The grid's x values, ascending.
    pub x: Vec<f64>,
    /// The grid's y values, ascending.
    pub y: Vec<f64>,
    /// X axis logarithmic.
    pub log_x: bool,
    /// Y axis logarithmic.
    pub log_y: bool,
    /// Row-major values, `y.len() × x.len()`, row 0 at the lowest y (NaN: no value, grey).
    pub values: Vec<f64>,
    /// A point to mark (x, y) and what to write about it beside the chart.
    pub mark: Option<(f64, f64, String)>,
}

/// Colour bands between the smallest and largest value (log-spaced).
const BANDS: usize = 12;
/// Raster cells across each axis.
const RASTER: usize = 150;

/// The viridis colour map at `t` in [0, 1] (five anchors, linearly blended).
fn viridis(t: f64) -> RGBColor {
    const A: [(f64, f64, f64); 5] = [
        (68.0, 1.0, 84.0),
        (59.0, 82.0, 139.0),
        (33.0, 145.0, 140.0),
        (94.0, 201.0, 98.0),
        (253.0, 231.0, 37.0),
    ];
    let s = t.clamp(0.0, 1.0) * 4.0;
    let i = (s.floor() as usize).min(3);
    let f = s - i as f64;
    let mix = |a: f64, b: f64| (a + (b - a) * f).round() as u8;
    RGBColor(
        mix(A[i].0, A[i + 1].0),
        mix(A[i].1, A[i + 1].1),
        mix(A[i].2, A[i + 1].2),
    )
}

impl Contour {
    fn axis(&self, log: bool, v: f64) -> f64 {
        if log {
            libm::log(v)
        } else {
            v
        }
    }

    /// The grid's nodes in axis coordinates (x, y).
    fn nodes(&self) -> (Vec<f64>, Vec<f64>) {
        (
            self.x.iter().map(|&v| self.axis(self.log_x, v)).collect(),
            self.y.iter().map(|&v| self.axis(self.log_y, v)).collect(),
        )
    }

    /// The value at (u, w) in axis coordinates, bilinear in ln(value) between the grid's
    /// `nodes` ([`Contour::nodes`]).
    fn at(&self, (xs, ys): &(Vec<f64>, Vec<f64>), u: f64, w: f64) -> f64 {
        let locate = |g: &[f64], v: f64| -> (usize, f64) {
            if g.len() < 2 {
                return (0, 0.0);
            }
            let i = g.partition_point(|&a| a <= v).clamp(1, g.len() - 1) - 1;
            (i, ((v - g[i]) / (g[i + 1] - g[i])).clamp(0.0, 1.0))
        };
        let ((i, fx), (j, fy)) = (locate(xs, u), locate(ys, w));
        let cols = self.x.len();
        let v = |r: usize, c: usize| {
            let r = r.min(self.y.len() - 1);
            let c = c.min(cols - 1);
            libm::log(self.values[r * cols + c])
        };
        let low = v(j, i) * (1.0 - fx) + v(j, i + 1) * fx;
        let high = v(j + 1, i) * (1.0 - fx) + v(j + 1, i + 1) * fx;
        libm::exp(low * (1.0 - fy) + high * fy)
    }

    fn value_range(&self) -> (f64, f64) {
        let finite = self.values.iter().filter(|v| v.is_finite() && **v > 0.0);
        let lo = finite.clone().fold(f64::INFINITY, |a, &b| a.min(b));
        let hi = finite.fold(f64::NEG_INFINITY, |a, &b| a.max(b));
        if lo.is_finite() {
            (lo, hi.max(lo * 1.0001))
        } else {
            (1.0, 10.0)
        }
    }
}

/// The band colour of `v` on a log scale over `(lo, hi)`.
fn band(v: f64, (lo, hi): (f64, f64)) -> RGBColor {
    if !v.is_finite() {
        return RGBColor(190, 190, 190);
    }
    let t = (libm::log(v / lo) / libm::log(hi / lo)).clamp(0.0, 0.999_999);
    let k = (t * BANDS as f64).floor();
    viridis((k + 0.5) / BANDS as f64)
}

impl Drawing for Contour {
    const SIZE: (u32, u32) = (1100, 800);
    fn draw_on<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        let c = self;
        let (plot, side) = with_side_panel(&root)?;
        let span = |g: &[f64]| (g[0], g[g.len() - 1].max(g[0] * 1.0001 + 1e-300));
        let (xs, ys) = (span(&c.x), span(&c.y));
        let range = c.value_range();
        let mut builder = ChartBuilder::on(&plot);
        builder
            .caption(&c.title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(80);
        macro_rules! body {
            ($chart:expr) => {{
                let mut chart = $chart;
                chart
                    .configure_mesh()
                    .disable_mesh()
                    .x_desc(&c.x_label)
                    .y_desc(&c.y_label)
                    .label_style(("sans-serif", 14))
                    .x_label_formatter(&|v| tick_label(*v, c.log_x, xs))
                    .y_label_formatter(&|v| tick_label(*v, c.log_y, ys))
                    .draw()
                    .map_err(|e| e.to_string())?;
                // Raster in axis coordinates; runs of one band along a row are one rectangle.
                let back = |log: bool, v: f64| if log { libm::exp(v) } else { v };
                let (u0, u1) = (c.axis(c.log_x, xs.0), c.axis(c.log_x, xs.1));
                let (w0, w1) = (c.axis(c.log_y, ys.0), c.axis(c.log_y, ys.1));
                let (du, dw) = ((u1 - u0) / RASTER as f64, (w1 - w0) / RASTER as f64);
                let nodes = c.nodes();
                let mut cells = Vec::new();
                for r in 0..RASTER {
                    let w = w0 + (r as f64 + 0.5) * dw;
                    let mut start = 0;
                    let mut colour = band(c.at(&nodes, u0 + 0.5 * du, w), range);
                    for k in 1..=RASTER {
                        let next = (k < RASTER)
                            .then(|| band(c.at(&nodes, u0 + (k as f64 + 0.5) * du, w), range));
                        if next != Some(colour) {
                            cells.push(Rectangle::new(
                                [
                                    (
                                        back(c.log_x, u0 + start as f64 * du),
                                        back(c.log_y, w0 + r as f64 * dw),
                                    ),
                                    (
                                        back(c.log_x, u0 + k as f64 * du),
                                        back(c.log_y, w0 + (r + 1) as f64 * dw),
                                    ),
                                ],
                                colour.filled(),
                            ));
                            start = k;
                            if let Some(n) = next {
                                colour = n;
                            }
                        }
                    }
                }
                chart.draw_series(cells).map_err(|e| e.to_string())?;
                // The grid's nodes, small, so the reader sees where the values were computed.
                chart
                    .draw_series(c.y.iter().flat_map(|&y| {
                        c.x.iter()
                            .map(move |&x| Circle::new((x, y), 1, BLACK.mix(0.35).filled()))
                    }))
                    .map_err(|e| e.to_string())?;
                if let Some((x, y, _)) = &c.mark {
                    chart
                        .draw_series([
                            Cross::new((*x, *y), 9, WHITE.stroke_width(5)),
                            Cross::new((*x, *y), 9, RED.stroke_width(2)),
                        ])
                        .map_err(|e| e.to_string())?;
                }
            }};
        }
        on_axes!(builder, (c.log_x, c.log_y), xs, ys, body);
        draw_bar(c, &side, range)?;
        root.present().map_err(|e| e.to_string())
    }
}

/// The colour bar (log scale, band edges labelled) and the mark's note, in the side panel.
fn draw_bar<DB: DrawingBackend>(
    c: &Contour,
    area: &DrawingArea<DB, plotters::coord::Shift>,
    (lo, hi): (f64, f64),
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let top = draw_wrapped(area, &c.value_label, 30, (20, 20))? + 20;
    let bottom = area.dim_in_pixel().1 as i32 - 170;
    let edge = |t: f64| lo * libm::pow(hi / lo, t);
    let ticks: Vec<(f64, String)> = (0..=BANDS)
        .step_by(3)
        .map(|k| {
            let t = k as f64 / BANDS as f64;
            (t, plain(edge(t)))
        })
        .collect();
    draw_colour_bar(
        area,
        (top, bottom),
        BANDS as i32,
        &|t| band(edge(t), (lo, hi)),
        &ticks,
    )?;
    let font = ("sans-serif", 14).into_font().color(&BLACK);
    let x0 = 20;
    let y = bottom + 20;
    area.draw(&Text::new("grey: failed points", (x0, y), font))
        .map_err(e)?;
    if let Some((_, _, note)) = &c.mark {
        area.draw(&Cross::new((x0 + 6, y + 30), 7, RED.stroke_width(2)))
            .map_err(e)?;
        draw_wrapped(area, note, 26, (x0 + 20, y + 22))?;
    }
    Ok(())
}
