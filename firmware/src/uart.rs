//! Arm's CMSDK APB UART (UART0 of the MPS2 board at 0x4000_4000): polled, one byte at a time.
//! On another board this is the one file to replace (see README.md).

use core::ptr::{read_volatile, write_volatile};

const BASE: usize = 0x4000_4000;
const DATA: *mut u32 = BASE as *mut u32;
const STATE: *mut u32 = (BASE + 0x04) as *mut u32;
const CTRL: *mut u32 = (BASE + 0x08) as *mut u32;
const BAUDDIV: *mut u32 = (BASE + 0x10) as *mut u32;

const TX_FULL: u32 = 1;
const RX_FULL: u32 = 1 << 1;
const TX_ENABLE: u32 = 1;
const RX_ENABLE: u32 = 1 << 1;

/// The link's UART.
pub struct Uart(());

impl Uart {
    /// Enables transmitter and receiver (the divisor is the smallest the CMSDK UART accepts;
    /// QEMU moves bytes as fast as the host reads them).
    pub fn take() -> Self {
        // SAFETY: BAUDDIV and CTRL are the UART's registers on this board's memory map; the
        // firmware owns the UART (one `Uart`, made once at reset).
        unsafe {
            write_volatile(BAUDDIV, 16);
            write_volatile(CTRL, TX_ENABLE | RX_ENABLE);
        }
        Uart(())
    }

    /// Sends one byte, waiting while the transmit buffer is full.
    pub fn put(&mut self, byte: u8) {
        // SAFETY: STATE and DATA are the UART's registers; a write to DATA queues one byte.
        unsafe {
            while read_volatile(STATE) & TX_FULL != 0 {}
            write_volatile(DATA, u32::from(byte));
        }
    }

    /// The next received byte, waiting for it.
    pub fn get(&mut self) -> u8 {
        // SAFETY: STATE and DATA are the UART's registers; reading DATA takes the byte.
        unsafe {
            while read_volatile(STATE) & RX_FULL == 0 {}
            read_volatile(DATA) as u8
        }
    }
}
