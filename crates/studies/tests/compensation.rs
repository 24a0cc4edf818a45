//! The measure → register → compensate loop end to end, the truth revealed: a part cut with
//! tool-setting errors, measured by the simulated instrument at a random pose, registered
//! (the setting errors found), the tool corrected and the residual compensated — and the next
//! part judged against the design.

use crate::common;
use common::GENTLE;

use metrology::{Instrument, ReadOptions, RegisterOptions};
use run_config::{Loaded, Machining, Origin, RunConfig, Scenario};
use std::path::Path;
use studies::measured::compensate::{next_compensation, CompensationOptions};
use studies::measured::simulate::simulate_measurement;

/// A 600 rpm cut of the prescription file `path` with ZPETC, the tool set off by `setting`.
fn loaded(path: &Path, setting: [f64; 2]) -> Loaded {
    let mut config = RunConfig {
        scenario: Scenario::Machine(Machining {
            tool_centre_height_m: setting[0],
            tool_x_offset_m: setting[1],
            ..common::gentle_cut(path)
        }),
        ..RunConfig::default()
    };
    config.controller.feedforward = run_config::FeedforwardKind::Zpetc;
    Loaded {
        config,
        origin: Origin::default(),
    }
}

#[test]
fn a_cycle_finds_the_setting_errors_and_the_next_part_meets_the_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    let design = dir.path().join("gentle.toml");
    std::fs::write(&design, GENTLE).unwrap();
    let (h, e) = (1.5e-6, -2e-6);
    let first = loaded(&design, [h, e]);
    let plan = common::plan(&first);
    let cut = simulate_measurement(&plan, &Instrument::default(), 3).unwrap();
    // The part as cut: the setting errors' geometry, tens of nanometres.
    assert!(cut.part.tilt_removed.pv_m > 20e-9, "{:?}", cut.part);
    let map = dir.path().join("part.xyz");
    std::fs::write(&map, metrology::to_zygo_xyz(&cut.map)).unwrap();
    let options = RegisterOptions {
        power: false,
        setting_errors: true,
    };
    let seen =
        studies::measured::register_map(&first, &map, &ReadOptions::default(), &options).unwrap();
    let r = &seen.registration;
    let found = [r.centre_height_m.unwrap(), r.x_offset_m.unwrap()];
    for (f, truth) in found.iter().zip([h, e]) {
        assert!(
            (f.value - truth).abs() < 0.1e-6 && (f.value - truth).abs() < 4.0 * f.std + 0.03e-6,
            "{f:?} against {truth}"
        );
    }
    let turned = r.rotation_rad.unwrap().value - cut.mounting.rotation_rad;
    assert!(turned.abs() < 1e-4, "rotation off by {turned} rad");
    // The next cut: the tool moved by the correction, the residual compensated.
    let reg = dir.path().join("register");
    studies::measured::write_data(&seen, &reg).unwrap();
    let next = next_compensation(
        &plan,
        &reg.join("part_error.csv"),
        None,
        &CompensationOptions {
            gain: 1.0,
            lowpass_m: 0.0,
        },
        4,
    )
    .unwrap();
    assert!(next.toolpath.feasibility.exceeded.is_empty());
    let comp = dir.path().join("compensate");
    studies::measured::write_compensation(&next, true, &comp).unwrap();
    let compensated = dir.path().join("compensated.toml");
    std::fs::write(
        &compensated,
        format!(
            "{GENTLE}\n[compensation]\npath = \"{}\"\npitch_mm = [0.15625, 0.15625]\n",
            comp.join("compensation.csv").display()
        ),
    )
    .unwrap();
    let correction = seen.setting_correction.unwrap();
    let second = loaded(
        &compensated,
        [h + correction.centre_height_m, e + correction.x_offset_m],
    );
    let again = simulate_measurement(&common::plan(&second), &Instrument::default(), 4).unwrap();
    let part = again.part.tilt_removed;
    // The goal after three cycles, met after one on a stage that is its model.
    assert!(part.pv_m < 20e-9 && part.rms_m < 3e-9, "{part:?}");
    assert!(part.rms_m < cut.part.tilt_removed.rms_m / 5.0);
}

#[test]
fn a_compensation_beyond_the_stroke_is_refused_and_a_map_of_another_aperture_too() {
    let dir = tempfile::tempdir().unwrap();
    let design = dir.path().join("gentle.toml");
    std::fs::write(&design, GENTLE).unwrap();
    let plan = common::plan(&loaded(&design, [0.0; 2]));
    // ±30 µm of astigmatism in the part's frame: beyond the gap sensor's ±25.6 µm.
    let write = |name: &str, nodes: usize, pitch_mm: f64| {
        let half = (nodes - 1) as f64 / 2.0;
        let mut text =
            format!("# heights in nm, row 0 at +y, column 0 at -x, pitch {pitch_mm} mm\n");
        for row in 0..nodes {
            let cells: Vec<String> = (0..nodes)
                .map(|col| {
                    let (x, y) = (
                        (col as f64 - half) * pitch_mm,
                        (half - row as f64) * pitch_mm,
                    );
                    format!("{:.3}", 30_000.0 * (x * x - y * y) / 100.0)
                })
                .collect();
            text += &cells.join(",");
            text.push('\n');
        }
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    let options = CompensationOptions {
        gain: 1.0,
        lowpass_m: 0.0,
    };
    let big = write("big.csv", 129, 0.15625);
    let next = next_compensation(&plan, &big, None, &options, 4).unwrap();
    assert!(
        next.toolpath
            .feasibility
            .exceeded
            .iter()
            .any(|e| e.contains("stroke") || e.contains("gap") || e.contains("DAC")),
        "{:?}",
        next.toolpath.feasibility.exceeded
    );
    // A residual over ±5 mm for a part of ±10 mm.
    let small = write("small.csv", 65, 0.15625);
    let e = next_compensation(&plan, &small, None, &options, 4).unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("small.csv") && text.contains("another aperture"),
        "{text}"
    );
}
