//! # libfts_servo
//!
//! The controller's front door ([`servo_runtime::Servo`]) as a C ABI, for a DAQ daemon written
//! in C or C++: an opaque handle opened from a deployment file, ticked once per sample, closed.
//! All memory is allocated at open; a tick allocates nothing, takes no lock, logs nothing and
//! cannot panic across the boundary (a panic inside any call is caught and returned as
//! [`FTS_SERVO_ERR_INTERNAL`]). Errors are codes, each with a message on the handle
//! ([`fts_servo_last_error`]) naming the file, key and allowed range.
//!
//! The header `include/fts_servo.h` is generated from this file (cbindgen, in a test that fails
//! when it is stale) and includes `fts_servo_contract.h` for the sample types.

use daq_io::{flags, Command, Latency, Sensor, Telemetry};
use ffi_support::{copy_message, guard, text, ErrorText, TextError};
use servo_config::MAX_TEXT_BYTES;
use servo_runtime::Servo;
use std::ffi::c_char;

/// The version of this C ABI: the functions and the structs of `fts_servo.h` (the sample
/// structs carry their own, `FTS_SERVO_CONTRACT_VERSION`).
pub const FTS_SERVO_ABI_VERSION: u32 = 1;

/// Success.
pub const FTS_SERVO_OK: i32 = 0;
/// `fts_servo_tick`: the loop is tripped; the command is its safe state (write it) until
/// `fts_servo_reset`. The message names the cause and tick.
pub const FTS_SERVO_TRIPPED: i32 = 1;
/// A pointer argument was null.
pub const FTS_SERVO_ERR_NULL: i32 = -1;
/// The caller was built against another ABI version or struct sizes (`fts_servo_abi`).
pub const FTS_SERVO_ERR_ABI: i32 = -2;
/// A deployment or controller file that cannot be read, parsed or built: the message names
/// the file, line, key and allowed range.
pub const FTS_SERVO_ERR_CONFIG: i32 = -3;
/// A controller made for another plant or servo rate than the loop's.
pub const FTS_SERVO_ERR_PROVENANCE: i32 = -4;
/// Refused by the loop's stability range: a gain outside it, a controller whose loop is not
/// checked or would not keep its margin.
pub const FTS_SERVO_ERR_MARGIN: i32 = -5;
/// Serving over iceoryx2 failed (the prefix is another live run's, another user's).
pub const FTS_SERVO_ERR_SERVE: i32 = -6;
/// Not in this state: no telemetry before the first tick, served twice.
pub const FTS_SERVO_ERR_STATE: i32 = -7;
/// An internal error was caught at the boundary (a bug: please report the message).
pub const FTS_SERVO_ERR_INTERNAL: i32 = -8;

/// What the caller was compiled against, checked by `fts_servo_open`: pass
/// `FTS_SERVO_ABI_INIT`.
#[repr(C)]
pub struct FtsServoAbi {
    /// `FTS_SERVO_ABI_VERSION` of the header.
    pub abi_version: u32,
    /// `sizeof(fts_Sensor)`.
    pub sensor_size: u32,
    /// `sizeof(fts_Command)`.
    pub command_size: u32,
    /// `sizeof(fts_Telemetry)`.
    pub telemetry_size: u32,
    /// `sizeof(fts_servo_state)`.
    pub state_size: u32,
    /// 0.
    pub reserved: u32,
}

/// What the loop has done so far (`fts_servo_get_state`).
#[repr(C)]
pub struct FtsServoState {
    /// Ticks run.
    pub ticks: u64,
    /// The tick whose command was the first in the safe state (when `trip_cause` ≠ 0).
    pub trip_tick: u64,
    /// Ticks whose command was at the output limit.
    pub saturated_ticks: u64,
    /// Controllers handed over while running.
    pub handovers: u64,
    /// Trips since open.
    pub trips: u64,
    /// Ticks that started a period or more after their sample was taken.
    pub overruns: u64,
    /// Telemetry records a served loop dropped.
    pub telemetry_dropped: u64,
    /// The output scale in force.
    pub gain_scale: f64,
    /// The trip the loop is in: its `FTS_FLAG_TRIP_*` bit (0: not tripped).
    pub trip_cause: u32,
    /// 1 when the safe state has been held for `protection.after_trip_s`.
    pub trip_settled: u32,
    /// A stop the control plane asked for: `FTS_STOP_CAUSE_*` (0: none).
    pub stop_cause: u32,
    /// 0.
    pub reserved: u32,
    /// Start lateness of each timed tick (after its sample's `published_ns`), ns.
    pub lateness: Latency,
    /// Execution time of each timed tick, ns.
    pub execution: Latency,
}

/// An open loop (opaque to C).
pub struct FtsServo {
    servo: Servo,
    error: ErrorText,
}

mod load;
pub use load::*;

/// The library's version, `fts-servo 0.1.0` (a static string).
#[no_mangle]
pub extern "C" fn fts_servo_version() -> *const c_char {
    concat!("fts-servo ", env!("CARGO_PKG_VERSION"), "\0")
        .as_ptr()
        .cast()
}

/// The library's `FTS_SERVO_ABI_VERSION`.
#[no_mangle]
pub extern "C" fn fts_servo_abi_version() -> u32 {
    FTS_SERVO_ABI_VERSION
}

impl FtsServoAbi {
    /// This library's own: what `FTS_SERVO_ABI_INIT` gives a caller built against its header
    /// (for Rust code calling the C functions).
    pub fn of_this_library() -> Self {
        FtsServoAbi {
            abi_version: FTS_SERVO_ABI_VERSION,
            sensor_size: size_of::<Sensor>() as u32,
            command_size: size_of::<Command>() as u32,
            telemetry_size: size_of::<Telemetry>() as u32,
            state_size: size_of::<FtsServoState>() as u32,
            reserved: 0,
        }
    }

    /// The version and the four sizes, in that order.
    fn fields(&self) -> [u32; 5] {
        [
            self.abi_version,
            self.sensor_size,
            self.command_size,
            self.telemetry_size,
            self.state_size,
        ]
    }
}

/// Why `abi` does not match this library, if it does not.
fn abi_mismatch(abi: &FtsServoAbi) -> Option<String> {
    let ours = FtsServoAbi::of_this_library().fields();
    let theirs = abi.fields();
    (ours != theirs).then(|| {
        format!(
            "ABI mismatch: the caller was built against ABI {} with struct sizes sensor {}, command {}, telemetry {}, state {}; this library (fts-servo {}) is ABI {} with {}, {}, {}, {}: rebuild against its fts_servo.h",
            theirs[0], theirs[1], theirs[2], theirs[3], theirs[4],
            env!("CARGO_PKG_VERSION"), ours[0], ours[1], ours[2], ours[3], ours[4]
        )
    })
}

/// Opens the loop of the deployment file `path` (as `servo deploy` writes it), checked and
/// built; `abi` is `FTS_SERVO_ABI_INIT`. On success `*out` is the handle (close it with
/// `fts_servo_close`); on failure `*out` is NULL and the message is copied into
/// `error[0..error_len]` (which may be NULL).
///
/// # Safety
/// `path` is a NUL-terminated string; `abi` points to an `fts_servo_abi`; `out` points to a
/// writable handle pointer; `error` is NULL or points to `error_len` writable bytes.
#[no_mangle]
pub unsafe extern "C" fn fts_servo_open(
    path: *const c_char,
    abi: *const FtsServoAbi,
    out: *mut *mut FtsServo,
    error: *mut c_char,
    error_len: usize,
) -> i32 {
    // SAFETY: the caller's promises are this function's.
    unsafe { open(path, abi, out, error, error_len, Source::File) }
}

/// [`fts_servo_open`] from the deployment's TOML `text` itself.
///
/// # Safety
/// As [`fts_servo_open`], with `text` a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn fts_servo_open_toml(
    text: *const c_char,
    abi: *const FtsServoAbi,
    out: *mut *mut FtsServo,
    error: *mut c_char,
    error_len: usize,
) -> i32 {
    // SAFETY: the caller's promises are this function's.
    unsafe { open(text, abi, out, error, error_len, Source::Toml) }
}

/// Where a deployment comes from.
#[derive(Clone, Copy)]
enum Source {
    File,
    Toml,
}

/// # Safety
/// As [`fts_servo_open`].
unsafe fn open(
    arg: *const c_char,
    abi: *const FtsServoAbi,
    out: *mut *mut FtsServo,
    error: *mut c_char,
    error_len: usize,
    source: Source,
) -> i32 {
    let fail = |code: i32, message: &str| {
        // SAFETY: `error` is null or holds `error_len` writable bytes (the caller's promise).
        unsafe { copy_message(error, error_len, message) };
        code
    };
    if out.is_null() {
        return fail(FTS_SERVO_ERR_NULL, "out is a null pointer");
    }
    // SAFETY: `out` is non-null and writable (the caller's promise).
    unsafe { *out = std::ptr::null_mut() };
    if abi.is_null() {
        return fail(
            FTS_SERVO_ERR_NULL,
            "abi is a null pointer: pass &FTS_SERVO_ABI_INIT",
        );
    }
    // SAFETY: non-null, and the caller promises an fts_servo_abi.
    if let Some(why) = abi_mismatch(unsafe { &*abi }) {
        return fail(FTS_SERVO_ERR_ABI, &why);
    }
    guard(FTS_SERVO_ERR_INTERNAL, || {
        let (what, limit) = match source {
            Source::File => ("path", 4096),
            Source::Toml => ("text", MAX_TEXT_BYTES as usize),
        };
        // SAFETY: a NUL-terminated string (the caller's promise), read before we return.
        let arg = match unsafe { text(arg, what, limit) } {
            Ok(a) => a,
            Err(e @ TextError::Null(_)) => return fail(FTS_SERVO_ERR_NULL, &e.to_string()),
            Err(e) => return fail(FTS_SERVO_ERR_CONFIG, &e.to_string()),
        };
        let built = match source {
            Source::File => Servo::from_file(arg),
            Source::Toml => Servo::from_toml(arg),
        };
        match built {
            Ok(servo) => {
                let handle = Box::new(FtsServo {
                    servo,
                    error: ErrorText::default(),
                });
                // SAFETY: `out` is non-null and writable (checked above).
                unsafe { *out = Box::into_raw(handle) };
                FTS_SERVO_OK
            }
            Err(e) => fail(FTS_SERVO_ERR_CONFIG, &e.to_string()),
        }
    })
}

/// Runs `f` on the handle `h`, or returns [`FTS_SERVO_ERR_NULL`] for a null handle.
///
/// # Safety
/// `h` is null or a handle from `fts_servo_open` not yet closed, used by no other thread now.
pub(crate) unsafe fn with(h: *mut FtsServo, f: impl FnOnce(&mut FtsServo) -> i32) -> i32 {
    if h.is_null() {
        return FTS_SERVO_ERR_NULL;
    }
    // SAFETY: non-null, a live handle, used by this thread alone (the caller's promise).
    let h = unsafe { &mut *h };
    guard(FTS_SERVO_ERR_INTERNAL, || f(h))
}

/// One tick: reads `*sample` (its `seq`, the gap and accelerometer readings in V, flags, and
/// `published_ns` for timing), writes the command into `*command`. Returns
/// [`FTS_SERVO_OK`], or [`FTS_SERVO_TRIPPED`] while the loop is in its safe state (the command
/// is that state's: write it). Real-time safe: no allocation, lock, log or system call (but the
/// monotonic clock's vDSO read when `published_ns` ≠ 0).
///
/// # Safety
/// `h` is a live handle used by this thread alone; `sample` and `command` point to an
/// `fts_Sensor` and a writable `fts_Command`.
#[no_mangle]
pub unsafe extern "C" fn fts_servo_tick(
    h: *mut FtsServo,
    sample: *const Sensor,
    command: *mut Command,
) -> i32 {
    // The tick has no panicking path (servo-runtime's no-allocation and fault tests drive it
    // through NaN, saturation, trips and handovers); should one ever panic, an `extern "C"`
    // function aborts the process rather than unwind into C. So no unwind guard here: it
    // would cost the tick an indirect call.
    if h.is_null() | sample.is_null() | command.is_null() {
        // SAFETY: `h` is null or live (the caller's promise).
        return unsafe { null_argument(h) };
    }
    // SAFETY: non-null, a live handle, used by this thread alone (the caller's promise).
    let h = unsafe { &mut *h };
    // SAFETY: non-null and an fts_Sensor (the caller's promise).
    let c = h.servo.tick(unsafe { &*sample });
    // SAFETY: non-null and writable (the caller's promise).
    unsafe { *command = c };
    if c.flags & flags::TRIPPED == 0 {
        return FTS_SERVO_OK;
    }
    tripped(h)
}

/// A tick given a null pointer (off the fast path).
///
/// # Safety
/// `h` is null or a live handle used by this thread alone.
#[cold]
unsafe fn null_argument(h: *mut FtsServo) -> i32 {
    // SAFETY: null, or a live handle used by this thread alone (the caller's promise).
    if let Some(h) = unsafe { h.as_mut() } {
        h.error
            .set(format_args!("sample or command is a null pointer"));
    }
    FTS_SERVO_ERR_NULL
}

/// The message of a tripped tick (off the fast path).
#[cold]
fn tripped(h: &mut FtsServo) -> i32 {
    if let Some(t) = h.servo.status().trip {
        h.error.set(format_args!(
            "tripped: {} at tick {}; the command is the safe state until fts_servo_reset",
            t.cause.name(),
            t.tick
        ));
    }
    FTS_SERVO_TRIPPED
}

/// The last tick's telemetry into `*out`: its reference, the reading it acted on, the
/// following error, the feedback's own error, the command and flags (real-time safe).
/// [`FTS_SERVO_ERR_STATE`] before the first tick.
///
/// # Safety
/// `h` is a live handle used by this thread alone; `out` points to a writable `fts_Telemetry`.
#[no_mangle]
pub unsafe extern "C" fn fts_servo_telemetry(h: *mut FtsServo, out: *mut Telemetry) -> i32 {
    let body = |h: &mut FtsServo| {
        if out.is_null() {
            h.error.set(format_args!("out is a null pointer"));
            return FTS_SERVO_ERR_NULL;
        }
        match h.servo.telemetry() {
            Some(t) => {
                // SAFETY: non-null and writable (the caller's promise).
                unsafe { *out = *t };
                FTS_SERVO_OK
            }
            None => {
                h.error.set(format_args!("no tick has run yet"));
                FTS_SERVO_ERR_STATE
            }
        }
    };
    // SAFETY: the caller's promises about `h`.
    unsafe { with(h, body) }
}

/// What the loop has done so far into `*out` (a scan of its timing histograms: cheap, no
/// allocation).
///
/// # Safety
/// `h` is a live handle used by this thread alone; `out` points to a writable
/// `fts_servo_state`.
#[no_mangle]
pub unsafe extern "C" fn fts_servo_get_state(h: *mut FtsServo, out: *mut FtsServoState) -> i32 {
    let body = |h: &mut FtsServo| {
        if out.is_null() {
            h.error.set(format_args!("out is a null pointer"));
            return FTS_SERVO_ERR_NULL;
        }
        let (s, timing) = (h.servo.status(), h.servo.timing());
        let state = FtsServoState {
            ticks: s.ticks,
            trip_tick: s.trip.map_or(0, |t| t.tick),
            saturated_ticks: s.saturated_ticks,
            handovers: s.handovers,
            trips: s.trips,
            overruns: s.overruns,
            telemetry_dropped: s.telemetry_dropped,
            gain_scale: s.gain_scale,
            trip_cause: s.trip.map_or(0, |t| t.cause.flag()),
            trip_settled: u32::from(s.trip_settled),
            stop_cause: s.stop.unwrap_or(0),
            reserved: 0,
            lateness: timing.lateness,
            execution: timing.execution,
        };
        // SAFETY: non-null and writable (the caller's promise).
        unsafe { *out = state };
        FTS_SERVO_OK
    };
    // SAFETY: the caller's promises about `h`.
    unsafe { with(h, body) }
}

/// Scales the controller output by `scale` from the next tick; [`FTS_SERVO_ERR_MARGIN`]
/// outside the loop's checked range (the message gives it).
///
/// # Safety
/// `h` is a live handle used by this thread alone.
#[no_mangle]
pub unsafe extern "C" fn fts_servo_set_gain(h: *mut FtsServo, scale: f64) -> i32 {
    let body = |h: &mut FtsServo| match h.servo.set_gain(scale) {
        Ok(()) => FTS_SERVO_OK,
        Err(e) => {
            h.error.set(format_args!("{e}"));
            FTS_SERVO_ERR_MARGIN
        }
    };
    // SAFETY: the caller's promises about `h`.
    unsafe { with(h, body) }
}

/// Re-arms the loop after a trip: protection cleared, controller and feedforward back to their
/// initial state; the next command starts from the safe state's and the difference fades in
/// 5 ms.
///
/// # Safety
/// `h` is a live handle used by this thread alone.
#[no_mangle]
pub unsafe extern "C" fn fts_servo_reset(h: *mut FtsServo) -> i32 {
    let body = |h: &mut FtsServo| {
        h.servo.reset();
        h.error.clear();
        FTS_SERVO_OK
    };
    // SAFETY: the caller's promises about `h`.
    unsafe { with(h, body) }
}

/// Serves the loop on run `prefix`: telemetry, health and the control plane over iceoryx2 from
/// a thread of its own (`servo record`, `servo ctl`, `servo view` and Python taps work against
/// it). Call before the first tick.
///
/// # Safety
/// `h` is a live handle used by this thread alone; `prefix` is a NUL-terminated string.
#[cfg(feature = "serve")]
#[no_mangle]
pub unsafe extern "C" fn fts_servo_serve(h: *mut FtsServo, prefix: *const c_char) -> i32 {
    let body = |h: &mut FtsServo| {
        // SAFETY: a NUL-terminated string (the caller's promise), read before we return.
        let prefix = match unsafe { text(prefix, "prefix", 256) } {
            Ok(p) => p,
            Err(e) => {
                h.error.set(format_args!("{e}"));
                if matches!(e, TextError::Content(_)) {
                    return FTS_SERVO_ERR_CONFIG;
                }
                return FTS_SERVO_ERR_NULL;
            }
        };
        match h.servo.serve(prefix) {
            Ok(()) => FTS_SERVO_OK,
            Err(servo_runtime::ServeError::AlreadyServed) => {
                h.error.set(format_args!("the loop is served already"));
                FTS_SERVO_ERR_STATE
            }
            Err(e) => {
                h.error.set(format_args!("{e}"));
                FTS_SERVO_ERR_SERVE
            }
        }
    };
    // SAFETY: the caller's promises about `h`.
    unsafe { with(h, body) }
}

/// Ends the service of a served loop: the last telemetry with the run's end, a final health
/// report (faulted with `faults`, `FTS_FLAG_*` bits, when nonzero). Waits for subscribers to
/// take them (up to 5 s). Nothing to do for a loop that is not served.
///
/// # Safety
/// `h` is a live handle used by this thread alone.
#[cfg(feature = "serve")]
#[no_mangle]
pub unsafe extern "C" fn fts_servo_end_service(h: *mut FtsServo, faults: u32) -> i32 {
    let body = |h: &mut FtsServo| {
        h.servo.close(faults);
        FTS_SERVO_OK
    };
    // SAFETY: the caller's promises about `h`.
    unsafe { with(h, body) }
}

/// The message of the last call that failed on `h` (or tripped), NUL-terminated; valid until
/// the next call on `h`. An empty string when there is none; a static message for a null `h`.
///
/// # Safety
/// `h` is null or a live handle.
#[no_mangle]
pub unsafe extern "C" fn fts_servo_last_error(h: *const FtsServo) -> *const c_char {
    if h.is_null() {
        return c"the handle is a null pointer".as_ptr();
    }
    // SAFETY: non-null and live (the caller's promise).
    unsafe { (*h).error.as_ptr() }
}

/// Closes the loop: ends its service if served, frees the handle. NULL is ignored.
///
/// # Safety
/// `h` is null or a live handle, not used again.
#[no_mangle]
pub unsafe extern "C" fn fts_servo_close(h: *mut FtsServo) {
    if h.is_null() {
        return;
    }
    // SAFETY: a live handle from Box::into_raw in `open`, given back once (the caller's
    // promise); dropping it ends the service.
    let handle = unsafe { Box::from_raw(h) };
    let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| drop(handle)));
}
