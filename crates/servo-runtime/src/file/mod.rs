//! Files (standard library only): the deployment a daemon's [`crate::Servo`] is built from,
//! the controller files it loads while running, what they were made for, and errors that name
//! the file, line, key and allowed range.

mod input_file;
mod made_for;
mod origin;
mod toml_format;

pub use input_file::{read_input, read_text, MAX_IMAGE_BYTES, MAX_TEXT_BYTES};
pub use made_for::{MadeFor, Mismatch};
pub use origin::{line_of, ConfigError, Origin};
pub use toml_format::{
    controller_toml, deployment_toml, matrix, num, parse_controller_file, parse_deployment,
    ControllerFile, DeploymentAndProvenance,
};

impl crate::Servo {
    /// The loop of the deployment `text` (TOML, as `servo deploy` writes it), checked and built.
    pub fn from_toml(text: &str) -> Result<Self, ConfigError> {
        Self::from_text(text, &Origin::default())
    }

    /// The loop of the deployment file `path` (a regular file of at most 4 MiB), checked and
    /// built; errors name the file, line, key and allowed range.
    pub fn from_file(path: impl AsRef<std::path::Path>) -> Result<Self, ConfigError> {
        let path = path.as_ref();
        let text = read_text(path)?;
        Self::from_text(
            &text,
            &Origin {
                path: Some(path.to_owned()),
                text: Some(text.clone()),
            },
        )
    }

    fn from_text(text: &str, at: &Origin) -> Result<Self, ConfigError> {
        let at = Origin {
            text: Some(text.to_owned()),
            ..at.clone()
        };
        let d = parse_deployment(text, &at)?;
        let mut servo = crate::Servo::new(&d.deployment).map_err(|e| at.located(&e))?;
        servo.host.made_for = d.made_for;
        Ok(servo)
    }
}
