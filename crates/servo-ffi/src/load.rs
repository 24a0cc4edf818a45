//! Controller loads: in one call between ticks (`fts_servo_load`), or in two halves — checked
//! and built on any thread (`fts_servo_loader_new`, `fts_servo_prepare`), swapped in on the ticking
//! thread without allocating (`fts_servo_swap`).

use crate::{
    with, FtsServo, FTS_SERVO_ERR_CONFIG, FTS_SERVO_ERR_INTERNAL, FTS_SERVO_ERR_MARGIN,
    FTS_SERVO_ERR_NULL, FTS_SERVO_ERR_PROVENANCE, FTS_SERVO_ERR_STATE, FTS_SERVO_OK,
};
use ffi_support::{copy_message, guard};
use servo_runtime::{LoadError, Loader, Prepared};
use std::ffi::c_char;

/// The check a loop's controller files pass, taken from its handle (opaque to C): used on any
/// thread while the loop ticks.
pub struct FtsServoLoader {
    loader: Loader,
}

/// A controller checked and built for a loop, waiting to be swapped in (opaque to C); after
/// the swap it holds the controller it replaced.
pub struct FtsServoPrepared {
    prepared: Prepared,
}

/// The code of a load's refusal.
fn code_of(e: &LoadError) -> i32 {
    match e {
        LoadError::Refused(r) if r.status == daq_io::ack_status::REFUSED_PROVENANCE => {
            FTS_SERVO_ERR_PROVENANCE
        }
        LoadError::Refused(r) if r.status == daq_io::ack_status::REFUSED_MARGIN => {
            FTS_SERVO_ERR_MARGIN
        }
        LoadError::Margin { .. } => FTS_SERVO_ERR_MARGIN,
        LoadError::Spent | LoadError::OtherLoop => FTS_SERVO_ERR_STATE,
        _ => FTS_SERVO_ERR_CONFIG,
    }
}

/// The bytes `file[0..len]`, or the code and message of why not.
///
/// # Safety
/// `file` is null or points to `len` readable bytes that outlive the returned slice's use.
unsafe fn file_bytes<'a>(file: *const u8, len: usize) -> Result<&'a [u8], (i32, String)> {
    if file.is_null() {
        return Err((FTS_SERVO_ERR_NULL, "file is a null pointer".into()));
    }
    if len > daq_io::MAX_LOAD_BYTES {
        return Err((
            FTS_SERVO_ERR_CONFIG,
            format!(
                "file is {len} bytes, more than the {} a controller file may have",
                daq_io::MAX_LOAD_BYTES
            ),
        ));
    }
    // SAFETY: `len` readable bytes at `file` (the caller's promise).
    Ok(unsafe { std::slice::from_raw_parts(file, len) })
}

/// Loads the controller file `file[0..len]` (UTF-8 TOML: a `[controller]` table or a
/// state-space file) into the running loop, handed over bumplessly at the next tick — taken
/// only when made for the loop's plant and rate and carrying its offline stability check whose
/// range allows the scale in force. Parses and allocates: not from the real-time thread while
/// it ticks (between ticks, on the thread that ticks, is fine; or use `fts_servo_prepare` on
/// another thread and `fts_servo_swap` here).
///
/// # Safety
/// `h` is a live handle used by this thread alone; `file` points to `len` readable bytes.
#[no_mangle]
pub unsafe extern "C" fn fts_servo_load(h: *mut FtsServo, file: *const u8, len: usize) -> i32 {
    let body = |h: &mut FtsServo| {
        // SAFETY: the caller's promise about `file`.
        let bytes = match unsafe { file_bytes(file, len) } {
            Ok(b) => b,
            Err((code, why)) => {
                h.error.set(format_args!("{why}"));
                return code;
            }
        };
        match h.servo.load(bytes) {
            Ok(()) => FTS_SERVO_OK,
            Err(e) => {
                h.error.set(format_args!("{e}"));
                code_of(&e)
            }
        }
    };
    // SAFETY: the caller's promises about `h`.
    unsafe { with(h, body) }
}

/// The check the loop's controller files pass, as `*out` (free it with
/// `fts_servo_loader_free`): a copy of the rule, independent of the handle, used on any
/// thread — one thread at a time — while the loop ticks. Allocates: call it between ticks.
///
/// # Safety
/// `h` is a live handle used by this thread alone; `out` points to a writable pointer.
#[no_mangle]
pub unsafe extern "C" fn fts_servo_loader_new(
    h: *mut FtsServo,
    out: *mut *mut FtsServoLoader,
) -> i32 {
    if out.is_null() {
        return FTS_SERVO_ERR_NULL;
    }
    let body = |h: &mut FtsServo| {
        let loader = Box::new(FtsServoLoader {
            loader: h.servo.loader(),
        });
        // SAFETY: non-null and writable (checked above; the caller's promise).
        unsafe { *out = Box::into_raw(loader) };
        FTS_SERVO_OK
    };
    // SAFETY: the caller's promises about `h`.
    unsafe { with(h, body) }
}

/// Checks and builds the controller file `file[0..len]` with `loader`'s rule (as
/// `fts_servo_load` does) on the calling thread — any thread — into `*out` (swap it in with
/// `fts_servo_swap`, free it with `fts_servo_prepared_free`). On failure `*out` is NULL, the
/// code is `fts_servo_load`'s and the message is copied into `error[0..error_len]` (which may
/// be NULL).
///
/// # Safety
/// `loader` is a live loader used by this thread alone; `file` points to `len` readable bytes;
/// `out` points to a writable pointer; `error` is NULL or points to `error_len` writable bytes.
#[no_mangle]
pub unsafe extern "C" fn fts_servo_prepare(
    loader: *const FtsServoLoader,
    file: *const u8,
    len: usize,
    out: *mut *mut FtsServoPrepared,
    error: *mut c_char,
    error_len: usize,
) -> i32 {
    let fail = |code: i32, message: &str| {
        // SAFETY: `error` is null or holds `error_len` writable bytes (the caller's promise).
        unsafe { copy_message(error, error_len, message) };
        code
    };
    if out.is_null() {
        return fail(FTS_SERVO_ERR_NULL, "out is a null pointer");
    }
    // SAFETY: non-null and writable (the caller's promise).
    unsafe { *out = std::ptr::null_mut() };
    if loader.is_null() {
        return fail(FTS_SERVO_ERR_NULL, "loader is a null pointer");
    }
    // SAFETY: a live loader (the caller's promise).
    let loader = unsafe { &*loader };
    guard(FTS_SERVO_ERR_INTERNAL, || {
        // SAFETY: the caller's promise about `file`.
        let bytes = match unsafe { file_bytes(file, len) } {
            Ok(b) => b,
            Err((code, why)) => return fail(code, &why),
        };
        match loader.loader.prepare(bytes) {
            Ok(prepared) => {
                let p = Box::new(FtsServoPrepared { prepared });
                // SAFETY: non-null and writable (checked above).
                unsafe { *out = Box::into_raw(p) };
                FTS_SERVO_OK
            }
            Err(e) => fail(code_of(&e), &e.to_string()),
        }
    })
}

/// Hands the loop to the prepared controller at the next tick, bumplessly. On the ticking
/// thread between ticks: no allocation, parse, lock or free — the controller it replaces moves
/// into `p` (free `p` off the ticking thread). `FTS_SERVO_ERR_MARGIN` when the output scale in
/// force lies outside the prepared loop's stable range, `FTS_SERVO_ERR_STATE` when `p` was
/// swapped in already or prepared by another loop's loader (the message on the handle).
///
/// # Safety
/// `h` is a live handle used by this thread alone; `p` is a live prepared controller used by
/// this thread alone now.
#[no_mangle]
pub unsafe extern "C" fn fts_servo_swap(h: *mut FtsServo, p: *mut FtsServoPrepared) -> i32 {
    if p.is_null() {
        return FTS_SERVO_ERR_NULL;
    }
    let body = |h: &mut FtsServo| {
        // SAFETY: non-null, live, this thread's now (the caller's promise).
        let p = unsafe { &mut *p };
        match h.servo.swap(&mut p.prepared) {
            Ok(()) => FTS_SERVO_OK,
            Err(e) => {
                h.error.set(format_args!("{e}"));
                code_of(&e)
            }
        }
    };
    // SAFETY: the caller's promises about `h`.
    unsafe { with(h, body) }
}

/// Frees a prepared controller (and the controller a swap moved into it); NULL is ignored.
///
/// # Safety
/// `p` is null or a live prepared controller, not used again.
#[no_mangle]
pub unsafe extern "C" fn fts_servo_prepared_free(p: *mut FtsServoPrepared) {
    if !p.is_null() {
        // SAFETY: from `Box::into_raw` in `fts_servo_prepare`, not freed before.
        drop(unsafe { Box::from_raw(p) });
    }
}

/// Frees a loader; NULL is ignored.
///
/// # Safety
/// `l` is null or a live loader, not used again.
#[no_mangle]
pub unsafe extern "C" fn fts_servo_loader_free(l: *mut FtsServoLoader) {
    if !l.is_null() {
        // SAFETY: from `Box::into_raw` in `fts_servo_loader_new`, not freed before.
        drop(unsafe { Box::from_raw(l) });
    }
}
