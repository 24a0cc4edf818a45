//! End-to-end: the `servo` binary as a user runs it.

use std::path::Path;

use crate::common;

use common::{json, servo, succeeded, tmp};

fn nm(v: &serde_json::Value, group: &str) -> f64 {
    v[group]["rms"].as_f64().unwrap() * 1e9
}

/// The plant-sim calibration: 468 Hz PID on the 0.174 kg stage, no accelerometer. Documented
/// 0.83 nm following / 0.23 nm true (thesis §5.7.4, crates/plant-sim/README.md); tolerances
/// ±10 % / ±15 % for a 2 s run with a different seed.
#[test]
fn calibrated_run_reproduces_the_documented_errors() {
    let cfg = tmp("cal.toml");
    std::fs::write(
        &cfg,
        "[run]\nduration_s = 2.0\nseed = 11\n\n[controller.pid]\nkp = 0.6443\nki = 219.46\nkd = 3.7097e-4\n",
    )
    .unwrap();
    let out = servo()
        .args([
            "run",
            "--json",
            "-q",
            "--no-record",
            "--mass",
            "heavy",
            "--noise",
            "sensor,current,base",
            "-c",
        ])
        .arg(&cfg)
        .output()
        .unwrap();
    let v = json(&out);
    let (f, t) = (nm(&v, "following_error_m"), nm(&v, "true_error_m"));
    assert!((f / 0.83 - 1.0).abs() < 0.10, "following {f:.3} nm");
    assert!((t / 0.23 - 1.0).abs() < 0.15, "true {t:.3} nm");
    assert_eq!(v["ticks"], 399_200);
}

fn fails_with(args: &[&str], cfg: Option<(&str, &str)>, needles: &[&str]) {
    let mut cmd = servo();
    cmd.args(args);
    if let Some((name, text)) = cfg {
        let p = tmp(name);
        std::fs::write(&p, text).unwrap();
        cmd.arg("-c").arg(&p);
    }
    let out = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    for n in needles {
        assert!(err.contains(n), "`{n}` missing from: {err}");
    }
}

#[test]
fn bad_input_names_file_line_key_and_range() {
    fails_with(
        &["run", "--no-record"],
        Some(("unknown.toml", "[run]\nduraton_s = 1.0\n")),
        &["unknown.toml", "line 2", "duraton_s"],
    );
    fails_with(
        &["run", "--no-record"],
        Some((
            "mass.toml",
            "[run]\nduration_s = 0.2\n\n[plant.stage]\nm2_kg = -0.07\n",
        )),
        &["mass.toml:5", "plant.stage.m2_kg", "[1e-6, 1e3] kg"],
    );
    fails_with(
        &["run", "--no-record", "--rate", "0"],
        None,
        &["plant.timing.servo_rate_hz", "[100, 2e6] Hz"],
    );
    fails_with(
        &["run", "--no-record", "--rate", "1e9"],
        None,
        &["servo_rate_hz"],
    );
    fails_with(
        &["run", "--no-record", "--noise", "sensr"],
        None,
        &["--noise", "sensr"],
    );
}

#[test]
fn unstable_loop_is_refused_before_running() {
    fails_with(
        &["run", "--no-record"],
        Some(("hot.toml", "[controller.pid]\nkp = 200.0\nkd = 0.1\n")),
        &["unstable", "spectral radius"],
    );
}

#[test]
fn controller_file_of_the_wrong_shape() {
    let ss = tmp("ctrl.toml");
    std::fs::write(&ss, "sample_rate_hz = 199600.0\na = [[0.5, 0.0], [0.0, 0.5]]\nb = [[1.0]]\nc = [[1.0, 0.0]]\nd = [[0.0]]\n").unwrap();
    let cfg = format!(
        "[controller]\nkind = \"ss\"\nss_file = {:?}\n",
        ss.display().to_string()
    );
    fails_with(
        &["run", "--no-record"],
        Some(("ss.toml", &cfg)),
        &["ctrl.toml", "b", "2×1"],
    );
}

/// A controller file with `d = [[1e250]]` (once read as "stable, spectral radius 0") and a NaN
/// sample rate are refused before anything runs, in process and by a HIL controller process
/// that repeats the check.
#[test]
fn overflowing_or_nan_controller_files_are_refused() {
    let file = |name: &str, rate: &str, d: &str| {
        let ss = tmp(name);
        std::fs::write(
            &ss,
            format!(
                "sample_rate_hz = {rate}\na = [[0.5]]\nb = [[1.0]]\nc = [[1.0]]\nd = [[{d}]]\n"
            ),
        )
        .unwrap();
        ss.display().to_string()
    };
    let ss = ["--controller", "ss", "--ss-file"];
    let huge = file("huge.toml", "199600.0", "1e250");
    for command in [
        &["run", "--no-record"][..],
        &["controller", "--prefix", "nobody-here"],
    ] {
        let args = [command, &ss, &[huge.as_str()]].concat();
        fails_with(&args, None, &["unstable", "spectral radius 2.533e241"]);
    }
    let nan_rate = file("nan-rate.toml", "nan", "0.0");
    let args = [&["run", "--no-record"][..], &ss, &[nan_rate.as_str()]].concat();
    fails_with(&args, None, &["nan-rate.toml", "sample_rate_hz", "NaN"]);
}

/// `servo synth --order` outside what a controller file holds is refused before any design
/// is written; `servo frf --points` is bounded.
#[test]
fn design_options_whose_output_cannot_be_used_are_refused() {
    let out = tmp("never.toml");
    for order in ["0", "1000"] {
        fails_with(
            &[
                "synth",
                "h2",
                "--order",
                order,
                "--out",
                out.to_str().unwrap(),
            ],
            None,
            &["--order", order, "states"],
        );
        assert!(!out.exists());
    }
    let err = servo()
        .args(["frf", "--points", "100000000"])
        .output()
        .unwrap();
    assert_eq!(err.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&err.stderr).contains("2..=10000"));
}

/// The Chapter 7 PID written as a state-space controller file (its exact discrete
/// realisation) gives the same run as `--controller pid` (same seed): the `ss` path is right.
#[test]
fn state_space_file_of_the_pid_matches_the_pid() {
    let t = 1.0 / 199_600.0;
    let pid = servo_core::PidConfig::THESIS_CH7.try_build(t).unwrap();
    let (a, b, c, d) = pid.coeffs().realization();
    let row = |r: usize| format!("[{}, {}, {}]", a[(r, 0)], a[(r, 1)], a[(r, 2)]);
    let text = format!(
        "sample_rate_hz = 199600.0\na = [{}, {}, {}]\nb = [[{}], [{}], [{}]]\nc = [[{}, {}, {}]]\nd = [[{}]]\n",
        row(0), row(1), row(2), b[0], b[1], b[2], c[0], c[1], c[2], d
    );
    let ss = tmp("pid_ss.toml");
    std::fs::write(&ss, text).unwrap();
    let run = |extra: &[&str]| {
        json(
            &servo()
                .args(["run", "--json", "-q", "--no-record", "--duration", "0.3"])
                .args(extra)
                .output()
                .unwrap(),
        )
    };
    let as_pid = run(&[]);
    let as_ss = run(&["--controller", "ss", "--ss-file", ss.to_str().unwrap()]);
    assert!(as_ss["meta"]["controller"]
        .as_str()
        .unwrap()
        .contains("3 states"));
    let (p, s) = (
        nm(&as_pid, "following_error_m"),
        nm(&as_ss, "following_error_m"),
    );
    assert!((p - s).abs() < 1e-4 * p, "pid {p} nm vs ss {s} nm");
}

#[test]
fn config_dump_shows_every_number() {
    let out = servo()
        .args(["config", "--dump", "--mass", "heavy"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    for needle in [
        "servo_rate_hz = 199600.0",
        "m2_kg = 0.17",
        "kp = 1.65",
        "delay_s = 0.000003159",
        "sensor_v_per_rt_hz",
    ] {
        assert!(text.contains(needle), "{needle} missing");
    }
    let v: serde_json::Value =
        serde_json::from_slice(&servo().args(["config", "--json"]).output().unwrap().stdout)
            .unwrap();
    assert_eq!(v["plant"]["actuator"]["kt_n_per_a"], 3.6658);
    let _ = Path::new(".");
}

/// `servo budget` writes data and pictures, and its totals are the root-sum-square of the
/// per-source contributions (independent sources, eq 5-15).
#[test]
fn budget_writes_data_and_plots() {
    let dir = tmp("budget");
    let out = servo()
        .args(["budget", "--mass", "heavy", "--points", "200", "--out-dir"])
        .arg(&dir)
        .output()
        .unwrap();
    succeeded(&out);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("thesis §5.7.2") && text.contains("total"),
        "{text}"
    );
    let b: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("budget.json")).unwrap()).unwrap();
    let sum: f64 = b["contributions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["following_rms_m"].as_f64().unwrap().powi(2))
        .sum();
    assert!((sum.sqrt() / b["following_rms_m"].as_f64().unwrap() - 1.0).abs() < 1e-12);
    // What it was made for: the heavy stage at the default rate, the default PID.
    assert_eq!(b["made_for"]["stage"], "heavy");
    assert_eq!(b["made_for"]["servo_rate_hz"], 199_600.0);
    assert!(
        b["controller"].as_str().unwrap().starts_with("PID"),
        "{}",
        b["controller"]
    );
    let csv = std::fs::read_to_string(dir.join("budget.csv")).unwrap();
    assert!(csv.starts_with("freq_hz,following_psd_sensor_m2_per_hz"));
    assert_eq!(csv.lines().count(), 201);
    assert!(dir.join("budget_psd.png").exists() && dir.join("budget_cas.svg").exists());
    // The sources by name, the margins of the loop.
    assert_eq!(
        b["following_psd_m2_per_hz"]["sensor"]
            .as_array()
            .unwrap()
            .len(),
        200
    );
    assert!(
        b["margins"]["phase_margin_deg"].as_f64().unwrap() > 20.0,
        "{}",
        b["margins"]
    );
}

#[test]
fn machining_writes_the_recording_the_form_report_and_pictures() {
    let dir = tmp("machine");
    let mcap = tmp("machine.mcap");
    let out = servo()
        .args([
            "machine",
            "--json",
            "--quiet",
            "--radius-range",
            "24.9975e-3:25e-3",
        ])
        .args(["--feedforward", "zpetc", "--out"])
        .arg(&mcap)
        .arg("--out-dir")
        .arg(&dir)
        .output()
        .unwrap();
    let report = json(&out);
    // Half a revolution of the Table 8-5 grid at the part edge with ZPETC: the form is true
    // to a few nm (the quantitative claims are in runner's machining tests).
    assert!(
        report["form_error_m"]["rms"].as_f64().unwrap() < 5e-9,
        "{report}"
    );
    for f in ["machine.json", "form_map.csv", "trajectory.csv"] {
        assert!(dir.join(f).exists(), "{f}");
    }
    // The form report recomputed from the file equals the live one.
    let back = json(
        &servo()
            .arg("inspect")
            .arg(&mcap)
            .arg("--json")
            .output()
            .unwrap(),
    );
    assert_eq!(back["summary"]["meta"]["scenario"], "machine");
    assert_eq!(back["form"], report);
    fails_with(
        &["machine", "--no-record", "--radius-range", "25e-3:24e-3"],
        None,
        &["--radius-range", "inner:outer"],
    );
    fails_with(
        &[
            "machine",
            "--no-record",
            "--surface",
            "image",
            "--image",
            "/nonexistent.png",
        ],
        None,
        &["scenario.surface.path", "/nonexistent.png", "PNG"],
    );
}

#[test]
fn spindle_errors_recovers_the_simulated_spindle() {
    let dir = tmp("spindle");
    let out = servo()
        .args(["spindle-errors", "--json", "--per-rev", "2048", "--out-dir"])
        .arg(&dir)
        .output()
        .unwrap();
    let r = json(&out);
    let synth = r["synthesised"]["artefact_rms_error_m"].as_f64().unwrap();
    assert!(synth < 0.01 * r["truth_rms_m"][0].as_f64().unwrap(), "{r}");
    assert!(dir.join("harmonic_weighting.csv").exists());
}

/// `servo frf --amplitude` sets the stepped-sine excitation: below the 150 Hz knee it is the
/// amplitude given, above it rises as (f/150)² (the stage falls as 1/f²); the measured open
/// loop (linear) is the same as with the default 2 mV, within the noise.
#[test]
fn frf_amplitude_sets_the_excitation() {
    let run = |amplitude: Option<&str>| {
        let mut c = servo();
        c.args([
            "frf", "--json", "--from", "20", "--to", "600", "--points", "2",
        ]);
        if let Some(a) = amplitude {
            c.args(["--amplitude", a]);
        }
        let dir = tmp(&format!("frf-amp-{}", amplitude.unwrap_or("default")));
        json(&c.arg("--out-dir").arg(&dir).output().unwrap())
    };
    let given = run(Some("0.004"));
    let default = run(None);
    let excitation = |v: &serde_json::Value, i: usize| v[i]["excitation_v"].as_f64().unwrap();
    assert_eq!(excitation(&given, 0), 0.004);
    assert_eq!(excitation(&default, 0), 0.002);
    assert!((excitation(&given, 1) / (0.004 * (600.0f64 / 150.0).powi(2)) - 1.0).abs() < 1e-12);
    for i in 0..2 {
        let (a, b) = (
            given[i]["magnitude_m_per_v"].as_f64().unwrap(),
            default[i]["magnitude_m_per_v"].as_f64().unwrap(),
        );
        assert!((a / b - 1.0).abs() < 0.01, "|H| {a} vs {b} at point {i}");
    }
}

/// A flag a command does not use is a usage error (exit 2, clap names it), not silently
/// ignored: the analyses take no scenario or run length, `servo frf` has one `--amplitude`.
#[test]
fn flags_a_command_does_not_use_are_rejected() {
    for args in [
        &["budget", "--scenario", "sine"][..],
        &["budget", "--duration", "5"],
        &["stiffness", "--controller", "pid"],
        &["tune", "--feedforward", "zpetc"],
        &["synth", "h2", "--seed", "3"],
        &["frf", "--frequency", "100"],
        &["identify", "x.csv", "--rpm", "60"],
        &["machine", "--scenario", "hold"],
    ] {
        let out = servo().args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?} was accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("unexpected argument"), "{args:?}: {err}");
    }
}

/// The book's thesis map holds what `servo thesis` computes now (regenerate it with
/// `servo thesis` and paste `thesis/thesis.md` when the model changes).
#[test]
fn thesis_map_table_is_the_commands_output() {
    let dir = tmp("thesis");
    let out = servo()
        .args(["thesis", "--out-dir"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let table = std::fs::read_to_string(dir.join("thesis.md")).unwrap();
    let page = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../docs/src/thesis-map.md"
    ))
    .unwrap();
    assert!(
        page.contains(&table),
        "docs/src/thesis-map.md's thesis table differs from `servo thesis`:\n{table}"
    );
}
