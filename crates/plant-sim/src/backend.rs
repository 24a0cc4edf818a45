//! The simulator as daq-io's [`Backend`]: one tick as the contract sees it — the readings as a
//! [`Sensor`] and what really happened as the contract's [`Truth`] — what the in-process run,
//! `servo plant`, libfts_plant and the practice stage step.

use crate::sim::{CommandChange, Simulator};
use daq_io::{Backend, Sensor, Truth};

impl Simulator {
    /// One tick as the contract sees it: [`Simulator::step_with_force`] with `dac_v` (V) and
    /// `extra_force_n` (N) on the tool, its readings as a [`Sensor`] (`seq` and the encoder
    /// count left to the caller) and its truth kept for [`Backend::truth`].
    #[inline]
    pub fn step_sensor(&mut self, dac_v: f64, extra_force_n: f64) -> Sensor {
        self.step_sensor_changed(dac_v, extra_force_n, CommandChange::NONE)
    }

    /// [`Simulator::step_sensor`] with the command changed on its way to the amplifier
    /// ([`Simulator::step_changed`]).
    #[inline(always)]
    pub(crate) fn step_sensor_changed(
        &mut self,
        dac_v: f64,
        extra_force_n: f64,
        change: CommandChange,
    ) -> Sensor {
        let (s, t) = self.step_changed(dac_v, extra_force_n, change);
        self.last_truth = t;
        s
    }
}

/// The stage with no force but the configured cutting profile's; zero readings before the
/// first command.
impl Backend for Simulator {
    #[inline]
    fn step(&mut self, dac_v: f64) -> Sensor {
        self.step_sensor(dac_v, 0.0)
    }

    fn truth(&self) -> Option<Truth> {
        Some(self.last_truth)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cutting::CuttingProfile;
    use crate::params::PlantParams;

    /// The backend's tick is the simulator's: the same readings and the same truth, bit for
    /// bit, as two seeded copies stepped through either door.
    #[test]
    fn the_backend_steps_the_simulator() {
        let p = PlantParams::default();
        let mut plain = Simulator::new(&p, 3, &CuttingProfile::None).unwrap();
        let mut backend = plain.clone();
        for k in 0..200 {
            let dac_v = 0.01 * libm::sin(f64::from(k) * 0.1);
            let (s, t) = plain.step(dac_v);
            let r = Backend::step(&mut backend, dac_v);
            assert_eq!(r, s);
            assert_eq!(Backend::truth(&backend), Some(t));
        }
    }
}
