//! Identification recovers the simulator's own Table 5-2 parameters (thesis §5.5.3) from an
//! open-loop FRF measured on the running, noisy simulator by stepped sine, starting 20–40 % off.

mod common;

use common::plan;
use num_complex::Complex64;
use runner::config::Loaded;
use studies::frf::{stepped_sine, FrfLoop, FrfSettings};
use studies::identify::{identify, table_5_2, with_table_5_2};

#[test]
fn recovers_the_simulators_table_5_2_parameters_within_2_percent() {
    let truth_cfg = Loaded::default(); // thesis stage, all noise on
    let freqs: Vec<f64> = (0..80)
        .map(|i| 20.0 * (500.0f64).powf(i as f64 / 79.0))
        .collect();
    let settings = FrfSettings::for_loop(FrfLoop::Open);
    let points = stepped_sine(
        &plan(&truth_cfg),
        FrfLoop::Open,
        &freqs,
        &settings,
        &mut |_, _| {},
    )
    .unwrap();
    let (f, g): (Vec<f64>, Vec<Complex64>) = points
        .iter()
        .filter(|p| !p.clipped)
        .map(|p| {
            (
                p.freq_hz,
                Complex64::from_polar(p.magnitude, p.phase_deg.to_radians()),
            )
        })
        .unzip();
    let truth = table_5_2(&truth_cfg.config.plant.stage);
    let mut start_cfg = truth_cfg.clone();
    let off = [1.3, 0.75, 1.4, 0.7, 1.25, 0.8];
    let start: Vec<f64> = truth.iter().zip(off).map(|(t, o)| t * o).collect();
    start_cfg.config.plant.stage = with_table_5_2(&truth_cfg.config.plant.stage, &start);
    let id = identify(&plan(&start_cfg), &f, &g).unwrap();
    println!(
        "fit {:.2} % ({:.2} % weighted), {} iterations",
        id.fit_percent, id.weighted_fit_percent, id.iterations
    );
    for (i, t) in truth.iter().enumerate() {
        let err = id.fitted[i] / t - 1.0;
        println!(
            "{:>12} {:>12.5e} truth {:>12.5e} ({:+.3} %, 1σ {:.3} %)",
            id.names[i],
            id.fitted[i],
            t,
            100.0 * err,
            100.0 * id.rel_std[i]
        );
        assert!(
            err.abs() < 0.02,
            "{} off by {:.2} %",
            id.names[i],
            100.0 * err
        );
    }
    assert!(
        id.fit_percent > 97.7,
        "fit {} % (thesis 97.7 %)",
        id.fit_percent
    );
}
