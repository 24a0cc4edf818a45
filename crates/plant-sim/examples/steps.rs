//! Runs the default heavy stage with all noise on for `N` steps (default 2·10⁷), for profiling:
//! `cargo run --release -p plant-sim --example steps -- 20000000`.

use plant_sim::cutting::CuttingProfile;
use plant_sim::{PlantParams, Simulator};

fn main() {
    let n: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(20_000_000);
    let mut sim = Simulator::new(&PlantParams::heavy(), 1, &CuttingProfile::None).unwrap();
    let start = std::time::Instant::now();
    let mut acc = 0.0;
    for k in 0..n {
        let (s, t) = sim.step(1e-3 * ((k & 1023) as f64 - 512.0) / 512.0);
        acc += s.gap_v + t.tool_m;
    }
    let dt = start.elapsed().as_secs_f64();
    println!(
        "{n} steps in {dt:.3} s: {:.1} ns/step, {:.1}× real time ({acc:e})",
        dt / n as f64 * 1e9,
        n as f64 / dt / 199_600.0
    );
}
