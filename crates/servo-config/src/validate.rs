//! Every value of a [`Deployment`] against its allowed range, named by its key — the checks a
//! run configuration shares for the same values (controller, reference).

use crate::check::{Allowed, Invalid};
use crate::deployment::{
    ControllerKind, ControllerSpec, Deployment, FeedforwardSpec, FirSpec, ReferenceSpec, Stage,
    MAX_FIR_SPAN, MAX_FIR_TAPS, MAX_PREVIEW, ZPETC_SECTIONS,
};

impl Deployment {
    /// Checks every value (the keys as a deployment file names them); the blocks' own checks
    /// follow when a `servo_runtime::Servo` is built.
    pub fn check(&self) -> Result<(), Invalid> {
        let rate = self.servo_rate_hz;
        if !(1e2..=2e6).contains(&rate) {
            return Err(Invalid::new(
                "",
                "servo_rate_hz",
                rate,
                Allowed::between(1e2, 2e6, "Hz"),
            ));
        }
        let nyquist = rate / 2.0;
        check_stage(&self.stage)?;
        check_controller(&self.controller, rate)?;
        if self.controller.kind == ControllerKind::Ss && self.controller.ss.is_none() {
            return Err(Invalid::new(
                "controller",
                "ss",
                f64::NAN,
                Allowed::Text("the matrices of a state-space controller for kind = \"ss\""),
            ));
        }
        if let Some(s) = &self.stability {
            if !(s.spectral_radius >= 0.0 && s.spectral_radius < 1.0) {
                return Err(Invalid::new(
                    "controller.stability",
                    "spectral_radius",
                    s.spectral_radius,
                    Allowed::Text("[0, 1): a stable loop"),
                ));
            }
            if !(s.unstable_below >= 0.0 && s.unstable_below < 1.0) {
                return Err(Invalid::new(
                    "controller.stability",
                    "unstable_below",
                    s.unstable_below,
                    Allowed::Text("[0, 1): the loop is stable at scale 1"),
                ));
            }
            if s.unstable_above.is_nan() || s.unstable_above <= 1.0 {
                return Err(Invalid::new(
                    "controller.stability",
                    "unstable_above",
                    s.unstable_above,
                    Allowed::Text("(1, ∞): the loop is stable at scale 1"),
                ));
            }
            // The record stands for this loop only if it was made on it, as it is.
            s.check_seal(rate, &self.stage, &self.controller)
                .map_err(|e| e.in_section("controller.stability"))?;
        }
        check_reference(&self.reference, nyquist, "reference")?;
        let preview = self.feedforward.preview();
        if preview > MAX_PREVIEW {
            return Err(Invalid::new(
                "feedforward",
                "preview_ticks",
                preview as f64,
                Allowed::between(0.0, MAX_PREVIEW as f64, "ticks"),
            ));
        }
        if let FeedforwardSpec::Zpetc(z) = &self.feedforward {
            if z.sections_used > ZPETC_SECTIONS {
                return Err(Invalid::new(
                    "feedforward",
                    "sections",
                    z.sections_used as f64,
                    Allowed::between(0.0, ZPETC_SECTIONS as f64, "sections"),
                ));
            }
            let finite = z.gain.is_finite() && z.sections.iter().flatten().all(|x| x.is_finite());
            if !finite {
                return Err(Invalid::new(
                    "feedforward",
                    "sections",
                    f64::NAN,
                    Allowed::Text("finite coefficients"),
                ));
            }
        }
        if let FeedforwardSpec::Fir(f) = &self.feedforward {
            check_fir(f)?;
        }
        if !(self.smoothing_hz == 0.0 || (self.smoothing_hz > 0.0 && self.smoothing_hz < nyquist)) {
            return Err(Invalid::new(
                "",
                "smoothing_hz",
                self.smoothing_hz,
                Allowed::OffOrBelow {
                    high: nyquist,
                    unit: "Hz",
                },
            ));
        }
        // The feedforward's preview is at most MAX_PREVIEW (checked above); the smoothing's half
        // window is any size a rate and a corner make.
        if preview.saturating_add(self.smoothing_half()) > MAX_PREVIEW {
            let lowest = rate / (2.0 * (MAX_PREVIEW - preview) as f64 + 1.0);
            return Err(Invalid::new(
                "",
                "smoothing_hz",
                self.smoothing_hz,
                Allowed::OffOrAtLeast {
                    low: lowest,
                    unit: "Hz (the preview holds 62 ticks, the feedforward takes its share)",
                },
            ));
        }
        self.protection
            .check(self.controller.limit_v, self.stage.dc_gain_m_per_v)
            .map_err(|e| e.in_section("protection"))
    }
}

fn positive(
    section: &'static str,
    key: &'static str,
    x: f64,
    unit: &'static str,
) -> Result<(), Invalid> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(Invalid::new(section, key, x, Allowed::Positive { unit }))
    }
}

fn check_stage(s: &Stage) -> Result<(), Invalid> {
    positive(
        "stage",
        "gap_sensitivity_v_per_m",
        s.gap_sensitivity_v_per_m,
        "V/m",
    )?;
    positive(
        "stage",
        "accel_sensitivity_v_per_m_s2",
        s.accel_sensitivity_v_per_m_s2,
        "V/(m/s²)",
    )?;
    positive("stage", "suspended_mass_kg", s.suspended_mass_kg, "kg")?;
    positive("stage", "stiffness_n_per_m", s.stiffness_n_per_m, "N/m")?;
    positive(
        "stage",
        "current_gain_a_per_v",
        s.current_gain_a_per_v,
        "A/V",
    )?;
    positive("stage", "kt_n_per_a", s.kt_n_per_a, "N/A")?;
    if !(s.damping_n_s_per_m.is_finite() && s.damping_n_s_per_m >= 0.0) {
        return Err(Invalid::new(
            "stage",
            "damping_n_s_per_m",
            s.damping_n_s_per_m,
            Allowed::Text("≥ 0 N·s/m"),
        ));
    }
    if !(s.dc_gain_m_per_v.is_finite() && s.dc_gain_m_per_v != 0.0) {
        return Err(Invalid::new(
            "stage",
            "dc_gain_m_per_v",
            s.dc_gain_m_per_v,
            Allowed::Text("a finite, nonzero static gain in m/V"),
        ));
    }
    Ok(())
}

/// Checks the controller values a run configuration and a deployment share (keys in the
/// `[controller]` table) for a loop at `rate_hz`: the scalars, and a state-space controller's
/// matrices when they are there.
pub fn check_controller(c: &ControllerSpec, rate_hz: f64) -> Result<(), Invalid> {
    let nyquist = rate_hz / 2.0;
    if !(c.limit_v > 0.0 && c.limit_v <= 10.0) {
        return Err(Invalid::new(
            "controller",
            "limit_v",
            c.limit_v,
            Allowed::Text("(0, 10] V (the DAC range)"),
        ));
    }
    if !(c.ka >= 0.0 && c.ka <= 1e3) {
        return Err(Invalid::new(
            "controller",
            "ka",
            c.ka,
            Allowed::between(0.0, 1e3, "V/V"),
        ));
    }
    if !(c.accel_filter_hz == 0.0 || (c.accel_filter_hz > 0.0 && c.accel_filter_hz < nyquist)) {
        return Err(Invalid::new(
            "controller",
            "accel_filter_hz",
            c.accel_filter_hz,
            Allowed::OffOrBelow {
                high: nyquist,
                unit: "Hz",
            },
        ));
    }
    if !(1..=2).contains(&c.accel_filter_order) {
        return Err(Invalid::new(
            "controller",
            "accel_filter_order",
            f64::from(c.accel_filter_order),
            Allowed::Text("1 or 2"),
        ));
    }
    if let Some(ss) = &c.ss {
        let n = ss.order();
        for i in 0..=n {
            for j in 0..=n {
                if !ss.entry(i, j).is_finite() {
                    let key = match (i < n, j < n) {
                        (true, true) => "ss.a",
                        (true, false) => "ss.b",
                        (false, true) => "ss.c",
                        (false, false) => "ss.d",
                    };
                    return Err(Invalid::new(
                        "controller",
                        key,
                        ss.entry(i, j),
                        Allowed::Text("finite"),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Checks a reference generator's values for a loop with Nyquist frequency `nyquist` (Hz), with
/// keys in `section` (`reference` in a deployment, `scenario` in a run configuration).
pub fn check_reference(
    r: &ReferenceSpec,
    nyquist: f64,
    section: &'static str,
) -> Result<(), Invalid> {
    let amp = |key: &'static str, a: f64| {
        if a.is_finite() && a.abs() <= 1e-3 {
            Ok(())
        } else {
            Err(Invalid::new(
                section,
                key,
                a,
                Allowed::between(-1e-3, 1e-3, "m"),
            ))
        }
    };
    let freq = |key: &'static str, f: f64| {
        if f > 0.0 && f < nyquist {
            Ok(())
        } else {
            Err(Invalid::new(
                section,
                key,
                f,
                Allowed::Open {
                    low: 0.0,
                    high: nyquist,
                    unit: "Hz",
                },
            ))
        }
    };
    match *r {
        ReferenceSpec::Hold => Ok(()),
        ReferenceSpec::Sine {
            amplitude_m,
            frequency_hz,
        } => {
            amp("amplitude_m", amplitude_m)?;
            freq("frequency_hz", frequency_hz)
        }
        ReferenceSpec::Step { amplitude_m, at_s } => {
            amp("amplitude_m", amplitude_m)?;
            if at_s.is_finite() && at_s >= 0.0 {
                Ok(())
            } else {
                Err(Invalid::new(section, "at_s", at_s, Allowed::Text("≥ 0 s")))
            }
        }
        ReferenceSpec::Chirp {
            amplitude_m,
            f_start_hz,
            f_end_hz,
            duration_s,
        } => {
            amp("amplitude_m", amplitude_m)?;
            freq("f_start_hz", f_start_hz)?;
            freq("f_end_hz", f_end_hz)?;
            positive(section, "duration_s", duration_s, "s")
        }
    }
}

/// Largest sum of |taps| an FIR feedforward may have: the most it can amplify the reference
/// (a filter designed to flatten a loop stays within a few).
const MAX_FIR_GAIN: f64 = 100.0;

/// An FIR feedforward's taps: 1 ..= [`MAX_FIR_TAPS`] of them, finite, their |sum| at most
/// [`MAX_FIR_GAIN`], the past it reads within [`MAX_FIR_SPAN`] (its preview is checked with
/// every feedforward's).
fn check_fir(f: &FirSpec) -> Result<(), Invalid> {
    if f.taps_used == 0 || f.taps_used > MAX_FIR_TAPS {
        return Err(Invalid::new(
            "feedforward",
            "taps",
            f.taps_used as f64,
            Allowed::between(1.0, MAX_FIR_TAPS as f64, "taps"),
        ));
    }
    let span = f.taps_used.checked_mul(f.stride);
    if f.stride == 0 || span.is_none_or(|span| span > MAX_FIR_SPAN) {
        return Err(Invalid::new(
            "feedforward",
            "stride_ticks",
            f.stride as f64,
            Allowed::Text("at least 1, and taps·stride_ticks at most 2048 ticks"),
        ));
    }
    let taps = &f.taps[..f.taps_used];
    let gain: f64 = taps.iter().map(|t| libm::fabs(*t)).sum();
    if !taps.iter().all(|t| t.is_finite()) || gain > MAX_FIR_GAIN {
        return Err(Invalid::new(
            "feedforward",
            "taps",
            gain,
            Allowed::Text("finite taps whose absolute values sum to at most 100"),
        ));
    }
    Ok(())
}
