//! What a [`crate::Servo`] reports of itself: its status, its trip, a refused gain change.

use crate::protection::TripCause;

/// A machine-protection trip: why, and the tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Trip {
    /// Which limit (or latched fault) tripped the loop.
    pub cause: TripCause,
    /// The tick whose command was the first in the safe state.
    pub tick: u64,
}

/// What a [`crate::Servo`] has done so far ([`crate::Servo::status`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Status {
    /// Ticks run (commands given).
    pub ticks: u64,
    /// The trip the loop is in, if any (until [`crate::Servo::reset`]).
    pub trip: Option<Trip>,
    /// Tripped, and the safe state has been held for `protection.after_trip_s`: a run may end.
    pub trip_settled: bool,
    /// A stop the control plane asked for ([`daq_io::stop_cause`]), if any.
    pub stop: Option<u32>,
    /// The output scale in force (dimensionless, 1 as deployed).
    pub gain_scale: f64,
    /// Ticks whose command was at the output limit.
    pub saturated_ticks: u64,
    /// Controllers handed over while running ([`crate::Servo::load`], `servo ctl load`).
    pub handovers: u64,
    /// Trips since the start (each re-arm clears one).
    pub trips: u64,
    /// Ticks that started a whole period or more after their sample was taken
    /// ([`daq_io::Sensor::published_ns`]; `std` only, 0 otherwise).
    pub overruns: u64,
    /// Telemetry records a served loop dropped because its service thread fell behind (the
    /// tick never waits; feature `serve`, 0 otherwise).
    pub telemetry_dropped: u64,
}

/// Why a gain change was refused ([`crate::Servo::set_gain`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GainRefused {
    /// The deployment carries no checked stability range.
    NotChecked,
    /// Outside `low..=high` (the stable range with the margin), or not a number.
    OutOfRange {
        /// The requested scale.
        scale: f64,
        /// The lowest scale allowed.
        low: f64,
        /// The highest scale allowed.
        high: f64,
    },
}

impl core::fmt::Display for GainRefused {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            GainRefused::NotChecked => f.write_str(
                "gain change refused: the deployment carries no [stability] record (check the loop offline with `servo deploy`)",
            ),
            GainRefused::OutOfRange { scale, low, high } => write!(
                f,
                "gain scale {scale} refused: allowed {low:.4}..={high:.4} (the stable range with a 2× margin on each side)"
            ),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for GainRefused {}
