//! `servo frf --prefix` (issue 17): the FRF measured through the transport on a plant serving
//! a prefix — here the simulator process — with this process as the controller injecting the
//! excitation; a plant that ends early or a clip stops the measurement, the plant at 0 V.

use crate::common;

use common::hil::prefix;
use common::{servo, succeeded, tmp};
use std::process::{Child, Stdio};

/// `servo plant` serving `p` for `duration_s` without a recorder, plus `extra` flags.
fn plant(p: &str, duration_s: &str, extra: &[&str]) -> Child {
    servo()
        .args([
            "plant",
            "--no-recorder",
            "--prefix",
            p,
            "--duration",
            duration_s,
        ])
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn frf(extra: &[&str], out_dir: &str) -> std::process::Output {
    servo()
        .args([
            "frf", "--json", "--points", "4", "--from", "100", "--to", "3000",
        ])
        .arg("--out-dir")
        .arg(tmp(out_dir))
        .args(extra)
        .output()
        .unwrap()
}

/// The simulator process computes the ticks the in-process simulator does (same seed), and
/// the transport pairs excitation and reading as the in-process rig does: the points are
/// equal to the last bit, open and closed loop.
#[test]
fn through_the_transport_the_frf_equals_the_in_process_one_bit_for_bit() {
    for which in ["open", "closed"] {
        let p = prefix(&format!("frf-{which}"));
        let mut server = plant(&p, "5", &[]);
        let remote = frf(
            &["--loop", which, "--prefix", &p],
            &format!("remote-{which}"),
        );
        succeeded(&remote);
        let status = server.wait().unwrap();
        assert!(
            status.success(),
            "the plant ended with {status} after the STOP"
        );
        let local = frf(&["--loop", which], &format!("local-{which}"));
        succeeded(&local);
        assert_eq!(remote.stdout, local.stdout, "{which} loop");
        let csv = std::fs::read_to_string(tmp(&format!("remote-{which}")).join("frf.csv")).unwrap();
        assert!(
            csv.contains(&format!("measured on the plant serving fts-servo/{p}")),
            "{csv}"
        );
    }
}

#[test]
fn a_plant_that_ends_first_is_named_with_the_duration_it_needs() {
    let p = prefix("frf-short");
    let mut server = plant(&p, "0.2", &[]);
    let out = frf(&["--prefix", &p], "remote-short");
    let e = String::from_utf8_lossy(&out.stderr);
    assert_ne!(out.status.code(), Some(0), "{e}");
    assert!(
        e.contains("ended its run") && e.contains("--duration"),
        "{e}"
    );
    assert!(e.contains("s of plant time"), "{e}");
    server.wait().unwrap();
}

/// 1 V at the 82 Hz suspension resonance (Q ≈ 18) drives the gap past the ADC range: the
/// measurement stops there, the plant is put back to 0 V and its run closed.
#[test]
fn a_clip_aborts_to_zero_volts_and_closes_the_run() {
    let p = prefix("frf-clip");
    let mut server = plant(&p, "10", &[]);
    let out = servo()
        .args([
            "frf",
            "--points",
            "2",
            "--from",
            "82",
            "--to",
            "1000",
            "--amplitude",
            "1",
        ])
        .arg("--out-dir")
        .arg(tmp("remote-clip"))
        .args(["--prefix", &p])
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{e}");
    assert!(
        e.contains("FRF aborted at 82") && e.contains("ADC range") && e.contains("0 V"),
        "{e}"
    );
    let status = server.wait().unwrap();
    assert!(
        status.success(),
        "the plant closed the run on the STOP ({status})"
    );
}
