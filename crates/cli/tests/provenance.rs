//! Results carry what they were made for, and the commands that consume them check it
//! (issue 17): a controller file or tuned gains for another stage or rate are refused with both
//! named (`--force` runs them anyway), a suggested command reproduces the design's plant, and
//! `servo identify` refuses an FRF that is not the plant's.

use crate::common;

use common::{servo, succeeded, tmp};

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn a_controller_designed_for_the_heavy_stage_runs_only_on_it() {
    let file = tmp("h2-heavy.toml");
    let out = servo()
        .args(["synth", "h2", "--rate", "20000", "--mass", "heavy", "--out"])
        .arg(&file)
        .output()
        .unwrap();
    succeeded(&out);
    let text = String::from_utf8_lossy(&out.stdout);
    // The suggested command is complete: the same stage and rate.
    let suggestion = text.lines().find(|l| l.contains("run it:")).unwrap();
    assert!(
        suggestion.contains("--rate 20000") && suggestion.contains("--mass heavy"),
        "{suggestion}"
    );
    let saved = std::fs::read_to_string(&file).unwrap();
    assert!(
        saved.contains("[made_for]") && saved.contains("stage = \"heavy\""),
        "{saved}"
    );
    let run = |extra: &[&str]| {
        servo()
            .args(["run", "--no-record", "-q", "--duration", "0.01"])
            .args(["--controller", "ss", "--ss-file"])
            .arg(&file)
            .args(extra)
            .output()
            .unwrap()
    };
    let light = run(&["--rate", "20000"]);
    let e = stderr(&light);
    assert_eq!(light.status.code(), Some(2), "{e}");
    assert!(
        e.contains("h2-heavy.toml") && e.contains("stage heavy") && e.contains("stage light"),
        "{e}"
    );
    succeeded(&run(&["--rate", "20000", "--mass", "heavy"]));
    // --force runs it anyway (the stability check still stands guard).
    let forced = run(&["--rate", "20000", "--force"]);
    assert!(!stderr(&forced).contains("made for"), "{}", stderr(&forced));
    // At another rate, the rate is named.
    let e = stderr(&run(&["--mass", "heavy", "--rate", "19000"]));
    assert!(e.contains("20000") && e.contains("19000"), "{e}");
}

#[test]
fn tuned_gains_carry_their_plant_and_refuse_another() {
    let file = tmp("pid-heavy.toml");
    let out = servo()
        .args(["tune", "--mass", "heavy", "--out"])
        .arg(&file)
        .output()
        .unwrap();
    succeeded(&out);
    // `servo run -c pid.toml` runs the tuned gains on the stage they were tuned for.
    let dump = servo()
        .args(["config", "--dump", "-c"])
        .arg(&file)
        .output()
        .unwrap();
    succeeded(&dump);
    let heavy_m2 = format!(
        "m2_kg = {}",
        run_config::presets::StagePreset::Heavy.params().m2_kg
    );
    assert!(
        String::from_utf8_lossy(&dump.stdout).contains(&heavy_m2),
        "the fragment's plant is the heavy stage"
    );
    let run = |extra: &[&str]| {
        servo()
            .args(["run", "--no-record", "-q", "--duration", "0.01", "-c"])
            .arg(&file)
            .args(extra)
            .output()
            .unwrap()
    };
    succeeded(&run(&[]));
    let light = run(&["--mass", "light"]);
    let e = stderr(&light);
    assert_eq!(light.status.code(), Some(2), "{e}");
    assert!(
        e.contains("controller.made_for") && e.contains("stage heavy") && e.contains("stage light"),
        "{e}"
    );
    // The fragment is never silently replaced.
    let before = std::fs::read(&file).unwrap();
    let again = servo().args(["tune", "--out"]).arg(&file).output().unwrap();
    let e = stderr(&again);
    assert_eq!(again.status.code(), Some(1), "{e}");
    assert!(
        e.contains("pid-heavy.toml") && e.contains("--overwrite"),
        "{e}"
    );
    assert_eq!(std::fs::read(&file).unwrap(), before);
    let replaced = servo()
        .args(["tune", "--overwrite", "--out"])
        .arg(&file)
        .output()
        .unwrap();
    succeeded(&replaced);
    assert_ne!(
        std::fs::read(&file).unwrap(),
        before,
        "the light stage's tuning"
    );
}

#[test]
fn identify_refuses_an_frf_that_is_not_the_plant() {
    let dir = tmp("frf-closed");
    let out = servo()
        .args(["frf", "--loop", "closed", "--points", "6", "--out-dir"])
        .arg(&dir)
        .output()
        .unwrap();
    succeeded(&out);
    let csv = dir.join("frf.csv");
    let first = std::fs::read_to_string(&csv).unwrap();
    assert!(
        first.starts_with("# fts-servo frf: quantity = PS"),
        "{first}"
    );
    let id = servo().arg("identify").arg(&csv).output().unwrap();
    let e = stderr(&id);
    assert_ne!(id.status.code(), Some(0), "{e}");
    assert!(
        e.contains("frf.csv") && e.contains("quantity PS") && e.contains("loop = open"),
        "{e}"
    );
}

/// Measure → identify → tune on the identified plant → run: the FRF of the heavy stage,
/// identified from the light stage's values, gives a model file whose stage is the heavy one
/// (m1 + m2 within 1 %), which `servo tune --plant` tunes on; the gains then run on that model
/// (`-c pid.toml`, or `--plant model.toml` beside it) and are refused on another plant.
#[test]
fn an_identified_model_is_a_plant_the_other_commands_take() {
    let dir = tmp("workflow");
    let frf = dir.join("frf");
    let heavy = ["--mass", "heavy"];
    let out = servo()
        .args([
            "frf", "--loop", "open", "--points", "80", "--from", "20", "--to", "10000",
        ])
        .args(heavy)
        .arg("--out-dir")
        .arg(&frf)
        .output()
        .unwrap();
    succeeded(&out);
    let model = dir.join("model.toml");
    let out = servo()
        .arg("identify")
        .arg(frf.join("frf.csv"))
        .arg("--out")
        .arg(&model)
        .output()
        .unwrap();
    succeeded(&out);
    let text = std::fs::read_to_string(&model).unwrap();
    assert!(
        text.contains("quantity P") && text.contains("SHA-256"),
        "{text}"
    );
    let loaded = run_config::Loaded::from_file(&model).unwrap();
    let s = loaded.config.plant.stage;
    let truth = run_config::presets::StagePreset::Heavy.params();
    let moving = |s: &plant_sim::params::StageParams| s.m1_kg + s.m2_kg;
    assert!(
        (moving(&s) / moving(&truth) - 1.0).abs() < 0.01,
        "identified {} kg against {} kg",
        moving(&s),
        moving(&truth)
    );
    let pid = dir.join("pid.toml");
    let out = servo()
        .args(["tune", "--plant"])
        .arg(&model)
        .arg("--out")
        .arg(&pid)
        .output()
        .unwrap();
    succeeded(&out);
    let run = |extra: &[&str]| {
        servo()
            .args(["run", "--no-record", "-q", "--duration", "0.01", "-c"])
            .arg(&pid)
            .args(extra)
            .output()
            .unwrap()
    };
    succeeded(&run(&[]));
    succeeded(&run(&["--plant", model.to_str().unwrap()]));
    let other = run(&["--mass", "light"]);
    assert_eq!(other.status.code(), Some(2), "{}", stderr(&other));
    // A plant file and a stage preset both name the stage: refused.
    let both = run(&["--plant", model.to_str().unwrap(), "--mass", "heavy"]);
    assert_eq!(both.status.code(), Some(2), "{}", stderr(&both));
    assert!(stderr(&both).contains("--mass"), "{}", stderr(&both));
}
