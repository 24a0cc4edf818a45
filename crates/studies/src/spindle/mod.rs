//! `servo spindle-errors`: the complementary three-probe separation of Appendix D on
//! simulated probe data — a known artefact form and spindle error motion, measured with the
//! three angle sets of Table D-1 — and how well each way of combining them recovers both.

use design::spindle::{
    harmonic_weighting, modify, separate, synchronous, synthesise, Separation, THESIS_ANGLE_SETS,
};
use plant_sim::metrology::{Harmonics, ProbeRig};
use run_config::{ConfigError, Origin};
use serde::Serialize;

/// The simulated measurement (defaults: Appendix D.3 and D.4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpindleStudy {
    /// Samples per revolution (10 000 pulses per revolution).
    pub per_rev: usize,
    /// Revolutions averaged (the last 32 of 200).
    pub revolutions: usize,
    /// Highest harmonic analysed in UPR (100).
    pub max_harmonic: usize,
    /// RMS of the artefact form error in m.
    pub artefact_rms_m: f64,
    /// RMS of the synchronous motion along each axis in m.
    pub motion_rms_m: f64,
    /// RMS of the asynchronous motion in m (white per sample).
    pub asynchronous_rms_m: f64,
    /// RMS of each probe's noise in m (0.3 nm, §D.3).
    pub probe_noise_rms_m: f64,
    /// Seed of the profiles and the noise.
    pub seed: u64,
}

impl Default for SpindleStudy {
    fn default() -> Self {
        SpindleStudy {
            per_rev: 10_000,
            revolutions: 32,
            max_harmonic: 100,
            artefact_rms_m: 20e-9,
            motion_rms_m: 30e-9,
            asynchronous_rms_m: 5e-9,
            probe_noise_rms_m: 0.3e-9,
            seed: 1,
        }
    }
}

/// RMS errors of one estimate against the simulated truth, in m.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Recovery {
    /// Artefact form.
    pub artefact_rms_error_m: f64,
    /// X motion.
    pub x_rms_error_m: f64,
    /// Y motion.
    pub y_rms_error_m: f64,
}

/// One angle set.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct SetReport {
    /// α, β in degrees.
    pub angles_deg: [f64; 2],
    /// Smallest |H(k)| over 2..=max_harmonic and where.
    pub min_weighting: f64,
    /// Harmonic of the smallest |H(k)|.
    pub min_weighting_upr: usize,
    /// The set alone.
    pub alone: Recovery,
    /// After the frequency-domain modification.
    pub modified: Recovery,
}

/// The study's result.
#[derive(Debug, Clone, Serialize)]
pub struct SpindleReport {
    /// RMS of the true artefact form, X and Y motion in the band, m.
    pub truth_rms_m: [f64; 3],
    /// Each angle set.
    pub sets: Vec<SetReport>,
    /// Least-squares synthesis over the three sets.
    pub synthesised: Recovery,
    /// The noise floor of the synthesised artefact predicted from the probe noise, m.
    pub predicted_noise_m: f64,
    /// Largest difference between the three sets' artefact profiles, before and after the
    /// frequency-domain modification, m (thesis D.4: 24.1 → 7.3 nm).
    pub spread_m: [f64; 2],
}

/// Profiles over one revolution for the data file and the plots (m).
pub struct SpindleProfiles {
    /// Angles in degrees.
    pub angle_deg: Vec<f64>,
    /// True artefact, true X, true Y (band-limited).
    pub truth: [Vec<f64>; 3],
    /// Each set alone.
    pub sets: Vec<Separation>,
    /// Each set modified.
    pub modified: Vec<Separation>,
    /// The synthesis.
    pub synthesised: Separation,
}

fn rms(v: impl ExactSizeIterator<Item = f64>) -> f64 {
    let n = v.len().max(1) as f64;
    (v.map(|x| x * x).sum::<f64>() / n).sqrt()
}

fn rms_diff(a: &[f64], b: &[f64]) -> f64 {
    rms(a.iter().zip(b).map(|(x, y)| x - y))
}

/// Largest pointwise difference between any two sets' artefact profiles.
fn spread(sets: &[Separation]) -> f64 {
    let n = sets.first().map_or(0, |s| s.artefact.len());
    (0..n)
        .map(|i| {
            let (lo, hi) = sets
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
                    (lo.min(s.artefact[i]), hi.max(s.artefact[i]))
                });
            hi - lo
        })
        .fold(0.0, f64::max)
}

fn recovery(s: &Separation, truth: &[Vec<f64>; 3]) -> Recovery {
    Recovery {
        artefact_rms_error_m: rms_diff(&s.artefact, &truth[0]),
        x_rms_error_m: rms_diff(&s.x, &truth[1]),
        y_rms_error_m: rms_diff(&s.y, &truth[2]),
    }
}

impl SpindleStudy {
    /// Checks every value (the errors name the field).
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |key: &str, v: String, range: &str| Origin::default().invalid(key, v, range);
        if !(64..=1 << 20).contains(&self.per_rev) {
            return Err(bad("per_rev", self.per_rev.to_string(), "64..=1048576"));
        }
        if !(1..=10_000).contains(&self.revolutions) {
            return Err(bad(
                "revolutions",
                self.revolutions.to_string(),
                "1..=10000",
            ));
        }
        if !(2..self.per_rev / 2).contains(&self.max_harmonic) {
            return Err(bad(
                "max_harmonic",
                self.max_harmonic.to_string(),
                "2..per_rev/2",
            ));
        }
        for (key, v) in [
            ("artefact_rms_m", self.artefact_rms_m),
            ("motion_rms_m", self.motion_rms_m),
            ("asynchronous_rms_m", self.asynchronous_rms_m),
            ("probe_noise_rms_m", self.probe_noise_rms_m),
        ] {
            if !(0.0..=1e-3).contains(&v) {
                return Err(bad(key, v.to_string(), "[0, 1e-3] m"));
            }
        }
        Ok(())
    }
}

/// Runs the study.
pub fn study(s: &SpindleStudy) -> (SpindleReport, SpindleProfiles) {
    let k = s.max_harmonic;
    let rig = ProbeRig {
        artefact: Harmonics::random(s.seed, k, s.artefact_rms_m),
        x: Harmonics::random(s.seed + 1, k, s.motion_rms_m),
        y: Harmonics::random(s.seed + 2, k, s.motion_rms_m),
        asynchronous_rms_m: s.asynchronous_rms_m,
        probe_noise_rms_m: s.probe_noise_rms_m,
        per_rev: s.per_rev,
    };
    let angle: Vec<f64> = (0..s.per_rev)
        .map(|i| i as f64 * std::f64::consts::TAU / s.per_rev as f64)
        .collect();
    let truth: [Vec<f64>; 3] =
        [&rig.artefact, &rig.x, &rig.y].map(|h| angle.iter().map(|&t| h.at(t)).collect());
    let sets: Vec<Separation> = THESIS_ANGLE_SETS
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let raw = rig.measure(
                a.alpha_rad,
                a.beta_rad,
                s.revolutions,
                s.seed + 10 + i as u64,
            );
            let sync = raw.map(|p| synchronous(&p, s.per_rev));
            separate([&sync[0], &sync[1], &sync[2]], *a, k)
        })
        .collect();
    let modified = modify(&sets);
    let synthesised = synthesise(&sets).expect("three sets");
    // Probe noise averaged over the revolutions, through S_i = S1 + a S2 + b S3 (the motion
    // cancels there) and the |H_i|²-weighted synthesis: per harmonic the complex amplitude's
    // variance is Σ|H_i|²σ_i²/(Σ|H_i|²)²/n, and a harmonic adds twice that to the mean square.
    let probe_var = s.probe_noise_rms_m.powi(2) / s.revolutions as f64;
    let per_harmonic = |k: usize| {
        let (num, den) = THESIS_ANGLE_SETS.iter().fold((0.0, 0.0), |(num, den), a| {
            let (wa, wb) = design::spindle::weights(a);
            let h2 = harmonic_weighting(a, k).norm_sqr();
            (num + h2 * probe_var * (1.0 + wa * wa + wb * wb), den + h2)
        });
        num / (den * den) / s.per_rev as f64
    };
    let predicted_noise_m = (2..=k).map(|k| 2.0 * per_harmonic(k)).sum::<f64>().sqrt();
    let report = SpindleReport {
        truth_rms_m: truth.each_ref().map(|v| rms(v.iter().copied())),
        sets: sets
            .iter()
            .zip(&modified)
            .map(|(set, m)| {
                let (h, at) = (2..=k)
                    .map(|kk| (harmonic_weighting(&set.angles, kk).norm(), kk))
                    .fold((f64::INFINITY, 0), |b, c| if c.0 < b.0 { c } else { b });
                SetReport {
                    angles_deg: [
                        set.angles.alpha_rad.to_degrees(),
                        set.angles.beta_rad.to_degrees(),
                    ],
                    min_weighting: h,
                    min_weighting_upr: at,
                    alone: recovery(set, &truth),
                    modified: recovery(m, &truth),
                }
            })
            .collect(),
        synthesised: recovery(&synthesised, &truth),
        predicted_noise_m,
        spread_m: [spread(&sets), spread(&modified)],
    };
    (
        report,
        SpindleProfiles {
            angle_deg: angle.iter().map(|t| t.to_degrees()).collect(),
            truth,
            sets,
            modified,
            synthesised,
        },
    )
}
