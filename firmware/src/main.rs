//! fts-servo on a Cortex-M7: the runtime's per-tick core ([`servo_runtime::Servo`], `no_std`,
//! no allocator) ticked in the TIMER0 interrupt, closed against the host's simulated stage over
//! the semihosting console (`console.rs`) — processor in the loop (`servo run --pil`).
//!
//! At reset the firmware sends a BOOT frame (what it is), then waits for the deployment image
//! the host sends (the same deployment `servo run` builds from the configuration; see
//! `servo_link::image`). It builds the loop, measures a probe of quiet ticks, builds
//! the loop again from scratch and answers READY (or REFUSED with the reason). From then on each
//! SAMPLE frame is the tick's "ADC conversion": it pends TIMER0, whose handler runs the tick and
//! times it with SysTick; the main loop sends the TICK reply. On a board the same handler is
//! entered by the timer itself at the servo rate (README.md).
#![no_std]
#![no_main]

mod clock;
mod console;
mod stack;

use console::Console;
use core::cell::RefCell;
use core::fmt::Write as _;
use cortex_m::peripheral::{syst::SystClkSource, NVIC, SYST};
use cortex_m_rt::entry;
use critical_section::Mutex;
use daq_io::{Command, Sensor};
use servo_link::{self as link, image, kind, Boot, FrameReader, Ready, Report, TickReply};
use servo_runtime::deployment::MAX_SS_ORDER;
use servo_runtime::{Deployment, Servo};

/// The MPS2 board's processor clock in Hz (SysTick counts it; 25 MHz on the FPGA image QEMU
/// models).
const SYSTICK_HZ: u32 = 25_000_000;
/// Quiet ticks the probe times before READY.
const PROBE_TICKS: u64 = 64;

/// The interrupt lines this firmware uses.
#[derive(Clone, Copy)]
enum Irq {
    /// CMSDK timer 0: the servo tick.
    Timer0 = 8,
}

// SAFETY: 8 is TIMER0's line on the mps2-an500 (Arm AN500); the vector table below has it.
unsafe impl cortex_m::interrupt::InterruptNumber for Irq {
    fn number(self) -> u16 {
        self as u16
    }
}

/// One entry of the device interrupt table.
#[repr(C)]
pub union Vector {
    handler: unsafe extern "C" fn(),
    reserved: usize,
}

extern "C" {
    fn TIMER0();
    fn DefaultHandler();
}

/// The board's 32 interrupt lines: TIMER0 is the tick, every other line reaches
/// cortex-m-rt's `DefaultHandler`.
#[link_section = ".vector_table.interrupts"]
#[no_mangle]
pub static __INTERRUPTS: [Vector; 32] = {
    let mut v = [Vector {
        handler: DefaultHandler,
    }; 32];
    v[Irq::Timer0 as usize] = Vector { handler: TIMER0 };
    v
};

impl Clone for Vector {
    fn clone(&self) -> Self {
        *self
    }
}
impl Copy for Vector {}

/// The loop and the tick's mailbox, shared by the main loop and the tick interrupt.
struct Loop {
    servo: Servo,
    /// A deployment's loop is built in `servo` (false until one is, and while one is built).
    ready: bool,
    sample: Sensor,
    /// The tick's command and its cost in SysTick counts, left by the tick interrupt.
    done: Option<(Command, u32)>,
    report: Report,
}

/// The sample before the first.
const NO_SAMPLE: Sensor = Sensor {
    seq: 0,
    time_s: 0.0,
    gap_v: 0.0,
    accel_v: 0.0,
    encoder_count: 0,
    flags: 0,
    reserved: 0,
    run_id: 0,
    published_ns: 0,
};

/// What a run has counted when it starts.
const NO_REPORT: Report = Report {
    ticks: 0,
    stack_used_bytes: 0,
    run_counts: 0,
};

/// The running loop, built in place ([`Servo::rebuild`]): never on the stack.
static LOOP: Mutex<RefCell<Loop>> = Mutex::new(RefCell::new(Loop {
    servo: Servo::UNBUILT,
    ready: false,
    sample: NO_SAMPLE,
    done: None,
    report: NO_REPORT,
}));

/// The deployment the host sent, decoded in place ([`image::decode_into`]).
static DEPLOYMENT: Mutex<RefCell<Deployment>> = Mutex::new(RefCell::new(Deployment::BLANK));

/// SysTick counts between two readings of its 24-bit down-counter.
fn elapsed(start: u32, end: u32) -> u32 {
    start.wrapping_sub(end) & 0x00FF_FFFF
}

/// Restarts SysTick's count and returns its first reading: each tick is timed from the same
/// phase of the counter's clock, so the same instructions always read the same counts.
#[inline(always)]
fn restart_stopwatch() -> u32 {
    // SAFETY: a write to SysTick's current-value register restarts the count from the reload
    // value; only the tick and the probe use SysTick, one at a time.
    unsafe { (*SYST::PTR).cvr.write(0) };
    SYST::get_current()
}

/// The servo tick: the sample in the mailbox through the loop, timed (`servo.tick` alone, not
/// the interrupt's entry), the command and its cost left in it (the main loop builds the
/// reply from them and the loop's telemetry and status). It holds the critical
/// section the main loop shares the loop with; on a board give the tick interrupt the loop to
/// itself (README: porting) so that interrupts above it still preempt.
#[export_name = "TIMER0"]
extern "C" fn servo_tick() {
    critical_section::with(|cs| {
        // The loop's address hidden from the optimiser: it is a constant (a static), and with
        // it every field would be reached by building its 32-bit address afresh (two or three
        // instructions a load on the M7); from one base register each is one load.
        let mut held = LOOP.borrow_ref_mut(cs);
        let l = core::hint::black_box(&mut *held);
        if l.ready {
            let start = restart_stopwatch();
            let command = l.servo.tick(&l.sample);
            l.done = Some((command, elapsed(start, SYST::get_current())));
            l.report.ticks += 1;
        }
    });
}

fn send(console: &mut Console, kind: u8, payload: &[u8]) {
    // Every payload here is a fixed-size record or a short text: far below the frame limit.
    let _ = link::write_frame(kind, payload, |b| console.put(b));
    console.flush();
}

/// A message in fixed storage (a refusal's text).
struct Text {
    buf: [u8; 256],
    len: usize,
}

impl Text {
    fn new() -> Self {
        Text {
            buf: [0; 256],
            len: 0,
        }
    }

    fn bytes(&self) -> &[u8] {
        &self.buf[..self.len]
    }
}

impl core::fmt::Write for Text {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        let n = s.len().min(self.buf.len() - self.len);
        self.buf[self.len..self.len + n].copy_from_slice(&s.as_bytes()[..n]);
        self.len += n;
        Ok(())
    }
}

/// The worst SysTick counts of [`PROBE_TICKS`] quiet ticks of `servo`, a loop just built.
fn probe(servo: &mut Servo) -> u32 {
    let mut s = NO_SAMPLE;
    let mut worst = 0;
    for k in 0..PROBE_TICKS {
        s.seq = k;
        s.time_s = k as f64 * servo.period_s();
        let start = restart_stopwatch();
        let _ = servo.tick(&s);
        worst = worst.max(elapsed(start, SYST::get_current()));
    }
    worst
}

/// Builds the loop of a deployment image where it runs: the image decoded into
/// [`DEPLOYMENT`], the loop built in [`LOOP`] (checked as `Servo::new` checks; its refusal
/// names the key), probed, and built again from scratch. The probe's worst tick in SysTick
/// counts, or None with the reason written to `why`.
#[inline(never)]
fn load(payload: &[u8], why: &mut Text) -> Option<u32> {
    critical_section::with(|cs| {
        let deployment = &mut *DEPLOYMENT.borrow_ref_mut(cs);
        let l = &mut *LOOP.borrow_ref_mut(cs);
        l.ready = false;
        if let Err(e) = image::decode_into(payload, deployment) {
            let _ = write!(why, "{e}");
            return None;
        }
        if let Err(e) = l.servo.rebuild(deployment) {
            let _ = write!(why, "{e}");
            return None;
        }
        // The loop's address hidden as the tick handler hides it: the same instructions.
        let worst = probe(core::hint::black_box(&mut l.servo));
        // The same deployment was accepted a moment ago.
        l.servo.rebuild(deployment).ok()?;
        (l.ready, l.sample, l.done, l.report) = (true, NO_SAMPLE, None, NO_REPORT);
        Some(worst)
    })
}

/// Runs one tick in the timer interrupt; the TICK frame to answer.
fn tick(payload: &[u8], console: &mut Console) {
    let Some(sample) = link::decode_sensor(payload) else {
        return send(console, kind::REFUSED, b"sample frame of the wrong length");
    };
    let loaded = critical_section::with(|cs| {
        let l = &mut *LOOP.borrow_ref_mut(cs);
        (l.sample, l.done) = (sample, None);
        l.ready
    });
    if !loaded {
        return send(
            console,
            kind::REFUSED,
            b"sample before a deployment was loaded",
        );
    }
    NVIC::pend(Irq::Timer0);
    // The interrupt is taken once the pend reaches the NVIC.
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
    let reply = critical_section::with(|cs| {
        let l = &mut *LOOP.borrow_ref_mut(cs);
        let (command, cost_counts) = l.done.take()?;
        let status = l.servo.status();
        Some(TickReply {
            command,
            telemetry: l.servo.telemetry().copied(),
            trip: status.trip,
            trip_settled: status.trip_settled,
            cost_counts,
        })
    });
    match reply {
        Some(r) => {
            let mut out = [0; link::TICK_BYTES];
            r.encode(&mut out);
            send(console, kind::TICK, &out);
        }
        None => send(console, kind::REFUSED, b"the tick interrupt did not run"),
    }
}

#[entry]
fn main() -> ! {
    let Some(mut core) = cortex_m::Peripherals::take() else {
        loop {
            cortex_m::asm::wfi();
        }
    };
    stack::paint();
    // SysTick free-running over its 24 bits at the processor clock: the tick's stopwatch.
    core.SYST.set_clock_source(SystClkSource::Core);
    core.SYST.set_reload(0x00FF_FFFF);
    core.SYST.clear_current();
    core.SYST.enable_counter();
    // SAFETY: the TIMER0 handler shares state only through the critical-section mutex.
    unsafe { NVIC::unmask(Irq::Timer0) };
    let Some(console) = cortex_m::singleton!(: Console = Console::open()) else {
        loop {
            cortex_m::asm::wfi();
        }
    };
    let boot = Boot {
        image_version: image::VERSION,
        max_order: MAX_SS_ORDER as u16,
        f64_in_hardware: cfg!(f64_in_hardware),
        stack_bytes: stack::size(),
        systick_hz: SYSTICK_HZ,
    };
    send(console, kind::BOOT, &boot.encode());
    let Some(reader) = cortex_m::singleton!(: FrameReader = FrameReader::default()) else {
        loop {
            cortex_m::asm::wfi();
        }
    };
    let mut run = clock::RunClock::start();
    loop {
        let byte = console.get();
        let frame = reader.push(byte);
        if let Ok(Some(_)) = frame {
            // Every frame: the clock's 32 bits never wrap between two readings.
            run.read();
        }
        match frame {
            Ok(None) => {}
            Ok(Some((kind::SAMPLE, p))) => tick(p, console),
            Ok(Some((kind::LOAD, p))) => {
                let mut why = Text::new();
                match load(p, &mut why) {
                    Some(probe_counts) => {
                        let ready = Ready {
                            probe_counts,
                            load_stack_bytes: stack::used(),
                        };
                        // The high-water mark from here on is the running loop's, and the
                        // run's clock counts from here.
                        stack::paint();
                        send(console, kind::READY, &ready.encode());
                        run.restart();
                    }
                    None => send(console, kind::REFUSED, why.bytes()),
                }
            }
            Ok(Some((kind::REPORT_REQUEST, _))) => {
                let mut report = critical_section::with(|cs| LOOP.borrow_ref(cs).report);
                report.stack_used_bytes = stack::used();
                report.run_counts = run.read();
                send(console, kind::REPORT, &report.encode());
            }
            Ok(Some(_)) => send(console, kind::REFUSED, b"unknown frame kind"),
            Err(e) => {
                let mut why = Text::new();
                let _ = write!(why, "{e}");
                send(console, kind::REFUSED, why.bytes());
            }
        }
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    let mut why = Text::new();
    let _ = write!(why, "firmware panicked: {}", info.message());
    if let Some(at) = info.location() {
        let _ = write!(why, " at {}:{}", at.file(), at.line());
    }
    send(&mut Console::open(), kind::REFUSED, why.bytes());
    loop {
        cortex_m::asm::wfi();
    }
}
