//! The processor-in-the-loop link as both ends read it: a byte stream reassembled into
//! CRC-checked frames, each dispatched by kind as the firmware does (a deployment image builds
//! the loop, a sample ticks it) and as the host does (boot, ready, tick and report replies).
//!
//! An input is the stream as it is (first byte even), or (first byte odd) frames to be sent
//! whole: records of kind (1 byte), length (2 bytes, little-endian) and payload, each framed
//! with its CRC by `servo_link::write_frame`. A fuzzer cannot make a CRC-32 match a payload it
//! changed by chance; the second form lets it reach what the frames carry.

use crate::deployment::check_command;
use crate::Scratch;
use servo_link::{decode_sensor, image, kind, Boot, FrameReader, Ready, Report, TickReply};
use servo_runtime::Servo;

/// A link's bytes (see the module's documentation), frame by frame; accepted when a loop was
/// built and ticked.
pub fn frames(_scratch: &Scratch, data: &[u8]) -> bool {
    match data.split_first() {
        Some((mode, records)) if mode % 2 == 1 => dispatch(&framed(records)),
        Some((_, stream)) => dispatch(stream),
        None => false,
    }
}

/// The stream that sends `records` (kind, length, payload) as whole frames; a record whose
/// length runs past the input ends them.
fn framed(mut records: &[u8]) -> Vec<u8> {
    let mut stream = Vec::new();
    while let [frame_kind, n0, n1, rest @ ..] = records {
        let n = usize::from(u16::from_le_bytes([*n0, *n1]));
        let Some(payload) = rest.get(..n) else {
            break;
        };
        // A payload above the link's largest is not written (as a sender refuses it).
        let _ = servo_link::write_frame(*frame_kind, payload, |b| stream.push(b));
        records = &rest[n..];
    }
    stream
}

/// Reads `stream` as the link's receiving ends do.
fn dispatch(stream: &[u8]) -> bool {
    let mut ticked = false;
    let mut reader = Box::<FrameReader>::default();
    let mut running: Option<(Servo, f64)> = None;
    for &byte in stream {
        let Ok(Some((frame_kind, payload))) = reader.push(byte) else {
            continue;
        };
        match frame_kind {
            kind::LOAD => {
                running = image::decode(payload).ok().and_then(|d| {
                    Servo::new(&d)
                        .ok()
                        .map(|servo| (servo, d.controller.limit_v))
                });
            }
            kind::SAMPLE => {
                let (Some(sample), Some((servo, limit_v))) = (decode_sensor(payload), &mut running)
                else {
                    continue;
                };
                #[cfg(feature = "planted")]
                planted(&sample);
                check_command(&servo.tick(&sample), *limit_v);
                ticked = true;
            }
            kind::BOOT => {
                let _ = Boot::decode(payload);
            }
            kind::READY => {
                let _ = Ready::decode(payload);
            }
            kind::TICK => {
                let _ = TickReply::decode(payload);
            }
            kind::REPORT => {
                let _ = Report::decode(payload);
            }
            _ => {}
        }
    }
    ticked
}

/// The planted fault: a sample whose encoder count is one 64-bit value (reachable only through
/// a frame with a valid CRC-32, of kind SAMPLE, after a deployment image that builds: a random
/// byte string gets there about once in 2⁹⁶ tries).
#[cfg(feature = "planted")]
fn planted(sample: &daq_io::Sensor) {
    if sample.encoder_count == 0x00C0_FFEE_5EED_F00D {
        panic!("the planted fault: encoder count 0x00C0FFEE5EEDF00D");
    }
}
