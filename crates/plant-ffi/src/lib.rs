//! # libfts_plant
//!
//! The simulated stage of fts-servo as a C ABI: the seeded four-mass stage of a run
//! configuration, stepped one tick at a time — the command in, the reading at the tick's end
//! and what really happened out. What `servo run` closes its loop against, for a C or C++
//! daemon that wants the same stage before it touches hardware. A separate library from
//! libfts_servo, so a daemon does not carry the simulator and its numerics.

use daq_io::{Backend, Sensor, Truth};
use ffi_support::{copy_message, guard, text, ErrorText};
use run_config::{simulated_stage, Loaded, SimBackend};
use std::ffi::c_char;

/// Success.
pub const FTS_PLANT_OK: i32 = 0;
/// A pointer argument was null.
pub const FTS_PLANT_ERR_NULL: i32 = -1;
/// The configuration cannot be read, parsed or built: the message names the file, line, key
/// and allowed range.
pub const FTS_PLANT_ERR_CONFIG: i32 = -3;
/// The run's ticks are done (`fts_plant_ticks`): step no further.
pub const FTS_PLANT_ERR_END: i32 = -7;
/// An internal error was caught at the boundary (a bug: please report the message).
pub const FTS_PLANT_ERR_INTERNAL: i32 = -8;

/// A simulated stage (opaque to C).
pub struct FtsPlant {
    stage: SimBackend,
    next_seq: u64,
    ticks: u64,
    error: ErrorText,
}

/// Opens the stage of the run configuration file `config` (`servo run -c`'s; NULL: the thesis
/// prototype): its plant, noise seed (`run.seed`) and scenario's cutting profile. On failure
/// `*out` is NULL and the message is copied into `error[0..error_len]` (which may be NULL).
///
/// # Safety
/// `config` is NULL or a NUL-terminated string; `out` points to a writable handle pointer;
/// `error` is NULL or points to `error_len` writable bytes.
#[no_mangle]
pub unsafe extern "C" fn fts_plant_open(
    config: *const c_char,
    out: *mut *mut FtsPlant,
    error: *mut c_char,
    error_len: usize,
) -> i32 {
    let fail = |code: i32, message: &str| {
        // SAFETY: `error` is null or holds `error_len` writable bytes (the caller's promise).
        unsafe { copy_message(error, error_len, message) };
        code
    };
    if out.is_null() {
        return fail(FTS_PLANT_ERR_NULL, "out is a null pointer");
    }
    // SAFETY: non-null and writable (the caller's promise).
    unsafe { *out = std::ptr::null_mut() };
    guard(FTS_PLANT_ERR_INTERNAL, || {
        let loaded = if config.is_null() {
            Ok(Loaded::default())
        } else {
            // SAFETY: a NUL-terminated string (the caller's promise), read before we return.
            match unsafe { text(config, "config", 4096) } {
                Ok(path) => Loaded::from_file(path.as_ref()),
                Err(e @ ffi_support::TextError::Null(_)) => {
                    return fail(FTS_PLANT_ERR_NULL, &e.to_string())
                }
                Err(e) => return fail(FTS_PLANT_ERR_CONFIG, &e.to_string()),
            }
        };
        let built = loaded
            .map_err(run_config::StageError::from)
            .and_then(|l| Ok((simulated_stage(&l)?, l.config.ticks())));
        match built {
            Ok((stage, ticks)) => {
                let handle = Box::new(FtsPlant {
                    stage,
                    next_seq: 0,
                    ticks,
                    error: ErrorText::default(),
                });
                // SAFETY: non-null and writable (checked above).
                unsafe { *out = Box::into_raw(handle) };
                FTS_PLANT_OK
            }
            Err(e) => fail(FTS_PLANT_ERR_CONFIG, &e.to_string()),
        }
    })
}

/// Runs `f` on the handle `p`.
///
/// # Safety
/// `p` is null or a live handle used by this thread alone.
unsafe fn with(p: *mut FtsPlant, f: impl FnOnce(&mut FtsPlant) -> i32) -> i32 {
    if p.is_null() {
        return FTS_PLANT_ERR_NULL;
    }
    // SAFETY: non-null, live, this thread's (the caller's promise).
    let p = unsafe { &mut *p };
    guard(FTS_PLANT_ERR_INTERNAL, || f(p))
}

/// The reading before the first command (tick 0) into `*sample`.
///
/// # Safety
/// `p` is a live handle used by this thread alone; `sample` points to a writable `fts_Sensor`.
#[no_mangle]
pub unsafe extern "C" fn fts_plant_initial(p: *mut FtsPlant, sample: *mut Sensor) -> i32 {
    let body = |p: &mut FtsPlant| {
        if sample.is_null() {
            p.error.set(format_args!("sample is a null pointer"));
            return FTS_PLANT_ERR_NULL;
        }
        let s = Sensor {
            seq: 0,
            ..p.stage.initial()
        };
        p.next_seq = 1;
        // SAFETY: non-null and writable (the caller's promise).
        unsafe { *sample = s };
        FTS_PLANT_OK
    };
    // SAFETY: the caller's promises about `p`.
    unsafe { with(p, body) }
}

/// Holds `dac_v` (V) for one tick; the reading at its end into `*sample` (its `seq` counts
/// the ticks) and, when `truth` is not NULL, what really happened into `*truth`.
/// [`FTS_PLANT_ERR_END`] after `fts_plant_ticks` steps.
///
/// # Safety
/// `p` is a live handle used by this thread alone; `sample` points to a writable
/// `fts_Sensor`; `truth` is NULL or points to a writable `fts_Truth`.
#[no_mangle]
pub unsafe extern "C" fn fts_plant_step(
    p: *mut FtsPlant,
    dac_v: f64,
    sample: *mut Sensor,
    truth: *mut Truth,
) -> i32 {
    let body = |p: &mut FtsPlant| {
        if sample.is_null() {
            p.error.set(format_args!("sample is a null pointer"));
            return FTS_PLANT_ERR_NULL;
        }
        if p.next_seq > p.ticks {
            p.error
                .set(format_args!("the run's {} ticks are done", p.ticks));
            return FTS_PLANT_ERR_END;
        }
        let s = Sensor {
            seq: p.next_seq.max(1),
            ..p.stage.step(dac_v)
        };
        p.next_seq = s.seq + 1;
        // SAFETY: non-null and writable (the caller's promise).
        unsafe { *sample = s };
        if !truth.is_null() {
            let t = Truth {
                seq: s.seq - 1,
                ..p.stage.truth().unwrap_or_default()
            };
            // SAFETY: non-null and writable (the caller's promise).
            unsafe { *truth = t };
        }
        FTS_PLANT_OK
    };
    // SAFETY: the caller's promises about `p`.
    unsafe { with(p, body) }
}

/// The run's ticks (its `run.duration_s` at its servo rate): the commands it takes.
///
/// # Safety
/// `p` is null or a live handle.
#[no_mangle]
pub unsafe extern "C" fn fts_plant_ticks(p: *const FtsPlant) -> u64 {
    if p.is_null() {
        return 0;
    }
    // SAFETY: non-null and live (the caller's promise).
    unsafe { (*p).ticks }
}

/// The servo period in s.
///
/// # Safety
/// `p` is null or a live handle.
#[no_mangle]
pub unsafe extern "C" fn fts_plant_period_s(p: *const FtsPlant) -> f64 {
    if p.is_null() {
        return 0.0;
    }
    // SAFETY: non-null and live (the caller's promise).
    unsafe { (*p).stage.sim().period_s() }
}

/// The message of the last call that failed on `p`, NUL-terminated; valid until the next
/// call on `p`.
///
/// # Safety
/// `p` is null or a live handle.
#[no_mangle]
pub unsafe extern "C" fn fts_plant_last_error(p: *const FtsPlant) -> *const c_char {
    if p.is_null() {
        return c"the handle is a null pointer".as_ptr();
    }
    // SAFETY: non-null and live (the caller's promise).
    unsafe { (*p).error.as_ptr() }
}

/// Frees the stage. NULL is ignored.
///
/// # Safety
/// `p` is null or a live handle, not used again.
#[no_mangle]
pub unsafe extern "C" fn fts_plant_close(p: *mut FtsPlant) {
    if !p.is_null() {
        // SAFETY: a live handle from Box::into_raw in `fts_plant_open`, given back once.
        drop(unsafe { Box::from_raw(p) });
    }
}
