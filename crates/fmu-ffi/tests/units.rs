//! The stage unit with a force equals the simulator's own step with that force, bit for bit;
//! the controller unit ticks as `Servo` does, holds its command until this point's readings
//! arrive and refuses readings changed after its tick; resources of another description are
//! refused.

use crate::support::{fmi2_unit, fmi3_unit, resources};
use daq_io::Backend;
use fmu::unit::{controller_files, stage_files};
use fmu::variables::{controller, stage};
use fmu::FmiVersion;
use fts_fmu::fmi2::*;
use fts_fmu::fmi3::*;
use plant_sim::cutting::CuttingProfile;
use plant_sim::{PlantParams, Simulator};
use rand::{Rng, SeedableRng};
use std::ffi::{c_void, CString};

const OK: i32 = 0;
const ERROR: i32 = 3;

/// FMI 2 calls on a unit (each returns its status).
struct Fmi2(*mut c_void);

impl Fmi2 {
    fn start(&self) {
        // SAFETY: a live instance.
        unsafe {
            assert_eq!(fmi2SetupExperiment(self.0, 0, 0.0, 0.0, 0, 0.0), OK);
            assert_eq!(fmi2EnterInitializationMode(self.0), OK);
            assert_eq!(fmi2ExitInitializationMode(self.0), OK);
        }
    }
    fn set(&self, vr: &[u32], x: &[f64]) -> i32 {
        // SAFETY: a live instance; arrays of equal length.
        unsafe { fmi2SetReal(self.0, vr.as_ptr(), vr.len(), x.as_ptr()) }
    }
    fn get(&self, vr: &[u32]) -> Vec<f64> {
        let mut x = vec![0.0; vr.len()];
        // SAFETY: a live instance; arrays of equal length.
        let status = unsafe { fmi2GetReal(self.0, vr.as_ptr(), vr.len(), x.as_mut_ptr()) };
        assert_eq!(status, OK);
        x
    }
    fn step(&self, t: f64, h: f64) -> i32 {
        // SAFETY: a live instance.
        unsafe { fmi2DoStep(self.0, t, h, 1) }
    }
}

impl Drop for Fmi2 {
    fn drop(&mut self) {
        // SAFETY: a live instance, freed once.
        unsafe { fmi2FreeInstance(self.0) }
    }
}

#[test]
fn the_stage_unit_with_a_force_steps_as_the_simulator_does_bit_for_bit() {
    let plant = PlantParams::heavy();
    let seed = 9;
    let files = stage_files(FmiVersion::V3, &plant, seed, 0.1);
    let dir = tempfile::tempdir().unwrap();
    let token = resources(dir.path(), &files);
    let unit = fmi3_unit(dir.path(), &token, None);
    assert!(!unit.is_null());
    let mut sim = Simulator::new(&plant, seed, &CuttingProfile::None).unwrap();
    let first = sim.initial();
    let period = plant.period_s();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(3);
    let out = [stage::GAP_V, stage::ACCEL_V, stage::TOOL_POSITION_M];
    let inputs = [stage::DAC_V, stage::FORCE_N];
    let mut got = [0.0; 3];
    // SAFETY: a live instance; arrays of the lengths given.
    unsafe {
        assert_eq!(
            fmi3EnterInitializationMode(unit, false, 0.0, 0.0, false, 0.0),
            OK
        );
        assert_eq!(fmi3ExitInitializationMode(unit), OK);
        assert_eq!(
            fmi3GetFloat64(unit, out.as_ptr(), 3, got.as_mut_ptr(), 3),
            OK
        );
        assert_eq!([got[0], got[1]], [first.gap_v, first.accel_v]);
        let mut t = 0.0;
        for k in 0..4000 {
            let u = [rng.random_range(-1.0..1.0), rng.random_range(-2.0..2.0)];
            assert_eq!(fmi3SetFloat64(unit, inputs.as_ptr(), 2, u.as_ptr(), 2), OK);
            let (mut a, mut b, mut c, mut last) = (true, true, true, 0.0);
            let s = fmi3DoStep(unit, t, period, true, &mut a, &mut b, &mut c, &mut last);
            assert_eq!((s, a, b, c), (OK, false, false, false));
            t += period;
            let want = sim.step_sensor(u[0], u[1]);
            let truth = sim.truth().unwrap();
            assert_eq!(
                fmi3GetFloat64(unit, out.as_ptr(), 3, got.as_mut_ptr(), 3),
                OK
            );
            assert_eq!(got, [want.gap_v, want.accel_v, truth.tool_m], "tick {k}");
        }
        fmi3FreeInstance(unit);
    }
}

#[test]
fn the_controller_unit_ticks_as_servo_holds_its_command_and_refuses_late_readings() {
    let plan = runner::Plan::new(&run_config::Loaded::default()).unwrap();
    let (deployment, text) = runner::deploy::deployment_file(&plan).unwrap();
    let files = controller_files(FmiVersion::V2, &text, deployment.period_s(), 0.1);
    let dir = tempfile::tempdir().unwrap();
    let token = resources(dir.path(), &files);
    let unit = Fmi2(fmi2_unit(dir.path(), &token));
    assert!(!unit.0.is_null());
    unit.start();
    let mut servo = servo_runtime::Servo::new(&deployment).unwrap();
    let period = deployment.period_s();
    let readings = [controller::GAP_V, controller::ACCEL_V];
    let mut held = 0.0;
    for k in 0..200u64 {
        // Before this point's readings: the command held over the last step.
        assert_eq!(unit.get(&[controller::DAC_V]), [held]);
        let r = [
            1e-3 * libm::sin(k as f64 * 0.37),
            2e-3 * libm::cos(k as f64 * 0.11),
        ];
        assert_eq!(unit.set(&readings, &r), OK);
        let got = unit.get(&[controller::DAC_V, controller::FOLLOWING_ERROR_M]);
        let sample = daq_io::Sensor {
            seq: k,
            time_s: k as f64 * period,
            gap_v: r[0],
            accel_v: r[1],
            run_id: 1,
            ..Default::default()
        };
        let want = servo.tick(&sample);
        let t = servo.telemetry().unwrap();
        assert_eq!(got, [want.dac_v, t.following_error_m], "tick {k}");
        // The same readings again are no change; others after the tick are refused.
        assert_eq!(unit.set(&readings, &r), OK);
        assert_eq!(unit.set(&readings, &[r[0] + 1e-6, r[1]]), ERROR);
        held = want.dac_v;
        assert_eq!(unit.step(k as f64 * period, period), OK);
    }
    // One tick per step: two are refused, as is a step beside the unit's time.
    assert_eq!(unit.step(200.0 * period, 2.0 * period), ERROR);
    assert_eq!(unit.step(100.0 * period, period), ERROR);
}

#[test]
fn resources_of_another_description_are_refused() {
    let files = stage_files(FmiVersion::V2, &PlantParams::default(), 1, 0.1);
    let dir = tempfile::tempdir().unwrap();
    let token = resources(dir.path(), &files);
    let other = fmu::token(b"kind = \"stage\"\n", None);
    assert_ne!(token, other);
    assert!(fmi2_unit(dir.path(), &other).is_null());
    assert!(fmi3_unit(dir.path(), &other, None).is_null());
    let unit = Fmi2(fmi2_unit(dir.path(), &token));
    assert!(!unit.0.is_null());
}

/// The messages an FMI 3 unit logged (tests in this file that log run one at a time through it).
static LOGGED: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());

extern "C" fn remember(
    _env: *mut c_void,
    _status: i32,
    _category: *const std::ffi::c_char,
    message: *const std::ffi::c_char,
) {
    // SAFETY: the unit passes a NUL-terminated message.
    let text = unsafe { std::ffi::CStr::from_ptr(message) };
    LOGGED
        .lock()
        .unwrap()
        .push(text.to_string_lossy().into_owned());
}

#[test]
fn a_deployment_the_runtime_refuses_is_refused_at_instantiation_with_its_message() {
    let plan = runner::Plan::new(&run_config::Loaded::default()).unwrap();
    let (deployment, text) = runner::deploy::deployment_file(&plan).unwrap();
    let line = text
        .lines()
        .find(|l| l.starts_with("following_error_m = "))
        .unwrap();
    let bad = text.replace(line, "following_error_m = -1.0");
    let files = controller_files(FmiVersion::V3, &bad, deployment.period_s(), 0.1);
    let dir = tempfile::tempdir().unwrap();
    let token = resources(dir.path(), &files);
    let unit = fmi3_unit(dir.path(), &token, Some(remember));
    assert!(unit.is_null());
    let logged = LOGGED.lock().unwrap().join("\n");
    assert!(
        logged.contains("protection.following_error_m") && logged.contains("deployment.toml"),
        "{logged}"
    );
}

#[test]
fn a_controller_built_early_is_checked_again_when_the_stages_plant_is_given() {
    let heavy = run_config::Loaded {
        config: run_config::RunConfig {
            plant: PlantParams::heavy(),
            ..Default::default()
        },
        ..Default::default()
    };
    let plan = runner::Plan::new(&heavy).unwrap();
    let (deployment, text) = runner::deploy::deployment_file(&plan).unwrap();
    let files = controller_files(FmiVersion::V2, &text, deployment.period_s(), 0.1);
    let dir = tempfile::tempdir().unwrap();
    let token = resources(dir.path(), &files);
    let unit = Fmi2(fmi2_unit(dir.path(), &token));
    let light = run_config::made_for_plant(&PlantParams::default()).plant_sha256;
    let light = CString::new(light).unwrap();
    // SAFETY: a live instance; one reference, one string.
    unsafe {
        assert_eq!(fmi2SetupExperiment(unit.0, 0, 0.0, 0.0, 0, 0.0), OK);
        assert_eq!(fmi2EnterInitializationMode(unit.0), OK);
        // The command read during initialisation builds the loop early ...
        assert_eq!(unit.set(&[controller::GAP_V], &[1e-3]), OK);
        assert_eq!(unit.get(&[controller::DAC_V]).len(), 1);
        // ... and the light stage's plant given afterwards is still checked.
        let vr = [controller::PLANT_SHA256];
        assert_eq!(fmi2SetString(unit.0, vr.as_ptr(), 1, &light.as_ptr()), OK);
        assert_eq!(fmi2ExitInitializationMode(unit.0), ERROR);
    }
}
