//! The stack's high-water mark: painted with a pattern at reset, scanned for the deepest word
//! overwritten since.

use core::ptr::{addr_of, read_volatile, write_volatile};

const PAINT: u32 = 0xCCCC_CCCC;
/// Bytes below the current stack pointer left unpainted (the painting function's own frame).
const MARGIN: usize = 256;

extern "C" {
    // cortex-m-rt's linker script: the top of the stack and its lowest address.
    static _stack_start: u32;
    static _stack_end: u32;
}

fn bounds() -> (usize, usize) {
    (
        addr_of!(_stack_end) as usize,
        addr_of!(_stack_start) as usize,
    )
}

/// Bytes reserved for the stack.
pub fn size() -> u32 {
    let (low, high) = bounds();
    (high - low) as u32
}

/// Paints the unused stack below the caller.
pub fn paint() {
    let (low, _) = bounds();
    let sp = cortex_m::register::msp::read() as usize - MARGIN;
    let mut at = low;
    while at < sp {
        // SAFETY: `low..sp` is stack below the live frames: no one holds a reference there.
        unsafe { write_volatile(at as *mut u32, PAINT) };
        at += 4;
    }
}

/// The deepest stack use since [`paint`], in bytes from the top.
pub fn used() -> u32 {
    let (low, high) = bounds();
    let mut at = low;
    // SAFETY: reads of the stack region's words, each aligned and inside the region.
    while at < high && unsafe { read_volatile(at as *const u32) } == PAINT {
        at += 4;
    }
    (high - at) as u32
}
