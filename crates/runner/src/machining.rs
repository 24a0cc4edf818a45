//! Freeform machining at run time (thesis Ch. 8), the controller's side: the surface reference
//! the controller computes per tick from the tracked encoder angle (§8.3), along the
//! [`SpiralCut`] the workpiece is cut on (`run_config::workpiece`).

use crate::repetitive::RepetitivePlan;
use daq_io::Sensor;
use run_config::surface::LoadedSurface;
use run_config::workpiece::SpiralCut;
use run_config::{Machining, MAX_BINS};
use servo_core::{Block, Repetitive, RepetitiveInput, SpindleTracker, SpindleTrackerConfig};
use servo_runtime::Reference;

/// The controller side: the surface height the tool should be at, from the tracked encoder
/// angle, `ahead` ticks after the end of the current tick (for preview), with the repetitive
/// controller's correction when the run has one.
#[derive(Debug, Clone)]
pub struct SurfaceReference {
    cut: SpiralCut,
    tracker: SpindleTracker,
    period_s: f64,
    learner: Option<Box<Learner>>,
}

/// The repetitive controller inside a [`SurfaceReference`].
#[derive(Debug, Clone)]
struct Learner {
    block: Repetitive<MAX_BINS>,
    lag_ticks: f64,
    on_tick: u64,
    off_tick: Option<u64>,
    meters_per_volt: f64,
}

impl SurfaceReference {
    /// The reference of `m` at servo period `period_s`, corrected by `repetitive`.
    pub fn new(
        m: &Machining,
        surface: LoadedSurface,
        period_s: f64,
        repetitive: Option<&RepetitivePlan>,
    ) -> Result<Self, servo_core::Error> {
        let learner = match repetitive {
            None => None,
            Some(p) => {
                let mut block = p.config.try_build::<MAX_BINS>(period_s)?;
                if let Some(t) = &p.table {
                    block.load(t)?;
                }
                Some(Box::new(Learner {
                    block,
                    lag_ticks: p.lag_ticks,
                    on_tick: p.on_tick,
                    off_tick: p.off_tick,
                    meters_per_volt: 1.0 / p.sensitivity_v_per_m,
                }))
            }
        };
        Ok(SurfaceReference {
            cut: SpiralCut::new(m, surface),
            tracker: SpindleTrackerConfig {
                pulses_per_rev: m.pulses_per_rev,
                speed_rpm: m.spindle_rpm,
                bandwidth_hz: m.tracker_bandwidth_hz,
            }
            .try_build(period_s)?,
            period_s,
            learner,
        })
    }

    /// The repetitive controller's learned table (m per bin), if the run has one.
    pub fn repetitive_table(&self) -> Option<&[f64]> {
        self.learner.as_ref().map(|l| l.block.table())
    }

    /// The height at the end of tick `k + ahead` (k: the last tracked tick), corrected.
    #[inline]
    fn height_m(&self, ahead: usize) -> f64 {
        let height = self
            .cut
            .height_m(self.tracker.predict_rad(ahead as f64 + 1.0));
        match &self.learner {
            None => height,
            Some(l) => {
                let rate = self.tracker.rate_rad_s() * self.period_s;
                height
                    + l.block
                        .output_m(self.tracker.predict_rad(ahead as f64), rate)
            }
        }
    }

    /// Tracks the sample's encoder; the repetitive controller learns from its gap reading.
    #[inline]
    fn track(&mut self, sample: &Sensor) {
        let theta = self.tracker.update(sample.encoder_count);
        if let Some(l) = &mut self.learner {
            let rate = self.tracker.rate_rad_s() * self.period_s;
            let on = sample.seq >= l.on_tick && l.off_tick.is_none_or(|off| sample.seq < off);
            l.block.set_enabled(on && !self.tracker.faulted());
            let target = self.cut.height_m(theta - l.lag_ticks * rate);
            let error = target - sample.gap_v * l.meters_per_volt;
            l.block.update(RepetitiveInput {
                angle_rad: theta,
                error_m: error,
                output_angle_rad: theta,
                rate_rad_per_tick: rate,
            });
        }
    }
}

/// The trajectory the runtime reads ahead: the tracked encoder of each sample, then the surface
/// height under the tool.
impl Reference for SurfaceReference {
    fn prime(&mut self, sample: &Sensor, out: &mut [f64]) {
        self.track(sample);
        for (j, v) in out.iter_mut().enumerate() {
            *v = self.height_m(j);
        }
    }

    #[inline]
    fn next(&mut self, sample: &Sensor, ahead: usize) -> f64 {
        self.track(sample);
        self.height_m(ahead)
    }

    /// The tracker lost the encoder, or the repetitive controller saw a non-finite value.
    fn faulted(&self) -> bool {
        self.tracker.faulted() || self.learner.as_ref().is_some_and(|l| l.block.faulted())
    }
}
