//! The files a user hands a run: the run configuration, a plant, a prescription and its sag
//! grid, a controller file, a measured FRF — each read from disk by the function a run uses.

use crate::Scratch;
use run_config::{ControllerConfig, ControllerKind, Loaded};
use runner::{Plan, PlanLoop};
use servo_runtime::Servo;
use std::sync::OnceLock;

/// A run configuration (with the files it names after `#--NAME--` lines): parsed, its plan
/// built (controller designed, plant discretised, surface loaded) and its loop built.
pub fn run_config(scratch: &Scratch, data: &[u8]) -> bool {
    let path = scratch.files("run.toml", data);
    let Ok(loaded) = Loaded::from_file(&path) else {
        return false;
    };
    Plan::new(&loaded).is_ok_and(|plan| PlanLoop::new(&plan).is_ok())
}

/// A plant file (`--plant`), read and checked by building its simulator.
pub fn plant_file(scratch: &Scratch, data: &[u8]) -> bool {
    let path = scratch.file("plant.toml", data);
    run_config::read_plant_file(&path).is_ok()
}

/// A surface prescription (`surface.kind = "prescription"`), with its grid files after
/// `#--NAME--` lines; what is read is evaluated across the aperture.
pub fn prescription(scratch: &Scratch, data: &[u8]) -> bool {
    read_and_evaluate(&scratch.files("prescription.toml", data))
}

/// A sag grid (CSV in mm), read as a prescription's `[grid]` on a 0.5 mm pitch.
pub fn sag_grid(scratch: &Scratch, data: &[u8]) -> bool {
    scratch.file("grid.csv", data);
    read_and_evaluate(&scratch.file(
        "prescription.toml",
        b"aperture_radius_mm = 0.5\n[grid]\npath = \"grid.csv\"\npitch_mm = [0.5, 0.5]\n",
    ))
}

/// Reads the prescription file `path`; evaluates its sag on a 9 × 9 grid over the aperture.
fn read_and_evaluate(path: &std::path::Path) -> bool {
    let Ok(p) = run_config::read_prescription(path) else {
        return false;
    };
    let r = p.aperture_radius_m;
    for i in 0..9 {
        for j in 0..9 {
            let at = |k: i32| r * f64::from(k - 4) / 4.0;
            std::hint::black_box(p.sag(at(i), at(j)));
        }
    }
    true
}

/// A controller file (state-space matrices or a `[controller]` fragment) as a running loop
/// takes it (`Servo::load`: `servo ctl load` on an embedded loop, `fts_servo_load`) and as the
/// default run's `controller.ss_file`; a loaded controller is ticked through hostile samples.
/// Accepted when either door takes it (a fragment is no `ss_file`).
pub fn controller_file(_scratch: &Scratch, data: &[u8]) -> bool {
    static BASE: OnceLock<(Plan, String)> = OnceLock::new();
    let (base, deployment) = BASE.get_or_init(|| {
        let plan = Plan::new(&Loaded::default()).expect("the default run plans");
        let (_, text) = runner::deploy::deployment_file(&plan).expect("the default run deploys");
        (plan, text)
    });
    let mut servo = Servo::from_toml(deployment).expect("its deployment builds");
    let loaded = servo.load(data).is_ok();
    if loaded {
        crate::deployment::tick_hostile(&mut servo, base.config.controller.limit_v);
    }
    let controller = ControllerConfig {
        kind: ControllerKind::Ss,
        ss_file: Some("controller.toml".into()),
        ..ControllerConfig::default()
    };
    let planned = base
        .with_controller_file(controller, Some(data.to_vec()))
        .is_ok_and(|plan| PlanLoop::new(&plan).is_ok());
    loaded || planned
}

/// A measured FRF (CSV: frequency, magnitude and phase or real and imaginary parts), read
/// for a 199.6 kHz loop.
pub fn frf_csv(scratch: &Scratch, data: &[u8]) -> bool {
    let path = scratch.file("frf.csv", data);
    run_config::frf_file::read_frf(&path, 99_800.0).is_ok()
}
