//! `servo latency` as a user runs it: the report's shape and consistency (not its speed: the
//! numbers depend on the machine), and refusals of settings the host or the ranges do not allow.

mod common;

use common::{json, servo};

#[test]
fn a_short_measurement_reports_consistent_statistics_and_the_readiness() {
    let v = json(
        &servo()
            .args([
                "latency",
                "--json",
                "--rate-hz",
                "20000",
                "--duration",
                "0.05",
            ])
            .args([
                "--wait",
                "sleep-spin",
                "--spin-margin-us",
                "20",
                "--cpu",
                "0",
            ])
            .output()
            .unwrap(),
    );
    assert_eq!(v["ticks"], 1000);
    assert_eq!(v["period_ns"], 50_000);
    assert_eq!(v["cpu"], 0);
    let l = &v["lateness_ns"];
    let q: Vec<u64> = ["min", "p50", "p99", "p999", "p9999", "max"]
        .iter()
        .map(|k| l[k].as_u64().unwrap())
        .collect();
    assert!(q.windows(2).all(|w| w[0] <= w[1]), "{q:?}");
    let overruns = v["overruns"].as_u64().unwrap();
    assert!(overruns <= 1000);
    assert_eq!(
        v["overrun_rate"].as_f64().unwrap(),
        overruns as f64 / 1000.0
    );
    // A stall of max ns: the recommended timeout is at least four of them.
    assert!(v["recommended_peer_timeout_ms"].as_u64().unwrap() * 1_000_000 >= 4 * q[5]);
    let names: Vec<&str> = v["readiness"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    assert_eq!(names.len(), 6, "{names:?}");
    for c in v["readiness"].as_array().unwrap() {
        assert_eq!(c["ok"].as_bool().unwrap(), c["advice"] == "", "{c}");
    }
}

#[test]
fn settings_the_host_or_the_ranges_refuse_are_clear_errors() {
    let out = servo()
        .args(["latency", "--duration", "0.01", "--cpu", "100000"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("--cpu 100000") && err.contains("this host has CPUs 0–"),
        "{err}"
    );
    for (flag, value) in [
        ("--rate-hz", "0"),
        ("--duration", "1e9"),
        ("--spin-margin-us", "-1"),
    ] {
        let out = servo()
            .args(["latency", &format!("{flag}={value}")])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{flag}: {err}");
        assert!(err.contains(flag), "{err}");
    }
}
