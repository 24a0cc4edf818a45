//! The per-tick payloads of the link and the target's boot and end-of-run reports.

use super::{Reader, Writer};
use daq_io::{Command, Sensor, Telemetry};
use servo_runtime::Trip;
use servo_runtime::TripCause;

/// Bytes of an encoded [`Sensor`].
pub const SENSOR_BYTES: usize = 64;
/// Bytes of an encoded [`TickReply`].
pub const TICK_BYTES: usize = 24 + 1 + 72 + 1 + 8 + 1 + 4;
/// Bytes of an encoded [`Boot`].
pub const BOOT_BYTES: usize = 2 + 2 + 2 + 1 + 4 + 4;
/// Bytes of an encoded [`Ready`].
pub const READY_BYTES: usize = 4 + 4;
/// Bytes of an encoded [`Report`].
pub const REPORT_BYTES: usize = 8 + 4 + 8;

/// The version of the link's frames and payloads (the first field of [`Boot`]): a host and a
/// firmware of different versions refuse each other before anything else is read.
pub const LINK_VERSION: u16 = 2;

/// Writes `s`'s fields in declaration order.
pub fn encode_sensor(s: &Sensor, out: &mut [u8; SENSOR_BYTES]) {
    let mut w = Writer::new(out);
    let _ = (|| {
        w.u64(s.seq)?;
        w.f64(s.time_s)?;
        w.f64(s.gap_v)?;
        w.f64(s.accel_v)?;
        w.u64(s.encoder_count)?;
        w.u32(s.flags)?;
        w.u32(s.reserved)?;
        w.u64(s.run_id)?;
        w.u64(s.published_ns)
    })();
}

/// The sample [`encode_sensor`] wrote; None unless `bytes` is exactly [`SENSOR_BYTES`] long.
pub fn decode_sensor(bytes: &[u8]) -> Option<Sensor> {
    let mut r = Reader::new(bytes);
    let s = Sensor {
        seq: r.u64()?,
        time_s: r.f64()?,
        gap_v: r.f64()?,
        accel_v: r.f64()?,
        encoder_count: r.u64()?,
        flags: r.u32()?,
        reserved: r.u32()?,
        run_id: r.u64()?,
        published_ns: r.u64()?,
    };
    (r.rest() == 0).then_some(s)
}

/// What the target answers to one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TickReply {
    /// The command of the tick.
    pub command: Command,
    /// The tick's telemetry (None after a closing sample).
    pub telemetry: Option<Telemetry>,
    /// The trip the loop is in, if any.
    pub trip: Option<Trip>,
    /// Tripped, and the safe state held for `protection.after_trip_s`.
    pub trip_settled: bool,
    /// SysTick counts (processor clock) the tick took on the target, interrupt body only.
    pub cost_counts: u32,
}

/// A byte that must be 0 or 1.
fn flag(b: u8) -> Option<bool> {
    match b {
        0 => Some(false),
        1 => Some(true),
        _ => None,
    }
}

/// The wire codes of the trip causes (0: no trip), fixed here rather than taken from the
/// order of [`TripCause::ALL`].
const CAUSES: [(TripCause, u8); 5] = [
    (TripCause::FollowingError, 1),
    (TripCause::SensorRange, 2),
    (TripCause::Saturation, 3),
    (TripCause::NotFinite, 4),
    (TripCause::ReferenceFault, 5),
];

fn cause_code(cause: TripCause) -> u8 {
    CAUSES
        .iter()
        .find(|(c, _)| *c == cause)
        .map_or(0, |&(_, code)| code)
}

fn cause_of(code: u8) -> Option<TripCause> {
    CAUSES.iter().find(|&&(_, k)| k == code).map(|&(c, _)| c)
}

impl TickReply {
    /// The reply's bytes.
    pub fn encode(&self, out: &mut [u8; TICK_BYTES]) {
        let mut w = Writer::new(out);
        let c = &self.command;
        let t = self.telemetry.unwrap_or_default();
        let _ = (|| {
            w.u64(c.seq)?;
            w.f64(c.dac_v)?;
            w.u32(c.flags)?;
            w.u32(c.reserved)?;
            w.u8(u8::from(self.telemetry.is_some()))?;
            w.u64(t.seq)?;
            for v in [
                t.time_s,
                t.reference_m,
                t.measured_m,
                t.following_error_m,
                t.controller_error_m,
                t.control_v,
                t.accel_m_s2,
            ] {
                w.f64(v)?;
            }
            w.u32(t.flags)?;
            w.u32(t.reserved)?;
            w.u8(self.trip.map_or(0, |t| cause_code(t.cause)))?;
            w.u64(self.trip.map_or(0, |t| t.tick))?;
            w.u8(u8::from(self.trip_settled))?;
            w.u32(self.cost_counts)
        })();
    }

    /// The reply [`TickReply::encode`] wrote; None unless `bytes` is one.
    pub fn decode(bytes: &[u8]) -> Option<Self> {
        let mut r = Reader::new(bytes);
        let command = Command {
            seq: r.u64()?,
            dac_v: r.f64()?,
            flags: r.u32()?,
            reserved: r.u32()?,
        };
        let present = flag(r.u8()?)?;
        let t = Telemetry {
            seq: r.u64()?,
            time_s: r.f64()?,
            reference_m: r.f64()?,
            measured_m: r.f64()?,
            following_error_m: r.f64()?,
            controller_error_m: r.f64()?,
            control_v: r.f64()?,
            accel_m_s2: r.f64()?,
            flags: r.u32()?,
            reserved: r.u32()?,
        };
        let cause = r.u8()?;
        let tick = r.u64()?;
        let trip = match cause {
            0 => None,
            c => Some(Trip {
                cause: cause_of(c)?,
                tick,
            }),
        };
        let reply = TickReply {
            command,
            telemetry: present.then_some(t),
            trip,
            trip_settled: flag(r.u8()?)?,
            cost_counts: r.u32()?,
        };
        (r.rest() == 0).then_some(reply)
    }
}

/// What the firmware says of itself at reset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Boot {
    /// The deployment image version it reads ([`super::image::VERSION`]).
    pub image_version: u16,
    /// The largest state-space order its build runs.
    pub max_order: u16,
    /// Built for a double-precision FPU (FPv5-D16, `-C target-cpu=cortex-m7`); false: f64 in
    /// software.
    pub f64_in_hardware: bool,
    /// Stack reserved for the loop in bytes (painted at reset; [`Report::stack_used_bytes`]).
    pub stack_bytes: u32,
    /// SysTick clock in Hz (the processor clock).
    pub systick_hz: u32,
}

/// Why a BOOT frame is not one this host reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BootError {
    /// Another link version (the firmware was built from another checkout).
    Version(u16),
    /// The right version but the wrong length.
    Length,
}

impl Boot {
    /// The boot report's bytes, [`LINK_VERSION`] first.
    pub fn encode(&self) -> [u8; BOOT_BYTES] {
        let mut out = [0; BOOT_BYTES];
        let mut w = Writer::new(&mut out);
        let _ = (|| {
            w.bytes(&LINK_VERSION.to_le_bytes())?;
            w.bytes(&self.image_version.to_le_bytes())?;
            w.bytes(&self.max_order.to_le_bytes())?;
            w.u8(u8::from(self.f64_in_hardware))?;
            w.u32(self.stack_bytes)?;
            w.u32(self.systick_hz)
        })();
        out
    }

    /// The report [`Boot::encode`] wrote; the link version is checked before anything else.
    pub fn decode(bytes: &[u8]) -> Result<Self, BootError> {
        let mut r = Reader::new(bytes);
        let version = r.take().map(u16::from_le_bytes).ok_or(BootError::Length)?;
        if version != LINK_VERSION {
            return Err(BootError::Version(version));
        }
        let b = (|| {
            Some(Boot {
                image_version: u16::from_le_bytes(r.take()?),
                max_order: u16::from_le_bytes(r.take()?),
                f64_in_hardware: flag(r.u8()?)?,
                stack_bytes: r.u32()?,
                systick_hz: r.u32()?,
            })
        })();
        match b {
            Some(b) if r.rest() == 0 => Ok(b),
            _ => Err(BootError::Length),
        }
    }
}

/// The target's answer to a deployment it built: what its probe and the building cost.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Ready {
    /// The worst of the probe's quiet ticks in SysTick counts.
    pub probe_counts: u32,
    /// Stack the building of the loop used at its deepest, bytes (more than a tick: the
    /// deployment and the loop pass through it).
    pub load_stack_bytes: u32,
}

impl Ready {
    /// Its bytes.
    pub fn encode(&self) -> [u8; READY_BYTES] {
        let mut out = [0; READY_BYTES];
        out[..4].copy_from_slice(&self.probe_counts.to_le_bytes());
        out[4..].copy_from_slice(&self.load_stack_bytes.to_le_bytes());
        out
    }

    /// What [`Ready::encode`] wrote; None unless `bytes` is one.
    pub fn decode(bytes: &[u8]) -> Option<Self> {
        let mut r = Reader::new(bytes);
        let ready = Ready {
            probe_counts: r.u32()?,
            load_stack_bytes: r.u32()?,
        };
        (r.rest() == 0).then_some(ready)
    }
}

/// What the target counted over the run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Report {
    /// Tick interrupts run (every sample's, the closing one's included).
    pub ticks: u64,
    /// Deepest stack use while the loop ran, bytes (the painted stack's high-water mark).
    pub stack_used_bytes: u32,
    /// Counts of the target's free-running clock (the rate its BOOT frame names) from READY to
    /// this report: everything the target did over the run — ticks, link, waiting — so work
    /// moved out of the timed tick still shows.
    pub run_counts: u64,
}

impl Report {
    /// The report's bytes.
    pub fn encode(&self) -> [u8; REPORT_BYTES] {
        let mut out = [0; REPORT_BYTES];
        out[..8].copy_from_slice(&self.ticks.to_le_bytes());
        out[8..12].copy_from_slice(&self.stack_used_bytes.to_le_bytes());
        out[12..].copy_from_slice(&self.run_counts.to_le_bytes());
        out
    }

    /// The report [`Report::encode`] wrote; None unless `bytes` is one.
    pub fn decode(bytes: &[u8]) -> Option<Self> {
        let mut r = Reader::new(bytes);
        let rep = Report {
            ticks: r.u64()?,
            stack_used_bytes: r.u32()?,
            run_counts: r.u64()?,
        };
        (r.rest() == 0).then_some(rep)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sample_round_trips_bit_for_bit() {
        let s = Sensor {
            seq: 123_456_789_012,
            time_s: 0.1 + 0.2,
            gap_v: -f64::MIN_POSITIVE / 3.0, // subnormal
            accel_v: f64::NAN,
            encoder_count: u64::MAX,
            flags: 0xdead_beef,
            reserved: 1,
            run_id: 42,
            published_ns: 7,
        };
        let mut b = [0; SENSOR_BYTES];
        encode_sensor(&s, &mut b);
        let back = decode_sensor(&b).unwrap();
        assert_eq!(back.accel_v.to_bits(), s.accel_v.to_bits());
        assert_eq!(back.gap_v.to_bits(), s.gap_v.to_bits());
        assert_eq!(
            (back.seq, back.encoder_count, back.flags, back.run_id),
            (s.seq, s.encoder_count, s.flags, s.run_id)
        );
        assert!(decode_sensor(&b[..SENSOR_BYTES - 1]).is_none());
    }

    #[test]
    fn a_tick_reply_round_trips_with_its_trip() {
        let reply = TickReply {
            command: Command {
                seq: 9,
                dac_v: -1.5,
                flags: 3,
                reserved: 0,
            },
            telemetry: Some(Telemetry {
                seq: 9,
                reference_m: 1e-6,
                control_v: -1.5,
                flags: 1 << 11,
                ..Default::default()
            }),
            trip: Some(Trip {
                cause: TripCause::SensorRange,
                tick: 8,
            }),
            trip_settled: true,
            cost_counts: 17,
        };
        let mut b = [0; TICK_BYTES];
        reply.encode(&mut b);
        assert_eq!(TickReply::decode(&b), Some(reply));
        let closing = TickReply {
            telemetry: None,
            trip: None,
            ..reply
        };
        closing.encode(&mut b);
        assert_eq!(TickReply::decode(&b), Some(closing));
        // Every cause has its own code, and a flag byte other than 0 or 1 is refused.
        for cause in TripCause::ALL {
            assert_eq!(cause_of(cause_code(cause)), Some(cause));
        }
        b[24] = 2;
        assert_eq!(TickReply::decode(&b), None);
    }

    #[test]
    fn boot_and_report_round_trip() {
        let boot = Boot {
            image_version: 1,
            max_order: 40,
            f64_in_hardware: true,
            stack_bytes: 65_536,
            systick_hz: 25_000_000,
        };
        assert_eq!(Boot::decode(&boot.encode()), Ok(boot));
        let mut other = boot.encode();
        other[0] = 9; // a firmware of another link version: refused before its fields are read
        assert_eq!(Boot::decode(&other), Err(BootError::Version(9)));
        assert_eq!(Boot::decode(&other[..3]), Err(BootError::Version(9)));
        assert_eq!(
            Boot::decode(&boot.encode()[..BOOT_BYTES - 1]),
            Err(BootError::Length)
        );
        let ready = Ready {
            probe_counts: 17,
            load_stack_bytes: 70_000,
        };
        assert_eq!(Ready::decode(&ready.encode()), Some(ready));
        let rep = Report {
            ticks: 2000,
            stack_used_bytes: 4321,
            run_counts: 5_000_000_000,
        };
        assert_eq!(Report::decode(&rep.encode()), Some(rep));
    }
}
