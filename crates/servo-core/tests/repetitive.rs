//! Repetitive control on the spindle angle against a sampled loop with a known response: the
//! error of a spindle-periodic disturbance falls revolution by revolution as the convergence
//! factor `|Q(1 − k_r·H·z^m·G)|` of the module docs says, whether a revolution is a whole
//! number of ticks or not and while the speed drifts.

use core::f64::consts::TAU;
use servo_core::{
    Block, Repetitive, RepetitiveConfig, RepetitiveInput, LEARNING_IDENTITY, LEARNING_TAPS,
};

const T: f64 = 1.0 / 199_600.0;
const BINS: usize = 1024;

/// The loop from the correction to the output: one tick of delay and a first-order lag with
/// pole `a` (unity DC gain), `G(z) = (1 − a)·z⁻²/(1 − a·z⁻¹)`.
struct Loop {
    a: f64,
    y: f64,
    u_prev: f64,
}

impl Loop {
    fn new(a: f64) -> Self {
        Loop {
            a,
            y: 0.0,
            u_prev: 0.0,
        }
    }

    /// The output of this tick; `u` acts from the next.
    fn tick(&mut self, u: f64) -> f64 {
        let y = self.y;
        self.y = self.a * self.y + (1.0 - self.a) * self.u_prev;
        self.u_prev = u;
        y
    }
}

/// A disturbance of 1, 7 and 50 cycles per revolution at the output, m.
fn disturbance_m(angle_rad: f64) -> f64 {
    40e-9 * libm::sin(angle_rad + 0.3)
        + 20e-9 * libm::sin(7.0 * angle_rad + 1.0)
        + 10e-9 * libm::cos(50.0 * angle_rad)
}

fn config() -> RepetitiveConfig {
    RepetitiveConfig {
        bins_per_rev: 1000,
        learning_gain: 0.5,
        // The loop's delay at low frequency: 2 ticks of delay + a/(1 − a) of the lag.
        lead_ticks: 3.0,
        learning_filter: LEARNING_IDENTITY,
        q_neighbour: 0.25,
        limit_m: 1e-6,
        max_speed_rpm: 3000.0,
    }
}

/// Runs `revolutions` with the spindle angle `angle(k)` and returns the RMS error of each
/// revolution (counted in nominal ticks `ticks_per_rev`).
fn run(angle: impl Fn(f64) -> f64, ticks_per_rev: f64, revolutions: usize) -> Vec<f64> {
    let mut rc: Repetitive<BINS> = config().try_build(T).unwrap();
    rc.set_enabled(true);
    let mut plant = Loop::new(0.5);
    let ticks = (ticks_per_rev * revolutions as f64) as usize;
    let mut sums = vec![(0.0, 0usize); revolutions + 1];
    let mut correction = 0.0;
    for k in 0..ticks {
        let theta = angle(k as f64);
        // The correction given last tick acts through the loop; the error is measured now.
        let error = -(plant.tick(correction) + disturbance_m(theta));
        let rate = angle(k as f64 + 1.0) - theta;
        correction = rc.update(RepetitiveInput {
            angle_rad: theta,
            error_m: error,
            output_angle_rad: theta + rate,
            rate_rad_per_tick: rate,
        });
        let rev = (k as f64 / ticks_per_rev) as usize;
        sums[rev].0 += error * error;
        sums[rev].1 += 1;
    }
    assert!(!rc.faulted());
    sums.iter()
        .filter(|s| s.1 > 0)
        .map(|s| (s.0 / s.1 as f64).sqrt())
        .collect()
}

/// The error's RMS over a revolution without correction.
fn uncorrected_rms() -> f64 {
    (0.5f64 * (40e-9f64.powi(2) + 20e-9f64.powi(2) + 10e-9f64.powi(2))).sqrt()
}

/// A revolution of 3992.4 ticks (3000 rpm at 199.6 kHz: no whole number of ticks): the first
/// revolutions switch on (the output ramps in over one) and learn; the error then halves each
/// revolution as `|1 − k_r| = 0.5` says at low harmonics, to what `Q` leaves of 50 cycles/rev.
#[test]
fn a_fractional_period_is_learned() {
    let ticks_per_rev = 3992.4;
    let rms = run(|k| TAU * k / ticks_per_rev, ticks_per_rev, 24);
    let start = uncorrected_rms();
    assert!(
        (rms[0] - start).abs() < 0.05 * start,
        "{} vs {start}",
        rms[0]
    );
    // Four revolutions after learning began (revolution 2): about 1/16 left, and halving.
    assert!(rms[6] < 0.12 * start, "{rms:?}");
    assert!(rms[6] < 0.75 * rms[5], "{rms:?}");
    // Converged: Q's residual at 50 cycles/rev, (1 − Q)/(1 − Q + Q·k_r·H) with
    // Q = 1 − 0.5(1 − cos(2π·50/1000)) = 0.988: 2.4 % of 10 nm; the rest learned away.
    let last = rms[rms.len() - 2];
    assert!(last < 0.02 * start, "{last:e} of {start:e}: {rms:?}");
}

/// The speed drifts ±1 % over 5 revolutions: indexed by the angle the table stays aligned with
/// the part, and the error falls as far as at a steady speed.
#[test]
fn a_drifting_speed_is_followed() {
    let ticks_per_rev = 3992.4;
    let drift_ticks = 5.0 * ticks_per_rev;
    let w = TAU / drift_ticks;
    // Angle of a speed (1 + 0.01·sin(wk))·2π/N integrated.
    let angle = move |k: f64| TAU / ticks_per_rev * (k + 0.01 * (1.0 - libm::cos(w * k)) / w);
    let rms = run(angle, ticks_per_rev, 24);
    let last = rms[rms.len() - 2];
    assert!(last < 0.02 * uncorrected_rms(), "{rms:?}");
    // A table indexed by time (a fixed 3992 ticks per period) would see the pattern slide by
    // up to 0.01·5·N/2π ≈ 3 % of a revolution per revolution: 50 cycles/rev would be ±1 rad
    // out of phase. The angle index keeps the converged error as at a steady speed.
    let steady = run(|k| TAU * k / ticks_per_rev, ticks_per_rev, 24);
    assert!(last < 2.0 * steady[steady.len() - 2] + 0.2e-9, "{last:e}");
}

/// Switching off moves the output to zero over one revolution without a jump, keeps the table,
/// and switching on again brings the learned correction back.
#[test]
fn switching_is_bumpless_and_keeps_the_table() {
    let ticks_per_rev = 3992.4;
    let rate = TAU / ticks_per_rev;
    let mut rc: Repetitive<BINS> = config().try_build(T).unwrap();
    let table: Vec<f64> = (0..1000)
        .map(|i| 100e-9 * libm::sin(TAU * (i as f64 + 0.5) / 1000.0))
        .collect();
    rc.load(&table).unwrap();
    rc.set_enabled(true);
    let mut k = 0.0;
    let tick = |rc: &mut Repetitive<BINS>, k: &mut f64| {
        let theta = rate * *k;
        *k += 1.0;
        rc.update(RepetitiveInput {
            angle_rad: theta,
            error_m: 0.0,
            output_angle_rad: theta,
            rate_rad_per_tick: rate,
        })
    };
    let mut prev = 0.0;
    let mut largest_step: f64 = 0.0;
    for _ in 0..(2.0 * ticks_per_rev) as usize {
        let c = tick(&mut rc, &mut k);
        largest_step = largest_step.max((c - prev).abs());
        prev = c;
    }
    assert_eq!(rc.weight(), 1.0);
    // The table's own slope per tick is 100 nm · 2π/N; the ramp adds at most 100 nm/N.
    let slope = 100e-9 * rate;
    assert!(
        largest_step < 2.0 * slope + 100e-9 / ticks_per_rev,
        "{largest_step:e}"
    );
    rc.set_enabled(false);
    largest_step = 0.0;
    for _ in 0..(1.5 * ticks_per_rev) as usize {
        let c = tick(&mut rc, &mut k);
        largest_step = largest_step.max((c - prev).abs());
        prev = c;
    }
    assert_eq!(prev, 0.0);
    assert!(
        largest_step < 2.0 * slope + 100e-9 / ticks_per_rev,
        "{largest_step:e}"
    );
    // A zero error while on does not change a table with Q = [¼, ½, ¼] except by its
    // smoothing of a sine over 1000 bins: (1 − cos(2π/1000))/2 per revolution.
    for (got, want) in rc.table().iter().zip(&table) {
        assert!(
            (got - want).abs() < 100e-9 * 2e-5 * 2.0,
            "{got:e} vs {want:e}"
        );
    }
}

/// A non-finite input zeroes the output and latches; reset forgets the table.
#[test]
fn a_non_finite_input_faults() {
    let mut rc: Repetitive<BINS> = config().try_build(T).unwrap();
    rc.load(&[1e-9; 1000]).unwrap();
    rc.set_enabled(true);
    let x = RepetitiveInput {
        angle_rad: 0.0,
        error_m: f64::NAN,
        output_angle_rad: 0.0,
        rate_rad_per_tick: 1e-3,
    };
    assert_eq!(rc.update(x), 0.0);
    assert!(rc.faulted());
    rc.reset();
    assert!(!rc.faulted() && rc.table().iter().all(|v| *v == 0.0));
}

/// Bins beyond the capacity or the ticks of a revolution, a table of the wrong length or out of
/// the limit: refused with the key.
#[test]
fn bad_configurations_are_refused() {
    let too_many = RepetitiveConfig {
        bins_per_rev: 2048,
        ..config()
    };
    assert!(too_many.try_build::<BINS>(T).is_err());
    // 3000 rpm at 199.6 kHz is 3992.4 ticks per revolution: 4096 bins would skip some.
    let skipping = RepetitiveConfig {
        bins_per_rev: 4096,
        ..config()
    };
    let err = skipping.try_build::<8192>(T).unwrap_err();
    assert!(
        matches!(err, servo_core::Error::OutOfRange { param: "bins_per_rev", max, .. } if max == 3992.0),
        "{err:?}"
    );
    let mut rc: Repetitive<BINS> = config().try_build(T).unwrap();
    assert!(rc.load(&[0.0; 999]).is_err());
    assert!(rc.load(&[2e-6; 1000]).is_err());
}

/// The learning filter reads the previous revolution's bin errors at offsets in the order the
/// spindle passes the bins (in time, as the lead): with `q₁ = 0` and `k_r = 1` a bin learns
/// exactly `Σ L_l·ē[i + l]` turning forwards and `Σ L_l·ē[i − l]` backwards.
#[test]
fn the_learning_filter_reads_the_neighbouring_bins() {
    let n = 100;
    let ticks_per_bin = 10;
    let g = |i: usize| 1e-9 * (1.0 + ((i * 37) % 11) as f64);
    let mut filter = [0.0; LEARNING_TAPS];
    let centre = LEARNING_TAPS / 2;
    filter[centre] = 0.1;
    filter[centre + 1] = 0.7;
    filter[centre - 2] = 0.2;
    filter[centre + 8] = 0.05;
    let expected = |i: usize, direction: f64| {
        let at = |l: isize| {
            let offset = if direction > 0.0 { l } else { -l };
            g((i as isize + offset).rem_euclid(n as isize) as usize)
        };
        0.1 * at(0) + 0.7 * at(1) + 0.2 * at(-2) + 0.05 * at(8)
    };
    for direction in [1.0, -1.0] {
        let cfg = RepetitiveConfig {
            bins_per_rev: n,
            learning_gain: 1.0,
            lead_ticks: 0.0,
            learning_filter: filter,
            q_neighbour: 0.0,
            limit_m: 1e-6,
            max_speed_rpm: 1000.0,
        };
        let mut rc: Repetitive<BINS> = cfg.try_build(T).unwrap();
        rc.set_enabled(true);
        let rate = direction * TAU / (n * ticks_per_bin) as f64;
        // One revolution to switch on, then one learning, and the bins the filter and Q wait
        // for (less one: no bin learns twice).
        for k in 0..(2 * n + 15) * ticks_per_bin {
            let theta = 1e-4 + rate * k as f64;
            let bin = (theta.rem_euclid(TAU) / TAU * n as f64) as usize;
            rc.update(RepetitiveInput {
                angle_rad: theta,
                error_m: g(bin),
                output_angle_rad: theta,
                rate_rad_per_tick: rate,
            });
        }
        let learned: Vec<usize> = (0..n).filter(|&i| rc.table()[i] != 0.0).collect();
        assert!(learned.len() >= 95, "{direction}: {} bins", learned.len());
        for i in learned {
            let got = rc.table()[i];
            let want = expected(i, direction);
            assert!(
                (got - want).abs() < 1e-22,
                "{direction}: bin {i}: {got:e} vs {want:e}"
            );
        }
    }
}

/// Where `Q` is far from 1 the law's factor is the textbook `Q·(1 − k_r·H·G)` (the robustness
/// filter acts on what is learned as on the table): a disturbance at a quarter of the bins'
/// rate (`Q = ½`, `H = ¾`) through an exactly led loop (`G = 1`) with `k_r = 1` settles at
/// `(1 − Q)/(1 − Q·(1 − k_r·H)) = 0.571` of itself. (Filtering only the table, `Q·c + k_r·ē`,
/// would settle at `(1 − Q)/(1 − Q + k_r·H) = 0.4`.)
#[test]
fn the_robustness_filter_acts_on_what_is_learned() {
    let n = 200;
    let ticks_per_rev = 2000.0;
    let harmonic = 50.0;
    let cfg = RepetitiveConfig {
        bins_per_rev: n,
        learning_gain: 1.0,
        lead_ticks: 0.0,
        learning_filter: LEARNING_IDENTITY,
        q_neighbour: 0.25,
        limit_m: 1e-6,
        max_speed_rpm: 3000.0,
    };
    let mut rc: Repetitive<BINS> = cfg.try_build(T).unwrap();
    rc.set_enabled(true);
    let rate = TAU / ticks_per_rev;
    let delay = 2;
    let mut given = std::collections::VecDeque::from(vec![0.0; delay]);
    let revolutions = 40;
    let mut sq = vec![0.0; revolutions];
    for k in 0..(revolutions as f64 * ticks_per_rev) as usize {
        let theta = rate * k as f64;
        // The correction given `delay` ticks ago for this tick's angle reaches the output now.
        let applied = given.pop_front().unwrap();
        let d = 10e-9 * libm::sin(harmonic * theta + 0.2);
        let error = -(applied + d);
        let c = rc.update(RepetitiveInput {
            angle_rad: theta,
            error_m: error,
            output_angle_rad: theta + delay as f64 * rate,
            rate_rad_per_tick: rate,
        });
        given.push_back(c);
        sq[(k as f64 / ticks_per_rev) as usize] += error * error;
    }
    let rms: Vec<f64> = sq.iter().map(|s| (s / ticks_per_rev).sqrt()).collect();
    let q = 1.0 - 2.0 * 0.25 * (1.0 - libm::cos(TAU * harmonic / n as f64));
    let h = 0.25 * (3.0 + libm::cos(TAU * harmonic / n as f64));
    let settled = (1.0 - q) / (1.0 - q * (1.0 - h));
    let ratio = rms[revolutions - 1] / rms[0];
    assert!((settled - 0.5714).abs() < 1e-3, "{settled}");
    assert!(
        (ratio - settled).abs() < 0.02,
        "{ratio} vs {settled}: {rms:?}"
    );
}
