//! A plan rebuilt from a recording runs the deployment the recording carries — the
//! coefficients its loop ran, which another processor designs a few bits apart — and says how
//! far its own design is from it; a plan with another controller designs its own.

use recorder::Input;
use run_config::{FeedforwardKind, Loaded, Scenario};
use runner::plan::DEPLOYMENT_INPUT;
use runner::Plan;
use servo_config::{parse_deployment, FeedforwardSpec, Origin, ZpetcSpec};

fn zpetc_run() -> Loaded {
    let mut l = Loaded::default();
    l.config.run.duration_s = 0.01;
    l.config.controller.feedforward = FeedforwardKind::Zpetc;
    l.config.scenario = Scenario::Sine {
        amplitude_m: 1e-6,
        frequency_hz: 500.0,
    };
    l
}

fn recorded(plan: &Plan) -> String {
    let i = plan.inputs.iter().find(|i| i.name == DEPLOYMENT_INPUT);
    String::from_utf8(i.expect("every plan embeds its deployment").data.clone()).unwrap()
}

fn with_recorded(text: String) -> Vec<Input> {
    vec![Input {
        name: DEPLOYMENT_INPUT.into(),
        media_type: "application/toml".into(),
        data: text.into_bytes(),
    }]
}

fn zpetc(plan: &Plan) -> ZpetcSpec {
    match plan.deployment.feedforward {
        FeedforwardSpec::Zpetc(z) => z,
        ref other => panic!("not a ZPETC: {other:?}"),
    }
}

/// The text with the value of the line `key = …` replaced by `value`.
fn with_line(text: &str, key: &str, value: String) -> String {
    let prefix = format!("{key} = ");
    let mut found = false;
    let lines: Vec<String> = text
        .lines()
        .map(|l| match l.strip_prefix(&prefix) {
            Some(_) if !found => {
                found = true;
                format!("{prefix}{value}")
            }
            _ => l.to_owned(),
        })
        .collect();
    assert!(found, "no line {key} in\n{text}");
    lines.join("\n")
}

#[test]
fn the_embedded_deployment_is_the_one_the_loop_runs() {
    let l = zpetc_run();
    let plan = Plan::new(&l).unwrap();
    assert_eq!(plan.design_difference, None);
    let text = recorded(&plan);
    let parsed = parse_deployment(&text, &Origin::default()).unwrap();
    assert_eq!(parsed.deployment, plan.deployment);
    // Rebuilt from its own recording: the same bits, designed again to the same bits.
    let again = Plan::with_inputs(&l, with_recorded(text.clone())).unwrap();
    assert_eq!(again.design_difference, Some(0.0));
    assert_eq!(again.deployment, plan.deployment);
    assert_eq!(recorded(&again), text);
}

#[test]
fn a_recorded_design_a_few_bits_apart_runs_as_recorded_and_the_gap_is_reported() {
    let l = zpetc_run();
    let plan = Plan::new(&l).unwrap();
    let designed = zpetc(&plan);
    let gain = designed.gain * (1.0 + 1e-9);
    let text = with_line(&recorded(&plan), "gain", format!("{gain:?}"));
    let replayed = Plan::with_inputs(&l, with_recorded(text.clone())).unwrap();
    assert_eq!(zpetc(&replayed).gain.to_bits(), gain.to_bits());
    assert_eq!(zpetc(&replayed).sections, designed.sections);
    let d = replayed.design_difference.unwrap();
    assert!((d - 1e-9).abs() < 1e-12, "difference {d:e}");
    // What a recording of the replay carries is what it ran.
    assert_eq!(recorded(&replayed).trim_end(), text.trim_end());

    // Another controller (a hot swap, a replay with a replaced controller) designs its own.
    let swapped = replayed
        .with_controller(replayed.config.controller.clone())
        .unwrap();
    assert_eq!(swapped.design_difference, None);
    assert_eq!(zpetc(&swapped).gain.to_bits(), designed.gain.to_bits());
}

#[test]
fn a_recorded_design_of_another_form_runs_and_says_so() {
    let l = zpetc_run();
    let plan = Plan::new(&l).unwrap();
    let designed = zpetc(&plan);
    assert!(designed.sections_used >= 2);
    // One section fewer: the recording of another version of the design.
    let text = recorded(&plan);
    let rows: Vec<&str> = text.lines().collect();
    let first = rows.iter().position(|r| r.starts_with("  [")).unwrap();
    let shorter: Vec<&str> = [&rows[..first], &rows[first + 1..]].concat();
    let replayed = Plan::with_inputs(&l, with_recorded(shorter.join("\n"))).unwrap();
    assert_eq!(replayed.design_difference, Some(f64::INFINITY));
    assert_eq!(zpetc(&replayed).sections_used, designed.sections_used - 1);
}

#[test]
fn a_damaged_embedded_deployment_is_refused_by_name() {
    let l = zpetc_run();
    let e = Plan::with_inputs(&l, with_recorded("gain = [".into()))
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains("deployment.toml (embedded in the recording)"),
        "{e}"
    );
}
