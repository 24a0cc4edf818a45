//! What a stall analysis concludes, and what a host is judged by: the survivable stall, what
//! limits it, a host's measured stalls, the refusal and the advice a user reads.

/// The longest stall searched, in s: a loop that survives this long needs no faster host.
pub const MAX_STALL_S: f64 = 0.1;
/// How much longer than the host's worst measured stall the survivable stall must be: a
/// measurement of seconds sees the common stalls, not the rarest (a longer one sees longer).
pub const STALL_MARGIN: f64 = 2.0;

/// What limits a stall.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Limit {
    /// `protection.following_error_m`.
    FollowingError,
    /// The measured position: `protection.position_limit_m`, or the gap sensor's range.
    SensorRange,
    /// The command after the stall stays at `controller.limit_v` longer than
    /// `protection.saturation_s`.
    Saturation,
    /// The peer timeout (`realtime.peer_timeout_s`): the plant ends the run at 0 V.
    PeerTimeout,
}

impl Limit {
    /// What a user reads.
    pub fn describe(self) -> &'static str {
        match self {
            Limit::FollowingError => "the following error reaches protection.following_error_m",
            Limit::SensorRange => "the measured position reaches the sensor's range",
            Limit::Saturation => {
                "the command after it stays at controller.limit_v longer than protection.saturation_s"
            }
            Limit::PeerTimeout => {
                "the peer timeout, realtime.peer_timeout_s, ends the run at 0 V"
            }
        }
    }
}

/// The stall a loop survives.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Survivable {
    /// The longest stall after which the stage stays within the limits, in ticks (None:
    /// longer than [`MAX_STALL_S`]).
    pub physics_ticks: Option<u64>,
    /// What a stall one tick longer than `physics_ticks` exceeds first.
    pub physics_limit: Option<Limit>,
    /// The longest stall the peer timeout lets the run ride out, in ticks.
    pub watchdog_ticks: u64,
    /// Servo period in s.
    pub period_s: f64,
}

impl Survivable {
    /// The longest stall the run survives, in ticks: the shorter of the two.
    pub fn ticks(&self) -> u64 {
        self.physics_ticks
            .map_or(self.watchdog_ticks, |p| p.min(self.watchdog_ticks))
    }

    /// The longest stall the run survives, in s.
    pub fn stall_s(&self) -> f64 {
        self.ticks() as f64 * self.period_s
    }

    /// What ends a longer stall.
    pub fn limit(&self) -> Limit {
        match (self.physics_ticks, self.physics_limit) {
            (Some(p), Some(l)) if p <= self.watchdog_ticks => l,
            _ => Limit::PeerTimeout,
        }
    }

    /// The physics alone, in s (None: beyond [`MAX_STALL_S`]).
    pub fn physics_s(&self) -> Option<f64> {
        self.physics_ticks.map(|m| m as f64 * self.period_s)
    }
}

/// The stalls measured on a host: the worst start lateness of a loop paced at the run's rate
/// with its real-time settings (`servo latency`, or the qualification at a run's start).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HostStalls {
    /// The longest stall seen, s.
    pub worst_s: f64,
    /// How long the host was measured, s.
    pub measured_s: f64,
    /// The loop rate measured at, Hz.
    pub rate_hz: f64,
    /// Where the number comes from (what measured it, where, with which settings).
    pub source: String,
}

/// A real-time run refused up front: the host stalls longer than the loop survives.
#[derive(Debug, Clone, PartialEq)]
pub struct Refusal {
    /// What the host did.
    pub host: HostStalls,
    /// What the loop survives.
    pub survivable: Survivable,
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "this host stalled {:.1} µs ({}); this loop survives stalls up to {:.1} µs ({}), less than {STALL_MARGIN} × the host's worst: a real-time run would fail. {}",
            self.host.worst_s * 1e6,
            self.host.source,
            self.survivable.stall_s() * 1e6,
            self.survivable.limit().describe(),
            advice(&self.survivable, self.host.worst_s)
        )
    }
}

/// What to change when a host stalls `host_s` (s) and the loop survives less than
/// [`STALL_MARGIN`] × it.
pub fn advice(survivable: &Survivable, host_s: f64) -> String {
    let physics = survivable.physics_s();
    let enough = |p: f64| p >= STALL_MARGIN * host_s;
    if survivable.limit() == Limit::PeerTimeout && physics.is_none_or(enough) {
        // The stage would ride the stall out; the watchdog ends the run first.
        let room = physics.map_or(format!("of more than {:.0} ms", MAX_STALL_S * 1e3), |p| {
            format!("up to {:.1} µs", p * 1e6)
        });
        return format!(
            "The stage rides out stalls {room}: a realtime.peer_timeout_s of at least {STALL_MARGIN} × the host's worst stall, within what the stage survives, lets the run continue through them."
        );
    }
    "Make the host stall less — a real-time kernel (PREEMPT_RT), the servo CPUs isolated (isolcpus=, nohz_full=, realtime.plant_cpu / realtime.controller_cpu), no other load on them — or lower plant.timing.servo_rate_hz with a controller designed for that rate (a slower loop rides out longer stalls in ticks of its own)."
        .into()
}
