//! Ctrl-C / SIGTERM as a stop flag the loop polls, so a run ends at a tick boundary with its
//! recording finished.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// A stop flag raised by Ctrl-C / SIGTERM (a second one is ignored: the file is being
/// finished).
pub fn stop_flag() -> Arc<AtomicBool> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
    stop
}
