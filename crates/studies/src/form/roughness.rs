//! Surface roughness of the machined face (thesis §8.5.1: Ra 1.2 nm on a flat NiP face, "no
//! filter applied", white-light interferometer with a 20X objective over 0.36 × 0.27 mm).
//!
//! The machined surface is what the round tool nose leaves: at radius ρ and angle φ the
//! height is the lowest of the nose profiles of the passes near it,
//! `h(ρ, φ) = min_k [e_k(φ) + (ρ − r_k(φ))² / 2R]`, with `e_k(φ)` the simulated true tool
//! error (tool − design surface) when pass k crossed angle φ and `r_k(φ)` the spiral's radius
//! there. With `e = 0` this is the kinematic feed-mark pattern alone (peak-to-valley
//! `f²/8R`); with the nearest pass's `e` alone it is the servo motion alone. Over a
//! measurement area in the middle of the cut band, each is reported as Sa, Sq, St (least-
//! squares plane removed, as an interferometer's software does) and Ra of radial profiles
//! (across the feed marks) and of profiles along the cut. What this leaves out — material
//! (grain boundaries, NiP's amorphous structure), the tool edge's own waviness and wear, chip
//! side flow, the instrument's noise floor — is not modelled and no term stands in for it.

use serde::Serialize;
use servo_core::Spiral;
use std::f64::consts::TAU;

/// The 20X field of §8.5.1 (m): 0.36 mm along the cut, 0.27 mm across it.
pub const MEASURED_AREA_M: [f64; 2] = [0.36e-3, 0.27e-3];

/// Radial sample points per feed in the evaluated surface.
const RADIAL_PER_FEED: usize = 40;

/// Passes within this many feeds of a point can reach it with their nose (f²/8R at one feed,
/// 9× that at three: far above any neighbour's cusp).
const ENVELOPE_FEEDS: f64 = 3.0;

/// Areal and profile statistics of one height map, m.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Texture {
    /// Arithmetic mean deviation from the least-squares plane.
    pub sa_m: f64,
    /// RMS deviation from it.
    pub sq_m: f64,
    /// Highest minus lowest point.
    pub st_m: f64,
    /// Mean Ra of the radial profiles (across the feed marks), each about its own mean line.
    pub ra_radial_m: f64,
    /// Mean Ra of the profiles along the cut.
    pub ra_along_m: f64,
}

/// The machined face's roughness and what makes it.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Roughness {
    /// The evaluated area, along the cut × across it, m.
    pub area_m: [f64; 2],
    /// Its mean radius, m.
    pub radius_m: f64,
    /// Tool nose radius R, m.
    pub nose_radius_m: f64,
    /// Feed per revolution f, m.
    pub feed_m_per_rev: f64,
    /// Kinematic feed marks' peak-to-valley, `f²/8R`, m.
    pub feed_mark_pv_m: f64,
    /// The machined surface: feed marks cut by the moving tool.
    pub surface: Texture,
    /// Feed marks alone (a motionless tool).
    pub feed_marks: Texture,
    /// The servo's tool motion alone (each point at its nearest pass's tool error).
    pub servo_motion: Texture,
}

/// Collects the tool error of every pass over the measurement window, then builds the surface.
#[derive(Debug, Clone)]
pub struct RoughnessWindow {
    nose_radius_m: f64,
    spiral: Spiral,
    /// Window: angles `[0, span)` of each revolution, in `bins` bins.
    span: f64,
    bins: usize,
    /// Radii the window covers, m (inner, outer).
    band_m: (f64, f64),
    /// Per revolution crossing the window: (revolution index, sum of e per bin, count).
    passes: Vec<(i64, Vec<f64>, Vec<u32>)>,
}

impl RoughnessWindow {
    /// A window of [`MEASURED_AREA_M`] (across-cut extent capped to the band) centred in the
    /// band `(inner, outer)` (m) of `spiral`, cut by a nose of radius `nose_radius_m` (m),
    /// sampled every `arc_per_tick_m` (m) along the cut. None when the band leaves fewer than ten
    /// feeds across after three feeds of passes are kept on each side for the envelope.
    pub fn new(
        spiral: Spiral,
        band_m: (f64, f64),
        nose_radius_m: f64,
        arc_per_tick_m: f64,
    ) -> Option<Self> {
        let (inner, outer) = band_m;
        let f = spiral.feed_m_per_rev;
        // Keep the envelope's reach of passes on each side of the window.
        let across = MEASURED_AREA_M[1].min(outer - inner - 2.0 * ENVELOPE_FEEDS * f);
        if across < 10.0 * f || f <= 0.0 {
            return None;
        }
        let mid = 0.5 * (inner + outer);
        let span = MEASURED_AREA_M[0] / mid;
        let bins =
            ((MEASURED_AREA_M[0] / arc_per_tick_m.max(1e-9)).round() as usize).clamp(8, 4096);
        Some(RoughnessWindow {
            nose_radius_m,
            spiral,
            span,
            bins,
            band_m: (mid - across / 2.0, mid + across / 2.0),
            passes: Vec::new(),
        })
    }

    /// Adds the tool error `e_m` (m) at unwrapped spindle angle `theta` (rad).
    pub fn add(&mut self, theta: f64, e_m: f64) {
        let r = self.spiral.radius_m(theta);
        let reach = ENVELOPE_FEEDS * self.spiral.feed_m_per_rev;
        if r < self.band_m.0 - reach || r > self.band_m.1 + reach {
            return;
        }
        let turn = (theta / TAU).floor();
        let phi = theta - turn * TAU;
        if !(0.0..self.span).contains(&phi) {
            return;
        }
        let bin = ((phi / self.span * self.bins as f64) as usize).min(self.bins - 1);
        let k = turn as i64;
        if self.passes.last().is_none_or(|p| p.0 != k) {
            self.passes
                .push((k, vec![0.0; self.bins], vec![0; self.bins]));
        }
        let pass = self.passes.last_mut().expect("pushed above");
        pass.1[bin] += e_m;
        pass.2[bin] += 1;
    }

    /// Per pass: its revolution and the tool error per bin (empty bins filled from their
    /// neighbours along the cut).
    fn errors(&self) -> Vec<(i64, Vec<f64>)> {
        self.passes
            .iter()
            .filter(|p| p.2.iter().any(|&n| n > 0))
            .map(|(k, sum, n)| {
                let known: Vec<(usize, f64)> = (0..self.bins)
                    .filter(|&j| n[j] > 0)
                    .map(|j| (j, sum[j] / n[j] as f64))
                    .collect();
                let e = (0..self.bins)
                    .map(|j| {
                        let at = known.partition_point(|&(i, _)| i < j);
                        match (at.checked_sub(1).map(|i| known[i]), known.get(at)) {
                            (_, Some(&(i, v))) if i == j => v,
                            (Some((i0, v0)), Some(&(i1, v1))) => {
                                v0 + (v1 - v0) * (j - i0) as f64 / (i1 - i0) as f64
                            }
                            (Some((_, v)), None) | (None, Some(&(_, v))) => v,
                            (None, None) => 0.0,
                        }
                    })
                    .collect();
                (*k, e)
            })
            .collect()
    }

    /// The passes' radii and tool errors at angle bin `j`: `(r(2πk + φ_j), e_k(j))`.
    fn at_bin(&self, passes: &[(i64, Vec<f64>)], j: usize) -> Vec<(f64, f64)> {
        let phi = (j as f64 + 0.5) / self.bins as f64 * self.span;
        passes
            .iter()
            .map(|(k, e)| (self.spiral.radius_m(TAU * *k as f64 + phi), e[j]))
            .collect()
    }

    /// A radial profile across `feeds` feed marks in the middle of the window, at its middle
    /// angle: rows of (radius m, machined surface m, feed marks alone m, servo motion alone m).
    pub fn radial_profile(&self, feeds: usize) -> Option<Vec<[f64; 4]>> {
        let passes = self.errors();
        if passes.len() < 10 {
            return None;
        }
        let at = self.at_bin(&passes, self.bins / 2);
        let f = self.spiral.feed_m_per_rev;
        let (mid, n) = (
            0.5 * (self.band_m.0 + self.band_m.1),
            feeds * RADIAL_PER_FEED,
        );
        Some(
            (0..=n)
                .map(|i| {
                    let p = mid + f * (i as f64 / RADIAL_PER_FEED as f64 - feeds as f64 / 2.0);
                    let [cut, marks, servo] = heights_at(&at, p, f, 2.0 * self.nose_radius_m);
                    [p, cut, marks, servo]
                })
                .collect(),
        )
    }

    /// The roughness of the collected window; None before enough passes crossed it.
    pub fn roughness(&self) -> Option<Roughness> {
        let passes = self.errors();
        let f = self.spiral.feed_m_per_rev;
        // Bounded whatever the feed: at most 20 000 radial points.
        let radial =
            (((self.band_m.1 - self.band_m.0) / f * RADIAL_PER_FEED as f64) as usize).min(20_000);
        if passes.len() < 10 || radial < 10 {
            return None;
        }
        let rho = |i: usize| {
            self.band_m.0 + (self.band_m.1 - self.band_m.0) * i as f64 / (radial - 1) as f64
        };
        let two_r = 2.0 * self.nose_radius_m;
        let at: Vec<Vec<(f64, f64)>> = (0..self.bins).map(|j| self.at_bin(&passes, j)).collect();
        // [radial][bin] of [machined surface, feed marks, servo motion].
        let heights: Vec<Vec<[f64; 3]>> = (0..radial)
            .map(|i| at.iter().map(|a| heights_at(a, rho(i), f, two_r)).collect())
            .collect();
        let maps = [0, 1, 2].map(|k| {
            heights
                .iter()
                .map(|row| row.iter().map(|h| h[k]).collect())
                .collect::<Vec<Vec<f64>>>()
        });
        let [surface, feed_marks, servo_motion] = maps.map(|m| texture(&m));
        Some(Roughness {
            area_m: [
                self.span * 0.5 * (self.band_m.0 + self.band_m.1),
                self.band_m.1 - self.band_m.0,
            ],
            radius_m: 0.5 * (self.band_m.0 + self.band_m.1),
            nose_radius_m: self.nose_radius_m,
            feed_m_per_rev: f,
            feed_mark_pv_m: f * f / (4.0 * two_r),
            surface,
            feed_marks,
            servo_motion,
        })
    }
}

/// At radius `p` (m), from the passes `(radius, tool error)` near it: the machined height (the
/// lowest nose circle of radius `two_r`/2), the feed marks alone (`e = 0`), and the nearest
/// pass's tool error alone, m.
fn heights_at(passes: &[(f64, f64)], p: f64, feed: f64, two_r: f64) -> [f64; 3] {
    let (mut cut, mut marks, mut nearest) = (f64::INFINITY, f64::INFINITY, (f64::INFINITY, 0.0));
    for &(rk, e) in passes {
        let d = p - rk;
        if d.abs() > ENVELOPE_FEEDS * feed {
            continue;
        }
        let nose = d * d / two_r;
        cut = cut.min(e + nose);
        marks = marks.min(nose);
        if d.abs() < nearest.0 {
            nearest = (d.abs(), e);
        }
    }
    [cut, marks, nearest.1]
}

/// Statistics of a height map `h[radial][along]` on a uniform grid.
fn texture(h: &[Vec<f64>]) -> Texture {
    let (n, m) = (h.len(), h[0].len());
    // Least-squares plane a + b·i + c·j (centred indices make the normal equations diagonal).
    let (ci, cj) = ((n as f64 - 1.0) / 2.0, (m as f64 - 1.0) / 2.0);
    let (mut s0, mut si, mut sj, mut sii, mut sjj) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (i, row) in h.iter().enumerate() {
        for (j, &v) in row.iter().enumerate() {
            let (x, y) = (i as f64 - ci, j as f64 - cj);
            s0 += v;
            si += v * x;
            sj += v * y;
            sii += x * x;
            sjj += y * y;
        }
    }
    let count = (n * m) as f64;
    let (a, b, c) = (
        s0 / count,
        si / sii.max(f64::MIN_POSITIVE),
        sj / sjj.max(f64::MIN_POSITIVE),
    );
    let dev = |i: usize, j: usize| h[i][j] - a - b * (i as f64 - ci) - c * (j as f64 - cj);
    let (mut abs, mut sq, mut lo, mut hi) = (0.0, 0.0, f64::INFINITY, f64::NEG_INFINITY);
    for i in 0..n {
        for j in 0..m {
            let d = dev(i, j);
            abs += d.abs();
            sq += d * d;
            lo = lo.min(d);
            hi = hi.max(d);
        }
    }
    let ra = |profile: &mut dyn Iterator<Item = f64>| {
        let v: Vec<f64> = profile.collect();
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        v.iter().map(|x| (x - mean).abs()).sum::<f64>() / v.len() as f64
    };
    let ra_radial = (0..m)
        .map(|j| ra(&mut (0..n).map(|i| h[i][j])))
        .sum::<f64>()
        / m as f64;
    let ra_along = (0..n).map(|i| ra(&mut h[i].iter().copied())).sum::<f64>() / n as f64;
    Texture {
        sa_m: abs / count,
        sq_m: (sq / count).sqrt(),
        st_m: hi - lo,
        ra_radial_m: ra_radial,
        ra_along_m: ra_along,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A motionless tool leaves the textbook feed marks: peak-to-valley f²/8R and, for the
    /// parabolic cusps, Ra = f²/(18√3·R) across them.
    #[test]
    fn a_still_tool_leaves_the_kinematic_feed_marks() {
        let (r0, f, nose) = (20e-3, 2e-6, 0.5e-3);
        let band = (r0 - 400e-6, r0);
        let spiral = Spiral {
            start_radius_m: r0,
            feed_m_per_rev: f,
        };
        let mut w = RoughnessWindow::new(spiral, band, nose, 2.6e-6).unwrap();
        let turns = 200.0;
        let steps = (turns * 2000.0) as usize;
        for s in 0..steps {
            w.add(TAU * turns * s as f64 / steps as f64, 0.0);
        }
        let r = w.roughness().unwrap();
        let pv = f * f / (8.0 * nose);
        assert!((r.feed_marks.st_m / pv - 1.0).abs() < 0.01, "{r:?}");
        let ra = f * f / (18.0 * 3f64.sqrt() * nose);
        assert!((r.feed_marks.ra_radial_m / ra - 1.0).abs() < 0.02, "{r:?}");
        // Along the cut the marks hardly change: the spiral moves in by 0.6 % of a feed over
        // the 0.36 mm window at 20 mm.
        assert!(r.feed_marks.ra_along_m < 0.05 * ra, "{r:?}");
        assert_eq!(r.servo_motion.sq_m, 0.0);
        assert!((r.surface.sa_m / r.feed_marks.sa_m - 1.0).abs() < 1e-12);
    }
}
