//! The R-L coil + analog PI current loop (§4.6.3–4.6.4): first order at its design bandwidth
//! when unsaturated, slew-limited by the bus voltage on large steps, clamped at peak current.

use crate::common;
use plant_sim::cutting::CuttingProfile;

use plant_sim::params::{CurrentLoopModel, PlantParams};
use plant_sim::Simulator;
use std::f64::consts::PI;

fn coil_plant() -> PlantParams {
    let mut p = common::quiet_ideal(PlantParams::heavy());
    p.actuator.model = CurrentLoopModel::Coil;
    p
}

/// Small step: i(t) = g·u·(1 − e^{−ωc (t − τ)}) (PI zero cancels the coil pole). RK4 at
/// ωc·h ≈ 0.4 is accurate to ~1e-4; back-EMF is negligible over a few ticks.
#[test]
fn unsaturated_loop_is_first_order_after_the_delay() {
    let p = coil_plant();
    let mut sim = Simulator::new(&p, 1, &CuttingProfile::None).unwrap();
    let wc = 2.0 * PI * p.actuator.coil.loop_bandwidth_hz;
    for k in 1..=6 {
        let (_, t) = sim.step(0.01);
        let elapsed = k as f64 * p.period_s() - p.timing.delay_s;
        let want = 0.01 * (1.0 - libm::exp(-wc * elapsed));
        assert!(
            (t.coil_current_a - want).abs() < 1e-3 * want,
            "tick {k}: {} vs {want}",
            t.coil_current_a
        );
    }
}

/// 10 A step: the amplifier clips at 36 V, so the current rises as (V/R)(1 − e^{−tR/L})
/// (R = coil + sense resistor), reaching 6 A after ≈ 50 µs instead of in a microsecond.
#[test]
fn large_step_is_slew_limited_by_the_bus() {
    let p = coil_plant();
    let c = p.actuator.coil;
    let r = c.resistance_ohm + c.sense_resistance_ohm;
    let mut sim = Simulator::new(&p, 1, &CuttingProfile::None).unwrap();
    for k in 1..=12 {
        let (_, t) = sim.step(10.0);
        let elapsed = k as f64 * p.period_s() - p.timing.delay_s;
        let want = c.bus_v / r * (1.0 - libm::exp(-elapsed * r / c.inductance_h));
        // Back-EMF (K_T·v, the coil accelerating at ~100 m/s²) takes < 0.5 % here.
        assert!(
            (t.coil_current_a - want).abs() < 5e-3 * want,
            "tick {k}: {} vs {want}",
            t.coil_current_a
        );
    }
}

#[test]
fn reference_is_clamped_at_peak_current() {
    let mut p = coil_plant();
    p.actuator.coil.bus_v = 200.0; // enough voltage to reach the clamp
    let mut sim = Simulator::new(&p, 1, &CuttingProfile::None).unwrap();
    let mut last = 0.0;
    for _ in 0..2000 {
        last = sim.step(30.0).1.coil_current_a;
    }
    // 30 V × 1 A/V asks for 30 A; the reference stops at 20 A (minus the back-EMF share).
    assert!((last - 20.0).abs() < 0.05, "{last}");
}

/// Every current-loop setting is checked whichever model is selected: a coil setting out of
/// range is refused on the ideal model too (a file that passes today does not break when the
/// model is switched), naming its key.
#[test]
fn coil_settings_are_checked_whatever_the_model() {
    for model in [CurrentLoopModel::Ideal, CurrentLoopModel::Coil] {
        let mut p = coil_plant();
        p.actuator.model = model;
        p.actuator.coil.bus_v = -36.0;
        let Err(e) = Simulator::new(&p, 1, &CuttingProfile::None) else {
            panic!("{model:?}: a negative bus voltage was accepted");
        };
        let e = e.to_string();
        assert!(e.contains("actuator.coil.bus_v"), "{model:?}: {e}");
    }
}
