//! Processor in the loop: the run's controller on a Cortex-M7 — the firmware of `firmware/`
//! under QEMU's `mps2-an500` — closed against the simulated stage on the host, one sample and
//! one command per tick in lockstep over the board's UART (QEMU's stdio).
//!
//! The plan's [`servo_runtime::Deployment`] goes to the target as an image at start (one
//! firmware runs every loop up to its order; nothing is rebuilt per controller). QEMU runs
//! with `-icount shift=0`: one guest instruction is one nanosecond of virtual time, so the
//! firmware's SysTick (25 MHz) counts one per [`INSTRUCTIONS_PER_COUNT`] instructions. Time on
//! a real part is estimated from those counts by [`TargetModel`], whose assumptions are stated:
//! QEMU models no pipeline, cache or FPU latency.

use crate::error::RunError;
use servo_runtime::link::{self, image, kind, Boot, FrameReader, Report, TickReply};
use servo_runtime::{ControllerKind, Deployment};
use std::io::{Read, Write};
use std::os::fd::AsFd;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};

/// Guest instructions per SysTick count under `-icount shift=0` (1 ns per instruction, SysTick
/// at the MPS2's 25 MHz processor clock).
pub const INSTRUCTIONS_PER_COUNT: f64 = 40.0;

/// The most bytes a firmware file may have.
const MAX_FIRMWARE_BYTES: u64 = 64 << 20;

/// How long the target may take to answer one frame (emulation on a busy host included).
const ANSWER_TIMEOUT_MS: u16 = 20_000;

/// How a tick's instruction count becomes time on a real part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetModel {
    /// The part's processor clock in Hz (480 MHz: an STM32H743/H753).
    pub clock_hz: f64,
    /// Cycles per instruction assumed: 1. The M7 dual-issues some pairs (< 1) and stalls on
    /// f64 divides, square roots and memory outside the TCMs (> 1); QEMU models none of it.
    pub cycles_per_instruction: f64,
    /// Share of the period the tick may take; the rest is interrupt entry, the converters'
    /// I/O and headroom.
    pub budget: f64,
}

impl Default for TargetModel {
    fn default() -> Self {
        TargetModel {
            clock_hz: 480e6,
            cycles_per_instruction: 1.0,
            budget: 0.8,
        }
    }
}

impl TargetModel {
    /// Seconds `instructions` take on the part.
    pub fn seconds(&self, instructions: f64) -> f64 {
        instructions * self.cycles_per_instruction / self.clock_hz
    }
}

/// What a PIL run needs besides its plan.
#[derive(Debug, Clone)]
pub struct PilOptions {
    /// The firmware ELF (`firmware/target/thumbv7em-none-eabihf/release/fts-firmware`).
    pub firmware: PathBuf,
    /// The QEMU system emulator (`qemu-system-arm`).
    pub qemu: PathBuf,
    /// The part the cost is converted for.
    pub model: TargetModel,
    /// Run even when the probe says the part cannot hold the rate (to measure the cost).
    pub force: bool,
}

impl PilOptions {
    /// PIL with `firmware` on `qemu-system-arm` from `PATH`, the default part, not forced.
    pub fn new(firmware: impl Into<PathBuf>) -> Self {
        PilOptions {
            firmware: firmware.into(),
            qemu: "qemu-system-arm".into(),
            model: TargetModel::default(),
            force: false,
        }
    }
}

/// What a PIL run measured on the target (its summary's `meta.target`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TargetMeta {
    /// Where the controller ran.
    pub machine: String,
    /// The firmware's build: `cortex-m7 (f64 in hardware, FPv5-D16)` or `f64 in software`.
    pub build: String,
    /// The firmware file.
    pub firmware: String,
    /// Guest instructions of a tick (the interrupt body), mean over the run.
    pub instructions_per_tick_mean: f64,
    /// The most guest instructions one tick took.
    pub instructions_per_tick_max: f64,
    /// The worst tick as time on the modelled part, s.
    pub tick_max_s: f64,
    /// The modelled part's clock, Hz, and the cycles per instruction assumed.
    pub clock_hz: f64,
    /// Cycles per instruction assumed.
    pub cycles_per_instruction: f64,
    /// Ticks whose time on the part exceeded the budget share of the period.
    pub over_budget_ticks: u64,
    /// Deepest stack use on the target, bytes.
    pub stack_used_bytes: u32,
    /// Why the link to the target was lost, if it was.
    pub lost: Option<String>,
}

/// Why a PIL run could not start or went on no further.
#[derive(Debug, thiserror::Error)]
pub enum PilError {
    /// The firmware file is not a readable ARM ELF of sane size.
    #[error("{}: {why}", path.display())]
    Firmware {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        why: String,
    },
    /// QEMU could not be started.
    #[error("could not start {}: {why} (install it: apt-get install qemu-system-arm)", qemu.display())]
    Emulator {
        /// The emulator.
        qemu: PathBuf,
        /// The OS error.
        why: String,
    },
    /// The target refused the loop, or cannot run it.
    #[error("the target refused the loop: {0}")]
    Refused(String),
    /// The link failed (the target stopped answering, a corrupted frame, QEMU exited).
    #[error("link to the target lost: {0}")]
    Lost(String),
}

/// Checks that `path` is a regular file of at most 64 MiB starting with the ELF magic.
fn check_firmware(path: &Path) -> Result<(), PilError> {
    let bad = |why: String| PilError::Firmware {
        path: path.to_owned(),
        why,
    };
    let meta = std::fs::metadata(path).map_err(|e| bad(e.to_string()))?;
    if !meta.is_file() {
        return Err(bad("not a regular file".into()));
    }
    if meta.len() > MAX_FIRMWARE_BYTES {
        return Err(bad(format!(
            "{} bytes, more than a firmware's {MAX_FIRMWARE_BYTES}",
            meta.len()
        )));
    }
    let mut head = [0u8; 20];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .map_err(|e| bad(e.to_string()))?;
    // ELF, 32-bit, little-endian, machine 40 (ARM).
    if head[..4] != *b"\x7fELF" || head[4] != 1 || head[5] != 1 || head[18] != 40 {
        return Err(bad(
            "not a 32-bit ARM ELF (build it: cd firmware && cargo build --release)".into(),
        ));
    }
    Ok(())
}

/// The largest state-space order of `d` (0 for PID and the cascade).
fn order_of(d: &Deployment) -> usize {
    match (&d.controller.kind, &d.controller.ss) {
        (ControllerKind::Ss, Some(m)) => m.order(),
        _ => 0,
    }
}

/// Refuses what the firmware's build cannot run.
fn check_boot(boot: &Boot, d: &Deployment) -> Result<(), PilError> {
    if boot.image_version != image::VERSION {
        return Err(PilError::Refused(format!(
            "the firmware reads deployment images of version {}, this servo writes {}: rebuild the firmware from this checkout",
            boot.image_version,
            image::VERSION
        )));
    }
    let order = order_of(d);
    if order > usize::from(boot.max_order) {
        return Err(PilError::Refused(format!(
            "controller order {order} is above the firmware's build (at most {}): reduce it (servo synth --order) or build the firmware for it",
            boot.max_order
        )));
    }
    Ok(())
}

/// Refuses a rate the modelled part cannot hold, judged by the probe's worst tick.
fn check_rate(
    m: &TargetModel,
    period_s: f64,
    probe_counts: u32,
    force: bool,
) -> Result<(), PilError> {
    let instructions = f64::from(probe_counts) * INSTRUCTIONS_PER_COUNT;
    let tick_s = m.seconds(instructions);
    let allowed_s = m.budget * period_s;
    if tick_s > allowed_s && !force {
        let max_rate = m.budget / tick_s;
        return Err(PilError::Refused(format!(
            "a tick takes about {instructions:.0} instructions on the target: {:.2} µs at {:.0} MHz ({} cycle per instruction), over {:.0} % of the {:.2} µs period; the part holds at most {:.0} Hz (plant.timing.servo_rate_hz) — or run it anyway to measure it (--force)",
            tick_s * 1e6,
            m.clock_hz / 1e6,
            m.cycles_per_instruction,
            m.budget * 100.0,
            period_s * 1e6,
            max_rate,
        )));
    }
    Ok(())
}

/// The loop running on the target.
pub struct TargetLoop {
    child: Child,
    input: ChildStdin,
    output: ChildStdout,
    reader: Box<FrameReader>,
    frame: Vec<u8>,
    outbox: Vec<u8>,
    inbox: [u8; 512],
    have: usize,
    at: usize,
    boot: Boot,
    opts: PilOptions,
    period_s: f64,
    last: Option<TickReply>,
    counts_total: u64,
    counts_max: u32,
    ticks: u64,
    over_budget: u64,
    lost: Option<String>,
}

impl TargetLoop {
    /// Boots the firmware, sends it `deployment` and waits until its loop is built; refuses a
    /// loop the firmware cannot run (an order above its build, a rate the modelled part cannot
    /// hold unless forced).
    pub fn start(deployment: &Deployment, opts: &PilOptions) -> Result<Self, PilError> {
        check_firmware(&opts.firmware)?;
        let mut child = Command::new(&opts.qemu)
            .args(["-M", "mps2-an500", "-nodefaults", "-display", "none"])
            .args(["-icount", "shift=0", "-no-reboot"])
            .args([
                "-chardev",
                "stdio,id=link,signal=off",
                "-serial",
                "chardev:link",
            ])
            .arg("-kernel")
            .arg(&opts.firmware)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| PilError::Emulator {
                qemu: opts.qemu.clone(),
                why: e.to_string(),
            })?;
        let (Some(input), Some(output)) = (child.stdin.take(), child.stdout.take()) else {
            let _ = child.kill();
            return Err(PilError::Lost("no pipes to the emulator".into()));
        };
        let mut target = TargetLoop {
            child,
            input,
            output,
            reader: Box::default(),
            frame: Vec::with_capacity(link::MAX_PAYLOAD),
            outbox: Vec::with_capacity(link::MAX_PAYLOAD + 8),
            inbox: [0; 512],
            have: 0,
            at: 0,
            boot: Boot {
                image_version: 0,
                max_order: 0,
                f64_in_hardware: false,
                stack_bytes: 0,
                systick_hz: 0,
            },
            opts: opts.clone(),
            period_s: deployment.period_s(),
            last: None,
            counts_total: 0,
            counts_max: 0,
            ticks: 0,
            over_budget: 0,
            lost: None,
        };
        target.expect(kind::BOOT)?;
        target.boot = Boot::decode(&target.frame)
            .ok_or_else(|| PilError::Lost("a BOOT frame of the wrong length".into()))?;
        check_boot(&target.boot, deployment)?;
        let mut bytes = vec![0u8; image::MAX_BYTES];
        let n = image::encode(deployment, &mut bytes)
            .ok_or_else(|| PilError::Refused("the deployment does not fit an image".into()))?;
        target.send(kind::LOAD, &bytes[..n])?;
        target.expect(kind::READY)?;
        let probe = <[u8; 4]>::try_from(target.frame.as_slice())
            .map(u32::from_le_bytes)
            .map_err(|_| PilError::Lost("a READY frame of the wrong length".into()))?;
        check_rate(&opts.model, deployment.period_s(), probe, opts.force)?;
        Ok(target)
    }

    fn send(&mut self, kind: u8, payload: &[u8]) -> Result<(), PilError> {
        self.outbox.clear();
        let out = &mut self.outbox;
        link::write_frame(kind, payload, |b| out.push(b));
        self.input
            .write_all(&self.outbox)
            .and_then(|()| self.input.flush())
            .map_err(|e| PilError::Lost(format!("writing to the emulator: {e}")))
    }

    /// Waits for the next frame (bounded by [`ANSWER_TIMEOUT_MS`]); its payload is left in
    /// `self.frame`. A REFUSED frame becomes [`PilError::Refused`].
    fn expect(&mut self, want: u8) -> Result<(), PilError> {
        loop {
            if self.at == self.have {
                self.fill()?;
            }
            let byte = self.inbox[self.at];
            self.at += 1;
            match self.reader.push(byte) {
                Ok(None) => {}
                Ok(Some((got, payload))) => {
                    self.frame.clear();
                    self.frame.extend_from_slice(payload);
                    return match got {
                        k if k == want => Ok(()),
                        kind::REFUSED => Err(PilError::Refused(
                            String::from_utf8_lossy(&self.frame).into_owned(),
                        )),
                        k => Err(PilError::Lost(format!(
                            "frame kind {k} where {want} was due"
                        ))),
                    };
                }
                Err(e) => return Err(PilError::Lost(e.to_string())),
            }
        }
    }

    fn fill(&mut self) -> Result<(), PilError> {
        use nix::poll::{poll, PollFd, PollFlags, PollTimeout};
        let mut fds = [PollFd::new(self.output.as_fd(), PollFlags::POLLIN)];
        let ready = poll(&mut fds, PollTimeout::from(ANSWER_TIMEOUT_MS))
            .map_err(|e| PilError::Lost(format!("waiting for the target: {e}")))?;
        if ready == 0 {
            return Err(PilError::Lost(format!(
                "the target did not answer within {} s",
                ANSWER_TIMEOUT_MS / 1000
            )));
        }
        let n = self
            .output
            .read(&mut self.inbox)
            .map_err(|e| PilError::Lost(format!("reading from the emulator: {e}")))?;
        if n == 0 {
            return Err(PilError::Lost("the emulator exited".into()));
        }
        (self.have, self.at) = (n, 0);
        Ok(())
    }

    /// One tick on the target: the sample out, the command and telemetry back (both None
    /// when `s` closes the run, as in process).
    pub fn tick(
        &mut self,
        s: &daq_io::Sensor,
    ) -> Result<(Option<daq_io::Command>, Option<daq_io::Telemetry>), PilError> {
        let mut bytes = [0u8; link::SENSOR_BYTES];
        link::encode_sensor(s, &mut bytes);
        self.send(kind::SAMPLE, &bytes)?;
        self.expect(kind::TICK)?;
        let reply = TickReply::decode(&self.frame)
            .ok_or_else(|| PilError::Lost("a TICK frame of the wrong length".into()))?;
        if reply.command.seq != s.seq {
            return Err(PilError::Lost(format!(
                "the target answered tick {} to sample {}",
                reply.command.seq, s.seq
            )));
        }
        self.last = Some(reply);
        let command = (s.flags & daq_io::flags::END == 0).then_some(reply.command);
        if command.is_some() {
            // The closing sample's tick gives no command: it is not a tick of the run.
            self.ticks += 1;
            self.counts_total += u64::from(reply.cost_counts);
            self.counts_max = self.counts_max.max(reply.cost_counts);
            let m = &self.opts.model;
            if m.seconds(f64::from(reply.cost_counts) * INSTRUCTIONS_PER_COUNT)
                > m.budget * self.period_s
            {
                self.over_budget += 1;
            }
        }
        Ok((command, reply.telemetry))
    }

    /// The trip the target's loop is in: its cause and tick.
    pub fn trip(&self) -> Option<(servo_runtime::TripCause, u64)> {
        self.last?.trip.map(|t| (t.cause, t.tick))
    }

    /// Tripped and settled: the run may end.
    pub fn run_over(&self) -> bool {
        self.last.is_some_and(|r| r.trip_settled)
    }

    /// Records why the link was lost (the run ends with `peer-lost`).
    pub fn lose(&mut self, e: &PilError) {
        self.lost = Some(e.to_string());
    }

    /// What the target is, for the recording's environment.
    pub fn describe(&self) -> Vec<(String, String)> {
        vec![
            ("controller_on".into(), self.machine()),
            ("target_build".into(), self.build()),
            (
                "target_firmware".into(),
                self.opts.firmware.display().to_string(),
            ),
        ]
    }

    fn machine(&self) -> String {
        "target: Cortex-M7 under qemu-system-arm (mps2-an500), one sample and one command per tick over UART0".into()
    }

    fn build(&self) -> String {
        if self.boot.f64_in_hardware {
            "cortex-m7: f64 in hardware (FPv5-D16)".into()
        } else {
            "thumbv7em default (Cortex-M4 FPU): f64 in software".into()
        }
    }

    /// Asks the target for its report, stops the emulator, and returns what was measured.
    pub fn finish(mut self) -> TargetMeta {
        let report = if self.lost.is_none() {
            self.send(kind::REPORT_REQUEST, &[])
                .and_then(|()| self.expect(kind::REPORT))
                .ok()
                .and_then(|()| Report::decode(&self.frame))
        } else {
            None
        };
        let _ = self.child.kill();
        let _ = self.child.wait();
        let m = self.opts.model;
        let mean = if self.ticks == 0 {
            0.0
        } else {
            self.counts_total as f64 / self.ticks as f64 * INSTRUCTIONS_PER_COUNT
        };
        let max = f64::from(self.counts_max) * INSTRUCTIONS_PER_COUNT;
        TargetMeta {
            machine: self.machine(),
            build: self.build(),
            firmware: self.opts.firmware.display().to_string(),
            instructions_per_tick_mean: mean,
            instructions_per_tick_max: max,
            tick_max_s: m.seconds(max),
            clock_hz: m.clock_hz,
            cycles_per_instruction: m.cycles_per_instruction,
            over_budget_ticks: self.over_budget,
            stack_used_bytes: report.map_or(0, |r| r.stack_used_bytes),
            lost: self.lost.take(),
        }
    }
}

/// A PIL run's facts for its recording's `end` record (what it measured on the target).
pub fn end_facts(t: &TargetMeta) -> Vec<(String, String)> {
    let mut facts = vec![
        (
            "target_instructions_per_tick_mean".to_string(),
            t.instructions_per_tick_mean.to_string(),
        ),
        (
            "target_instructions_per_tick_max".to_string(),
            t.instructions_per_tick_max.to_string(),
        ),
        ("target_clock_hz".to_string(), t.clock_hz.to_string()),
        (
            "target_cycles_per_instruction".to_string(),
            t.cycles_per_instruction.to_string(),
        ),
        (
            "target_over_budget_ticks".to_string(),
            t.over_budget_ticks.to_string(),
        ),
        (
            "target_stack_used_bytes".to_string(),
            t.stack_used_bytes.to_string(),
        ),
    ];
    if let Some(why) = &t.lost {
        facts.push(("target_lost".to_string(), why.clone()));
    }
    facts
}

impl TargetMeta {
    /// What a recording's `environment` and `end` records say of a PIL run (None for a run
    /// whose controller ran in process; numbers missing from an unfinished file read 0).
    pub fn from_records(
        environment: &std::collections::BTreeMap<String, String>,
        end: &std::collections::BTreeMap<String, String>,
    ) -> Option<Self> {
        let machine = environment.get("controller_on")?.clone();
        let text = |k: &str| environment.get(k).cloned().unwrap_or_default();
        let number = |k: &str| end.get(k).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
        let max = number("target_instructions_per_tick_max");
        let model = TargetModel {
            clock_hz: number("target_clock_hz"),
            cycles_per_instruction: number("target_cycles_per_instruction"),
            ..TargetModel::default()
        };
        Some(TargetMeta {
            machine,
            build: text("target_build"),
            firmware: text("target_firmware"),
            instructions_per_tick_mean: number("target_instructions_per_tick_mean"),
            instructions_per_tick_max: max,
            tick_max_s: if model.clock_hz > 0.0 {
                model.seconds(max)
            } else {
                0.0
            },
            clock_hz: model.clock_hz,
            cycles_per_instruction: model.cycles_per_instruction,
            over_budget_ticks: number("target_over_budget_ticks") as u64,
            stack_used_bytes: number("target_stack_used_bytes") as u32,
            lost: end.get("target_lost").cloned(),
        })
    }
}

impl Drop for TargetLoop {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl From<PilError> for RunError {
    fn from(e: PilError) -> Self {
        RunError::Pil(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use servo_runtime::SsMatrices;

    fn boot(max_order: u16) -> Boot {
        Boot {
            image_version: image::VERSION,
            max_order,
            f64_in_hardware: true,
            stack_bytes: 1 << 16,
            systick_hz: 25_000_000,
        }
    }

    #[test]
    fn an_order_above_the_firmwares_build_is_refused_naming_both() {
        let mut d = Deployment::thesis_prototype();
        d.controller.kind = ControllerKind::Ss;
        d.controller.ss = SsMatrices::from_fn(13, |i, j| if i == j { 0.5 } else { 0.0 });
        assert!(check_boot(&boot(40), &d).is_ok());
        let Err(PilError::Refused(why)) = check_boot(&boot(8), &d) else {
            panic!("order 13 on an order-8 build must be refused");
        };
        assert!(
            why.contains("order 13") && why.contains("at most 8"),
            "{why}"
        );
        // PID has no order.
        assert!(check_boot(&boot(8), &Deployment::thesis_prototype()).is_ok());
        // Another image version: rebuild the firmware.
        let old = Boot {
            image_version: image::VERSION + 1,
            ..boot(40)
        };
        assert!(matches!(check_boot(&old, &d), Err(PilError::Refused(w)) if w.contains("rebuild")));
    }

    #[test]
    fn the_rate_check_converts_counts_to_time_on_the_part() {
        let m = TargetModel::default();
        let period = 1.0 / 199_600.0; // 5.01 µs; 80 % of it is 4.008 µs = 1924 cycles at 480 MHz
                                      // 48 counts = 1920 instructions: fits; 49 counts = 1960: does not.
        assert!(check_rate(&m, period, 48, false).is_ok());
        let Err(PilError::Refused(why)) = check_rate(&m, period, 49, false) else {
            panic!("1960 instructions exceed 80 % of 5.01 µs at 480 MHz");
        };
        // The rate it would hold: 0.8 / (1960 / 480 MHz) = 195 918 Hz.
        assert!(why.contains("195918 Hz"), "{why}");
        assert!(check_rate(&m, period, 49, true).is_ok(), "--force runs it");
    }

    #[test]
    fn a_firmware_path_is_checked_before_qemu_sees_it() {
        let dir = tempfile::tempdir().unwrap();
        let not_elf = dir.path().join("fw.bin");
        std::fs::write(&not_elf, [0u8; 64]).unwrap();
        let x86_elf = dir.path().join("host.elf");
        let mut head = [0u8; 64];
        head[..6].copy_from_slice(b"\x7fELF\x02\x01");
        head[18] = 62; // x86-64
        std::fs::write(&x86_elf, head).unwrap();
        for (path, says) in [
            (dir.path().to_owned(), "not a regular file"),
            (not_elf, "not a 32-bit ARM ELF"),
            (x86_elf, "not a 32-bit ARM ELF"),
            (dir.path().join("missing"), "No such file"),
        ] {
            let e = check_firmware(&path).unwrap_err().to_string();
            assert!(
                e.contains(says) && e.contains(&*path.to_string_lossy()),
                "{e}"
            );
        }
    }
}
