//! The run's clock: CMSDK APB timer 1 of the MPS2 board (Arm AN500), free-running down from
//! 2³² − 1 at the peripheral clock (25 MHz, the processor's), read often enough that its 32
//! bits never wrap between two readings (a frame at least every 171 s), summed into 64 bits.

use core::ptr::{read_volatile, write_volatile};

/// CMSDK APB timer 1's registers (AN500's memory map).
const TIMER1: usize = 0x4000_1000;
const CTRL: usize = TIMER1;
const VALUE: usize = TIMER1 + 0x4;
const RELOAD: usize = TIMER1 + 0x8;

/// Counts since [`RunClock::restart`].
pub struct RunClock {
    last: u32,
    total: u64,
}

fn value() -> u32 {
    // SAFETY: VALUE is the timer's counter register: a 32-bit read with no side effect.
    unsafe { read_volatile(VALUE as *const u32) }
}

impl RunClock {
    /// Starts timer 1 free-running (no interrupt) and the count from now.
    pub fn start() -> Self {
        // SAFETY: the timer's RELOAD, VALUE and CTRL registers; this firmware uses timer 1 for
        // nothing else. Reload first, then the count, then enable (bit 0; no interrupt).
        unsafe {
            write_volatile(RELOAD as *mut u32, u32::MAX);
            write_volatile(VALUE as *mut u32, u32::MAX);
            write_volatile(CTRL as *mut u32, 1);
        }
        RunClock {
            last: value(),
            total: 0,
        }
    }

    /// Counts from now on.
    pub fn restart(&mut self) {
        self.last = value();
        self.total = 0;
    }

    /// Adds the counts since the last reading and returns the total since the restart.
    pub fn read(&mut self) -> u64 {
        let now = value();
        // A down-counter: the counts elapsed are last − now, modulo 2³².
        self.total += u64::from(self.last.wrapping_sub(now));
        self.last = now;
        self.total
    }
}
