//! The deployment file: written in shortest round-trip form, so a file read back is the loop
//! that was written, bit for bit; every bad value named by file, line, key and allowed range.

use servo_config::{
    deployment_toml, parse_deployment, ControllerKind, Deployment, FeedforwardSpec, Origin,
    ReferenceSpec, SafeState, SsMatrices, Stability, ZpetcSpec, ZPETC_SECTIONS,
};
use servo_runtime::Servo;

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
    d.stability = Some(
        Stability {
            spectral_radius: 0.999_983_123_456_789,
            unstable_below: 0.123_456_789_012_345_67,
            unstable_above: f64::INFINITY,
            sha256: Default::default(),
        }
        .sealed(d.servo_rate_hz, &d.stage, &d.controller),
    );
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

/// A ZPETC's preview beyond what the loop keeps is refused by its own key (it was added to the
/// smoothing's half window first: found by fuzzing the deployment image, an overflow).
#[test]
fn a_zpetc_preview_beyond_the_loop_is_refused_by_key() {
    let text = deployment_toml(&rich(), None, "zpetc");
    for preview in ["63", "9223372036854775807"] {
        let bad = text.replacen(
            "preview_ticks = 7",
            &format!("preview_ticks = {preview}"),
            1,
        );
        let e = parse_deployment(&bad, &Origin::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("feedforward.preview_ticks") && e.contains("62"),
            "{e}"
        );
    }
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

/// An FIR feedforward's taps, stride and preview come back bit for bit; taps that reach back
/// further than the loop keeps, or a stride of 0, are refused by key.
#[test]
fn an_fir_deployment_reads_back_and_its_reach_is_checked() {
    use servo_runtime::deployment::{FirSpec, MAX_FIR_TAPS};
    let mut d = rich();
    let mut u = numbers(0x9e37_79b9_7f4a_7c15);
    let mut taps = [0.0; MAX_FIR_TAPS];
    for t in taps.iter_mut().take(96) {
        *t = (u() * 1e3).fract() * 0.04 - 0.02;
    }
    taps[0] = 1.0;
    d.feedforward = FeedforwardSpec::Fir(FirSpec {
        taps,
        taps_used: 96,
        preview: 32,
        stride: 16,
    });
    let text = deployment_toml(&d, None, "fir");
    let back = parse_deployment(&text, &Origin::default()).unwrap();
    assert_eq!(back.deployment, d);
    let mut servo = Servo::new(&back.deployment).unwrap();
    assert!(servo.tick(&Default::default()).dac_v.is_finite());
    for (from, to) in [
        ("stride_ticks = 16", "stride_ticks = 22"),
        ("stride_ticks = 16", "stride_ticks = 0"),
        // 96 taps × this stride is 2⁶⁴ + 32 ticks: a reach that wrapped to 32 was taken.
        ("stride_ticks = 16", "stride_ticks = 192153584101141163"),
    ] {
        let bad = text.replacen(from, to, 1);
        let e = parse_deployment(&bad, &Origin::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("feedforward.stride_ticks") && e.contains("2048"),
            "{e}"
        );
    }
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
    // The stability record's keys are named as the file spells them, with their line.
    let bad = text.replacen("spectral_radius = ", "spectral_radius = 1.5 # ", 1);
    let e = parse_deployment(&bad, &at(&bad)).unwrap_err().to_string();
    let line = bad
        .lines()
        .position(|l| l.starts_with("spectral_radius"))
        .unwrap()
        + 1;
    assert!(
        e.contains(&format!(
            "deploy.toml:{line}: controller.stability.spectral_radius"
        )),
        "{e}"
    );
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

/// A deployment whose coefficients or stability record were edited after the check (by hand,
/// or a damaged copy) is refused when opened — from TOML and from the firmware's image —
/// naming what no longer matches; the intact one opens.
#[test]
fn an_edited_deployment_is_refused_at_open() {
    use servo_link::image;
    let at = |t: &str| Origin {
        path: Some("deploy.toml".into()),
        text: Some(t.to_owned()),
    };
    let d = rich();
    let text = deployment_toml(&d, None, "t");
    assert!(Servo::from_toml(&text).is_ok());
    let entry = d.controller.ss.as_ref().unwrap().entry(3, 4);
    let written = servo_config::num(entry);
    assert!(text.contains(&written));
    let edits = [
        (
            text.replacen(&written, &servo_config::num(entry * 1.001), 1),
            "controller.stability.sha256.controller",
        ),
        (
            text.lines()
                .map(|l| match l.starts_with("unstable_below = ") {
                    true => "unstable_below = 0.01",
                    false => l,
                })
                .collect::<Vec<_>>()
                .join("\n"),
            "controller.stability.sha256.record",
        ),
        (
            text.replacen("kt_n_per_a = 3.6658", "kt_n_per_a = 3.7", 1),
            "controller.stability.sha256.stage",
        ),
    ];
    for (bad, key) in edits {
        assert_ne!(bad, text, "{key}: the edit did not apply");
        let e = Servo::from_toml(&bad).err().expect("refused").to_string();
        assert!(
            e.contains(key) && e.contains("does not match"),
            "{key}: {e}"
        );
        let e = parse_deployment(&bad, &at(&bad)).unwrap_err().to_string();
        assert!(e.contains("deploy.toml:") && e.contains(key), "{key}: {e}");
    }
    // A PID gain edited in the thesis deployment.
    let pid = deployment_toml(&Deployment::thesis_prototype(), None, "t");
    let bad = pid.replacen("kp = 1.65", "kp = 3.3", 1);
    assert_ne!(bad, pid);
    let e = Servo::from_toml(&bad).err().expect("refused").to_string();
    assert!(e.contains("controller.stability.sha256.controller"), "{e}");
    // What the record does not cover stays editable: protection and the reference.
    let ok = pid.replacen(
        "following_error_m = 0.00002",
        "following_error_m = 0.00001",
        1,
    );
    assert_ne!(ok, pid);
    assert!(Servo::from_toml(&ok).is_ok());

    // The same in the image the firmware takes: an entry of A changed in its bytes.
    let mut bytes = vec![0u8; image::MAX_BYTES];
    let n = image::encode(&d, &mut bytes).unwrap();
    bytes.truncate(n);
    assert!(Servo::new(&image::decode(&bytes).unwrap()).is_ok());
    let old = entry.to_bits().to_le_bytes();
    let at_entry = bytes.windows(8).position(|w| w == old).unwrap();
    bytes[at_entry..at_entry + 8].copy_from_slice(&(entry * 1.001).to_bits().to_le_bytes());
    let e = Servo::new(&image::decode(&bytes).unwrap()).err().unwrap();
    assert_eq!(
        (e.section, e.key),
        ("controller.stability", "sha256.controller"),
        "{e}"
    );
}

/// What a deployment says it was made for is checked at open as at a load: a rate that is not
/// the loop's is refused, naming the key.
#[test]
fn a_deployment_made_for_another_rate_is_refused_at_open() {
    let made_for = servo_config::MadeFor {
        tool: "fts-servo test".into(),
        plant_sha256: "ab".repeat(32),
        stage: "light".into(),
        servo_rate_hz: 199_600.0,
    };
    let d = Deployment::thesis_prototype();
    let text = deployment_toml(&d, Some(&made_for), "t");
    assert!(Servo::from_toml(&text).is_ok());
    let other = servo_config::MadeFor {
        servo_rate_hz: 20_000.0,
        ..made_for
    };
    let e = Servo::from_toml(&deployment_toml(&d, Some(&other), "t"))
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("controller.made_for.servo_rate_hz"), "{e}");
}

/// A controller fragment's error points at its own line and never quotes the file.
#[test]
fn a_fragments_error_is_located_at_its_line() {
    let text = "# tuned\n[controller]\nkind = \"pid\"\n\n[controller.pid]\nkp = 1.0\nkx = 2.0\n";
    let at = Origin {
        path: Some("pid.toml".into()),
        text: Some(text.to_owned()),
    };
    let e = servo_config::parse_controller_file(text, &at, &Default::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("pid.toml: line 7, column 1: unknown field `kx`"),
        "{e}"
    );
    assert!(
        !e.contains("kx = 2.0"),
        "the file's text is not quoted: {e}"
    );
}
