//! Discrete state-space controller of any order: `x⁺ = A x + B e`, `u = C x + D e`.
//!
//! Shapes are const generics (`StateSpace<27, 1, 1>` runs the full-order H2 controller of thesis
//! §6.4.1). The tick is two dense products laid out for the FMA units: `A` and `B` are stored by
//! column so `A x` is a sum of column·scalar products (independent lanes, no horizontal sums),
//! and even and odd columns go to separate accumulators to halve the dependency chain. `C` is
//! stored by row and reduced with four partial sums. The tick runs with the widest vector
//! instructions the machine has ([`crate::simd`]), with the same result on every CPU. Where
//! there are no wide vector units (a microcontroller's scalar FPU) the update runs by row
//! instead, four rows at a time with `A` stored in blocks of four rows: the same sums in the
//! same order, the same bits. Storage for the largest order holds any smaller one, loaded in
//! place ([`StateSpace::load`]) and run by [`StateSpace::update_order`].

use crate::block::{Block, FaultLatch};
use crate::error::{check_period, Error};
use crate::limits::Limits;
use crate::math::{flush, mul_add};
use crate::simd::{self, Simd};
use nalgebra::SMatrix;

/// A discrete state-space realisation in nalgebra matrices (any unit; the thesis uses V/V).
///
/// ```
/// use nalgebra::SMatrix;
/// use servo_core::{Block, Limits, StateSpaceConfig};
/// // A discrete integrator x⁺ = x + T·e, u = x.
/// let config = StateSpaceConfig::<1, 1, 1> {
///     a: SMatrix::from_element(1.0),
///     b: SMatrix::from_element(1e-3),
///     c: SMatrix::from_element(1.0),
///     d: SMatrix::zeros(),
///     limits: Limits::UNLIMITED,
/// };
/// let mut ss = config.try_build(1e-3).unwrap();
/// ss.update([1.0]);
/// assert_eq!(ss.update([1.0]), [1e-3]);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct StateSpaceConfig<const NX: usize, const NU: usize, const NY: usize> {
    /// State transition matrix (NX × NX).
    pub a: SMatrix<f64, NX, NX>,
    /// Input matrix (NX × NU).
    pub b: SMatrix<f64, NX, NU>,
    /// Output matrix (NY × NX).
    pub c: SMatrix<f64, NY, NX>,
    /// Feed-through matrix (NY × NU).
    pub d: SMatrix<f64, NY, NU>,
    /// Limits applied to every output.
    pub limits: Limits,
}

impl<const NX: usize, const NU: usize, const NY: usize> StateSpaceConfig<NX, NU, NY> {
    /// Validates the matrices (all finite) for a controller sampled every `sample_period_s` s.
    pub fn try_build(&self, sample_period_s: f64) -> Result<StateSpace<NX, NU, NY>, Error> {
        let mut built = StateSpace::EMPTY;
        let entry = |i: usize, j: usize| match (i < NX, j < NX) {
            (true, true) => self.a[(i, j)],
            (true, false) => self.b[(i, j - NX)],
            (false, true) => self.c[(i - NX, j)],
            (false, false) => self.d[(i - NX, j - NX)],
        };
        built.load(NX, entry, self.limits, sample_period_s)?;
        Ok(built)
    }
}

/// A running discrete state-space block; input `e` (NU), output `u` (NY), clamped.
///
/// The state keeps evolving while an output is clamped (no anti-windup: an H2 controller has
/// no integrator to protect unless the designer put one in; add a limit-aware design there).
#[derive(Debug, Clone)]
pub struct StateSpace<const NX: usize, const NU: usize, const NY: usize> {
    a_cols: [[f64; NX]; NX],
    b_cols: [[f64; NX]; NU],
    c_rows: [[f64; NX]; NY],
    d_cols: [[f64; NY]; NU],
    limits: Limits,
    sample_period_s: f64,
    /// The state and the next one's storage: a tick writes `x[1 - now]` from `x[now]`, then
    /// flips `now` (no copy).
    x: [[f64; NX]; 2],
    now: usize,
    fault: FaultLatch,
}

impl<const NX: usize, const NU: usize, const NY: usize> StateSpace<NX, NU, NY> {
    /// Storage for a realisation of any order up to `NX`, loaded in place with
    /// [`StateSpace::load`] (a microcontroller builds its loop where it will run, not on its
    /// stack): every matrix and the state zero, output 0.
    pub const EMPTY: Self = StateSpace {
        a_cols: [[0.0; NX]; NX],
        b_cols: [[0.0; NX]; NU],
        c_rows: [[0.0; NX]; NY],
        d_cols: [[0.0; NY]; NU],
        limits: Limits::UNLIMITED,
        sample_period_s: 0.0,
        x: [[0.0; NX]; 2],
        now: 0,
        fault: FaultLatch::CLEAR,
    };

    /// Loads the realisation of order `order` (`1 ≤ order ≤ NX`) in place: `entry(i, j)` is
    /// row `i`, column `j` of `[[A, B], [C, D]]` (`order + NY` rows, `order + NU` columns),
    /// sampled every `sample_period_s` s; the rest of the storage and the state are zeroed and
    /// a fault cleared. Run it with [`StateSpace::update_order`] of the same order. Refused,
    /// the storage untouched, when the order or the period is out of range or an entry is not
    /// finite (naming the matrix).
    pub fn load(
        &mut self,
        order: usize,
        entry: impl Fn(usize, usize) -> f64,
        limits: Limits,
        sample_period_s: f64,
    ) -> Result<(), Error> {
        self.load_as(order, entry, limits, sample_period_s, BLOCKED)
    }

    /// [`StateSpace::load`] with `A` by column or `blocked` (this processor's layout, or the
    /// other one's for a test).
    fn load_as(
        &mut self,
        order: usize,
        entry: impl Fn(usize, usize) -> f64,
        limits: Limits,
        sample_period_s: f64,
        blocked: bool,
    ) -> Result<(), Error> {
        let sample_period_s = check_period(sample_period_s)?;
        if !(1..=NX).contains(&order) {
            return Err(Error::OutOfRange {
                param: "order",
                value: order as f64,
                min: 1.0,
                max: NX as f64,
            });
        }
        // Matrix by matrix, as a configuration is checked.
        let n = order;
        for (name, rows, cols) in [
            ("a", 0..n, 0..n),
            ("b", 0..n, n..n + NU),
            ("c", n..n + NY, 0..n),
            ("d", n..n + NY, n..n + NU),
        ] {
            for i in rows {
                if cols.clone().any(|j| !entry(i, j).is_finite()) {
                    return Err(Error::NotFinite { param: name });
                }
            }
        }
        // Every array written where it lies: no copy of the storage on the stack. `A` packed
        // for `order` ([`a_at`]), the rest zero.
        let a = self.a_cols.as_flattened_mut();
        a.fill(0.0);
        for j in 0..order {
            for i in 0..order {
                if let Some(v) = a.get_mut(a_at(order, i, j, blocked)) {
                    *v = entry(i, j);
                }
            }
        }
        for (u, col) in self.b_cols.iter_mut().enumerate() {
            for (i, b) in col.iter_mut().enumerate() {
                *b = if i < order { entry(i, order + u) } else { 0.0 };
            }
        }
        for (k, row) in self.c_rows.iter_mut().enumerate() {
            for (j, c) in row.iter_mut().enumerate() {
                *c = if j < order { entry(order + k, j) } else { 0.0 };
            }
        }
        for (u, col) in self.d_cols.iter_mut().enumerate() {
            for (k, d) in col.iter_mut().enumerate() {
                *d = entry(order + k, order + u);
            }
        }
        self.x.iter_mut().for_each(|x| x.fill(0.0));
        self.now = 0;
        self.fault = FaultLatch::CLEAR;
        self.limits = limits;
        self.sample_period_s = sample_period_s;
        Ok(())
    }

    /// One tick of the order-`N` realisation [`StateSpace::load`] put here (`N ≤ NX`, checked
    /// when it compiles): the bits of a `StateSpace<N, NU, NY>` of the same matrices.
    #[inline]
    pub fn update_order<const N: usize>(&mut self, e: [f64; NU]) -> [f64; NY] {
        const { assert!(N <= NX, "the order runs in the storage's top-left corner") };
        simd::vectorised(
            #[inline(always)]
            || self.tick::<N>(e),
        )
    }

    /// The current state vector.
    pub fn state(&self) -> &[f64; NX] {
        &self.x[self.now]
    }

    /// The sample period the matrices were designed for, in s.
    pub fn sample_period_s(&self) -> f64 {
        self.sample_period_s
    }
}

/// `acc += col · s` for every lane.
#[inline(always)]
fn axpy<const N: usize>(acc: &mut [f64; N], col: &[f64; N], s: f64) {
    for (a, c) in acc.iter_mut().zip(col) {
        *a = mul_add(*c, s, *a);
    }
}

/// Dot product with four partial sums (breaks the FMA latency chain).
#[inline(always)]
fn dot<const N: usize>(a: &[f64; N], b: &[f64; N]) -> f64 {
    let mut part = [0.0f64; 4];
    let (a4, a_rest) = a.as_chunks::<4>();
    let (b4, b_rest) = b.as_chunks::<4>();
    for (x, y) in a4.iter().zip(b4) {
        for l in 0..4 {
            part[l] = mul_add(x[l], y[l], part[l]);
        }
    }
    for (l, (x, y)) in a_rest.iter().zip(b_rest).enumerate() {
        part[l] = mul_add(*x, *y, part[l]);
    }
    (part[0] + part[1]) + (part[2] + part[3])
}

/// The first `N` entries of `a` (there are `N`: the order is checked where it is chosen, and
/// a block lies within the storage).
#[inline(always)]
fn head<const N: usize>(a: &[f64]) -> &[f64; N] {
    a.first_chunk().unwrap_or(&[0.0; N])
}

/// Column `j` of the order-`N` realisation's `A`, stored by column ([`a_at`]).
#[inline(always)]
fn column<const N: usize, const NX: usize>(a_cols: &[[f64; NX]; NX], j: usize) -> &[f64; N] {
    head(&a_cols.as_flattened()[a_at(N, 0, j, false)..])
}

/// How `A` lies in its storage: by column (x86-64, for the column kernel's vector lanes) or
/// in blocks of [`ROWS`] rows, each block's columns side by side (elsewhere, for the row
/// kernel: a block's entries all lie within a Cortex-M7 load's reach of the block's start).
const BLOCKED: bool = cfg!(not(target_arch = "x86_64"));

/// Where entry `(i, j)` of an order-`n` realisation's `A` lies in the flattened storage.
#[inline(always)]
const fn a_at(n: usize, i: usize, j: usize, blocked: bool) -> usize {
    let full = n / ROWS * ROWS;
    if !blocked {
        j * n + i
    } else if i < full {
        (i / ROWS) * ROWS * n + j * ROWS + i % ROWS
    } else {
        // The rows left over, as one narrower block.
        full * n + j * (n - full) + (i - full)
    }
}

/// Rows of the state update the row kernel computes together: each column's `x[j]` is loaded
/// once for four rows, and the eight accumulators, four entries of `A` and `x[j]` fit in a
/// Cortex-M7's sixteen double registers.
const ROWS: usize = 4;

/// Rows `first..first + R` of the next state, `A x + B e`, each row's even and odd columns
/// summed in the order the column kernel sums them (one accumulator each, from 0; the inputs'
/// columns after the odd ones), then flushed.
#[inline(always)]
fn rows<const N: usize, const CAP: usize, const NU: usize, const R: usize>(
    a_cols: &[[f64; CAP]; CAP],
    b_cols: &[[f64; CAP]; NU],
    x: &[f64; CAP],
    e: &[f64; NU],
    first: usize,
    blocked: bool,
) -> [f64; R] {
    let a = a_cols.as_flattened();
    // Column `j`'s entries of these rows, side by side.
    let part = |j: usize| -> &[f64; R] { head(&a[a_at(N, first, j, blocked)..]) };
    let (mut even, mut odd) = ([0.0; R], [0.0; R]);
    let mut j = 0;
    while j + 1 < N {
        let (x_even, x_odd) = (x[j], x[j + 1]);
        let (a_even, a_odd) = (part(j), part(j + 1));
        for r in 0..R {
            even[r] = mul_add(a_even[r], x_even, even[r]);
            odd[r] = mul_add(a_odd[r], x_odd, odd[r]);
        }
        j += 2;
    }
    if j < N {
        let a_even = part(j);
        for r in 0..R {
            even[r] = mul_add(a_even[r], x[j], even[r]);
        }
    }
    for (col, &ek) in b_cols.iter().zip(e) {
        for r in 0..R {
            odd[r] = mul_add(col[first + r], ek, odd[r]);
        }
    }
    core::array::from_fn(|r| flush(even[r] + odd[r]))
}

impl<const NX: usize, const NU: usize, const NY: usize> StateSpace<NX, NU, NY> {
    /// [`Block::update`] with the vector instructions `simd` (or the baseline where this
    /// machine lacks them): the result is the same bit for bit; only the speed differs.
    pub fn update_with(&mut self, simd: Simd, e: [f64; NU]) -> [f64; NY] {
        simd::with(
            simd,
            #[inline(always)]
            || self.tick::<NX>(e),
        )
    }

    /// One tick of the order-`N` realisation in the top-left of the matrices (`N ≤ NX`), with
    /// the kernel written for this processor: by column where there are wide vector units
    /// (x86-64), by row elsewhere (a microcontroller's FPU). Both give the same bits, and the
    /// bits of a `StateSpace<N, NU, NY>` of the same matrices.
    #[inline(always)]
    fn tick<const N: usize>(&mut self, e: [f64; NU]) -> [f64; NY] {
        #[cfg(target_arch = "x86_64")]
        {
            self.tick_by_columns::<N>(e)
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            self.tick_by_rows::<N>(e, BLOCKED)
        }
    }

    /// The output `C x + D e` of the order-`N` realisation (before the limits).
    #[inline(always)]
    fn output<const N: usize>(&self, e: &[f64; NU]) -> [f64; NY] {
        let x = head::<N>(self.state());
        let mut y: [f64; NY] = core::array::from_fn(|i| dot(head::<N>(&self.c_rows[i]), x));
        for (col, &ej) in self.d_cols.iter().zip(e) {
            axpy(&mut y, col, ej);
        }
        y
    }

    /// The state update as column · scalar products into even and odd accumulators (every
    /// lane independent: what wide vector units run best).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))] // the host's tests hold the row kernel to it
    #[inline(always)]
    fn tick_by_columns<const N: usize>(&mut self, e: [f64; NU]) -> [f64; NY] {
        let y = self.output::<N>(&e);
        let mut even = [0.0; N];
        let mut odd = [0.0; N];
        let x = head::<N>(&self.x[self.now]);
        let (x_pairs, x_last) = x.as_chunks::<2>();
        for (p, xs) in x_pairs.iter().enumerate() {
            axpy(&mut even, column::<N, NX>(&self.a_cols, 2 * p), xs[0]);
            axpy(&mut odd, column::<N, NX>(&self.a_cols, 2 * p + 1), xs[1]);
        }
        if let [xj] = x_last {
            axpy(&mut even, column::<N, NX>(&self.a_cols, N - 1), *xj);
        }
        for (col, &ej) in self.b_cols.iter().zip(&e) {
            axpy(&mut odd, head(col), ej);
        }
        self.now = 1 - self.now;
        for ((x, a), b) in self.x[self.now].iter_mut().zip(&even).zip(&odd) {
            *x = flush(a + b);
        }
        self.checked::<N>(y)
    }

    /// The state update row by row, each row's even and odd columns summed in the order
    /// [`Self::tick_by_columns`] sums them (the same bits), [`ROWS`] rows at a time with their
    /// accumulators in registers instead of two arrays in memory: what a scalar FPU with 16
    /// registers (a Cortex-M7's FPv5-D16) runs best — a load and a multiply-add per entry, one
    /// load of each state value per block. `blocked`: `A` in [`ROWS`]-row blocks ([`a_at`]).
    #[cfg_attr(target_arch = "x86_64", allow(dead_code))] // the host's tests hold it to the column kernel
    #[inline(always)]
    fn tick_by_rows<const N: usize>(&mut self, e: [f64; NU], blocked: bool) -> [f64; NY] {
        // The new state is written into the same array the old one is read from: the compiler
        // cannot tell the halves apart, so it reads `x` where it is used instead of copying
        // the whole of it to the stack first (which it does with two separate borrows).
        let (now, xs) = (self.now, &mut self.x);
        let (a, b) = (&self.a_cols, &self.b_cols);
        let blocks = N / ROWS;
        for k in 0..blocks {
            let first = k * ROWS;
            let block: [f64; ROWS] = rows::<N, NX, NU, ROWS>(a, b, &xs[now], &e, first, blocked);
            xs[1 - now][first..first + ROWS].copy_from_slice(&block);
        }
        for i in blocks * ROWS..N {
            xs[1 - now][i] = rows::<N, NX, NU, 1>(a, b, &xs[now], &e, i, blocked)[0];
        }
        // The output from the state the update read (still in place).
        let y = self.output::<N>(&e);
        self.now = 1 - self.now;
        self.checked::<N>(y)
    }

    /// `y` within the limits, or 0 with the fault latched when `y` or the new state (its
    /// first `N`) is not finite.
    #[inline(always)]
    fn checked<const N: usize>(&mut self, y: [f64; NY]) -> [f64; NY] {
        if self.fault.check_all(&y) | self.fault.check_all(head::<N>(&self.x[self.now])) {
            return [0.0; NY];
        }
        y.map(|v| self.limits.clamp(v))
    }
}

impl<const NX: usize, const NU: usize, const NY: usize> Block for StateSpace<NX, NU, NY> {
    type Input = [f64; NU];
    type Output = [f64; NY];

    /// One tick, run with the widest vector instructions this machine has ([`simd`]).
    #[inline]
    fn update(&mut self, e: [f64; NU]) -> [f64; NY] {
        simd::vectorised(
            #[inline(always)]
            || self.tick::<NX>(e),
        )
    }

    fn reset(&mut self) {
        self.x = [[0.0; NX]; 2];
        self.fault = FaultLatch::default();
    }

    fn faulted(&self) -> bool {
        self.fault.is_set()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random numbers in [-0.5, 0.5) (xorshift), for test matrices.
    fn lcg(seed: &mut u64) -> f64 {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 7;
        *seed ^= *seed << 17;
        (*seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }

    fn random_config<const NX: usize, const NU: usize, const NY: usize>(
        seed: &mut u64,
    ) -> StateSpaceConfig<NX, NU, NY> {
        // Scale A so that its spectral radius stays below 1 (‖A‖∞ < 0.5·… ≤ 0.95).
        let scale = 0.95 / NX as f64 * 2.0;
        StateSpaceConfig {
            a: SMatrix::from_fn(|_, _| lcg(seed) * scale),
            b: SMatrix::from_fn(|_, _| lcg(seed)),
            c: SMatrix::from_fn(|_, _| lcg(seed)),
            d: SMatrix::from_fn(|_, _| lcg(seed)),
            limits: Limits::UNLIMITED,
        }
    }

    /// Compare with the textbook nested loops over nalgebra's matrices, 1e-12 relative.
    #[allow(clippy::needless_range_loop)] // the naive index loops are the point
    fn against_naive<const NX: usize, const NU: usize, const NY: usize>(seed: u64) {
        let mut seed = seed;
        let cfg = random_config::<NX, NU, NY>(&mut seed);
        let mut ss = cfg.try_build(5e-5).unwrap();
        let mut x = [0.0f64; NX];
        for _ in 0..500 {
            let e: [f64; NU] = core::array::from_fn(|_| lcg(&mut seed));
            let mut y_ref = [0.0f64; NY];
            for (i, yi) in y_ref.iter_mut().enumerate() {
                for j in 0..NX {
                    *yi += cfg.c[(i, j)] * x[j];
                }
                for j in 0..NU {
                    *yi += cfg.d[(i, j)] * e[j];
                }
            }
            let mut x_ref = [0.0f64; NX];
            for (i, xi) in x_ref.iter_mut().enumerate() {
                for j in 0..NX {
                    *xi += cfg.a[(i, j)] * x[j];
                }
                for j in 0..NU {
                    *xi += cfg.b[(i, j)] * e[j];
                }
            }
            x = x_ref;
            let y = ss.update(e);
            for i in 0..NY {
                assert!((y[i] - y_ref[i]).abs() <= 1e-12 * (1.0 + y_ref[i].abs()));
            }
            for i in 0..NX {
                assert!((ss.state()[i] - x[i]).abs() <= 1e-12 * (1.0 + x[i].abs()));
            }
        }
    }

    #[test]
    fn matches_naive_matrix_loop() {
        against_naive::<27, 1, 1>(1);
        against_naive::<8, 2, 3>(2);
        against_naive::<13, 1, 1>(3);
        against_naive::<1, 1, 1>(4);
        against_naive::<4, 3, 2>(5);
    }

    /// The row kernel (a microcontroller's) gives the column kernel's bits, state and
    /// output, over 2 000 random inputs on orders odd and even, one and two inputs.
    #[test]
    fn the_row_kernel_gives_the_column_kernels_bits() {
        fn same<const NX: usize, const NU: usize>(seed: u64) {
            let mut seed = seed;
            let cfg = random_config::<NX, NU, 1>(&mut seed);
            let entry = |i: usize, j: usize| match (i < NX, j < NX) {
                (true, true) => cfg.a[(i, j)],
                (true, false) => cfg.b[(i, j - NX)],
                (false, true) => cfg.c[(0, j)],
                (false, false) => cfg.d[(0, j - NX)],
            };
            // Each kernel on its own layout of `A`, whatever this machine's is.
            let (mut by_cols, mut by_rows) = (
                StateSpace::<NX, NU, 1>::EMPTY,
                StateSpace::<NX, NU, 1>::EMPTY,
            );
            by_cols
                .load_as(NX, entry, Limits::UNLIMITED, 5e-5, false)
                .unwrap();
            by_rows
                .load_as(NX, entry, Limits::UNLIMITED, 5e-5, true)
                .unwrap();
            for _ in 0..2000 {
                let e: [f64; NU] = core::array::from_fn(|_| lcg(&mut seed));
                let (yc, yr) = (
                    by_cols.tick_by_columns::<NX>(e),
                    by_rows.tick_by_rows::<NX>(e, true),
                );
                assert_eq!(yc[0].to_bits(), yr[0].to_bits());
                let bits = |x: &[f64; NX]| x.map(f64::to_bits);
                assert_eq!(bits(by_cols.state()), bits(by_rows.state()));
            }
        }
        same::<1, 1>(31);
        same::<2, 1>(32);
        same::<13, 1>(33);
        same::<28, 2>(34);
        same::<29, 1>(35);
        same::<40, 1>(36);
    }

    /// An order-`N` realisation loaded in place into storage for 40 states runs with the bits
    /// of a `StateSpace<N>` of the same matrices; loading another order over it starts afresh.
    #[test]
    fn a_realisation_loaded_in_place_runs_with_its_own_orders_bits() {
        fn same<const N: usize>(storage: &mut StateSpace<40, 1, 1>, seed: u64) {
            let mut seed = seed;
            let cfg = random_config::<N, 1, 1>(&mut seed);
            let mut own = cfg.try_build(5e-5).unwrap();
            let entry = |i: usize, j: usize| match (i < N, j < N) {
                (true, true) => cfg.a[(i, j)],
                (true, false) => cfg.b[(i, 0)],
                (false, true) => cfg.c[(0, j)],
                (false, false) => cfg.d[(0, 0)],
            };
            storage.load(N, entry, Limits::UNLIMITED, 5e-5).unwrap();
            for _ in 0..2000 {
                let e = [lcg(&mut seed)];
                let (y, y_own) = (storage.update_order::<N>(e), own.update(e));
                assert_eq!(y[0].to_bits(), y_own[0].to_bits());
            }
            for (a, b) in storage.state().iter().zip(own.state()) {
                assert_eq!(a.to_bits(), b.to_bits());
            }
            assert!(storage.state()[N..].iter().all(|&v| v == 0.0));
        }
        let mut storage = StateSpace::<40, 1, 1>::EMPTY;
        same::<29>(&mut storage, 41);
        same::<13>(&mut storage, 42);
        same::<1>(&mut storage, 43);
        same::<40>(&mut storage, 44);
        let bad = |i, j| if (i, j) == (2, 3) { f64::NAN } else { 0.5 };
        assert_eq!(
            storage.load(5, bad, Limits::UNLIMITED, 5e-5),
            Err(Error::NotFinite { param: "a" })
        );
        assert!(matches!(
            storage.load(41, |_, _| 0.0, Limits::UNLIMITED, 5e-5),
            Err(Error::OutOfRange { param: "order", .. })
        ));
    }

    #[test]
    fn nonfinite_input_faults_to_zero() {
        let mut seed = 9;
        let mut ss = random_config::<27, 1, 1>(&mut seed)
            .try_build(5e-5)
            .unwrap();
        ss.update([1.0]);
        assert_eq!(ss.update([f64::INFINITY]), [0.0]);
        assert!(ss.faulted());
        assert_eq!(ss.update([1.0]), [0.0]);
        ss.reset();
        assert!(!ss.faulted());
        assert_ne!(ss.update([1.0]), [0.0]);
    }

    #[test]
    fn rejects_nonfinite_matrix() {
        let mut seed = 3;
        let mut cfg = random_config::<4, 1, 1>(&mut seed);
        cfg.c[(0, 2)] = f64::NAN;
        assert_eq!(
            cfg.try_build(1e-4).unwrap_err(),
            Error::NotFinite { param: "c" }
        );
    }

    /// Every instruction set this machine has gives the tick the same bits: the baseline
    /// (SSE2), x86-64-v3 (AVX2) and x86-64-v4 (AVX-512) runs of one 27-state controller over
    /// 2 000 random inputs (levels the machine lacks run the baseline, and still agree).
    #[test]
    fn every_instruction_set_gives_the_same_bits() {
        let mut seed = 21;
        let cfg = random_config::<27, 2, 1>(&mut seed);
        let levels = [Simd::Baseline, Simd::X86_64V3, Simd::X86_64V4];
        let mut blocks = levels.map(|_| cfg.try_build(5e-6).unwrap());
        for _ in 0..2000 {
            let e = [lcg(&mut seed), lcg(&mut seed)];
            let out = core::array::from_fn::<_, 3, _>(|i| blocks[i].update_with(levels[i], e));
            for (i, o) in out.iter().enumerate() {
                assert_eq!(o[0].to_bits(), out[0][0].to_bits(), "{:?}", levels[i]);
            }
        }
        for b in &blocks[1..] {
            let bits = |x: &[f64; 27]| x.map(f64::to_bits);
            assert_eq!(bits(b.state()), bits(blocks[0].state()));
        }
    }
}
