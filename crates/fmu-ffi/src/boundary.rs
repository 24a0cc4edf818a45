//! What every FMI entry point shares: panics caught at the boundary, the instance pointer
//! checked, C strings read, the resource folder found.

use crate::instance::{log_with, Instance, Logger, Status};
use crate::model::Value;
use fmu::VarType;
use std::ffi::{c_char, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;

/// Runs `f`, `on_panic` if it panics (a bug; nothing unwinds into the importer).
pub fn guarded<T>(on_panic: T, f: impl FnOnce() -> T) -> T {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or(on_panic)
}

/// Frees the instance `c` (NULL is ignored).
///
/// # Safety
/// `c` is NULL or an instance made by an instantiate function, not used again.
pub unsafe fn free(c: *mut c_void) {
    if !c.is_null() {
        // SAFETY: an instance from Box::into_raw at instantiation, given back once.
        drop(unsafe { Box::from_raw(c.cast::<Instance>()) });
    }
}

/// The instance `instance`, or NULL with `logger` told why it was not made.
pub fn instance_or_refusal(
    name: &str,
    instance: Result<Instance, (Logger, String)>,
) -> *mut c_void {
    match instance {
        Ok(i) => Box::into_raw(Box::new(i)).cast(),
        Err((logger, message)) => {
            let name = CString::new(name.replace('\0', "")).unwrap_or_default();
            log_with(&logger, &name, Status::Error, "logStatusError", &message);
            std::ptr::null_mut()
        }
    }
}

/// Runs `f` on the instance `c`: [`Status::Fatal`] for NULL or a panic.
///
/// # Safety
/// `c` is NULL or a live instance used by this thread alone.
pub unsafe fn with(c: *mut c_void, f: impl FnOnce(&mut Instance) -> Status) -> i32 {
    if c.is_null() {
        return Status::Fatal as i32;
    }
    // SAFETY: non-null, live, this thread's (the caller's promise).
    let i = unsafe { &mut *c.cast::<Instance>() };
    guarded(Status::Fatal, || f(i)) as i32
}

/// The string at `s` (lossy UTF-8, at most 64 KiB), or `default` for NULL.
///
/// # Safety
/// `s` is NULL or NUL-terminated.
pub unsafe fn text_or(s: *const c_char, default: &str) -> String {
    if s.is_null() {
        return default.to_owned();
    }
    // SAFETY: NUL-terminated (the caller's promise).
    let bytes = unsafe { CStr::from_ptr(s) }.to_bytes();
    String::from_utf8_lossy(&bytes[..bytes.len().min(1 << 16)]).into_owned()
}

/// The folder an FMI 2 resource URI names (`file:///a/b/resources`, `file:/a/b`, with
/// percent escapes).
pub fn resources_from_uri(uri: &str) -> Result<PathBuf, String> {
    let rest = uri
        .strip_prefix("file://localhost")
        .or_else(|| uri.strip_prefix("file://"))
        .or_else(|| uri.strip_prefix("file:"))
        .ok_or_else(|| {
            format!("fmuResourceLocation {uri:?}: a file: URI of the unit's resources folder")
        })?;
    let bytes = rest.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut k = 0;
    while k < bytes.len() {
        if bytes[k] == b'%' && k + 2 < bytes.len() {
            let hex = std::str::from_utf8(&bytes[k + 1..k + 3]).unwrap_or("");
            if let Ok(b) = u8::from_str_radix(hex, 16) {
                out.push(b);
                k += 3;
                continue;
            }
        }
        out.push(bytes[k]);
        k += 1;
    }
    let path = String::from_utf8(out).map_err(|e| format!("fmuResourceLocation {uri:?}: {e}"))?;
    Ok(PathBuf::from(path))
}

/// Gets `n` values of type `ty` at `vr` into `out` through `put`; `n_out` is FMI 3's count of
/// values (None: FMI 2, where it is `n`).
///
/// # Safety
/// `c` is NULL or a live instance; `vr` holds `n` references, `out` room for `n` values.
pub unsafe fn get_values<T>(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    out: *mut T,
    n_out: Option<usize>,
    ty: VarType,
    put: impl Fn(&mut Instance, Value) -> T,
) -> i32 {
    let body = |i: &mut Instance| {
        if let Err(e) = counts(n, n_out, vr.is_null() || out.is_null()) {
            return i.error(&e);
        }
        for k in 0..n {
            // SAFETY: `vr` holds `n` references and `out` room for `n` values.
            let r = unsafe { *vr.add(k) };
            match i.get(r, ty) {
                Ok(v) => {
                    let x = put(i, v);
                    // SAFETY: as above.
                    unsafe { out.add(k).write(x) };
                }
                Err(s) => return s,
            }
        }
        Status::Ok
    };
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, body) }
}

/// Sets `n` values of type `ty` at `vr` from `values` through `take`; `n_values` is FMI 3's
/// count of values (None: FMI 2, where it is `n`).
///
/// # Safety
/// `c` is NULL or a live instance; `vr` and `values` hold `n` entries.
pub unsafe fn set_values<T: Copy>(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    values: *const T,
    n_values: Option<usize>,
    ty: VarType,
    take: impl Fn(T) -> Value,
) -> i32 {
    let body = |i: &mut Instance| {
        if let Err(e) = counts(n, n_values, vr.is_null() || values.is_null()) {
            return i.error(&e);
        }
        for k in 0..n {
            // SAFETY: `vr` and `values` hold `n` entries.
            let (r, x) = unsafe { (*vr.add(k), *values.add(k)) };
            let s = i.set(r, ty, take(x));
            if s != Status::Ok {
                return s;
            }
        }
        Status::Ok
    };
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, body) }
}

/// The arrays of a get or set agree: as many values as references, none NULL when used.
fn counts(n: usize, n_values: Option<usize>, null: bool) -> Result<(), String> {
    match n_values {
        Some(m) if m != n => Err(format!(
            "{n} value references and {m} values: this unit has scalars only"
        )),
        _ if n > 0 && null => Err("a null value-reference or value array".into()),
        _ => Ok(()),
    }
}

/// FMI functions a unit does not provide (its description says so): each takes the instance
/// first and answers an error naming the function. The arguments after the instance are not
/// read; the C calling convention of the target (the caller cleans up) makes the shorter
/// signature harmless on x86-64 Linux, the one platform the units ship for.
macro_rules! not_provided {
    ($($name:ident),* $(,)?) => {$(
        #[doc = concat!("`", stringify!($name), "`: not provided by this unit (an error).")]
        ///
        /// # Safety
        /// `c` is NULL or a live instance.
        #[no_mangle]
        pub unsafe extern "C" fn $name(c: *mut std::ffi::c_void) -> i32 {
            // SAFETY: the caller's promise about `c`.
            unsafe {
                $crate::boundary::with(c, |i| i.error(concat!(stringify!($name), " is not provided by this unit (see its modelDescription.xml)")))
            }
        }
    )*};
}
pub(crate) use not_provided;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resource_uris_name_their_folders() {
        let p = |u: &str| resources_from_uri(u).unwrap();
        assert_eq!(
            p("file:///srv/units/a%20b/resources"),
            PathBuf::from("/srv/units/a b/resources")
        );
        assert_eq!(
            p("file:/srv/x/resources/"),
            PathBuf::from("/srv/x/resources/")
        );
        assert_eq!(p("file://localhost/srv/x"), PathBuf::from("/srv/x"));
        assert!(resources_from_uri("http://example.com/x").is_err());
    }
}
