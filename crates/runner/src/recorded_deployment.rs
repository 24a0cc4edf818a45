//! The deployment a run's loop ran, carried in its recording
//! ([`DEPLOYMENT_INPUT`]) so that a plan rebuilt from it runs the same
//! coefficients. The plan-time numerics (nalgebra's and faer's kernels) take the vector
//! instructions the processor has: on another machine the same configuration designs
//! coefficients a few bits apart (a ZPETC's pole–zero cancellation amplifies them), or of
//! another form. A plan rebuilt from a recording runs the recorded deployment and says how far
//! its own design is from it.

use crate::error::RunError;
use recorder::Input;
use servo_config::{deployment_toml, parse_deployment, Deployment, Origin};

/// Attachment name of the deployment the run's loop ran, in its recording: a plan rebuilt
/// from the recording runs it.
pub const DEPLOYMENT_INPUT: &str = "deployment.toml";

const HEADER: &str =
    "fts-servo deployment: the loop this run ran (servo_runtime::Servo::from_file \
                      reads it), as designed on the recording machine; `servo replay` runs it.";

/// The deployment `d` as the recording's [`DEPLOYMENT_INPUT`] attachment.
pub(crate) fn embedded(d: &Deployment) -> Input {
    Input {
        name: DEPLOYMENT_INPUT.into(),
        media_type: "application/toml".into(),
        data: deployment_toml(d, None, HEADER).into_bytes(),
    }
}

/// Replaces the `designed` deployment by the recording's (`recorded`, the attachment's bytes)
/// and returns the largest relative difference between their numbers: 0 when this machine
/// designed the same bits, infinite when the two differ in form (another controller or
/// feedforward structure: a recording made by another version of the design).
pub(crate) fn adopt(designed: &mut Deployment, recorded: &[u8]) -> Result<f64, RunError> {
    let at = Origin {
        path: Some(format!("{DEPLOYMENT_INPUT} (embedded in the recording)").into()),
        text: None,
    };
    let text = std::str::from_utf8(recorded)
        .map_err(|_| at.invalid("(file)", "not UTF-8", "a deployment file in TOML"))?;
    let ran = parse_deployment(text, &at)?.deployment;
    let difference = largest_difference(
        &deployment_toml(designed, None, ""),
        &deployment_toml(&ran, None, ""),
    );
    *designed = Deployment {
        stability: designed.stability,
        ..ran
    };
    Ok(difference)
}

/// The largest relative difference between the numbers of two texts of the same form
/// (infinite when their words or their count of numbers differ).
fn largest_difference(a: &str, b: &str) -> f64 {
    fn words(s: &str) -> Vec<&str> {
        s.split(|c: char| c.is_whitespace() || ",[]={}".contains(c))
            .filter(|w| !w.is_empty())
            .collect()
    }
    let (a, b) = (words(a), words(b));
    if a.len() != b.len() {
        return f64::INFINITY;
    }
    a.iter().zip(&b).fold(0.0, |worst: f64, (x, y)| {
        match (x.parse::<f64>(), y.parse::<f64>()) {
            (Ok(x), Ok(y)) if x.to_bits() == y.to_bits() => worst,
            (Ok(x), Ok(y)) => worst.max((x - y).abs() / x.abs().max(y.abs())),
            _ if x == y => worst,
            _ => f64::INFINITY,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::largest_difference;

    #[test]
    fn differences_are_relative_and_forms_must_match() {
        let a = "gain = 1.0\nsections = [[2.0, -4.0]]\nkind = \"zpetc\"";
        assert_eq!(largest_difference(a, a), 0.0);
        let b = "gain = 1.0\nsections = [[2.0, -5.0]]\nkind = \"zpetc\"";
        assert_eq!(largest_difference(a, b), 1.0 / 5.0);
        let fewer = "gain = 1.0\nsections = [[2.0]]\nkind = \"zpetc\"";
        assert_eq!(largest_difference(a, fewer), f64::INFINITY);
        let other = "gain = 1.0\nsections = [[2.0, -4.0]]\nkind = \"fir\"";
        assert_eq!(largest_difference(a, other), f64::INFINITY);
    }
}
