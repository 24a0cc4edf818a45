//! `servo latency` as a user runs it: the report's shape and consistency (not its speed: the
//! numbers depend on the machine), and refusals of settings the host or the ranges do not allow.

use crate::common;

use common::{as_nobody, euid, json, servo, tmp};

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
    assert_eq!(v["cpus"], serde_json::json!([0]));
    assert_eq!(v["policy"], "other");
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
    assert!(v["recommended_peer_timeout_ms"].as_f64().unwrap() * 1e6 >= 4.0 * q[5] as f64);
    // The recommended budget absorbs twice the worst stall and twice the overrun rate.
    assert!(v["recommended_overrun_burst_ms"].as_u64().unwrap() * 1_000_000 >= 2 * q[5]);
    let rate = v["recommended_overrun_rate"].as_f64().unwrap();
    assert!(
        rate >= 0.01 && rate >= 2.0 * overruns as f64 / 1000.0,
        "{rate}"
    );
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
        err.contains("CPU affinity 100000") && err.contains("this host has CPUs 0–"),
        "{err}"
    );
    let out = servo()
        .args([
            "latency",
            "--duration",
            "0.01",
            "--rt-policy",
            "fifo",
            "--rt-priority",
            "99",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("priority 99") && err.contains("1..=98"),
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

/// One core, a low FIFO priority, sleeping between ticks, a tenth of a second: what the kernel
/// then reports is what was asked (the machine is never starved: the loop sleeps).
#[test]
#[ignore = "needs root (SCHED_FIFO needs CAP_SYS_NICE): CI runs it, `-- --ignored _as_root`"]
fn a_real_time_policy_and_core_are_applied_as_asked_as_root() {
    assert_eq!(euid(), 0, "SCHED_FIFO needs CAP_SYS_NICE: run as root");
    let v = json(
        &servo()
            .args([
                "latency",
                "--json",
                "--rate-hz",
                "2000",
                "--duration",
                "0.1",
            ])
            .args(["--rt-policy", "fifo", "--rt-priority", "3", "--cpu", "0"])
            .args(["--wait", "sleep-spin", "--spin-margin-us", "100"])
            .output()
            .unwrap(),
    );
    assert_eq!(v["policy"], "fifo", "{v}");
    assert_eq!(v["priority"], 3, "{v}");
    assert_eq!(v["cpus"], serde_json::json!([0]), "{v}");
    assert_eq!(v["ticks"], 200);
}

/// An unprivileged user asking for SCHED_FIFO, for the loop qualification and for a HIL
/// process, is refused before anything runs, with what to change.
#[test]
#[ignore = "needs root (acts as another user): CI runs it, `-- --ignored _as_root`"]
fn a_host_that_refuses_real_time_gets_a_clear_error_as_root() {
    assert_eq!(euid(), 0, "acting as another user needs root");
    let exe = env!("CARGO_BIN_EXE_servo");
    for args in [
        &["latency", "--duration", "0.01", "--rt-policy", "fifo"][..],
        &[
            "plant",
            "--prefix",
            "nobody-rt",
            "--realtime",
            "--rate",
            "20000",
            "--rt-policy",
            "fifo",
            "--wait",
            "sleep-spin",
            "--spin-margin-us",
            "20",
        ][..],
    ] {
        let mut cmd = std::process::Command::new(exe);
        cmd.args(args).current_dir("/");
        let out = as_nobody(cmd);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("scheduling policy fifo priority 10")
                && err.contains("the host refused")
                && err.contains("CAP_SYS_NICE"),
            "{args:?}: {err}"
        );
    }
}

/// Two spinning real-time processes on a host without a spare CPU would starve it: refused
/// from the configuration, naming the key and what to use instead.
#[test]
fn spinning_real_time_hil_processes_that_would_starve_the_host_are_refused() {
    let out = servo()
        .args([
            "run",
            "--hil",
            "--realtime",
            "--no-record",
            "--rt-policy",
            "fifo",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("realtime.policy") && err.contains("sleep-spin"),
        "{err}"
    );
}

/// `servo latency` judges the run's loop: the default PID holding position survives what its
/// 0.5 ms peer timeout lets pass (99 ticks at 199.6 kHz), and the report says so beside the
/// host's worst stall, on this host's name and time.
#[test]
fn latency_reports_the_stall_the_loop_survives_beside_the_hosts() {
    let v = json(
        &servo()
            .args(["latency", "--json", "--duration", "0.05"])
            .output()
            .unwrap(),
    );
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap();
    assert_eq!(v["host"], host.trim());
    assert_eq!(v["survivable"]["watchdog_ticks"], 99);
    assert!(v["survivable"]["physics_ticks"].is_null(), "{v}");
    let survivable = v["survivable_stall_s"].as_f64().unwrap();
    assert!(
        (survivable - 99.0 / 199_600.0).abs() < 1e-12,
        "{survivable}"
    );
    assert!(v["loop"].as_str().unwrap().starts_with("PID"), "{v}");
    let worst = v["host_stalls"]["worst_s"].as_f64().unwrap();
    assert_eq!(
        (worst * 1e9).round(),
        v["lateness_ns"]["max"].as_f64().unwrap()
    );
    assert_eq!(v["holds"], 2.0 * worst <= survivable);
}

/// A real-time run checks the host before any process starts: with a `servo latency` result
/// whose worst stall (injected: 3.8 ms) the loop does not survive, it is refused, naming both
/// stalls and the flag that helps; a result of another host or rate is refused naming its key.
#[test]
fn a_real_time_run_on_a_host_that_stalls_too_long_is_refused_up_front() {
    let dir = tmp("qualification");
    std::fs::create_dir(&dir).unwrap();
    let mut v = json(
        &servo()
            .args(["latency", "--json", "--duration", "0.01"])
            .output()
            .unwrap(),
    );
    v["host_stalls"]["worst_s"] = serde_json::json!(3.8e-3);
    let file = dir.join("latency.json");
    std::fs::write(&file, v.to_string()).unwrap();
    let run = |extra: &[&str]| {
        servo()
            .current_dir(&dir)
            .args([
                "run",
                "--hil",
                "--realtime",
                "--no-record",
                "--qualification",
            ])
            .arg(&file)
            .args(extra)
            .output()
            .unwrap()
    };
    let out = run(&[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    for expected in [
        "this host stalled 3800.0 µs",
        "this loop survives stalls up to 496.0 µs",
        "(flag --peer-timeout-ms)",
    ] {
        assert!(err.contains(expected), "{expected:?} in {err}");
    }
    assert!(!err.contains("servo plant"), "no process started: {err}");
    let out = run(&["--controller-cpu", "0"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("cpus") && err.contains("realtime.controller_cpu"),
        "{err}"
    );
    let out = run(&["--rate", "100000"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("rate_hz") && err.contains("latency.json"),
        "{err}"
    );
    v["host"] = serde_json::json!("another-host");
    std::fs::write(&file, v.to_string()).unwrap();
    let out = run(&[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("host") && err.contains("another-host"),
        "{err}"
    );
}
