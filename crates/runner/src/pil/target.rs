//! The loop on the target: QEMU started, the firmware booted and loaded, one frame out and one
//! back per tick.

use super::{
    check_boot, check_firmware, check_rate, instructions_per_count, PilError, PilOptions,
    TargetMeta, ANSWER_TIMEOUT, ICOUNT_SHIFT,
};
use servo_config::Deployment;
use servo_link::TickReply;
use servo_link::{self as link, image, kind, Boot, BootError, FrameReader, Ready, Report};
use std::io::{Read, Write};
use std::os::fd::AsFd;
use std::os::unix::process::CommandExt;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::time::Instant;

/// The most of QEMU's own messages kept (it names a missing machine, an unloadable file).
const STDERR_BYTES: u64 = 4096;

/// The command that starts `qemu`: through util-linux's `setpriv --pdeathsig KILL` when it is
/// on `PATH`, so the emulator dies with this process even when it is killed outright (it
/// would otherwise wait on its link forever).
fn emulator(qemu: &std::path::Path) -> Command {
    let setpriv = std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|dir| dir.join("setpriv"))
            .find(|p| p.is_file())
    });
    match setpriv {
        Some(setpriv) => {
            let mut c = Command::new(setpriv);
            c.args(["--pdeathsig", "KILL", "--"]).arg(qemu);
            c
        }
        None => Command::new(qemu),
    }
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
    per_count: f64,
    load_stack_bytes: u32,
    /// The thread draining QEMU's stderr; it returns the first [`STDERR_BYTES`] of it.
    stderr: Option<std::thread::JoinHandle<String>>,
    opts: PilOptions,
    period_s: f64,
    last: Option<TickReply>,
    counts_total: u64,
    counts_max: u32,
    ticks: u64,
    samples: u64,
    over_budget: u64,
    lost: Option<String>,
}

impl TargetLoop {
    /// Boots the firmware, sends it `deployment` and waits until its loop is built; refuses a
    /// loop the firmware cannot run (an order above its build, a rate the modelled part cannot
    /// hold unless forced).
    pub fn start(deployment: &Deployment, opts: &PilOptions) -> Result<Self, PilError> {
        check_firmware(&opts.firmware)?;
        let icount = format!("shift={ICOUNT_SHIFT}");
        let mut child = emulator(&opts.qemu)
            .args(["-M", "mps2-an500", "-nodefaults", "-display", "none"])
            .args(["-icount", &icount, "-no-reboot"])
            // The link is Arm semihosting on QEMU's own standard input and output (`:tt`): the
            // firmware reads what the host sent and writes a frame in one call each.
            .args(["-semihosting-config", "enable=on,target=native"])
            .arg("-kernel")
            .arg(&opts.firmware)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            // Its own process group: a Ctrl-C at the terminal stops the run, not the target.
            .process_group(0)
            .spawn()
            .map_err(|e| PilError::Emulator {
                qemu: opts.qemu.clone(),
                why: e.to_string(),
            })?;
        let (Some(input), Some(output), Some(err)) =
            (child.stdin.take(), child.stdout.take(), child.stderr.take())
        else {
            let _ = child.kill();
            let _ = child.wait();
            return Err(PilError::Lost("no pipes to the emulator".into()));
        };
        // Drained as it comes (a full pipe would stall QEMU), the first few KiB kept.
        let stderr = std::thread::spawn(move || {
            let mut err = err;
            let mut head = String::new();
            let _ = (&mut err).take(STDERR_BYTES).read_to_string(&mut head);
            let _ = std::io::copy(&mut err, &mut std::io::sink());
            head
        });
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
            boot: Boot::default(),
            per_count: 0.0,
            load_stack_bytes: 0,
            stderr: Some(stderr),
            opts: opts.clone(),
            period_s: deployment.period_s(),
            last: None,
            counts_total: 0,
            counts_max: 0,
            ticks: 0,
            samples: 0,
            over_budget: 0,
            lost: None,
        };
        target.expect(kind::BOOT)?;
        target.boot = Boot::decode(&target.frame).map_err(|e| match e {
            BootError::Version(v) => PilError::Refused(format!(
                "the firmware speaks link version {v}, this servo {}: rebuild the firmware from this checkout",
                link::LINK_VERSION
            )),
            BootError::Length => PilError::Lost("a BOOT frame of the wrong length".into()),
        })?;
        check_boot(&target.boot, deployment)?;
        target.per_count = instructions_per_count(target.boot.systick_hz);
        let mut bytes = vec![0u8; image::MAX_BYTES];
        let n = image::encode(deployment, &mut bytes)
            .ok_or_else(|| PilError::Refused("the deployment does not fit an image".into()))?;
        target.send(kind::LOAD, &bytes[..n])?;
        target.expect(kind::READY)?;
        let ready = Ready::decode(&target.frame)
            .ok_or_else(|| PilError::Lost("a READY frame of the wrong length".into()))?;
        target.load_stack_bytes = ready.load_stack_bytes;
        let probe = f64::from(ready.probe_counts) * target.per_count;
        check_rate(&opts.model, target.period_s, probe, opts.force)?;
        Ok(target)
    }

    fn send(&mut self, kind: u8, payload: &[u8]) -> Result<(), PilError> {
        self.outbox.clear();
        let out = &mut self.outbox;
        if !link::write_frame(kind, payload, |b| out.push(b)) {
            return Err(PilError::Lost(format!(
                "a frame of {} bytes (at most {})",
                payload.len(),
                link::MAX_PAYLOAD
            )));
        }
        self.input
            .write_all(&self.outbox)
            .and_then(|()| self.input.flush())
            .map_err(|e| PilError::Lost(format!("writing to the emulator: {e}")))
    }

    /// Waits for the next frame, whole within [`ANSWER_TIMEOUT`]; its payload is left in
    /// `self.frame`. A REFUSED frame becomes [`PilError::Refused`].
    fn expect(&mut self, want: u8) -> Result<(), PilError> {
        let deadline = Instant::now() + ANSWER_TIMEOUT;
        loop {
            if self.at == self.have {
                self.fill(deadline)?;
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

    fn fill(&mut self, deadline: Instant) -> Result<(), PilError> {
        use nix::poll::{poll, PollFd, PollFlags, PollTimeout};
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let ms = u16::try_from(left.as_millis()).unwrap_or(u16::MAX);
            let mut fds = [PollFd::new(self.output.as_fd(), PollFlags::POLLIN)];
            match poll(&mut fds, PollTimeout::from(ms)) {
                Ok(0) if left.is_zero() => {
                    return Err(PilError::Lost(format!(
                        "the target did not answer within {} s",
                        ANSWER_TIMEOUT.as_secs()
                    )))
                }
                Ok(0) => continue,
                Ok(_) => break,
                // A signal (Ctrl-C: the run's stop request) interrupts the wait, not the run.
                Err(nix::errno::Errno::EINTR) => continue,
                Err(e) => return Err(PilError::Lost(format!("waiting for the target: {e}"))),
            }
        }
        let n = self
            .output
            .read(&mut self.inbox)
            .map_err(|e| PilError::Lost(format!("reading from the emulator: {e}")))?;
        if n == 0 {
            return Err(PilError::Lost(self.exited()));
        }
        (self.have, self.at) = (n, 0);
        Ok(())
    }

    /// How the emulator ended, with the start of what it printed (QEMU names a missing
    /// machine, a firmware it cannot load).
    fn exited(&mut self) -> String {
        // Its stdout is closed: it is ending; make sure, then collect it (its stderr closes
        // with it, which ends the drain thread).
        let _ = self.child.kill();
        let status = self
            .child
            .wait()
            .map_or("unknown".into(), |s| s.to_string());
        let said = self
            .stderr
            .take()
            .and_then(|t| t.join().ok())
            .unwrap_or_default();
        match said.trim() {
            "" => format!("the emulator exited ({status})"),
            said => format!("the emulator exited ({status}): {said}"),
        }
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
        self.samples += 1;
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
            if m.seconds(f64::from(reply.cost_counts) * self.per_count) > m.budget * self.period_s {
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
        "target: Cortex-M7 under qemu-system-arm (mps2-an500), one sample and one command per tick over the semihosting console".into()
    }

    fn build(&self) -> String {
        if self.boot.f64_in_hardware {
            "cortex-m7: f64 in hardware (FPv5-D16)".into()
        } else {
            "thumbv7em default (Cortex-M4 FPU): f64 in software".into()
        }
    }

    /// Asks the target for its report and returns what was measured (the emulator stops when
    /// `self` drops, at the end).
    pub fn finish(mut self) -> TargetMeta {
        let (mut stack_used_bytes, mut run_counts) = (0, 0);
        if self.lost.is_none() {
            let asked = self
                .send(kind::REPORT_REQUEST, &[])
                .and_then(|()| self.expect(kind::REPORT));
            match asked.map(|()| Report::decode(&self.frame)) {
                // The target counts the closing sample's tick too.
                Ok(Some(r)) if r.ticks == self.samples => {
                    (stack_used_bytes, run_counts) = (r.stack_used_bytes, r.run_counts)
                }
                Ok(Some(r)) => {
                    self.lost = Some(format!(
                        "the target ticked {} times for {} samples",
                        r.ticks, self.samples
                    ))
                }
                Ok(None) => self.lost = Some("a REPORT frame of the wrong length".into()),
                Err(e) => self.lost = Some(format!("no report at the end: {e}")),
            }
        }
        let m = self.opts.model;
        let mean = if self.ticks == 0 {
            0.0
        } else {
            self.counts_total as f64 / self.ticks as f64 * self.per_count
        };
        let max = f64::from(self.counts_max) * self.per_count;
        let run = if self.samples == 0 {
            0.0
        } else {
            run_counts as f64 / self.samples as f64 * self.per_count
        };
        TargetMeta {
            machine: self.machine(),
            build: self.build(),
            firmware: self.opts.firmware.display().to_string(),
            instructions_per_tick_mean: mean,
            instructions_per_tick_max: max,
            instructions_per_tick_run: run,
            tick_max_s: m.seconds(max),
            clock_hz: m.clock_hz,
            cycles_per_instruction: m.cycles_per_instruction,
            over_budget_ticks: self.over_budget,
            stack_used_bytes,
            load_stack_bytes: self.load_stack_bytes,
            stack_bytes: self.boot.stack_bytes,
            lost: self.lost.take(),
        }
    }
}

impl Drop for TargetLoop {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
