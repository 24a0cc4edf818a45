//! Freeform machining at run time (thesis Ch. 8): the workpiece on the spindle (plant side:
//! the exact spindle angle, the encoder count, the cutting force of the surface being cut) and
//! the surface reference the controller computes per tick from the tracked encoder angle
//! (§8.3), both along one [`SpiralCut`].

use crate::config::Machining;
use crate::surface::LoadedSurface;
use daq_io::Sensor;
use servo_core::surface::Surface;
use servo_core::{Block, Encoder, SpindleTracker, SpindleTrackerConfig, Spiral};
use servo_runtime::Reference;

/// A surface cut along the facing spiral: the design height under the tool at each unwrapped
/// spindle angle (what the plant cuts, the controller follows and the form is judged against).
#[derive(Debug, Clone)]
pub struct SpiralCut {
    surface: LoadedSurface,
    spiral: Spiral,
}

impl SpiralCut {
    /// `surface` along the spiral of `m`.
    pub fn new(m: &Machining, surface: LoadedSurface) -> Self {
        SpiralCut {
            surface,
            spiral: m.spiral(),
        }
    }

    /// X radius in m at the unwrapped spindle angle `theta_rad`.
    #[inline]
    pub fn radius_m(&self, theta_rad: f64) -> f64 {
        self.spiral.radius_m(theta_rad)
    }

    /// Design height in m under the tool at spindle angle `theta_rad`.
    #[inline]
    pub fn height_m(&self, theta_rad: f64) -> f64 {
        self.surface.depth_m(self.radius_m(theta_rad), theta_rad)
    }
}

/// The plant side: the part on a spindle turning at exactly the configured speed from angle 0,
/// cut along the spiral.
#[derive(Debug, Clone)]
pub struct Workpiece {
    cut: SpiralCut,
    rad_per_tick: f64,
    encoder: Encoder,
    /// Force per metre of depth of cut, N/m (specific thrust × feed).
    force_per_depth_n_per_m: f64,
    peak_m: f64,
    finish_depth_m: Option<f64>,
}

impl Workpiece {
    /// The workpiece of `m` at servo period `period_s` (s).
    pub fn new(m: &Machining, surface: LoadedSurface, period_s: f64) -> Self {
        Workpiece {
            peak_m: surface.peak_m(),
            cut: SpiralCut::new(m, surface),
            rad_per_tick: m.rad_per_s() * period_s,
            encoder: Encoder {
                pulses_per_rev: m.pulses_per_rev,
            },
            force_per_depth_n_per_m: plant_sim::cutting::thrust_force_n(
                m.specific_thrust_n_per_m2,
                m.feed_m_per_rev,
                1.0,
            ),
            finish_depth_m: m.finish_depth_m,
        }
    }

    /// Spindle angle in rad at the start of tick `k` (unwrapped).
    #[inline]
    pub fn angle_rad(&self, k: u64) -> f64 {
        k as f64 * self.rad_per_tick
    }

    /// The encoder count at the start of tick `k`.
    #[inline]
    pub fn encoder_count(&self, k: u64) -> u64 {
        self.encoder.count_at(self.angle_rad(k))
    }

    /// Cutting force on the tool in N during tick `k` (positive away from the part): the chip
    /// area (feed × the depth of cut at the tool's design position) times the specific thrust
    /// (a known disturbance, as the thesis applied it in §5.7.5; the few-nm deflection's effect
    /// on the chip is neglected).
    #[inline]
    pub fn cutting_force_n(&self, k: u64) -> f64 {
        let depth = match self.finish_depth_m {
            Some(d) => d,
            None => (self.peak_m - self.cut.height_m(self.angle_rad(k))).max(0.0),
        };
        self.force_per_depth_n_per_m * depth
    }
}

/// The controller side: the surface height the tool should be at, from the tracked encoder
/// angle, `ahead` ticks after the end of the current tick (for preview).
#[derive(Debug, Clone)]
pub struct SurfaceReference {
    cut: SpiralCut,
    tracker: SpindleTracker,
}

impl SurfaceReference {
    /// The reference of `m` at servo period `period_s`.
    pub fn new(
        m: &Machining,
        surface: LoadedSurface,
        period_s: f64,
    ) -> Result<Self, servo_core::Error> {
        Ok(SurfaceReference {
            cut: SpiralCut::new(m, surface),
            tracker: SpindleTrackerConfig {
                pulses_per_rev: m.pulses_per_rev,
                speed_rpm: m.spindle_rpm,
                bandwidth_hz: m.tracker_bandwidth_hz,
            }
            .try_build(period_s)?,
        })
    }

    /// The height at the end of tick `k + ahead` (k: the last tracked tick).
    #[inline]
    fn height_m(&self, ahead: usize) -> f64 {
        self.cut
            .height_m(self.tracker.predict_rad(ahead as f64 + 1.0))
    }
}

/// The trajectory the runtime reads ahead: the tracked encoder of each sample, then the surface
/// height under the tool.
impl Reference for SurfaceReference {
    fn prime(&mut self, sample: &Sensor, out: &mut [f64]) {
        self.tracker.update(sample.encoder_count);
        for (j, v) in out.iter_mut().enumerate() {
            *v = self.height_m(j);
        }
    }

    #[inline]
    fn next(&mut self, sample: &Sensor, ahead: usize) -> f64 {
        self.tracker.update(sample.encoder_count);
        self.height_m(ahead)
    }

    /// The tracker lost the encoder.
    fn faulted(&self) -> bool {
        self.tracker.faulted()
    }
}
