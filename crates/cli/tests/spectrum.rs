//! `servo spectrum` (thesis §5.7.4, Fig 5-15): a recording's spectra agree with the error
//! budget of its own configuration — rebuilt from the recording alone — per decade band, and
//! a decimated recording is analysed without a comparison that aliasing would falsify.

use crate::common;

use common::{assert_bands_agree, json, servo, spectrum, succeeded, tmp, tuned};
use serde_json::Value;

#[test]
fn a_pid_run_agrees_with_its_budget_in_every_decade_band() {
    let file = tmp("pid.mcap");
    succeeded(
        &servo()
            .args(["run", "-q", "--duration", "3", "--out"])
            .arg(&file)
            .output()
            .unwrap(),
    );
    let s = spectrum(&file, &tmp("spectrum-pid"), &[]);
    std::fs::remove_file(&file).unwrap();
    assert_eq!(s["sample_rate_hz"], 199_600.0);
    assert_eq!(s["resolution_hz"], 10.0);
    // 2.9 s after the settle time, in segments of 0.1 s (19 960 samples) at 50 % overlap.
    let samples = s["samples"].as_u64().unwrap();
    assert!(samples.abs_diff(578_840) <= 1, "{samples}"); // the settle tick's stamp decides it

    assert_eq!(
        s["segments"].as_u64().unwrap(),
        (samples - 19_960) / 9_980 + 1
    );
    assert_eq!(s["made_for"]["stage"], "light");
    for signal in ["following_error_m", "true_error_m", "control_v"] {
        assert_bands_agree(&s, signal, 10.0);
    }
    // Every bin (10 Hz to Nyquist), recorded and predicted, against the budget's exact RMS
    // (discrete Lyapunov, `servo budget`): the bin-wise prediction integrates to it, and the
    // recording does too within its estimate's variance (below 10 Hz: 1–2 % of the power).
    let budget = json(
        &servo()
            .args(["budget", "--json", "--out-dir"])
            .arg(tmp("budget-pid"))
            .output()
            .unwrap(),
    );
    let bin = s["resolution_hz"].as_f64().unwrap();
    let rms = |psd: &Value| {
        (psd.as_array()
            .unwrap()
            .iter()
            .map(|d| d.as_f64().unwrap())
            .sum::<f64>()
            * bin)
            .sqrt()
    };
    for (signal, key) in [
        ("following_error_m", "following_rms_m"),
        ("true_error_m", "true_rms_m"),
    ] {
        let exact = budget["budget"][key].as_f64().unwrap();
        let predicted = rms(&s["predicted_psd"][signal]);
        let recorded = rms(&s["recorded_psd"][signal]);
        assert!(
            (predicted / exact - 1.0).abs() < 0.02,
            "{signal}: {predicted} vs {exact}"
        );
        assert!(
            (recorded / exact - 1.0).abs() < 0.05,
            "{signal}: {recorded} vs {exact}"
        );
    }
    for f in ["spectrum.csv", "spectrum.json"] {
        assert!(tmp("spectrum-pid").join(f).exists(), "{f}");
    }
}

/// An H2 controller file recorded, then deleted: the recording's embedded copy rebuilds the
/// closed loop the budget is computed on.
#[test]
fn the_prediction_comes_from_the_recording_not_from_files_on_disk() {
    let h2 = tmp("h2-spectrum.toml");
    let synth = servo()
        .args(["synth", "h2", "--rate", "20000", "--out"])
        .arg(&h2)
        .output()
        .unwrap();
    succeeded(&synth);
    // A well-posed design warns of nothing (its slowest pole, a noise filter's 1.7e-5 inside
    // the unit circle, is the plant's own and known to rounding).
    let said = String::from_utf8_lossy(&synth.stderr);
    assert!(!said.contains("warning"), "{said}");
    let file = tmp("h2.mcap");
    succeeded(
        &servo()
            .args(["run", "-q", "--duration", "2", "--rate", "20000"])
            .args(["--controller", "ss", "--ss-file"])
            .arg(&h2)
            .arg("--out")
            .arg(&file)
            .output()
            .unwrap(),
    );
    std::fs::remove_file(&h2).unwrap();
    let s = spectrum(&file, &tmp("spectrum-h2"), &[]);
    assert!(s["prediction_note"].is_null(), "{}", s["prediction_note"]);
    assert!(
        s["controller"].as_str().unwrap().contains("state space"),
        "{}",
        s["controller"]
    );
    assert_bands_agree(&s, "following_error_m", 10.0);
    assert_bands_agree(&s, "true_error_m", 10.0);
}

#[test]
fn a_decimated_recording_is_analysed_without_a_comparison_aliasing_would_falsify() {
    let file = tmp("every4.mcap");
    succeeded(
        &servo()
            .args([
                "run",
                "-q",
                "--duration",
                "1",
                "--record-every",
                "4",
                "--out",
            ])
            .arg(&file)
            .output()
            .unwrap(),
    );
    let s = spectrum(&file, &tmp("spectrum-every4"), &[]);
    assert_eq!(s["sample_rate_hz"], 49_900.0);
    assert!(s["predicted_psd"].is_null());
    let note = s["prediction_note"].as_str().unwrap();
    assert!(
        note.contains("every 4 ticks") && note.contains("--record-every 1"),
        "{note}"
    );
    let bad = servo()
        .args(["spectrum", "--resolution-hz", "0"])
        .arg(&file)
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--resolution-hz"));
}

/// A window of the run, and a prediction for another controller (after a `servo ctl load`,
/// the part after the swap against the loaded controller's budget): a window outside the run
/// is refused; the other controller's budget is that controller's, not the recorded one's.
#[test]
fn a_window_and_another_controller_are_what_the_spectrum_predicts() {
    let file = tmp("window.mcap");
    succeeded(
        &servo()
            .args(["run", "-q", "--duration", "2", "--out"])
            .arg(&file)
            .output()
            .unwrap(),
    );
    let window = spectrum(&file, &tmp("spectrum-window"), &["--from-s", "1"]);
    let samples = window["samples"].as_u64().unwrap();
    assert!(samples.abs_diff(199_600) <= 1, "{samples}");
    assert_eq!(window["from_s"], 1.0);
    let pid = tuned("spectrum-pid-1500.toml", &["--bandwidth-hz", "1500"]);
    let other = spectrum(
        &file,
        &tmp("spectrum-other"),
        &["--controller-from", pid.to_str().unwrap()],
    );
    assert_ne!(other["predicted_with"], other["controller"]);
    // In 100 Hz – 1 kHz the recorded loop's own budget matches the recording; the tuned
    // PID's (Ki 381, Kp 0.12, rejecting that band worse) predicts half as much again: the
    // budget is the other controller's.
    let own = &window["bands"][1]["rms"]["following_error_m"];
    assert!(
        own["difference_percent"].as_f64().unwrap().abs() < 10.0,
        "{own}"
    );
    let band = &other["bands"][1]["rms"]["following_error_m"];
    assert!(
        band["difference_percent"].as_f64().unwrap() < -30.0,
        "{band}"
    );
    let bad = servo()
        .arg("spectrum")
        .arg(&file)
        .args(["--from-s", "5"])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(2));
    let e = String::from_utf8_lossy(&bad.stderr);
    assert!(
        e.contains("--from-s") && e.contains("end at 2.000 s"),
        "{e}"
    );
}
