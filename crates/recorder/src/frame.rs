//! The recorded signal groups, one MCAP channel each, as ROS 2 message definitions encoded
//! in CDR: Foxglove decodes and plots them without any plug-in (`/telemetry.following_error_m`).

/// Declares a flat group of `f32` fields with its ROS 2 field list and CDR body codec.
/// float32 keeps ~7 significant digits: picometres on a 50 µm stroke, far finer on nm-scale
/// errors, at half the bytes of float64 (the recorder's throughput is bytes through zstd).
macro_rules! fields {
    ($(#[$doc:meta])* $name:ident { $($(#[$fdoc:meta])* $field:ident),+ $(,)? }) => {
        $(#[$doc])*
        #[derive(Debug, Clone, Copy, Default, PartialEq)]
        pub struct $name {
            $($(#[$fdoc])* pub $field: f32,)+
        }

        impl $name {
            /// Field names, in wire order.
            pub const FIELDS: &'static [&'static str] = &[$(stringify!($field)),+];
            /// Number of fields.
            pub const LEN: usize = Self::FIELDS.len();

            /// The fields in wire order.
            pub fn values(&self) -> [f32; Self::LEN] {
                [$(self.$field),+]
            }

            /// From the fields in wire order.
            pub fn from_values(v: [f32; Self::LEN]) -> Self {
                let mut it = v.into_iter();
                $name { $($field: it.next().unwrap_or_default(),)+ }
            }

            /// The `ros2msg` field list: one `float32` line per field.
            pub fn field_text() -> String {
                Self::FIELDS.iter().map(|f| format!("float32 {f}\n")).collect()
            }

            /// Appends the CDR body (4-aligned little-endian floats).
            #[inline]
            pub fn put(&self, out: &mut Vec<u8>) {
                $(out.extend_from_slice(&self.$field.to_le_bytes());)+
            }

            /// Reads the fields back from a CDR body.
            pub fn take(body: &mut impl Iterator<Item = f32>) -> Option<Self> {
                Some($name { $($field: body.next()?,)+ })
            }
        }
    };
}

/// A message type of its own MCAP channel: topic, ROS 2 schema, CDR codec.
pub trait Message: Sized {
    /// MCAP topic.
    const TOPIC: &'static str;
    /// ROS 2 message type name (schema name).
    const SCHEMA_NAME: &'static str;
    /// Bytes of an encoded message (CDR header and body): every message of the topic has it.
    const PAYLOAD_BYTES: usize;
    /// The `ros2msg` schema text.
    fn schema_text() -> String;
    /// Appends the CDR body (after the encapsulation header).
    fn put_body(&self, out: &mut Vec<u8>);
    /// Reads a CDR body.
    fn take_body(body: &[u8]) -> Option<Self>;

    /// Appends the CDR encoding (little-endian encapsulation header, then the body).
    #[inline]
    fn encode(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&CDR_LE_HEADER);
        self.put_body(out);
    }

    /// Decodes a CDR payload written by [`Message::encode`].
    fn decode(data: &[u8]) -> Option<Self> {
        Self::take_body(data.strip_prefix(&CDR_LE_HEADER[..])?)
    }
}

/// The little-endian `f32`s of a CDR body.
pub(crate) fn floats(body: &[u8]) -> impl Iterator<Item = f32> + '_ {
    body.chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
}

/// Makes a flat field group a [`Message`] of its own topic.
macro_rules! message {
    ($name:ident, $topic:literal, $schema:literal) => {
        impl Message for $name {
            const TOPIC: &'static str = $topic;
            const SCHEMA_NAME: &'static str = $schema;
            const PAYLOAD_BYTES: usize = CDR_LE_HEADER.len() + 4 * Self::LEN;
            fn schema_text() -> String {
                Self::field_text()
            }
            #[inline]
            fn put_body(&self, out: &mut Vec<u8>) {
                self.put(out)
            }
            fn take_body(body: &[u8]) -> Option<Self> {
                Self::take(&mut floats(body))
            }
        }
    };
}

/// CDR encapsulation header for little-endian plain CDR.
const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

fields!(
    /// What the controller knew this tick (all SI; the reference and measurement in m): the
    /// tick's reference with the reading it acted on.
    TelemetryRecord {
    /// Reference position in m.
    reference_m,
    /// Measured position the tick acted on (ADC gap reading / sensitivity) in m.
    measured_m,
    /// Following error `reference − measured` in m.
    following_error_m,
    /// The feedback's own error `shaped reference − measured` in m (after smoothing or ZPETC).
    controller_error_m,
    /// Controller output (DAC command) in V.
    control_v,
    /// Accelerometer reading in m/s².
    accel_m_s2,
    /// Status flags of the tick ([`daq_io::flags`] bits) as a number.
    flags,
});
message!(TelemetryRecord, "/telemetry", "fts_servo/msg/Telemetry");

fields!(
    /// What no sensor sees, at the same tick.
    TruthRecord {
    /// True tool position relative to the frame `x1 − xg` in m.
    tool_m,
    /// True positioning error `tool − reference` in m.
    true_error_m,
    /// Sensor gap `x2 − xg` in m.
    gap_m,
    /// Motor force in N.
    motor_force_n,
    /// Cutting force in N.
    cutting_force_n,
    /// Coil current in A.
    coil_current_a,
    /// Current noise in A.
    current_noise_a,
    /// Base displacement in m.
    base_m,
    /// Sensor noise in the tick's reading in V.
    sensor_noise_v,
});
message!(TruthRecord, "/truth", "fts_servo/msg/Truth");

/// One tick: both groups, stamped with the tick time (the MCAP log time of both messages).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Frame {
    /// Tick time in ns of simulation time.
    pub time_ns: u64,
    /// Controller-side signals.
    pub telemetry: TelemetryRecord,
    /// Ground truth.
    pub truth: TruthRecord,
}

impl Frame {
    /// The frame of one tick: the controller's telemetry joined with the plant's truth (the
    /// one conversion from the f64 sample contract to the f32 recorded schemas; the flags of
    /// both, [`daq_io::flags`] bits, are merged), stamped at the tick's end (the truth's time).
    pub fn join(t: &daq_io::Telemetry, truth: &daq_io::Truth) -> Frame {
        Frame {
            time_ns: (truth.time_s * 1e9).round() as u64,
            telemetry: TelemetryRecord {
                reference_m: t.reference_m as f32,
                measured_m: t.measured_m as f32,
                following_error_m: t.following_error_m as f32,
                controller_error_m: t.controller_error_m as f32,
                control_v: t.control_v as f32,
                accel_m_s2: t.accel_m_s2 as f32,
                flags: (t.flags | truth.flags) as f32,
            },
            truth: TruthRecord {
                tool_m: known(truth, truth.tool_m),
                // Without the controller's telemetry the tick's reference is not known.
                true_error_m: if t.flags & daq_io::flags::NO_TELEMETRY != 0 {
                    f32::NAN
                } else {
                    known(truth, truth.tool_m - t.reference_m)
                },
                gap_m: truth.gap_m as f32,
                motor_force_n: truth.motor_force_n as f32,
                cutting_force_n: truth.cutting_force_n as f32,
                coil_current_a: truth.coil_current_a as f32,
                current_noise_a: truth.current_noise_a as f32,
                base_m: truth.base_m as f32,
                sensor_noise_v: truth.sensor_noise_v as f32,
            },
        }
    }
}

/// `x` as recorded, or NaN where the plant knows no truth ([`daq_io::flags::NO_TRUTH`]).
fn known(truth: &daq_io::Truth, x: f64) -> f32 {
    if truth.flags & daq_io::flags::NO_TRUTH != 0 {
        f32::NAN
    } else {
        x as f32
    }
}

/// Bytes of a telemetry message before contract v6 (CDR header, six `f32`).
pub(crate) const LEGACY_TELEMETRY_BYTES: usize = 4 + 6 * 4;

/// The recorded telemetry of a recording made before contract v6 (no `controller_error_m`;
/// the reference paired with the next reading): its five signals and flags, the controller's
/// error taken as the following error.
pub(crate) fn legacy_telemetry(data: &[u8]) -> Option<TelemetryRecord> {
    let body = data.strip_prefix(&CDR_LE_HEADER[..])?;
    if data.len() != LEGACY_TELEMETRY_BYTES {
        return None;
    }
    let mut f = floats(body);
    let (reference_m, measured_m, following_error_m) = (f.next()?, f.next()?, f.next()?);
    Some(TelemetryRecord {
        reference_m,
        measured_m,
        following_error_m,
        controller_error_m: following_error_m,
        control_v: f.next()?,
        accel_m_s2: f.next()?,
        flags: f.next()?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cdr_round_trip_and_layout() {
        let t = TelemetryRecord {
            reference_m: 1.5,
            measured_m: -2e-9,
            flags: 4.0,
            ..Default::default()
        };
        let mut buf = Vec::new();
        t.encode(&mut buf);
        assert_eq!(buf.len(), 4 + 4 * TelemetryRecord::FIELDS.len());
        assert_eq!(&buf[4..8], &1.5f32.to_le_bytes());
        assert_eq!(TelemetryRecord::decode(&buf), Some(t));
        assert!(
            TelemetryRecord::schema_text().starts_with("float32 reference_m\nfloat32 measured_m\n")
        );
        assert_eq!(TelemetryRecord::decode(&buf[..12]), None);
    }
}
