//! A [`Deployment`] as bytes: what a host sends a microcontroller once at start, so one
//! firmware runs any loop `servo deploy` / `servo synth` made (up to [`MAX_SS_ORDER`]) without
//! being rebuilt. Every field in a fixed order, little-endian, after a magic and a version; a
//! state-space controller carries only its `(order + 1)²` used entries. Decoding checks the
//! layout; [`servo_runtime::Servo::new`] then checks the values as it does for a TOML deployment.

use super::{Reader, Writer};
use servo_config::{
    ControllerKind, Deployment, FeedforwardSpec, FirSpec, PidGains, ReferenceSpec, Seal,
    SsMatrices, Stability, Stage, ZpetcSpec, MAX_FIR_SPAN, MAX_FIR_TAPS, MAX_PREVIEW, MAX_SS_ORDER,
    ZPETC_SECTIONS,
};
use servo_config::{ProtectionConfig, SafeState};

/// First bytes of an image.
pub const MAGIC: [u8; 4] = *b"FTSD";
/// The layout version this build reads and writes.
pub const VERSION: u16 = 2;
/// The largest image in bytes (the largest state-space controller and the larger of the
/// largest ZPETC and FIR filters).
pub const MAX_BYTES: usize = 6
    + 8 * 9
    + (3 + 8 * 7 + 1 + 8 * (MAX_SS_ORDER + 1) * (MAX_SS_ORDER + 1))
    + 25
    + 3 * 32
    + 33
    + max(
        1 + 8 + 8 + 8 + 8 * 5 * ZPETC_SECTIONS,
        1 + 8 + 8 + 8 + 8 * MAX_FIR_TAPS,
    )
    + 8
    + (3 + 8 * 6);

const fn max(a: usize, b: usize) -> usize {
    if a > b {
        a
    } else {
        b
    }
}

/// Why bytes are not a deployment image: the field where decoding stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageError {
    /// The field (the configuration key it carries), or `magic` / `version` / `length`.
    pub field: &'static str,
}

impl core::fmt::Display for ImageError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "deployment image: `{}` is missing or out of range (image version {VERSION})",
            self.field
        )
    }
}

/// Writes `d` into `out`; returns the bytes used (None if `out` is shorter than needed;
/// [`MAX_BYTES`] always suffices).
pub fn encode(d: &Deployment, out: &mut [u8]) -> Option<usize> {
    let mut w = Writer::new(out);
    w.bytes(&MAGIC)?;
    w.bytes(&VERSION.to_le_bytes())?;
    w.f64(d.servo_rate_hz)?;
    let s = &d.stage;
    for v in [
        s.gap_sensitivity_v_per_m,
        s.accel_sensitivity_v_per_m_s2,
        s.suspended_mass_kg,
        s.damping_n_s_per_m,
        s.stiffness_n_per_m,
        s.current_gain_a_per_v,
        s.kt_n_per_a,
        s.dc_gain_m_per_v,
    ] {
        w.f64(v)?;
    }
    let c = &d.controller;
    w.u8(match c.kind {
        ControllerKind::Pid => 0,
        ControllerKind::Accel => 1,
        ControllerKind::Ss => 2,
    })?;
    for v in [c.pid.kp, c.pid.ki, c.pid.kd, c.pid.tf_s, c.ka] {
        w.f64(v)?;
    }
    w.u8(u8::from(c.kg_scaling))?;
    w.f64(c.accel_filter_hz)?;
    w.u8(c.accel_filter_order)?;
    w.f64(c.limit_v)?;
    match &c.ss {
        None => w.u8(0)?,
        Some(m) => {
            w.u8(m.order() as u8)?;
            for i in 0..=m.order() {
                for j in 0..=m.order() {
                    w.f64(m.entry(i, j))?;
                }
            }
        }
    }
    match &d.stability {
        None => w.u8(0)?,
        Some(st) => {
            w.u8(1)?;
            w.f64(st.spectral_radius)?;
            w.f64(st.unstable_below)?;
            w.f64(st.unstable_above)?;
            for digest in [&st.sha256.stage, &st.sha256.controller, &st.sha256.record] {
                w.bytes(digest)?;
            }
        }
    }
    let (tag, fields) = match d.reference {
        ReferenceSpec::Hold => (0, [0.0; 4]),
        ReferenceSpec::Sine {
            amplitude_m,
            frequency_hz,
        } => (1, [amplitude_m, frequency_hz, 0.0, 0.0]),
        ReferenceSpec::Step { amplitude_m, at_s } => (2, [amplitude_m, at_s, 0.0, 0.0]),
        ReferenceSpec::Chirp {
            amplitude_m,
            f_start_hz,
            f_end_hz,
            duration_s,
        } => (3, [amplitude_m, f_start_hz, f_end_hz, duration_s]),
    };
    w.u8(tag)?;
    for v in fields {
        w.f64(v)?;
    }
    match &d.feedforward {
        FeedforwardSpec::None => w.u8(0)?,
        FeedforwardSpec::Model => w.u8(1)?,
        FeedforwardSpec::Zpetc(z) => {
            w.u8(2)?;
            w.f64(z.gain)?;
            w.u64(z.preview as u64)?;
            w.u64(z.sections_used as u64)?;
            for s in &z.sections[..z.sections_used.min(ZPETC_SECTIONS)] {
                for &v in s {
                    w.f64(v)?;
                }
            }
        }
        FeedforwardSpec::Fir(f) => {
            w.u8(3)?;
            w.u64(f.preview as u64)?;
            w.u64(f.stride as u64)?;
            w.u64(f.taps_used as u64)?;
            for &v in &f.taps[..f.taps_used.min(MAX_FIR_TAPS)] {
                w.f64(v)?;
            }
        }
    }
    w.f64(d.smoothing_hz)?;
    let p = &d.protection;
    w.u8(u8::from(p.enabled))?;
    w.f64(p.following_error_m)?;
    w.u8(u8::from(p.position_limit_m.is_some()))?;
    w.f64(p.position_limit_m.unwrap_or(0.0))?;
    w.f64(p.saturation_s)?;
    w.u8(match p.safe_state {
        SafeState::Zero => 0,
        SafeState::Hold => 1,
        SafeState::Retract => 2,
    })?;
    for v in [p.retract_m, p.retract_speed_m_per_s, p.after_trip_s] {
        w.f64(v)?;
    }
    Some(w.len())
}

/// Reads `$r`'s next field of type `$t`, naming `$key` when it is missing.
macro_rules! field {
    ($r:expr, $t:ident, $key:expr) => {
        $r.$t().ok_or(ImageError { field: $key })?
    };
}

/// A count or length of at most `max`, named `key` when it is missing or larger.
fn count(r: &mut Reader, max: usize, key: &'static str) -> Result<usize, ImageError> {
    r.u64()
        .and_then(|v| usize::try_from(v).ok())
        .filter(|&v| v <= max)
        .ok_or(ImageError { field: key })
}

fn flag(v: u8, key: &'static str) -> Result<bool, ImageError> {
    match v {
        0 => Ok(false),
        1 => Ok(true),
        _ => Err(ImageError { field: key }),
    }
}

/// The deployment an image holds (its values still to be checked by [`servo_runtime::Servo::new`]).
pub fn decode(bytes: &[u8]) -> Result<Deployment, ImageError> {
    let mut d = Deployment::BLANK;
    decode_into(bytes, &mut d)?;
    Ok(d)
}

/// [`decode`] in place: the deployment an image holds written into `d` (a microcontroller's
/// static: the state-space matrices are written where they lie, not built on the stack). A
/// refused image leaves `d` partly written: decode another before using it.
pub fn decode_into(bytes: &[u8], d: &mut Deployment) -> Result<(), ImageError> {
    let mut r = Reader::new(bytes);
    if r.take::<4>() != Some(MAGIC) {
        return Err(ImageError { field: "magic" });
    }
    if r.take::<2>().map(u16::from_le_bytes) != Some(VERSION) {
        return Err(ImageError { field: "version" });
    }
    let servo_rate_hz = field!(r, f64, "servo_rate_hz");
    let stage = Stage {
        gap_sensitivity_v_per_m: field!(r, f64, "stage.gap_sensitivity_v_per_m"),
        accel_sensitivity_v_per_m_s2: field!(r, f64, "stage.accel_sensitivity_v_per_m_s2"),
        suspended_mass_kg: field!(r, f64, "stage.suspended_mass_kg"),
        damping_n_s_per_m: field!(r, f64, "stage.damping_n_s_per_m"),
        stiffness_n_per_m: field!(r, f64, "stage.stiffness_n_per_m"),
        current_gain_a_per_v: field!(r, f64, "stage.current_gain_a_per_v"),
        kt_n_per_a: field!(r, f64, "stage.kt_n_per_a"),
        dc_gain_m_per_v: field!(r, f64, "stage.dc_gain_m_per_v"),
    };
    let kind = match field!(r, u8, "controller.kind") {
        0 => ControllerKind::Pid,
        1 => ControllerKind::Accel,
        2 => ControllerKind::Ss,
        _ => {
            return Err(ImageError {
                field: "controller.kind",
            })
        }
    };
    let pid = PidGains {
        kp: field!(r, f64, "controller.kp"),
        ki: field!(r, f64, "controller.ki"),
        kd: field!(r, f64, "controller.kd"),
        tf_s: field!(r, f64, "controller.tf_s"),
    };
    let ka = field!(r, f64, "controller.ka");
    let kg_scaling = flag(
        field!(r, u8, "controller.kg_scaling"),
        "controller.kg_scaling",
    )?;
    let accel_filter_hz = field!(r, f64, "controller.accel_filter_hz");
    let accel_filter_order = field!(r, u8, "controller.accel_filter_order");
    let limit_v = field!(r, f64, "controller.limit_v");
    match usize::from(field!(r, u8, "controller.ss")) {
        0 => d.controller.ss = None,
        n if n <= MAX_SS_ORDER => {
            if r.rest() < 8 * (n + 1) * (n + 1) {
                return Err(ImageError {
                    field: "controller.ss",
                });
            }
            let m = d.controller.ss.get_or_insert(SsMatrices::BLANK);
            m.refill(n, |_, _| r.f64().unwrap_or(f64::NAN));
        }
        _ => {
            return Err(ImageError {
                field: "controller.ss",
            })
        }
    }
    let c = &mut d.controller;
    (c.kind, c.pid, c.ka, c.kg_scaling) = (kind, pid, ka, kg_scaling);
    (c.accel_filter_hz, c.accel_filter_order, c.limit_v) =
        (accel_filter_hz, accel_filter_order, limit_v);
    let stability = match field!(r, u8, "stability") {
        0 => None,
        1 => Some(Stability {
            spectral_radius: field!(r, f64, "stability.spectral_radius"),
            unstable_below: field!(r, f64, "stability.unstable_below"),
            unstable_above: field!(r, f64, "stability.unstable_above"),
            sha256: Seal {
                stage: field!(r, take, "stability.sha256.stage"),
                controller: field!(r, take, "stability.sha256.controller"),
                record: field!(r, take, "stability.sha256.record"),
            },
        }),
        _ => return Err(ImageError { field: "stability" }),
    };
    let tag = field!(r, u8, "reference.kind");
    let mut f = [0.0; 4];
    for v in &mut f {
        *v = field!(r, f64, "reference");
    }
    let reference = match tag {
        0 => ReferenceSpec::Hold,
        1 => ReferenceSpec::Sine {
            amplitude_m: f[0],
            frequency_hz: f[1],
        },
        2 => ReferenceSpec::Step {
            amplitude_m: f[0],
            at_s: f[1],
        },
        3 => ReferenceSpec::Chirp {
            amplitude_m: f[0],
            f_start_hz: f[1],
            f_end_hz: f[2],
            duration_s: f[3],
        },
        _ => {
            return Err(ImageError {
                field: "reference.kind",
            })
        }
    };
    let feedforward = match field!(r, u8, "feedforward") {
        0 => FeedforwardSpec::None,
        1 => FeedforwardSpec::Model,
        2 => {
            let gain = field!(r, f64, "feedforward.gain");
            let preview = count(&mut r, MAX_PREVIEW, "feedforward.preview")?;
            let used = count(&mut r, ZPETC_SECTIONS, "feedforward.sections")?;
            let mut sections = [[0.0; 5]; ZPETC_SECTIONS];
            for s in &mut sections[..used] {
                for v in s {
                    *v = field!(r, f64, "feedforward.sections");
                }
            }
            FeedforwardSpec::Zpetc(ZpetcSpec {
                gain,
                preview,
                sections,
                sections_used: used,
            })
        }
        3 => {
            let preview = count(&mut r, MAX_PREVIEW, "feedforward.preview")?;
            let stride = count(&mut r, MAX_FIR_SPAN, "feedforward.stride")?;
            let used = count(&mut r, MAX_FIR_TAPS, "feedforward.taps")?;
            let mut taps = [0.0; MAX_FIR_TAPS];
            for v in &mut taps[..used] {
                *v = field!(r, f64, "feedforward.taps");
            }
            FeedforwardSpec::Fir(FirSpec {
                taps,
                taps_used: used,
                preview,
                stride,
            })
        }
        _ => {
            return Err(ImageError {
                field: "feedforward",
            })
        }
    };
    let smoothing_hz = field!(r, f64, "smoothing_hz");
    let enabled = flag(field!(r, u8, "protection.enabled"), "protection.enabled")?;
    let following_error_m = field!(r, f64, "protection.following_error_m");
    let has_limit = flag(
        field!(r, u8, "protection.position_limit_m"),
        "protection.position_limit_m",
    )?;
    let limit = field!(r, f64, "protection.position_limit_m");
    let saturation_s = field!(r, f64, "protection.saturation_s");
    let safe_state = match field!(r, u8, "protection.safe_state") {
        0 => SafeState::Zero,
        1 => SafeState::Hold,
        2 => SafeState::Retract,
        _ => {
            return Err(ImageError {
                field: "protection.safe_state",
            })
        }
    };
    let protection = ProtectionConfig {
        enabled,
        following_error_m,
        position_limit_m: has_limit.then_some(limit),
        saturation_s,
        safe_state,
        retract_m: field!(r, f64, "protection.retract_m"),
        retract_speed_m_per_s: field!(r, f64, "protection.retract_speed_m_per_s"),
        after_trip_s: field!(r, f64, "protection.after_trip_s"),
    };
    if r.rest() != 0 {
        return Err(ImageError { field: "length" });
    }
    (d.servo_rate_hz, d.stage, d.stability) = (servo_rate_hz, stage, stability);
    (d.reference, d.feedforward) = (reference, feedforward);
    (d.smoothing_hz, d.protection) = (smoothing_hz, protection);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rich() -> Deployment {
        let mut d = Deployment::thesis_prototype();
        d.controller.kind = ControllerKind::Ss;
        d.controller.ss = SsMatrices::from_fn(MAX_SS_ORDER, |i, j| {
            (i as f64 + 1.0) / (j as f64 + 3.0) - 0.1
        });
        d.reference = ReferenceSpec::Chirp {
            amplitude_m: 1e-6,
            f_start_hz: 10.0,
            f_end_hz: 2e3,
            duration_s: 0.5,
        };
        let mut sections = [[0.0; 5]; ZPETC_SECTIONS];
        for (k, s) in sections.iter_mut().enumerate() {
            *s = [1.0, -0.5, 0.25, -0.1 * k as f64, 0.01];
        }
        d.feedforward = FeedforwardSpec::Zpetc(ZpetcSpec {
            gain: 1.25,
            preview: 7,
            sections,
            sections_used: ZPETC_SECTIONS,
        });
        d.smoothing_hz = 5e3;
        d.protection.position_limit_m = Some(30e-6);
        d.protection.safe_state = SafeState::Retract;
        d
    }

    fn rich_fir() -> Deployment {
        let mut d = rich();
        let mut taps = [0.0; MAX_FIR_TAPS];
        for (k, t) in taps.iter_mut().enumerate() {
            *t = 0.5f64.powi(k as i32) - 0.01;
        }
        d.feedforward = FeedforwardSpec::Fir(FirSpec {
            taps,
            taps_used: MAX_FIR_TAPS,
            preview: 30,
            stride: 16,
        });
        d
    }

    #[test]
    fn deployments_round_trip_and_the_largest_fits() {
        let mut buf = [0u8; MAX_BYTES];
        for d in [Deployment::thesis_prototype(), rich(), rich_fir()] {
            let n = encode(&d, &mut buf).expect("MAX_BYTES suffices");
            assert_eq!(decode(&buf[..n]), Ok(d));
        }
        // The largest deployment uses the whole bound, no more.
        let largest = if encode(&rich(), &mut buf) > encode(&rich_fir(), &mut buf) {
            rich()
        } else {
            rich_fir()
        };
        assert_eq!(encode(&largest, &mut buf), Some(MAX_BYTES));
        assert!(encode(&largest, &mut buf[..MAX_BYTES - 1]).is_none());
    }

    #[test]
    fn a_damaged_image_names_its_field() {
        let mut buf = [0u8; MAX_BYTES];
        let n = encode(&rich(), &mut buf).unwrap();
        // Cut inside the matrices: the controller's state space is named.
        assert_eq!(
            decode(&buf[..200]),
            Err(ImageError {
                field: "controller.ss"
            })
        );
        assert_eq!(
            decode(&buf[..n - 3]),
            Err(ImageError {
                field: "protection.after_trip_s"
            })
        );
        let mut long = [0u8; MAX_BYTES + 1];
        long[..n].copy_from_slice(&buf[..n]);
        assert_eq!(decode(&long), Err(ImageError { field: "length" }));
        buf[4] = 9; // another version
        assert_eq!(decode(&buf[..n]), Err(ImageError { field: "version" }));
        assert_eq!(decode(b"ELF\x7f"), Err(ImageError { field: "magic" }));
    }

    #[test]
    fn hostile_values_are_refused_at_their_field() {
        let mut buf = [0u8; MAX_BYTES];
        let n = encode(&rich(), &mut buf).unwrap();
        // The ZPETC preview sits after the tags and the gain: find it by encoding 7 and 8.
        let mut other = rich();
        if let FeedforwardSpec::Zpetc(z) = &mut other.feedforward {
            z.preview = 8;
        }
        let mut buf2 = [0u8; MAX_BYTES];
        encode(&other, &mut buf2).unwrap();
        let at = (0..n).find(|&i| buf[i] != buf2[i]).unwrap();
        buf[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
        assert_eq!(
            decode(&buf[..n]),
            Err(ImageError {
                field: "feedforward.preview"
            })
        );
        // A flag byte of 2 (kg_scaling is the byte after kp, ki, kd, tf_s and ka).
        let mut buf = [0u8; MAX_BYTES];
        let n = encode(&Deployment::thesis_prototype(), &mut buf).unwrap();
        let kg = 6 + 8 * 9 + 1 + 8 * 5;
        assert_eq!(buf[kg], 0);
        buf[kg] = 2;
        assert_eq!(
            decode(&buf[..n]),
            Err(ImageError {
                field: "controller.kg_scaling"
            })
        );
    }
}
