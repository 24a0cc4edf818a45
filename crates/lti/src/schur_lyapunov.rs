//! Lyapunov and Stein equations for many right-hand sides with one matrix, by the real Schur
//! form (Bartels–Stewart): `A = U R Uᵀ` (`U` orthogonal, `R` quasi-upper-triangular — 1×1
//! diagonal blocks for real eigenvalues, 2×2 for complex pairs) is computed once (O(n³)), after
//! which each equation is a block substitution in real arithmetic (O(n³), no iteration). What
//! Newton's refinement of a Riccati solution and the Riccati condition estimate need: the
//! closed loop stays the same while the right-hand side changes.
//!
//! The Schur form is of the balanced matrix `D⁻¹AD` (the equations scaled to match) and comes
//! from faer's real QZ algorithm on the pair `(A, I)` (faer has no public real Schur):
//! `QᵀAZ = S`, `QᵀZ = T` with `T` triangular and orthogonal, hence `±1` on its diagonal, so
//! `ZᵀAZ` is quasi-triangular with `S`'s blocks; it is formed as `ZᵀAZ` and its entries below
//! the blocks, rounding, are dropped (a backward error of `ε‖A‖`) — or, should they be more
//! than rounding, nalgebra's real Schur form is taken instead.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::evd::hessenberg::{hessenberg_in_place, hessenberg_in_place_scratch};
use faer::linalg::gevd::qz_real::{hessenberg_to_qz, hessenberg_to_qz_scratch};
use faer::linalg::gevd::{ComputeEigenvectors, GeneralizedSchurParams};
use faer::linalg::householder::{
    apply_block_householder_sequence_on_the_right_in_place_scratch,
    apply_block_householder_sequence_on_the_right_in_place_with_conj,
};
use faer::linalg::qr::no_pivoting::factor::recommended_block_size;
use faer::{Auto, Col, Conj, Mat, Par};
use nalgebra::DMatrix;
use num_complex::Complex64;

/// The real Schur form `A = U R Uᵀ` of a real square matrix.
pub struct SchurForm {
    /// The balancing `D` (powers of two): the form is of `D⁻¹AD`, whose eigenvalues a matrix
    /// with rows and columns of very different sizes keeps only balanced (a closed loop of norm
    /// 10¹⁸ whose spectral radius is 0.99998).
    d: Vec<f64>,
    u: DMatrix<f64>,
    /// `Uᵀ` (products with it are matrix products, not dot products).
    ut: DMatrix<f64>,
    /// `R` and its diagonal blocks (what [`Side::Transposed`] solves on).
    upper: Blocked,
    /// `PRᵀP` (`P` the order-reversing permutation: quasi-upper-triangular again) and its
    /// blocks (what [`Side::Plain`] solves on: `RZ + ZRᵀ` is `R'ᵀZ' + Z'R'` with `Z' = PZP`).
    reversed: Blocked,
}

/// A quasi-upper-triangular matrix with the first index of each diagonal block (and `n` last).
struct Blocked {
    r: DMatrix<f64>,
    /// `Rᵀ`, for the discrete equation's `RᵀC`.
    rt: DMatrix<f64>,
    starts: Vec<usize>,
}

/// QR sweeps nalgebra's Schur iteration may take per row (LAPACK allows 30 per eigenvalue;
/// nalgebra's unbounded iteration can cycle for ever on some matrices).
const SWEEPS_PER_ROW: usize = 100;

/// How far below its blocks `UᵀAU` may be from zero, in units of `n·ε·‖A‖_F` (rounding of
/// the two products).
const REDUCTION_TOLERANCE: f64 = 64.0;

/// Which operator of `A` an equation is written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// `AᵀZ + ZA + W = 0` or `Z = AᵀZA + W` (the closed loop of a control Riccati equation).
    Transposed,
    /// `AZ + ZAᵀ + W = 0` or `Z = AZAᵀ + W` (a gramian; the adjoint of the other).
    Plain,
}

/// Which equation [`SchurForm::solve`] solves.
#[derive(Clone, Copy)]
enum Equation {
    Continuous,
    Discrete,
}

impl SchurForm {
    /// The Schur form of `a`, or `None` when `a` is not finite or neither faer's QZ nor
    /// nalgebra's Schur iteration reduces it within their sweep limits (what they leave then
    /// is not quasi-triangular, which is checked).
    pub fn new(a: &DMatrix<f64>) -> Option<Self> {
        let n = a.nrows();
        if a.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let (a, d) = crate::state_space::balance(a.clone());
        let (z, s) = real_qz(&a);
        let from_qz = blocks(n, |i, j| s[(i, j)]).and_then(|starts| {
            Self::checked(&a, &d, DMatrix::from_fn(n, n, |i, j| z[(i, j)]), starts)
        });
        from_qz.or_else(|| {
            // Should faer's QZ not reduce the matrix, nalgebra's real Schur form.
            let limit = SWEEPS_PER_ROW * n.max(1);
            let (q, t) = nalgebra::Schur::try_new(a.clone(), f64::EPSILON, limit)?.unpack();
            let starts = blocks(n, |i, j| t[(i, j)])?;
            Self::checked(&a, &d, q, starts)
        })
    }

    /// `R = UᵀAU` with its entries below the diagonal `starts` blocks dropped — `None` when
    /// they are more than rounding (`U` does not reduce `A`).
    fn checked(a: &DMatrix<f64>, d: &[f64], u: DMatrix<f64>, starts: Vec<usize>) -> Option<Self> {
        let n = a.nrows();
        let ut = u.transpose();
        let mut r = &ut * a * &u;
        let mut dropped = 0.0;
        for w in starts.windows(2) {
            for j in w[0]..w[1] {
                for i in w[1]..n {
                    dropped += r[(i, j)] * r[(i, j)];
                    r[(i, j)] = 0.0;
                }
            }
        }
        if dropped.sqrt() > REDUCTION_TOLERANCE * (n as f64) * f64::EPSILON * a.norm() {
            return None;
        }
        let reversed = DMatrix::from_fn(n, n, |i, j| r[(n - 1 - j, n - 1 - i)]);
        let reversed_starts = starts.iter().rev().map(|&s| n - s).collect();
        Some(SchurForm {
            d: d.to_vec(),
            ut,
            u,
            upper: Blocked::new(r, starts),
            reversed: Blocked::new(reversed, reversed_starts),
        })
    }

    /// The eigenvalues of `A`, from the diagonal blocks of `R` (a 2×2 block's pair by the
    /// quadratic formula).
    pub fn eigenvalues(&self) -> Vec<Complex64> {
        let r = &self.upper.r;
        let mut out = Vec::with_capacity(r.nrows());
        for w in self.upper.starts.windows(2) {
            let i = w[0];
            if w[1] - i == 1 {
                out.push(Complex64::new(r[(i, i)], 0.0));
                continue;
            }
            let (a, b, c, d) = (r[(i, i)], r[(i, i + 1)], r[(i + 1, i)], r[(i + 1, i + 1)]);
            let mid = 0.5 * (a + d);
            let discriminant = 0.25 * (a - d) * (a - d) + b * c;
            let root = if discriminant >= 0.0 {
                Complex64::new(discriminant.sqrt(), 0.0)
            } else {
                Complex64::new(0.0, (-discriminant).sqrt())
            };
            out.push(Complex64::new(mid, 0.0) + root);
            out.push(Complex64::new(mid, 0.0) - root);
        }
        out
    }

    /// `Z` with `AᵀZ + ZA + W = 0` ([`Side::Transposed`]) or `AZ + ZAᵀ + W = 0`
    /// ([`Side::Plain`]). Unique when no two eigenvalues of `A` sum to zero.
    pub fn continuous(&self, w: &DMatrix<f64>, side: Side) -> DMatrix<f64> {
        self.solve(w, side, Equation::Continuous)
    }

    /// `Z` with `Z = AᵀZA + W` ([`Side::Transposed`]) or `Z = AZAᵀ + W` ([`Side::Plain`]).
    /// Unique when no product of two eigenvalues of `A` is one.
    pub fn discrete(&self, w: &DMatrix<f64>, side: Side) -> DMatrix<f64> {
        self.solve(w, side, Equation::Discrete)
    }

    /// In Schur coordinates (`Ẑ = UᵀZU`, `Ŵ = UᵀWU`); the plain side on the reversed form.
    fn solve(&self, w: &DMatrix<f64>, side: Side, equation: Equation) -> DMatrix<f64> {
        let n = self.u.nrows();
        // In the balanced basis: `DWD` and `Z = D⁻¹ẐD⁻¹` (transposed), `D⁻¹WD⁻¹` and
        // `Z = DẐD` (plain).
        let d = &self.d;
        let scale = |i: usize, j: usize| match side {
            Side::Transposed => d[i] * d[j],
            Side::Plain => 1.0 / (d[i] * d[j]),
        };
        let w = DMatrix::from_fn(n, n, |i, j| w[(i, j)] * scale(i, j));
        let what = &self.ut * w * &self.u;
        let zhat = match side {
            Side::Transposed => self.upper.solve(&what, equation),
            Side::Plain => {
                let flip =
                    |m: &DMatrix<f64>| DMatrix::from_fn(n, n, |i, j| m[(n - 1 - i, n - 1 - j)]);
                flip(&self.reversed.solve(&flip(&what), equation))
            }
        };
        let z = &self.u * zhat * &self.ut;
        DMatrix::from_fn(n, n, |i, j| z[(i, j)] / scale(i, j))
    }
}

impl Blocked {
    fn new(r: DMatrix<f64>, starts: Vec<usize>) -> Self {
        Blocked {
            rt: r.transpose(),
            r,
            starts,
        }
    }

    /// `Z` with `RᵀZ + ZR + W = 0` or `Z = RᵀZR + W`, block column by block column: for block
    /// `J` the columns before it are known, `C = Z_{:,<J} R_{<J,J}`, and
    /// - continuous: `RᵀZ_J + Z_J R_JJ = −W_J − C`,
    /// - discrete: `Z_J − RᵀZ_J R_JJ = W_J + RᵀC`,
    ///
    /// each then solved block row by block row (`Rᵀ` is quasi-lower-triangular): with
    /// `E = Σ_{K<I} R_KIᵀ Z_KJ` from the rows solved, a Sylvester equation of at most 2×2,
    /// `R_IIᵀ Z_IJ + Z_IJ R_JJ = F_I − E` or `Z_IJ − R_IIᵀ Z_IJ R_JJ = F_I + E R_JJ`.
    fn solve(&self, w: &DMatrix<f64>, equation: Equation) -> DMatrix<f64> {
        let r = &self.r;
        let n = r.nrows();
        let rs = r.as_slice();
        let mut z = DMatrix::<f64>::zeros(n, n);
        for cols in self.starts.windows(2) {
            let (j0, q) = (cols[0], cols[1] - cols[0]);
            let known = z.columns(0, j0) * r.view((0, j0), (j0, q));
            let rhs = match equation {
                Equation::Continuous => -(w.columns(j0, q) + &known),
                Equation::Discrete => w.columns(j0, q) + &self.rt * &known,
            };
            let rjj = block(rs, n, j0, q);
            for rows in self.starts.windows(2) {
                let (i0, p) = (rows[0], rows[1] - rows[0]);
                let zs = z.as_slice();
                let mut e = [[0.0; 2]; 2];
                for (a, ea) in e.iter_mut().enumerate().take(p) {
                    let rc = &rs[(i0 + a) * n..(i0 + a) * n + i0];
                    for (b, eab) in ea.iter_mut().enumerate().take(q) {
                        *eab = dot(rc, &zs[(j0 + b) * n..(j0 + b) * n + i0]);
                    }
                }
                let mut f = [[0.0; 2]; 2];
                for (a, fa) in f.iter_mut().enumerate().take(p) {
                    for (b, fab) in fa.iter_mut().enumerate().take(q) {
                        *fab = rhs[(i0 + a, b)]
                            + match equation {
                                Equation::Continuous => -e[a][b],
                                Equation::Discrete => (0..q).map(|l| e[a][l] * rjj[l][b]).sum(),
                            };
                    }
                }
                let rii = block(rs, n, i0, p);
                let mt = [[rii[0][0], rii[1][0]], [rii[0][1], rii[1][1]]];
                let x = small_sylvester(&mt, &rjj, &f, p, q, equation);
                for (a, xa) in x.iter().enumerate().take(p) {
                    for (b, xab) in xa.iter().enumerate().take(q) {
                        z[(i0 + a, j0 + b)] = *xab;
                    }
                }
            }
        }
        z
    }
}

/// The diagonal block of size `size` at `start` of the column-major n×n matrix `rs`.
fn block(rs: &[f64], n: usize, start: usize, size: usize) -> [[f64; 2]; 2] {
    let mut b = [[0.0; 2]; 2];
    for (i, bi) in b.iter_mut().enumerate().take(size) {
        for (j, bij) in bi.iter_mut().enumerate().take(size) {
            *bij = rs[start + i + (start + j) * n];
        }
    }
    b
}

/// `Σ aᵢbᵢ` with four partial sums (vectorisable).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut s = [0.0; 4];
    let (ac, bc) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = ac
        .remainder()
        .iter()
        .zip(bc.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ac.zip(bc) {
        for k in 0..4 {
            s[k] += x[k] * y[k];
        }
    }
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}

/// `X` (p×q, p and q at most 2) with `MX + XN = F` (continuous) or `X − MXN = F` (discrete),
/// by Gaussian elimination with partial pivoting on its Kronecker form (a singular system
/// gives non-finite entries, which the caller's checks see).
fn small_sylvester(
    m: &[[f64; 2]; 2],
    n: &[[f64; 2]; 2],
    f: &[[f64; 2]; 2],
    p: usize,
    q: usize,
    equation: Equation,
) -> [[f64; 2]; 2] {
    if p == 1 && q == 1 {
        // Two real eigenvalues: `(m + n)x = f` or `(1 − mn)x = f`.
        let divisor = match equation {
            Equation::Continuous => m[0][0] + n[0][0],
            Equation::Discrete => 1.0 - m[0][0] * n[0][0],
        };
        return [[f[0][0] / divisor, 0.0], [0.0, 0.0]];
    }
    let size = p * q;
    let mut k = [[0.0f64; 5]; 4];
    // vec(X) column-major: index i + p·j. vec(MX) = (I⊗M)vec X, vec(XN) = (Nᵀ⊗I)vec X,
    // vec(MXN) = (Nᵀ⊗M)vec X.
    for j in 0..q {
        for i in 0..p {
            let row = i + p * j;
            for l in 0..q {
                for h in 0..p {
                    let identity = f64::from(u8::from(h == i && l == j));
                    k[row][h + p * l] = match equation {
                        Equation::Continuous => {
                            f64::from(u8::from(l == j)) * m[i][h]
                                + f64::from(u8::from(h == i)) * n[l][j]
                        }
                        Equation::Discrete => identity - n[l][j] * m[i][h],
                    };
                }
            }
            k[row][4] = f[i][j];
        }
    }
    for c in 0..size {
        let pivot = (c..size)
            .max_by(|&a, &b| k[a][c].abs().total_cmp(&k[b][c].abs()))
            .unwrap_or(c);
        k.swap(c, pivot);
        let top = k[c];
        for row in k.iter_mut().take(size).skip(c + 1) {
            let factor = row[c] / top[c];
            for (v, t) in row.iter_mut().zip(top).skip(c) {
                *v -= factor * t;
            }
        }
    }
    let mut x = [0.0f64; 4];
    for c in (0..size).rev() {
        let known: f64 = (c + 1..size).map(|l| k[c][l] * x[l]).sum();
        x[c] = (k[c][4] - known) / k[c][c];
    }
    let mut out = [[0.0; 2]; 2];
    for (i, oi) in out.iter_mut().enumerate().take(p) {
        for (j, oij) in oi.iter_mut().enumerate().take(q) {
            *oij = x[i + p * j];
        }
    }
    out
}

/// `(Z, S)` of the real QZ decomposition of `(a, I)`: `QᵀaZ = S` quasi-upper-triangular.
/// The Hessenberg form comes from Householder reflections (`a = V H Vᵀ`, blocked), not the
/// generalised reduction's rotations (with `I` for the second matrix, `(H, I)` is already
/// Hessenberg-triangular); the QZ sweeps then accumulate onto `V`, and `Q` is not formed.
/// `S` is updated only on the active window (faer's eigenvalues-only sweep, which still
/// accumulates every rotation into `Z`): its diagonal blocks are exact, its upper part stale,
/// so the caller forms `ZᵀaZ` itself.
fn real_qz(a: &DMatrix<f64>) -> (Mat<f64>, Mat<f64>) {
    let n = a.nrows();
    let mut s = Mat::<f64>::from_fn(n, n, |i, j| a[(i, j)]);
    let mut t = Mat::<f64>::identity(n, n);
    let mut z = Mat::<f64>::identity(n, n);
    if n == 0 {
        return (z, s);
    }
    let block = recommended_block_size::<f64>(n - 1, n - 1);
    let mut householder = Mat::<f64>::zeros(block, n - 1);
    // The unblocked double-shift sweep at every order: faer's blocked QZ (multishift sweeps
    // with aggressive early deflation) took 5–50 s on (A, I) pairs of order 76–150 in our
    // measurements (riccati at n = 80: 6.2 s against 27 ms unblocked).
    let schur = GeneralizedSchurParams {
        blocking_threshold: usize::MAX,
        ..Auto::<f64>::auto()
    };
    let mut memory = MemBuffer::new(StackReq::any_of(&[
        hessenberg_in_place_scratch::<f64>(n, block, Par::Seq, Default::default()),
        apply_block_householder_sequence_on_the_right_in_place_scratch::<f64>(n - 1, block, n),
        hessenberg_to_qz_scratch::<f64>(n, Par::Seq, schur),
    ]));
    let stack = MemStack::new(&mut memory);
    hessenberg_in_place(
        s.as_mut(),
        householder.as_mut(),
        Par::Seq,
        stack,
        Default::default(),
    );
    apply_block_householder_sequence_on_the_right_in_place_with_conj(
        s.as_ref().submatrix(1, 0, n - 1, n - 1),
        householder.as_ref(),
        Conj::No,
        z.as_mut().submatrix_mut(1, 1, n - 1, n - 1),
        Par::Seq,
        stack,
    );
    // The reflectors' vectors lie below the subdiagonal.
    for j in 0..n {
        for i in j + 2..n {
            s[(i, j)] = 0.0;
        }
    }
    // The eigenvalues (αr + iαi)/β, which the diagonal blocks of S carry too.
    let (mut re, mut im, mut beta) = (Col::<f64>::zeros(n), Col::zeros(n), Col::zeros(n));
    hessenberg_to_qz(
        s.as_mut(),
        t.as_mut(),
        None,
        Some(z.as_mut()),
        re.as_mut(),
        im.as_mut(),
        beta.as_mut(),
        ComputeEigenvectors::No,
        Par::Seq,
        schur,
        stack,
    );
    (z, s)
}

/// The first index of each diagonal block of the quasi-triangular n×n matrix with entries
/// `s(i, j)` (and `n` last), or `None` when it is not quasi-triangular (two subdiagonal entries
/// in a row: the iteration did not converge) or not finite.
fn blocks(n: usize, s: impl Fn(usize, usize) -> f64) -> Option<Vec<usize>> {
    if (0..n).any(|j| (0..n).any(|i| !s(i, j).is_finite())) {
        return None;
    }
    let mut starts = Vec::with_capacity(n + 1);
    let mut i = 0;
    while i < n {
        starts.push(i);
        let pair = i + 1 < n && s(i + 1, i) != 0.0;
        if pair && i + 2 < n && s(i + 2, i + 1) != 0.0 {
            return None;
        }
        i += if pair { 2 } else { 1 };
    }
    starts.push(n);
    Some(starts)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A nonnormal matrix with a complex pair, a real pole and a Jordan-like coupling; every
    /// equation's residual is at rounding level for symmetric and nonsymmetric right-hand sides.
    #[test]
    fn all_four_equations_hold_to_rounding() {
        let a = DMatrix::from_row_slice(
            4,
            4,
            &[
                -0.3, 2.0, 0.5, 0.0, -2.0, -0.3, 1.0, 3.0, 0.0, 0.0, -1.5, 10.0, 0.0, 0.0, 0.0,
                -0.8,
            ],
        );
        let w = DMatrix::from_fn(4, 4, |i, j| 1.0 + (i * 3 + j * 7) as f64 % 5.0);
        let ws = (&w + w.transpose()) * 0.5;
        let s = SchurForm::new(&a).unwrap();
        let ad = &a * 0.3; // spectral radius < 1 for the discrete forms
        let sd = SchurForm::new(&ad).unwrap();
        for w in [&w, &ws] {
            let scale = w.norm();
            let z = s.continuous(w, Side::Transposed);
            assert!((a.transpose() * &z + &z * &a + w).norm() < 1e-13 * scale);
            let z = s.continuous(w, Side::Plain);
            assert!((&a * &z + &z * a.transpose() + w).norm() < 1e-13 * scale);
            let z = sd.discrete(w, Side::Transposed);
            assert!((ad.transpose() * &z * &ad + w - &z).norm() < 1e-13 * scale);
            let z = sd.discrete(w, Side::Plain);
            assert!((&ad * &z * ad.transpose() + w - &z).norm() < 1e-13 * scale);
        }
    }

    /// Larger nonnormal matrices with many complex pairs and real eigenvalues: the residual of
    /// each equation is at rounding relative to the sizes of its terms.
    #[test]
    fn many_blocks_hold_to_rounding() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(42);
        let mut next = move || rng.random::<f64>() - 0.5;
        for n in [7, 30, 61] {
            let raw = DMatrix::from_fn(n, n, |_, _| next());
            let radius = crate::eigenvalues(&raw)
                .iter()
                .map(|l| l.norm())
                .fold(0.0, f64::max);
            // Continuous: shifted left of the axis; discrete: scaled inside the circle.
            let a = &raw - DMatrix::identity(n, n) * (radius + 0.1);
            let ad = &raw / (radius * 1.1);
            let w = DMatrix::from_fn(n, n, |_, _| next());
            let s = SchurForm::new(&a).unwrap();
            let sd = SchurForm::new(&ad).unwrap();
            assert!(s.upper.starts.len() < n + 1, "no complex pair at n = {n}");
            // The blocks' eigenvalues are the matrix's (each near one of the reference's).
            let reference = crate::eigenvalues(&a);
            for l in s.eigenvalues() {
                let nearest = reference
                    .iter()
                    .map(|r| (r - l).norm())
                    .fold(f64::INFINITY, f64::min);
                assert!(nearest < 1e-10 * radius, "{l} at n = {n}");
            }
            let tol = 1e-13 * n as f64;
            for side in [Side::Transposed, Side::Plain] {
                let op = |m: &DMatrix<f64>| match side {
                    Side::Transposed => m.transpose(),
                    Side::Plain => m.clone(),
                };
                let z = s.continuous(&w, side);
                let (left, right) = (op(&a) * &z, &z * op(&a).transpose());
                let terms = left.norm() + right.norm() + w.norm();
                assert!((left + right + &w).norm() < tol * terms, "{side:?} n = {n}");
                let z = sd.discrete(&w, side);
                let middle = op(&ad) * &z * op(&ad).transpose();
                let terms = middle.norm() + w.norm() + z.norm();
                assert!((middle + &w - &z).norm() < tol * terms, "{side:?} n = {n}");
            }
        }
    }
}
