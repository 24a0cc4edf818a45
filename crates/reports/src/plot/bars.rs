//! Grouped horizontal bars about zero (sensitivities: one row per parameter, one bar per
//! quantity), the legend beside them.

use super::ticks::tick_label;
use super::{draw_legend, with_side_panel, Drawing, Series, COLORS};
use plotters::prelude::*;

/// Grouped bars: `values[group][row]` for each row label (NaN: no bar).
#[derive(Debug, Clone)]
pub struct Bars {
    /// Title.
    pub title: String,
    /// The value axis's label with unit.
    pub value_label: String,
    /// Row labels, top to bottom.
    pub rows: Vec<String>,
    /// Group names (the legend).
    pub groups: Vec<String>,
    /// `values[group][row]`.
    pub values: Vec<Vec<f64>>,
}

impl Drawing for Bars {
    const SIZE: (u32, u32) = (1270, 620);
    fn draw_on<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        let b = self;
        let (plot, side) = with_side_panel(&root)?;
        let reach = b
            .values
            .iter()
            .flatten()
            .filter(|v| v.is_finite())
            .fold(0.0f64, |m, v| m.max(v.abs()))
            .max(1e-3)
            * 1.1;
        let n = b.rows.len().max(1);
        let mut chart = ChartBuilder::on(&plot)
            .caption(&b.title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(260)
            .build_cartesian_2d(-reach..reach, 0.0..n as f64)
            .map_err(|e| e.to_string())?;
        let label = |y: &f64| {
            let r = n as f64 - y - 0.5;
            let i = r.round();
            if (r - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < n {
                b.rows[i as usize].clone()
            } else {
                String::new()
            }
        };
        chart
            .configure_mesh()
            .disable_y_mesh()
            .x_desc(&b.value_label)
            .label_style(("sans-serif", 14))
            .y_labels(2 * n + 1)
            .y_label_formatter(&label)
            .x_label_formatter(&|v| tick_label(*v, false, (-reach, reach)))
            .draw()
            .map_err(|e| e.to_string())?;
        let groups = b.groups.len().max(1) as f64;
        let height = 0.8 / groups;
        for (g, values) in b.values.iter().enumerate() {
            let colour = COLORS[g % COLORS.len()];
            chart
                .draw_series(
                    values
                        .iter()
                        .enumerate()
                        .filter(|(_, v)| v.is_finite())
                        .map(|(r, &v)| {
                            let top = n as f64 - r as f64 - 0.1 - g as f64 * height;
                            Rectangle::new([(0.0, top - height), (v, top)], colour.filled())
                        }),
                )
                .map_err(|e| e.to_string())?;
        }
        chart
            .draw_series([PathElement::new(
                vec![(0.0, 0.0), (0.0, n as f64)],
                BLACK.stroke_width(1),
            )])
            .map_err(|e| e.to_string())?;
        let legend: Vec<Series> = b
            .groups
            .iter()
            .map(|g| Series::line(g.clone(), vec![], vec![]))
            .collect();
        draw_legend(&legend, &side, 60)?;
        root.present().map_err(|e| e.to_string())
    }
}
