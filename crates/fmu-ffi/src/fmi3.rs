//! The FMI 3.0 co-simulation functions.

use crate::boundary::{
    free, get_values, guarded, instance_or_refusal, not_provided, set_values, text_or, with,
};
use crate::instance::{log_with, Fmi3Logger, Instance, Logger, Status};
use crate::model::Value;
use fmu::VarType;
use std::ffi::{c_char, c_void, CString};
use std::path::PathBuf;

/// `fmi3GetVersion`.
#[no_mangle]
pub extern "C" fn fmi3GetVersion() -> *const c_char {
    c"3.0".as_ptr()
}

/// `fmi3InstantiateCoSimulation`: the resources checked against `token`; event mode, early
/// return and intermediate updates are not offered (the description says so).
///
/// # Safety
/// The strings are NULL or NUL-terminated; `log` is NULL or an FMI 3 log callback.
#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
    instance_name: *const c_char,
    token: *const c_char,
    resource_path: *const c_char,
    _visible: bool,
    logging_on: bool,
    _event_mode_used: bool,
    _early_return_allowed: bool,
    _required_intermediate: *const u32,
    _n_required_intermediate: usize,
    environment: *mut c_void,
    log: Option<Fmi3Logger>,
    _intermediate_update: *const c_void,
) -> *mut c_void {
    guarded(std::ptr::null_mut(), || {
        let logger = Logger::V3 {
            callback: log,
            environment,
        };
        // SAFETY: NULL or NUL-terminated (the caller's promise).
        let (name, token, path) = unsafe {
            (
                text_or(instance_name, "fts"),
                text_or(token, ""),
                text_or(resource_path, ""),
            )
        };
        let made = if path.is_empty() {
            let message = "resourcePath is empty: the unit's resources folder is needed";
            Err((logger, message.to_owned()))
        } else {
            Instance::new(&name, &token, &PathBuf::from(path), logger, logging_on)
        };
        instance_or_refusal(&name, made)
    })
}

/// `fmi3InstantiateModelExchange`: not offered (NULL, logged).
///
/// # Safety
/// `log` is NULL or an FMI 3 log callback.
#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateModelExchange(
    _instance_name: *const c_char,
    _token: *const c_char,
    _resource_path: *const c_char,
    _visible: bool,
    _logging_on: bool,
    environment: *mut c_void,
    log: Option<Fmi3Logger>,
) -> *mut c_void {
    let logger = Logger::V3 {
        callback: log,
        environment,
    };
    log_with(
        &logger,
        &CString::default(),
        Status::Error,
        "logStatusError",
        "this unit is for co-simulation: it has no model-exchange interface",
    );
    std::ptr::null_mut()
}

/// `fmi3InstantiateScheduledExecution`: not offered (NULL).
#[no_mangle]
pub extern "C" fn fmi3InstantiateScheduledExecution() -> *mut c_void {
    std::ptr::null_mut()
}

/// `fmi3FreeInstance`.
///
/// # Safety
/// `c` is NULL or an instance of `fmi3InstantiateCoSimulation`, not used again.
#[no_mangle]
pub unsafe extern "C" fn fmi3FreeInstance(c: *mut c_void) {
    // SAFETY: the caller's promise about `c`.
    unsafe { free(c) }
}

/// `fmi3SetDebugLogging`: categories are not told apart (errors are always logged).
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi3SetDebugLogging(
    c: *mut c_void,
    logging_on: bool,
    _n: usize,
    _categories: *const *const c_char,
) -> i32 {
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, |i| i.set_logging(logging_on)) }
}

/// `fmi3EnterInitializationMode` at `start_time` (a tolerance and stop time are not used).
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi3EnterInitializationMode(
    c: *mut c_void,
    _tolerance_defined: bool,
    _tolerance: f64,
    start_time: f64,
    _stop_time_defined: bool,
    _stop_time: f64,
) -> i32 {
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, |i| i.enter_initialization(start_time)) }
}

/// `fmi3ExitInitializationMode`: builds the unit from its parameters.
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi3ExitInitializationMode(c: *mut c_void) -> i32 {
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, Instance::exit_initialization) }
}

/// `fmi3EnterStepMode`: step mode is where initialisation ends (no event mode).
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi3EnterStepMode(c: *mut c_void) -> i32 {
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, |_| Status::Ok) }
}

/// `fmi3Terminate`.
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi3Terminate(c: *mut c_void) -> i32 {
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, Instance::terminate) }
}

/// `fmi3Reset`.
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi3Reset(c: *mut c_void) -> i32 {
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, Instance::reset) }
}

/// `fmi3GetFloat64` (value reference 0 is the time).
///
/// # Safety
/// `c` is NULL or a live instance; `vr` holds `n` references, `values` room for `nv`.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetFloat64(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    values: *mut f64,
    nv: usize,
) -> i32 {
    // SAFETY: the caller's promises.
    unsafe {
        get_values(c, vr, n, values, Some(nv), VarType::Real, |_, v| match v {
            Value::Real(x) => x,
            _ => f64::NAN,
        })
    }
}

/// `fmi3GetInt32`.
///
/// # Safety
/// `c` is NULL or a live instance; `vr` holds `n` references, `values` room for `nv`.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetInt32(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    values: *mut i32,
    nv: usize,
) -> i32 {
    // SAFETY: the caller's promises.
    unsafe {
        get_values(
            c,
            vr,
            n,
            values,
            Some(nv),
            VarType::Integer,
            |_, v| match v {
                Value::Integer(x) => x,
                _ => 0,
            },
        )
    }
}

/// `fmi3GetBoolean`.
///
/// # Safety
/// `c` is NULL or a live instance; `vr` holds `n` references, `values` room for `nv`.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetBoolean(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    values: *mut bool,
    nv: usize,
) -> i32 {
    // SAFETY: the caller's promises.
    unsafe {
        get_values(c, vr, n, values, Some(nv), VarType::Boolean, |_, v| {
            matches!(v, Value::Boolean(true))
        })
    }
}

/// `fmi3GetString`: the strings stay valid until the next call on `c`.
///
/// # Safety
/// `c` is NULL or a live instance; `vr` holds `n` references, `values` room for `nv`.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetString(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    values: *mut *const c_char,
    nv: usize,
) -> i32 {
    let clear = |i: &mut Instance| {
        i.clear_strings();
        Status::Ok
    };
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, clear) };
    // SAFETY: the caller's promises.
    unsafe {
        get_values(
            c,
            vr,
            n,
            values,
            Some(nv),
            VarType::String,
            |i, v| match v {
                Value::String(s) => i.keep_string(s),
                _ => std::ptr::null(),
            },
        )
    }
}

/// `fmi3SetFloat64`.
///
/// # Safety
/// `c` is NULL or a live instance; `vr` holds `n` references, `values` `nv` values.
#[no_mangle]
pub unsafe extern "C" fn fmi3SetFloat64(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    values: *const f64,
    nv: usize,
) -> i32 {
    // SAFETY: the caller's promises.
    unsafe { set_values(c, vr, n, values, Some(nv), VarType::Real, Value::Real) }
}

/// `fmi3SetInt32`.
///
/// # Safety
/// `c` is NULL or a live instance; `vr` holds `n` references, `values` `nv` values.
#[no_mangle]
pub unsafe extern "C" fn fmi3SetInt32(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    values: *const i32,
    nv: usize,
) -> i32 {
    // SAFETY: the caller's promises.
    unsafe { set_values(c, vr, n, values, Some(nv), VarType::Integer, Value::Integer) }
}

/// `fmi3SetBoolean`.
///
/// # Safety
/// `c` is NULL or a live instance; `vr` holds `n` references, `values` `nv` values.
#[no_mangle]
pub unsafe extern "C" fn fmi3SetBoolean(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    values: *const u8,
    nv: usize,
) -> i32 {
    // Read as bytes: any nonzero byte is true (a `bool` other than 0 or 1 would be undefined).
    // SAFETY: the caller's promises.
    unsafe {
        set_values(c, vr, n, values, Some(nv), VarType::Boolean, |b| {
            Value::Boolean(b != 0)
        })
    }
}

/// `fmi3SetString`.
///
/// # Safety
/// `c` is NULL or a live instance; `vr` holds `n` references, `values` `nv` strings, each
/// NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn fmi3SetString(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    values: *const *const c_char,
    nv: usize,
) -> i32 {
    // SAFETY: the caller's promises; each string is NULL or NUL-terminated.
    unsafe {
        set_values(c, vr, n, values, Some(nv), VarType::String, |s| {
            Value::String(text_or(s, ""))
        })
    }
}

/// `fmi3DoStep`: a whole number of ticks from `t`; never an event or an early return.
///
/// # Safety
/// `c` is NULL or a live instance; the out-pointers are NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi3DoStep(
    c: *mut c_void,
    t: f64,
    h: f64,
    _no_set_prior: bool,
    event_handling_needed: *mut bool,
    terminate_simulation: *mut bool,
    early_return: *mut bool,
    last_successful_time: *mut f64,
) -> i32 {
    let body = |i: &mut Instance| {
        let s = i.do_step(t, h);
        // SAFETY: each NULL or writable (the caller's promise).
        unsafe {
            for flag in [event_handling_needed, terminate_simulation, early_return] {
                if !flag.is_null() {
                    *flag = false;
                }
            }
            if !last_successful_time.is_null() {
                *last_successful_time = i.time_s();
            }
        }
        s
    };
    // SAFETY: the caller's promise about `c`.
    unsafe { with(c, body) }
}

not_provided!(
    fmi3EnterEventMode,
    fmi3GetFloat32,
    fmi3GetInt8,
    fmi3GetUInt8,
    fmi3GetInt16,
    fmi3GetUInt16,
    fmi3GetUInt32,
    fmi3GetInt64,
    fmi3GetUInt64,
    fmi3GetBinary,
    fmi3GetClock,
    fmi3SetFloat32,
    fmi3SetInt8,
    fmi3SetUInt8,
    fmi3SetInt16,
    fmi3SetUInt16,
    fmi3SetUInt32,
    fmi3SetInt64,
    fmi3SetUInt64,
    fmi3SetBinary,
    fmi3SetClock,
    fmi3GetNumberOfVariableDependencies,
    fmi3GetVariableDependencies,
    fmi3GetFMUState,
    fmi3SetFMUState,
    fmi3FreeFMUState,
    fmi3SerializedFMUStateSize,
    fmi3SerializeFMUState,
    fmi3DeserializeFMUState,
    fmi3GetDirectionalDerivative,
    fmi3GetAdjointDerivative,
    fmi3EnterConfigurationMode,
    fmi3ExitConfigurationMode,
    fmi3GetIntervalDecimal,
    fmi3GetIntervalFraction,
    fmi3GetShiftDecimal,
    fmi3GetShiftFraction,
    fmi3SetIntervalDecimal,
    fmi3SetIntervalFraction,
    fmi3SetShiftDecimal,
    fmi3SetShiftFraction,
    fmi3EvaluateDiscreteStates,
    fmi3UpdateDiscreteStates,
    fmi3EnterContinuousTimeMode,
    fmi3CompletedIntegratorStep,
    fmi3SetTime,
    fmi3SetContinuousStates,
    fmi3GetContinuousStateDerivatives,
    fmi3GetEventIndicators,
    fmi3GetContinuousStates,
    fmi3GetNominalsOfContinuousStates,
    fmi3GetNumberOfEventIndicators,
    fmi3GetNumberOfContinuousStates,
    fmi3GetOutputDerivatives,
    fmi3ActivateModelPartition,
);
