//! What a unit does, whichever FMI version calls it: its variables' values, initialisation and
//! steps of whole ticks.

use fmu::Variable;

/// A variable's value.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// A real.
    Real(f64),
    /// An integer.
    Integer(i32),
    /// A Boolean.
    Boolean(bool),
    /// A string.
    String(String),
}

/// A unit: the stage or the controller.
pub trait Model {
    /// Its variables (the description's).
    fn variables(&self) -> &[Variable];
    /// Stores `value` at `vr` (type, causality, mode and table range already checked).
    fn set(&mut self, vr: u32, value: Value) -> Result<(), String>;
    /// The value at `vr` (type already checked); builds the unit if it must.
    fn get(&mut self, vr: u32) -> Result<Value, String>;
    /// Builds the unit from its parameters (the end of initialisation).
    fn initialize(&mut self) -> Result<(), String>;
    /// Advances `ticks` servo ticks with the inputs held.
    fn step(&mut self, ticks: u64) -> Result<(), String>;
    /// One tick, s.
    fn period_s(&self) -> f64;
    /// Back to the state after instantiation (parameters at their start values).
    fn reset(&mut self);
}
