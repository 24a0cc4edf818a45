//! The configuration loader and the controller-file reader on generated input (property-based):
//! real keys with hostile values (NaN, ±inf, 1e308, subnormals, negative, wrong types, wrong
//! shapes) are accepted only when valid and otherwise refused with an error naming the file —
//! never a panic.

use proptest::prelude::*;
use run_config::{Loaded, Origin, RunConfig};
use runner::Plan;
use std::path::Path;

/// A TOML value, well-formed or not for the key it lands on.
fn value() -> impl Strategy<Value = String> {
    let special = prop_oneof![
        Just("nan"),
        Just("inf"),
        Just("-inf"),
        Just("1e308"),
        Just("-1e308"),
        Just("5e-324"),
        Just("0"),
        Just("-0.0"),
    ]
    .prop_map(str::to_string);
    let wrong_type = prop_oneof![
        Just("true"),
        Just("\"zero\""),
        Just("\"retract\""),
        Just("[1.0, 2.0]"),
    ]
    .prop_map(str::to_string);
    prop_oneof![
        3 => special,
        1 => wrong_type,
        3 => (-1e7f64..1e7).prop_map(|x| format!("{x:e}")),
        3 => (-1e-3f64..1e-3).prop_map(|x| format!("{x:e}")),
        1 => (0u64..u64::MAX).prop_map(|x| x.to_string()),
    ]
}

/// `[section]` and key pairs the loader really has (checked paths, not just unknown-key errors).
const KEYS: &[(&str, &str)] = &[
    ("run", "duration_s"),
    ("run", "settle_s"),
    ("controller", "ka"),
    ("controller", "limit_v"),
    ("controller", "accel_filter_hz"),
    ("controller", "accel_filter_order"),
    ("controller", "smoothing_hz"),
    ("controller.pid", "kp"),
    ("controller.pid", "ki"),
    ("controller.pid", "kd"),
    ("controller.pid", "tf_s"),
    ("plant.stage", "m2_kg"),
    ("plant.stage", "k2_n_per_m"),
    ("plant.capa", "sensitivity_v_per_m"),
    ("plant.timing", "servo_rate_hz"),
    ("plant.timing", "delay_s"),
    ("plant.noise", "sensor_v_per_rt_hz"),
    ("plant.adc", "anti_alias_hz"),
    ("plant.adc", "oversampling"),
    ("protection", "following_error_m"),
    ("protection", "position_limit_m"),
    ("protection", "saturation_s"),
    ("protection", "safe_state"),
    ("protection", "retract_m"),
    ("protection", "retract_speed_m_per_s"),
    ("protection", "after_trip_s"),
    ("nonsense", "key"),
];

/// A config text of a few keys with generated values (one table per section).
fn config_text() -> impl Strategy<Value = String> {
    prop::collection::btree_map(0..KEYS.len(), value(), 1..5).prop_map(|picked| {
        // A sine scenario, so its amplitude and frequency are checked too.
        let mut by_section: std::collections::BTreeMap<&str, Vec<String>> = Default::default();
        by_section.insert(
            "scenario",
            vec![
                "kind = \"sine\"".into(),
                "amplitude_m = 1e-6".into(),
                "frequency_hz = 100.0".into(),
            ],
        );
        for (i, v) in picked {
            let (section, key) = KEYS[i];
            by_section
                .entry(section)
                .or_default()
                .push(format!("{key} = {v}"));
        }
        by_section
            .into_iter()
            .map(|(s, lines)| format!("[{s}]\n{}\n", lines.join("\n")))
            .collect()
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, ..ProptestConfig::default() })]

    #[test]
    fn configs_are_built_or_refused_with_the_file_named(text in config_text()) {
        let path = Path::new("fuzz.toml");
        let config: RunConfig = match toml::from_str(&text) {
            Ok(c) => c,
            Err(_) => return Ok(()), // the TOML/serde layer: a parse error, no panic
        };
        let loaded = Loaded {
            config,
            origin: Origin { path: Some(path.into()), text: Some(text.clone()) },
        };
        if let Err(e) = Plan::new(&loaded) {
            let msg = e.to_string();
            prop_assert!(msg.contains("fuzz.toml"), "{msg}\n{text}");
        }
    }
}

/// A matrix of `rows` × `cols` generated values (finite or not).
fn matrix(rows: usize, cols: usize) -> impl Strategy<Value = String> {
    let entry = prop_oneof![
        8 => (-1e3f64..1e3).prop_map(|x| format!("{x:e}")),
        1 => Just("nan".to_string()),
        1 => Just("1e250".to_string()),
        1 => Just("-inf".to_string()),
    ];
    prop::collection::vec(prop::collection::vec(entry, cols), rows).prop_map(|m| {
        let rows: Vec<String> = m.iter().map(|r| format!("[{}]", r.join(", "))).collect();
        format!("[{}]", rows.join(", "))
    })
}

/// A controller file of order `n` whose shapes are right or off by one.
fn controller_text() -> impl Strategy<Value = String> {
    (
        0usize..5,
        0usize..2,
        0usize..2,
        prop_oneof![Just(199_600.0), Just(f64::NAN), Just(20e3), Just(-1.0)],
    )
        .prop_flat_map(|(n, dr, dc, rate)| {
            let r = n + dr; // dr = 1: one row too many in b
            let c = 1 + dc; // dc = 1: c has a column too many
            (
                matrix(n, n),
                matrix(r, 1),
                matrix(1, n + dc),
                matrix(1, c),
                Just(rate),
            )
        })
        .prop_map(|(a, b, c, d, rate)| {
            format!("sample_rate_hz = {rate}\na = {a}\nb = {b}\nc = {c}\nd = {d}\n")
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, ..ProptestConfig::default() })]

    #[test]
    fn controller_files_are_read_or_refused_with_the_file_named(text in controller_text()) {
        let path = Path::new("fuzz-controller.toml");
        let at = run_config::Origin { path: Some(path.into()), text: Some(text.clone()) };
        let running = servo_config::ControllerSpec::default();
        match servo_config::parse_controller_file(&text, &at, &running)
            .and_then(|f| f.check_rate(199_600.0, &at, "the rate").map(|()| f))
        {
            Ok(f) => {
                let m = f.spec.ss.expect("a state-space file holds matrices");
                let n = m.order();
                prop_assert!((0..=n).all(|i| (0..=n).all(|j| m.entry(i, j).is_finite())), "{text}");
            }
            Err(e) => prop_assert!(e.to_string().contains("fuzz-controller.toml"), "{e}"),
        }
    }
}
