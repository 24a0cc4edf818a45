//! Decimated overview channel: every millisecond of run, the minimum, maximum and mean of the
//! main signals, so a long run opens at once in Foxglove or Python (`/overview`, 1 kHz,
//! in chunks of its own: a reader that asks only for it never decompresses the full-rate data).

use crate::frame::{floats, Frame, Message};

fields!(
    /// The signals the overview follows (SI, as in [`crate::Telemetry`] and [`crate::Truth`]).
    Signals {
    /// Following error in m.
    following_error_m,
    /// True positioning error in m.
    true_error_m,
    /// Measured position in m.
    measured_m,
    /// Reference position in m.
    reference_m,
    /// DAC command in V.
    control_v,
    /// Accelerometer reading in m/s².
    accel_m_s2,
    /// Coil current in A.
    coil_current_a,
    /// Cutting force in N.
    cutting_force_n,
});

impl Signals {
    /// The followed signals of one tick.
    pub fn of(f: &Frame) -> Signals {
        Signals {
            following_error_m: f.telemetry.following_error_m,
            true_error_m: f.truth.true_error_m,
            measured_m: f.telemetry.measured_m,
            reference_m: f.telemetry.reference_m,
            control_v: f.telemetry.control_v,
            accel_m_s2: f.telemetry.accel_m_s2,
            coil_current_a: f.truth.coil_current_a,
            cutting_force_n: f.truth.cutting_force_n,
        }
    }
}

/// One overview sample: the ticks of one period `[t, t + OVERVIEW_PERIOD_NS)`, stamped `t`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Overview {
    /// Ticks in the period.
    pub ticks: u32,
    /// Smallest value of each signal.
    pub min: Signals,
    /// Largest value of each signal.
    pub max: Signals,
    /// Mean of each signal.
    pub mean: Signals,
}

impl Message for Overview {
    const TOPIC: &'static str = "/overview";
    const SCHEMA_NAME: &'static str = "fts_servo/msg/Overview";
    const PAYLOAD_BYTES: usize = 4 + 4 + 3 * 4 * Signals::LEN;

    fn schema_text() -> String {
        format!(
            "uint32 ticks\nfts_servo/Signals min\nfts_servo/Signals max\n\
             fts_servo/Signals mean\n{}\nMSG: fts_servo/Signals\n{}",
            "=".repeat(80),
            Signals::field_text()
        )
    }

    fn put_body(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.ticks.to_le_bytes());
        self.min.put(out);
        self.max.put(out);
        self.mean.put(out);
    }

    fn take_body(body: &[u8]) -> Option<Self> {
        let ticks = u32::from_le_bytes(body.get(..4)?.try_into().ok()?);
        let mut rest = floats(&body[4..]);
        Some(Overview {
            ticks,
            min: Signals::take(&mut rest)?,
            max: Signals::take(&mut rest)?,
            mean: Signals::take(&mut rest)?,
        })
    }
}

/// Overview period in ns (1 kHz).
pub const OVERVIEW_PERIOD_NS: u64 = 1_000_000;

/// Accumulates the ticks of the current period.
#[derive(Debug, Default)]
pub struct OverviewBin {
    period: Option<u64>,
    ticks: u32,
    min: [f32; Signals::LEN],
    max: [f32; Signals::LEN],
    sum: [f64; Signals::LEN],
}

impl OverviewBin {
    /// Adds a tick; when it opens a new period, returns the finished one with its start time
    /// in ns.
    #[inline]
    pub fn add(&mut self, frame: &Frame) -> Option<(u64, Overview)> {
        let period = frame.time_ns / OVERVIEW_PERIOD_NS;
        let done = match self.period {
            Some(p) if p != period => self.take(),
            _ => None,
        };
        let v = Signals::of(frame).values();
        if self.ticks == 0 {
            self.period = Some(period);
            self.min = v;
            self.max = v;
            self.sum = v.map(f64::from);
        } else {
            for (i, x) in v.into_iter().enumerate() {
                self.min[i] = self.min[i].min(x);
                self.max[i] = self.max[i].max(x);
                self.sum[i] += f64::from(x);
            }
        }
        self.ticks += 1;
        done
    }

    /// The period being filled, if it has ticks (at the end of a run).
    pub fn take(&mut self) -> Option<(u64, Overview)> {
        let period = self.period.take()?;
        let n = std::mem::take(&mut self.ticks);
        (n > 0).then(|| {
            let mean = self.sum.map(|s| (s / f64::from(n)) as f32);
            (
                period * OVERVIEW_PERIOD_NS,
                Overview {
                    ticks: n,
                    min: Signals::from_values(self.min),
                    max: Signals::from_values(self.max),
                    mean: Signals::from_values(mean),
                },
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(time_ns: u64, error: f32) -> Frame {
        let mut f = Frame {
            time_ns,
            ..Default::default()
        };
        f.telemetry.following_error_m = error;
        f
    }

    #[test]
    fn one_sample_per_millisecond_with_min_max_mean() {
        let mut bin = OverviewBin::default();
        let mut out = Vec::new();
        // 5 µs ticks over 2.5 ms: errors 0, 1, 2, … within each millisecond.
        for k in 0..500u64 {
            let t = k * 5_000;
            out.extend(bin.add(&frame(t, (k % 200) as f32)));
        }
        out.extend(bin.take());
        assert_eq!(out.len(), 3);
        let (t0, first) = out[0];
        assert_eq!(t0, 0);
        assert_eq!(first.ticks, 200);
        assert_eq!(first.min.following_error_m, 0.0);
        assert_eq!(first.max.following_error_m, 199.0);
        assert_eq!(first.mean.following_error_m, 99.5);
        assert_eq!(out[2].0, 2_000_000);
        assert_eq!(out[2].1.ticks, 100);
        assert_eq!(out[2].1.max.following_error_m, 99.0);
    }

    #[test]
    fn cdr_round_trip() {
        let mut bin = OverviewBin::default();
        bin.add(&frame(0, -3.0));
        bin.add(&frame(5, 1.0));
        let (_, o) = bin.take().unwrap();
        let mut buf = Vec::new();
        o.encode(&mut buf);
        assert_eq!(buf.len(), 4 + 4 + 3 * 4 * Signals::LEN);
        assert_eq!(Overview::decode(&buf), Some(o));
        assert!(Overview::schema_text()
            .contains("\nMSG: fts_servo/Signals\nfloat32 following_error_m\n"));
    }
}
