//! `servo intermittent-cut`: the §7.6 intermittent cut per acceleration gain.

use crate::args::{AccelArgs, PlantArgs, RunLengthArgs};
use crate::output::{print_json, print_written, CliError};
use clap::Args;
use plant_sim::params::StageParams;
use run_config::presets::{ScenarioKind, ScenarioValues};
use run_config::Scenario;
use runner::Plan;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::intermittent::{self, DEFAULT_DURATION_S, THESIS_KAS};
use studies::StudyError;

/// The intermittent cut of §7.6 for a list of acceleration gains Ka
///
/// Peak following error
/// and the form-error height at the step edge per Ka (thesis: 75 → 25 nm and 106 → 27 nm
/// for Ka 0 → 4). Without a configuration file it runs §7.6's settings: the PID gains raised
/// with Ka by Kg (§7.4.1; --fixed-pid keeps them) on the 0.174 kg stage (--mass light: Ka = 4
/// with Kg-scaled gains is unstable there), Table 7-3's 0.08 N cut, Ha first order at 300 Hz.
/// Example: servo intermittent-cut --kas 0,1,4
#[derive(Args, Debug)]
pub struct IntermittentCmd {
    #[command(flatten)]
    plant: PlantArgs,
    #[command(flatten)]
    length: RunLengthArgs,
    #[command(flatten)]
    accel: AccelArgs,
    /// Cutting force in N (0.08 N: Table 7-3's 8 µm/rev × 2 µm cut in copper).
    #[arg(value_parser = crate::args::finite, long)]
    force: Option<f64>,
    /// Spindle speed in rpm (250, Table 7-3).
    #[arg(value_parser = crate::args::finite, long)]
    rpm: Option<f64>,
    /// Keep the PID gains fixed as Ka rises (default without a configuration file: raised by
    /// Kg, as §7.6 did; with one, its `controller.kg_scaling` unless this flag is given).
    #[arg(long)]
    fixed_pid: bool,
    /// Acceleration gains (V/V; default §7.5's 0, 0.5, 1, 4).
    #[arg(long, value_delimiter = ',')]
    kas: Option<Vec<f64>>,
    /// Output directory for CSV and JSON.
    #[arg(long, default_value = "intermittent")]
    out_dir: PathBuf,
    /// Print the table as JSON.
    #[arg(long)]
    json: bool,
}

impl IntermittentCmd {
    /// Runs every Ka, writes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let mut l = self.plant.load()?;
        // §7.6's settings unless a configuration says otherwise; --fixed-pid always holds.
        let defaults = self.plant.config.is_none();
        if self.fixed_pid || defaults {
            l.config.controller.kg_scaling = !self.fixed_pid;
        }
        if defaults && self.plant.mass.is_none() && self.plant.plant.is_none() {
            l.config.plant.stage = StageParams::THESIS_HEAVY;
        }
        if self.length.duration.is_none() {
            l.config.run.duration_s = DEFAULT_DURATION_S;
        }
        self.length.apply(&mut l);
        self.accel.apply(&mut l.config.controller);
        let given = ScenarioValues {
            force_n: self.force,
            spindle_rpm: self.rpm,
            ..Default::default()
        };
        if let Scenario::IntermittentCut {
            force_n,
            spindle_rpm,
        } = &mut l.config.scenario
        {
            crate::args::set(force_n, self.force);
            crate::args::set(spindle_rpm, self.rpm);
        } else {
            l.config.scenario = ScenarioKind::IntermittentCut.scenario(&given, 0.0);
        }
        let plan = Plan::new(&l)?;
        let kas = self.kas.clone().unwrap_or(THESIS_KAS.to_vec());
        let rows = intermittent::study(&plan, &kas)?;
        let written =
            reports::intermittent::write(&rows, &self.out_dir).map_err(StudyError::from)?;
        if self.json {
            print_json(&rows);
            return Ok(ExitCode::SUCCESS);
        }
        println!("Intermittent cut (§7.6): force steps twice per revolution");
        println!(
            "  {:>5} {:>8} {:>22} {:>22} {:>16}",
            "Ka", "PID ×", "peak following (nm)", "edge form error (nm)", "following RMS"
        );
        for r in &rows {
            println!(
                "  {:>5} {:>8.3} {:>22.1} {:>22.1} {:>16.1}",
                r.ka,
                r.pid_scale,
                r.peak_following_error_m * 1e9,
                r.edge_form_error_m * 1e9,
                r.following_rms_m * 1e9
            );
        }
        print_written(&written);
        Ok(ExitCode::SUCCESS)
    }
}
