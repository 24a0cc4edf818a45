//! `servo inspect`: a recording read back in one streaming pass (constant memory): its
//! summary recomputed, how the run ended, whether the file is complete, and the form report
//! of a machining run (from the surface embedded in the file).

use super::machine::print_form;
use crate::output::{print_json, print_summary, CliError};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::form::FormSink;

/// Check a recording byte by byte and print its summary
///
/// Recomputes the summary of a recording, finished or not. Example: servo inspect run.mcap
///
/// Every byte is checked (CRCs, indexes, summary, message sizes). Exit 0 for a complete,
/// intact file; 1 for a damaged or unfinished one (what is intact is still printed, and where
/// the damage is), unless --salvage.
#[derive(Args, Debug)]
pub struct InspectCmd {
    /// The MCAP file written by `servo run` (or its `.partial` file).
    file: PathBuf,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
    /// Read a damaged or unfinished recording (a killed run's `.partial`) as far as it is
    /// intact, say what was skipped, and exit 0 (without it such a file exits 1).
    #[arg(long)]
    salvage: bool,
}

impl InspectCmd {
    /// Reads, recomputes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let mut form = FormSink::default();
        let i = runner::recording::inspect_with(&self.file, &mut form)?;
        let report = form.analysis.map(|a| a.report());
        let code = match i.damage() {
            Some(damage) if !self.salvage => {
                eprintln!(
                    "error: {}: {damage}; not trusted as a whole run (--salvage reads what is intact)",
                    self.file.display(),
                );
                ExitCode::FAILURE
            }
            _ => ExitCode::SUCCESS,
        };
        if self.json {
            print_json(&serde_json::json!({
                "summary": i.summary,
                "end": i.end,
                "file": i.read.to_string(),
                "form": report,
            }));
            return Ok(code);
        }
        print_summary(&i.summary, false);
        println!("  file                      {}", i.read);
        if let Some(f) = &report {
            print_form(f);
        }
        Ok(code)
    }
}
