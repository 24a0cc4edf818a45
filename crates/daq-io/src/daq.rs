//! The two seams: [`Daq`], what a controller loop talks to, and [`Backend`], what serves the
//! plant side (the simulator, or a DAQ daemon's ADC/DAC hardware). [`InProcess`] joins the two
//! in one thread with no transport at all: `servo run` is `InProcess` around the simulator.

use crate::contract::{flags, Command, Sensor, Truth};

/// Why a [`Daq`] exchange failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DaqError {
    /// A sample of another run arrived (another plant publishes on the prefix).
    #[error("a sample of run {got:016x} arrived in run {expected:016x}: another plant is publishing on this prefix")]
    ForeignRun {
        /// The run id of the first sample.
        expected: u64,
        /// The run id of the stray sample.
        got: u64,
    },
    /// No sensor sample arrived within the timeout: the plant is gone.
    #[error("plant lost: no sensor sample for tick {seq} within {timeout_ms} ms")]
    PlantLost {
        /// The tick waited for.
        seq: u64,
        /// The timeout in ms.
        timeout_ms: u64,
    },
    /// The transport failed.
    #[cfg(feature = "std")]
    #[error("transport: {0}")]
    Transport(String),
}

/// The controller's side of the sample exchange: read tick k's sample, write tick k's command.
///
/// ```
/// use daq_io::{Backend, Daq, InProcess, Sensor};
/// struct Echo;
/// impl Backend for Echo {
///     fn step(&mut self, dac_v: f64) -> Sensor { Sensor { gap_v: dac_v, ..Default::default() } }
/// }
/// let mut daq = InProcess::new(Echo, 2);
/// let s = daq.read().unwrap();
/// daq.write(daq_io::Command { seq: s.seq, dac_v: 0.5, ..Default::default() }).unwrap();
/// assert_eq!(daq.read().unwrap().gap_v, 0.5);
/// ```
pub trait Daq {
    /// The sample of the next tick (its `seq` counts up from 0). A sample with
    /// [`flags::END`] closes the run: no command is expected for it.
    fn read(&mut self) -> Result<Sensor, DaqError>;
    /// The command for the tick of the last sample read (`command.seq` echoes it).
    fn write(&mut self, command: Command) -> Result<(), DaqError>;
}

/// The plant side: hardware (or a simulator) that holds a DAC value for one tick and reads
/// its sensors at the end of the tick. `step` is the hot path: no allocation, no blocking.
pub trait Backend {
    /// The readings before the first command (served at run time 0). Default: all zero.
    fn initial(&mut self) -> Sensor {
        Sensor::default()
    }
    /// Holds `dac_v` (V) for one tick; returns the readings at the end of the tick (`seq` is
    /// filled in by the caller; the backend sets `time_s` on its own clock, which
    /// [`crate::serve::serve`] rebases to run time: the first command's reading at one period,
    /// whatever an earlier session left the clock at).
    fn step(&mut self, dac_v: f64) -> Sensor;
    /// What really happened over the last step, if the backend knows (a simulator does).
    fn truth(&self) -> Option<Truth> {
        None
    }
    /// The plant as the clock: a backend with a sample clock of its own (the ADC's conversion
    /// clock, an interrupt, a blocking read that returns when the conversion is done) blocks
    /// here until tick `k`'s edge and returns when that edge was, in ns of `CLOCK_MONOTONIC`
    /// ([`crate::clock::monotonic_ns`] with the `std` feature). The real-time server then
    /// paces on it, and measures its lateness against it. Default `None`: no clock of its own;
    /// the server paces on the wall clock.
    fn wait_for_tick(&mut self, k: u64) -> Option<u64> {
        let _ = k;
        None
    }
}

/// A [`Backend`] driven directly by the controller's thread: no transport, no copies beyond
/// the samples themselves. The run ends after `ticks` commands.
pub struct InProcess<B> {
    backend: B,
    ticks: u64,
    next: Sensor,
    started: bool,
}

impl<B: Backend> InProcess<B> {
    /// A run of `ticks` commands.
    pub fn new(backend: B, ticks: u64) -> Self {
        InProcess {
            backend,
            ticks,
            next: Sensor::default(),
            started: false,
        }
    }

    /// The backend (for its [`Backend::truth`] after a write).
    pub fn backend(&self) -> &B {
        &self.backend
    }

    /// Ends the run early: the next [`Daq::read`] returns the closing sample.
    pub fn stop(&mut self) {
        self.ticks = self.ticks.min(self.next.seq);
    }
}

impl<B: Backend> Daq for InProcess<B> {
    #[inline]
    fn read(&mut self) -> Result<Sensor, DaqError> {
        if !self.started {
            self.started = true;
            self.next = Sensor {
                seq: 0,
                ..self.backend.initial()
            };
        }
        if self.next.seq >= self.ticks {
            self.next.flags |= flags::END;
        }
        Ok(self.next)
    }

    #[inline]
    fn write(&mut self, command: Command) -> Result<(), DaqError> {
        let seq = self.next.seq + 1;
        let mut s = self.backend.step(command.dac_v);
        s.seq = seq;
        self.next = s;
        Ok(())
    }
}
