//! PID tuning by convex-concave programming (Hast, Åström, Bernhardsson & Boyd, "PID design by
//! convex-concave optimization", ECC 2013), each step a linear program solved by clarabel.
//!
//! The controller is linear in its gains, `C(jω) = Σᵢ kᵢ Bᵢ(jω)` (`Bᵢ`: the responses of the
//! discrete PID with one unit gain), so the loop `L = P·C` is too. Wanted:
//!
//! - maximise `ki` — the integral gain sets the rejection of low-frequency load disturbances
//!   (the integrated error of a load step is `1/ki`, the IE criterion);
//! - subject to `|S(jω)| = 1/|1 + L(jω)| ≤ Ms` and `|T(jω)| = |L|/|1 + L| ≤ Mt` on a
//!   frequency grid (robustness, and no closed-loop peaking that a large `ki` would bring), and
//!   `|T(j2πf)| ≥ 1/√2` at every grid frequency up to `f_b` (the bandwidth as the runner
//!   defines it, the first −3 dB crossing, is then at least `f_b`: a dip below −3 dB before
//!   `f_b`, as at the m4 mode, does not pass).
//!
//! All three are `|c + L(jω)| ≥ r` — the outside of a disc, not convex: `c = 1, r = 1/Ms`;
//! `|T| ≤ Mt` is the outside of the Apollonius circle `c = Mt²/(Mt² − 1), r = Mt/(Mt² − 1)`;
//! `|T| ≥ 1/√2` is `|L − 1| ≥ √2`, `c = −1, r = √2`. Linearised at
//! the gains of iteration j, with `ū = conj(c + L_j)/|c + L_j|`, the constraint
//! `Re{ū (c + L)} ≥ r` is a half-plane inside the true feasible set (`|z| ≥ Re{ū z}` for
//! `|ū| = 1`): every iterate is feasible on the grid and the objective never gets worse; the
//! iteration stops when it no longer improves. The bandwidth row carries a penalised slack,
//! so a start below the bandwidth still gives a feasible program; a bandwidth the peak bounds
//! forbid ends in [`TuneError::Unreachable`] with the best `|T(f_b)|` found.

use num_complex::Complex64;

/// One PID tuning problem on a frequency grid.
#[derive(Debug, Clone)]
pub struct PidTuning {
    /// Grid frequencies in Hz (log-spaced to Nyquist is typical; denser near crossover helps).
    pub freq_hz: Vec<f64>,
    /// Plant response `P(jω)` at each frequency: controller output → measured signal, so that
    /// the loop with negative feedback is `L = P·C`.
    pub plant: Vec<Complex64>,
    /// Controller responses per unit gain `[B_kp, B_ki, B_kd](jω)` at each frequency.
    pub basis: Vec<[Complex64; 3]>,
    /// Sensitivity peak bound `Ms` (> 1), e.g. 1.5–2.
    pub ms: f64,
    /// Complementary sensitivity peak bound `Mt` (> 1), e.g. 1.3–2.
    pub mt: f64,
    /// Required closed-loop bandwidth in Hz: `|T| ≥ 1/√2` at every grid frequency up to the
    /// one nearest to it.
    pub bandwidth_hz: f64,
    /// Upper bounds on `[kp, ki, kd]` (keeps every LP bounded).
    pub upper: [f64; 3],
}

/// The tuned gains and how they were reached (see [`PidTuning::evaluate`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidTuned {
    /// `[kp, ki, kd]`.
    pub gains: [f64; 3],
    /// Linear programs solved.
    pub iterations: usize,
    /// Largest `|S|` on the grid.
    pub max_sensitivity: f64,
    /// Smallest `|T|` on the grid up to the bandwidth (≥ 1/√2: solutions are only returned
    /// when it is).
    pub t_up_to_bandwidth: f64,
}

/// Tuning errors.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum TuneError {
    /// The problem data are inconsistent.
    #[error("PID tuning: {0}")]
    Invalid(String),
    /// The start violates `|S| ≤ Ms` or `|T| ≤ Mt` somewhere on the grid.
    #[error("PID tuning: the starting gains have max |S| = {0:.3}, max |T| = {1:.3} beyond Ms, Mt; start from a gentler PID")]
    InfeasibleStart(f64, f64),
    /// No gains meet the bandwidth under the peak bounds (the best found: the smallest `|T|`
    /// up to `f_b`, in dB).
    #[error("PID tuning: the bandwidth is out of reach under the Ms, Mt bounds (the best gains' |T| falls to {0:.2} dB below it, −3 dB needed); lower the bandwidth or raise Ms/Mt")]
    Unreachable(f64),
    /// clarabel did not solve a step.
    #[error("PID tuning: the linear program of iteration {0} ended {1}")]
    Solver(usize, String),
}

impl PidTuning {
    /// The loop gain `L = P·C` at grid point `i` for gains `k = [kp, ki, kd]`.
    pub fn loop_gain(&self, i: usize, k: &[f64; 3]) -> Complex64 {
        let b = &self.basis[i];
        self.plant[i] * (b[0] * k[0] + b[1] * k[1] + b[2] * k[2])
    }

    /// The grid index of the bandwidth frequency.
    fn bandwidth_index(&self) -> usize {
        let d = |f: f64| libm::log(f / self.bandwidth_hz).abs();
        (0..self.freq_hz.len())
            .min_by(|&a, &b| d(self.freq_hz[a]).total_cmp(&d(self.freq_hz[b])))
            .unwrap_or(0)
    }

    /// Largest `|S|`, largest `|T|` on the grid, and the smallest `|T|` on the grid up to the
    /// bandwidth, for gains `k`.
    pub fn evaluate(&self, k: &[f64; 3]) -> (f64, f64, f64) {
        let (mut max_s, mut max_t, mut min_t) = (0.0f64, 0.0f64, f64::INFINITY);
        let bw = self.bandwidth_index();
        for i in 0..self.freq_hz.len() {
            let l = self.loop_gain(i, k);
            let one_l = (Complex64::new(1.0, 0.0) + l).norm();
            max_s = max_s.max(1.0 / one_l);
            max_t = max_t.max(l.norm() / one_l);
            if self.freq_hz[i] <= self.freq_hz[bw] {
                min_t = min_t.min(l.norm() / one_l);
            }
        }
        (max_s, max_t, min_t)
    }

    fn check(&self) -> Result<(), TuneError> {
        let n = self.freq_hz.len();
        if n == 0 || self.plant.len() != n || self.basis.len() != n {
            return Err(TuneError::Invalid(format!(
                "{n} frequencies, {} plant and {} basis responses",
                self.plant.len(),
                self.basis.len()
            )));
        }
        let valid = self.ms > 1.0 && self.mt > 1.0 && self.bandwidth_hz > 0.0;
        if !valid {
            return Err(TuneError::Invalid(format!(
                "Ms = {}, Mt = {} (allowed > 1), bandwidth {} Hz (allowed > 0)",
                self.ms, self.mt, self.bandwidth_hz
            )));
        }
        Ok(())
    }

    /// Runs the convex-concave iteration from `start` (which must satisfy `|S| ≤ Ms` on the
    /// grid), at most `max_iterations` linear programs in all.
    ///
    /// `|T| ≥ 1/√2` is imposed at the bandwidth first; where the solution's `|T|` still falls
    /// below it at a lower grid frequency (a dip, e.g. at a parasitic mode), that frequency
    /// joins the constraints and the iteration resumes from the solution — a cutting-plane
    /// loop, so each constraint is linearised near where `|T|` already is rather than deep
    /// inside the excluded disk, where its tangent would point the wrong way.
    pub fn solve(&self, start: [f64; 3], max_iterations: usize) -> Result<PidTuned, TuneError> {
        self.check()?;
        let (s0, t0, _) = self.evaluate(&start);
        if s0 > self.ms * (1.0 + 1e-9) || t0 > self.mt * (1.0 + 1e-9) {
            return Err(TuneError::InfeasibleStart(s0, t0));
        }
        let bw = self.bandwidth_index();
        let mut held = vec![bw];
        let mut k = start;
        let mut iterations = 0;
        while iterations < max_iterations {
            k = self.iterate(k, &held, max_iterations - iterations, &mut iterations)?;
            let below = |i: &usize| {
                self.closed_loop_gain(*i, &k) < std::f64::consts::FRAC_1_SQRT_2 * (1.0 - 1e-6)
            };
            if held.iter().any(below) {
                break; // out of reach: reported below
            }
            let dip = (0..bw)
                .filter(|i| !held.contains(i))
                .map(|i| (i, self.closed_loop_gain(i, &k)))
                .filter(|&(_, t)| t < std::f64::consts::FRAC_1_SQRT_2)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            match dip {
                Some((i, _)) => held.push(i),
                None => break,
            }
        }
        let (max_sensitivity, _, t_up_to_bandwidth) = self.evaluate(&k);
        if t_up_to_bandwidth < std::f64::consts::FRAC_1_SQRT_2 * (1.0 - 1e-6) {
            return Err(TuneError::Unreachable(
                20.0 * libm::log10(t_up_to_bandwidth),
            ));
        }
        Ok(PidTuned {
            gains: k,
            iterations,
            max_sensitivity,
            t_up_to_bandwidth,
        })
    }

    /// `|T|` at grid point `i` for gains `k`.
    fn closed_loop_gain(&self, i: usize, k: &[f64; 3]) -> f64 {
        let l = self.loop_gain(i, k);
        l.norm() / (Complex64::new(1.0, 0.0) + l).norm()
    }

    /// The convex-concave iteration from `k` with `|T| ≥ 1/√2` held at the grid points
    /// `held`: at most `budget` linear programs, counted in `iterations`.
    fn iterate(
        &self,
        mut k: [f64; 3],
        held: &[usize],
        budget: usize,
        iterations: &mut usize,
    ) -> Result<[f64; 3], TuneError> {
        let mt2 = self.mt * self.mt;
        let (t_centre, t_radius) = (mt2 / (mt2 - 1.0), self.mt / (mt2 - 1.0));
        // Variables: the gains scaled by the upper bounds (order 1), then one slack.
        let scale = self.upper;
        let mut last_objective = f64::INFINITY;
        // The penalty makes any bandwidth deficit cost more than all the ki there is.
        let penalty = 1e3;
        for _ in 0..budget {
            *iterations += 1;
            let it = *iterations;
            let mut rows: Vec<Vec<f64>> = Vec::new();
            let mut b = Vec::new();
            for i in 0..self.freq_hz.len() {
                let l = self.loop_gain(i, &k);
                // Row of Re{ū (c + L(x))} ≥ r as  −Re{ū P B}·x ≤ Re{ū c} − r.
                let mut half_plane = |c: f64, r: f64, slack: f64| {
                    let z = Complex64::new(c, 0.0) + l;
                    let u = z.conj() / z.norm();
                    let coef = |j: usize| -(u * self.plant[i] * self.basis[i][j]).re * scale[j];
                    rows.push(vec![coef(0), coef(1), coef(2), slack]);
                    b.push(u.re * c - r);
                };
                half_plane(1.0, 1.0 / self.ms, 0.0);
                half_plane(t_centre, t_radius, 0.0);
                if held.contains(&i) {
                    half_plane(-1.0, std::f64::consts::SQRT_2, -1.0);
                }
            }
            for j in 0..4 {
                let mut lower = vec![0.0; 4];
                lower[j] = -1.0;
                rows.push(lower);
                b.push(0.0);
                if j < 3 {
                    let mut upper = vec![0.0; 4];
                    upper[j] = 1.0;
                    rows.push(upper);
                    b.push(1.0);
                }
            }
            let q = [0.0, -1.0, 0.0, penalty];
            let x = crate::lp::solve(None, &q, &rows, &b).map_err(|e| TuneError::Solver(it, e))?;
            // x ≥ 0 holds to the solver's tolerance; gains are non-negative exactly.
            k = [0, 1, 2].map(|j| (x[j] * scale[j]).max(0.0));
            // The objective never increases (each program contains the previous solution).
            let objective: f64 = q.iter().zip(&x).map(|(q, x)| q * x).sum();
            if last_objective - objective <= 1e-9 * objective.abs().max(1e-3) {
                break;
            }
            last_objective = objective;
        }
        Ok(k)
    }
}
