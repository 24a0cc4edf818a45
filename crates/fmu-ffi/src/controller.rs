//! The controller unit: servo-runtime's `Servo` of the unit's deployment, ticked once per step
//! on the readings of the step's communication point.
//!
//! The command depends on this point's readings (direct feedthrough): it is computed when it
//! is first read after the readings are set, or at the step. A master that steps the stage,
//! gives its readings to the controller, reads the command and gives it to the stage closes
//! the loop with the servo's own timing (reading k → command k, held over tick k).

use crate::model::{Model, Value};
use daq_io::{flags, Sensor};
use fmu::variables::{controller, controller_variables};
use fmu::Variable;
use servo_config::{parse_deployment, Deployment, MadeFor, Origin};
use servo_runtime::Servo;

/// The readings a tick acts on.
#[derive(Debug, Clone, Copy, Default)]
struct Readings {
    gap_v: f64,
    accel_v: f64,
    flags: i32,
}

impl Readings {
    /// The same bits (a NaN reading set again is the same reading).
    fn same_as(&self, other: &Readings) -> bool {
        self.gap_v.to_bits() == other.gap_v.to_bits()
            && self.accel_v.to_bits() == other.accel_v.to_bits()
            && self.flags == other.flags
    }
}

/// What the last tick gave.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Outputs {
    dac_v: f64,
    reference_m: f64,
    measured_m: f64,
    following_error_m: f64,
    flags: i32,
    tripped: bool,
}

/// The controller unit.
pub struct ControllerUnit {
    vars: Vec<Variable>,
    /// The deployment's file, for messages.
    source: String,
    deployment: Deployment,
    made_for: Option<MadeFor>,
    plant_sha256: String,
    servo: Option<Servo>,
    readings: Readings,
    /// Readings were set at this communication point.
    fresh: bool,
    /// This point's tick is taken (its command was read).
    ticked: bool,
    out: Outputs,
    tick: u64,
}

impl ControllerUnit {
    /// The unit of the deployment `text` (the resource `origin` names); refused with the
    /// runtime's message when the deployment does not pass its checks.
    pub fn new(text: &str, origin: &Origin) -> Result<Self, String> {
        let d = parse_deployment(text, origin).map_err(|e| e.to_string())?;
        // Built once here so a deployment the runtime refuses is refused at instantiation.
        let source = origin_name(origin);
        Servo::new(&d.deployment).map_err(|e| format!("{source}: {e}"))?;
        Ok(ControllerUnit {
            vars: controller_variables(),
            source,
            deployment: d.deployment,
            made_for: d.made_for,
            plant_sha256: String::new(),
            servo: None,
            readings: Readings::default(),
            fresh: false,
            ticked: false,
            out: Outputs::default(),
            tick: 0,
        })
    }

    /// The deployment was made for the plant `plant_sha256` names (when set).
    fn check_made_for(&self) -> Result<(), String> {
        if !self.plant_sha256.is_empty() {
            let for_plant = self.made_for.as_ref().map(|m| m.plant_sha256.as_str());
            if for_plant != Some(self.plant_sha256.as_str()) {
                return Err(format!(
                    "{}: controller.made_for: the deployment was made for {}; plant_sha256 = {} is another plant (redesign the deployment for this stage: servo deploy -c with its plant)",
                    self.source,
                    self.made_for
                        .as_ref()
                        .map_or("an unstated plant".into(), MadeFor::describe),
                    self.plant_sha256
                ));
            }
        }
        Ok(())
    }

    /// Ticks once on the held readings.
    fn tick_now(&mut self) -> Result<(), String> {
        let servo = match &mut self.servo {
            Some(s) => s,
            None => {
                self.initialize()?;
                self.servo.as_mut().expect("initialised above")
            }
        };
        let r = self.readings;
        let sample = Sensor {
            seq: self.tick,
            time_s: self.tick as f64 * self.deployment.period_s(),
            gap_v: r.gap_v,
            accel_v: r.accel_v,
            flags: r.flags as u32,
            run_id: 1,
            ..Sensor::default()
        };
        let command = servo.tick(&sample);
        let t = servo.telemetry().copied().unwrap_or_default();
        self.out = Outputs {
            dac_v: command.dac_v,
            reference_m: t.reference_m,
            measured_m: t.measured_m,
            following_error_m: t.following_error_m,
            flags: t.flags as i32,
            tripped: t.flags & flags::TRIPPED != 0,
        };
        self.ticked = true;
        Ok(())
    }
}

fn origin_name(origin: &Origin) -> String {
    origin
        .path
        .as_ref()
        .map_or("the deployment".into(), |p| p.display().to_string())
}

impl Model for ControllerUnit {
    fn variables(&self) -> &[Variable] {
        &self.vars
    }

    fn set(&mut self, vr: u32, value: Value) -> Result<(), String> {
        let mut r = self.readings;
        match (vr, value) {
            (controller::GAP_V, Value::Real(x)) => r.gap_v = x,
            (controller::ACCEL_V, Value::Real(x)) => r.accel_v = x,
            (controller::READING_FLAGS, Value::Integer(n)) => r.flags = n,
            (controller::PLANT_SHA256, Value::String(s)) => {
                // A loop built early (an output read during initialisation) is built again,
                // checked against this plant.
                self.plant_sha256 = s;
                self.servo = None;
                self.ticked = false;
                self.out = Outputs::default();
                return Ok(());
            }
            (vr, _) => return Err(format!("value reference {vr} is not settable")),
        }
        if self.ticked && !r.same_as(&self.readings) {
            return Err(format!(
                "tick {} has been taken on this communication point's readings (its command was read): set the readings before reading the command; the next step takes new ones",
                self.tick
            ));
        }
        self.readings = r;
        self.fresh = true;
        Ok(())
    }

    fn get(&mut self, vr: u32) -> Result<Value, String> {
        let output = matches!(
            vr,
            controller::DAC_V
                | controller::REFERENCE_M
                | controller::MEASURED_M
                | controller::FOLLOWING_ERROR_M
                | controller::FLAGS
                | controller::TRIPPED
        );
        // Read before this point's readings are set: the command held over the last step.
        if output && self.fresh && !self.ticked {
            self.tick_now()?;
        }
        let o = self.out;
        let r = self.readings;
        Ok(match vr {
            controller::GAP_V => Value::Real(r.gap_v),
            controller::ACCEL_V => Value::Real(r.accel_v),
            controller::READING_FLAGS => Value::Integer(r.flags),
            controller::DAC_V => Value::Real(o.dac_v),
            controller::REFERENCE_M => Value::Real(o.reference_m),
            controller::MEASURED_M => Value::Real(o.measured_m),
            controller::FOLLOWING_ERROR_M => Value::Real(o.following_error_m),
            controller::FLAGS => Value::Integer(o.flags),
            controller::TRIPPED => Value::Boolean(o.tripped),
            controller::PLANT_SHA256 => Value::String(self.plant_sha256.clone()),
            vr => return Err(format!("value reference {vr} is not a variable")),
        })
    }

    fn initialize(&mut self) -> Result<(), String> {
        if self.servo.is_some() {
            return Ok(());
        }
        self.check_made_for()?;
        let servo = Servo::new(&self.deployment).map_err(|e| format!("{}: {e}", self.source))?;
        self.servo = Some(servo);
        Ok(())
    }

    fn step(&mut self, ticks: u64) -> Result<(), String> {
        if ticks != 1 {
            return Err(format!(
                "a step of {ticks} ticks: the controller takes one tick per step (its readings change every tick)"
            ));
        }
        if !self.ticked {
            self.tick_now()?;
        }
        self.ticked = false;
        self.fresh = false;
        self.tick += 1;
        Ok(())
    }

    fn period_s(&self) -> f64 {
        self.deployment.period_s()
    }

    fn reset(&mut self) {
        self.servo = None;
        self.plant_sha256.clear();
        self.readings = Readings::default();
        self.fresh = false;
        self.ticked = false;
        self.out = Outputs::default();
        self.tick = 0;
    }
}
