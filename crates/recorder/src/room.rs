//! The producer's wait for room in a full ring ([`crate::WhenFull::Wait`]): it parks, and the
//! writer wakes it as soon as it has taken frames out — neither spinning on a core the writer
//! and its compressors need, nor sleeping past the moment room is made. A wake that is missed
//! (the writer took frames between the producer's last look and its parking) costs at most
//! [`LONGEST_NAP`].

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::thread::Thread;
use std::time::Duration;

/// The longest a waiting producer parks before it looks at the ring again.
pub(crate) const LONGEST_NAP: Duration = Duration::from_millis(1);

/// Shared by the producer and the writer of one recording.
#[derive(Debug, Default)]
pub(crate) struct Room {
    /// The producer is (about to be) parked.
    waiting: AtomicBool,
    /// The producer's thread, recorded when it waits.
    producer: Mutex<Option<Thread>>,
}

impl Room {
    /// Producer: parks until the writer makes room or [`LONGEST_NAP`] passes, unless
    /// `still_full()` says room was made meanwhile.
    pub(crate) fn wait(&self, still_full: impl Fn() -> bool) {
        *self.producer.lock().unwrap_or_else(|e| e.into_inner()) = Some(std::thread::current());
        self.waiting.store(true, Ordering::SeqCst);
        if still_full() {
            std::thread::park_timeout(LONGEST_NAP);
        }
        self.waiting.store(false, Ordering::SeqCst);
    }

    /// Writer: wakes a waiting producer (after it has taken frames out).
    pub(crate) fn made(&self) {
        if self.waiting.load(Ordering::SeqCst) {
            if let Some(t) = self
                .producer
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .as_ref()
            {
                t.unpark();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    /// A producer waiting on a full ring is woken by the writer's `made` long before its
    /// longest nap ends; the wait is counted, not timed: the writer wakes it once and the
    /// waiter sees the room that was made (no wall-clock assertion).
    #[test]
    fn the_writer_wakes_a_waiting_producer() {
        let room = Arc::new(Room::default());
        let full = Arc::new(AtomicBool::new(true));
        let (r, f) = (room.clone(), full.clone());
        let writer = std::thread::spawn(move || {
            while !r.waiting.load(Ordering::SeqCst) {
                std::thread::yield_now();
            }
            f.store(false, Ordering::SeqCst);
            r.made();
        });
        while full.load(Ordering::SeqCst) {
            room.wait(|| full.load(Ordering::SeqCst));
        }
        writer.join().unwrap();
        assert!(!room.waiting.load(Ordering::SeqCst));
    }

    /// Room made before the producer parks: it does not park at all.
    #[test]
    fn room_made_before_parking_is_seen() {
        let room = Room::default();
        room.wait(|| false);
        assert!(!room.waiting.load(Ordering::SeqCst));
    }
}
