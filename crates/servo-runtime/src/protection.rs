//! Machine protection: the `[protection]` limits (as LinuxCNC trips on following error) and the
//! safe state a trip takes the loop to. Every tick is checked; the first limit exceeded (or a
//! latched fault) trips the loop, and from then on the command is the safe state until an
//! explicit re-arm ([`crate::Servo::reset`]). Allocation-free.

use daq_io::flags;
use servo_config::{ProtectionConfig, SafeState};

/// Why the loop tripped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TripCause {
    /// |reference − measured| beyond `protection.following_error_m`.
    FollowingError,
    /// The gap reading clipped at the ADC range or passed `protection.position_limit_m`.
    SensorRange,
    /// The command stayed at its limit for longer than `protection.saturation_s`.
    Saturation,
    /// A non-finite reading or controller output.
    NotFinite,
    /// The reference or feedforward latched a fault (a lost spindle lock).
    ReferenceFault,
}

impl TripCause {
    /// Every cause, in the order their flag bits are decoded.
    pub const ALL: [TripCause; 5] = [
        TripCause::FollowingError,
        TripCause::SensorRange,
        TripCause::Saturation,
        TripCause::NotFinite,
        TripCause::ReferenceFault,
    ];

    /// The [`flags`] bit that carries this cause on telemetry and commands.
    pub fn flag(self) -> u32 {
        match self {
            TripCause::FollowingError => flags::TRIP_FOLLOWING_ERROR,
            TripCause::SensorRange => flags::TRIP_SENSOR_RANGE,
            TripCause::Saturation => flags::TRIP_SATURATION,
            TripCause::NotFinite => flags::TRIP_NOT_FINITE,
            TripCause::ReferenceFault => flags::TRIP_REFERENCE_FAULT,
        }
    }

    /// The cause a tripped record's flags carry (None when the record is not tripped).
    pub fn of_flags(bits: u32) -> Option<TripCause> {
        if bits & flags::TRIPPED == 0 {
            return None;
        }
        Self::ALL.into_iter().find(|c| bits & c.flag() != 0)
    }

    /// The name written into recordings, summaries and messages.
    pub fn name(self) -> &'static str {
        match self {
            TripCause::FollowingError => "following-error",
            TripCause::SensorRange => "sensor-range",
            TripCause::Saturation => "saturation",
            TripCause::NotFinite => "non-finite",
            TripCause::ReferenceFault => "reference-fault",
        }
    }
}

/// What one tick showed, as the limits see it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Observation {
    /// Following error `reference − measured` in m.
    pub following_error_m: f64,
    /// Measured position in m.
    pub measured_m: f64,
    /// The gap conversion clipped at the ADC range.
    pub gap_clipped: bool,
    /// The command was at its limit or the DAC clipped.
    pub saturated: bool,
}

/// The protection state of one run.
#[derive(Debug, Clone)]
pub(crate) struct Protection {
    enabled: bool,
    following_limit_m: f64,
    position_limit_m: f64,
    saturation_ticks: u64,
    safe_state: SafeState,
    retract_v: f64,
    retract_step_v: f64,
    after_ticks: u64,
    saturated_for: u64,
    trip: Option<(TripCause, u64)>,
    /// `trip`'s flag bits (0 untripped), read by every tick.
    trip_flags: u32,
    /// Trips since the start (a clear does not reset it).
    trips: u64,
    safe_v: f64,
}

impl Protection {
    /// Off: storage for a loop not yet built.
    pub(crate) const OFF: Protection = Protection {
        enabled: false,
        following_limit_m: f64::INFINITY,
        position_limit_m: f64::INFINITY,
        saturation_ticks: u64::MAX,
        safe_state: SafeState::Zero,
        retract_v: 0.0,
        retract_step_v: 0.0,
        after_ticks: 0,
        saturated_for: 0,
        trip: None,
        trip_flags: 0,
        trips: 0,
        safe_v: 0.0,
    };

    /// The limits of `p` for a loop at `rate_hz` on a stage of static gain `gain` (m/V, which
    /// turns the retract position and speed into volts).
    pub fn new(p: &ProtectionConfig, rate: f64, gain: f64) -> Self {
        let off_if_zero = |x: f64| if x > 0.0 { x } else { f64::INFINITY };
        Protection {
            enabled: p.enabled,
            following_limit_m: off_if_zero(p.following_error_m),
            position_limit_m: p.position_limit_m.unwrap_or(f64::INFINITY),
            saturation_ticks: if p.saturation_s > 0.0 {
                libm::round(p.saturation_s * rate) as u64
            } else {
                u64::MAX
            },
            safe_state: p.safe_state,
            retract_v: p.retract_m / gain,
            retract_step_v: p.retract_speed_m_per_s / libm::fabs(gain) / rate,
            after_ticks: libm::round(p.after_trip_s * rate) as u64,
            saturated_for: 0,
            trip: None,
            trip_flags: 0,
            trips: 0,
            safe_v: 0.0,
        }
    }

    /// The cause and tick of the trip, if tripped.
    #[inline]
    pub fn trip(&self) -> Option<(TripCause, u64)> {
        self.trip
    }

    /// Flag bits for a command given while in the current state (0 before a trip).
    #[inline]
    pub fn flags(&self) -> u32 {
        self.trip_flags
    }

    /// Checks the limits against what tick `seq`'s sample showed; trips (the command of `seq`
    /// becomes the safe state, starting from `last_v`) when one is exceeded.
    #[inline]
    pub fn watch(&mut self, seq: u64, o: &Observation, last_v: f64) {
        if !self.enabled || self.trip.is_some() {
            return;
        }
        self.saturated_for = if o.saturated {
            self.saturated_for + 1
        } else {
            0
        };
        let cause = if o.gap_clipped || o.measured_m.abs() > self.position_limit_m {
            Some(TripCause::SensorRange)
        } else if o.following_error_m.abs() > self.following_limit_m {
            Some(TripCause::FollowingError)
        } else if self.saturated_for > self.saturation_ticks {
            Some(TripCause::Saturation)
        } else {
            None
        };
        if let Some(c) = cause {
            self.trip_now(c, seq, last_v);
        }
    }

    /// Trips for `cause` at tick `seq` (a latched fault), unless already tripped. Without
    /// protection, a fault still gives 0 V but does not trip.
    #[inline]
    pub fn fault(&mut self, cause: TripCause, seq: u64, last_v: f64) {
        if self.enabled && self.trip.is_none() {
            self.trip_now(cause, seq, last_v);
        }
    }

    /// Clears a trip (an explicit re-arm): the limits are watched again from the next sample.
    pub(crate) fn clear(&mut self) {
        (self.trip, self.trip_flags) = (None, 0);
        self.saturated_for = 0;
        self.safe_v = 0.0;
    }

    /// Trips since the start, re-armed ones included.
    pub fn trips(&self) -> u64 {
        self.trips
    }

    fn trip_now(&mut self, cause: TripCause, seq: u64, last_v: f64) {
        (self.trip, self.trip_flags) = (Some((cause, seq)), flags::TRIPPED | cause.flag());
        self.trips += 1;
        self.safe_v = if last_v.is_finite() { last_v } else { 0.0 };
    }

    /// This tick's command in the safe state, in V (advances the retract ramp).
    #[inline]
    pub fn safe_command(&mut self) -> f64 {
        match self.safe_state {
            SafeState::Zero => 0.0,
            SafeState::Hold => self.safe_v,
            SafeState::Retract => {
                let d =
                    (self.retract_v - self.safe_v).clamp(-self.retract_step_v, self.retract_step_v);
                self.safe_v += d;
                self.safe_v
            }
        }
    }

    /// Whether the run should end after tick `seq`: tripped, and the safe state has been held
    /// for `after_trip_s`.
    #[inline]
    pub fn run_over(&self, seq: u64) -> bool {
        self.trip
            .is_some_and(|(_, at)| seq >= at.saturating_add(self.after_ticks))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quiet() -> Observation {
        Observation {
            following_error_m: 1e-9,
            measured_m: 1e-6,
            gap_clipped: false,
            saturated: false,
        }
    }

    /// The thesis prototype's static gain, m/V (0.16697 mm/V).
    const GAIN: f64 = 1.6697e-4;

    fn protection(edit: impl FnOnce(&mut ProtectionConfig)) -> Protection {
        let mut c = ProtectionConfig::default();
        edit(&mut c);
        Protection::new(&c, 199_600.0, GAIN)
    }

    #[test]
    fn each_limit_trips_with_its_cause_at_its_tick() {
        let mut p = protection(|_| {});
        for seq in 0..100 {
            p.watch(seq, &quiet(), 0.1);
        }
        assert_eq!(p.trip(), None);
        assert_eq!(p.flags(), 0);
        p.watch(
            100,
            &Observation {
                following_error_m: -20.1e-6,
                ..quiet()
            },
            0.1,
        );
        assert_eq!(p.trip(), Some((TripCause::FollowingError, 100)));
        assert_eq!(p.flags(), flags::TRIPPED | flags::TRIP_FOLLOWING_ERROR);
        // The first trip stays: later limits do not overwrite it.
        p.watch(
            101,
            &Observation {
                gap_clipped: true,
                ..quiet()
            },
            0.1,
        );
        assert_eq!(p.trip(), Some((TripCause::FollowingError, 100)));

        let mut p = protection(|_| {});
        p.watch(
            7,
            &Observation {
                gap_clipped: true,
                ..quiet()
            },
            0.0,
        );
        assert_eq!(p.trip(), Some((TripCause::SensorRange, 7)));

        let mut p = protection(|c| c.position_limit_m = Some(10e-6));
        p.watch(
            3,
            &Observation {
                measured_m: 9.9e-6,
                ..quiet()
            },
            0.0,
        );
        assert_eq!(p.trip(), None);
        p.watch(
            4,
            &Observation {
                measured_m: -10.1e-6,
                ..quiet()
            },
            0.0,
        );
        assert_eq!(p.trip(), Some((TripCause::SensorRange, 4)));

        // 10 ms at 199.6 kHz = 1996 ticks of saturation are allowed, the 1997th trips; an
        // unsaturated tick restarts the count.
        let mut p = protection(|_| {});
        let sat = Observation {
            saturated: true,
            ..quiet()
        };
        for seq in 0..1000 {
            p.watch(seq, &sat, 10.0);
        }
        p.watch(1000, &quiet(), 10.0);
        for seq in 1001..=2996 {
            p.watch(seq, &sat, 10.0);
        }
        assert_eq!(p.trip(), None);
        p.watch(2997, &sat, 10.0);
        assert_eq!(p.trip(), Some((TripCause::Saturation, 2997)));

        let mut p = protection(|_| {});
        p.fault(TripCause::NotFinite, 9, f64::NAN);
        assert_eq!(p.trip(), Some((TripCause::NotFinite, 9)));
        assert_eq!(TripCause::of_flags(p.flags()), Some(TripCause::NotFinite));
    }

    #[test]
    fn zero_limits_are_off_and_disabled_protection_never_trips() {
        let mut p = protection(|c| {
            c.following_error_m = 0.0;
            c.saturation_s = 0.0;
        });
        let bad = Observation {
            following_error_m: 1e-3,
            saturated: true,
            ..quiet()
        };
        for seq in 0..100_000 {
            p.watch(seq, &bad, 10.0);
        }
        assert_eq!(p.trip(), None);
        let mut p = protection(|c| c.enabled = false);
        p.watch(
            0,
            &Observation {
                gap_clipped: true,
                ..bad
            },
            10.0,
        );
        p.fault(TripCause::NotFinite, 1, 0.0);
        assert_eq!(p.trip(), None);
    }

    #[test]
    fn safe_states_zero_hold_and_a_bounded_retract() {
        let trip = |state| {
            let mut p = protection(|c| c.safe_state = state);
            p.fault(TripCause::NotFinite, 0, 1.5);
            p
        };
        let mut zero = trip(SafeState::Zero);
        assert_eq!(zero.safe_command(), 0.0);
        let mut hold = trip(SafeState::Hold);
        assert_eq!((hold.safe_command(), hold.safe_command()), (1.5, 1.5));
        // A non-finite last command holds 0 V.
        let mut p = protection(|c| c.safe_state = SafeState::Hold);
        p.fault(TripCause::NotFinite, 0, f64::INFINITY);
        assert_eq!(p.safe_command(), 0.0);
        // Retract: from 1.5 V to −5 µm / 0.16697 mm/V = −0.029945 V at 5 mm/s
        // (0.15003 mV per tick at 199.6 kHz), then held.
        let mut r = trip(SafeState::Retract);
        let gain = GAIN;
        let target = -5e-6 / gain;
        let step = 5e-3 / gain / 199_600.0;
        let first = r.safe_command();
        assert!((first - (1.5 - step)).abs() < 1e-12, "{first}");
        let ticks = ((1.5 - target) / step).ceil() as usize;
        let mut v = first;
        for _ in 1..ticks {
            let next = r.safe_command();
            assert!((v - next) <= step * (1.0 + 1e-9) && next >= target - 1e-15);
            v = next;
        }
        assert!((v - target).abs() < 1e-12, "{v} vs {target}");
        assert_eq!(r.safe_command(), v);
    }

    #[test]
    fn the_run_ends_after_the_safe_state_was_held() {
        // 5 ms at 199.6 kHz = 998 ticks.
        let mut p = protection(|_| {});
        assert!(!p.run_over(u64::MAX));
        p.fault(TripCause::NotFinite, 1000, 0.0);
        assert!(!p.run_over(1997));
        assert!(p.run_over(1998));
    }
}
