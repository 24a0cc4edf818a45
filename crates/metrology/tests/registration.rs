//! Registration recovers a known pose and tool-setting errors from maps made independently of
//! the fit: the files of scripts/make_metrology_testdata.py (NumPy's design, a known pose), and
//! maps made here with random poses and the exact (not linearised) setting errors.

use crate::support::{design, synthetic, PITCH_M};
use metrology::{register, Estimate, MapFormat, MeasuredMap, RegisterError, RegisterOptions};
use optics::toolpath::ToolPath;

/// `e` within `tolerance` of `truth` and within 4σ of it.
fn near(name: &str, e: Estimate, truth: f64, tolerance: f64) {
    let off = (e.value - truth).abs();
    assert!(
        off <= tolerance,
        "{name}: {} against {truth} (tolerance {tolerance})",
        e.value
    );
    assert!(
        off <= 4.0 * e.std + 1e-15,
        "{name}: {} ± {} against {truth}",
        e.value,
        e.std
    );
}

#[test]
fn the_pose_of_the_synthetic_map_from_every_format() {
    let path = design();
    let mut first = None;
    for ext in ["datx", "dat", "xyz", "npy", "csv"] {
        let r = register(&synthetic(ext), &path, &RegisterOptions::default()).expect("registers");
        // The generator's pose: piston 120 nm, tilt (30, −20) µrad, decentre (0.21, −0.13) mm,
        // rotation 7°; white noise 0.5 nm.
        near("piston", r.piston_m, 120e-9, 1e-9);
        near("tilt x", r.tilt_rad[0], 30e-6, 0.05e-6);
        near("tilt y", r.tilt_rad[1], -20e-6, 0.05e-6);
        near("decentre x", r.decentre_m[0], 0.21e-3, 0.2e-6);
        near("decentre y", r.decentre_m[1], -0.13e-3, 0.2e-6);
        near(
            "rotation",
            r.rotation_rad.expect("a freeform shows it"),
            7f64.to_radians(),
            20e-6,
        );
        // What is left is the noise.
        assert!(
            (r.residual.tilt_removed.rms_m - 0.5e-9).abs() < 0.05e-9,
            "{ext}: {:?}",
            r.residual
        );
        assert!(r.aperture_covered > 0.9 && r.aperture_covered <= 1.0);
        let d = r.decentre_m[0].value;
        match first {
            None => first = Some(d),
            Some(f) => assert!((d - f).abs() < 5e-9, "{ext}: {d} against {f}"),
        }
    }
}

/// A map of the design seen with a pose and setting errors, made pixel by pixel with the
/// exact setting error (not the fit's linearised signatures).
struct Truth {
    piston: f64,
    tilt: [f64; 2],
    decentre: [f64; 2],
    rotation: f64,
    centre_height: f64,
    x_offset: f64,
}

fn seen(path: &ToolPath, t: &Truth, seed: u64) -> MeasuredMap {
    let (rows, cols, pitch) = (150, 150, PITCH_M);
    let mut state = seed;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut heights = vec![f64::NAN; rows * cols];
    for (i, h) in heights.iter_mut().enumerate() {
        let (row, col) = (i / cols, i % cols);
        let u = (col as f64 - (cols as f64 - 1.0) / 2.0) * pitch;
        let v = ((rows as f64 - 1.0) / 2.0 - row as f64) * pitch;
        let (wx, wy) = (u - t.decentre[0], v - t.decentre[1]);
        let (s, c) = (libm::sin(t.rotation), libm::cos(t.rotation));
        let (qx, qy) = (c * wx + s * wy, -s * wx + c * wy);
        let r = libm::hypot(qx, qy);
        if r > 5e-3 || uniform() < 0.05 {
            continue;
        }
        let setting = path.setting_error_m(r, libm::atan2(qy, qx), t.centre_height, t.x_offset);
        let noise = (uniform() + uniform() + uniform() - 1.5) * 2.0 * 0.3e-9;
        *h = -path.prescription().sag(qx, qy).z_m
            + setting
            + t.piston
            + t.tilt[0] * u
            + t.tilt[1] * v
            + noise;
    }
    MeasuredMap {
        rows,
        cols,
        pitch_m: [pitch; 2],
        heights_m: heights,
        format: MapFormat::Npy,
        wavelength_m: None,
    }
}

#[test]
fn random_poses_and_setting_errors_are_recovered() {
    let path = design();
    let options = RegisterOptions {
        power: false,
        setting_errors: true,
    };
    let mut state = 0x5eed_u64;
    let mut draw = |lo: f64, hi: f64| {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1);
        lo + (hi - lo) * ((state >> 11) as f64 / (1u64 << 53) as f64)
    };
    for seed in 1..=4 {
        let t = Truth {
            piston: draw(-1e-6, 1e-6),
            tilt: [draw(-50e-6, 50e-6), draw(-50e-6, 50e-6)],
            decentre: [draw(-0.2e-3, 0.2e-3), draw(-0.2e-3, 0.2e-3)],
            rotation: draw(-std::f64::consts::PI, std::f64::consts::PI),
            centre_height: draw(-3e-6, 3e-6),
            x_offset: draw(-3e-6, 3e-6),
        };
        let r = register(&seen(&path, &t, seed), &path, &options).expect("registers");
        let tag = |name: &str| format!("seed {seed} {name}");
        near(&tag("decentre x"), r.decentre_m[0], t.decentre[0], 0.5e-6);
        near(&tag("decentre y"), r.decentre_m[1], t.decentre[1], 0.5e-6);
        near(
            &tag("rotation"),
            r.rotation_rad.expect("observable"),
            t.rotation,
            50e-6,
        );
        near(&tag("tilt x"), r.tilt_rad[0], t.tilt[0], 0.1e-6);
        near(
            &tag("centre height"),
            r.centre_height_m.expect("fitted"),
            t.centre_height,
            0.1e-6,
        );
        near(
            &tag("x offset"),
            r.x_offset_m.expect("fitted"),
            t.x_offset,
            0.1e-6,
        );
        assert!(r.residual.tilt_removed.rms_m < 1e-9, "{:?}", r.residual);
    }
}

#[test]
fn maps_that_cannot_be_registered_are_refused_with_the_reason() {
    let path = design();
    let mut small = synthetic("datx");
    small.pitch_m = [PITCH_M * 0.25; 2];
    let e = refusal(&small, &path);
    assert!(e.contains("another aperture"), "{e}");
    let mut sparse = synthetic("datx");
    for (i, h) in sparse.heights_m.iter_mut().enumerate() {
        if i % 20 != 0 {
            *h = f64::NAN;
        }
    }
    let e = refusal(&sparse, &path);
    assert!(e.contains("too few valid pixels"), "{e}");
}

/// Why `map` is not registered (a panic naming what was found when it is).
fn refusal(map: &MeasuredMap, path: &ToolPath) -> String {
    match register(map, path, &RegisterOptions::default()) {
        Err(RegisterError(e)) => e,
        Ok(r) => panic!(
            "registered: decentre {:?}, covered {}",
            r.decentre_m, r.aperture_covered
        ),
    }
}
