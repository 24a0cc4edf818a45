//! # fmu
//!
//! The simulated stage and the controller as FMI co-simulation units (FMI 2.0 and 3.0): the
//! variables each unit has ([`variables`]), its `modelDescription.xml` ([`description`]) and
//! the `.fmu` archive ([`package`]). The functions an importer calls are libfts_fmu (crate
//! `fmu-ffi`), which reads the same variable tables, so the description and the binary agree
//! by construction.

pub mod description;
pub mod package;
pub mod unit;
pub mod units;
pub mod variables;

pub use package::{write_archive, UnitFiles};
pub use variables::{Causality, Kind, Start, VarType, Variable};

/// The FMI version of a unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FmiVersion {
    /// FMI 2.0 (what most tools load today).
    V2,
    /// FMI 3.0.
    V3,
}

impl FmiVersion {
    /// The folder of the x86-64 Linux binary inside the archive.
    pub fn binary_dir(self) -> &'static str {
        match self {
            FmiVersion::V2 => "binaries/linux64",
            FmiVersion::V3 => "binaries/x86_64-linux",
        }
    }
}

/// The resource file libfts_fmu reads at instantiation: what the unit is and its configuration.
pub const UNIT_FILE: &str = "unit.toml";
/// The controller unit's deployment, a resource beside [`UNIT_FILE`].
pub const DEPLOYMENT_FILE: &str = "deployment.toml";

/// The instantiation token (FMI 2's GUID) of a unit whose resources are `unit` and
/// `deployment`: their SHA-256, so a binary refuses resources that are not its description's.
pub fn token(unit: &[u8], deployment: Option<&[u8]>) -> String {
    use sha2::{Digest, Sha256};
    let mut h = Sha256::new();
    // Length-prefixed, so the two files' boundary is part of what is hashed.
    h.update((unit.len() as u64).to_le_bytes());
    h.update(unit);
    if let Some(d) = deployment {
        h.update(d);
    }
    let hex: String = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
    format!(
        "{{{}-{}-{}-{}-{}}}",
        &hex[0..8],
        &hex[8..12],
        &hex[12..16],
        &hex[16..20],
        &hex[20..32]
    )
}
