//! A value outside its allowed range, named by its configuration key — without allocation, so
//! the per-tick core reports it on a microcontroller as well. The TOML layer adds the file and
//! line ([`crate::ConfigError`]).

use core::fmt;

/// What a key allows, printable.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum Allowed {
    /// `[low, high] unit`.
    Between {
        /// Smallest allowed value.
        low: f64,
        /// Largest allowed value.
        high: f64,
        /// The unit.
        unit: &'static str,
    },
    /// `(low, high) unit`.
    Open {
        /// The value must be above this.
        low: f64,
        /// The value must be below this.
        high: f64,
        /// The unit.
        unit: &'static str,
    },
    /// `> 0 unit` and finite.
    Positive {
        /// The unit.
        unit: &'static str,
    },
    /// `0 (off) or (0, high) unit`.
    OffOrBelow {
        /// The value must be below this.
        high: f64,
        /// The unit.
        unit: &'static str,
    },
    /// `0 (off) or ≥ low unit`.
    OffOrAtLeast {
        /// Smallest allowed nonzero value.
        low: f64,
        /// The unit (and why).
        unit: &'static str,
    },
    /// `[-reach, reach] unit`, printed to four digits.
    PlusMinus {
        /// Largest allowed magnitude.
        reach: f64,
        /// The unit (and why).
        unit: &'static str,
    },
    /// Said in words.
    Text(&'static str),
    /// A digest that must match what it was made from (the words say of what).
    Digest(&'static str),
}

impl Allowed {
    /// `[low, high] unit`.
    pub const fn between(low: f64, high: f64, unit: &'static str) -> Self {
        Allowed::Between { low, high, unit }
    }
}

impl fmt::Display for Allowed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Allowed::Between {
                low,
                high,
                unit: "",
            } => write!(f, "[{low}, {high}]"),
            Allowed::Between { low, high, unit } => write!(f, "[{low}, {high}] {unit}"),
            Allowed::Open { low, high, unit } => write!(f, "({low}, {high}) {unit}"),
            Allowed::Positive { unit } => write!(f, "> 0 {unit}"),
            Allowed::OffOrBelow { high, unit } => write!(f, "0 (off) or (0, {high}) {unit}"),
            Allowed::OffOrAtLeast { low, unit } => write!(f, "0 (off) or ≥ {low:.0} {unit}"),
            Allowed::PlusMinus { reach, unit } => write!(f, "[-{reach:.3e}, {reach:.3e}] {unit}"),
            Allowed::Text(t) => f.write_str(t),
            Allowed::Digest(what) => write!(
                f,
                "the SHA-256 of {what} as the stability check saw them: they changed since — check the loop again (servo deploy, servo tune or servo synth)"
            ),
        }
    }
}

/// A configuration value outside its allowed range: `section.key = value: allowed …`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Invalid {
    /// The table the key is in (`controller`, `protection`, …; empty: the top level).
    pub section: &'static str,
    /// The key within the table (`limit_v`, `ss.a`).
    pub key: &'static str,
    /// The value (NaN when it is not a number: a missing table, a matrix).
    pub value: f64,
    /// What is allowed.
    pub allowed: Allowed,
}

impl Invalid {
    /// `section.key = value`, allowed `allowed`.
    pub const fn new(
        section: &'static str,
        key: &'static str,
        value: f64,
        allowed: Allowed,
    ) -> Self {
        Invalid {
            section,
            key,
            value,
            allowed,
        }
    }

    /// The same error with its key in `section` (a check written for a table, used in
    /// another).
    pub const fn in_section(self, section: &'static str) -> Self {
        Invalid { section, ..self }
    }

    /// The dotted key, written to `f`.
    pub fn write_key(&self, f: &mut impl fmt::Write) -> fmt::Result {
        if self.section.is_empty() {
            f.write_str(self.key)
        } else {
            write!(f, "{}.{}", self.section, self.key)
        }
    }
}

impl fmt::Display for Invalid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.write_key(f)?;
        match self.allowed {
            Allowed::Digest(_) => write!(f, " = (does not match): allowed {}", self.allowed),
            _ => write!(f, " = {}: allowed {}", self.value, self.allowed),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for Invalid {}
