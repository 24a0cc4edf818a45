//! A plant served on a prefix — the simulator process (`servo plant`) or a lab's DAQ daemon
//! (`daq_io::serve`) — driven tick by tick from this process, which takes the controller's
//! place: what a measurement (`servo frf --prefix`) injects its excitation through.
//!
//! The plant keeps its safety duties (pacing, peer loss, zero current). When the measurement
//! ends — finished, failed or aborted — this side asks for a STOP and answers the remaining
//! samples with 0 V until the plant closes the run.

use crate::error::RunError;
use crate::hil::{PLANT_TIMEOUT, STARTUP_TIMEOUT};
use daq_io::contract::{command, stop_cause};
use daq_io::ipc::{ControlSender, ControllerLink, Endpoint};
use daq_io::{flags, Command, Control, Daq, Sensor};

/// Relative mismatch of the served sample period that counts as another rate.
const RATE_TOLERANCE: f64 = 1e-6;

/// Most samples answered with 0 V while waiting for the plant to close the run after the STOP
/// (the plant checks its control plane at least every 2048 ticks).
const DRAIN_TICKS: u32 = 1 << 16;

/// The plant of run `prefix`, joined as its controller.
pub struct RemotePlant {
    link: ControllerLink,
    stopper: ControlSender,
    last: Sensor,
    period_s: f64,
    skipped: u64,
    closed: bool,
    // Last: the node outlives the ports opened on it.
    _ep: Endpoint,
}

impl RemotePlant {
    /// Joins run `prefix` as its controller and takes the plant's first sample (waiting up to
    /// [`STARTUP_TIMEOUT`] for it); `period_s` is the servo period the caller is configured
    /// for, checked against the plant's from the second sample on.
    pub fn join(prefix: &str, period_s: f64) -> Result<Self, RunError> {
        let ep = Endpoint::open(prefix, "controller")?;
        let mut link = ControllerLink::new(&ep, STARTUP_TIMEOUT, PLANT_TIMEOUT)?;
        let stopper = ControlSender::new(&ep)?;
        let last = link.read().map_err(RunError::PlantLost)?;
        Ok(RemotePlant {
            link,
            stopper,
            last,
            period_s,
            skipped: 0,
            closed: false,
            _ep: ep,
        })
    }

    /// The plant's first sample (its readings before any command).
    pub fn initial(&self) -> Sensor {
        self.last
    }

    /// Samples the plant published that this side never answered (a real-time plant moved
    /// on before the command came): each is a tick whose excitation was not the one asked.
    pub fn skipped(&self) -> u64 {
        self.skipped
    }

    /// Holds `dac_v` (V) for one tick: sends it as the answer to the last sample and returns
    /// the next. The plant ending the run or faulting first is an error.
    pub fn step(&mut self, dac_v: f64) -> Result<Sensor, RunError> {
        self.link
            .write(Command {
                seq: self.last.seq,
                dac_v,
                ..Default::default()
            })
            .map_err(RunError::PlantLost)?;
        self.link.prepare();
        let s = self.link.read().map_err(RunError::PlantLost)?;
        if s.flags & (flags::END | flags::PLANT_FAULTS) != 0 {
            self.closed = true;
            return Err(RunError::PlantEnded {
                ticks: s.seq,
                faults: s.flags & flags::PLANT_FAULTS,
            });
        }
        if s.seq == 1 {
            let served = s.time_s - self.last.time_s;
            if (served / self.period_s - 1.0).abs() > RATE_TOLERANCE {
                return Err(RunError::RateMismatch {
                    served_hz: 1.0 / served,
                    configured_hz: 1.0 / self.period_s,
                });
            }
        }
        self.skipped += s.seq.saturating_sub(self.last.seq).saturating_sub(1);
        self.last = s;
        Ok(s)
    }

    /// Asks the plant to end the run and answers with 0 V until it has (bounded); once only.
    pub fn close(&mut self) {
        if self.closed {
            return;
        }
        self.closed = true;
        let stop = Control {
            command: command::STOP,
            value: f64::from(stop_cause::CONTROL),
            ..Default::default()
        };
        if self.stopper.send(stop).is_err() {
            return;
        }
        for _ in 0..DRAIN_TICKS {
            let zero = Command {
                seq: self.last.seq,
                ..Default::default()
            };
            if self.link.write(zero).is_err() {
                return;
            }
            match self.link.read() {
                Ok(s) if s.flags & flags::END == 0 => self.last = s,
                _ => return,
            }
        }
    }
}

impl Drop for RemotePlant {
    /// A measurement that failed or was abandoned still leaves the plant at 0 V and its run
    /// closed.
    fn drop(&mut self) {
        self.close();
    }
}
