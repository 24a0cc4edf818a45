//! The deployment file: written in shortest round-trip form, so a file read back is the loop
//! that was written, bit for bit; every bad value named by file, line, key and allowed range.

use servo_runtime::{
    deployment_toml, parse_deployment, ControllerKind, Deployment, FeedforwardSpec, Origin,
    ReferenceSpec, SafeState, Servo, SsMatrices, Stability, ZpetcSpec, ZPETC_SECTIONS,
};

/// Deterministic numbers spanning many decades and both signs (xorshift).
fn numbers(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed;
    move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        let unit = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        unit * 10f64.powi((s % 40) as i32 - 30)
    }
}

fn rich() -> Deployment {
    let mut x = numbers(0x9e37_79b9_7f4a_7c15);
    let mut d = Deployment::thesis_prototype();
    d.controller.kind = ControllerKind::Ss;
    d.controller.ss = SsMatrices::from_fn(29, |_, _| x());
    d.stability = Some(Stability {
        spectral_radius: 0.999_983_123_456_789,
        unstable_below: 0.123_456_789_012_345_67,
        unstable_above: f64::INFINITY,
    });
    d.reference = ReferenceSpec::Chirp {
        amplitude_m: 1.234_567_890_123e-6,
        f_start_hz: 100.0,
        f_end_hz: 2000.0,
        duration_s: 0.1,
    };
    // Stable sections (poles well inside the unit circle) with full-precision coefficients.
    let mut u = numbers(0x2545_f491_4f6c_dd1d);
    let mut small = move || (u() * 1e6).fract() * 0.4;
    let mut sections = [[1.0, 0.0, 0.0, 0.0, 0.0]; ZPETC_SECTIONS];
    for s in sections.iter_mut().take(7) {
        *s = [1.0 + small(), small(), small(), small(), small() * 0.5];
    }
    d.feedforward = FeedforwardSpec::Zpetc(ZpetcSpec {
        gain: 1.000_000_000_000_2,
        preview: 7,
        sections,
        sections_used: 7,
    });
    d.smoothing_hz = 4000.0;
    d.protection.safe_state = SafeState::Retract;
    d.protection.position_limit_m = Some(2.2e-5);
    d
}

#[test]
fn a_deployment_read_back_is_the_one_written_bit_for_bit() {
    let d = rich();
    let text = deployment_toml(&d, None, "a test\nof two lines");
    assert!(text.starts_with("# a test\n# of two lines\n"), "{text}");
    let back = parse_deployment(&text, &Origin::default()).unwrap();
    assert_eq!(back.deployment, d);
    // And the loop built from it runs.
    let mut servo = Servo::new(&back.deployment).unwrap();
    let c = servo.tick(&Default::default());
    assert!(c.dac_v.is_finite());
}

#[test]
fn bad_values_are_named_by_file_line_key_and_range() {
    let text = deployment_toml(&Deployment::thesis_prototype(), None, "t");
    let at = |t: &str| Origin {
        path: Some("deploy.toml".into()),
        text: Some(t.to_owned()),
    };
    for (from, to, key, range) in [
        (
            "limit_v = 10.0",
            "limit_v = 12.0",
            "controller.limit_v",
            "(0, 10] V",
        ),
        ("ka = 0.0", "ka = -1.0", "controller.ka", "[0, 1000] V/V"),
        (
            "servo_rate_hz = 199600.0",
            "servo_rate_hz = 50.0",
            "servo_rate_hz",
            "[100, 2000000] Hz",
        ),
        (
            "following_error_m = 0.00002",
            "following_error_m = nan",
            "protection.following_error_m",
            "0 (off)",
        ),
        (
            "dc_gain_m_per_v = ",
            "dc_gain_m_per_v = 0.0 #",
            "stage.dc_gain_m_per_v",
            "nonzero",
        ),
    ] {
        assert!(text.contains(from), "{from} not in\n{text}");
        let bad = text.replacen(from, to, 1);
        let e = parse_deployment(&bad, &at(&bad)).unwrap_err().to_string();
        assert!(
            e.contains("deploy.toml:") && e.contains(key) && e.contains(range),
            "{key}: {e}"
        );
    }
    // An unknown key and a missing table are parse errors naming the file.
    let e = parse_deployment(&format!("{text}\n[extra]\nx = 1\n"), &at("")).unwrap_err();
    assert!(
        e.to_string().contains("deploy.toml") && e.to_string().contains("extra"),
        "{e}"
    );
    let no_stage = text.replace("[stage]", "[stagex]");
    let e = parse_deployment(&no_stage, &at(""))
        .unwrap_err()
        .to_string();
    assert!(e.contains("stage"), "{e}");
}
