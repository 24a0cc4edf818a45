//! Repetitive control on the spindle angle (Tomizuka, Tsao & Chew, ASME J. Dyn. Sys. 111, 1989;
//! Tsao & Tomizuka, ibid. 116, 1994): a plug-in correction added to the reference of a
//! spindle-synchronised cut, learned from the error of earlier revolutions.
//!
//! The learned signal is a table of `bins_per_rev` values over one revolution, indexed by the
//! **spindle angle** (not by time), so a revolution may last a fractional number of ticks and
//! the speed may drift. Each tick the error measured at the sample's angle is averaged into the
//! bin under it; when the angle leaves a bin, the bin learns:
//!
//! ```text
//! u[i] = c_j[i] + k_r·ē_j[i],   c_{j+1}[i] = q₁·u[i−1] + (1 − 2q₁)·u[i] + q₁·u[i+1]
//! ```
//!
//! (`j` the revolution, `ē` the bin's mean error, filtered over neighbouring bins by the learning
//! filter `L` when it is not the identity): the learning gain `k_r`, and a zero-phase
//! robustness filter `Q` over the bins applied to the table and what it learns alike. The correction for an angle is the table interpolated
//! linearly between bin centres, read `lead_ticks` ahead of it (a phase lead `z^m` that
//! compensates the loop's delay). The error converges revolution by revolution at harmonic `n`
//! (cycles per revolution) when
//!
//! ```text
//! |Q(n)·(1 − k_r·L(n)·H(n)·e^{jωm}·G(e^{jω}))| < 1,  Q(n) = 1 − 2q₁(1 − cos 2πn/N),  H(n) = (3 + cos 2πn/N)/4
//! ```
//!
//! with `G` the loop from the correction to the error's measurement, `H` the bin average of the
//! interpolated table and `L(n) = Σ L_l·e^{j2πnl/N}`; `design::repetitive` evaluates it for a loop before a run.
//!
//! The table is `BINS` values, fixed at build time: `8·BINS` bytes (`Repetitive<8192>` is
//! 64 KiB). Switching on and off is bumpless: the output is weighted by a factor that moves by
//! the turned angle over one revolution, and the table learns only at full weight.
//!
//! ```
//! use servo_core::{Block, Repetitive, RepetitiveConfig, RepetitiveInput};
//! let cfg = RepetitiveConfig { bins_per_rev: 1000, ..RepetitiveConfig::DEFAULT };
//! let mut rc: Repetitive<1024> = cfg.try_build(1.0 / 199_600.0).unwrap();
//! let c = rc.update(RepetitiveInput {
//!     angle_rad: 0.0,
//!     error_m: 1e-9,
//!     output_angle_rad: 0.01,
//!     rate_rad_per_tick: 3.1e-5,
//! });
//! assert_eq!(c, 0.0); // nothing learned yet, and not switched on
//! ```

use crate::block::{Block, FaultLatch};
use crate::error::{check_period, check_range, Error};
use core::f64::consts::TAU;

/// Configuration of a [`Repetitive`] controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RepetitiveConfig {
    /// Bins per revolution `N`: the table's resolution. At least [`MIN_BINS`], at most the
    /// capacity `BINS` and half the ticks of one revolution at `max_speed_rpm` (every bin sees
    /// two samples each revolution).
    pub bins_per_rev: usize,
    /// Learning gain `k_r` in (0, 2): the fraction of a revolution's error learned per
    /// revolution (with an exact loop model, `1 − k_r` is the error left after each).
    pub learning_gain: f64,
    /// Phase lead in ticks, [0, 1000] and short of the bins learned this revolution (N − 11
    /// bins at the fastest speed): the loop's delay from the correction to the measured error.
    /// The block's caller adds its own read-ahead (`output_angle_rad`) to it.
    pub lead_ticks: f64,
    /// Robustness filter weight `q₁` in [0, 0.25] on each neighbouring bin (`Q = [q₁, 1 − 2q₁,
    /// q₁]`, zero phase): 0 learns every harmonic up to `N/2`; 0.25 is the binomial low-pass
    /// that removes the harmonic `N/2` and keeps learning stable where the loop model is poor.
    pub q_neighbour: f64,
    /// The learning filter `L`: taps on the bins' mean errors at offsets −8..=8 bins in the
    /// order the spindle passes them (index `8 + l`; in time, as the lead), each in
    /// [−100, 100]: bin `i` learns `k_r·Σ L_l·ē[i + l]` (an FIR over the previous revolution,
    /// non-causal, fitted to the inverse of the loop by `design::repetitive`).
    /// [`LEARNING_IDENTITY`]: the bin's own error.
    pub learning_filter: [f64; LEARNING_TAPS],
    /// Largest correction in m, (0, 1e-3]: the table is clamped to ±limit.
    pub limit_m: f64,
    /// The fastest spindle speed the controller will see in rpm, (0, 1e6].
    pub max_speed_rpm: f64,
}

/// Taps of the learning filter: offsets −8..=8 bins.
pub const LEARNING_TAPS: usize = 17;

/// Bins each side of the learning filter's centre.
const HALF_TAPS: usize = LEARNING_TAPS / 2;

/// The learning filter that takes each bin's own error.
pub const LEARNING_IDENTITY: [f64; LEARNING_TAPS] = {
    let mut taps = [0.0; LEARNING_TAPS];
    taps[HALF_TAPS] = 1.0;
    taps
};

impl RepetitiveConfig {
    /// 4096 bins, `k_r` = 0.5, no lead, the identity learning filter, the binomial `Q`
    /// (q₁ = 0.25), ±10 µm, 1000 rpm.
    pub const DEFAULT: RepetitiveConfig = RepetitiveConfig {
        bins_per_rev: 4096,
        learning_gain: 0.5,
        lead_ticks: 0.0,
        learning_filter: LEARNING_IDENTITY,
        q_neighbour: 0.25,
        limit_m: 10e-6,
        max_speed_rpm: 1000.0,
    };

    /// Validates the configuration for sample period `sample_period_s` (s) and a table of
    /// `BINS` values.
    pub fn try_build<const BINS: usize>(
        &self,
        sample_period_s: f64,
    ) -> Result<Repetitive<BINS>, Error> {
        let t = check_period(sample_period_s)?;
        let rpm = check_range("max_speed_rpm", self.max_speed_rpm, 1e-9, 1e6)?;
        let ticks_per_rev = 60.0 / (rpm * t);
        if BINS < MIN_BINS {
            return Err(Error::DelayTooLong {
                samples: MIN_BINS,
                capacity: BINS,
            });
        }
        if self.bins_per_rev > BINS {
            return Err(Error::DelayTooLong {
                samples: self.bins_per_rev,
                capacity: BINS,
            });
        }
        let most = libm::floor(ticks_per_rev)
            .min(BINS as f64)
            .max(MIN_BINS as f64);
        check_range(
            "bins_per_rev",
            self.bins_per_rev as f64,
            MIN_BINS as f64,
            most,
        )?;
        for tap in self.learning_filter {
            check_range("learning_filter", tap, -100.0, 100.0)?;
        }
        Ok(Repetitive {
            bins: self.bins_per_rev,
            bins_per_rad: self.bins_per_rev as f64 / TAU,
            gain: check_range("learning_gain", self.learning_gain, 1e-6, 2.0 - 1e-6)?,
            lead_ticks: self.lead_ticks,
            q1: check_range("q_neighbour", self.q_neighbour, 0.0, 0.25)?,
            limit_m: check_range("limit_m", self.limit_m, 1e-12, 1e-3)?,
            filter: self.learning_filter,
            table: [0.0; BINS],
            window: Window::EMPTY,
            bin: usize::MAX,
            sum_m: 0.0,
            count: 0,
            pending: Pending::EMPTY,
            last_angle_rad: f64::NAN,
            on: false,
            weight: 0.0,
            fault: FaultLatch::CLEAR,
        })
    }
}

/// Fewest bins per revolution (the learning filter's span fits four times).
pub const MIN_BINS: usize = 4 * LEARNING_TAPS;

/// The last bins' mean errors in the order the spindle passed them, for the learning filter.
#[derive(Debug, Clone, Copy)]
struct Window {
    errors: [f64; LEARNING_TAPS],
    /// Where the next goes (the oldest, once full).
    head: usize,
    /// Consecutive bins held.
    len: usize,
    /// The newest bin.
    last_bin: usize,
    /// Whether the spindle passed them in increasing angle.
    forward: bool,
}

impl Window {
    const EMPTY: Window = Window {
        errors: [0.0; LEARNING_TAPS],
        head: 0,
        len: 0,
        last_bin: usize::MAX,
        forward: true,
    };

    /// Adds bin `b`'s mean error (of `n` bins); a bin that does not follow the last starts
    /// again (false).
    #[inline]
    fn push(&mut self, b: usize, mean_m: f64, n: usize) -> bool {
        let after = self.last_bin < n && b == (self.last_bin + 1) % n;
        let before = self.last_bin < n && b == (self.last_bin + n - 1) % n;
        let follows = match self.len {
            0 => false,
            1 => {
                self.forward = after;
                after || before
            }
            _ => (self.forward && after) || (!self.forward && before),
        };
        if !follows {
            self.len = 0;
            self.head = 0;
        }
        self.errors[self.head] = mean_m;
        self.head = (self.head + 1) % LEARNING_TAPS;
        self.len = (self.len + 1).min(LEARNING_TAPS);
        self.last_bin = b;
        follows
    }

    /// Once full: the middle bin and its filtered error `Σ L_l·ē[l]`, `l` counted in the
    /// order the spindle passes the bins (in time, as the lead: turning backwards the filter
    /// still leads).
    #[inline]
    fn filtered(&self, filter: &[f64; LEARNING_TAPS], n: usize) -> Option<(usize, f64)> {
        if self.len < LEARNING_TAPS {
            return None;
        }
        let centre = if self.forward {
            (self.last_bin + n - HALF_TAPS) % n
        } else {
            (self.last_bin + HALF_TAPS) % n
        };
        // errors[(head + v) % T] is the v-th oldest: pass offset v − K.
        let sum = filter
            .iter()
            .enumerate()
            .map(|(v, tap)| tap * self.errors[(self.head + v) % LEARNING_TAPS])
            .sum();
        Some((centre, sum))
    }
}

/// The last two bins' `c + k_r·L·ē` in the order the spindle passed them.
#[derive(Debug, Clone, Copy)]
struct Pending {
    bins: [usize; 2],
    values: [f64; 2],
    len: usize,
}

impl Pending {
    const EMPTY: Pending = Pending {
        bins: [usize::MAX; 2],
        values: [0.0; 2],
        len: 0,
    };

    /// Adds bin `b`'s value; once the two before it are in, the middle one and
    /// `(its predecessor, its value, b's value)`.
    #[inline]
    fn push(&mut self, b: usize, value: f64) -> Option<(usize, [f64; 3])> {
        let done =
            (self.len == 2).then_some((self.bins[1], [self.values[0], self.values[1], value]));
        self.bins = [self.bins[1], b];
        self.values = [self.values[1], value];
        self.len = (self.len + 1).min(2);
        done
    }
}

/// What a [`Repetitive`] controller reads each tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RepetitiveInput {
    /// Spindle angle of the sample in rad, unwrapped (a tracked encoder angle).
    pub angle_rad: f64,
    /// Error measured with the sample in m (desired minus measured position).
    pub error_m: f64,
    /// Spindle angle in rad of the reference the correction is for (a preview reads ahead).
    pub output_angle_rad: f64,
    /// Spindle speed in rad per tick (for the lead).
    pub rate_rad_per_tick: f64,
}

/// Repetitive controller of `BINS` table values (see the [module](self) docs).
#[derive(Debug, Clone)]
pub struct Repetitive<const BINS: usize> {
    bins: usize,
    bins_per_rad: f64,
    gain: f64,
    lead_ticks: f64,
    q1: f64,
    limit_m: f64,
    filter: [f64; LEARNING_TAPS],
    table: [f64; BINS],
    window: Window,
    /// The bin the accumulator belongs to (`usize::MAX`: none yet).
    bin: usize,
    sum_m: f64,
    count: u32,
    /// The last bins' `c + k_r·L·ē`, waiting for their successor to apply `Q`.
    pending: Pending,
    last_angle_rad: f64,
    on: bool,
    weight: f64,
    fault: FaultLatch,
}

impl<const BINS: usize> Repetitive<BINS> {
    /// Switches the correction on or off: the output moves to (or from) the table over one
    /// revolution of the spindle; the table learns only while fully on and is kept while off.
    pub fn set_enabled(&mut self, on: bool) {
        self.on = on;
    }

    /// Whether the controller is switched on.
    pub fn enabled(&self) -> bool {
        self.on
    }

    /// The fraction of the table in the output, [0, 1] (1: on and learning).
    pub fn weight(&self) -> f64 {
        self.weight
    }

    /// The correction in m for the reference at `angle_rad` with the spindle turning
    /// `rate_rad_per_tick`: what [`Block::update`] returns, without learning (for a reference
    /// read ahead over several ticks at once).
    #[inline]
    pub fn output_m(&self, angle_rad: f64, rate_rad_per_tick: f64) -> f64 {
        if self.fault.is_set() {
            return 0.0;
        }
        let read = angle_rad + self.lead_ticks * rate_rad_per_tick;
        let c = self.weight * self.correction_m(read);
        if c.is_finite() {
            c
        } else {
            0.0
        }
    }

    /// The learned table in m: bin `i` is the correction at spindle angle `(i + ½)·2π/N`.
    pub fn table(&self) -> &[f64] {
        &self.table[..self.bins]
    }

    /// Starts from a learned `table` (m per bin, as [`Repetitive::table`] gives it): refused
    /// unless it has `bins_per_rev` finite values within ±`limit_m`.
    pub fn load(&mut self, table: &[f64]) -> Result<(), Error> {
        check_range(
            "table length",
            table.len() as f64,
            self.bins as f64,
            self.bins as f64,
        )?;
        for v in table {
            check_range("table value", *v, -self.limit_m, self.limit_m)?;
        }
        self.table[..self.bins].copy_from_slice(table);
        self.bin = usize::MAX;
        self.window = Window::EMPTY;
        self.pending = Pending::EMPTY;
        Ok(())
    }

    /// The bin coordinate of `angle_rad`, in [0, N).
    #[inline]
    fn position(&self, angle_rad: f64) -> f64 {
        let n = self.bins as f64;
        let u = angle_rad * self.bins_per_rad;
        let u = u - libm::floor(u / n) * n;
        if u >= n {
            0.0
        } else {
            u
        }
    }

    /// The table interpolated between bin centres at `angle_rad`, as it was one revolution
    /// before.
    #[inline]
    fn correction_m(&self, angle_rad: f64) -> f64 {
        let u = self.position(angle_rad) - 0.5;
        let below = libm::floor(u);
        let frac = u - below;
        let n = self.bins;
        let i = if below < 0.0 { n - 1 } else { below as usize };
        let j = if i + 1 == n { 0 } else { i + 1 };
        // Bins learn K + 2 bins behind the spindle, so a read ahead of it finds the previous
        // revolution's value (what a bin learns acts one revolution later).
        self.table[i] + frac * (self.table[j] - self.table[i])
    }

    /// The bin the window's middle holds learns: `u = c + k_r·Σ L_l·ē`, and the bin before it
    /// in pass order takes `Q` of the three latest `u`: `c⁺ = q₁·(u₋ + u₊) + (1 − 2q₁)·u`.
    #[inline]
    fn learn(&mut self, centre: usize, filtered_m: f64) {
        let u = self.table[centre] + self.gain * filtered_m;
        if let Some((i, [before, at, after])) = self.pending.push(centre, u) {
            let new = self.q1 * (before + after) + (1.0 - 2.0 * self.q1) * at;
            self.table[i] = new.clamp(-self.limit_m, self.limit_m);
        }
    }
}

impl<const BINS: usize> Block for Repetitive<BINS> {
    type Input = RepetitiveInput;
    /// Correction in m to add to the reference at `output_angle_rad`.
    type Output = f64;

    #[inline]
    fn update(&mut self, x: RepetitiveInput) -> f64 {
        if self.fault.check_all(&[
            x.angle_rad,
            x.error_m,
            x.output_angle_rad,
            x.rate_rad_per_tick,
        ]) {
            return 0.0;
        }
        // The weight follows the switch by the angle turned: one revolution from 0 to 1.
        let turned = if self.last_angle_rad.is_nan() {
            0.0
        } else {
            libm::fabs(x.angle_rad - self.last_angle_rad) / TAU
        };
        self.last_angle_rad = x.angle_rad;
        self.weight = if self.on {
            (self.weight + turned).min(1.0)
        } else {
            (self.weight - turned).max(0.0)
        };
        let learning = self.on && self.weight >= 1.0;
        if !learning {
            // Bins left alone keep last revolution's value; learning starts afresh.
            self.window = Window::EMPTY;
            self.pending = Pending::EMPTY;
        }
        let bin = self.position(x.angle_rad) as usize;
        if bin != self.bin {
            if learning && self.count > 0 && self.bin < self.bins {
                let n = self.bins;
                if !self
                    .window
                    .push(self.bin, self.sum_m / f64::from(self.count), n)
                {
                    self.pending = Pending::EMPTY;
                }
                // A bin learns once the bins the filter reads past it are in, and is written
                // once its successor has learned too (Q): K + 2 bins late, well before it is
                // read again a revolution on.
                if let Some((centre, e)) = self.window.filtered(&self.filter, n) {
                    self.learn(centre, e);
                }
            }
            self.bin = bin;
            self.sum_m = 0.0;
            self.count = 0;
        }
        if learning {
            self.sum_m += x.error_m;
            self.count = self.count.saturating_add(1);
        }
        self.output_m(x.output_angle_rad, x.rate_rad_per_tick)
    }

    /// Forgets the table, the switch and the fault; the configuration is kept.
    fn reset(&mut self) {
        self.table = [0.0; BINS];
        self.window = Window::EMPTY;
        self.bin = usize::MAX;
        self.sum_m = 0.0;
        self.count = 0;
        self.pending = Pending::EMPTY;
        self.last_angle_rad = f64::NAN;
        self.on = false;
        self.weight = 0.0;
        self.fault = FaultLatch::CLEAR;
    }

    fn faulted(&self) -> bool {
        self.fault.is_set()
    }
}
