//! An independent reference for a continuous Riccati solution: Newton's method with the
//! residual formed in double-double arithmetic (about 32 digits, from error-free products and
//! sums) and the iterate kept as a double-double, so that what limits the reference is the
//! equation, not rounding in `f64`.

use lti::schur_lyapunov::{SchurForm, Side};
use nalgebra::DMatrix;

/// A double-double number `hi + lo`, `|lo| ≤ ulp(hi)/2`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Dd(f64, f64);

fn quick_two_sum(a: f64, b: f64) -> Dd {
    let s = a + b;
    Dd(s, b - (s - a))
}

fn two_sum(a: f64, b: f64) -> Dd {
    let s = a + b;
    let bb = s - a;
    Dd(s, (a - (s - bb)) + (b - bb))
}

impl std::ops::Add for Dd {
    type Output = Dd;
    fn add(self, y: Dd) -> Dd {
        let s = two_sum(self.0, y.0);
        quick_two_sum(s.0, s.1 + self.1 + y.1)
    }
}

impl std::ops::Mul for Dd {
    type Output = Dd;
    fn mul(self, y: Dd) -> Dd {
        let p = self.0 * y.0;
        let e = self.0.mul_add(y.0, -p) + (self.0 * y.1 + self.1 * y.0);
        quick_two_sum(p, e)
    }
}

impl std::ops::Neg for Dd {
    type Output = Dd;
    fn neg(self) -> Dd {
        Dd(-self.0, -self.1)
    }
}

fn dd(m: &DMatrix<f64>) -> DMatrix<Dd> {
    m.map(|v| Dd(v, 0.0))
}

fn product(a: &DMatrix<Dd>, b: &DMatrix<Dd>) -> DMatrix<Dd> {
    DMatrix::from_fn(a.nrows(), b.ncols(), |i, j| {
        (0..a.ncols()).fold(Dd::default(), |s, k| s + a[(i, k)] * b[(k, j)])
    })
}

/// `AᵀX + XA − XBBᵀX + Q` (the CARE with `R = I`, no cross term) in double-double.
fn residual(a: &DMatrix<Dd>, b: &DMatrix<Dd>, q: &DMatrix<Dd>, x: &DMatrix<Dd>) -> DMatrix<Dd> {
    let xb = product(x, b);
    let coupled = product(&xb, &xb.transpose());
    let ax = product(&a.transpose(), x);
    DMatrix::from_fn(x.nrows(), x.ncols(), |i, j| {
        ax[(i, j)] + ax[(j, i)] + -coupled[(i, j)] + q[(i, j)]
    })
}

/// The stabilising solution of `AᵀX + XA − XBBᵀX + Q = 0` to well beyond `f64`'s rounding,
/// refined from `x` by double-double Newton steps, and the size of each correction (relative
/// to `‖X‖`; falling fast when the reference has converged).
pub fn care_reference(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    x: &DMatrix<f64>,
    steps: usize,
) -> (DMatrix<f64>, Vec<f64>) {
    let (ad, bd, qd) = (dd(a), dd(b), dd(q));
    let mut xd = dd(x);
    let mut corrections = Vec::new();
    for _ in 0..steps {
        let hi = xd.map(|v| v.0);
        let closed = a - b * b.transpose() * &hi;
        let res = residual(&ad, &bd, &qd, &xd).map(|v| v.0 + v.1);
        let schur = SchurForm::new(&closed).expect("the closed loop's Schur form");
        let delta = schur.continuous(&res, Side::Transposed);
        let delta = (&delta + delta.transpose()) * 0.5;
        corrections.push(delta.norm() / hi.norm());
        xd = DMatrix::from_fn(x.nrows(), x.ncols(), |i, j| {
            xd[(i, j)] + Dd(delta[(i, j)], 0.0)
        });
    }
    (xd.map(|v| v.0 + v.1), corrections)
}
