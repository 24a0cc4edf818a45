//! The byte layout of every contract type, from the compiler (`size_of`, `offset_of!`): what
//! the C header must match (checked in CI by compiling assertions generated from this table)
//! and what [`LAYOUT_FINGERPRINT`] hashes.

use crate::contract::{
    Ack, Command, Control, ControllerLoad, Health, Latency, Sensor, Telemetry, TelemetryBlock,
    Truth, TruthBlock,
};
use core::mem::{align_of, offset_of, size_of};

/// One contract type: its name, size and alignment, and each field's offset, in bytes.
#[derive(Debug, Clone, Copy)]
pub struct TypeLayout {
    /// The Rust (and, prefixed `fts_`, the C) type name.
    pub name: &'static str,
    /// Size in bytes.
    pub size: usize,
    /// Alignment in bytes.
    pub align: usize,
    /// `(field, offset in bytes)`, in declaration order.
    pub fields: &'static [(&'static str, usize)],
}

macro_rules! layouts {
    ($($t:ident { $($f:ident),+ $(,)? })+) => {
        /// Every contract type's layout.
        pub const LAYOUTS: &[TypeLayout] = &[$(TypeLayout {
            name: stringify!($t),
            size: size_of::<$t>(),
            align: align_of::<$t>(),
            fields: &[$((stringify!($f), offset_of!($t, $f))),+],
        }),+];
    };
}

layouts! {
    Sensor { seq, time_s, gap_v, accel_v, encoder_count, flags, reserved, run_id, published_ns }
    Command { seq, dac_v, flags, reserved }
    Telemetry { seq, time_s, reference_m, measured_m, following_error_m, controller_error_m, control_v, accel_m_s2, flags, reserved }
    Truth { seq, time_s, tool_m, gap_m, motor_force_n, cutting_force_n, coil_current_a, current_noise_a, base_m, sensor_noise_v, dac_v, flags, reserved }
    TelemetryBlock { block, count, flags, run_id, ticks }
    TruthBlock { block, count, flags, run_id, ticks }
    Control { command, reserved, value, id }
    Ack { id, tick, value, low, high, unstable_at, command, status, role, reserved }
    Latency { count, min_ns, p50_ns, p99_ns, p999_ns, p9999_ns, max_ns }
    Health { role, state, ticks, overruns, faults, stop_cause, wall_s, latency, lateness, execution }
    ControllerLoad { id, len, reserved, data }
}

/// FNV-1a over every size, alignment and offset of [`LAYOUTS`]: changes whenever a layout
/// does (a test pins it, so a layout change without a [`crate::contract::CONTRACT_VERSION`]
/// bump fails).
pub const LAYOUT_FINGERPRINT: u64 = {
    const fn mix(h: u64, x: usize) -> u64 {
        (h ^ x as u64).wrapping_mul(0x0000_0100_0000_01b3)
    }
    let mut h = 0xcbf2_9ce4_8422_2325;
    let mut i = 0;
    while i < LAYOUTS.len() {
        let t = &LAYOUTS[i];
        h = mix(mix(h, t.size), t.align);
        let mut j = 0;
        while j < t.fields.len() {
            h = mix(h, t.fields[j].1);
            j += 1;
        }
        i += 1;
    }
    h
};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contract::CONTRACT_VERSION;

    #[test]
    fn the_layout_is_pinned_to_its_version() {
        // A failure here means a contract layout changed: bump CONTRACT_VERSION (and the
        // `fts_servo::vN` type names, and include/fts_servo_contract.h), then pin the new
        // fingerprint.
        assert_eq!(
            (CONTRACT_VERSION, LAYOUT_FINGERPRINT),
            (6, 0xccba_2bb2_2bed_bcc7),
            "fingerprint {LAYOUT_FINGERPRINT:#018x}"
        );
    }

    #[test]
    fn fields_are_in_declaration_order_within_the_size() {
        // repr(C) keeps declaration order; the C check compares every offset and size.
        for t in LAYOUTS {
            let mut offsets: Vec<usize> = t.fields.iter().map(|f| f.1).collect();
            offsets.push(t.size);
            assert!(offsets.windows(2).all(|w| w[0] < w[1]), "{}", t.name);
            assert_eq!(t.size % t.align, 0, "{}", t.name);
        }
    }
}
