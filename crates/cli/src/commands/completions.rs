//! `servo completions`: the shell completion script of every command and flag (clap_complete).

use crate::output::CliError;
use clap::Args;
use std::process::ExitCode;

/// Print the completion script for a shell.
///
/// Example (bash): servo completions bash > ~/.local/share/bash-completion/completions/servo
/// zsh: servo completions zsh > "${fpath[1]}/_servo"; fish: servo completions fish >
/// ~/.config/fish/completions/servo.fish
#[derive(Args, Debug)]
pub struct CompletionsCmd {
    /// The shell.
    #[arg(value_enum)]
    shell: clap_complete::Shell,
}

impl CompletionsCmd {
    /// Writes the script for the command line `C` to stdout.
    pub fn exec<C: clap::CommandFactory>(&self) -> Result<ExitCode, CliError> {
        let mut command = C::command();
        clap_complete::generate(self.shell, &mut command, "servo", &mut std::io::stdout());
        Ok(ExitCode::SUCCESS)
    }
}
