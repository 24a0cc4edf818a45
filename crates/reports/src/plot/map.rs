//! Maps of values on a grid (the form-error map) with their colour bar.

use super::ticks::{plain, tick_label};
use super::{draw_colour_bar, draw_wrapped, with_side_panel, Drawing};
use plotters::prelude::*;

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

impl Drawing for Map {
    const SIZE: (u32, u32) = (1470, 500);
    fn draw_on<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        let map = self;
        let (plot, side) = with_side_panel(&root)?;
        let rows = map.values.len() / map.cols.max(1);
        let scale = map
            .values
            .iter()
            .filter(|v| v.is_finite())
            .fold(0.0f64, |m, v| m.max(v.abs()))
            .max(1e-300);
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
        draw_wrapped(&side, &map.value_label, 30, (20, 20))?;
        let bottom = side.dim_in_pixel().1 as i32 - 60;
        let ticks: Vec<(f64, String)> = (0..=4)
            .map(|k| (k as f64 / 4.0, plain(scale * (k as f64 / 2.0 - 1.0))))
            .collect();
        draw_colour_bar(
            &side,
            (60, bottom),
            200,
            &|t| diverging(scale * (2.0 * t - 1.0), scale),
            &ticks,
        )?;
        root.present().map_err(|e| e.to_string())
    }
}

/// A [`Map`] drawn nearly square (a map over a circular aperture, x and y alike in length).
#[derive(Debug, Clone)]
pub struct SquareMap(pub Map);

impl Drawing for SquareMap {
    const SIZE: (u32, u32) = (1060, 760);
    fn draw_on<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        self.0.draw_on(root)
    }
}
