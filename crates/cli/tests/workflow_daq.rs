//! The measure → identify → design workflow on a DAQ daemon (issue 17): a practice stage whose
//! Table 5-2 parameters are drawn from a seed this test holds and the client never sees, with a
//! sensor-mount resonance the identification model does not contain, served through shared
//! memory by `daq_io::serve` (as the `daq_daemon` example serves it); `servo frf --prefix`
//! measures it, `servo identify` recovers the draw and reports the resonance, `servo tune`
//! designs on the identified model.

mod common;

use common::hil::prefix;
use common::{json, servo, succeeded, tmp, tuned};
use daq_io::ipc::Endpoint;
use daq_io::serve::{serve, Pacing, ServeOptions};
use plant_sim::practice::PracticeStage;
use plant_sim::PlantParams;
use std::sync::atomic::AtomicUsize;

/// The seed of the draw (the test's; the client is told nothing).
const SEED: u64 = 2026;

#[test]
fn a_hidden_stage_is_identified_through_shared_memory_and_its_resonance_reported() {
    let p = prefix("practice");
    let plant = PlantParams::default();
    let mut stage = PracticeStage::new(&plant, SEED).unwrap();
    let truth = *stage.truth();
    let rate = plant.timing.servo_rate_hz;
    let ep = Endpoint::open(&p, "plant").unwrap();
    let daemon = std::thread::spawn(move || {
        // Longer than the measurement needs: the client's STOP ends it.
        let mut opts = ServeOptions::new((120.0 * rate) as u64, 1.0 / rate, Pacing::Lockstep);
        opts.wait_for_recorder = false;
        serve(&ep, &mut stage, &opts, &AtomicUsize::new(0)).unwrap()
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
    let report = daemon.join().unwrap();
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
    let mut covered = 0;
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
        covered += usize::from(error.abs() <= sigma);
    }
    assert!(covered >= 5, "1σ covers the draw for {covered} of 6");
    // The mount: reported as a misfit where it is, and fitted there beside the stage.
    let misfit = &id["misfits"][0];
    let (from, to) = (
        misfit["from_hz"].as_f64().unwrap(),
        misfit["to_hz"].as_f64().unwrap(),
    );
    assert!(
        from <= truth.mount_hz && truth.mount_hz <= to,
        "{misfit} vs {} Hz",
        truth.mount_hz
    );
    let extra = &id["extra_resonance"];
    let pole = extra["pole_hz"].as_f64().unwrap();
    assert!(
        (pole / truth.mount_hz - 1.0).abs() < 0.01,
        "{extra} vs {} Hz",
        truth.mount_hz
    );
    let text = std::fs::read_to_string(&model).unwrap();
    assert!(text.contains("NOT in this model"), "{text}");
    // Design on the identified model; the gains run on it.
    let pid = tuned("practice-pid.toml", &["--plant", model.to_str().unwrap()]);
    succeeded(
        &servo()
            .args(["run", "--no-record", "-q", "--duration", "0.05", "-c"])
            .arg(&pid)
            .output()
            .unwrap(),
    );
}
