//! Through the front door, the ticking thread allocates nothing: PID, the acceleration cascade
//! and a 29-state controller with ZPETC, timed ticks, served (telemetry into the service
//! thread's ring, health every 2048 ticks), a gain change and a controller handed over while
//! ticking (loaded between ticks, or prepared on another thread and swapped in).

use daq_io::Sensor;
use densa_alloc::{is_active, measure, CountingAllocator};
use servo_config::{
    controller_toml, ControllerKind, ControllerSpec, Deployment, FeedforwardSpec, MadeFor,
    SsMatrices, Stability, ZpetcSpec, ZPETC_SECTIONS,
};
use servo_runtime::Servo;

/// Counts per thread: the test harness's own threads never enter a measurement.
#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator::system();

fn deployments() -> Vec<Deployment> {
    let base = Deployment::thesis_prototype();
    let mut accel = base.clone();
    accel.controller.kind = ControllerKind::Accel;
    accel.controller.ka = 1.0;
    accel.controller.kg_scaling = true;
    let mut ss = base.clone();
    ss.controller.kind = ControllerKind::Ss;
    // A stable 29-state realisation (diagonal A inside the unit circle).
    ss.controller.ss = SsMatrices::from_fn(29, |i, j| match (i < 29, j < 29) {
        (true, true) if i == j => 0.5 + 0.01 * i as f64,
        (true, true) => 0.0,
        (false, false) => 0.1,
        _ => 0.01,
    });
    let mut sections = [[1.0, 0.0, 0.0, 0.0, 0.0]; ZPETC_SECTIONS];
    sections[0] = [0.5, 0.3, 0.2, -0.2, 0.05];
    ss.feedforward = FeedforwardSpec::Zpetc(ZpetcSpec {
        gain: 1.0,
        preview: 3,
        sections,
        sections_used: 1,
    });
    ss.reference = servo_config::ReferenceSpec::Sine {
        amplitude_m: 1e-6,
        frequency_hz: 200.0,
    };
    ss.smoothing_hz = 10_000.0;
    let mut all = vec![base, accel, ss];
    for d in &mut all {
        d.stability = Some(
            Stability {
                spectral_radius: 0.9999,
                unstable_below: 0.1,
                unstable_above: 5.0,
                sha256: Default::default(),
            }
            .sealed(d.servo_rate_hz, &d.stage, &d.controller),
        );
    }
    all
}

/// Ticks `n` samples (timed: each says when it was taken).
fn ticks(servo: &mut Servo, from: u64, n: u64) -> f64 {
    let mut acc = 0.0;
    for k in from..from + n {
        let s = Sensor {
            seq: k,
            gap_v: 1e-3 * ((k % 7) as f64 - 3.0),
            published_ns: 1 + k * 5_000,
            run_id: 7,
            ..Default::default()
        };
        acc += servo.tick(&s).dac_v;
    }
    acc
}

#[test]
fn the_front_door_tick_allocates_nothing() {
    assert!(is_active(), "the counting allocator must be installed");
    for (i, d) in deployments().into_iter().enumerate() {
        let mut servo = Servo::new(&d).unwrap();
        ticks(&mut servo, 0, 10);
        let (acc, stats) = measure(|| {
            let a = ticks(&mut servo, 10, 20_000);
            servo.set_gain(0.8).unwrap();
            a + ticks(&mut servo, 20_010, 5_000)
        });
        assert!(acc.is_finite());
        assert_eq!(
            (stats.allocs, stats.reallocs, stats.deallocs),
            (0, 0, 0),
            "deployment {i}: {stats:?}"
        );
    }
}

#[test]
fn a_loaded_controller_is_handed_over_without_allocating_on_the_tick() {
    let d = deployments().remove(0);
    let made_for = MadeFor {
        tool: "test".into(),
        plant_sha256: "p".into(),
        stage: "light".into(),
        servo_rate_hz: 199_600.0,
    };
    let text = servo_config::deployment_toml(&d, Some(&made_for), "t");
    let mut servo = Servo::from_toml(&text).unwrap();
    ticks(&mut servo, 0, 100);
    let mut c = ControllerSpec::default();
    c.pid.kp *= 0.9;
    // Its own check's record (the deployment's was made on the other gains).
    let checked = d.stability.map(|s| s.sealed(d.servo_rate_hz, &d.stage, &c));
    let file = controller_toml(&c, Some(&made_for), checked.as_ref());
    // Parsing and building allocate on the calling thread; the handover happens in the ticks.
    servo.load(file.as_bytes()).unwrap();
    let (_, stats) = measure(|| ticks(&mut servo, 100, 1_000));
    assert_eq!((stats.allocs, stats.deallocs), (0, 0), "{stats:?}");
    assert_eq!(servo.status().handovers, 1);
}

/// A load in two halves: checked and built on another thread while the loop ticks, swapped in
/// on the ticking thread without allocating or freeing — the same loop `load` makes, bit for
/// bit; a prepared controller swaps in once, and only into the loop it was prepared for.
#[test]
fn a_controller_prepared_on_another_thread_is_swapped_in_without_allocating() {
    let d = deployments().remove(0);
    let made_for = MadeFor {
        tool: "test".into(),
        plant_sha256: "p".into(),
        stage: "light".into(),
        servo_rate_hz: 199_600.0,
    };
    let text = servo_config::deployment_toml(&d, Some(&made_for), "t");
    let mut c = ControllerSpec::default();
    c.pid.kp *= 0.9;
    let checked = d.stability.map(|s| s.sealed(d.servo_rate_hz, &d.stage, &c));
    let file = controller_toml(&c, Some(&made_for), checked.as_ref());

    let mut servo = Servo::from_toml(&text).unwrap();
    let loader = servo.loader();
    let (mut prepared, before) = std::thread::scope(|s| {
        let preparing = s.spawn(|| loader.prepare(file.as_bytes()));
        let before = ticks(&mut servo, 0, 1_000);
        (preparing.join().unwrap().unwrap(), before)
    });
    let (after, stats) = measure(|| {
        servo.swap(&mut prepared).unwrap();
        ticks(&mut servo, 1_000, 1_000)
    });
    assert_eq!((stats.allocs, stats.deallocs), (0, 0), "{stats:?}");
    assert_eq!(servo.status().handovers, 1);
    assert!(matches!(
        servo.swap(&mut prepared),
        Err(servo_runtime::LoadError::Spent)
    ));
    drop(prepared);

    // The one-call load, between the same ticks: the same commands.
    let mut loaded = Servo::from_toml(&text).unwrap();
    assert_eq!(ticks(&mut loaded, 0, 1_000).to_bits(), before.to_bits());
    loaded.load(file.as_bytes()).unwrap();
    assert_eq!(ticks(&mut loaded, 1_000, 1_000).to_bits(), after.to_bits());

    // Prepared for a loop at another rate: refused by this one.
    let mut other = d.clone();
    other.servo_rate_hz = 100_000.0;
    let other_for = MadeFor {
        servo_rate_hz: 100_000.0,
        ..made_for.clone()
    };
    other.stability = other
        .stability
        .map(|s| s.sealed(other.servo_rate_hz, &other.stage, &other.controller));
    let other_servo = Servo::from_toml(&servo_config::deployment_toml(
        &other,
        Some(&other_for),
        "t",
    ))
    .unwrap();
    let checked = d.stability.map(|s| s.sealed(100_000.0, &d.stage, &c));
    let other_file = controller_toml(&c, Some(&other_for), checked.as_ref());
    let mut foreign = other_servo.loader().prepare(other_file.as_bytes()).unwrap();
    assert!(matches!(
        servo.swap(&mut foreign),
        Err(servo_runtime::LoadError::OtherLoop)
    ));
}

#[cfg(feature = "serve")]
#[test]
fn a_served_tick_allocates_nothing() {
    let prefix = format!("rt-noalloc-{}", std::process::id());
    for d in deployments() {
        let mut servo = Servo::new(&d).unwrap();
        servo.serve(&prefix).unwrap();
        ticks(&mut servo, 0, 10);
        let (acc, stats) = measure(|| ticks(&mut servo, 10, 10_000));
        servo.close(0);
        assert!(acc.is_finite());
        assert_eq!((stats.allocs, stats.deallocs), (0, 0), "{stats:?}");
    }
}
