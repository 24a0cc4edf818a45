//! `servo register`: a measured part against its design.

use crate::output::{print_json, print_written, CliError};
use clap::Args;
use metrology::{Estimate, LengthUnit, ReadOptions, RegisterOptions};
use run_config::Loaded;
use std::f64::consts::PI;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::measured::MeasuredStudy;

/// Register a measured surface map against the design and report what is left.
///
/// Reads the map (Zygo .datx, MetroPro .dat, Zygo .xyz, NumPy .npy, CSV grid; units, pitch and
/// missing pixels from the file, `--height-unit`/`--pitch-mm` where it states none), fits on
/// the valid pixels over the part the terms the instrument and the machine add to the
/// configuration's prescription — piston, tilt, decentre, rotation about the axis (where the
/// design shows one), with `--power` power, with `--setting-errors` the tool's centre height
/// and X offset — each with its standard uncertainty, and reports the residual as an optician
/// does (PV and RMS after piston and tilt, and power; Standard Zernike terms). Writes
/// `registration.json`, `residual.csv` (the instrument's grid, nm), `part_error.csv` (the
/// residual in the part's frame as a sag grid in mm: what `servo compensate` takes) and
/// pictures into `--out-dir`. A map that does not fit the design (another aperture, too few
/// valid pixels, unknown units) exits 2 naming the file and the reason.
/// Example: servo register -c cut.toml part.datx --setting-errors
#[derive(Args, Debug)]
pub struct RegisterCmd {
    /// The machining configuration whose `[scenario.surface]` prescription is the design.
    #[arg(short, long)]
    config: PathBuf,
    /// The measured map.
    map: PathBuf,
    /// The heights' unit, for a file that does not state it (.npy, a bare CSV grid).
    #[arg(long, value_parser = unit)]
    height_unit: Option<LengthUnit>,
    /// The pixel pitch in mm, for a file that does not state it.
    #[arg(long, value_parser = crate::args::positive)]
    pitch_mm: Option<f64>,
    /// Fit power too (the instrument's focus, or the part's radius error).
    #[arg(long)]
    power: bool,
    /// Fit the tool's centre height and X offset.
    #[arg(long)]
    setting_errors: bool,
    /// Directory for registration.json, residual.csv, part_error.csv and the pictures.
    #[arg(long, default_value = "register")]
    out_dir: PathBuf,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

/// A `--height-unit` value.
fn unit(s: &str) -> Result<LengthUnit, String> {
    LengthUnit::parse(s).ok_or_else(|| format!("'{s}': allowed m, mm, um, nm"))
}

impl RegisterCmd {
    /// Reads, registers, writes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let loaded = Loaded::from_file(&self.config)?;
        let read = ReadOptions {
            height_unit: self.height_unit,
            pitch_m: self.pitch_mm.map(|p| p * 1e-3),
        };
        let options = RegisterOptions {
            power: self.power,
            setting_errors: self.setting_errors,
        };
        let study = studies::measured::register_map(&loaded, &self.map, &read, &options)?;
        let written =
            reports::measured::write(&study, &self.out_dir).map_err(studies::StudyError::from)?;
        if self.json {
            print_json(&study);
        } else {
            print(&study);
            print_written(&written);
        }
        Ok(ExitCode::SUCCESS)
    }
}

/// `e` scaled to a unit, with its uncertainty.
fn pm(e: Estimate, scale: f64, digits: usize) -> String {
    format!("{:+.digits$} ± {:.digits$}", e.value * scale, e.std * scale)
}

/// The report as lines.
fn print(s: &MeasuredStudy) {
    let r = &s.registration;
    let p = &s.provenance;
    println!(
        "Registered {} ({:?}, {} × {} pixels of {:.4} mm): {} valid, {} on the part ({:.1} % of its aperture), {} fitted",
        p.map_file,
        p.format,
        p.pixels[0],
        p.pixels[1],
        p.pitch_m[0] * 1e3,
        r.pixels_valid,
        r.pixels_on_part,
        r.aperture_covered * 100.0,
        r.pixels_fitted
    );
    println!("  piston            {} nm", pm(r.piston_m, 1e9, 2));
    println!(
        "  tilt x, y         {} µrad, {} µrad",
        pm(r.tilt_rad[0], 1e6, 3),
        pm(r.tilt_rad[1], 1e6, 3)
    );
    println!(
        "  decentre x, y     {} µm, {} µm",
        pm(r.decentre_m[0], 1e6, 3),
        pm(r.decentre_m[1], 1e6, 3)
    );
    match r.rotation_rad {
        Some(rot) => println!("  rotation          {}°", pm(rot, 180.0 / PI, 5)),
        None => println!("  rotation          not seen (the design is rotationally symmetric)"),
    }
    if let Some(a) = r.power_m {
        println!("  power (Z4)        {} nm", pm(a, 1e9, 3));
    }
    if let (Some(h), Some(e)) = (r.centre_height_m, r.x_offset_m) {
        println!("  tool centre height {} µm", pm(h, 1e6, 4));
        println!("  tool X offset      {} µm", pm(e, 1e6, 4));
    }
    if let Some(c) = s.setting_correction {
        println!(
            "  before the next cut: move the tool {:+.3} µm in centre height and {:+.3} µm in X",
            c.centre_height_m * 1e6,
            c.x_offset_m * 1e6
        );
    }
    let f = &r.residual;
    println!(
        "  residual: {:.2} nm PV, {:.3} nm RMS after piston and tilt; {:.2} nm PV, {:.3} nm RMS after power too",
        f.tilt_removed.pv_m * 1e9,
        f.tilt_removed.rms_m * 1e9,
        f.power_removed.pv_m * 1e9,
        f.power_removed.rms_m * 1e9
    );
    println!(
        "  uncertainties widened ×{:.2} for the residual's spatial correlation",
        r.variance_inflation.sqrt()
    );
}
