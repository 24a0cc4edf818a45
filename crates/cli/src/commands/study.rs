//! `servo study`: design-space studies (thesis §6.5) on every local core, resumable, in shards
//! for a cluster, and `servo study merge` to join the shards.

use crate::output::{points_bar, print_json, print_written, CliError};
use clap::{Args, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use studies::design_space::evaluate::Point;
use studies::design_space::journal::{claim, Shard};
use studies::design_space::spec::Study;
use studies::design_space::{axis_label, execute, finish, gather};

/// Design-space study over plant parameters and controller families (thesis §6.5).
///
/// FILE is a run configuration (the operating point) with a [study] table: controller families
/// (h2, h2-bandwidth, pid), sampling (grid, random, latin-hypercube) and [[study.parameter]]
/// entries (any numeric key of `servo config --dump`, or plant.stage.moving_mass_kg). Each point
/// is a synthesis plus an exact budget; points are journaled as they finish (run the same
/// command again to resume), failed points are kept with their reason. Writes study.csv,
/// study.parquet, study.json, sensitivity.csv and the plots of Fig 6-14 / 6-17. Ctrl-C (or
/// SIGTERM) stops after the points being evaluated, keeping them; a second Ctrl-C stops at once.
/// Example: servo study examples/studies/flexure.toml --out-dir flexure
#[derive(Args, Debug)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct StudyCmd {
    #[command(subcommand)]
    merge: Option<StudySub>,
    /// The study file.
    #[arg(required = true)]
    file: Option<PathBuf>,
    /// Study folder: the description, the journals, the results (resumed if it holds this
    /// study; refused if it holds another).
    #[arg(long, default_value = "study")]
    out_dir: PathBuf,
    /// Worker threads (default: every core).
    #[arg(long)]
    jobs: Option<usize>,
    /// Run only slice i of N (points with index mod N = i − 1), e.g. one Slurm array task;
    /// join the slices with `servo study merge`.
    #[arg(long)]
    shard: Option<String>,
    /// Print the optima and counts as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Subcommand, Debug)]
enum StudySub {
    /// Join the shards of a study into the table a single run gives
    ///
    /// The shards are their folders, or one folder holding them all; the result is the table,
    /// summary and plots a single run gives, byte for byte.
    Merge(MergeCmd),
}

/// `servo study merge`.
#[derive(Args, Debug)]
struct MergeCmd {
    /// Study folders holding the shards' journals (`points-i-of-N.csv`).
    #[arg(required = true)]
    dirs: Vec<PathBuf>,
    /// Folder of the merged results.
    #[arg(long)]
    out_dir: PathBuf,
    /// Print the optima and counts as JSON.
    #[arg(long)]
    json: bool,
}

impl StudyCmd {
    /// Runs the study (or its shard) or merges shards.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        if let Some(StudySub::Merge(m)) = &self.merge {
            return m.exec();
        }
        let file = self.file.as_deref().unwrap_or(Path::new("study.toml"));
        let study = Study::from_file(file)?;
        let shard = match &self.shard {
            Some(s) => Shard::parse(s)
                .map_err(|range| run_config::Origin::default().invalid("--shard", s, &range))?,
            None => Shard::ALL,
        };
        let jobs = match self.jobs {
            Some(0) => {
                return Err(run_config::Origin::default()
                    .invalid("--jobs", 0, "1 or more threads")
                    .into())
            }
            Some(n) => n,
            None => every_core(),
        };
        let stop = crate::interrupt::stop_on_signals();
        let total = shard.points(study.points()).count();
        let bar = points_bar(total, &format!("study {}", study.table.name), "points");
        let run = execute::run_shard(
            &study,
            &self.out_dir,
            shard,
            jobs,
            &|| stop.is_set(),
            &mut |done, _| bar.set_position(done),
        );
        bar.finish_and_clear();
        let run = run?;
        let journal = self.out_dir.join(shard.file_name());
        if !run.complete() {
            eprintln!(
                "servo study: stopped after {} of {} points ({} this run); journal {} — run the same command to resume",
                run.points.len(),
                run.total,
                run.evaluated,
                journal.display()
            );
            return Ok(crate::interrupt::exit_code(&stop, false));
        }
        if shard != Shard::ALL {
            let note = format!(
                "shard {}/{} of study \"{}\" done: {} points ({} this run) in {}\n  join the shards: servo study merge FOLDER… --out-dir RESULTS",
                shard.index,
                shard.count,
                study.table.name,
                run.total,
                run.evaluated,
                journal.display()
            );
            if self.json {
                print_json(
                    &serde_json::json!({ "shard": [shard.index, shard.count], "points": run.total, "journal": journal }),
                );
            } else {
                println!("{note}");
            }
            return Ok(ExitCode::SUCCESS);
        }
        report_finished(&study, &run.points, &self.out_dir, jobs, self.json)
    }
}

/// The threads that use every core of this machine.
fn every_core() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

impl MergeCmd {
    fn exec(&self) -> Result<ExitCode, CliError> {
        let (study, points) = gather(&self.dirs)?;
        claim(&study, &self.out_dir)?;
        report_finished(&study, &points, &self.out_dir, every_core(), self.json)
    }
}

/// Sensitivities (on `jobs` threads), files and the printed summary of a finished study.
fn report_finished(
    study: &Study,
    points: &[Point],
    dir: &Path,
    jobs: usize,
    json: bool,
) -> Result<ExitCode, CliError> {
    let n = studies::design_space::sensitivity::loops(study);
    let bar = points_bar(n as usize, "sensitivities", "loops");
    let done = finish(study, points, dir, jobs, &mut |d, _| bar.set_position(d));
    bar.finish_and_clear();
    let (found, mut written) = done?;
    reports::design_space::plots(study, points, &found, dir, &mut written);
    if json {
        print_json(&serde_json::json!({
            "points": found.points, "failures": found.failures, "optima": found.optima,
            "sensitivities": found.sensitivities
        }));
        return Ok(ExitCode::SUCCESS);
    }
    println!(
        "Study \"{}\" (thesis §6.5): {} points, {} evaluated, {} failed",
        study.table.name,
        found.points,
        found.ok,
        found.points - found.ok
    );
    for f in &found.failures {
        println!(
            "  failed: {} point(s), first #{}: {}",
            f.points, f.first_index, f.reason
        );
    }
    for o in &found.optima {
        let at: Vec<String> = o
            .values
            .iter()
            .map(|(k, v)| format!("{} = {v:.4e}", axis_label(k)))
            .collect();
        println!(
            "  optimum ({}): following {:.3} nm, true {:.3} nm, bandwidth {:.0} Hz at {}",
            o.controller.name(),
            o.following_rms_m * 1e9,
            o.true_rms_m * 1e9,
            o.bandwidth_hz,
            at.join(", ")
        );
    }
    for s in &found.sensitivities {
        match &s.failed {
            None => println!(
                "  sensitivity ({}) d ln e / d ln {}: following {:+.3}, true {:+.3}",
                s.controller.name(),
                axis_label(&s.key),
                s.following,
                s.true_error
            ),
            Some(why) => println!("  sensitivity ({}) {}: {why}", s.controller.name(), s.key),
        }
    }
    print_written(&written);
    Ok(ExitCode::SUCCESS)
}
