//! The FMI 2.0 co-simulation functions.

use crate::boundary::{
    free, get_values, guarded, instance_or_refusal, not_provided, resources_from_uri, set_values,
    text_or, with,
};
use crate::instance::{Fmi2Logger, Instance, Logger, Status};
use crate::model::Value;
use fmu::VarType;
use std::ffi::{c_char, c_void};

/// `fmi2CallbackFunctions`.
#[repr(C)]
pub struct CallbackFunctions {
    logger: Option<Fmi2Logger>,
    allocate_memory: Option<unsafe extern "C" fn(usize, usize) -> *mut c_void>,
    free_memory: Option<unsafe extern "C" fn(*mut c_void)>,
    step_finished: Option<unsafe extern "C" fn(*mut c_void, i32)>,
    component_environment: *mut c_void,
}

/// `fmi2GetTypesPlatform`.
#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

/// `fmi2GetVersion`.
#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

/// `fmi2Instantiate`: co-simulation only; the resources checked against `guid`.
///
/// # Safety
/// The strings are NULL or NUL-terminated; `functions` is NULL or an FMI 2 callback table.
#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instance_name: *const c_char,
    fmu_type: i32,
    guid: *const c_char,
    resource_location: *const c_char,
    functions: *const CallbackFunctions,
    _visible: i32,
    logging_on: i32,
) -> *mut c_void {
    guarded(std::ptr::null_mut(), || {
        // SAFETY: NULL or a callback table (the caller's promise), read before we return.
        let (callback, environment) = match unsafe { functions.as_ref() } {
            Some(f) => (f.logger, f.component_environment),
            None => (None, std::ptr::null_mut()),
        };
        let logger = Logger::V2 {
            callback,
            environment,
        };
        // SAFETY: NULL or NUL-terminated (the caller's promise).
        let name = unsafe { text_or(instance_name, "fts") };
        // SAFETY: NULL or NUL-terminated (the caller's promise).
        let (guid, uri) = unsafe { (text_or(guid, ""), text_or(resource_location, "")) };
        let made = if fmu_type != 1 {
            Err((
                logger,
                "this unit is for co-simulation (fmi2CoSimulation): it has no model-exchange interface".to_owned(),
            ))
        } else {
            match resources_from_uri(&uri) {
                Ok(resources) => Instance::new(&name, &guid, &resources, logger, logging_on != 0),
                Err(e) => Err((logger, e)),
            }
        };
        instance_or_refusal(&name, made)
    })
}

/// `fmi2FreeInstance`.
///
/// # Safety
/// `c` is NULL or an instance of `fmi2Instantiate`, not used again.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: *mut c_void) {
    // SAFETY: the caller's promise about `c`.
    unsafe { free(c) }
}

/// `fmi2SetDebugLogging`: categories are not told apart (errors are always logged).
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: *mut c_void,
    logging_on: i32,
    _n: usize,
    _categories: *const *const c_char,
) -> i32 {
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, |i| i.set_logging(logging_on != 0)) }
}

/// `fmi2SetupExperiment`: the start time (a tolerance and stop time are not used).
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetupExperiment(
    c: *mut c_void,
    _tolerance_defined: i32,
    _tolerance: f64,
    start_time: f64,
    _stop_time_defined: i32,
    _stop_time: f64,
) -> i32 {
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, |i| i.set_start(start_time)) }
}

/// `fmi2EnterInitializationMode`.
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: *mut c_void) -> i32 {
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, |i| i.enter_initialization(i.start_s())) }
}

/// `fmi2ExitInitializationMode`: builds the unit from its parameters.
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: *mut c_void) -> i32 {
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, Instance::exit_initialization) }
}

/// `fmi2Terminate`.
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2Terminate(c: *mut c_void) -> i32 {
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, Instance::terminate) }
}

/// `fmi2Reset`.
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2Reset(c: *mut c_void) -> i32 {
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, Instance::reset) }
}

fn real(v: Value) -> f64 {
    match v {
        Value::Real(x) => x,
        _ => f64::NAN,
    }
}

fn integer(v: Value) -> i32 {
    match v {
        Value::Integer(n) => n,
        _ => 0,
    }
}

fn boolean(v: Value) -> i32 {
    matches!(v, Value::Boolean(true)).into()
}

/// `fmi2GetReal`.
///
/// # Safety
/// `c` is NULL or a live instance; `vr` holds `n` references, `value` room for `n`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetReal(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    value: *mut f64,
) -> i32 {
    // SAFETY: the caller's promises.
    unsafe { get_values(c, vr, n, value, None, VarType::Real, |_, v| real(v)) }
}

/// `fmi2GetInteger`.
///
/// # Safety
/// `c` is NULL or a live instance; `vr` holds `n` references, `value` room for `n`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetInteger(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    value: *mut i32,
) -> i32 {
    // SAFETY: the caller's promises.
    unsafe { get_values(c, vr, n, value, None, VarType::Integer, |_, v| integer(v)) }
}

/// `fmi2GetBoolean`.
///
/// # Safety
/// `c` is NULL or a live instance; `vr` holds `n` references, `value` room for `n`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBoolean(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    value: *mut i32,
) -> i32 {
    // SAFETY: the caller's promises.
    unsafe { get_values(c, vr, n, value, None, VarType::Boolean, |_, v| boolean(v)) }
}

/// `fmi2GetString`: the strings stay valid until the next call on `c`.
///
/// # Safety
/// `c` is NULL or a live instance; `vr` holds `n` references, `value` room for `n`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetString(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    value: *mut *const c_char,
) -> i32 {
    let clear = |i: &mut Instance| {
        i.clear_strings();
        Status::Ok
    };
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, clear) };
    // SAFETY: the caller's promises.
    unsafe {
        get_values(c, vr, n, value, None, VarType::String, |i, v| match v {
            Value::String(s) => i.keep_string(s),
            _ => std::ptr::null(),
        })
    }
}

/// `fmi2SetReal`.
///
/// # Safety
/// `c` is NULL or a live instance; `vr` and `value` hold `n` entries.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetReal(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    value: *const f64,
) -> i32 {
    // SAFETY: the caller's promises.
    unsafe { set_values(c, vr, n, value, None, VarType::Real, Value::Real) }
}

/// `fmi2SetInteger`.
///
/// # Safety
/// `c` is NULL or a live instance; `vr` and `value` hold `n` entries.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetInteger(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    value: *const i32,
) -> i32 {
    // SAFETY: the caller's promises.
    unsafe { set_values(c, vr, n, value, None, VarType::Integer, Value::Integer) }
}

/// `fmi2SetBoolean`.
///
/// # Safety
/// `c` is NULL or a live instance; `vr` and `value` hold `n` entries.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetBoolean(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    value: *const i32,
) -> i32 {
    // SAFETY: the caller's promises.
    unsafe {
        set_values(c, vr, n, value, None, VarType::Boolean, |b| {
            Value::Boolean(b != 0)
        })
    }
}

/// `fmi2SetString`.
///
/// # Safety
/// `c` is NULL or a live instance; `vr` and `value` hold `n` entries, each NULL or
/// NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetString(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    value: *const *const c_char,
) -> i32 {
    // SAFETY: the caller's promises; each string is NULL or NUL-terminated.
    unsafe {
        set_values(c, vr, n, value, None, VarType::String, |s| {
            Value::String(text_or(s, ""))
        })
    }
}

/// `fmi2DoStep`: a whole number of ticks from `t`.
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2DoStep(c: *mut c_void, t: f64, h: f64, _no_set_prior: i32) -> i32 {
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, |i| i.do_step(t, h)) }
}

/// `fmi2CancelStep`: steps are synchronous; nothing to cancel.
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2CancelStep(c: *mut c_void) -> i32 {
    // SAFETY: the caller's promise about `c`.
    unsafe {
        with(c, |i| {
            i.error("steps are synchronous: there is no step to cancel")
        })
    }
}

/// `fmi2GetRealStatus`: `fmi2LastSuccessfulTime` (2) is the unit's time.
///
/// # Safety
/// `c` is NULL or a live instance; `value` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealStatus(c: *mut c_void, kind: i32, value: *mut f64) -> i32 {
    let body = |i: &mut Instance| {
        if kind != 2 || value.is_null() {
            return i.error("only fmi2LastSuccessfulTime is a real status of this unit");
        }
        // SAFETY: non-null and writable (the caller's promise).
        unsafe { *value = i.time_s() };
        Status::Ok
    };
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, body) }
}

not_provided!(
    fmi2GetFMUstate,
    fmi2SetFMUstate,
    fmi2FreeFMUstate,
    fmi2SerializedFMUstateSize,
    fmi2SerializeFMUstate,
    fmi2DeSerializeFMUstate,
    fmi2GetDirectionalDerivative,
    fmi2SetRealInputDerivatives,
    fmi2GetRealOutputDerivatives,
    fmi2GetStatus,
    fmi2GetIntegerStatus,
    fmi2GetBooleanStatus,
    fmi2GetStringStatus,
    fmi2EnterEventMode,
    fmi2NewDiscreteStates,
    fmi2EnterContinuousTimeMode,
    fmi2CompletedIntegratorStep,
    fmi2SetTime,
    fmi2SetContinuousStates,
    fmi2GetDerivatives,
    fmi2GetEventIndicators,
    fmi2GetContinuousStates,
    fmi2GetNominalsOfContinuousStates,
);
