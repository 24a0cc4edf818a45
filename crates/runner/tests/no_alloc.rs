//! The tick of a machining run — encoder tracking, surface height with preview, ZPETC, the
//! controller, and the simulated stage with the part's cutting force — allocates nothing.

use daq_io::{Backend, Sensor};
use densa_alloc::{is_active, measure, CountingAllocator};
use run_config::{FeedforwardKind, Loaded, Scenario};
use run_config::{Machining, SurfaceConfig};
use runner::{Plan, PlanLoop};

/// Counts per thread: the test harness's own threads never enter a measurement.
#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator::system();

#[test]
fn machining_tick_allocates_nothing() {
    for (surface, ff) in [
        (SurfaceConfig::THESIS_GRID, FeedforwardKind::Zpetc),
        (SurfaceConfig::THESIS_BEAM, FeedforwardKind::Model),
    ] {
        let mut cfg = Loaded::default();
        cfg.config.scenario = Scenario::Machine(Machining {
            surface,
            finish_depth_m: None,
            ..Machining::default()
        });
        cfg.config.controller.feedforward = ff;
        let plan = Plan::new(&cfg).unwrap();
        let mut servo = PlanLoop::new(&plan).unwrap();
        let mut plant = plan.stage();
        let mut sample = Sensor::default();
        // Warm up past the first tick (which fills the preview window).
        for _ in 0..10 {
            let (cmd, _) = servo.tick(&sample);
            sample = Sensor {
                seq: sample.seq + 1,
                ..plant.step(cmd.unwrap().dac_v)
            };
        }
        assert!(is_active(), "the counting allocator must be installed");
        let (acc, stats) = measure(|| {
            let mut acc = 0.0;
            for _ in 0..50_000 {
                let (cmd, tel) = servo.tick(&sample);
                acc += tel.map_or(0.0, |t| t.following_error_m);
                sample = Sensor {
                    seq: sample.seq + 1,
                    ..plant.step(cmd.unwrap().dac_v)
                };
            }
            acc
        });
        assert!(acc.is_finite());
        assert!(sample.encoder_count > 0);
        assert_eq!((stats.allocs, stats.reallocs), (0, 0), "{stats:?}");
    }
}
