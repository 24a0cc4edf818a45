//! One instantiated unit as both FMI versions drive it: its mode, time in ticks, the checks
//! every call passes (type, causality, mode, range, step) and the messages it logs.

use crate::controller::ControllerUnit;
use crate::model::{Model, Value};
use crate::stage::StageUnit;
use fmu::unit::read_resources;
use fmu::{Causality, Kind, VarType, DEPLOYMENT_FILE};
use servo_config::Origin;
use std::ffi::{c_char, c_void, CString};
use std::path::Path;

/// FMI's status codes (the same numbers in 2.0 and 3.0).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(i32)]
pub enum Status {
    /// Done.
    Ok = 0,
    /// Done, with a message.
    Warning = 1,
    /// Not done; the call may be repeated otherwise.
    Discard = 2,
    /// Not done: the call was wrong (the message says why); the instance lives on.
    Error = 3,
    /// The instance is unusable.
    Fatal = 4,
}

/// How the importer takes messages.
pub enum Logger {
    /// FMI 2's variadic logger (called with the message as its format, `%` doubled).
    V2 {
        /// The callback.
        callback: Option<Fmi2Logger>,
        /// Its component environment.
        environment: *mut c_void,
    },
    /// FMI 3's log-message callback.
    V3 {
        /// The callback.
        callback: Option<Fmi3Logger>,
        /// Its instance environment.
        environment: *mut c_void,
    },
}

/// `fmi2CallbackLogger`.
pub type Fmi2Logger =
    unsafe extern "C" fn(*mut c_void, *const c_char, i32, *const c_char, *const c_char, ...);
/// `fmi3LogMessageCallback`.
pub type Fmi3Logger = unsafe extern "C" fn(*mut c_void, i32, *const c_char, *const c_char);

/// The life of an instance (FMI's states, as far as co-simulation has them).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Instantiated,
    Initialization,
    Step,
    Terminated,
}

/// One unit instance.
pub struct Instance {
    name: CString,
    model: Box<dyn Model>,
    logger: Logger,
    logging_on: bool,
    mode: Mode,
    ticks: u64,
    start_s: f64,
    /// The strings handed out by the last string get (valid until the next call).
    strings: Vec<CString>,
}

/// A communication step may differ from a whole number of ticks by this fraction of a tick
/// (a master's floating-point step); otherwise it is refused, never interpolated.
pub const TICK_TOLERANCE: f64 = 1e-6;

/// The most ticks one communication step may take (5 s of run at 199.6 kHz): a step is
/// computed before the call returns, so its length is bounded.
pub const MAX_STEP_TICKS: f64 = 1e6;

impl Instance {
    /// The unit whose resources are in the folder `resources`, checked against the
    /// description's instantiation token `token`.
    pub fn new(
        name: &str,
        token: &str,
        resources: &Path,
        logger: Logger,
        logging_on: bool,
    ) -> Result<Self, (Logger, String)> {
        let model: Result<Box<dyn Model>, String> =
            read_resources(resources, token).and_then(|r| match r.unit.kind()? {
                Kind::Stage => Ok(Box::new(StageUnit::new(
                    r.unit.plant.unwrap_or_default(),
                    r.unit.seed,
                )) as Box<dyn Model>),
                Kind::Controller => {
                    let text = r
                        .deployment
                        .ok_or_else(|| format!("resources/{DEPLOYMENT_FILE}: missing"))?;
                    let origin = Origin {
                        path: Some(resources.join(DEPLOYMENT_FILE)),
                        text: Some(text.clone()),
                    };
                    Ok(Box::new(ControllerUnit::new(&text, &origin)?) as Box<dyn Model>)
                }
            });
        match model {
            Ok(model) => Ok(Instance {
                name: CString::new(name.replace('\0', "")).unwrap_or_default(),
                model,
                logger,
                logging_on,
                mode: Mode::Instantiated,
                ticks: 0,
                start_s: 0.0,
                strings: Vec::new(),
            }),
            Err(e) => Err((logger, e)),
        }
    }

    /// Logs `message` with `status` under `category` (errors always, the rest when logging is
    /// on).
    pub fn log(&self, status: Status, category: &str, message: &str) {
        if status == Status::Ok && !self.logging_on {
            return;
        }
        log_with(&self.logger, &self.name, status, category, message);
    }

    /// Logs `message` as an error and returns [`Status::Error`].
    pub fn error(&self, message: &str) -> Status {
        self.log(Status::Error, "logStatusError", message);
        Status::Error
    }

    /// Turns logging of the non-error categories on or off.
    pub fn set_logging(&mut self, on: bool) -> Status {
        self.logging_on = on;
        Status::Ok
    }

    fn variable(&self, vr: u32, ty: VarType) -> Result<&fmu::Variable, String> {
        let v = self
            .model
            .variables()
            .iter()
            .find(|v| v.vr == vr)
            .ok_or_else(|| format!("value reference {vr} is not a variable of this unit"))?;
        if v.ty != ty {
            return Err(format!(
                "{} (value reference {vr}) is a {:?}, not a {ty:?}",
                v.name, v.ty
            ));
        }
        Ok(v)
    }

    /// Sets `vr` to `value` of type `ty`.
    pub fn set(&mut self, vr: u32, ty: VarType, value: Value) -> Status {
        let checked = self.variable(vr, ty).and_then(|v| {
            let before_start = matches!(self.mode, Mode::Instantiated | Mode::Initialization);
            match v.causality {
                Causality::Parameter if !before_start => Err(format!(
                    "{} is a parameter: set it before initialisation ends",
                    v.name
                )),
                Causality::Output | Causality::CalculatedParameter => Err(format!(
                    "{} is computed by the unit: it cannot be set",
                    v.name
                )),
                _ if self.mode == Mode::Terminated => {
                    Err(format!("{}: the unit is terminated", v.name))
                }
                _ => Ok(()),
            }?;
            let x = match value {
                Value::Real(x) => x,
                Value::Integer(n) => n.into(),
                _ => return Ok(()),
            };
            // A variable with a range takes finite values within it; one without (the DAC
            // command, the controller's readings) takes any value, as the hardware's would
            // (the stage's DAC clips and flags a non-finite command; a non-finite reading trips
            // the controller).
            let bounded = v.min.is_some() || v.max.is_some() || v.causality == Causality::Parameter;
            let out_of_range =
                !x.is_finite() || v.min.is_some_and(|lo| x < lo) || v.max.is_some_and(|hi| x > hi);
            if out_of_range && bounded {
                return Err(format!(
                    "{} = {x} is outside its allowed range {}",
                    v.name,
                    v.range.as_deref().unwrap_or("(finite)")
                ));
            }
            Ok(())
        });
        match checked.and_then(|()| self.model.set(vr, value)) {
            Ok(()) => Status::Ok,
            Err(e) => self.error(&e),
        }
    }

    /// The value at `vr` of type `ty` (FMI 3's value reference 0 is the time).
    pub fn get(&mut self, vr: u32, ty: VarType) -> Result<Value, Status> {
        if vr == 0 && ty == VarType::Real && matches!(self.logger, Logger::V3 { .. }) {
            return Ok(Value::Real(self.time_s()));
        }
        let checked = self.variable(vr, ty).map(|_| ());
        match checked.and_then(|()| self.model.get(vr)) {
            Ok(v) => Ok(v),
            Err(e) => Err(self.error(&e)),
        }
    }

    /// Keeps `s` until the next string get and returns a pointer to it.
    pub fn keep_string(&mut self, s: String) -> *const c_char {
        let c = CString::new(s.replace('\0', "")).unwrap_or_default();
        self.strings.push(c);
        self.strings.last().map_or(std::ptr::null(), |c| c.as_ptr())
    }

    /// Forgets the strings handed out before (at the start of a string get).
    pub fn clear_strings(&mut self) {
        self.strings.clear();
    }

    /// Sets the start time in s (after instantiation, before initialisation).
    pub fn set_start(&mut self, start_s: f64) -> Status {
        if self.mode != Mode::Instantiated {
            return self
                .error("the experiment is set up after instantiation, before initialisation");
        }
        if !start_s.is_finite() {
            return self.error(&format!("start time {start_s}: not a finite number"));
        }
        self.start_s = start_s;
        Status::Ok
    }

    /// The start time in s.
    pub fn start_s(&self) -> f64 {
        self.start_s
    }

    /// Enters initialisation at `start_s`.
    pub fn enter_initialization(&mut self, start_s: f64) -> Status {
        if self.mode != Mode::Instantiated {
            return self.error("initialisation is entered once, after instantiation");
        }
        if !start_s.is_finite() {
            return self.error(&format!("start time {start_s}: not a finite number"));
        }
        self.start_s = start_s;
        self.mode = Mode::Initialization;
        Status::Ok
    }

    /// Builds the unit and enters step mode.
    pub fn exit_initialization(&mut self) -> Status {
        if self.mode != Mode::Initialization {
            return self.error("initialisation is exited once, after entering it");
        }
        match self.model.initialize() {
            Ok(()) => {
                self.mode = Mode::Step;
                Status::Ok
            }
            Err(e) => self.error(&e),
        }
    }

    /// One communication step from `t_s` of `h_s`: a whole number of ticks.
    pub fn do_step(&mut self, t_s: f64, h_s: f64) -> Status {
        if self.mode != Mode::Step {
            return self.error("a step needs an initialised unit (exit initialisation first)");
        }
        let period = self.model.period_s();
        let n = h_s / period;
        let ticks = n.round();
        if ticks > MAX_STEP_TICKS {
            return self.error(&format!(
                "communication step {h_s:e} s is {ticks:e} ticks: at most {MAX_STEP_TICKS:e} ticks a step"
            ));
        }
        if !(ticks >= 1.0 && (n - ticks).abs() <= TICK_TOLERANCE) {
            return self.error(&format!(
                "communication step {h_s:e} s is not a whole number of ticks of {period:e} s (within {TICK_TOLERANCE:e} of a tick): this unit steps whole servo ticks and does not interpolate"
            ));
        }
        let now = self.start_s + self.ticks as f64 * period;
        if (t_s - now).abs() > 0.5 * period {
            return self.error(&format!(
                "communication point {t_s:e} s is not this unit's time {now:e} s (tick {})",
                self.ticks
            ));
        }
        match self.model.step(ticks as u64) {
            Ok(()) => {
                self.ticks += ticks as u64;
                Status::Ok
            }
            Err(e) => self.error(&e),
        }
    }

    /// Ends the simulation.
    pub fn terminate(&mut self) -> Status {
        self.mode = Mode::Terminated;
        Status::Ok
    }

    /// Back to the instantiated state.
    pub fn reset(&mut self) -> Status {
        self.model.reset();
        self.mode = Mode::Instantiated;
        self.ticks = 0;
        self.start_s = 0.0;
        Status::Ok
    }

    /// The unit's time in s.
    pub fn time_s(&self) -> f64 {
        self.start_s + self.ticks as f64 * self.model.period_s()
    }
}

/// Logs through `logger` for the instance `name`.
pub fn log_with(logger: &Logger, name: &CString, status: Status, category: &str, message: &str) {
    let category = CString::new(category).unwrap_or_default();
    let message = CString::new(message.replace('\0', "")).unwrap_or_default();
    match *logger {
        Logger::V2 {
            callback: Some(cb),
            environment,
        } => {
            // The message is the format, its `%` doubled: a printf-style logger prints it as
            // it is, and so does one that does not format (FMPy's).
            let format = CString::new(
                message
                    .to_bytes()
                    .iter()
                    .flat_map(|&b| if b == b'%' { vec![b'%', b'%'] } else { vec![b] })
                    .collect::<Vec<u8>>(),
            )
            .unwrap_or_default();
            // SAFETY: the importer's logger, called as FMI 2 defines it, with a format that
            // takes no arguments.
            unsafe {
                cb(
                    environment,
                    name.as_ptr(),
                    status as i32,
                    category.as_ptr(),
                    format.as_ptr(),
                )
            }
        }
        Logger::V3 {
            callback: Some(cb),
            environment,
        } => {
            // SAFETY: the importer's callback, called as FMI 3 defines it.
            unsafe {
                cb(
                    environment,
                    status as i32,
                    category.as_ptr(),
                    message.as_ptr(),
                )
            }
        }
        _ => {}
    }
}
