//! Zero-phase-error tracking control (Tomizuka, 1987, ASME J. Dyn. Sys. 109:65–68) designed
//! from a discrete closed-loop model from reference to output.
//!
//! With the loop written `T(z⁻¹) = z⁻ᵈ B_a(z⁻¹) B_u(z⁻¹) / A(z⁻¹)` — `B_a` the zeros that may be
//! inverted, `B_u` the rest (outside or near the unit circle, or oscillatory on the negative real
//! axis) — the feedforward
//!
//! ```text
//! F(z) = zᵈ A(z⁻¹) B_u(z) / (B_a(z⁻¹) B_u(1)²)
//! ```
//!
//! makes `T·F = B_u(z⁻¹) B_u(z) / B_u(1)²`: real (zero phase) at every frequency and 1 at DC.
//! `F` needs `d + s` ticks of preview (`s` = the order of `B_u`). The model is first reduced
//! by balanced truncation (a sampled loop at 200 kHz has 30 states, most of them noise filters
//! the reference never reaches); `F` is returned as second-order sections, each zero of `F`
//! paired with its nearest pole, because the expanded polynomials of a 200 kHz loop (poles
//! near z = 1) lose most of their digits.

use lti::reduce::Balancing;
use lti::{eigenvalues, LtiError, StateSpace};
use num_complex::Complex64;

/// Zeros of `T` inside this radius on the negative real half-plane are inverted; beyond it they
/// would make `F` ring at Nyquist and are treated like zeros outside the unit circle.
pub const NEGATIVE_ZERO_RADIUS: f64 = 0.5;

/// Generalized eigenvalues larger than `1 / FINITE_ZERO` are the pencil's infinite ones.
const FINITE_ZERO: f64 = 1e-10;

/// Zeros closer to the unit circle than this are not inverted.
pub const UNIT_CIRCLE_MARGIN: f64 = 1e-6;

/// Largest gain `|F|` a design may have anywhere up to Nyquist. `F` inverts a loop that rolls
/// off, so it rises above the loop's bandwidth — to 10⁴–10⁵ at Nyquist for the thesis loops —
/// but a reduced model with a zero just outside the unit circle near DC (a truncation
/// artefact, or a slow non-minimum-phase zero) makes the zero-phase compensation divide by
/// `B_u(1)² ≈ 0` and lifts `|F|` to 10⁹–10¹²: the reference's own rounding would then saturate
/// the DAC. Such an order is passed over.
pub const MAX_GAIN: f64 = 1e6;

/// A ZPETC design.
#[derive(Debug, Clone)]
pub struct ZpetcDesign {
    /// Overall gain of `F` after the sections (each section has unity DC gain).
    pub gain: f64,
    /// Sections `[b0, b1, b2, a1, a2]` of `F·z^{-preview}` with `a0 = 1`.
    pub sections: Vec<[f64; 5]>,
    /// Ticks of preview `d + s`.
    pub preview: usize,
    /// Order of the reduced model the filter inverts.
    pub order: usize,
    /// Zeros of the reduced model that were not inverted (z-plane).
    pub unacceptable_zeros: Vec<Complex64>,
    /// Largest relative error `|T_r − T| / |T|` of the reduced model on the check grid.
    pub model_error: f64,
}

impl ZpetcDesign {
    /// `F(e^{j2πfT})` including the preview advance, at `f_hz` for period `period_s`.
    pub fn response(&self, f_hz: f64, period_s: f64) -> Complex64 {
        let z = Complex64::from_polar(1.0, 2.0 * std::f64::consts::PI * f_hz * period_s);
        let zi = 1.0 / z;
        let sections: Complex64 = self
            .sections
            .iter()
            .map(|&[b0, b1, b2, a1, a2]| (b0 + zi * (b1 + zi * b2)) / (1.0 + zi * (a1 + zi * a2)))
            .product();
        self.gain * sections * z.powi(self.preview as i32)
    }

    /// The largest `|F|` from DC to Nyquist (2000 points) and where it is, Hz.
    pub fn peak_gain(&self, period_s: f64) -> (f64, f64) {
        let nyquist = 0.5 / period_s;
        (0..=2000)
            .map(|i| {
                let f = nyquist * i as f64 / 2000.0;
                (self.response(f, period_s).norm(), f)
            })
            .fold((0.0, 0.0), |a, b| if b.0 > a.0 { b } else { a })
    }
}

/// Errors of [`design`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ZpetcError {
    /// The model is not a SISO discrete model.
    #[error("ZPETC needs a single-input single-output model, got {0}×{1}")]
    NotSiso(usize, usize),
    /// A linear-algebra step failed.
    #[error(transparent)]
    Lti(#[from] LtiError),
    /// Every reduced order that matches the model makes a filter louder than [`MAX_GAIN`].
    #[error("every reduced model that matches the loop makes a filter with a gain of {peak:.1e} at {at_hz:.0} Hz (at most {MAX_GAIN:.0e}: the reference's rounding would saturate the DAC); its model's zeros outside the unit circle: {zeros}")]
    TooLoud {
        /// The quietest such filter's largest gain.
        peak: f64,
        /// Where, Hz.
        at_hz: f64,
        /// That model's zeros that were not inverted (z-plane), as text.
        zeros: String,
    },
    /// No reduced order up to the limit matches the model well enough.
    #[error("no reduced model of order ≤ {max_order} matches the loop within {tolerance} up to {f_check_hz:.0} Hz (best {best:.2e})")]
    NoFit {
        /// Largest order tried.
        max_order: usize,
        /// Required relative accuracy.
        tolerance: f64,
        /// Upper end of the check band in Hz.
        f_check_hz: f64,
        /// Best relative error reached.
        best: f64,
    },
}

/// Designs the ZPETC of the stable SISO discrete loop `sys` (period `period_s`): the smallest
/// balanced truncation of order ≤ `max_order` whose response matches `sys` within `tolerance`
/// (relative) from 1 Hz to `f_check_hz` and whose inverse stays within [`MAX_GAIN`],
/// factored and inverted as above.
pub fn design(
    sys: &StateSpace,
    period_s: f64,
    max_order: usize,
    f_check_hz: f64,
    tolerance: f64,
) -> Result<ZpetcDesign, ZpetcError> {
    if sys.nu() != 1 || sys.ny() != 1 {
        return Err(ZpetcError::NotSiso(sys.ny(), sys.nu()));
    }
    let grid = lti::spectral::log_space(1.0, f_check_hz, 200);
    let response = lti::FrequencyResponse::new(sys);
    let full: Vec<Complex64> = grid
        .iter()
        .map(|&f| Ok(response.discrete(f, period_s)?[(0, 0)]))
        .collect::<Result<_, LtiError>>()?;
    let dc_full = sys.freq_response_discrete(0.0, period_s)?[(0, 0)].re;
    let balancing = Balancing::new(sys)?;
    let mut best = f64::INFINITY;
    // The quietest design that matched but was too loud: (peak, at Hz, design).
    let mut quietest: Option<(f64, f64, ZpetcDesign)> = None;
    for order in 1..=max_order.min(sys.nx()) {
        let reduced = balancing.truncate(order).sys;
        let Some(zpk) = Zpk::of(&reduced) else {
            continue;
        };
        let error = grid
            .iter()
            .zip(&full)
            .map(|(&f, t)| (zpk.response(f, period_s) - t).norm() / t.norm())
            .fold(0.0, f64::max);
        best = best.min(error);
        if error <= tolerance {
            let design = zpk.inverse(order, error, dc_full);
            let (peak, at_hz) = design.peak_gain(period_s);
            if peak <= MAX_GAIN {
                return Ok(design);
            }
            if quietest.as_ref().is_none_or(|q| peak < q.0) {
                quietest = Some((peak, at_hz, design));
            }
        }
    }
    if let Some((peak, at_hz, design)) = quietest {
        let zeros: Vec<String> = design
            .unacceptable_zeros
            .iter()
            .map(|q| format!("{:.4}{:+.4}j", q.re, q.im))
            .collect();
        return Err(ZpetcError::TooLoud {
            peak,
            at_hz,
            zeros: zeros.join(", "),
        });
    }
    Err(ZpetcError::NoFit {
        max_order,
        tolerance,
        f_check_hz,
        best,
    })
}

/// `T(z) = k Π(z − zeros) / Π(z − poles)`.
struct Zpk {
    k: f64,
    zeros: Vec<Complex64>,
    poles: Vec<Complex64>,
    /// `T(1)`.
    dc: f64,
}

impl Zpk {
    /// The zero-pole-gain form of a SISO model: the zeros are the finite generalized
    /// eigenvalues of the system pencil `([A B; C D], [I 0; 0 0])` (QZ, no polynomial is ever
    /// formed); the gain matches the DC response. None when the DC gain is zero.
    fn of(sys: &StateSpace) -> Option<Zpk> {
        let n = sys.nx();
        let poles = eigenvalues(&sys.a);
        let m = faer::Mat::<f64>::from_fn(n + 1, n + 1, |i, j| match (i < n, j < n) {
            (true, true) => sys.a[(i, j)],
            (true, false) => sys.b[(i, 0)],
            (false, true) => sys.c[(0, j)],
            (false, false) => sys.d[(0, 0)],
        });
        let e =
            faer::Mat::<f64>::from_fn(n + 1, n + 1, |i, j| if i == j && i < n { 1.0 } else { 0.0 });
        let gevd =
            faer::linalg::solvers::GeneralizedEigen::new_from_real(m.as_ref(), e.as_ref()).ok()?;
        let (alpha, beta) = (gevd.S_a(), gevd.S_b());
        let zeros: Vec<Complex64> = (0..=n)
            .filter_map(|i| {
                let (a, b) = (alpha[i], beta[i]);
                let (a, b) = (Complex64::new(a.re, a.im), Complex64::new(b.re, b.im));
                (b.norm() > FINITE_ZERO * a.norm()).then(|| a / b)
            })
            .collect();
        let dc = sys.freq_response_discrete(0.0, 1.0).ok()?[(0, 0)].re;
        let one = Complex64::new(1.0, 0.0);
        let shape: Complex64 = zeros.iter().map(|q| one - q).product::<Complex64>()
            / poles.iter().map(|p| one - p).product::<Complex64>();
        (dc != 0.0).then(|| Zpk {
            k: dc / shape.re,
            zeros,
            poles,
            dc,
        })
    }

    fn response(&self, f_hz: f64, period_s: f64) -> Complex64 {
        let z = Complex64::from_polar(1.0, 2.0 * std::f64::consts::PI * f_hz * period_s);
        let num: Complex64 = self.zeros.iter().map(|q| z - q).product();
        let den: Complex64 = self.poles.iter().map(|p| z - p).product();
        self.k * num / den
    }

    /// The ZPETC of this model, scaled so that it inverts the full loop's DC gain `dc_full`.
    fn inverse(&self, order: usize, model_error: f64, dc_full: f64) -> ZpetcDesign {
        let (accepted, rejected): (Vec<Complex64>, Vec<Complex64>) =
            self.zeros.iter().partition(|q| invertible(**q));
        let d = self.poles.len() - self.zeros.len();
        // F·z^{-(d+s)} = G Π(1 − p z⁻¹) Π(1 − z⁻¹/q_u) / Π(1 − q_a z⁻¹),
        // G = Π(−q_u) / (k B_u(1)²), B_u(1) = Π(1 − q_u).
        let mirrored: Vec<Complex64> = rejected.iter().map(|q| 1.0 / q).collect();
        let numerator: Vec<Complex64> = self.poles.iter().chain(&mirrored).copied().collect();
        let bu1: Complex64 = rejected.iter().map(|q| 1.0 - q).product();
        let neg: Complex64 = rejected.iter().map(|q| -q).product();
        let mut gain = (neg / (self.k * bu1 * bu1)).re;
        let sections = sections(&numerator, &accepted);
        // Unity-DC sections; the gain carries the rest, matched to the full loop's DC gain.
        let sections: Vec<[f64; 5]> = sections
            .into_iter()
            .map(|[b0, b1, b2, a1, a2]| {
                let dc = (b0 + b1 + b2) / (1.0 + a1 + a2);
                gain *= dc;
                [b0 / dc, b1 / dc, b2 / dc, a1, a2]
            })
            .collect();
        ZpetcDesign {
            gain: gain * self.dc / dc_full,
            sections,
            preview: d + rejected.len(),
            order,
            unacceptable_zeros: rejected,
            model_error,
        }
    }
}

/// Whether the zero `q` of the loop may become a pole of the feedforward.
fn invertible(q: Complex64) -> bool {
    q.norm() < 1.0 - UNIT_CIRCLE_MARGIN && !(q.re < 0.0 && q.norm() >= NEGATIVE_ZERO_RADIUS)
}

/// Roots grouped into real second-order factors: conjugate pairs together, real roots two by
/// two (closest to the unit circle first); each group as `[c1, c2]` of `1 + c1 z⁻¹ + c2 z⁻²`.
fn factors(roots: &[Complex64]) -> Vec<(Complex64, [f64; 2])> {
    const IMAG: f64 = 1e-9;
    let mut complex: Vec<Complex64> = roots.iter().filter(|r| r.im > IMAG).copied().collect();
    complex.sort_by(|a, b| b.norm().total_cmp(&a.norm()));
    let mut real: Vec<f64> = roots
        .iter()
        .filter(|r| r.im.abs() <= IMAG)
        .map(|r| r.re)
        .collect();
    real.sort_by(|a, b| b.abs().total_cmp(&a.abs()));
    let mut out: Vec<(Complex64, [f64; 2])> = complex
        .into_iter()
        .map(|r| (r, [-2.0 * r.re, r.norm_sqr()]))
        .collect();
    for pair in real.chunks(2) {
        let (c1, c2) = match *pair {
            [a, b] => (-(a + b), a * b),
            [a] => (-a, 0.0),
            _ => unreachable!("chunks of two"),
        };
        out.push((Complex64::new(pair[0], 0.0), [c1, c2]));
    }
    out
}

/// Second-order sections `[b0, b1, b2, a1, a2]` of `Π(1 − n z⁻¹) / Π(1 − d z⁻¹)`: each
/// denominator factor paired with the nearest numerator factor (near-cancelling pairs keep
/// every section's gain close to 1), the leftover numerator factors on their own.
fn sections(numerator: &[Complex64], denominator: &[Complex64]) -> Vec<[f64; 5]> {
    let mut nums = factors(numerator);
    let mut out = Vec::new();
    for (d_root, [a1, a2]) in factors(denominator) {
        let [b1, b2] = if nums.is_empty() {
            [0.0, 0.0]
        } else {
            let nearest = (0..nums.len())
                .min_by(|&i, &j| {
                    (nums[i].0 - d_root)
                        .norm()
                        .total_cmp(&(nums[j].0 - d_root).norm())
                })
                .expect("not empty");
            nums.swap_remove(nearest).1
        };
        out.push([1.0, b1, b2, a1, a2]);
    }
    out.extend(
        nums.into_iter()
            .map(|(_, [b1, b2])| [1.0, b1, b2, 0.0, 0.0]),
    );
    out
}
