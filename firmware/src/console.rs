//! The link to the host under QEMU: Arm semihosting on the emulator's own standard input and
//! output (`:tt`, QEMU run without a character device on them). `SYS_READ` returns what the
//! host has sent, up to a block, and a reply leaves in one `SYS_WRITE`: a frame crosses per call,
//! where QEMU's UART moves a byte per turn of its event loop (about 80 µs of wall time a tick
//! against 3 ms). On a board this is the one file to replace (a UART or USB driver with the same
//! three calls; README.md).

/// Semihosting operation numbers (Arm, "Semihosting for AArch32 and AArch64", 2.0).
const SYS_OPEN: u32 = 0x01;
const SYS_WRITE: u32 = 0x05;
const SYS_READ: u32 = 0x06;
/// `SYS_OPEN` modes "r" and "w" (on `:tt`, the emulator's standard input and output).
const MODE_READ: u32 = 0;
const MODE_WRITE: u32 = 4;
/// The console's name, NUL-terminated.
const TT: &[u8; 4] = b":tt\0";

/// Bytes gathered before they are written: the largest reply frame (a refusal's text) fits.
const OUT_BYTES: usize = 512;
/// Bytes taken from the host in one read.
const IN_BYTES: usize = 512;

/// The console: bytes out are gathered until [`Console::flush`], bytes in are read in blocks.
pub struct Console {
    read: u32,
    write: u32,
    out: [u8; OUT_BYTES],
    out_len: usize,
    inbox: [u8; IN_BYTES],
    have: usize,
    at: usize,
}

/// One semihosting call with its parameter block.
fn call(op: u32, block: &[u32]) -> u32 {
    // SAFETY: `block` is the parameter block `op` reads (its pointers, where it has any, point
    // at live buffers of the stated lengths); the call is a BKPT 0xAB the emulator serves.
    unsafe { cortex_m::asm::semihosting_syscall(op, block.as_ptr() as u32) }
}

impl Console {
    /// Opens the console's input and output.
    pub fn open() -> Self {
        let open = |mode: u32| call(SYS_OPEN, &[TT.as_ptr() as u32, mode, 3]);
        Console {
            read: open(MODE_READ),
            write: open(MODE_WRITE),
            out: [0; OUT_BYTES],
            out_len: 0,
            inbox: [0; IN_BYTES],
            have: 0,
            at: 0,
        }
    }

    /// Queues one byte (written by [`Console::flush`], or now when the queue is full).
    pub fn put(&mut self, byte: u8) {
        if self.out_len == OUT_BYTES {
            self.flush();
        }
        self.out[self.out_len] = byte;
        self.out_len += 1;
    }

    /// Writes what is queued (again where the emulator's output was momentarily full).
    pub fn flush(&mut self) {
        let mut from = 0;
        while from < self.out_len {
            let left = self.out_len - from;
            let block = [self.write, self.out[from..].as_ptr() as u32, left as u32];
            // The call returns how many bytes it did not write.
            let unwritten = call(SYS_WRITE, &block) as usize;
            from += left - unwritten.min(left);
        }
        self.out_len = 0;
    }

    /// The next byte from the host, waiting for it (the emulator's read of its standard input
    /// returns what the host has sent, up to [`IN_BYTES`]).
    pub fn get(&mut self) -> u8 {
        while self.at == self.have {
            let block = [self.read, self.inbox.as_mut_ptr() as u32, IN_BYTES as u32];
            // The call returns how many bytes it did not read.
            let unread = call(SYS_READ, &block) as usize;
            self.have = IN_BYTES - unread.min(IN_BYTES);
            self.at = 0;
        }
        let byte = self.inbox[self.at];
        self.at += 1;
        byte
    }
}
