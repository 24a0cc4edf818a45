//! A controller load in two halves: checked and built on any thread ([`Loader::prepare`]),
//! swapped in on the ticking thread between ticks ([`crate::Servo::swap`]) without allocating,
//! parsing or freeing — the controller it replaces leaves in the [`Prepared`], to be dropped
//! off the ticking thread.

use crate::load::{build, CarriedCheck, LoadError, Vet};
use crate::servo_loop::Slot;
use servo_config::Origin;
use servo_config::LOADED_FILE;
use servo_config::{ControllerSpec, Stability, Stage};

/// The check a loop's controller files pass, taken from the loop ([`crate::Servo::loader`]):
/// owned, so it is used on any thread while the loop ticks.
pub struct Loader {
    pub(crate) check: CarriedCheck,
    pub(crate) stage: Stage,
    pub(crate) period_s: f64,
}

/// A controller checked and built for a loop, ready to take it ([`crate::Servo::swap`]); after
/// the swap it holds what the loop let go (the replaced controller), freed when it is dropped.
pub struct Prepared {
    pub(crate) controller: Option<Slot>,
    pub(crate) stability: Stability,
    pub(crate) spec: ControllerSpec,
    pub(crate) retired: [Option<Slot>; 2],
    /// The loop it was built for (a swap into another is refused).
    pub(crate) stage: Stage,
    pub(crate) period_s: f64,
}

impl Prepared {
    /// The stable range of output scales its loop allows (`[low, high]`, dimensionless): a
    /// swap is refused while the scale in force lies outside.
    pub fn scale_range(&self) -> (f64, f64) {
        (self.stability.low(), self.stability.high())
    }
}

impl Loader {
    /// Checks the controller file `file` (UTF-8 TOML: a `[controller]` table, or a state-space
    /// file as `servo synth` writes it) by the deployment's rule — made for this loop's plant
    /// and rate, carrying its sealed offline stability check — and builds it. Parses and
    /// allocates: call it off the ticking thread.
    pub fn prepare(&self, file: &[u8]) -> Result<Prepared, LoadError> {
        let v = self.check.vet(file).map_err(LoadError::Refused)?;
        let controller = build(&v, &self.stage, self.period_s).map_err(|e| {
            let at = Origin {
                path: Some(LOADED_FILE.into()),
                text: std::str::from_utf8(file).ok().map(str::to_owned),
            };
            LoadError::Invalid(at.located(&e))
        })?;
        Ok(Prepared {
            controller: Some(controller),
            stability: v.stability,
            spec: v.spec,
            retired: [None, None],
            stage: self.stage,
            period_s: self.period_s,
        })
    }
}
