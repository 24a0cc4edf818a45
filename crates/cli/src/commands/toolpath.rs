//! `servo toolpath`: what a prescription's tool path asks of the stage, before it is cut.

use crate::args::PrescriptionCutArgs;
use crate::output::{print_json, print_written, CliError, BAD_INPUT};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::toolpath::TableSize;

/// Check a prescription's tool path against the stage before cutting it.
///
/// Takes the configuration's `[scenario.surface] kind = "prescription"`, compensates the tool
/// nose, leaves the rotationally symmetric part to the Z slide and reports, per radius band at
/// the spindle speed: the FTS stroke, peak velocity, acceleration and DAC voltage, the
/// predicted form error through the configured loop and feedforward, the slope along the cut
/// against the clearance angle and the concave curvature against the nose; over the aperture,
/// the predicted form error on the part (PV and RMS after piston and tilt, and power; Zernike
/// coefficients) and the effect of 1 µm of tool centre height and X offset. Writes
/// `toolpath.json`, the FTS command table `fts_table.csv` (radius × encoder count → height in
/// m), `part_error.csv` (the predicted error as a sag grid in mm, to load back as
/// `[compensation]`) and pictures into `--out-dir`. Exit 2 when a band exceeds a limit.
/// Example: servo toolpath -c cut.toml --feedforward zpetc
#[derive(Args, Debug)]
pub struct ToolpathCmd {
    #[command(flatten)]
    cut: PrescriptionCutArgs,
    /// Radius bands from the aperture's edge to the axis.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u16).range(1..=100))]
    bands: u16,
    /// Radii (rows) of the command table, from the edge to the axis.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u16).range(2..=4096))]
    table_radii: u16,
    /// Encoder counts (columns) of the command table per revolution.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u16).range(8..=8192))]
    table_counts: u16,
    /// Directory for toolpath.json, fts_table.csv, part_error.csv and the pictures.
    #[arg(long, default_value = "toolpath")]
    out_dir: PathBuf,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

impl ToolpathCmd {
    /// Plans, checks, writes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let plan = self.cut.plan()?;
        let study = studies::toolpath::study(&plan, usize::from(self.bands))?;
        let (m, path, _) = studies::toolpath::demands::prescription_of(&plan)?;
        let table = TableSize {
            radii: usize::from(self.table_radii),
            counts: usize::from(self.table_counts),
            pulses_per_rev: m.pulses_per_rev,
        };
        let title = format!("{} rpm, {}", m.spindle_rpm, plan.controller.description);
        let written = reports::toolpath::write(&study, path, table, &title, &self.out_dir)
            .map_err(studies::StudyError::from)?;
        if self.json {
            print_json(&study);
        } else {
            print(&study);
            print_written(&written);
        }
        Ok(if study.feasibility.exceeded.is_empty() {
            ExitCode::SUCCESS
        } else {
            ExitCode::from(BAD_INPUT)
        })
    }
}

/// The report as tables.
fn print(s: &studies::toolpath::ToolpathStudy) {
    let f = &s.feasibility;
    println!(
        "Tool path at {} rpm, nose {:.3} mm compensated: Z slide travel {:.2} µm, FTS stroke {:.3} µm",
        f.spindle_rpm,
        f.nose_radius_m * 1e3,
        f.z_slide_travel_m * 1e6,
        f.fts_stroke_m * 1e6
    );
    println!(
        "  {:>13} {:>10} {:>10} {:>11} {:>9} {:>9} {:>10} {:>7} {:>6}",
        "band mm",
        "stroke µm",
        "v mm/s",
        "a m/s²",
        "DAC V",
        "99.9% Hz",
        "error nm",
        "slope°",
        "R·κ"
    );
    for b in &f.bands {
        println!(
            "  {:>6.2}–{:<6.2} {:>10.3} {:>10.3} {:>11.3} {:>9.3} {:>9.0} {:>10.2} {:>7.2} {:>6.3}",
            b.radius_m[0] * 1e3,
            b.radius_m[1] * 1e3,
            b.stroke_m * 1e6,
            b.peak_velocity_m_per_s * 1e3,
            b.peak_acceleration_m_per_s2,
            b.peak_voltage_v,
            b.bandwidth_hz,
            b.predicted_rms_m * 1e9,
            b.slope_along_cut_rad.to_degrees(),
            b.nose_tightness
        );
    }
    if f.exceeded.is_empty() {
        println!(
            "  within the DAC's ±{} V, the {:.1}° clearance and the nose everywhere",
            f.dac_range_v,
            f.clearance_angle_rad.to_degrees()
        );
    }
    for e in &f.exceeded {
        println!("  EXCEEDED {e}");
    }
    let nm = |r: studies::toolpath::Residual| {
        format!("{:.2} nm PV, {:.3} nm RMS", r.pv_m * 1e9, r.rms_m * 1e9)
    };
    println!(
        "  predicted form error on the part: {} after piston and tilt; {} after power too",
        nm(s.form.tilt_removed),
        nm(s.form.power_removed)
    );
    for t in &s.sensitivity {
        println!(
            "  a {:.0} µm {}: {} after piston and tilt; {} after power too",
            t.size_m * 1e6,
            t.error,
            nm(t.form.tilt_removed),
            nm(t.form.power_removed)
        );
    }
}
