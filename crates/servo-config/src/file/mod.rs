//! Files (standard library only): the deployment a daemon's `servo_runtime::Servo` is built from,
//! the controller files it loads while running, what they were made for, and errors that name
//! the file, line, key and allowed range.

mod exact;
mod input_file;
mod made_for;
mod origin;
mod toml_format;

pub use exact::{exact_array, exact_arrays};
pub use input_file::{read_input, read_text, LOADED_FILE, MAX_IMAGE_BYTES, MAX_TEXT_BYTES};
pub use made_for::{MadeFor, Mismatch};
pub use origin::{line_of, toml_message, ConfigError, Origin};
pub use toml_format::{
    controller_toml, deployment_toml, matrix, num, parse_controller_file, parse_deployment,
    stability_toml, ControllerFile, DeploymentAndProvenance,
};
