//! A stability record bound to the loop it was made on ([`Seal`]): digests computed when the
//! offline check writes the record, and compared when a loop is built from it — a deployment
//! opened (Rust, C, the firmware's image) or a controller loaded. Every number is hashed in a
//! fixed order as its IEEE 754 bits, little-endian, after a tag naming the part.

use crate::check::{Allowed, Invalid};
use crate::deployment::{ControllerKind, ControllerSpec, Seal, Stability, Stage};
use sha2::{Digest, Sha256};

/// The SHA-256 of the servo rate (Hz) and the stage's numbers.
fn stage_digest(servo_rate_hz: f64, stage: &Stage) -> [u8; 32] {
    let mut h = Sha256::new();
    h.update(b"fts-servo stage 1");
    for v in [
        servo_rate_hz,
        stage.gap_sensitivity_v_per_m,
        stage.accel_sensitivity_v_per_m_s2,
        stage.suspended_mass_kg,
        stage.damping_n_s_per_m,
        stage.stiffness_n_per_m,
        stage.current_gain_a_per_v,
        stage.kt_n_per_a,
        stage.dc_gain_m_per_v,
    ] {
        h.update(v.to_bits().to_le_bytes());
    }
    h.finalize().into()
}

/// The SHA-256 of the controller's kind and the coefficients that kind uses (the output limit,
/// which clips but does not change the linear loop, is not among them).
fn controller_digest(c: &ControllerSpec) -> [u8; 32] {
    let mut h = Sha256::new();
    h.update(b"fts-servo controller 1");
    let mut number = |v: f64| h.update(v.to_bits().to_le_bytes());
    let p = &c.pid;
    match c.kind {
        ControllerKind::Pid => {
            number(0.0);
            [p.kp, p.ki, p.kd, p.tf_s].into_iter().for_each(&mut number);
        }
        ControllerKind::Accel => {
            number(1.0);
            [p.kp, p.ki, p.kd, p.tf_s, c.ka, c.accel_filter_hz]
                .into_iter()
                .for_each(&mut number);
            number(f64::from(c.accel_filter_order));
            number(f64::from(u8::from(c.kg_scaling)));
        }
        ControllerKind::Ss => {
            number(2.0);
            if let Some(m) = &c.ss {
                let n = m.order();
                number(n as f64);
                for i in 0..=n {
                    for j in 0..=n {
                        number(m.entry(i, j));
                    }
                }
            }
        }
    }
    h.finalize().into()
}

/// The SHA-256 of a record's numbers and the digests of what it was made on.
fn record_digest(s: &Stability, stage: &[u8; 32], controller: &[u8; 32]) -> [u8; 32] {
    let mut h = Sha256::new();
    h.update(b"fts-servo stability 1");
    h.update(stage);
    h.update(controller);
    for v in [s.spectral_radius, s.unstable_below, s.unstable_above] {
        h.update(v.to_bits().to_le_bytes());
    }
    h.finalize().into()
}

impl Stability {
    /// This record sealed to the loop it was made on: at `servo_rate_hz` (Hz) on `stage` with
    /// `controller`.
    pub fn sealed(self, servo_rate_hz: f64, stage: &Stage, controller: &ControllerSpec) -> Self {
        let stage = stage_digest(servo_rate_hz, stage);
        let controller = controller_digest(controller);
        let record = record_digest(&self, &stage, &controller);
        Stability {
            sha256: Seal {
                stage,
                controller,
                record,
            },
            ..self
        }
    }

    /// Whether this record was made on the loop at `servo_rate_hz` (Hz) on `stage` with
    /// `controller`, and is as it was made; the first part that does not match, named by its
    /// key under `[stability]`, when not.
    pub fn check_seal(
        &self,
        servo_rate_hz: f64,
        stage: &Stage,
        controller: &ControllerSpec,
    ) -> Result<(), Invalid> {
        let mismatch = |key, what| {
            Err(Invalid::new(
                "stability",
                key,
                f64::NAN,
                Allowed::Digest(what),
            ))
        };
        if self.sha256 == Seal::default() {
            return mismatch("sha256", "the loop it was made on (the record carries none: it was written by hand or by an older fts-servo)");
        }
        let stage = stage_digest(servo_rate_hz, stage);
        if stage != self.sha256.stage {
            return mismatch("sha256.stage", "servo_rate_hz and [stage]");
        }
        let controller = controller_digest(controller);
        if controller != self.sha256.controller {
            return mismatch(
                "sha256.controller",
                "the controller's gains or matrices (the kind and the coefficients it uses)",
            );
        }
        if record_digest(self, &stage, &controller) != self.sha256.record {
            return mismatch(
                "sha256.record",
                "the record's own numbers (spectral_radius, unstable_below, unstable_above)",
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::deployment::Deployment;

    #[test]
    fn each_edit_is_named_by_the_part_it_breaks() {
        let d = Deployment::thesis_prototype();
        let s = d.stability.unwrap();
        let check = |rate: f64, stage, controller, s: crate::Stability| {
            s.check_seal(rate, stage, controller).err().map(|e| e.key)
        };
        assert_eq!(check(d.servo_rate_hz, &d.stage, &d.controller, s), None);
        assert_eq!(
            check(20_000.0, &d.stage, &d.controller, s),
            Some("sha256.stage")
        );
        let mut c = d.controller.clone();
        c.pid.kp *= 1.0 + f64::EPSILON;
        assert_eq!(
            check(d.servo_rate_hz, &d.stage, &c, s),
            Some("sha256.controller")
        );
        // What the PID does not use is not sealed.
        let mut c = d.controller.clone();
        c.ka = 3.0;
        c.limit_v = 5.0;
        assert_eq!(check(d.servo_rate_hz, &d.stage, &c, s), None);
        let edited = crate::Stability {
            unstable_above: 40.0,
            ..s
        };
        assert_eq!(
            check(d.servo_rate_hz, &d.stage, &d.controller, edited),
            Some("sha256.record")
        );
        let unsealed = crate::Stability {
            sha256: Default::default(),
            ..s
        };
        assert_eq!(
            check(d.servo_rate_hz, &d.stage, &d.controller, unsealed),
            Some("sha256")
        );
    }
}
