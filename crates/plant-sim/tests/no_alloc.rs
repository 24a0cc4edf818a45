//! `Simulator::step` allocates nothing (counting allocator over 100 000 steps, all noise on).

use plant_sim::cutting::CuttingProfile;
use plant_sim::{PlantParams, Simulator};
use stats_alloc::{Region, StatsAlloc, INSTRUMENTED_SYSTEM};
use std::alloc::System;

#[global_allocator]
static GLOBAL: &StatsAlloc<System> = &INSTRUMENTED_SYSTEM;

#[test]
fn step_allocates_nothing() {
    let cut = CuttingProfile::IntermittentCut {
        force_n: 1.0,
        spindle_rpm: 250.0,
    };
    let mut sim = Simulator::new(&PlantParams::heavy(), 1, &cut).unwrap();
    let region = Region::new(GLOBAL);
    let mut acc = 0.0;
    for k in 0..100_000 {
        let (s, t) = sim.step((k as f64 * 1e-3).sin() * 1e-3);
        acc += s.gap_v + t.tool_m;
    }
    let stats = region.change();
    assert!(acc.is_finite());
    assert_eq!(
        (stats.allocations, stats.reallocations),
        (0, 0),
        "{stats:?}"
    );
}
