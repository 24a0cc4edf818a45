//! `servo view`: a live view of a running HIL run in Foxglove (a WebSocket server; see the
//! `live-view` crate).

use crate::output::CliError;
use clap::Args;
use live_view::{serve, ViewOptions};
use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// Live view of a HIL run in Foxglove: connect the app to the printed ws:// address.
///
/// Taps the run like the recorder (its own process, never the servo path) and publishes
/// /overview (min, max and mean of the main signals per millisecond of run: the recording's
/// own bins) and /health; the gain_scale parameter and the stop service act on the run's
/// control plane as `servo ctl gain` and `servo ctl stop` do (a gain is applied only if the
/// loop keeps its 6 dB margin). Serves localhost only unless --host says otherwise; ends
/// one second after the run.
/// Example: servo run --hil --prefix bench & servo view --prefix bench
#[derive(Args, Debug)]
pub struct ViewCmd {
    /// Run prefix.
    #[arg(long)]
    prefix: String,
    /// Address to listen on. Anything but a loopback address lets other machines steer the
    /// run's gain and stop it: choose it knowingly.
    #[arg(long, default_value = "127.0.0.1")]
    host: String,
    /// TCP port (0: any free port; the address is printed).
    #[arg(long, default_value_t = 8765)]
    port: u16,
    /// Publish every n-th millisecond bin of /overview, 1..=1000.
    #[arg(long, default_value_t = 1)]
    every: u32,
}

impl ViewCmd {
    /// Serves until the run ends or a signal.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        if !(1..=1000).contains(&self.every) {
            return Err(runner::config::Origin::default()
                .invalid("--every", self.every, "1..=1000 bins")
                .into());
        }
        let stop = Arc::new(AtomicBool::new(false));
        for signal in [SIGINT, SIGTERM, SIGHUP] {
            let _ = signal_hook::flag::register(signal, stop.clone());
        }
        let mut o = ViewOptions::new(&self.prefix, self.port);
        o.host = self.host.clone();
        o.every = self.every;
        let report = serve(&o, &stop, |port| {
            println!("ws://{}:{port}", self.host);
            eprintln!(
                "live view of run {:?}: open Foxglove, Open connection → Foxglove WebSocket → ws://{}:{port}",
                self.prefix, self.host
            );
        })
        .map_err(|e| CliError::Processes(e.to_string()))?;
        eprintln!(
            "run {:?} {}: {} ticks seen, {} overview samples published, {} records lost by the view, gain changes applied {:?}",
            self.prefix,
            if report.run_ended { "ended" } else { "left" },
            report.ticks,
            report.overview_samples,
            report.dropped,
            report.applied_gains
        );
        Ok(ExitCode::SUCCESS)
    }
}
