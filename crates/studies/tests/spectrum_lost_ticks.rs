//! A recording that lacks ticks (the transport overwrote blocks a recorder had not taken, or
//! the controller's telemetry for a tick never came) is refused by the spectrum with where:
//! a missing tick is a step in every signal, and a spectrum across it is not the loop's.

use run_config::{Loaded, Origin, RunConfig};
use runner::recording::{FrameSink, RunHeader};
use std::collections::BTreeMap;
use std::num::NonZeroU32;
use studies::spectrum::{SpectrumOptions, SpectrumSink};

/// The spectrum of 0.5 s of frames at the default servo rate, with the ticks in `skipped`
/// missing and those in `no_telemetry` recorded from the truth alone.
fn spectrum_of(skipped: &[u64], no_telemetry: &[u64]) -> Result<(), String> {
    let config = RunConfig::default();
    let rate = config.plant.timing.servo_rate_hz;
    let header = RunHeader {
        loaded: Loaded {
            config,
            origin: Origin::default(),
        },
        controller: "PID".into(),
        inputs: BTreeMap::new(),
        every: NonZeroU32::MIN,
        reading_used: true,
        arithmetic: servo_core::ARITHMETIC.into(),
    };
    let mut sink = SpectrumSink::new(SpectrumOptions {
        resolution_hz: 20.0,
        from_s: Some(0.0),
        to_s: None,
        controller: None,
        swaps: Vec::new(),
    });
    sink.header(&header).map_err(|e| e.to_string())?;
    let ticks = (0.5 * rate) as u64;
    for k in (0..ticks).filter(|k| !skipped.contains(k)) {
        let mut f = recorder::Frame {
            time_ns: (k as f64 / rate * 1e9).round() as u64,
            ..Default::default()
        };
        // A deterministic broadband signal.
        let v = ((k.wrapping_mul(2_654_435_761) % 1000) as f32 - 500.0) * 1e-12;
        f.telemetry.following_error_m = v;
        f.telemetry.control_v = v * 1e6;
        f.truth.true_error_m = v;
        if no_telemetry.contains(&k) {
            f.telemetry = recorder::TelemetryRecord {
                flags: daq_io::flags::NO_TELEMETRY as f32,
                ..Default::default()
            };
        }
        sink.frame(&f);
    }
    sink.finish().map(|_| ()).map_err(|e| e.to_string())
}

#[test]
fn a_whole_recording_is_analysed() {
    spectrum_of(&[], &[]).unwrap();
}

#[test]
fn skipped_ticks_are_refused_with_their_count_and_time() {
    let rate = RunConfig::default().plant.timing.servo_rate_hz;
    let at = (0.25 * rate) as u64;
    let e = spectrum_of(&[at, at + 1, at + 2], &[]).unwrap_err();
    let first_s = at as f64 / rate;
    assert!(e.contains("lacks 3 tick(s)"), "{e}");
    assert!(e.contains(&format!("{first_s:.6} s")), "{e}");
}

#[test]
fn ticks_without_telemetry_are_refused() {
    let e = spectrum_of(&[], &[1000, 5000]).unwrap_err();
    assert!(e.contains("lacks 2 tick(s)"), "{e}");
}
