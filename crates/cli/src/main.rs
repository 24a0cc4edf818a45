//! `servo`: run the fast tool servo closed loop against the simulated stage (or a plant
//! process), record it, read it back, and run the thesis's studies. A thin shell over the
//! `runner` (runtime) and `studies` (offline analyses) libraries: parsing, progress, printing.

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::process::ExitCode;

mod args;
mod choice;
mod commands;
mod interrupt;
mod output;
#[cfg(test)]
mod reference_page;

use commands::*;

#[derive(Parser)]
#[command(
    name = "servo",
    version,
    about = "Fast tool servo runtime and simulator (thesis prototype by default)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    Run(run::Run),
    Machine(machine::MachineCmd),
    Toolpath(toolpath::ToolpathCmd),
    Measure(measure::MeasureCmd),
    Register(register::RegisterCmd),
    Compensate(compensate::CompensateCmd),
    Inspect(inspect::InspectCmd),
    Replay(replay::ReplayCmd),
    Export(export::ExportCmd),
    Config(config::ConfigCmd),
    Budget(budget::BudgetCmd),
    Spectrum(spectrum::SpectrumCmd),
    Frf(frf::FrfCmd),
    Identify(identify::IdentifyCmd),
    Fit(fit::FitCmd),
    Tune(tune::TuneCmd),
    Synth(synth::SynthCmd),
    Deploy(deploy::DeployCmd),
    Fmu(fmu::FmuCmd),
    Study(study::StudyCmd),
    Stiffness(stiffness::StiffnessCmd),
    IntermittentCut(intermittent::IntermittentCmd),
    SpindleErrors(spindle_errors::SpindleErrorsCmd),
    Thesis(thesis::ThesisCmd),
    Plant(hil::PlantCmd),
    Controller(hil::ControllerCmd),
    Record(hil::RecordCmd),
    Ctl(ctl::CtlCmd),
    View(view::ViewCmd),
    Latency(latency::LatencyCmd),
    Completions(completions::CompletionsCmd),
}

impl Command {
    fn exec(&self) -> Result<ExitCode, output::CliError> {
        match self {
            Command::Run(c) => c.exec(),
            Command::Machine(c) => c.exec(),
            Command::Toolpath(c) => c.exec(),
            Command::Measure(c) => c.exec(),
            Command::Register(c) => c.exec(),
            Command::Compensate(c) => c.exec(),
            Command::Inspect(c) => c.exec(),
            Command::Replay(c) => c.exec(),
            Command::Export(c) => c.exec(),
            Command::Config(c) => c.exec(),
            Command::Budget(c) => c.exec(),
            Command::Spectrum(c) => c.exec(),
            Command::Frf(c) => c.exec(),
            Command::Identify(c) => c.exec(),
            Command::Fit(c) => c.exec(),
            Command::Tune(c) => c.exec(),
            Command::Synth(c) => c.exec(),
            Command::Deploy(c) => c.exec(),
            Command::Fmu(c) => c.exec(),
            Command::Study(c) => c.exec(),
            Command::Stiffness(c) => c.exec(),
            Command::IntermittentCut(c) => c.exec(),
            Command::SpindleErrors(c) => c.exec(),
            Command::Thesis(c) => c.exec(),
            Command::Plant(c) => c.exec(),
            Command::Controller(c) => c.exec(),
            Command::Record(c) => c.exec(),
            Command::Ctl(c) => c.exec(),
            Command::View(c) => c.exec(),
            Command::Latency(c) => c.exec(),
            Command::Completions(c) => c.exec::<Cli>(),
        }
    }
}

fn main() -> ExitCode {
    // `servo … | head` must end quietly, not panic on a closed pipe.
    sigpipe::reset();
    interrupt::write_limits_as_errors();
    interrupt::follow_parent();
    // The exit codes close `servo --help` (computed: they come from the code that sets them).
    let matches = Cli::command()
        .after_help(output::exit_codes_help())
        .get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    cli.command.exec().unwrap_or_else(|e| output::fail_cli(&e))
}

#[cfg(test)]
mod tests {
    use super::Cli;
    use clap::CommandFactory;

    /// clap's own consistency checks over every command and flag (duplicate flags, conflicts
    /// naming flags that do not exist, bad defaults).
    #[test]
    fn command_line_is_consistent() {
        Cli::command().debug_assert();
    }

    /// `servo --help` lists each command on one short line; the long text is in the
    /// command's own help.
    #[test]
    fn every_command_has_a_one_line_summary() {
        fn check(c: &clap::Command, path: &str, long: &mut Vec<String>) {
            for sub in c.get_subcommands() {
                let about = sub.get_about().map(|a| a.to_string()).unwrap_or_default();
                let path = format!("{path} {}", sub.get_name());
                let n = about.chars().count();
                if about.is_empty() || about.contains('\n') || n > 90 {
                    long.push(format!("{path}: {about:?} ({n} characters)"));
                }
                check(sub, &path, long);
            }
        }
        let mut long = Vec::new();
        check(&Cli::command(), "servo", &mut long);
        assert!(long.is_empty(), "{}", long.join("\n"));
    }

    /// The book's generated reference pages are what the code says: the command line from
    /// the parser, the configuration from its types and checks
    /// (`UPDATE_REFERENCE=1 cargo test -p servo-cli reference_page` rewrites them).
    #[test]
    fn reference_page_is_current() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/src/reference");
        let pages = [
            ("cli.md", super::reference_page::page(&Cli::command())),
            (
                "configuration.md",
                super::reference_page::configuration_page(&runner::schema::schema()),
            ),
            ("exit-codes.md", super::reference_page::exit_codes_page()),
        ];
        for (name, page) in pages {
            let path = dir.join(name);
            if std::env::var_os("UPDATE_REFERENCE").is_some() {
                std::fs::write(&path, &page).unwrap();
            }
            let committed = std::fs::read_to_string(&path).unwrap_or_default();
            assert!(
                committed == page,
                "{} is stale: UPDATE_REFERENCE=1 cargo test -p servo-cli reference_page",
                path.display()
            );
        }
    }

    /// The completion scripts name every command and each command's flags.
    #[test]
    fn completions_cover_every_command_and_flag() {
        let cli = Cli::command();
        for shell in [clap_complete::Shell::Bash, clap_complete::Shell::Zsh] {
            let mut script = Vec::new();
            clap_complete::generate(shell, &mut Cli::command(), "servo", &mut script);
            let script = String::from_utf8(script).unwrap();
            for sub in cli.get_subcommands() {
                assert!(
                    script.contains(sub.get_name()),
                    "{shell}: {}",
                    sub.get_name()
                );
                for flag in sub.get_arguments().filter_map(|a| a.get_long()) {
                    assert!(script.contains(&format!("--{flag}")), "{shell}: --{flag}");
                }
            }
        }
    }
}
