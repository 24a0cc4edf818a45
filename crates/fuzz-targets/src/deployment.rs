//! A deployment as each door takes it: the TOML of `Servo::from_toml`, the C ABI's
//! `fts_servo_open_toml`, and the image the firmware builds its loop from. A loop that is
//! built is ticked through hostile samples, and its commands must stay defined.

use crate::Scratch;
use daq_io::{Command, Sensor};
use servo_link::image;
use servo_runtime::Servo;
use std::ffi::{c_char, CString};

/// Samples a peer might send: a plain one, NaN and infinite readings, unknown flags, a
/// sequence that jumps back and forward, the end marker.
pub(crate) fn hostile_samples() -> [Sensor; 6] {
    let plain = |seq: u64| Sensor {
        seq,
        time_s: seq as f64 * 5e-6,
        gap_v: 0.1,
        accel_v: -0.05,
        run_id: 7,
        ..Sensor::default()
    };
    [
        plain(0),
        Sensor {
            gap_v: f64::NAN,
            accel_v: f64::INFINITY,
            ..plain(1)
        },
        Sensor {
            flags: !daq_io::flags::END,
            ..plain(2)
        },
        Sensor {
            gap_v: f64::NEG_INFINITY,
            ..plain(1_000_000)
        },
        plain(3),
        Sensor {
            flags: daq_io::flags::END,
            ..plain(4)
        },
    ]
}

/// The defined safe behaviour of a command: finite and within the output limit.
pub(crate) fn check_command(c: &Command, limit_v: f64) {
    assert!(
        c.dac_v.is_finite() && c.dac_v.abs() <= limit_v,
        "command {} V outside ±{limit_v} V",
        c.dac_v
    );
}

/// Ticks `servo` through [`hostile_samples`], checking each command against `limit_v`.
pub(crate) fn tick_hostile(servo: &mut Servo, limit_v: f64) {
    for s in hostile_samples() {
        check_command(&servo.tick(&s), limit_v);
    }
}

/// A deployment file's text, through `Servo::from_toml`.
pub fn from_toml(_scratch: &Scratch, data: &[u8]) -> bool {
    let Ok(text) = std::str::from_utf8(data) else {
        return false;
    };
    let built = Servo::from_toml(text);
    let Ok(parsed) = servo_config::parse_deployment(text, &servo_config::Origin::default()) else {
        assert!(
            built.is_err(),
            "a deployment that does not parse is refused"
        );
        return false;
    };
    let Ok(mut servo) = built else {
        return false;
    };
    tick_hostile(&mut servo, parsed.deployment.controller.limit_v);
    true
}

/// A deployment's text through the C ABI (as a C string: up to its first NUL), opened,
/// ticked and closed.
pub fn c_abi_open_toml(_scratch: &Scratch, data: &[u8]) -> bool {
    let end = data.iter().position(|&b| b == 0).unwrap_or(data.len());
    let text = CString::new(&data[..end]).expect("no NUL before the end");
    let abi = fts_servo::FtsServoAbi::of_this_library();
    let mut handle = std::ptr::null_mut();
    let mut error = [0 as c_char; 256];
    // SAFETY: a NUL-terminated text, the library's own ABI description, a writable handle
    // pointer and 256 writable bytes for the message.
    let code = unsafe {
        fts_servo::fts_servo_open_toml(
            text.as_ptr(),
            &abi,
            &mut handle,
            error.as_mut_ptr(),
            error.len(),
        )
    };
    assert_eq!(
        code == fts_servo::FTS_SERVO_OK,
        !handle.is_null(),
        "a handle exactly when opened"
    );
    assert_eq!(
        error[255], 0,
        "the message is NUL-terminated within its buffer"
    );
    if handle.is_null() {
        return false;
    }
    for s in hostile_samples() {
        let mut c = Command::default();
        // SAFETY: a live handle, a sample and a writable command.
        unsafe { fts_servo::fts_servo_tick(handle, &s, &mut c) };
        assert!(c.dac_v.is_finite(), "command {} V", c.dac_v);
    }
    // SAFETY: the live handle, closed once.
    unsafe { fts_servo::fts_servo_close(handle) };
    true
}

/// A deployment image as the firmware receives it: decoded, built and ticked.
pub fn image(_scratch: &Scratch, data: &[u8]) -> bool {
    let Ok(d) = image::decode(data) else {
        return false;
    };
    let Ok(mut servo) = Servo::new(&d) else {
        return false;
    };
    tick_hostile(&mut servo, d.controller.limit_v);
    true
}
