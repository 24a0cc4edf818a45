//! A counting global allocator proves that 100 000 ticks of every block allocate nothing.

use crate::common;

use common::*;
use densa_alloc::{is_active, measure, CountingAllocator};
use servo_core::*;

/// Counts per thread: the test harness's own threads never enter a measurement.
#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator::system();

const TICKS: usize = 100_000;

/// Bytes allocated (and allocations made) by this thread while `f` runs.
fn allocated_by(f: impl FnOnce()) -> (u64, u64) {
    assert!(is_active(), "the counting allocator must be installed");
    let ((), stats) = measure(f);
    (stats.bytes_allocated, stats.allocs + stats.reallocs)
}

#[test]
fn every_block_ticks_without_allocating() {
    let (mut pid, mut bq, mut cas, mut ss, mut dob, mut dl, mut ff) = (
        pid(),
        biquad(),
        cascade(),
        state_space_27(),
        observer(),
        delay(),
        feedforward(),
    );
    let mut avg = Averager::<4>::new();
    let freqs = [100.0, 1000.0];
    let mut sweep = SteppedSineConfig {
        frequencies_hz: &freqs,
        amplitude: 1.0,
        ramp_periods: 2,
        settle_periods: 2,
        measure_periods: 4,
        ramp_down_periods: 1,
    }
    .try_build(T)
    .unwrap();
    let mut chirp = ChirpConfig {
        amplitude: 1.0,
        f_start_hz: 1.0,
        f_end_hz: 1e4,
        duration_s: 0.25,
        sweep: Sweep::Exponential,
    }
    .try_build(T)
    .unwrap();
    let mut rc: Box<Repetitive<4096>> = Box::new(
        RepetitiveConfig {
            bins_per_rev: 4000,
            ..RepetitiveConfig::DEFAULT
        }
        .try_build(T)
        .unwrap(),
    );
    rc.set_enabled(true);
    let mut sink = 0.0;
    let (bytes, count) = allocated_by(|| {
        for k in 0..TICKS {
            let x = libm::sin(k as f64 * 1e-3);
            let r = sweep.update(()).position + chirp.update(()).position;
            sink += pid.update(x) + bq.update(x) + dl.update(x);
            sink += cas.update(CascadeInput { error: x, accel: r });
            sink += ss.update([x])[0];
            sink += dob.update(ObserverInput {
                control: x,
                inner: r,
            });
            sink += ff.update(Setpoint {
                position: x,
                velocity: r,
                acceleration: x,
            });
            sink += avg.update([x, r, x, r]);
            // 25 revolutions of 4000 ticks: every bin learns, the table wraps.
            let angle = k as f64 * (core::f64::consts::TAU / 4000.0);
            sink += rc.update(RepetitiveInput {
                angle_rad: angle,
                error_m: 1e-9 * x,
                output_angle_rad: angle,
                rate_rad_per_tick: core::f64::consts::TAU / 4000.0,
            });
        }
    });
    assert!(sink.is_finite());
    assert_eq!(
        (bytes, count),
        (0, 0),
        "the servo tick allocated {bytes} bytes in {count} calls"
    );
}
