//! The thesis workflow on a DAQ daemon (issue 17), one chain through shared memory: a practice
//! stage whose Table 5-2 parameters are drawn from a seed this test holds and the client never
//! sees, with a sensor-mount resonance the identification model does not contain, served by
//! `daq_io::serve` (as the `daq_daemon` example serves it). `servo frf --prefix` measures it
//! open loop, `servo identify` recovers the draw and the resonance (into the model), `servo tune`
//! designs on the identified model, `servo ctl load` deploys the design into a loop closed on
//! the daemon (`servo controller` + `servo record` on the identified model) bumplessly, and
//! `servo spectrum` of the recording agrees with the identified model's budget.

use crate::common;

use common::hil::{
    assert_bumpless, assert_swapped_in, ctl_load, ctl_stop, prefix, recorded_commands, swap_tick,
    wait_for_ticks,
};
use common::{assert_bands_agree, json, servo, spectrum, succeeded, tmp, tuned};
use daq_io::ipc::Endpoint;
use daq_io::serve::{serve, Pacing, ServeOptions};
use plant_sim::practice::{PracticeEffects, PracticeStage};
use plant_sim::PlantParams;
use std::process::Stdio;
use std::sync::atomic::AtomicUsize;

/// The seed of the draw (the test's; the client is told nothing).
const SEED: u64 = 2026;

#[test]
fn a_hidden_stage_is_measured_identified_designed_for_deployed_and_compared() {
    let p = prefix("practice");
    let plant = PlantParams::default();
    // Without the suspension drift: a stage that changes during the measurement has no one
    // drawn k2 to judge the identified one against.
    let steady = PracticeEffects {
        suspension_drift: false,
        ..Default::default()
    };
    let mut stage = PracticeStage::new(&plant, SEED, steady).unwrap();
    let truth = *stage.draw();
    let rate = plant.timing.servo_rate_hz;
    let ep = Endpoint::open(&p, "plant").unwrap();
    let daemon = std::thread::spawn(move || {
        // Longer than the measurement needs: the client's STOP ends it.
        let mut opts = ServeOptions::new((120.0 * rate) as u64, 1.0 / rate, Pacing::Lockstep);
        opts.wait_for_recorder = false;
        let report = serve(&ep, &mut stage, &opts, &AtomicUsize::new(0)).unwrap();
        (report, stage)
    });
    let dir = tmp("practice");
    let frf = dir.join("frf");
    succeeded(
        &servo()
            .args(["frf", "--prefix", &p, "--loop", "open", "--points", "80"])
            .args(["--from", "20", "--to", "10000", "--out-dir"])
            .arg(&frf)
            .output()
            .unwrap(),
    );
    let (report, stage) = daemon.join().unwrap();
    assert_eq!(report.faults, 0);
    let model = dir.join("model.toml");
    let id = json(
        &servo()
            .arg("identify")
            .arg(frf.join("frf.csv"))
            .arg("--json")
            .arg("-o")
            .arg(&model)
            .output()
            .unwrap(),
    );
    let drawn = studies::identify::table_5_2(&truth.stage);
    // The reported uncertainty bounds the draw: every parameter within 3σ (its calibration over
    // 30 stages is `studies`' `identify_coverage` test: 60–76 % within 1σ, ≥ 90 % within 2σ).
    for (i, truth) in drawn.iter().enumerate() {
        let fitted = id["fitted"][i].as_f64().unwrap();
        let sigma = id["rel_std"][i].as_f64().unwrap();
        let error = fitted / truth - 1.0;
        println!(
            "{}: {:+.3} % (1σ {:.3} %)",
            id["names"][i],
            100.0 * error,
            100.0 * sigma
        );
        assert!(
            error.abs() < 0.02,
            "{}: {fitted} vs drawn {truth}",
            id["names"][i]
        );
        assert!(
            error.abs() <= 3.0 * sigma,
            "{}: {:+.3} % is beyond 3σ ({:.3} %)",
            id["names"][i],
            100.0 * error,
            100.0 * sigma
        );
    }
    // The in-band mode and the mount: each reported as a misfit where it is, and fitted there
    // beside the stage …
    let text = std::fs::read_to_string(&model).unwrap();
    let written: toml::Table = toml::from_str(&text).unwrap();
    let modes = written["plant"]["modes"].as_array().unwrap();
    assert_eq!(modes.len(), 2, "{text}");
    // Placed by the accelerometer's FRF `servo frf` measured beside the gap's: the in-band mode
    // on the motor force (the stage's), the mount on the reading.
    for (drawn, site) in [(truth.band_hz, "force"), (truth.mount_hz, "sensor")] {
        let misfit = id["misfits"].as_array().unwrap().iter().find(|m| {
            m["from_hz"].as_f64().unwrap() <= drawn && drawn <= m["to_hz"].as_f64().unwrap()
        });
        assert!(misfit.is_some(), "{} vs {drawn} Hz", id["misfits"]);
        let off = |m: &serde_json::Value| (m["hz"].as_f64().unwrap() / drawn - 1.0).abs();
        let extra = id["extra_modes"]
            .as_array()
            .unwrap()
            .iter()
            .min_by(|a, b| off(a).total_cmp(&off(b)))
            .unwrap();
        let pole = extra["hz"].as_f64().unwrap();
        assert!(off(extra) < 0.01, "{extra} vs {drawn} Hz");
        // … and carried into the model every later step designs on.
        let written = modes.iter().find(|m| m["hz"].as_float() == Some(pole));
        assert!(written.is_some(), "{pole} Hz: {text}");
        assert_eq!(written.unwrap()["at"].as_str(), Some(site), "{text}");
    }
    // Design on the identified model.
    let model = model.to_str().unwrap();
    // The in-band stage mode (+6 dB at 1.2–2 kHz) puts the default 1 kHz out of reach under
    // the Ms, Mt bounds, as the thesis's 1.6 kHz dynamics limited its stage (§6.4.2).
    let pid = tuned(
        "practice-pid.toml",
        &["--plant", model, "--bandwidth-hz", "500"],
    );

    // Deploy: the daemon's next session, the loop closed on it by `servo controller` with its
    // default gains and recorded, both configured with the identified model; the design loaded
    // half a second in, the run stopped 10 s after the swap (the swap's tick is the operator's, so
    // the window differs from run to run: long enough that chance moves no band's RMS by more
    // than a quarter of the 10 % compared, checked below).
    let ep = Endpoint::open(&p, "plant").unwrap();
    let daemon = std::thread::spawn(move || {
        let mut stage = stage;
        let mut opts = ServeOptions::new((600.0 * rate) as u64, 1.0 / rate, Pacing::Lockstep);
        opts.wait_for_recorder = true;
        serve(&ep, &mut stage, &opts, &AtomicUsize::new(0)).unwrap()
    });
    let rec = dir.join("deployed.mcap");
    let recorder = servo()
        .args([
            "record", "-q", "--json", "--plant", model, "--prefix", &p, "--out",
        ])
        .arg(&rec)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut controller = servo()
        .args(["controller", "--plant", model, "--prefix", &p])
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    wait_for_ticks(&p, (0.5 * rate) as u64, &mut controller);
    let swap = swap_tick(&ctl_load(&p, &pid));
    wait_for_ticks(&p, swap as u64 + (10.0 * rate) as u64, &mut controller);
    ctl_stop(&p);
    assert!(controller.wait().unwrap().success());
    succeeded(&recorder.wait_with_output().unwrap());
    let report = daemon.join().unwrap();
    assert_eq!(report.faults, 0);

    let (u, _) = recorded_commands(&rec);
    assert_bumpless(&u, swap);
    // The recording keeps the loaded file: its spectrum, by default, is of the part after the
    // swap (and its settle time) against the budget of the identified model under it.
    assert_swapped_in(&rec, swap, &pid);
    let s = spectrum(&rec, &dir.join("spectrum"), &[]);
    // The swap's tick time (to rounding: the spectrum counts ticks of 1/rate).
    let swapped_at = swap as f64 / rate;
    let noted = s["swapped_at_s"][0].as_f64().unwrap();
    assert!(
        (noted - swapped_at).abs() < 1e-12,
        "{noted} vs {swapped_at}"
    );
    assert!(
        (s["from_s"].as_f64().unwrap() - (swapped_at + 0.1)).abs() < 1e-9,
        "{}",
        s["from_s"]
    );
    let loaded = s["predicted_with"].as_str().unwrap();
    assert!(
        loaded.starts_with("PID") && loaded != s["controller"],
        "{loaded}"
    );
    // Made for the identified model (the plant the tuned gains were made for, too).
    let tuned = std::fs::read_to_string(&pid).unwrap();
    let tuned_for = tuned
        .lines()
        .find_map(|l| l.strip_prefix("plant_sha256 = "))
        .unwrap()
        .trim_matches('"');
    assert_eq!(
        s["made_for"]["plant_sha256"], tuned_for,
        "{}",
        s["made_for"]
    );
    for signal in ["following_error_m", "control_v"] {
        for b in s["bands"].as_array().unwrap() {
            let chance = b["rms"][signal]["chance_percent"].as_f64().unwrap();
            assert!(
                chance <= 2.5,
                "{signal} {}: ±{chance} % by chance",
                b["from_hz"]
            );
        }
        assert_bands_agree(&s, signal, 10.0);
    }
}
