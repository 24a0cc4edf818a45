//! # metrology
//!
//! Measure the part, correct the next one. A measured surface map read as the instrument wrote
//! it ([`read_map`]: Zygo `.datx`, MetroPro `.dat`, Zygo `.xyz`, NumPy `.npy`, CSV grids; units
//! and pitch from the file, missing pixels kept missing), registered against the design
//! ([`register`]: piston, tilt, decentre, rotation, optionally power and the tool's centre
//! height and X offset, each with its uncertainty) and its residual reported as an optician
//! does ([`form_of`]: PV/RMS after piston and tilt, and power; Standard Zernike terms).
//!
//! Conventions: heights in m toward the instrument (which faces the part as the tool did);
//! maps in image order, row 0 at +y and column 0 at −x.

mod aperture;
mod form;
mod formats;
mod instrument;
mod map;
mod register;

pub use aperture::ApertureMap;
pub use form::{form_of, Form, Residual, FITTED_TERMS};
pub use formats::{read_map, to_zygo_xyz, ReadOptions, MAX_MAP_BYTES, MAX_PIXELS};
pub use instrument::{Instrument, Mounting};
pub use map::{LengthUnit, MapFormat, MeasuredMap};
pub use register::{
    register, Estimate, RegisterError, RegisterOptions, Registration, MIN_VALID_PIXELS,
};

use std::fmt;
use std::path::{Path, PathBuf};

/// A map file that cannot be read: the file and why.
#[derive(Debug, Clone, PartialEq)]
pub struct MapError {
    /// The file.
    pub file: PathBuf,
    /// Why, naming the key or the part of the file.
    pub reason: String,
}

impl MapError {
    fn new(file: &Path, reason: String) -> Self {
        MapError {
            file: file.to_path_buf(),
            reason,
        }
    }
}

impl fmt::Display for MapError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.file.display(), self.reason)
    }
}

impl std::error::Error for MapError {}

impl fmt::Display for RegisterError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for RegisterError {}
