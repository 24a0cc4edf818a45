//! The simulator's whole tick as one affine map, laid out for the hot loop.

use nalgebra::DMatrix;
use servo_core::{mul_add, simd};

/// Rows of the tick matrix handled together, kept in registers; columns are split by index
/// modulo 4 into separate accumulators (independent multiply-add chains).
const ROW_GROUP: usize = 8;

/// The whole tick as one affine map of `z = [x_k, command per interval, f_cut, w_i, w_g, w_a]`:
/// rows `[x_{k+1} (n), ADC conversions (2 per conversion), truth (7)]`, stored column-major
/// with the row count padded to a multiple of [`ROW_GROUP`] so the product is whole SIMD
/// vectors whose accumulators stay in registers.
#[derive(Debug, Clone)]
pub(crate) struct TickMatrix {
    /// Rows (padded to a multiple of [`ROW_GROUP`]).
    pub(crate) rows: usize,
    /// Entries, column-major.
    pub(crate) cols: Vec<f64>,
}

impl TickMatrix {
    pub(crate) fn new(blocks: &[DMatrix<f64>]) -> Self {
        let stacked = blocks.iter().map(|b| b.nrows()).sum::<usize>();
        let rows = stacked.div_ceil(ROW_GROUP) * ROW_GROUP;
        let ncols = blocks[0].ncols();
        let mut cols = vec![0.0; rows * ncols];
        let mut r0 = 0;
        for b in blocks {
            for (j, col) in cols.chunks_exact_mut(rows).enumerate() {
                for i in 0..b.nrows() {
                    col[r0 + i] = b[(i, j)];
                }
            }
            r0 += b.nrows();
        }
        TickMatrix { rows, cols }
    }

    /// `out = M z` (`out.len() == rows`), with the widest vector instructions this machine
    /// has ([`simd`]; the same result on every CPU).
    #[inline]
    pub(crate) fn apply(&self, z: &[f64], out: &mut [f64]) {
        simd::vectorised(
            #[inline(always)]
            || self.product(z, out),
        );
    }

    #[inline(always)]
    fn product(&self, z: &[f64], out: &mut [f64]) {
        let column = |j: usize, r0: usize| -> &[f64; ROW_GROUP] {
            self.cols[j * self.rows + r0..][..ROW_GROUP]
                .try_into()
                .expect("padded rows")
        };
        for (g, block) in out.chunks_exact_mut(ROW_GROUP).enumerate() {
            let r0 = g * ROW_GROUP;
            let mut acc = [[0.0f64; ROW_GROUP]; 4];
            let (quads, rest) = z.as_chunks::<4>();
            for (q, zz) in quads.iter().enumerate() {
                for (k, a) in acc.iter_mut().enumerate() {
                    let c = column(4 * q + k, r0);
                    for l in 0..ROW_GROUP {
                        a[l] = mul_add(c[l], zz[k], a[l]);
                    }
                }
            }
            for (k, &zl) in rest.iter().enumerate() {
                let c = column(4 * quads.len() + k, r0);
                for l in 0..ROW_GROUP {
                    acc[k][l] = mul_add(c[l], zl, acc[k][l]);
                }
            }
            for (l, o) in block.iter_mut().enumerate() {
                *o = (acc[0][l] + acc[1][l]) + (acc[2][l] + acc[3][l]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;
    use servo_core::simd::Simd;

    /// The product gives the same bits with every instruction set (baseline, AVX2, AVX-512;
    /// levels this machine lacks run the baseline), and equals the plain row-by-column sums
    /// to rounding.
    #[test]
    fn every_instruction_set_gives_the_same_bits() {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(9);
        let mut rnd = move || rng.random::<f64>() - 0.5;
        let blocks = [
            DMatrix::from_fn(13, 23, |_, _| rnd()),
            DMatrix::from_fn(9, 23, |_, _| rnd()),
        ];
        let m = TickMatrix::new(&blocks);
        let z: Vec<f64> = (0..23).map(|_| rnd() * 1e3).collect();
        let run = |simd: Simd| {
            let mut out = vec![0.0; m.rows];
            simd::with(
                simd,
                #[inline(always)]
                || m.product(&z, &mut out),
            );
            out
        };
        let base = run(Simd::Baseline);
        for simd in [Simd::X86_64V3, Simd::X86_64V4] {
            let got = run(simd);
            assert!(
                got.iter()
                    .zip(&base)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{simd:?}"
            );
        }
        let stacked = [blocks[0].clone(), blocks[1].clone()];
        for (r, want) in stacked
            .iter()
            .flat_map(|b| {
                b.row_iter()
                    .map(|row| row.iter().zip(&z).map(|(a, x)| a * x).sum::<f64>())
                    .collect::<Vec<_>>()
            })
            .enumerate()
        {
            assert!(
                (base[r] - want).abs() < 1e-9,
                "row {r}: {} vs {want}",
                base[r]
            );
        }
    }
}
