//! `servo study`: each point is what `servo synth h2` (or `servo tune`) and `servo budget` give
//! for the same plant; shards merged equal the single run byte for byte; bad input is refused
//! with its file, key and allowed range.

use crate::common;

use common::{json, servo, succeeded, tmp};
use std::path::Path;

const STUDY: &str =
    "[study]\nname = \"check\"\ncontrollers = [\"h2\", \"h2-bandwidth\", \"pid\"]\n\
    bandwidth_hz = 1000.0\n\
    [[study.parameter]]\nkey = \"plant.stage.c2_n_s_per_m\"\nvalues = [2.28, 10.0]\n";

fn rows(dir: &Path) -> Vec<std::collections::HashMap<String, String>> {
    let text = std::fs::read_to_string(dir.join("study.csv")).unwrap();
    let mut lines = text.lines();
    let head: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    lines
        .map(|l| {
            head.iter()
                .cloned()
                .zip(l.split(',').map(String::from))
                .collect()
        })
        .collect()
}

#[test]
fn each_point_is_what_synth_or_tune_and_budget_give() {
    let file = tmp("check.toml");
    std::fs::write(&file, STUDY).unwrap();
    let dir = tmp("check");
    let out = json(
        &servo()
            .arg("study")
            .arg(&file)
            .arg("--out-dir")
            .arg(&dir)
            .arg("--json")
            .output()
            .unwrap(),
    );
    assert_eq!(out["points"], 6);
    for row in rows(&dir) {
        assert_eq!(row["status"], "ok", "{row:?}");
        let c2 = &row["plant.stage.c2_n_s_per_m"];
        let config = tmp(&format!("plant-{}-{c2}.toml", row["index"]));
        std::fs::write(&config, format!("[plant.stage]\nc2_n_s_per_m = {c2}\n")).unwrap();
        let controller = tmp(&format!("controller-{}.toml", row["index"]));
        let made = match row["controller"].as_str() {
            "pid" => servo()
                .args(["tune", "--bandwidth-hz", "1000", "-c"])
                .arg(&config)
                .arg("--out")
                .arg(&controller)
                .output()
                .unwrap(),
            _ => servo()
                .args([
                    "synth",
                    "h2",
                    "--sensor-noise-scale",
                    &row["design_value"],
                    "-c",
                ])
                .arg(&config)
                .arg("--out")
                .arg(&controller)
                .output()
                .unwrap(),
        };
        succeeded(&made);
        let mut budget = servo();
        budget
            .arg("budget")
            .arg("--json")
            .arg("--out-dir")
            .arg(tmp("budget"));
        if row["controller"] == "pid" {
            budget.arg("-c").arg(&controller);
        } else {
            budget
                .arg("-c")
                .arg(&config)
                .args(["--controller", "ss", "--ss-file"])
                .arg(&controller);
        }
        let b = &json(&budget.output().unwrap())["budget"];
        for key in ["bandwidth_hz", "following_rms_m", "true_rms_m"] {
            let study: f64 = row[key].parse().unwrap();
            assert_eq!(study, b[key].as_f64().unwrap(), "{key} of {row:?}");
        }
    }
    // The h2-bandwidth points meet their bandwidth; the plots and columnar table are there.
    for row in rows(&dir)
        .iter()
        .filter(|r| r["controller"] == "h2-bandwidth")
    {
        let bw: f64 = row["bandwidth_hz"].parse().unwrap();
        assert!((bw / 1000.0 - 1.0).abs() <= 2.1e-3, "{bw}");
    }
    for name in [
        "study.parquet",
        "study.json",
        "study.png",
        "sensitivity.png",
        "sensitivity.csv",
    ] {
        assert!(dir.join(name).is_file(), "{name}");
    }
}

#[test]
fn shards_merged_equal_a_single_run_and_bad_input_is_named() {
    let file = tmp("grid.toml");
    std::fs::write(
        &file,
        "[study]\nname = \"grid\"\n\
         [[study.parameter]]\nkey = \"plant.stage.k2_n_per_m\"\nfrom = 1e4\nto = 1e5\npoints = 2\nspacing = \"log\"\n\
         [[study.parameter]]\nkey = \"plant.stage.c2_n_s_per_m\"\nvalues = [1.0, 30.0]\n",
    )
    .unwrap();
    let single = tmp("single");
    succeeded(
        &servo()
            .arg("study")
            .arg(&file)
            .arg("--out-dir")
            .arg(&single)
            .args(["--jobs", "1"])
            .output()
            .unwrap(),
    );
    let shards = tmp("shards");
    for i in 1..=3 {
        let out = servo()
            .arg("study")
            .arg(&file)
            .arg("--out-dir")
            .arg(&shards)
            .args(["--shard", &format!("{i}/3")])
            .output()
            .unwrap();
        succeeded(&out);
        assert!(String::from_utf8_lossy(&out.stdout).contains("servo study merge"));
    }
    let merged = tmp("merged");
    succeeded(
        &servo()
            .args(["study", "merge"])
            .arg(&shards)
            .arg("--out-dir")
            .arg(&merged)
            .output()
            .unwrap(),
    );
    let read = |d: &Path, f: &str| std::fs::read(d.join(f)).unwrap();
    assert_eq!(read(&single, "study.csv"), read(&merged, "study.csv"));
    assert_eq!(
        read(&single, "sensitivity.csv"),
        read(&merged, "sensitivity.csv")
    );
    assert!(single.join("map-h2.png").is_file());

    // Bad input: an unknown key, a log range through zero, a shard out of range.
    let cases = [
        (
            "key = \"plant.stage.k9\"\nvalues = [1.0]",
            "study.parameter[0].key",
        ),
        (
            "key = \"plant.stage.k2_n_per_m\"\nfrom = 0.0\nto = 1.0\npoints = 2\nspacing = \"log\"",
            "> 0 with log spacing",
        ),
    ];
    for (i, (param, expect)) in cases.iter().enumerate() {
        let bad = tmp(&format!("bad{i}.toml"));
        std::fs::write(&bad, format!("[study]\n[[study.parameter]]\n{param}\n")).unwrap();
        let out = servo()
            .arg("study")
            .arg(&bad)
            .arg("--out-dir")
            .arg(tmp("never"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(expect) && err.contains(&*bad.to_string_lossy()),
            "{err}"
        );
    }
    let out = servo()
        .arg("study")
        .arg(&file)
        .args(["--shard", "4/3"])
        .arg("--out-dir")
        .arg(tmp("never"))
        .output()
        .unwrap();
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("--shard"));
    assert!(!tmp("never").exists(), "a refused study writes nothing");
}
