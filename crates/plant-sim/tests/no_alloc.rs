//! `Simulator::step` allocates nothing (counting allocator over 100 000 steps, all noise on).

use densa_alloc::{is_active, measure, CountingAllocator};
use plant_sim::cutting::CuttingProfile;
use plant_sim::{PlantParams, Simulator};

/// Counts per thread: the test harness's own threads never enter a measurement.
#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator::system();

#[test]
fn step_allocates_nothing() {
    let cut = CuttingProfile::IntermittentCut {
        force_n: 1.0,
        spindle_rpm: 250.0,
    };
    let mut sim = Simulator::new(&PlantParams::heavy(), 1, &cut).unwrap();
    assert!(is_active(), "the counting allocator must be installed");
    let (acc, stats) = measure(|| {
        let mut acc = 0.0;
        for k in 0..100_000 {
            let (s, t) = sim.step(libm::sin(k as f64 * 1e-3) * 1e-3);
            acc += s.gap_v + t.tool_m;
        }
        acc
    });
    assert!(acc.is_finite());
    assert_eq!((stats.allocs, stats.reallocs), (0, 0), "{stats:?}");
}
