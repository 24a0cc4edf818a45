//! One tick through the C ABI (`fts_servo_tick`, as a C daemon calls it: an opaque handle,
//! pointers in, a status code out) against the same tick through the Rust front door
//! (`Servo::tick`) in the same run: the PID of the thesis prototype and a 13-state controller
//! (thesis Table 6-1's reduced H2). Three ways: the Rust tick inlined into its caller's loop
//! (`rust`), the Rust tick as a function call (`rust_call`: what any library call costs), and
//! the C ABI (`c_abi`). The ratio c_abi / rust_call is the boundary's own cost.

#![allow(missing_docs)] // criterion_group! generates undocumented items.

use criterion::{criterion_group, criterion_main, Criterion};
use daq_io::{Command, Sensor};
use servo_config::{deployment_toml, ControllerKind, Deployment, SsMatrices};
use servo_runtime::Servo;
use std::ffi::CString;
use std::hint::black_box;

/// The thesis prototype, and the same loop with a stable 13-state controller (the cost does
/// not depend on the numbers).
fn deployments() -> [(&'static str, Deployment); 2] {
    let pid = Deployment::thesis_prototype();
    let mut seed = 0x2545_f491_4f6c_dd1d_u64;
    let mut rnd = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut ss = pid.clone();
    ss.controller.kind = ControllerKind::Ss;
    ss.controller.ss = SsMatrices::from_fn(13, |i, j| {
        let x = rnd();
        if i < 13 && j < 13 {
            x * 1.8 / 13.0
        } else {
            x * 1e-3
        }
    });
    [("pid", pid), ("state_space_13", ss)]
}

fn ticks(c: &mut Criterion) {
    for (name, d) in deployments() {
        let mut group = c.benchmark_group(format!("c_abi_{name}"));
        let mut servo = Servo::new(&d).unwrap();
        let mut sample = Sensor::default();
        group.bench_function("rust", |b| {
            b.iter(|| {
                sample.seq += 1;
                sample.gap_v = black_box(1e-4);
                black_box(servo.tick(&sample))
            })
        });
        let mut servo = Servo::new(&d).unwrap();
        let mut sample = Sensor::default();
        group.bench_function("rust_call", |b| {
            b.iter(|| {
                sample.seq += 1;
                sample.gap_v = black_box(1e-4);
                black_box(tick_call(&mut servo, &sample))
            })
        });
        let text = CString::new(deployment_toml(&d, None, "bench")).unwrap();
        let abi = fts_servo::FtsServoAbi::of_this_library();
        let mut h = std::ptr::null_mut();
        // SAFETY: a NUL-terminated text, the ABI struct, a writable handle pointer, no buffer.
        let opened = unsafe {
            fts_servo::fts_servo_open_toml(text.as_ptr(), &abi, &mut h, std::ptr::null_mut(), 0)
        };
        assert_eq!(opened, fts_servo::FTS_SERVO_OK);
        let (mut sample, mut command) = (Sensor::default(), Command::default());
        group.bench_function("c_abi", |b| {
            b.iter(|| {
                sample.seq += 1;
                sample.gap_v = black_box(1e-4);
                // SAFETY: a live handle used by this thread alone; valid sample and command.
                black_box(unsafe { fts_servo::fts_servo_tick(h, &sample, &mut command) })
            })
        });
        // SAFETY: the live handle, not used again.
        unsafe { fts_servo::fts_servo_close(h) };
        group.finish();
    }
}

/// `Servo::tick` behind a call the optimiser may not inline.
#[inline(never)]
fn tick_call(servo: &mut Servo, sample: &Sensor) -> Command {
    servo.tick(sample)
}

criterion_group!(benches, ticks);
criterion_main!(benches);
