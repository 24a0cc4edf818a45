//! Why a run ended, and the flag that asks it to end: set from a signal handler (which signal)
//! or by the control plane, polled by the loop at tick boundaries.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// A request to end the run, shared between whoever asks (a signal handler, a control-plane
/// thread) and the loop. 0 = keep running; a signal number; or [`StopRequest::CONTROL`].
#[derive(Debug, Default, Clone)]
pub struct StopRequest(Arc<AtomicUsize>);

impl StopRequest {
    /// The value a control-plane STOP (or a library caller) stores.
    pub const CONTROL: usize = daq_io::stop_cause::CONTROL as usize;

    /// Not stopped.
    pub fn new() -> Self {
        Self::default()
    }

    /// The raw cell: nonzero means stop.
    pub fn cell(&self) -> &AtomicUsize {
        &self.0
    }

    /// The shared cell, for a signal handler to store the signal number into
    /// (`signal_hook::flag::register_usize`).
    pub fn shared(&self) -> Arc<AtomicUsize> {
        self.0.clone()
    }

    /// Asks the run to stop (control plane, library caller).
    pub fn request(&self) {
        let _ = self
            .0
            .compare_exchange(0, Self::CONTROL, Ordering::Relaxed, Ordering::Relaxed);
    }

    /// Whether a stop was asked for.
    #[inline]
    pub fn is_set(&self) -> bool {
        self.0.load(Ordering::Relaxed) != 0
    }

    /// How the run ends if it ends now because of this request.
    pub fn reason(&self) -> EndReason {
        EndReason::of_cause(self.0.load(Ordering::Relaxed) as u32)
    }
}

/// How a run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EndReason {
    /// It ran its whole duration.
    Completed,
    /// A control-plane STOP (`servo ctl stop`) or a library caller ended it.
    Stopped,
    /// A signal ended it (its number: 1 SIGHUP, 2 SIGINT, 15 SIGTERM).
    Signal(i32),
    /// The plant or the controller was lost (HIL).
    PeerLost,
    /// The controller answered late more often than the overrun budget allows (HIL, real
    /// time): the plant drove zero current and ended the run.
    OverrunBudget,
    /// The recording could not be written (disk full, I/O error): the run was ended safely.
    WriteFailed,
    /// Machine protection tripped the loop; it held the safe state, then the run ended.
    Tripped,
}

impl EndReason {
    /// The end a [`daq_io::stop_cause`] describes (0: completed).
    pub fn of_cause(cause: u32) -> EndReason {
        match cause {
            daq_io::stop_cause::NONE => EndReason::Completed,
            1..=127 => EndReason::Signal(cause as i32),
            daq_io::stop_cause::WRITE_FAILED => EndReason::WriteFailed,
            daq_io::stop_cause::TRIPPED => EndReason::Tripped,
            _ => EndReason::Stopped,
        }
    }

    /// The reason of a run whose loop `tripped`: a trip outranks completing the duration or
    /// a later stop request (the run did not do what it was asked).
    pub fn after_trip(self, tripped: bool) -> EndReason {
        match self {
            EndReason::Completed | EndReason::Stopped if tripped => EndReason::Tripped,
            reason => reason,
        }
    }

    /// The name written into the recording and the summary.
    pub fn name(self) -> &'static str {
        match self {
            EndReason::Completed => "completed",
            EndReason::Stopped => "stopped",
            EndReason::Signal(_) => "interrupted",
            EndReason::PeerLost => "peer-lost",
            EndReason::OverrunBudget => "overrun-budget",
            EndReason::WriteFailed => "write-failed",
            EndReason::Tripped => "tripped",
        }
    }

    /// The signal's name, for [`EndReason::Signal`].
    pub fn signal_name(self) -> Option<&'static str> {
        match self {
            EndReason::Signal(1) => Some("SIGHUP"),
            EndReason::Signal(2) => Some("SIGINT"),
            EndReason::Signal(15) => Some("SIGTERM"),
            EndReason::Signal(_) => Some("signal"),
            _ => None,
        }
    }

    /// One of each way a run ends (SIGINT stands for every signal).
    pub const EACH: [EndReason; 7] = [
        EndReason::Completed,
        EndReason::Stopped,
        EndReason::Signal(2),
        EndReason::PeerLost,
        EndReason::OverrunBudget,
        EndReason::WriteFailed,
        EndReason::Tripped,
    ];

    /// What it means for the run and its recording, in a sentence.
    pub fn meaning(self) -> &'static str {
        match self {
            EndReason::Completed => "the run ran its whole duration",
            EndReason::Stopped => {
                "`servo ctl stop` (or a library caller) ended the run at a tick boundary; the \
                 recording is finished"
            }
            EndReason::Signal(_) => {
                "a signal interrupted the run, in process or sent to any HIL process: 128 + its \
                 number (130 SIGINT, 143 SIGTERM, 129 SIGHUP); the run ends at a tick boundary \
                 and the recording is finished (a second Ctrl-C ends the process at once)"
            }
            EndReason::PeerLost => {
                "a HIL peer was lost: the controller silent for the peer timeout (the plant \
                 drove zero current and ended the run), or the plant gone mid-run (killed or \
                 crashed: the recording ends at its last tick)"
            }
            EndReason::OverrunBudget => {
                "the controller answered late more often than the overrun budget allows: the \
                 plant drove zero current and ended the run"
            }
            EndReason::WriteFailed => {
                "the recording could not be written (a full disk, a file size limit, a \
                 quota): the run was ended safely and the recording finished with the part \
                 that fit, shorter; when even that cannot be written, the `.partial` file holds \
                 every complete chunk"
            }
            EndReason::Tripped => {
                "machine protection tripped the loop: it held the safe state, then the run ended"
            }
        }
    }

    /// The process exit code that says it: 0 completed or stopped on request, 128 + the
    /// signal number when interrupted (130 SIGINT, 143 SIGTERM, 129 SIGHUP, as shells do),
    /// 3 a lost peer or an exceeded overrun budget (the plant faulted the run), 4 a failed recording, 5 a machine-protection trip.
    pub fn exit_code(self) -> u8 {
        match self {
            EndReason::Completed | EndReason::Stopped => 0,
            EndReason::Signal(s) => (128 + s.clamp(0, 127)) as u8,
            EndReason::PeerLost | EndReason::OverrunBudget => 3,
            EndReason::WriteFailed => 4,
            EndReason::Tripped => 5,
        }
    }

    /// The `end` metadata record of a run that ended this way after `ticks` ticks
    /// (`simulated_s` seconds).
    pub fn record(self, ticks: u64, simulated_s: f64) -> BTreeMap<String, String> {
        let mut m = BTreeMap::from([
            ("reason".to_string(), self.name().to_string()),
            ("ticks".to_string(), ticks.to_string()),
            ("simulated_s".to_string(), simulated_s.to_string()),
        ]);
        if let Some(s) = self.signal_name() {
            m.insert("signal".into(), s.into());
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_signal_number_becomes_its_reason_and_exit_code() {
        let stop = StopRequest::new();
        assert_eq!(stop.reason(), EndReason::Completed);
        stop.cell().store(15, Ordering::Relaxed);
        assert!(stop.is_set());
        assert_eq!(stop.reason(), EndReason::Signal(15));
        assert_eq!(stop.reason().exit_code(), 143);
        assert_eq!(stop.reason().signal_name(), Some("SIGTERM"));
        // A later request does not overwrite the first reason.
        stop.request();
        assert_eq!(stop.reason(), EndReason::Signal(15));
        let control = StopRequest::new();
        control.request();
        assert_eq!(control.reason(), EndReason::Stopped);
        assert_eq!(control.reason().exit_code(), 0);
    }
}
