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
/// loop keeps its 6 dB margin). Speaks the Foxglove WebSocket protocol
/// (foxglove.websocket.v1, also under the SDK's name foxglove.sdk.v1). On loopback (the
/// default) only the Unix user running the view gets in — other users' connections are closed
/// before they see anything; with --host beyond loopback every client also needs the token in
/// the printed URL (cleartext: use an SSH tunnel over untrusted networks). Ends one second
/// after the run.
/// Example: servo run --hil --prefix bench & servo view --prefix bench
#[derive(Args, Debug)]
pub struct ViewCmd {
    /// Run prefix.
    #[arg(long)]
    prefix: String,
    /// Address to listen on. Anything but a loopback address lets other machines that have
    /// the printed token steer the run's gain and stop it: choose it knowingly.
    #[arg(long, default_value = "127.0.0.1")]
    host: String,
    /// Watch only: no parameters and no stop service.
    #[arg(long)]
    read_only: bool,
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
            return Err(run_config::Origin::default()
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
        o.read_only = self.read_only;
        let loopback = self
            .host
            .parse::<std::net::IpAddr>()
            .is_ok_and(live_view::ws::peer::is_loopback)
            || self.host == "localhost";
        if !loopback {
            o.token = Some(
                live_view::ws::new_token()
                    .map_err(|e| CliError::Processes(format!("no token: {e}")))?,
            );
        }
        let query = o
            .token
            .as_ref()
            .map_or(String::new(), |t| format!("/?token={t}"));
        let report = serve(&o, &stop, |port| {
            let url = format!("ws://{}:{port}{query}", self.host);
            println!("{url}");
            eprintln!(
                "live view of run {:?}{}: open Foxglove, Open connection → Foxglove WebSocket → {url}{}",
                self.prefix,
                if self.read_only { " (read-only)" } else { "" },
                if loopback {
                    " (only your Unix user can connect)"
                } else {
                    " (cleartext; anyone with this URL can steer the run)"
                }
            );
        })
        .map_err(|e| CliError::Processes(e.to_string()))?;
        eprintln!(
            "run {:?} {}: {} ticks seen, {} overview samples published, {} records lost by the view, gain changes applied {:?}, {} connections refused",
            self.prefix,
            if report.run_ended { "ended" } else { "left" },
            report.ticks,
            report.overview_samples,
            report.dropped,
            report.applied_gains,
            report.refused
        );
        if let Some(first) = &report.bad_blocks.first {
            eprintln!(
                "{} blocks refused and skipped (another run's, or impossible counts or ticks: a foreign or faulty publisher); the first: {first}",
                report.bad_blocks.count
            );
        }
        Ok(ExitCode::SUCCESS)
    }
}
