//! A prescription's tool path before the cut, against closed forms: Fringe astigmatism
//! `a ρ² cos 2θ` on a plane (nose 0) puts `a (r/R)² cos 2θ` on the FTS at each radius —
//! stroke `2a(r/R)²`, peak velocity `2Ω a (r/R)²`, acceleration `4Ω² a (r/R)²`, all at twice
//! the spindle frequency — and the predicted error is `|T(2Ω) − 1|` times its RMS. The sphere
//! goes entirely to the Z slide. A file that is not a prescription is refused with its key.

use optics::{Prescription, Zernike, ZernikeOrder};
use recorder::Input;
use run_config::surface::LoadedSurface;
use run_config::{Loaded, Machining, Origin, RunConfig, Scenario, SurfaceConfig};
use runner::plan::PRESCRIPTION_INPUT;
use runner::{Plan, RunError};
use std::f64::consts::TAU;
use studies::toolpath::demands::feasibility;

const A_M: f64 = 2e-6;
const NORM_M: f64 = 0.01;

/// The run of a machining `m` whose surface is the embedded prescription `data` (JSON, as a
/// recording holds it).
fn planned(m: Machining, nose_compensation: bool, data: Vec<u8>) -> Result<Plan, RunError> {
    let config = RunConfig {
        scenario: Scenario::Machine(Machining {
            surface: SurfaceConfig::Prescription {
                path: PRESCRIPTION_INPUT.into(),
                nose_compensation,
                clearance_angle_rad: 0.12,
            },
            ..m
        }),
        ..RunConfig::default()
    };
    let input = Input {
        name: PRESCRIPTION_INPUT.into(),
        media_type: "application/json".into(),
        data,
    };
    let loaded = Loaded {
        config,
        origin: Origin::default(),
    };
    Plan::with_inputs(&loaded, vec![input])
}

fn plan_of(p: &Prescription, rpm: f64, nose_compensation: bool) -> Plan {
    let m = Machining {
        spindle_rpm: rpm,
        start_radius_m: p.aperture_radius_m,
        ..Machining::default()
    };
    planned(m, nose_compensation, serde_json::to_vec(p).unwrap()).expect("the prescription plans")
}

fn astigmatism(base_radius_m: Option<f64>) -> Prescription {
    Prescription {
        base: base_radius_m.map(|r| optics::Conic {
            curvature_per_m: 1.0 / r,
            conic: 0.0,
            even_asphere: vec![],
        }),
        zernike: Some(Zernike {
            order: ZernikeOrder::Fringe,
            norm_radius_m: NORM_M,
            coefficients_m: vec![0.0, 0.0, 0.0, 0.0, A_M],
        }),
        aperture_radius_m: NORM_M,
        ..Prescription::default()
    }
}

#[test]
fn astigmatism_demands_are_the_closed_forms() {
    let rpm = 600.0;
    let plan = plan_of(&astigmatism(None), rpm, false);
    let f = feasibility(&plan, 4).unwrap();
    let omega = rpm * TAU / 60.0;
    let outer = &f.bands[0]; // 7.5–10 mm, its outer edge the largest
    let amp = A_M; // (r/R)² = 1 at the edge
    assert!(
        (outer.stroke_m - 2.0 * amp).abs() < 1e-3 * amp,
        "{}",
        outer.stroke_m
    );
    assert!((outer.peak_velocity_m_per_s - 2.0 * omega * amp).abs() < 1e-3 * 2.0 * omega * amp);
    assert!(
        (outer.peak_acceleration_m_per_s2 - 4.0 * omega * omega * amp).abs()
            < 1e-3 * 4.0 * omega * omega * amp
    );
    assert!((outer.bandwidth_hz - 2.0 * rpm / 60.0).abs() < 1e-9);
    // The predicted error: |T − 1| at 2Ω times the harmonic's RMS a/√2.
    let t = plan
        .closed_loop
        .response(
            loop_model::closed_loop::output::TOOL_M,
            loop_model::closed_loop::input::REFERENCE_M,
            2.0 * rpm / 60.0,
        )
        .unwrap();
    let want = (t - 1.0).norm() * amp / 2f64.sqrt();
    assert!(
        (outer.predicted_rms_m - want).abs() < 1e-6 * want,
        "{} vs {want}",
        outer.predicted_rms_m
    );
    // Slope along the cut: max |∂z/∂θ|/r = 2a/r at the edge.
    assert!(
        (outer.slope_along_cut_rad - libm::atan(2.0 * amp / NORM_M)).abs()
            < 1e-3 * 2.0 * amp / NORM_M
    );
    assert!(f.exceeded.is_empty(), "{:?}", f.exceeded);
}

#[test]
fn a_sphere_goes_to_the_z_slide_and_the_nose_is_compensated() {
    // A 100 mm sphere plus the astigmatism, nose-compensated: the FTS keeps the astigmatism's
    // ±a stroke (to the sphere's slight change of it), the Z slide takes the sphere's sag.
    let plan = plan_of(&astigmatism(Some(0.1)), 600.0, true);
    let f = feasibility(&plan, 2).unwrap();
    let sphere_sag = 0.1 - (0.1f64 * 0.1 - NORM_M * NORM_M).sqrt();
    assert!(
        (f.z_slide_travel_m - sphere_sag).abs() < 0.02 * sphere_sag,
        "{}",
        f.z_slide_travel_m
    );
    assert!(
        (f.fts_stroke_m - 2.0 * A_M).abs() < 0.05 * 2.0 * A_M,
        "{}",
        f.fts_stroke_m
    );
    let Some(LoadedSurface::Prescription(path)) = &plan.surface else {
        panic!("a prescription")
    };
    assert!((path.nose_radius_m() - 0.5e-3).abs() < 1e-15);
}

#[test]
fn a_start_outside_the_aperture_is_refused_at_its_key() {
    let mut p = astigmatism(None);
    p.aperture_radius_m = 0.005;
    let e = planned(Machining::default(), true, serde_json::to_vec(&p).unwrap())
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains("scenario.start_radius_m") && e.contains("aperture"),
        "{e}"
    );
}

#[test]
fn a_damaged_embedded_prescription_is_refused_not_a_panic() {
    // A recording's copy whose grid holds fewer values than its size says.
    let mut p = astigmatism(None);
    p.grid = Some(optics::SagGrid {
        pitch_m: [1e-3, 1e-3],
        columns: 0,
        rows: 0,
        sag_m: vec![0.0; 3],
    });
    let m = || Machining {
        start_radius_m: NORM_M,
        ..Machining::default()
    };
    let e = planned(m(), true, serde_json::to_vec(&p).unwrap())
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains("scenario.surface.path") && e.contains("grid"),
        "{e}"
    );
    // Not JSON at all.
    let e = planned(m(), true, b"{ not json".to_vec())
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains("scenario.surface.path") && e.contains("embeds"),
        "{e}"
    );
}
