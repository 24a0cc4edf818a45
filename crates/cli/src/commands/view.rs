//! `servo view`: a live view of a running HIL run in Foxglove (a WebSocket server; see the
//! `live-view` crate).

use crate::output::CliError;
use clap::Args;
use live_view::ws::tls::Tls;
use live_view::{serve, ViewOptions};
use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// Live view of a HIL run in Foxglove: connect the app to the printed ws:// (wss://) address.
///
/// Taps the run like the recorder (its own process, never the servo path) and publishes
/// /overview (min, max and mean of the main signals per millisecond of run: the recording's
/// own bins) and /health; the gain_scale parameter and the stop service act on the run's
/// control plane as `servo ctl gain` and `servo ctl stop` do (a gain is applied only if the
/// loop keeps its 6 dB margin). Speaks the Foxglove WebSocket protocol
/// (foxglove.websocket.v1, also under the SDK's name foxglove.sdk.v1). On loopback (the
/// default) only the Unix user running the view gets in — other users' connections are closed
/// before they see anything; with --host beyond loopback every client also needs the token in
/// the printed URL, and the view speaks TLS (wss://): with --tls-cert/--tls-key, or a
/// self-signed certificate made on first use in $XDG_CONFIG_HOME/fts-servo/live-view (else
/// ~/.config/…), whose SHA-256 fingerprint is printed on the line after the URL for clients to
/// pin. Ends one second after the run.
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
    /// TLS certificate chain (PEM, the server's certificate first), with --tls-key: serve
    /// wss:// with it (on any address).
    #[arg(long, requires = "tls_key")]
    tls_cert: Option<PathBuf>,
    /// Private key of --tls-cert (PEM; mode 600, the user's own).
    #[arg(long, requires = "tls_cert")]
    tls_key: Option<PathBuf>,
    /// Beyond loopback, serve ws:// without TLS: the token and the run's data cross the
    /// network in cleartext (only where every machine on the path is trusted, or through a
    /// tunnel).
    #[arg(long, conflicts_with = "tls_cert")]
    cleartext: bool,
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
        o.cleartext = self.cleartext;
        let self_signed = self.tls(loopback, &mut o)?;
        let query = o
            .token
            .as_ref()
            .map_or(String::new(), |t| format!("/?token={t}"));
        let scheme = if o.tls.is_some() { "wss" } else { "ws" };
        let report = serve(&o, &stop, |port| {
            let url = format!("{scheme}://{}:{port}{query}", self.host);
            println!("{url}");
            if let Some(tls) = &o.tls {
                println!("sha256 {}", tls.fingerprint());
            }
            eprintln!(
                "live view of run {:?}{}: open Foxglove, Open connection → Foxglove WebSocket → {url}{}",
                self.prefix,
                if self.read_only { " (read-only)" } else { "" },
                match (loopback, &o.tls) {
                    (true, None) => " (only your Unix user can connect)".to_owned(),
                    (_, Some(_)) => format!(
                        " (TLS: clients pin the certificate by the SHA-256 fingerprint printed after the URL; anyone with the URL can steer the run){}",
                        self_signed.as_ref().map_or(String::new(), |dir| format!(
                            "; the certificate is the self-signed one in {}: a browser trusts it once you open https://…:{port}/ in it and accept it",
                            dir.display()
                        ))
                    ),
                    (false, None) => {
                        " (cleartext, as asked; anyone with this URL can steer the run)".to_owned()
                    }
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

    /// The TLS identity to serve with: the files given; beyond loopback without
    /// --cleartext, the self-signed one of this user (made on first use; its directory
    /// returned); none otherwise.
    fn tls(&self, loopback: bool, o: &mut ViewOptions) -> Result<Option<PathBuf>, CliError> {
        let refused = |e: live_view::ws::tls::TlsError| CliError::Processes(format!("TLS: {e}"));
        if let (Some(cert), Some(key)) = (&self.tls_cert, &self.tls_key) {
            o.tls = Some(Tls::from_pem_files(cert, key).map_err(refused)?);
            return Ok(None);
        }
        if loopback || self.cleartext {
            return Ok(None);
        }
        let dir = tls_dir().ok_or_else(|| {
            CliError::Processes(
                "TLS: neither XDG_CONFIG_HOME nor HOME is set, so there is no place for the \
                 self-signed certificate: give --tls-cert and --tls-key"
                    .into(),
            )
        })?;
        let mut names = vec!["localhost".to_owned()];
        if let Ok(host) = std::fs::read_to_string("/proc/sys/kernel/hostname") {
            names.push(host.trim().to_owned());
        }
        if self
            .host
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| !ip.is_unspecified())
        {
            names.push(self.host.clone());
        }
        let (tls, made) = Tls::self_signed(&dir, &names).map_err(refused)?;
        if made {
            eprintln!(
                "made a self-signed TLS certificate for the live view in {} (kept for the next views)",
                dir.display()
            );
        }
        o.tls = Some(tls);
        Ok(Some(dir))
    }
}

/// Where the self-signed certificate of this user's live views is kept:
/// `$XDG_CONFIG_HOME/fts-servo/live-view`, else `$HOME/.config/fts-servo/live-view`.
fn tls_dir() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CONFIG_HOME")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".config")))?;
    Some(base.join("fts-servo").join("live-view"))
}
