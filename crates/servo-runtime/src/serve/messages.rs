//! The messages between a served loop's ticking thread and its service thread, over
//! lock-free single-producer rings (fixed size, moved by value; a controller crosses boxed).

use crate::host::Timing;
use servo_config::Controller;
use servo_config::Stability;

/// Service thread → ticking thread.
pub(crate) enum Request {
    Gain {
        id: u64,
        scale: f64,
    },
    Load {
        id: u64,
        controller: Box<Controller>,
        stability: Stability,
        radius: f64,
    },
    Stop {
        cause: u32,
    },
}

/// How a served run ended (the final health report).
pub(crate) struct End {
    pub(crate) ticks: u64,
    pub(crate) overruns: u64,
    pub(crate) timing: Timing,
    pub(crate) faults: u32,
    pub(crate) stop_cause: u32,
}

/// Ticking thread → service thread.
pub(crate) enum Event {
    Started {
        run_id: u64,
    },
    Gain {
        id: u64,
        tick: u64,
        scale: f64,
    },
    Loaded {
        id: u64,
        tick: u64,
        radius: f64,
        replaced: Option<Box<Controller>>,
    },
    Health {
        ticks: u64,
        overruns: u64,
        timing: Timing,
    },
    End(End),
}
