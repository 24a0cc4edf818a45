//! `servo toolpath`: what a prescription's tool path asks of the stage, before it is cut.

use crate::args::{ControllerArgs, FeedforwardArgs, PlantArgs};
use crate::output::{print_json, print_written, write_result, CliError, BAD_INPUT};
use clap::Args;
use runner::config::Scenario;
use runner::surface::LoadedSurface;
use runner::toolpath::{command_table, feasibility};
use runner::Plan;
use std::path::PathBuf;
use std::process::ExitCode;

/// Check a prescription's tool path against the stage before cutting it.
///
/// Takes the configuration's `[scenario.surface] kind = "prescription"`, compensates the tool
/// nose, leaves the rotationally symmetric part to the Z slide and reports, per radius band at
/// the spindle speed: the FTS stroke, peak velocity, acceleration and DAC voltage, the
/// predicted form error through the configured loop and feedforward, the slope along the cut
/// against the clearance angle and the concave curvature against the nose. Writes
/// `toolpath.json` and the FTS command table `fts_table.csv` (radius × encoder count → height
/// in m) into `--out-dir`. Exit 2 when a band exceeds a limit.
/// Example: servo toolpath -c cut.toml --feedforward zpetc
#[derive(Args, Debug)]
pub struct ToolpathCmd {
    #[command(flatten)]
    plant: PlantArgs,
    #[command(flatten)]
    controller: ControllerArgs,
    #[command(flatten)]
    feedforward: FeedforwardArgs,
    /// Spindle speed in rpm (default: the configured one).
    #[arg(value_parser = crate::args::finite, long)]
    rpm: Option<f64>,
    /// Radius bands from the aperture's edge to the axis.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u16).range(1..=100))]
    bands: u16,
    /// Radii (rows) of the command table, from the edge to the axis.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u16).range(2..=4096))]
    table_radii: u16,
    /// Encoder counts (columns) of the command table per revolution.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u16).range(8..=8192))]
    table_counts: u16,
    /// Directory for toolpath.json and fts_table.csv.
    #[arg(long, default_value = "toolpath")]
    out_dir: PathBuf,
    /// Replace the files if they exist.
    #[arg(long)]
    overwrite: bool,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

impl ToolpathCmd {
    /// Plans, checks, writes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let mut l = self.plant.load()?;
        self.controller.apply(&mut l);
        self.feedforward.apply(&mut l);
        if let Scenario::Machine(m) = &mut l.config.scenario {
            crate::args::set(&mut m.spindle_rpm, self.rpm);
        }
        let plan = Plan::new(&l)?;
        let f = feasibility(&plan, usize::from(self.bands))?;
        let (Scenario::Machine(m), Some(LoadedSurface::Prescription(path))) =
            (&plan.config.scenario, &plan.surface)
        else {
            unreachable!("feasibility accepted the plan's prescription")
        };
        let table = command_table(
            path,
            usize::from(self.table_radii),
            usize::from(self.table_counts),
            m.pulses_per_rev,
        );
        let json_path = self.out_dir.join("toolpath.json");
        let table_path = self.out_dir.join("fts_table.csv");
        std::fs::create_dir_all(&self.out_dir).map_err(|source| CliError::Write {
            path: self.out_dir.clone(),
            source,
        })?;
        let json = serde_json::to_string_pretty(&f).unwrap_or_default();
        write_result(&json_path, &json, self.overwrite)?;
        write_result(&table_path, &table, self.overwrite)?;
        if self.json {
            print_json(&f);
        } else {
            print(&f);
            print_written(&studies::report::Written {
                files: vec![json_path, table_path],
                note: None,
            });
        }
        Ok(if f.exceeded.is_empty() {
            ExitCode::SUCCESS
        } else {
            ExitCode::from(BAD_INPUT)
        })
    }
}

/// The report as a table.
fn print(f: &runner::toolpath::Feasibility) {
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
}
