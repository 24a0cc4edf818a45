//! A lockstep run loses nothing to a slow recorder. The truth and telemetry queues overwrite
//! their oldest block when full (a real-time loop must never wait for a recorder), and a
//! lockstep loop runs as fast as its two busy-polling processes can: on a loaded machine the
//! recorder, at low priority, can fall a queue behind and its recording would lack ticks. The
//! recorder therefore reports the ticks it has taken (`recorded` leaf, a [`Health`] with role
//! [`role::RECORDER`]), and a lockstep plant holds — sleeping, so that the recorder has the
//! CPU — while that report lags by more than half the truth queue.
//!
//! A hold never silences the plant for longer than [`PATIENCE`] at a time (the controller
//! declares a plant lost after 1 s of silence); a recorder that reports nothing new for that
//! long (gone, paused, or a build that does not report) is no longer waited for until it
//! reports progress again, and its own count of dropped frames says what it lost meanwhile.

use crate::contract::{role, Health, BLOCK_TICKS};
use crate::ipc::{leaf, settings, take, Endpoint, IpcError, Subscriber};
use std::time::{Duration, Instant};

/// The longest one hold lasts, and the silence after which the recorder is no longer waited
/// for: half the controller's 1 s plant timeout.
pub const PATIENCE: Duration = Duration::from_millis(500);

/// Sleep between looks at the recorder's report while holding.
const POLL: Duration = Duration::from_micros(200);

/// The plant's side: the recorder's last report and the holds so far.
pub struct RecorderPace {
    reports: Subscriber<Health>,
    /// Ticks the plant may run ahead of the recorder: half the truth queue.
    max_lag: u64,
    /// Ticks the recorder has taken (its latest report).
    recorded: u64,
    patience: Duration,
    /// The recorder reported nothing new for `patience`: not waited for until it reports
    /// more than it had then.
    silent: bool,
    /// Wall time spent holding, s.
    held_s: f64,
}

impl RecorderPace {
    /// Subscribes to run `ep`'s recorder reports; holds last at most `patience` each.
    pub fn new(ep: &Endpoint, patience: Duration) -> Result<Self, IpcError> {
        let queue = settings(leaf::TRUTH).buffer as u64 * BLOCK_TICKS as u64;
        Ok(RecorderPace {
            reports: ep.subscriber::<Health>(leaf::RECORDED)?,
            max_lag: queue / 2,
            recorded: 0,
            patience,
            silent: false,
            held_s: 0.0,
        })
    }

    /// Before tick `k`: holds while the recorder lags by more than half the queue, until it
    /// is within a quarter (or a hold has lasted `patience`; or the recorder has been silent
    /// that long, and is then no longer waited for). `holding` is called once when a hold
    /// begins (the plant announces it).
    pub fn hold(&mut self, k: u64, holding: impl FnOnce()) {
        self.update();
        if self.silent || k.saturating_sub(self.recorded) <= self.max_lag {
            return;
        }
        holding();
        let start = Instant::now();
        let mut moved = start;
        loop {
            std::thread::sleep(POLL);
            let before = self.recorded;
            self.update();
            if self.recorded > before {
                moved = Instant::now();
            }
            if k.saturating_sub(self.recorded) <= self.max_lag / 2 {
                break;
            }
            if moved.elapsed() >= self.patience {
                self.silent = true;
                break;
            }
            if start.elapsed() >= self.patience {
                break;
            }
        }
        self.held_s += start.elapsed().as_secs_f64();
    }

    /// Wall time spent holding for the recorder, s.
    pub fn held_s(&self) -> f64 {
        self.held_s
    }

    /// Whether the recorder is silent (reported nothing new for the patience) and not waited
    /// for.
    pub fn silent(&self) -> bool {
        self.silent
    }

    fn update(&mut self) {
        while let Some(h) = take(&self.reports) {
            if h.role == role::RECORDER && h.ticks > self.recorded {
                self.recorded = h.ticks;
                self.silent = false;
            }
        }
    }
}
