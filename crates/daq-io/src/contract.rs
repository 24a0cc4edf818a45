//! The sample contract: the `#[repr(C)]` messages plant, controller and recorder exchange.
//!
//! Every message carries the tick index `seq` it belongs to. Layouts are fixed (C layout, no
//! implicit padding) so other languages can map them: `examples/python/tap_telemetry.py` reads
//! [`TelemetryBlock`] with `ctypes`, and `include/fts_servo_contract.h` declares them for a C
//! or C++ DAQ daemon (CI compiles a C file asserting every size and offset against these
//! types). The layouts are versioned: [`CONTRACT_VERSION`] is in every iceoryx2 type name
//! (`fts_servo::v6::…`) and in every node name, and a peer of another version is refused at
//! connect with both versions named ([`crate::ipc::Endpoint::open`]). Change a layout, bump
//! the version (a test pins [`crate::layout::LAYOUT_FINGERPRINT`]).

/// The version of the sample contract's layouts (every `#[repr(C)]` type here).
pub const CONTRACT_VERSION: u32 = 6;

#[cfg(feature = "ipc")]
use iceoryx2::prelude::ZeroCopySend;

/// What a message type must be to cross processes: iceoryx2's `ZeroCopySend` with the `ipc`
/// feature, nothing without it (the contract alone, as plant-sim uses it).
#[cfg(feature = "ipc")]
pub trait Shareable: ZeroCopySend {}
#[cfg(feature = "ipc")]
impl<T: ZeroCopySend> Shareable for T {}
/// What a message type must be to cross processes (nothing without the `ipc` feature).
#[cfg(not(feature = "ipc"))]
pub trait Shareable {}
#[cfg(not(feature = "ipc"))]
impl<T> Shareable for T {}

/// Bits of the `flags` words: the one table of status bits for every sample, telemetry and
/// truth record (and the recording's `flags` field). Bits 0–7 are the plant's (converters),
/// 8–15 the controller's, 16 and up the transport's.
pub mod flags {
    /// A gap-channel conversion clipped at the ADC range.
    pub const GAP_CLIPPED: u32 = 1;
    /// An accelerometer conversion clipped.
    pub const ACCEL_CLIPPED: u32 = 1 << 1;
    /// The command clipped at the DAC range.
    pub const DAC_CLIPPED: u32 = 1 << 2;
    /// The command was NaN/inf: the DAC was driven to 0 V.
    pub const COMMAND_NOT_FINITE: u32 = 1 << 3;
    /// The controller output was at its limit, or the DAC clipped (telemetry).
    pub const SATURATED: u32 = 1 << 8;
    /// Machine protection tripped: this tick's command is the configured safe state
    /// (telemetry, from the trip's tick on; one of the `TRIP_*` bits says why).
    pub const TRIPPED: u32 = 1 << 9;
    /// Trip cause: |reference − measured| beyond the following-error limit.
    pub const TRIP_FOLLOWING_ERROR: u32 = 1 << 10;
    /// Trip cause: the gap reading clipped at the ADC range or passed the position limit.
    pub const TRIP_SENSOR_RANGE: u32 = 1 << 11;
    /// Trip cause: the command stayed saturated longer than the saturation limit.
    pub const TRIP_SATURATION: u32 = 1 << 12;
    /// Trip cause: a non-finite reading or controller output.
    pub const TRIP_NOT_FINITE: u32 = 1 << 13;
    /// Trip cause: the reference or feedforward latched a fault (a lost spindle lock).
    pub const TRIP_REFERENCE_FAULT: u32 = 1 << 14;
    /// Every `TRIP_*` cause bit.
    pub const TRIP_CAUSES: u32 = TRIP_FOLLOWING_ERROR
        | TRIP_SENSOR_RANGE
        | TRIP_SATURATION
        | TRIP_NOT_FINITE
        | TRIP_REFERENCE_FAULT;
    /// The plant has no more ticks: this sample closes the run (no command expected).
    pub const END: u32 = 1 << 16;
    /// The plant lost its controller and drives zero current (safe state).
    pub const FAULT_PEER_LOST: u32 = 1 << 17;
    /// The command of the previous tick came late: the DAC held its last value (real time).
    pub const OVERRUN: u32 = 1 << 18;
    /// The controller refused a non-finite command or latched a fault; the command is 0 V.
    pub const FAULT_CONTROLLER: u32 = 1 << 19;
    /// The controller answered late more often than the overrun budget allows (it is alive
    /// but cannot keep the rate): the plant drove zero current and ended the run.
    pub const FAULT_OVERRUN_BUDGET: u32 = 1 << 20;
    /// Recorded frames only: the recorder has the plant's truth of this tick but not the
    /// controller's telemetry (lost in transport, or the controller was gone); the telemetry
    /// fields are zero, not the loop's.
    pub const NO_TELEMETRY: u32 = 1 << 21;
    /// Truth records and recorded frames: the plant knows no truth (a DAQ daemon on real
    /// hardware): the truth fields are zero but the command it applied; the true tool error is
    /// not known.
    pub const NO_TRUTH: u32 = 1 << 22;
    /// Every fault that ends a run at the plant.
    pub const PLANT_FAULTS: u32 = FAULT_PEER_LOST | FAULT_OVERRUN_BUDGET;
}

/// Plant → controller, once per tick: the sensor readings at the start of tick `seq`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "ipc", type_name("fts_servo::v6::Sensor"))]
pub struct Sensor {
    /// Tick index (0 for the reading before the first command).
    pub seq: u64,
    /// Time of the reading in s since the run's first reading (run time).
    pub time_s: f64,
    /// Gap (capacitive sensor) reading in V.
    pub gap_v: f64,
    /// Accelerometer reading in V.
    pub accel_v: f64,
    /// Spindle encoder count (pulses since the start; 0 without a spindle).
    pub encoder_count: u64,
    /// [`flags`] bits.
    pub flags: u32,
    /// Reserved, 0.
    pub reserved: u32,
    /// The run's identity: a random number the plant draws at start and puts on every sample
    /// (nonzero). A controller that sees it change is listening to another plant.
    pub run_id: u64,
    /// When the plant published this sample, in ns of the host's `CLOCK_MONOTONIC` (0:
    /// unknown). The controller's start lateness is its own monotonic time minus this.
    pub published_ns: u64,
}

/// Controller → plant, once per tick: the DAC command for tick `seq`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "ipc", type_name("fts_servo::v6::Command"))]
pub struct Command {
    /// The tick this command answers (the echoed [`Sensor::seq`]).
    pub seq: u64,
    /// DAC output in V.
    pub dac_v: f64,
    /// [`flags`] bits.
    pub flags: u32,
    /// Reserved, 0.
    pub reserved: u32,
}

/// What the controller saw and did on one tick (recorded on `/telemetry`): the reading it
/// acted on, the reference of that tick, the errors it formed and the command it gave.
///
/// Convention (contract v6): record `seq = k` pairs tick k's reference with the reading of
/// sample k — the one the controller used — so `following_error_m` is `r − y` as the
/// controller saw it. (Contract v5 paired the reference with the *next* reading; recordings
/// say which convention they hold.)
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "ipc", type_name("fts_servo::v6::Telemetry"))]
pub struct Telemetry {
    /// Tick index.
    pub seq: u64,
    /// Time of the reading the tick acted on (the start of the tick), in s since the run's
    /// first reading (run time).
    pub time_s: f64,
    /// Reference position of the tick in m (the desired tool position at the tick's end).
    pub reference_m: f64,
    /// Measured position the tick acted on (gap reading / sensitivity) in m.
    pub measured_m: f64,
    /// Following error `reference − measured` in m.
    pub following_error_m: f64,
    /// The feedback's own error `shaped reference − measured` in m: the reference after
    /// smoothing or ZPETC (equal to the following error without them, and while tripped).
    pub controller_error_m: f64,
    /// Command output of the tick in V.
    pub control_v: f64,
    /// Accelerometer reading the tick acted on in m/s².
    pub accel_m_s2: f64,
    /// The sample's flags (its DAC bit is about the previous command) plus the controller's
    /// for this tick's command (saturation, faults, trip).
    pub flags: u32,
    /// Reserved, 0.
    pub reserved: u32,
}

/// What really happened in the plant over one tick (simulator only; recorded on `/truth`).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "ipc", type_name("fts_servo::v6::Truth"))]
pub struct Truth {
    /// Tick index.
    pub seq: u64,
    /// Time at the end of the tick in s since the run's first reading (run time).
    pub time_s: f64,
    /// True tool position relative to the frame in m.
    pub tool_m: f64,
    /// Gap the sensor measures in m.
    pub gap_m: f64,
    /// Motor force in N.
    pub motor_force_n: f64,
    /// Cutting force in N.
    pub cutting_force_n: f64,
    /// Coil current in A.
    pub coil_current_a: f64,
    /// Current noise in A.
    pub current_noise_a: f64,
    /// Base displacement in m.
    pub base_m: f64,
    /// Sensor noise in V.
    pub sensor_noise_v: f64,
    /// DAC output applied in V.
    pub dac_v: f64,
    /// [`flags`] bits (the plant's view: overrun, fault).
    pub flags: u32,
    /// Reserved, 0.
    pub reserved: u32,
}

/// Ticks per [`TelemetryBlock`] / [`TruthBlock`]: recorder traffic is batched so the servo
/// path publishes one message per 64 ticks (0.32 ms at 199.6 kHz).
pub const BLOCK_TICKS: usize = 64;

/// Up to [`BLOCK_TICKS`] consecutive [`Telemetry`] records.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "ipc", type_name("fts_servo::v6::TelemetryBlock"))]
pub struct TelemetryBlock {
    /// Block index (consecutive; a gap means blocks were dropped).
    pub block: u64,
    /// Valid entries in `ticks`.
    pub count: u32,
    /// [`flags::END`] on the last block of a run.
    pub flags: u32,
    /// The run's identity ([`Sensor::run_id`]): a recorder keeps to one run.
    pub run_id: u64,
    /// The records, `ticks[..count]`.
    pub ticks: [Telemetry; BLOCK_TICKS],
}

/// Up to [`BLOCK_TICKS`] consecutive [`Truth`] records.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "ipc", type_name("fts_servo::v6::TruthBlock"))]
pub struct TruthBlock {
    /// Block index (consecutive; a gap means blocks were dropped).
    pub block: u64,
    /// Valid entries in `ticks`.
    pub count: u32,
    /// [`flags::END`] on the last block of a run.
    pub flags: u32,
    /// The run's identity ([`Sensor::run_id`]): a recorder keeps to one run.
    pub run_id: u64,
    /// The records, `ticks[..count]`.
    pub ticks: [Truth; BLOCK_TICKS],
}

/// A block of records ([`TelemetryBlock`], [`TruthBlock`]) as a sender fills it and a
/// receiver reads it ([`RecordBlock::records`], [`crate::BlockCheck`]).
pub trait RecordBlock: Copy + Default + core::fmt::Debug + Shareable {
    /// One record.
    type Record: Copy;
    /// Appends a record; returns true when the block is full.
    fn push(&mut self, r: Self::Record) -> bool;
    /// The records it holds, `ticks[..count]`; None when its count is above [`BLOCK_TICKS`]
    /// (a peer's count is never taken on trust: see [`crate::BlockCheck`]).
    fn records(&self) -> Option<&[Self::Record]>;
    /// The tick sequence number of a record.
    fn seq(r: &Self::Record) -> u64;
    /// The block's index in its stream.
    fn index(&self) -> u64;
    /// Its record count as sent (what [`RecordBlock::records`] checks).
    fn count(&self) -> u32;
    /// No records held.
    fn is_empty(&self) -> bool;
    /// Sets the block index, flags and run identity before sending.
    fn seal(&mut self, index: u64, flags: u32, run_id: u64);
    /// Empties the block after sending.
    fn clear(&mut self);
}

macro_rules! block {
    ($b:ty, $r:ty) => {
        impl Default for $b {
            fn default() -> Self {
                Self {
                    block: 0,
                    count: 0,
                    flags: 0,
                    run_id: 0,
                    ticks: [Default::default(); BLOCK_TICKS],
                }
            }
        }

        impl RecordBlock for $b {
            type Record = $r;
            #[inline]
            fn push(&mut self, r: $r) -> bool {
                self.ticks[self.count as usize] = r;
                self.count += 1;
                self.count as usize == BLOCK_TICKS
            }
            fn records(&self) -> Option<&[$r]> {
                self.ticks.get(..self.count as usize)
            }
            fn seq(r: &$r) -> u64 {
                r.seq
            }
            fn index(&self) -> u64 {
                self.block
            }
            fn count(&self) -> u32 {
                self.count
            }
            fn is_empty(&self) -> bool {
                self.count == 0
            }
            fn seal(&mut self, index: u64, flags: u32, run_id: u64) {
                self.block = index;
                self.flags = flags;
                self.run_id = run_id;
            }
            fn clear(&mut self) {
                self.count = 0;
            }
        }
    };
}
block!(TelemetryBlock, Telemetry);
block!(TruthBlock, Truth);

/// Control-plane commands ([`Control::command`]).
pub mod command {
    /// Start a plant waiting for it (`wait_for_start`).
    pub const START: u32 = 3;
    /// Stop at the next tick boundary (the plant ends the run as if its duration were over).
    /// `value`: why, as a [`super::stop_cause`] (0: a control-plane request).
    pub const STOP: u32 = 1;
    /// Multiply the controller output (all gains of a linear controller) by `value`
    /// (dimensionless, 0.1..=10).
    pub const SET_GAIN_SCALE: u32 = 2;
    /// Replace the controller (the [`super::Ack::command`] answering a
    /// [`super::ControllerLoad`]; not sent as a [`super::Control`]).
    pub const LOAD_CONTROLLER: u32 = 4;
}

/// A control-plane message (anyone → plant and controller).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "ipc", type_name("fts_servo::v6::Control"))]
pub struct Control {
    /// One of [`command`].
    pub command: u32,
    /// Reserved, 0.
    pub reserved: u32,
    /// Argument (unit per command).
    pub value: f64,
    /// Request id the [`Ack`] echoes (0: no acknowledgement wanted).
    pub id: u64,
}

/// What a run did with a [`Control`] message ([`Ack::status`]).
pub mod ack_status {
    /// Applied at [`super::Ack::tick`].
    pub const APPLIED: u32 = 1;
    /// Refused: the change would leave the loop with less than the required stability
    /// margin ([`super::Ack::low`]..=[`super::Ack::high`] is what is allowed).
    pub const REFUSED_MARGIN: u32 = 2;
    /// Refused: not a number, or a command this process does not take (a controller file
    /// that does not parse or build).
    pub const REFUSED_INVALID: u32 = 3;
    /// Refused: a controller made for another plant or rate than the run's.
    pub const REFUSED_PROVENANCE: u32 = 4;
}

/// The reply to a [`Control`] message with an `id` (controller or plant → anyone).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "ipc", type_name("fts_servo::v6::Ack"))]
pub struct Ack {
    /// The request's [`Control::id`].
    pub id: u64,
    /// The tick at which it was applied (or seen, when refused).
    pub tick: u64,
    /// The request's value.
    pub value: f64,
    /// The lowest value allowed (gain scale: the stable range's lower end with the margin).
    pub low: f64,
    /// The highest value allowed.
    pub high: f64,
    /// The value at which the loop would go unstable (gain scale; 0 if not applicable).
    pub unstable_at: f64,
    /// The request's [`Control::command`].
    pub command: u32,
    /// One of [`ack_status`].
    pub status: u32,
    /// Which process answers, one of [`role`].
    pub role: u32,
    /// Reserved, 0.
    pub reserved: u32,
}

impl Ack {
    /// The reply of process `role` (one of [`role`]) to `request`, seen or applied at `tick`,
    /// with `status` (one of [`ack_status`]); no range.
    pub fn to(request: &Control, tick: u64, status: u32, role: u32) -> Self {
        Self {
            id: request.id,
            tick,
            value: request.value,
            command: request.command,
            status,
            role,
            ..Default::default()
        }
    }
}

/// Largest controller file a [`ControllerLoad`] carries, bytes (a state-space controller of
/// order 40, the largest a run takes, is ≈ 40 kB as `servo synth` writes it).
pub const MAX_LOAD_BYTES: usize = 65_536;

/// A controller to swap in while the loop runs (anyone → controller): the bytes of a controller
/// file or a `[controller]` config fragment. Answered by an [`Ack`] with
/// [`command::LOAD_CONTROLLER`].
#[derive(Clone, Copy)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "ipc", type_name("fts_servo::v6::ControllerLoad"))]
pub struct ControllerLoad {
    /// Request id the [`Ack`] echoes (nonzero).
    pub id: u64,
    /// Bytes of `data` used.
    pub len: u32,
    /// Reserved, 0.
    pub reserved: u32,
    /// The file, UTF-8 TOML.
    pub data: [u8; MAX_LOAD_BYTES],
}

impl ControllerLoad {
    /// Request `id` carrying `file`, or `None` when it exceeds [`MAX_LOAD_BYTES`].
    pub fn new(id: u64, file: &[u8]) -> Option<Self> {
        let mut load = ControllerLoad {
            id,
            len: u32::try_from(file.len()).ok()?,
            reserved: 0,
            data: [0; MAX_LOAD_BYTES],
        };
        load.data.get_mut(..file.len())?.copy_from_slice(file);
        Some(load)
    }

    /// The file's bytes (empty when `len` is out of range).
    pub fn file(&self) -> &[u8] {
        self.data.get(..self.len as usize).unwrap_or(&[])
    }
}

impl core::fmt::Debug for ControllerLoad {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("ControllerLoad")
            .field("id", &self.id)
            .field("len", &self.len)
            .finish_non_exhaustive()
    }
}

/// Why a run was stopped early: a signal's number (1 SIGHUP, 2 SIGINT, 15 SIGTERM), or
/// [`stop_cause::CONTROL`].
pub mod stop_cause {
    /// Not stopped.
    pub const NONE: u32 = 0;
    /// A control-plane STOP (`servo ctl stop`) or a library caller.
    pub const CONTROL: u32 = 1 << 16;
    /// The recorder could not write the recording (a full disk): the run is ended safely.
    pub const WRITE_FAILED: u32 = 1 << 17;
    /// Machine protection tripped the loop (the controller asks the plant to end the run
    /// after its safe-state interval).
    pub const TRIPPED: u32 = 1 << 18;

    /// The cause a STOP command's `value` carries (0 or out of range: [`CONTROL`]).
    pub fn of_value(value: f64) -> u32 {
        if (1.0..128.0).contains(&value) {
            value as u32
        } else if value == f64::from(WRITE_FAILED) {
            WRITE_FAILED
        } else if value == f64::from(TRIPPED) {
            TRIPPED
        } else {
            CONTROL
        }
    }
}

/// Which process a [`Health`] report comes from.
pub mod role {
    /// The plant (simulator or DAQ daemon).
    pub const PLANT: u32 = 1;
    /// The controller.
    pub const CONTROLLER: u32 = 2;
    /// The recorder (its [`super::Health::ticks`] are the ticks it has taken from the
    /// transport, on the `recorded` leaf).
    pub const RECORDER: u32 = 3;
}

/// Process states in a [`Health`] report.
pub mod state {
    /// Waiting for its peers.
    pub const WAITING: u32 = 1;
    /// Running ticks.
    pub const RUNNING: u32 = 2;
    /// Finished normally.
    pub const DONE: u32 = 3;
    /// Stopped by a fault (see the flags).
    pub const FAULTED: u32 = 4;
    /// Lockstep plant: holding its next tick until the recorder catches up (published when a
    /// hold begins, with the tick; see `crate::recorder_pace`).
    pub const HELD_FOR_RECORDER: u32 = 5;

    /// The final state of a run that ended with fault bits `faults`: [`FAULTED`] if any.
    pub const fn ended(faults: u32) -> u32 {
        if faults != 0 {
            FAULTED
        } else {
            DONE
        }
    }
}

/// Percentiles of a per-tick time in ns: round trip (sensor published → command received),
/// start lateness or execution time ([`Health`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "ipc", type_name("fts_servo::v6::Latency"))]
pub struct Latency {
    /// Exchanges measured.
    pub count: u64,
    /// Minimum in ns.
    pub min_ns: u64,
    /// Median in ns.
    pub p50_ns: u64,
    /// 99th percentile in ns.
    pub p99_ns: u64,
    /// 99.9th percentile in ns.
    pub p999_ns: u64,
    /// 99.99th percentile in ns.
    pub p9999_ns: u64,
    /// Maximum in ns.
    pub max_ns: u64,
}

/// A process's periodic status (every 2048 ticks and once at the end).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "ipc", type_name("fts_servo::v6::Health"))]
pub struct Health {
    /// One of [`role`].
    pub role: u32,
    /// One of [`state`].
    pub state: u32,
    /// Ticks done.
    pub ticks: u64,
    /// Late commands (real time: the DAC held its value).
    pub overruns: u64,
    /// Sticky [`flags`] fault bits.
    pub faults: u32,
    /// Why the run was stopped early, a [`stop_cause`] (0: it was not).
    pub stop_cause: u32,
    /// Wall time since the first tick in s.
    pub wall_s: f64,
    /// Round trip sensor published → command received (plant; zero from the controller).
    pub latency: Latency,
    /// Start lateness of each tick: the plant's tick start after its deadline (or after its
    /// backend's clock edge); the controller's tick start after the sample was published.
    pub lateness: Latency,
    /// Execution time of each tick (Simulink Real-Time's TET): the plant's own work (publish,
    /// step, truth) without the wait for the command; the controller's sample-to-command time.
    pub execution: Latency,
}
