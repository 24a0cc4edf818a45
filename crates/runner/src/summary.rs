//! The run summary a precision engineer reads at a glance, computed from the recorded frames
//! (so `servo inspect` recomputes exactly the same numbers from the file).

use daq_io::Latency;
use recorder::Frame;
use run_config::RunConfig;
use serde::{Deserialize, Serialize};
use servo_runtime::TripCause;
use std::fmt;

/// RMS, peak-to-valley and mean of a signal.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Stats {
    /// Root mean square.
    pub rms: f64,
    /// Peak-to-valley (max − min).
    pub pv: f64,
    /// Mean.
    pub mean: f64,
}

impl Stats {
    /// Not known (NaN; `null` in JSON): a true error where the plant knows no truth.
    pub const UNKNOWN: Stats = Stats {
        rms: f64::NAN,
        pv: f64::NAN,
        mean: f64::NAN,
    };
}

/// Running RMS, peak-to-valley and mean.
#[derive(Debug, Clone, Copy)]
pub struct Acc {
    n: u64,
    sum: f64,
    sum_sq: f64,
    min: f64,
    max: f64,
}

impl Default for Acc {
    fn default() -> Self {
        Acc {
            n: 0,
            sum: 0.0,
            sum_sq: 0.0,
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
        }
    }
}

impl Acc {
    /// Adds one value.
    pub fn add(&mut self, x: f64) {
        self.n += 1;
        self.sum += x;
        self.sum_sq += x * x;
        self.min = self.min.min(x);
        self.max = self.max.max(x);
    }

    /// The statistics so far.
    pub fn stats(&self) -> Stats {
        let n = self.n.max(1) as f64;
        Stats {
            rms: (self.sum_sq / n).sqrt(),
            pv: if self.n > 0 { self.max - self.min } else { 0.0 },
            mean: self.sum / n,
        }
    }
}

/// Accumulates a summary tick by tick (allocation-free).
#[derive(Debug, Clone, Default)]
pub struct SummaryBuilder {
    settle_ns: u64,
    ticks: u64,
    last_ns: u64,
    following: Acc,
    truth: Acc,
    control: Acc,
    saturated: u64,
    adc_clipped: u64,
    /// The telemetry of the frame before the last one added.
    before: recorder::TelemetryRecord,
    /// The first tripped frame: its cause, time and the telemetry before it.
    trip: Option<(TripCause, u64, recorder::TelemetryRecord)>,
}

impl SummaryBuilder {
    /// Statistics over frames at or after `settle_s`.
    pub fn new(settle_s: f64) -> Self {
        SummaryBuilder {
            settle_ns: (settle_s * 1e9).round() as u64,
            ..Default::default()
        }
    }

    /// Frames added so far.
    pub fn ticks(&self) -> u64 {
        self.ticks
    }

    /// Adds one frame.
    #[inline]
    pub fn add(&mut self, f: &Frame) {
        self.ticks += 1;
        self.last_ns = f.time_ns;
        let flags = f.telemetry.flags as u32;
        if self.trip.is_none() {
            if let Some(cause) = TripCause::of_flags(flags) {
                self.trip = Some((cause, f.time_ns, self.before));
            }
            self.before = f.telemetry;
        }
        if f.time_ns < self.settle_ns {
            return;
        }
        if flags & (daq_io::flags::GAP_CLIPPED | daq_io::flags::ACCEL_CLIPPED) != 0 {
            self.adc_clipped += 1;
        }
        // A tick the controller did not act on (a stall skipped it, its telemetry was lost)
        // has no reference, error or command to count.
        if flags & daq_io::flags::NO_TELEMETRY != 0 {
            return;
        }
        self.following.add(f.telemetry.following_error_m as f64);
        if flags & daq_io::flags::NO_TRUTH == 0 {
            self.truth.add(f.truth.true_error_m as f64);
        }
        self.control.add(f.telemetry.control_v as f64);
        if flags & daq_io::flags::SATURATED != 0 {
            self.saturated += 1;
        }
    }

    /// The machine-protection trip the frames so far show, for a loop at `servo_rate_hz`.
    pub fn trip(&self, servo_rate_hz: f64) -> Option<TripReport> {
        self.trip.map(|(cause, time_ns, before)| TripReport {
            cause: cause.name().into(),
            // Frames are stamped at the end of their tick.
            tick: ((time_ns as f64 * 1e-9 * servo_rate_hz).round() as u64).saturating_sub(1),
            time_s: time_ns as f64 * 1e-9,
            following_error_m: before.following_error_m.into(),
            measured_m: before.measured_m.into(),
            control_v: before.control_v.into(),
        })
    }

    /// The summary so far.
    pub fn finish(&self, meta: RunMeta) -> Summary {
        Summary {
            ticks: self.ticks,
            simulated_s: self.last_ns as f64 * 1e-9,
            stats_ticks: self.following.n,
            following_error_m: self.following.stats(),
            true_error_m: if self.truth.n == 0 && self.following.n > 0 {
                // The plant knows no truth: not known, not zero.
                Stats::UNKNOWN
            } else {
                self.truth.stats()
            },
            control_v: self.control.stats(),
            saturated_ticks: self.saturated,
            adc_clipped_ticks: self.adc_clipped,
            trip: self.trip(meta.servo_rate_hz),
            meta,
        }
    }
}

/// A machine-protection trip as the frames show it: the first tick whose command was the safe
/// state, and what the tick before it showed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TripReport {
    /// `following-error`, `sensor-range`, `saturation`, `non-finite` or `reference-fault`.
    pub cause: String,
    /// The first tick commanded in the safe state.
    pub tick: u64,
    /// The end of that tick, s of simulated time.
    pub time_s: f64,
    /// Following error the tick before, m.
    pub following_error_m: f64,
    /// Measured position the tick before, m.
    pub measured_m: f64,
    /// Command the tick before, V.
    pub control_v: f64,
}

/// Facts about the run besides the statistics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunMeta {
    /// Loop rate in Hz.
    pub servo_rate_hz: f64,
    /// Seed.
    pub seed: u64,
    /// Statistics start, s.
    pub settle_s: f64,
    /// Controller description.
    pub controller: String,
    /// Scenario kind.
    pub scenario: String,
    /// Wall-clock seconds (live runs only).
    pub wall_s: Option<f64>,
    /// Stopped before its duration (Ctrl-C).
    pub interrupted: bool,
    /// Messages written to the recording, if recorded.
    pub recorded_messages: Option<u64>,
    /// Frames dropped by the recorder.
    pub dropped_frames: Option<u64>,
    /// Closed-loop spectral radius checked before the run.
    pub spectral_radius: Option<f64>,
    /// Multi-process (HIL) facts: overruns, latency, faults.
    pub hil: Option<HilMeta>,
    /// How the run ended (`completed`, `stopped`, `interrupted`, `peer-lost`,
    /// `write-failed`; `unfinished` for a recording that ends early).
    pub end_reason: Option<String>,
    /// Summary of a recording decimated at every n-th tick (`record_every` > 1): its counts
    /// are of the recorded ticks and its statistics an estimate from them.
    pub recorded_every: Option<u32>,
    /// The loop's digest ([`daq_io::digest::LoopDigest`], hex), when asked for: equal for
    /// two loops that read the same samples and gave the same commands.
    pub loop_digest: Option<String>,
    /// How the run's dense products rounded ([`servo_core::ARITHMETIC`]): two runs agree bit
    /// for bit only with the same arithmetic.
    #[serde(default)]
    pub arithmetic: String,
    /// Where the controller ran when not in this process: a PIL run's target and what it
    /// measured there (`servo run --pil`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target: Option<crate::pil::TargetMeta>,
    /// The repetitive controller's learned table at the end of an in-process machining run,
    /// m per bin (in the recording as [`crate::repetitive::LEARNED_ATTACHMENT`]).
    #[serde(skip)]
    pub repetitive_table_m: Option<Vec<f64>>,
}

/// The summary of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Ticks run.
    pub ticks: u64,
    /// Simulated time in s.
    pub simulated_s: f64,
    /// Ticks in the statistics window.
    pub stats_ticks: u64,
    /// Following error `reference − measured` (what the sensor reports), m.
    pub following_error_m: Stats,
    /// True tool error `tool − reference` (what the part gets), m.
    pub true_error_m: Stats,
    /// Control output, V.
    pub control_v: Stats,
    /// Ticks with the command at its limit or the DAC clipping.
    pub saturated_ticks: u64,
    /// Ticks where an ADC channel (gap or accelerometer) clipped — a limit cycle or a stroke
    /// beyond the sensor range.
    pub adc_clipped_ticks: u64,
    /// The machine-protection trip, if the loop tripped.
    pub trip: Option<TripReport>,
    /// Run facts.
    pub meta: RunMeta,
}

impl Summary {
    /// The statistics only (what a recording must reproduce).
    pub fn same_statistics(&self, other: &Summary) -> bool {
        (self.ticks, self.stats_ticks, self.saturated_ticks)
            == (other.ticks, other.stats_ticks, other.saturated_ticks)
            && self.following_error_m == other.following_error_m
            && self.true_error_m == other.true_error_m
            && self.control_v == other.control_v
    }
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let m = &self.meta;
        writeln!(
            f,
            "fts-servo run: {} scenario, {}, seed {}",
            m.scenario, m.controller, m.seed
        )?;
        writeln!(
            f,
            "  simulated {:.4} s at {:.1} kHz ({} ticks){}; statistics after {} s",
            self.simulated_s,
            m.servo_rate_hz / 1e3,
            self.ticks,
            match (&m.end_reason, m.interrupted) {
                (Some(r), true) => format!(", ENDED EARLY: {r}"),
                (None, true) => ", INTERRUPTED".to_string(),
                _ => String::new(),
            },
            // To the ns: 10 % of 0.1 s prints as 0.01, not 0.010000000000000002.
            (m.settle_s * 1e9).round() / 1e9
        )?;
        if let Some(n) = m.recorded_every {
            writeln!(
                f,
                "  recorded every {n}th tick: counts are of the recorded ticks, statistics \
                 estimated from them"
            )?;
        }
        let nm = |s: &Stats| format!("RMS {:>8.3} nm   PV {:>8.3} nm", s.rms * 1e9, s.pv * 1e9);
        writeln!(
            f,
            "  following error (sensor)  {}",
            nm(&self.following_error_m)
        )?;
        if self.true_error_m.rms.is_nan() {
            writeln!(
                f,
                "  true tool error           not known (the plant knows no simulator truth)"
            )?;
        } else {
            writeln!(f, "  true tool error           {}", nm(&self.true_error_m))?;
        }
        writeln!(
            f,
            "  control output            RMS {:>8.4} V    saturated {} ticks",
            self.control_v.rms, self.saturated_ticks
        )?;
        if self.adc_clipped_ticks > 0 {
            writeln!(f, "  WARNING                   an ADC clipped on {} ticks (limit cycle or over-range)", self.adc_clipped_ticks)?;
        }
        if let Some(t) = &self.trip {
            writeln!(
                f,
                "  TRIPPED                   {} at tick {} (t = {:.6} s; the tick before: following error {:.3} µm, measured {:.3} µm, command {:.4} V); safe state from then on",
                t.cause,
                t.tick,
                t.time_s,
                t.following_error_m * 1e6,
                t.measured_m * 1e6,
                t.control_v
            )?;
        }
        if let Some(d) = &m.loop_digest {
            writeln!(f, "  loop digest               {d}")?;
        }
        if let Some(t) = &m.target {
            writeln!(f, "  controller ran on         {}", t.machine)?;
            writeln!(f, "  target build              {}", t.build)?;
            writeln!(
                f,
                "  target cost               {:.0} instructions per tick (mean), {:.0} max: about {:.2} µs at {:.0} MHz ({} cycles/instruction, estimated); {} ticks over budget",
                t.instructions_per_tick_mean,
                t.instructions_per_tick_max,
                t.tick_max_s * 1e6,
                t.clock_hz / 1e6,
                t.cycles_per_instruction,
                t.over_budget_ticks,
            )?;
            if t.instructions_per_tick_run > 0.0 {
                writeln!(
                    f,
                    "  target in all             {:.0} instructions per tick (everything it ran: the tick, its interrupt, the link)",
                    t.instructions_per_tick_run
                )?;
            }
            writeln!(
                f,
                "  target stack              {} bytes running, {} building the loop, of {} reserved",
                t.stack_used_bytes, t.load_stack_bytes, t.stack_bytes
            )?;
            if let Some(why) = &t.lost {
                writeln!(f, "  TARGET LOST               {why}")?;
            }
        }
        if let Some(r) = m.spectral_radius {
            writeln!(
                f,
                "  closed loop               stable, spectral radius {r:.6}"
            )?;
        }
        if let Some(w) = m.wall_s {
            writeln!(
                f,
                "  wall time                 {:.3} s ({:.1}× real time)",
                w,
                self.simulated_s / w.max(1e-9)
            )?;
        }
        match (m.recorded_messages, m.dropped_frames) {
            (Some(n), Some(d)) => writeln!(
                f,
                "  recorded                  {n} messages, {d} frames dropped"
            )?,
            (Some(n), None) => writeln!(f, "  recording                 {n} messages")?,
            _ => {}
        }
        if let Some(h) = &m.hil {
            let us = |l: &Latency| {
                format!(
                    "p50 {:.2} / p99 {:.2} / p99.99 {:.2} / max {:.1} µs",
                    l.p50_ns as f64 * 1e-3,
                    l.p99_ns as f64 * 1e-3,
                    l.p9999_ns as f64 * 1e-3,
                    l.max_ns as f64 * 1e-3
                )
            };
            // Over the exchanges the plant timed; an embedding daemon has none: its ticks.
            let ticks = match h.latency.count {
                0 => self.ticks.max(1),
                n => n,
            } as f64;
            writeln!(
                f,
                "  {:<26}{} overruns ({:.4} %); round trip {}",
                if h.realtime {
                    "HIL, real time"
                } else {
                    "HIL, lockstep"
                },
                h.overruns,
                100.0 * h.overruns as f64 / ticks,
                us(&h.latency)
            )?;
            if h.truth_only_ticks > 0 && h.faults & daq_io::flags::FAULT_PEER_LOST == 0 {
                writeln!(
                    f,
                    "  {:<26}{} ticks the controller skipped (stalls) or whose telemetry was lost: in no error statistic",
                    "not acted on", h.truth_only_ticks
                )?;
            }
            if let Some(first) = &h.first_bad_block {
                writeln!(
                    f,
                    "  {:<26}{} refused and skipped (impossible counts or ticks: a foreign or faulty publisher); the first: {first}",
                    "bad blocks", h.bad_blocks
                )?;
            }
            if h.realtime {
                writeln!(f, "  {:<26}{}", "plant lateness", us(&h.plant_lateness))?;
            }
            writeln!(f, "  {:<26}{}", "plant execution", us(&h.plant_execution))?;
            writeln!(
                f,
                "  {:<26}{}",
                "controller lateness",
                us(&h.controller_lateness)
            )?;
            writeln!(
                f,
                "  {:<26}{}",
                "controller execution",
                us(&h.controller_execution)
            )?;
            if h.faults & daq_io::flags::FAULT_OVERRUN_BUDGET != 0 {
                writeln!(
                    f,
                    "  FAULT                     overrun budget exceeded: the controller answered late too often; the plant drove zero current"
                )?;
            }
            if h.faults & daq_io::flags::FAULT_PEER_LOST != 0 {
                writeln!(
                    f,
                    "  FAULT                     controller lost: the plant drove zero current ({} ticks recorded from the plant alone)",
                    h.truth_only_ticks
                )?;
            }
        }
        Ok(())
    }
}

/// What the plant and controller reported about a HIL run (in the summary).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HilMeta {
    /// Paced to the wall clock (false: lockstep).
    pub realtime: bool,
    /// Late commands (real time: the DAC held its value).
    pub overruns: u64,
    /// Round trip sensor → command as the plant measured it, ns.
    pub latency: Latency,
    /// Fault bits ([`daq_io::flags`]) the plant raised.
    pub faults: u32,
    /// Ticks recorded from the plant's truth alone (no telemetry: controller lost).
    pub truth_only_ticks: u64,
    /// The plant's tick start after its deadline, ns (real time).
    pub plant_lateness: Latency,
    /// The plant's own work per tick (publish, step, truth), ns.
    pub plant_execution: Latency,
    /// The controller's tick start after the sample's publication, ns.
    pub controller_lateness: Latency,
    /// The controller's sample-to-command time per tick (TET), ns.
    pub controller_execution: Latency,
    /// Telemetry and truth blocks the recorder refused as impossible (a count above
    /// capacity, ticks going backwards: a foreign or faulty publisher) and skipped.
    #[serde(default)]
    pub bad_blocks: u64,
    /// The first refused block: its stream and why.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub first_bad_block: Option<String>,
}

impl HilMeta {
    /// The percentiles as `key → "p50 … / p99 … / p99.99 … / max … ns"` entries for the
    /// recording's end record.
    pub fn record(&self) -> Vec<(String, String)> {
        let line = |l: &Latency| {
            format!(
                "count {} / p50 {} / p99 {} / p99.9 {} / p99.99 {} / max {} ns",
                l.count, l.p50_ns, l.p99_ns, l.p999_ns, l.p9999_ns, l.max_ns
            )
        };
        vec![
            ("hil.overruns".into(), self.overruns.to_string()),
            ("hil.round_trip".into(), line(&self.latency)),
            ("hil.plant.lateness".into(), line(&self.plant_lateness)),
            ("hil.plant.execution".into(), line(&self.plant_execution)),
            (
                "hil.controller.lateness".into(),
                line(&self.controller_lateness),
            ),
            (
                "hil.controller.execution".into(),
                line(&self.controller_execution),
            ),
            (
                "hil.bad_blocks".into(),
                match &self.first_bad_block {
                    Some(first) => format!("{} refused; the first: {first}", self.bad_blocks),
                    None => "0".into(),
                },
            ),
        ]
    }
}

impl RunMeta {
    /// The facts every summary of a run of `c` shares; the live ones (wall time, recording, HIL)
    /// unset.
    pub fn of(c: &RunConfig, controller: String) -> RunMeta {
        RunMeta {
            servo_rate_hz: c.plant.timing.servo_rate_hz,
            seed: c.run.seed,
            settle_s: c.run.settle(),
            controller,
            scenario: c.scenario.name().into(),
            wall_s: None,
            interrupted: false,
            recorded_messages: None,
            dropped_frames: None,
            spectral_radius: None,
            hil: None,
            end_reason: None,
            recorded_every: None,
            loop_digest: None,
            arithmetic: servo_core::ARITHMETIC.into(),
            target: None,
            repetitive_table_m: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use daq_io::{flags, Telemetry, Truth};

    /// A tick the controller did not act on (a real-time stall skipped its sample) has no
    /// known reference: it counts in no error or command statistic, and its recorded true
    /// error is unknown (NaN) — not the tool's position minus a reference of 0.
    #[test]
    fn ticks_without_telemetry_count_in_no_error_statistic() {
        let mut s = SummaryBuilder::new(0.0);
        let acted = Telemetry {
            reference_m: 10e-6,
            following_error_m: 1e-9,
            control_v: 0.1,
            ..Default::default()
        };
        let truth = |tool_m: f64, time_s: f64| Truth {
            tool_m,
            time_s,
            ..Default::default()
        };
        s.add(&Frame::join(&acted, &truth(10e-6 + 2e-9, 1e-5)));
        let skipped = Telemetry {
            flags: flags::NO_TELEMETRY,
            ..Default::default()
        };
        let frame = Frame::join(&skipped, &truth(12e-6, 2e-5));
        assert!(frame.truth.true_error_m.is_nan());
        s.add(&frame);
        assert_eq!(s.ticks(), 2);
        assert_eq!((s.following.n, s.truth.n, s.control.n), (1, 1, 1));
        assert!((s.truth.max - 2e-9).abs() < 1e-12, "{}", s.truth.max);
        assert_eq!(s.following.max, f64::from(1e-9f32));
    }
}
