//! One stage tick through the FMI boundary as a compiled master calls it (set the DAC command,
//! step one tick, get the two readings) against the simulator's own tick in the same run: the
//! ratio is what the FMI boundary costs a C or Rust master (FMPy's Python wrappers add their
//! own, `scripts/fmu_speed.py`).

#![allow(missing_docs)] // criterion_group! generates undocumented items.

use criterion::{criterion_group, criterion_main, Criterion};
use daq_io::Backend;
use fmu::unit::stage_files;
use fmu::variables::stage;
use fmu::FmiVersion;
use fts_fmu::fmi2::*;
use fts_fmu::fmi3::*;
use plant_sim::cutting::CuttingProfile;
use plant_sim::{PlantParams, Simulator};
use std::ffi::c_void;
use std::hint::black_box;

#[path = "../tests/support.rs"]
mod support;

/// A started stage unit of `version` whose resources are in `dir`.
fn unit(dir: &std::path::Path, version: FmiVersion) -> *mut c_void {
    let token = support::resources(dir, &stage_files(version, &PlantParams::default(), 1, 1.0));
    // SAFETY: a live instance, started once.
    unsafe {
        match version {
            FmiVersion::V2 => {
                let c = support::fmi2_unit(dir, &token);
                assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), 0);
                assert_eq!(fmi2EnterInitializationMode(c), 0);
                assert_eq!(fmi2ExitInitializationMode(c), 0);
                c
            }
            FmiVersion::V3 => {
                let c = support::fmi3_unit(dir, &token, None);
                assert_eq!(
                    fmi3EnterInitializationMode(c, false, 0.0, 0.0, false, 0.0),
                    0
                );
                assert_eq!(fmi3ExitInitializationMode(c), 0);
                c
            }
        }
    }
}

fn stage_tick(c: &mut Criterion) {
    let plant = PlantParams::default();
    let h = plant.period_s();
    let mut group = c.benchmark_group("stage_tick");
    let mut sim = Simulator::new(&plant, 1, &CuttingProfile::None).unwrap();
    sim.initial();
    group.bench_function("simulator", |b| {
        b.iter(|| {
            let s = sim.step_sensor(black_box(1e-3), 0.0);
            black_box((s.gap_v, s.accel_v))
        })
    });
    let dir = tempfile::tempdir().unwrap();
    let (input, out) = ([stage::DAC_V], [stage::GAP_V, stage::ACCEL_V]);
    let c2 = unit(dir.path(), FmiVersion::V2);
    let mut k = 0u64;
    group.bench_function("fmi2", |b| {
        b.iter(|| {
            let mut r = [0.0; 2];
            // SAFETY: a live instance; arrays of the lengths given.
            unsafe {
                fmi2SetReal(c2, input.as_ptr(), 1, &black_box(1e-3));
                fmi2DoStep(c2, k as f64 * h, h, 1);
                fmi2GetReal(c2, out.as_ptr(), 2, r.as_mut_ptr());
            }
            k += 1;
            black_box(r)
        })
    });
    let c3 = unit(dir.path(), FmiVersion::V3);
    let mut k = 0u64;
    group.bench_function("fmi3", |b| {
        b.iter(|| {
            let mut r = [0.0; 2];
            let (mut e, mut t, mut x, mut last) = (false, false, false, 0.0);
            // SAFETY: a live instance; arrays of the lengths given.
            unsafe {
                fmi3SetFloat64(c3, input.as_ptr(), 1, &black_box(1e-3), 1);
                fmi3DoStep(c3, k as f64 * h, h, true, &mut e, &mut t, &mut x, &mut last);
                fmi3GetFloat64(c3, out.as_ptr(), 2, r.as_mut_ptr(), 2);
            }
            k += 1;
            black_box(r)
        })
    });
    group.finish();
    // SAFETY: live instances, freed once.
    unsafe {
        fmi2FreeInstance(c2);
        fmi3FreeInstance(c3);
    }
}

criterion_group!(benches, stage_tick);
criterion_main!(benches);
