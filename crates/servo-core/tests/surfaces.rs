//! Surfaces against the thesis's own formulas (§8.5.3 and §8.5.4 MATLAB scripts, transcribed
//! here with std's functions) on a grid of spindle positions, and against the geometry the
//! thesis reports (Tables 8-3 to 8-5).

use servo_core::surface::{BeamIntegrator, HeightMap, MicroLenslet, SinusoidalGrid, Surface};
use servo_core::{Block, Encoder, SpindleTrackerConfig, Spiral};
use std::f64::consts::{PI, TAU};

const BEAM: BeamIntegrator = BeamIntegrator {
    radius_m: 0.1,
    pitch_m: 2e-3,
};
const GRID: SinusoidalGrid = SinusoidalGrid {
    ax_m: 5e-6,
    ay_m: 5e-6,
    lambda_x_m: 1e-3,
    lambda_y_m: 1e-3,
};

/// (r, θ) over a 50 mm part: 40 radii × 90 angles.
fn positions() -> impl Iterator<Item = (f64, f64)> {
    (0..40).flat_map(|i| (0..90).map(move |j| (i as f64 * 0.6e-3 + 0.013e-3, j as f64 * 0.0697)))
}

#[test]
fn beam_integrator_matches_the_thesis_script() {
    for (r, theta) in positions() {
        // x = r*cos(theta); y = r*sin(theta); x_local = x - floor(x/L)*L - L/2; …
        let (x, y) = (r * libm::cos(theta), r * libm::sin(theta));
        let (l, big_r) = (2e-3, 0.1);
        let xl = x - (x / l).floor() * l - l / 2.0;
        let yl = y - (y / l).floor() * l - l / 2.0;
        let z = big_r - (big_r * big_r - (xl * xl + yl * yl)).sqrt();
        assert!(
            (BEAM.depth_m(r, theta) - z).abs() < 1e-17,
            "r {r} θ {theta}"
        );
    }
}

#[test]
fn sinusoidal_grid_matches_the_thesis_script() {
    for (r, theta) in positions() {
        let (x, y) = (r * libm::cos(theta), r * libm::sin(theta));
        let z = 5e-6 * libm::sin(2.0 * PI * x / 1e-3) + 5e-6 * libm::sin(2.0 * PI * y / 1e-3);
        assert!(
            (GRID.depth_m(r, theta) - z).abs() < 1e-17,
            "r {r} θ {theta}"
        );
    }
}

/// Table 8-4: R = 100 mm, L = 2 mm → 10 µm deep at the cell corners, 5 µm at the edge
/// midpoints (the thesis measured 5.218 µm there against 5 µm nominal), 0 at the centres.
#[test]
fn beam_integrator_geometry() {
    let at = |x: f64, y: f64| BEAM.depth_m(libm::hypot(x, y), libm::atan2(y, x));
    let corner = 0.1 - (0.01f64 - 2e-6).sqrt();
    let edge = 0.1 - (0.01f64 - 1e-6).sqrt();
    for (cx, cy) in [(1e-3, 1e-3), (3e-3, -5e-3), (-7e-3, 9e-3)] {
        assert!(at(cx, cy).abs() < 1e-15, "centre ({cx}, {cy})");
        assert!((at(cx + 0.999_999e-3, cy + 0.999_999e-3) - corner).abs() < 1e-10);
        assert!((at(cx + 0.999_999e-3, cy) - edge).abs() < 1e-10);
    }
    assert!((corner - 10.0e-6).abs() < 0.01e-6 && (edge - 5.0e-6).abs() < 0.01e-6);
}

/// Table 8-5: ±5 µm along each direction, 10 µm peak to valley along a line, at most 10 µm
/// deep overall.
#[test]
fn sinusoidal_grid_geometry() {
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    for i in 0..400 {
        for j in 0..400 {
            let (x, y) = (i as f64 * 2.5e-6, j as f64 * 2.5e-6);
            let z = GRID.depth_m(libm::hypot(x, y), libm::atan2(y, x));
            lo = lo.min(z);
            hi = hi.max(z);
        }
    }
    assert!(
        (hi - 10e-6).abs() < 1e-9 && (lo + 10e-6).abs() < 1e-9,
        "{lo} … {hi}"
    );
}

/// Table 8-3: 100 Hz motion at 16 rpm is n = 375 oscillations per revolution.
#[test]
fn micro_lenslet_frequency() {
    let lens = MicroLenslet {
        amplitude_m: 10e-6,
        per_revolution: 375.0,
    };
    let (fs, rpm) = (199_600.0, 16.0);
    let mut crossings = 0;
    let mut last = 0.0;
    for k in 1..=199_600 {
        let theta = TAU * rpm / 60.0 * k as f64 / fs;
        let z = lens.depth_m(0.0, theta);
        if last < 0.0 && z >= 0.0 {
            crossings += 1;
        }
        last = z;
    }
    assert_eq!(crossings, 100);
}

#[test]
fn height_map_is_nearest_pixel_centred_and_y_up() {
    // 4 × 4 pixels of 1 mm: top-left 255, bottom-right 51.
    let mut pixels = [0u8; 16];
    pixels[0] = 255;
    pixels[15] = 51;
    let map = HeightMap {
        pixels: &pixels,
        width: 4,
        height: 4,
        pixel_m: 1e-3,
        depth_range_m: 10e-6,
    };
    let at = |x: f64, y: f64| map.depth_m(libm::hypot(x, y), libm::atan2(y, x));
    assert!((at(-1.5e-3, 1.5e-3) - 10e-6).abs() < 1e-18); // top-left pixel centre
    assert!((at(-1.01e-3, 1.99e-3) - 10e-6).abs() < 1e-18); // same pixel
    assert!((at(1.5e-3, -1.5e-3) - 2e-6).abs() < 1e-18); // bottom-right: 51/255
    assert_eq!(at(0.5e-3, 0.5e-3), 0.0);
    assert_eq!(at(2.5e-3, 0.0), 0.0); // outside
}

#[test]
fn encoder_angle() {
    let e = Encoder {
        pulses_per_rev: 80_000,
    };
    assert_eq!(e.angle_rad(0), 0.0);
    assert!((e.angle_rad(20_000) - PI / 2.0).abs() < 1e-15);
    assert!((e.angle_rad(80_000 + 40_000) - PI).abs() < 1e-15);
}

#[test]
fn blank_face_is_the_surface_peak() {
    // Table 8-4: 10 µm deep lenslets (cell corners above the centres).
    assert!((BEAM.peak_m() - 10.0e-6).abs() < 0.01e-6);
    let grid = SinusoidalGrid {
        ax_m: 5e-6,
        ay_m: -5e-6,
        lambda_x_m: 1e-3,
        lambda_y_m: 1e-3,
    };
    assert_eq!(grid.peak_m(), 10e-6);
}

const RATE_HZ: f64 = 199_600.0;
const PULSES: u64 = 80_000;

/// §8.3's encoder at the Table 8-5 speed, tracked at 10 Hz.
const TRACKER: SpindleTrackerConfig = SpindleTrackerConfig {
    pulses_per_rev: PULSES,
    speed_rpm: 60.0,
    bandwidth_hz: 10.0,
};

/// The count of an ideal encoder at `t_s` for a spindle at `rpm` starting at angle 0.
fn count_at(t_s: f64, rpm: f64) -> u64 {
    (rpm / 60.0 * t_s * PULSES as f64).floor() as u64
}

#[test]
fn tracker_interpolates_between_pulses() {
    // 60 rpm (Table 8-5): 0.4 pulses per tick, so the raw count is a staircase of ±½ pulse.
    let pulse = TAU / PULSES as f64;
    let mut pll = TRACKER.try_build(1.0 / RATE_HZ).unwrap();
    let (mut worst, mut sum2, mut n) = (0.0f64, 0.0, 0.0);
    for k in 0..(RATE_HZ as u64) {
        let t = k as f64 / RATE_HZ;
        let theta = pll.update(count_at(t, 60.0));
        if t > 0.5 {
            let e = (theta - TAU * t) / pulse;
            worst = worst.max(e.abs());
            sum2 += e * e;
            n += 1.0;
        }
    }
    let rms = (sum2 / n).sqrt();
    // Interpolation must beat the count's own ±½-pulse quantisation (RMS 1/√12 = 0.29 pulse)
    // by the loop's noise-bandwidth ratio, √(33 Hz / 99.8 kHz) ≈ 0.02.
    assert!(rms < 0.29 * 0.02 * 3.0, "RMS {rms} pulses");
    assert!(worst < 0.05, "worst {worst} pulses");
    assert!((pll.rate_rad_s() - TAU).abs() < 1e-3 * TAU);
}

#[test]
fn tracker_locks_onto_an_off_nominal_speed() {
    // Spindle 1 % faster than configured: the type-2 loop removes the rate error.
    let mut pll = TRACKER.try_build(1.0 / RATE_HZ).unwrap();
    let mut theta = 0.0;
    for k in 0..(RATE_HZ as u64) {
        theta = pll.update(count_at(k as f64 / RATE_HZ, 60.6));
    }
    let truth = TAU * 1.01 * (RATE_HZ - 1.0) / RATE_HZ;
    assert!((theta - truth).abs() < 0.1 * TAU / PULSES as f64);
    assert!((pll.rate_rad_s() / TAU - 1.01).abs() < 1e-4);
    assert!(!pll.faulted());
}

#[test]
fn tracker_faults_when_the_encoder_jumps() {
    let mut pll = TRACKER.try_build(1.0 / RATE_HZ).unwrap();
    let mut last = 0.0;
    for k in 0..1000 {
        last = pll.update(count_at(k as f64 / RATE_HZ, 60.0));
    }
    let frozen = pll.update(count_at(1000.0 / RATE_HZ, 60.0) + 100);
    assert!(pll.faulted());
    assert!((frozen - last).abs() < 1e-3 * TAU / PULSES as f64);
    assert_eq!(pll.update(5), frozen);
    pll.reset();
    assert!(!pll.faulted());
}

#[test]
fn tracker_rejects_bad_configuration() {
    let bad = SpindleTrackerConfig {
        speed_rpm: f64::NAN,
        ..TRACKER
    };
    assert!(bad.try_build(1.0 / RATE_HZ).is_err());
    let fast = SpindleTrackerConfig {
        bandwidth_hz: 50e3,
        ..bad
    };
    assert!(fast.try_build(1.0 / RATE_HZ).is_err());
}

#[test]
fn spiral_feeds_inward_per_revolution() {
    let s = Spiral {
        start_radius_m: 25e-3,
        feed_m_per_rev: 5e-6,
    };
    assert_eq!(s.radius_m(0.0), 25e-3);
    assert!((s.radius_m(10.0 * TAU) - (25e-3 - 50e-6)).abs() < 1e-15);
    assert_eq!(s.radius_m(1e9), 0.0);
}
