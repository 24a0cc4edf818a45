//! # servo-link
//!
//! The serial link between a host and a [`servo_runtime::Servo`] on a microcontroller: framed messages
//! (sync byte, kind, length, payload, CRC-32) and the byte layouts of what they carry — the
//! [`servo_config::Deployment`] sent once at start ([`image`]), one [`daq_io::Sensor`] per tick in and
//! one [`TickReply`] per tick out. `no_std`, no allocation: the firmware (`firmware/`) and the
//! host's processor-in-the-loop driver (`servo run --pil`) share this crate, so both ends
//! agree on every byte. All numbers little-endian.
#![cfg_attr(not(test), no_std)]

pub mod image;
mod payload;

pub use payload::{
    decode_sensor, encode_sensor, Boot, BootError, Ready, Report, TickReply, BOOT_BYTES,
    LINK_VERSION, READY_BYTES, REPORT_BYTES, SENSOR_BYTES, TICK_BYTES,
};

/// First byte of every frame.
pub const SYNC: u8 = 0xA5;

/// Largest payload a frame carries in bytes (a deployment image with the largest state-space
/// controller fits).
pub const MAX_PAYLOAD: usize = 16_384;

const _: () = assert!(
    image::MAX_BYTES <= MAX_PAYLOAD,
    "the largest image fits one frame"
);

/// Frame kinds.
pub mod kind {
    /// Target → host at reset: what the firmware is ([`super::Boot`]).
    pub const BOOT: u8 = 1;
    /// Host → target: a deployment image ([`super::image`]) to build the loop from.
    pub const LOAD: u8 = 2;
    /// Target → host: the loop is built ([`super::Ready`]: the probe's cost of a tick, the
    /// stack the building used).
    pub const READY: u8 = 3;
    /// Target → host: the deployment was refused; payload: the reason, UTF-8.
    pub const REFUSED: u8 = 4;
    /// Host → target: one sample ([`super::SENSOR_BYTES`]).
    pub const SAMPLE: u8 = 5;
    /// Target → host: the tick's answer ([`super::TickReply`]).
    pub const TICK: u8 = 6;
    /// Host → target: send the run's report; no payload.
    pub const REPORT_REQUEST: u8 = 7;
    /// Target → host: the run's report ([`super::Report`]).
    pub const REPORT: u8 = 8;
}

/// CRC-32 (IEEE 802.3: reflected polynomial 0xEDB88320) of one more byte, from the running
/// value `crc` (start with `!0`, finish with `!crc`). Byte by byte, so a receiver keeps up
/// with its UART: it detects every error of up to three bits in any frame this link carries.
fn crc32_byte(mut crc: u32, byte: u8) -> u32 {
    crc ^= u32::from(byte);
    for _ in 0..8 {
        crc = if crc & 1 != 0 {
            (crc >> 1) ^ 0xEDB8_8320
        } else {
            crc >> 1
        };
    }
    crc
}

/// CRC-32 (IEEE) of `parts`, one after the other.
fn crc32<'a>(parts: impl IntoIterator<Item = &'a [u8]>) -> u32 {
    !parts
        .into_iter()
        .flatten()
        .fold(!0, |crc, &b| crc32_byte(crc, b))
}

/// Writes one frame of `kind` carrying `payload` byte by byte through `put`; false (nothing
/// written) when the payload exceeds [`MAX_PAYLOAD`].
#[must_use]
pub fn write_frame(kind: u8, payload: &[u8], mut put: impl FnMut(u8)) -> bool {
    let Ok(len) = u16::try_from(payload.len()) else {
        return false;
    };
    if payload.len() > MAX_PAYLOAD {
        return false;
    }
    let head = [kind, len.to_le_bytes()[0], len.to_le_bytes()[1]];
    let crc = crc32([&head[..], payload]);
    put(SYNC);
    head.iter().chain(payload).for_each(|&b| put(b));
    crc.to_le_bytes().iter().for_each(|&b| put(b));
    true
}

/// What [`FrameReader::push`] found wrong in the byte stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameError {
    /// A frame's length field exceeds [`MAX_PAYLOAD`].
    TooLong(u16),
    /// A frame's CRC-32 did not match its bytes (a corrupted or desynchronised link).
    Crc,
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FrameError::TooLong(n) => write!(
                f,
                "link frame of {n} bytes (at most {MAX_PAYLOAD}): the link is desynchronised"
            ),
            FrameError::Crc => f.write_str("link frame failed its CRC-32: the link is corrupted"),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Sync,
    Kind,
    Len0,
    Len1,
    Payload,
    /// The CRC's bytes, 0..4.
    Crc(u8),
}

/// Reassembles frames from a byte stream, one byte at a time, in fixed storage (bytes before a
/// [`SYNC`] are skipped). The CRC runs with the bytes, so no byte costs more than another.
pub struct FrameReader {
    state: State,
    kind: u8,
    len: usize,
    at: usize,
    crc: u32,
    got: u32,
    buf: [u8; MAX_PAYLOAD],
}

impl Default for FrameReader {
    fn default() -> Self {
        FrameReader {
            state: State::Sync,
            kind: 0,
            len: 0,
            at: 0,
            crc: !0,
            got: 0,
            buf: [0; MAX_PAYLOAD],
        }
    }
}

impl FrameReader {
    /// Takes the next byte; returns a whole frame's kind and payload when `byte` completes one.
    pub fn push(&mut self, byte: u8) -> Result<Option<(u8, &[u8])>, FrameError> {
        match self.state {
            State::Sync => {
                if byte == SYNC {
                    self.crc = !0;
                    self.state = State::Kind;
                }
                return Ok(None);
            }
            State::Crc(i) => {
                self.got |= u32::from(byte) << (8 * i);
                if i < 3 {
                    self.state = State::Crc(i + 1);
                    return Ok(None);
                }
                self.state = State::Sync;
                if self.got != !self.crc {
                    return Err(FrameError::Crc);
                }
                return Ok(Some((self.kind, &self.buf[..self.len])));
            }
            _ => {}
        }
        self.crc = crc32_byte(self.crc, byte);
        match self.state {
            State::Kind => {
                self.kind = byte;
                self.state = State::Len0;
            }
            State::Len0 => {
                self.len = usize::from(byte);
                self.state = State::Len1;
            }
            State::Len1 => {
                self.len |= usize::from(byte) << 8;
                if self.len > MAX_PAYLOAD {
                    self.state = State::Sync;
                    return Err(FrameError::TooLong(self.len as u16));
                }
                (self.at, self.got) = (0, 0);
                self.state = if self.len == 0 {
                    State::Crc(0)
                } else {
                    State::Payload
                };
            }
            State::Payload => {
                self.buf[self.at] = byte;
                self.at += 1;
                if self.at == self.len {
                    self.state = State::Crc(0);
                }
            }
            State::Sync | State::Crc(_) => {}
        }
        Ok(None)
    }
}

/// Little-endian field writer over a fixed buffer; `None` once the buffer is full.
pub(crate) struct Writer<'a> {
    out: &'a mut [u8],
    at: usize,
}

impl<'a> Writer<'a> {
    pub(crate) fn new(out: &'a mut [u8]) -> Self {
        Writer { out, at: 0 }
    }

    pub(crate) fn bytes(&mut self, b: &[u8]) -> Option<()> {
        let end = self.at.checked_add(b.len())?;
        self.out.get_mut(self.at..end)?.copy_from_slice(b);
        self.at = end;
        Some(())
    }

    pub(crate) fn u8(&mut self, v: u8) -> Option<()> {
        self.bytes(&[v])
    }

    pub(crate) fn u32(&mut self, v: u32) -> Option<()> {
        self.bytes(&v.to_le_bytes())
    }

    pub(crate) fn u64(&mut self, v: u64) -> Option<()> {
        self.bytes(&v.to_le_bytes())
    }

    pub(crate) fn f64(&mut self, v: f64) -> Option<()> {
        self.u64(v.to_bits())
    }

    pub(crate) fn len(&self) -> usize {
        self.at
    }
}

/// Little-endian field reader; `None` past the end.
pub(crate) struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Reader { bytes, at: 0 }
    }

    pub(crate) fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let end = self.at.checked_add(N)?;
        let b = self.bytes.get(self.at..end)?;
        self.at = end;
        b.try_into().ok()
    }

    pub(crate) fn u8(&mut self) -> Option<u8> {
        self.take::<1>().map(|b| b[0])
    }

    pub(crate) fn u32(&mut self) -> Option<u32> {
        self.take().map(u32::from_le_bytes)
    }

    pub(crate) fn u64(&mut self) -> Option<u64> {
        self.take().map(u64::from_le_bytes)
    }

    pub(crate) fn f64(&mut self) -> Option<f64> {
        self.u64().map(f64::from_bits)
    }

    pub(crate) fn rest(&self) -> usize {
        self.bytes.len() - self.at
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_check_value() {
        // The catalogue's check value: CRC-32/ISO-HDLC("123456789") = 0xCBF43926.
        assert_eq!(crc32([&b"123456789"[..]]), 0xCBF4_3926);
    }

    fn frames_of(stream: &[u8]) -> ([(u8, usize, u8); 4], usize, usize) {
        let mut r = FrameReader::default();
        let mut got = [(0, 0, 0); 4];
        let (mut n, mut errors) = (0, 0);
        for &b in stream {
            match r.push(b) {
                Ok(Some((kind, payload))) => {
                    got[n] = (kind, payload.len(), payload.first().copied().unwrap_or(0));
                    n += 1;
                }
                Ok(None) => {}
                Err(_) => errors += 1,
            }
        }
        (got, n, errors)
    }

    #[test]
    fn frames_survive_noise_between_them_and_a_bad_crc_is_caught() {
        let mut stream = [0u8; 64];
        let mut n = 0;
        let mut put = |b| {
            stream[n] = b;
            n += 1;
        };
        put(0x00); // line noise before the first sync
        assert!(write_frame(kind::SAMPLE, &[7, 8, 9], &mut put));
        assert!(write_frame(kind::REPORT_REQUEST, &[], &mut put));
        let (got, count, errors) = frames_of(&stream[..n]);
        assert_eq!((count, errors), (2, 0));
        assert_eq!(got[0], (kind::SAMPLE, 3, 7));
        assert_eq!(got[1], (kind::REPORT_REQUEST, 0, 0));
        // One flipped payload bit: the CRC refuses the frame; the next one still arrives.
        stream[5] ^= 0x10;
        let (got, count, errors) = frames_of(&stream[..n]);
        assert_eq!((count, errors), (1, 1));
        assert_eq!(got[0], (kind::REPORT_REQUEST, 0, 0));
    }

    #[test]
    fn a_stray_sync_in_noise_costs_one_frame_at_most() {
        // Noise holding a sync byte and a short length: the reader takes it for a frame, its
        // CRC fails, and the frames after it arrive whole.
        let mut stream = [0u8; 64];
        let mut n = 0;
        let mut put = |b| {
            stream[n] = b;
            n += 1;
        };
        for b in [SYNC, kind::TICK, 1, 0, 0x55, 1, 2, 3, 4] {
            put(b);
        }
        assert!(write_frame(kind::SAMPLE, &[7, 8, 9], &mut put));
        assert!(write_frame(kind::SAMPLE, &[6], &mut put));
        let (got, count, errors) = frames_of(&stream[..n]);
        assert_eq!(errors, 1);
        assert_eq!(got[count - 1], (kind::SAMPLE, 1, 6));
    }

    #[test]
    fn an_oversized_payload_is_not_sent_cut_short() {
        let big = [0u8; MAX_PAYLOAD + 1];
        let mut written = 0;
        assert!(!write_frame(kind::LOAD, &big, |_| written += 1));
        assert_eq!(written, 0);
        assert!(write_frame(kind::LOAD, &big[..MAX_PAYLOAD], |_| written += 1));
        assert_eq!(written, MAX_PAYLOAD + 8);
    }

    #[test]
    fn an_overlong_length_is_refused_not_buffered() {
        let mut r = FrameReader::default();
        let over = ((MAX_PAYLOAD + 1) as u16).to_le_bytes();
        let mut result = Ok(None);
        for b in [SYNC, kind::LOAD, over[0], over[1]] {
            result = r.push(b);
        }
        assert_eq!(result, Err(FrameError::TooLong(MAX_PAYLOAD as u16 + 1)));
    }
}
