//! fts-servo `daq-io`: the sample contract between plant, controller and recorder, and its
//! transports.
//!
//! - [`contract`]: the `#[repr(C)]` messages (sensor, command, telemetry, truth, control,
//!   health) with sequence numbers and status flags.
//! - [`Daq`] (controller side) and [`Backend`] (plant side, simulator or hardware); [`InProcess`]
//!   joins them in one thread — what `servo run` uses.
//! - [`ipc`]: the same contract over iceoryx2 shared memory under a per-run prefix; [`serve`]
//!   runs the plant side (lockstep or real time — on the wall clock or the backend's own —,
//!   overruns, lost-peer and overrun-budget safe state).
//! - Real time: [`clock`] (monotonic time, tick waits), [`watchdog`] (peer timeout, overrun
//!   budget, grace window), [`realtime`] (scheduling, CPUs, locked memory), [`qualify`] (host
//!   qualification), [`TickStats`] (lateness and execution-time histograms).
//!
//! Without the default `ipc` feature the crate is the contract alone (no iceoryx2): what
//! the simulated stage uses to report its samples. Without `std` as well it is `#![no_std]`
//! with no allocator — the contract, its layout table and the [`Daq`]/[`Backend`] seams —
//! which the runtime's per-tick core and the firmware share with the host.
//!
//! Embedding in a DAQ daemon: implement [`Backend`] for the ADC/DAC hardware and call
//! [`serve::serve`]; see `examples/daq_daemon.rs`.

#![cfg_attr(not(feature = "std"), no_std)]

mod block_check;
#[cfg(feature = "std")]
pub mod clock;
pub mod contract;
#[cfg(feature = "ipc")]
pub mod control_client;
mod daq;
pub mod digest;
#[cfg(feature = "std")]
mod histogram;
#[cfg(feature = "std")]
pub mod input_file;
#[cfg(feature = "ipc")]
pub mod ipc;
pub mod layout;
#[cfg(feature = "ipc")]
pub mod peers;
#[cfg(feature = "ipc")]
pub mod qualify;
#[cfg(feature = "realtime")]
pub mod realtime;
#[cfg(feature = "ipc")]
pub mod recorder_pace;
#[cfg(feature = "ipc")]
pub mod serve;
#[cfg(feature = "std")]
pub mod watchdog;

pub use block_check::{BadBlock, BlockCheck};
pub use contract::{
    ack_status, flags, stop_cause, Ack, Command, Control, ControllerLoad, Health, Latency, Sensor,
    Telemetry, TelemetryBlock, Truth, TruthBlock, BLOCK_TICKS, CONTRACT_VERSION, MAX_LOAD_BYTES,
};
pub use daq::{Backend, Daq, DaqError, InProcess};
#[cfg(feature = "std")]
pub use histogram::{LatencyHistogram, TickStats};
