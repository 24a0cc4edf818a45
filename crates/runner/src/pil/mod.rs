//! Processor in the loop: the run's controller on a Cortex-M7 — the firmware of `firmware/`
//! under QEMU's `mps2-an500` — closed against the simulated stage on the host, one sample and
//! one command per tick in lockstep over Arm semihosting on QEMU's standard input and output (a
//! frame per call each way, about 80 µs of wall time a tick; the board's UART under QEMU moved a
//! byte per turn of its event loop, about 3 ms a tick).
//!
//! The plan's [`servo_config::Deployment`] goes to the target as an image at start (one
//! firmware runs every loop up to its order; nothing is rebuilt per controller). QEMU runs
//! with `-icount` ([`ICOUNT_SHIFT`]): every guest instruction takes the same time of the
//! emulated clock, so the firmware's SysTick counts instructions ([`instructions_per_count`]).
//! Time on a real part is estimated from those counts by [`TargetModel`], whose assumptions
//! are stated: QEMU models no pipeline, cache or FPU latency.

use servo_config::{ControllerKind, Deployment};
use servo_link::{image, Boot};
use std::path::{Path, PathBuf};

mod elf;
mod meta;
mod target;

pub use meta::{end_facts, TargetMeta};
pub use target::TargetLoop;

/// QEMU's `-icount` shift: one guest instruction takes 2^5 = 32 ns of the emulated clock, so
/// the MPS2's 25 MHz SysTick counts one per 1.25 instructions.
pub const ICOUNT_SHIFT: u32 = 5;

/// Guest instructions per SysTick count of a target whose SysTick runs at `systick_hz` (Hz).
pub fn instructions_per_count(systick_hz: u32) -> f64 {
    1e9 / (f64::from(1u32 << ICOUNT_SHIFT) * f64::from(systick_hz.max(1)))
}

/// How long the target may take to answer one frame (emulation on a busy host included).
const ANSWER_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(20);

/// How a tick's instruction count becomes time on a real part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetModel {
    /// The part's processor clock in Hz (480 MHz: an STM32H743/H753).
    pub clock_hz: f64,
    /// Cycles per instruction assumed: 1.5, an estimate. QEMU counts instructions and models
    /// no pipeline; replayed through a model of the M7's dual issue and FPU latencies
    /// (`scripts/m7_cycles.py`, after the M7 machine model LLVM schedules with) the ticks
    /// here take 1.3 (PID) to 1.6 (the full H2 controller) cycles an instruction. Memory
    /// outside the tightly coupled memories, cache misses and mispredicted branches add to it:
    /// measure on the board.
    pub cycles_per_instruction: f64,
    /// Share of the period the tick may take; the rest is interrupt entry, the converters'
    /// I/O and headroom.
    pub budget: f64,
}

impl Default for TargetModel {
    fn default() -> Self {
        TargetModel {
            clock_hz: 480e6,
            cycles_per_instruction: 1.5,
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

/// Checks that `path` is a complete 32-bit ARM executable ([`elf::check`]) before QEMU sees it.
fn check_firmware(path: &Path) -> Result<(), PilError> {
    elf::check(path).map_err(|why| PilError::Firmware {
        path: path.to_owned(),
        why,
    })
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
            "controller order {order} is above the firmware's build (at most {}): reduce it (servo synth --order) or build the firmware with a higher FTS_SERVO_MAX_SS_ORDER (at most 40)",
            boot.max_order
        )));
    }
    Ok(())
}

/// Refuses a rate the modelled part cannot hold, judged by the probe's worst tick.
fn check_rate(
    m: &TargetModel,
    period_s: f64,
    instructions: f64,
    force: bool,
) -> Result<(), PilError> {
    let tick_s = m.seconds(instructions);
    let allowed_s = m.budget * period_s;
    if tick_s > allowed_s && !force {
        let max_rate = m.budget / tick_s;
        return Err(PilError::Refused(format!(
            "a tick takes {instructions:.0} instructions on the target: about {:.2} µs at {:.0} MHz ({} cycles per instruction, estimated), over {:.0} % of the {:.2} µs period; the part holds at most {:.0} Hz (plant.timing.servo_rate_hz) — or run it anyway to measure it (--force)",
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

#[cfg(test)]
mod tests {
    use super::*;
    use servo_config::SsMatrices;

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
        // 5.01 µs; 80 % of it is 4.008 µs = 1924 cycles at 480 MHz = 1282 instructions at 1.5.
        let period = 1.0 / 199_600.0;
        assert!(check_rate(&m, period, 1280.0, false).is_ok());
        let Err(PilError::Refused(why)) = check_rate(&m, period, 1290.0, false) else {
            panic!("1290 instructions exceed 80 % of 5.01 µs at 480 MHz");
        };
        // The rate it would hold: 0.8 / (1290 · 1.5 / 480 MHz) = 198 450 Hz.
        assert!(why.contains("198450 Hz"), "{why}");
        assert!(
            check_rate(&m, period, 1290.0, true).is_ok(),
            "--force runs it"
        );
        // QEMU's clock at shift 5 (32 ns an instruction) against the MPS2's 25 MHz SysTick.
        assert_eq!(instructions_per_count(25_000_000), 1.25);
    }

    /// An ELF header QEMU would be given: 32-bit, little-endian, executable, ARM.
    fn arm_elf_header() -> Vec<u8> {
        elf::minimal(64)
    }

    #[test]
    fn an_emulator_that_ends_is_reported_with_what_it_said() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let fw = dir.path().join("fw.elf");
        std::fs::write(&fw, arm_elf_header()).unwrap();
        let qemu = dir.path().join("qemu");
        std::fs::write(
            &qemu,
            "#!/bin/sh\necho 'no such machine: mps2-an500' >&2\nexit 3\n",
        )
        .unwrap();
        std::fs::set_permissions(&qemu, std::fs::Permissions::from_mode(0o700)).unwrap();
        let opts = PilOptions {
            qemu,
            ..PilOptions::new(&fw)
        };
        let Err(PilError::Lost(why)) = TargetLoop::start(&Deployment::thesis_prototype(), &opts)
        else {
            panic!("an emulator that exits at once loses the link");
        };
        assert!(
            why.contains("exit status: 3") && why.contains("no such machine"),
            "{why}"
        );
    }

    #[test]
    fn a_firmware_path_is_checked_before_qemu_sees_it() {
        let dir = tempfile::tempdir().unwrap();
        let not_elf = dir.path().join("fw.bin");
        std::fs::write(&not_elf, [0u8; 64]).unwrap();
        let x86_elf = dir.path().join("host.elf");
        let mut head = [0u8; 64];
        head[..6].copy_from_slice(b"\x7fELF\x01\x01");
        head[16] = 2;
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
