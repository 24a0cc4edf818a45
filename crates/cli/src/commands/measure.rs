//! `servo measure`: a part cut and measured in simulation.

use crate::args::PrescriptionCutArgs;
use crate::output::{print_json, write_result, CliError};
use clap::Args;
use metrology::Instrument;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::measured::simulate::{simulate_measurement, SimulatedMeasurement};

/// Cut the prescription in simulation and measure the part.
///
/// The part over the whole aperture is the loop's steady-state error ring by ring (as `servo
/// toolpath` predicts it) through the stage the run simulates — with `[run] practice_seed`, the
/// practice stage's linear loop (its hidden parameters and modes; its force constant over the
/// stroke and its drift left out) — plus a `[compensation]`'s move of the path and the
/// machine's tool centre height and X offset (`[scenario] tool_centre_height_m`,
/// `tool_x_offset_m`, plus the practice stage's hidden ones with `[run.practice_effects]
/// tool_setting = true`). The instrument samples it on its own pixels with the part mounted at
/// a random pose (`--seed`), each pixel its area's mean, white noise and dropouts, no data
/// off the part; writes a Zygo XYZ file (`--out`) for `servo register`. Prints the truth the
/// measurement hides (the part's form, the setting errors, the mounting).
/// Example: servo measure -c cut.toml --out part.xyz --seed 1
#[derive(Args, Debug)]
pub struct MeasureCmd {
    #[command(flatten)]
    cut: PrescriptionCutArgs,
    /// The measured map (Zygo XYZ).
    #[arg(long, default_value = "part.xyz")]
    out: PathBuf,
    /// Replace an existing map.
    #[arg(long)]
    overwrite: bool,
    /// Seed of the mounting pose, the noise and the dropouts.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Instrument pixels per side.
    #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u16).range(16..=4096))]
    pixels: u16,
    /// Instrument noise per pixel in nm RMS.
    #[arg(long, default_value_t = 0.5, value_parser = crate::args::finite)]
    noise_nm: f64,
    /// Print the truth as JSON.
    #[arg(long)]
    json: bool,
}

impl MeasureCmd {
    /// Plans, cuts, measures, writes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let plan = self.cut.plan()?;
        if !(0.0..=1000.0).contains(&self.noise_nm) {
            return Err(plan
                .origin
                .invalid("noise_nm", self.noise_nm, "[0, 1000] nm")
                .into());
        }
        let instrument = Instrument {
            pixels: usize::from(self.pixels),
            noise_m: self.noise_nm * 1e-9,
            ..Instrument::default()
        };
        let s = simulate_measurement(&plan, &instrument, self.seed)?;
        write_result(&self.out, &metrology::to_zygo_xyz(&s.map), self.overwrite)?;
        if self.json {
            print_json(&s);
        } else {
            print(&s, &self.out);
        }
        Ok(ExitCode::SUCCESS)
    }
}

/// The truth and the file.
fn print(s: &SimulatedMeasurement, out: &std::path::Path) {
    let t = s.part.tilt_removed;
    println!(
        "Cut on {}: the part is {:.2} nm PV, {:.3} nm RMS from the design after piston and tilt",
        s.stage,
        t.pv_m * 1e9,
        t.rms_m * 1e9
    );
    println!(
        "  (truth) tool centre height {:+.3} µm, X offset {:+.3} µm; mounted {:+.1} µm, {:+.1} µm off centre, turned {:+.2}°",
        s.tool_setting_m[0] * 1e6,
        s.tool_setting_m[1] * 1e6,
        s.mounting.decentre_m[0] * 1e6,
        s.mounting.decentre_m[1] * 1e6,
        s.mounting.rotation_rad.to_degrees()
    );
    let valid = s.map.heights_m.iter().filter(|h| h.is_finite()).count();
    println!(
        "  measured {} × {} pixels of {:.4} mm ({valid} with data, {:.2} nm RMS noise): wrote {}",
        s.map.rows,
        s.map.cols,
        s.map.pitch_m[0] * 1e3,
        s.instrument.noise_m * 1e9,
        out.display()
    );
}
