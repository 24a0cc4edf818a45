//! What the study tests share.

/// The practice stage's linear and time-invariant effects (the in-band mode): a stage whose
/// drawn model with its modes is the truth a measurement is judged against.
pub const STEADY: plant_sim::practice::PracticeEffects = plant_sim::practice::PracticeEffects {
    band_mode: true,
    ..plant_sim::practice::PracticeEffects::NONE
};

/// The resolved plan of `l` (every test configuration is valid).
pub fn plan(l: &run_config::Loaded) -> runner::Plan {
    runner::Plan::new(l).unwrap()
}

/// Runs the machining plan `p` to its end, unrecorded: its summary and form analysis.
#[allow(dead_code)] // Used by the machining tests, not by every test binary.
pub fn machine(p: &runner::Plan) -> (runner::summary::Summary, studies::form::FormAnalysis) {
    let stop = runner::stop::StopRequest::new();
    studies::form::run_machining(
        p,
        runner::run::RunOptions {
            out: None,
            stop: &stop,
            progress: &mut |_, _| {},
            digest: false,
        },
    )
    .unwrap()
}

/// The open-loop FRF of `p` by stepped sine at `freqs` Hz, with the settings `servo frf --loop
/// open` uses.
#[allow(dead_code)] // Used by the FRF and identification tests, not by every test binary.
pub fn open_loop_frf(p: &runner::Plan, freqs: &[f64]) -> Vec<studies::frf::FrfPoint> {
    use studies::frf::{stepped_sine, FrfLoop, FrfSettings};
    let settings = FrfSettings::for_loop(FrfLoop::Open);
    stepped_sine(p, FrfLoop::Open, freqs, &settings, &mut |_, _| {}).unwrap()
}

/// The book's gentle freeform: a 500 mm sphere, 3 µm astigmatism, 2 µm coma, 1.5 µm trefoil
/// (Fringe) over a 20 mm aperture.
pub const GENTLE: &str = r#"
aperture_radius_mm = 10.0
[base]
radius_mm = 500.0
[zernike]
order = "fringe"
norm_radius_mm = 10.0
coefficients_mm = [0.0, 0.0, 0.0, 0.0, 0.003, 0.0, 0.002, 0.0, 0.0, 0.0015]
"#;

/// A cut of the prescription file `path` at 600 rpm from the aperture's edge (the gentle
/// freeform's 10 mm), its nose compensated.
#[allow(dead_code)] // Used by the tool-path and compensation tests, not by every test binary.
pub fn gentle_cut(path: &std::path::Path) -> run_config::Machining {
    run_config::Machining {
        surface: run_config::SurfaceConfig::Prescription {
            path: path.to_owned(),
            nose_compensation: true,
            clearance_angle_rad: 0.12,
        },
        spindle_rpm: 600.0,
        start_radius_m: 10e-3,
        ..run_config::Machining::default()
    }
}
