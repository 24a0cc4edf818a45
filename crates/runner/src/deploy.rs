//! The deployment a daemon runs (`servo deploy`): the plan's loop with every coefficient the
//! runtime needs — the ZPETC designed, the stability checked on the plant model — written as
//! the TOML `servo_runtime::Servo::from_file` reads, with what it was made for.

use crate::error::RunError;
use crate::gain_range::checked;
use crate::plan::Plan;
use run_config::made_for_plant;
use servo_config::{deployment_toml, Deployment};

/// The checked deployment of `plan` and its file text.
pub fn deployment_file(plan: &Plan) -> Result<(Deployment, String), RunError> {
    let d = checked(plan)?;
    let s = d
        .stability
        .expect("a checked deployment carries its stability");
    let header = format!(
        "fts-servo deployment: everything a Servo runs (servo_runtime::Servo::from_file).\n\
         Made by `servo deploy` for {}; {}.\n\
         Checked on the plant model: spectral radius {:.6}; output scales allowed {:.4}..={:.4}.\n\
         {}",
        plan.controller.description,
        made_for_plant(&plan.config.plant).describe(),
        s.spectral_radius,
        s.low(),
        s.high(),
        match plan.config.scenario.reference(plan.config.run.duration_s) {
            Some(_) => "Reference: the built-in generator below (Servo::tick).".to_owned(),
            None =>
                "Reference: the host's trajectory (Servo::tick_with); [reference] holds position."
                    .to_owned(),
        }
    );
    let text = deployment_toml(&d, Some(&made_for_plant(&plan.config.plant)), &header);
    Ok((d, text))
}
