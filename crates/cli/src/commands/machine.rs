//! `servo machine`: cut a freeform surface in simulation and report the form error.

use super::run::with_progress;
use crate::args::{ControllerArgs, FeedforwardArgs, PlantArgs, RecordingArgs, RunLengthArgs};
use crate::choice::choice;
use crate::interrupt::stop_on_signals;
use crate::output::{print_json, print_summary, print_written, CliError};
use clap::Args;
use run_config::presets::{ImageMap, SurfacePreset};
use run_config::{FeedforwardKind, Machining, Scenario};
use runner::Plan;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::form::{self, FormReport};

/// Machine a freeform surface in simulation (thesis Ch. 8) and show the form error.
///
/// Cuts the facing spiral over `--radius-range` with the spindle synchronised to the servo
/// (encoder → angle → surface height per tick, §8.3), cutting force on, and writes the
/// recording (MCAP), `machine.json` (form error PV/RMS, machined grid amplitude, following
/// error), `form_map.csv`, `trajectory.csv` and pictures into `--out-dir`.
/// Example: servo machine --surface sinusoidal-grid --feedforward zpetc
#[derive(Args, Debug)]
pub struct MachineCmd {
    #[command(flatten)]
    plant: PlantArgs,
    #[command(flatten)]
    length: RunLengthArgs,
    #[command(flatten)]
    controller: ControllerArgs,
    #[command(flatten)]
    feedforward: FeedforwardArgs,
    #[command(flatten)]
    recording: RecordingArgs,
    /// Surface (default: the configured one, else the sinusoidal grid of Table 8-5).
    #[arg(long, value_parser = choice::<SurfacePreset>())]
    surface: Option<SurfacePreset>,
    /// Greyscale PNG height map for --surface image.
    #[arg(long)]
    image: Option<PathBuf>,
    /// Pixel edge of the height map in m.
    #[arg(value_parser = crate::args::finite, long, default_value_t = 20e-6)]
    pixel_m: f64,
    /// Height of a white pixel in m (Table 8-6: 5 µm).
    #[arg(value_parser = crate::args::finite, long, default_value_t = 5e-6)]
    depth_range_m: f64,
    /// Spindle speed in rpm (default: the surface's thesis speed).
    #[arg(value_parser = crate::args::finite, long)]
    rpm: Option<f64>,
    /// The band to cut, `inner:outer` radius in m (the tool moves inward from `outer`; default:
    /// from the configured start radius, the grid part's 31.8 mm edge, ten revolutions in —
    /// 150 for the flat face, whose roughness field is 0.27 mm across).
    #[arg(long)]
    radius_range: Option<String>,
    /// Radial feed per revolution in m (default: the surface's thesis feed, 2e-6 for the flat
    /// face of Table 8-2, 5e-6 for Tables 8-3..8-6).
    #[arg(value_parser = crate::args::finite, long)]
    feed: Option<f64>,
    /// Cut from a flat blank in one pass (the depth of cut and the force follow the
    /// surface) instead of a finishing pass of constant depth over a pre-shaped part.
    #[arg(long)]
    flat_blank: bool,
    /// Learn a correction per revolution (repetitive control on the spindle angle): the
    /// configured [scenario.repetitive], else its defaults (4096 bins, learning gain 0.5).
    #[arg(long)]
    repetitive: bool,
    /// Directory for the analysis files.
    #[arg(long, default_value = "machine")]
    out_dir: PathBuf,
}

/// `inner:outer` in m.
fn radius_range(text: &str) -> Option<(f64, f64)> {
    let (a, b) = text.split_once(':')?;
    let (inner, outer) = (a.trim().parse::<f64>().ok()?, b.trim().parse::<f64>().ok()?);
    (inner >= 0.0 && outer > inner && outer <= 1.0).then_some((inner, outer))
}

impl MachineCmd {
    /// Cuts, analyses, writes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let mut l = self.plant.load()?;
        self.length.apply(&mut l);
        self.controller.apply(&mut l.config.controller);
        self.feedforward
            .apply(&mut l.config.controller, l.origin.path.as_deref());
        let mut m = match &l.config.scenario {
            Scenario::Machine(m) => m.clone(),
            _ => Machining::default(),
        };
        if let Some(preset) = self.surface {
            m.surface = preset.surface(ImageMap {
                path: self.image.clone().unwrap_or_default(),
                pixel_m: self.pixel_m,
                depth_range_m: self.depth_range_m,
            });
            m.spindle_rpm = preset.spindle_rpm();
            m.feed_m_per_rev = preset.feed_m_per_rev();
        }
        crate::args::set(&mut m.spindle_rpm, self.rpm);
        crate::args::set(&mut m.feed_m_per_rev, self.feed);
        let (inner, outer) = match &self.radius_range {
            None => m.default_band_m(),
            Some(text) => radius_range(text).ok_or_else(|| {
                l.origin.invalid(
                    "--radius-range",
                    text,
                    "inner:outer in m, 0 ≤ inner < outer ≤ 1",
                )
            })?,
        };
        if self.flat_blank {
            m.finish_depth_m = None;
        }
        if self.repetitive && m.repetitive.is_none() {
            m.repetitive = Some(Box::default());
        }
        m.start_radius_m = outer;
        if self.length.duration.is_none() {
            l.config.run.duration_s = m.duration_to(inner);
        }
        l.config.scenario = Scenario::Machine(m);
        let plan = Plan::new(&l)?;
        let rec = &self.recording;
        let out = rec.out(&self.out_dir.join("machine.mcap"));
        if out.is_some() {
            std::fs::create_dir_all(&self.out_dir).map_err(|source| CliError::Write {
                path: self.out_dir.clone(),
                source,
            })?;
        }
        let stop = stop_on_signals();
        let (summary, analysis) = with_progress(rec, out.clone(), &stop, "machining", |opts| {
            form::run_machining(&plan, opts)
        })?;
        let title = format!(
            "{}, {}",
            summary.meta.controller,
            match plan.config.controller.feedforward {
                FeedforwardKind::None => "no feedforward",
                FeedforwardKind::Model => "model feedforward",
                FeedforwardKind::Zpetc => "ZPETC feedforward (tool)",
                FeedforwardKind::ZpetcSensor => "ZPETC feedforward (sensor)",
                FeedforwardKind::Fir => "FIR feedforward (measured FRF)",
            }
        );
        let learned = summary.meta.repetitive_table_m.as_deref();
        let written = reports::form::write(&analysis, &title, learned, &self.out_dir)
            .map_err(studies::StudyError::from)?;
        let report = analysis.report();
        let code = crate::interrupt::exit_code(&stop, summary.trip.is_some());
        if rec.json {
            print_json(&report);
            return Ok(code);
        }
        print_summary(&summary, false);
        if let Some(fit) = &plan.fir {
            println!("  {fit}");
        }
        print_form(&report);
        if let Some(p) = &plan.repetitive {
            print_repetitive(p, &report);
        }
        if summary.saturated_ticks > 0 && plan.repetitive.is_some() {
            println!(
                "  note: the DAC saturated for {} ticks: if the form error grew over the revolutions, the learning law is too fast for this stage (lower scenario.repetitive.learning_gain)",
                summary.saturated_ticks
            );
        } else if summary.saturated_ticks > 0 && plan.config.controller.smoothing_hz == 0.0 {
            println!(
                "  note: the DAC saturated for {} ticks: the surface has kinks or steps the loop cannot follow; try --smoothing-hz 5000",
                summary.saturated_ticks
            );
        }
        if let Some(o) = out {
            println!("  wrote {}", o.written());
        }
        print_written(&written);
        Ok(code)
    }
}

/// The repetitive controller's law and how the form error converged.
fn print_repetitive(p: &runner::repetitive::RepetitivePlan, report: &FormReport) {
    let c = &p.config;
    let k = &p.convergence;
    let taps = runner::repetitive::fitted_taps(&c.learning_filter).len();
    let filter = if taps > 1 {
        format!(", a {taps}-tap learning filter fitted to the loop")
    } else {
        String::new()
    };
    println!(
        "  repetitive control: {} bins, learning gain {}, q1 {}, lead {:.2} ticks{filter}; slowest harmonic {} ({:.0} Hz): error × {:.3} per revolution",
        c.bins_per_rev, c.learning_gain, c.q_neighbour, c.lead_ticks, k.harmonic, k.frequency_hz, k.factor
    );
    let revs: Vec<String> = report
        .revolution_rms_m
        .iter()
        .map(|v| format!("{:.1}", v * 1e9))
        .collect();
    println!("    checked on {}", p.checked_on);
    println!("  form error RMS per revolution (nm): {}", revs.join(" "));
    if let Some(s) = report.synchronous_rms_m {
        println!(
            "  spindle-synchronous part (each angle averaged over the revolutions): RMS {:.1} nm",
            s * 1e9
        );
    }
}

/// The form report of a machining run, in a few lines.
pub fn print_form(report: &FormReport) {
    let nm = |v: f64| v * 1e9;
    println!(
        "  machined band {:.3}–{:.3} mm ({:.1} revolutions)",
        report.band_m[0] * 1e3,
        report.band_m[1] * 1e3,
        report.revolutions
    );
    println!(
        "  form error (tool − design): mean {:.1} nm (piston; removed from RMS, PV and the map), RMS {:.1} nm, PV {:.1} nm, max |e − mean| {:.1} nm",
        nm(report.form_error_m.mean),
        nm(report.form_error_m.rms),
        nm(report.form_error_m.pv),
        nm(report.max_abs_form_error_m)
    );
    if let Some(g) = report.grid {
        println!(
            "  grid peak-to-valley: X {:.3} µm, Y {:.3} µm (nominal {:.3} µm; thesis edge 11.18 µm without feedforward)",
            g.machined_pv_x_m * 1e6,
            g.machined_pv_y_m * 1e6,
            g.nominal_pv_x_m * 1e6
        );
    }
    if let Some(f) = report.max_motion_frequency_hz {
        println!("  fastest tool motion {f:.0} Hz at the outer radius");
    }
    if let Some(r) = &report.roughness {
        println!(
            "  roughness over {:.2} × {:.2} mm at r = {:.2} mm (nose R {:.2} mm, feed {:.1} µm/rev; feed marks f²/8R = {:.2} nm PV):",
            r.area_m[0] * 1e3,
            r.area_m[1] * 1e3,
            r.radius_m * 1e3,
            r.nose_radius_m * 1e3,
            r.feed_m_per_rev * 1e6,
            nm(r.feed_mark_pv_m)
        );
        println!(
            "    {:<22} {:>8} {:>8} {:>8} {:>10} {:>10}",
            "nm", "Sa", "Sq", "St", "Ra radial", "Ra along"
        );
        for (what, t) in [
            ("machined surface", &r.surface),
            ("feed marks alone", &r.feed_marks),
            ("servo motion alone", &r.servo_motion),
        ] {
            println!(
                "    {:<22} {:>8.3} {:>8.3} {:>8.3} {:>10.3} {:>10.3}",
                what,
                nm(t.sa_m),
                nm(t.sq_m),
                nm(t.st_m),
                nm(t.ra_radial_m),
                nm(t.ra_along_m)
            );
        }
        println!(
            "    thesis §8.5.1: Ra 1.2 nm on flat NiP (material, tool edge and instrument are not modelled)"
        );
    }
}
