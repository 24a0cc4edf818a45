//! `servo frf`: measure a frequency response — on the simulator in this process, or through
//! the transport on any plant serving a prefix — beside the model.

use crate::args::{ControllerArgs, PlantArgs};
use crate::choice::choice;
use crate::output::{points_bar, print_json, print_written, CliError};
use clap::Args;
use runner::remote_plant::RemotePlant;
use runner::Plan;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::frf::{
    self, Chirp, FrfLoop, FrfMethod, FrfPlant, FrfPoint, FrfSettings, CHIRP_REPEATS, CHIRP_S,
};
use studies::StudyError;

/// Measure a frequency response and compare it with the model.
///
/// Stepped sine (§5.5.1: ramp, settle, integer periods, exact-bin DFT) or chirp, open loop
/// (DAC command → measured position) or closed loop (injection at the controller output,
/// §5.7.5). On the simulator in this process, or with --prefix on the plant serving that run
/// (`servo plant --prefix P --no-recorder --duration S`, or a DAQ daemon): this process joins
/// as its controller and injects the excitation; a clipped reading or command aborts to 0 V.
/// Example: servo frf --loop closed --from 10 --to 20000 --points 40
#[derive(Args, Debug)]
pub struct FrfCmd {
    #[command(flatten)]
    plant: PlantArgs,
    #[command(flatten)]
    controller: ControllerArgs,
    /// Noise seed of the simulated stage.
    #[arg(long)]
    seed: Option<u64>,
    /// Which loop.
    #[arg(long = "loop", value_parser = choice::<FrfLoop>(), default_value = "open")]
    which: FrfLoop,
    /// Lowest frequency in Hz.
    #[arg(value_parser = crate::args::finite, long, default_value_t = 10.0)]
    from: f64,
    /// Highest frequency in Hz.
    #[arg(value_parser = crate::args::finite, long, default_value_t = 20000.0)]
    to: f64,
    /// Frequencies (log-spaced; stepped sine), 2 to 10 000.
    #[arg(long, default_value_t = 30, value_parser = clap::value_parser!(u16).range(2..=10_000))]
    points: u16,
    /// Excitation amplitude in V (stepped sine: below 150 Hz, rising as f² above, up to 5 V,
    /// default 2 mV open loop / 10 mV closed loop; chirp: constant, default 2 mV open loop /
    /// 0.2 V closed loop).
    #[arg(value_parser = crate::args::finite, long)]
    amplitude: Option<f64>,
    /// Stepped sine (§5.5.1) or a repeated exponential chirp with a Welch H1 estimate.
    #[arg(long, value_parser = choice::<FrfMethod>(), default_value = "stepped")]
    method: FrfMethod,
    /// Output directory for CSV, JSON, PNG and SVG.
    #[arg(long, default_value = "frf")]
    out_dir: PathBuf,
    /// Measure on the plant serving this run prefix (the simulator process or a DAQ daemon)
    /// instead of the simulator in this process.
    #[arg(long)]
    prefix: Option<String>,
    /// Print the measured points as JSON.
    #[arg(long)]
    json: bool,
}

impl FrfCmd {
    /// Measures, writes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let mut l = self.plant.load()?;
        self.controller.apply(&mut l.config.controller);
        crate::args::set(&mut l.config.run.seed, self.seed);
        let plan = Plan::new(&l)?;
        let (pts, measured_on) = match &self.prefix {
            None => (
                self.measure(&plan, &mut plan.stage())?,
                match plan.config.run.practice_seed {
                    Some(seed) => format!("the practice stage of seed {seed} (simulated, hidden)"),
                    None => format!("the simulated stage, seed {}", plan.config.run.seed),
                },
            ),
            Some(prefix) => self.measure_remote(&plan, prefix)?,
        };
        let curve = frf::model_curve(&plan, self.which, self.from, self.to, 600)?;
        let title = format!("{:?}-loop FRF", self.which);
        let made_for = run_config::made_for_plant(&plan.config.plant);
        let provenance = reports::frf::Provenance {
            which: self.which,
            made_for: &made_for,
            measured_on: &measured_on,
        };
        let written = reports::frf::write(&pts, &curve, &title, &provenance, &self.out_dir)
            .map_err(StudyError::from)?;
        if self.json {
            print_json(&pts);
            return Ok(ExitCode::SUCCESS);
        }
        self.print(&pts);
        print_written(&written);
        Ok(ExitCode::SUCCESS)
    }

    /// The stepped-sine settings and frequencies.
    fn stepped(&self) -> (FrfSettings, Vec<f64>) {
        let mut settings = FrfSettings::for_loop(self.which);
        crate::args::set(&mut settings.amplitude_v, self.amplitude);
        let freqs = lti::spectral::log_space(self.from, self.to, usize::from(self.points));
        (settings, freqs)
    }

    /// The chirp.
    fn chirp(&self) -> Chirp {
        Chirp {
            band: (self.from, self.to),
            amplitude_v: self.amplitude.unwrap_or(frf::chirp_amplitude_v(self.which)),
            duration_s: CHIRP_S,
            repeats: CHIRP_REPEATS,
        }
    }

    fn measure(&self, plan: &Plan, plant: &mut dyn FrfPlant) -> Result<Vec<FrfPoint>, StudyError> {
        match self.method {
            FrfMethod::Stepped => {
                let (settings, freqs) = self.stepped();
                let bar = points_bar(freqs.len(), "stepped sine", "frequencies");
                let pts = frf::stepped_sine_on(
                    plan,
                    self.which,
                    &freqs,
                    &settings,
                    plant,
                    &mut |d, _| bar.set_position(d as u64),
                );
                bar.finish_and_clear();
                pts
            }
            FrfMethod::Chirp => frf::chirp_on(plan, self.which, &self.chirp(), plant),
        }
    }

    /// Measures on the plant serving `prefix`, saying first how long it must serve.
    fn measure_remote(
        &self,
        plan: &Plan,
        prefix: &str,
    ) -> Result<(Vec<FrfPoint>, String), CliError> {
        let fs = plan.config.plant.timing.servo_rate_hz;
        let ticks = match self.method {
            FrfMethod::Stepped => {
                let (settings, freqs) = self.stepped();
                frf::stepped_sine_ticks(plan, self.which, &freqs, &settings)?
            }
            FrfMethod::Chirp => self.chirp().ticks(fs),
        };
        eprintln!(
            "servo frf: measuring on the plant serving fts-servo/{prefix}/…: {ticks} ticks \
             ({:.2} s of plant time at {fs} Hz; start it with at least that --duration)",
            ticks as f64 / fs
        );
        let mut plant = RemotePlant::join(prefix, plan.config.plant.period_s())?;
        let pts = self.measure(plan, &mut plant)?;
        if plant.skipped() > 0 {
            eprintln!(
                "servo frf: warning — {} samples were published before this side answered them \
                 (a real-time plant moved on): those ticks held the previous command",
                plant.skipped()
            );
        }
        plant.close();
        Ok((pts, format!("the plant serving fts-servo/{prefix}")))
    }

    fn print(&self, pts: &[FrfPoint]) {
        let how = match self.method {
            FrfMethod::Chirp => "chirp + H1",
            FrfMethod::Stepped => "stepped sine",
        };
        println!(
            "FRF ({:?} loop, {how}), measured vs model of the sampled loop:",
            self.which
        );
        println!(
            "  {:>10} {:>12} {:>9} {:>9} {:>9} {:>9}",
            "Hz", "|H| (m/V)", "phase °", "Δ dB", "Δ °", "γ²"
        );
        let (mut worst_db, mut worst_deg) = (0.0f64, 0.0f64);
        let stride = (pts.len() / 30).max(1); // the table shows ~30 rows; the CSV has every point
        for (i, p) in pts.iter().enumerate() {
            if i % stride == 0 {
                println!(
                    "  {:>10.2} {:>12.4e} {:>9.2} {:>+9.3} {:>+9.2} {:>9.5}{}",
                    p.freq_hz,
                    p.magnitude,
                    p.phase_deg,
                    p.error_db(),
                    p.error_deg(),
                    p.coherence,
                    if p.clipped { "  CLIPPED" } else { "" }
                );
            }
            if p.coherence > 0.99 && !p.clipped {
                worst_db = worst_db.max(p.error_db().abs());
                worst_deg = worst_deg.max(p.error_deg().abs());
            }
        }
        println!("  where γ² > 0.99: largest deviation {worst_db:.3} dB, {worst_deg:.2}°");
    }
}
