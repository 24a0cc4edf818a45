//! The continuous model against transfer functions derived independently from mechanical
//! impedances (node equations in the frequency domain, thesis eq 5-4..5-7 without its typos),
//! to 1e-9 relative; and static/modal checks.

use num_complex::Complex64 as C;
use plant_sim::impedance::Impedances as Imp;
use plant_sim::model::{input, mechanics, output};
use plant_sim::params::{PlantParams, StageParams};
use plant_sim::PlantModel;
use std::f64::consts::PI;

fn freqs() -> Vec<f64> {
    (0..60)
        .map(|i| libm::pow(10f64, 0.5 + i as f64 * 0.08))
        .collect() // 3 Hz … 170 kHz
}

fn close(got: C, want: C, what: &str, f: f64) {
    assert!(
        (got - want).norm() <= 1e-9 * want.norm(),
        "{what} at {f} Hz: {got} vs {want}"
    );
}

#[test]
fn mechanics_match_impedance_transfer_functions() {
    for p in [
        StageParams::THESIS,
        StageParams::THESIS_HEAVY,
        StageParams {
            k5_n_per_m: 300.0,
            c5_n_s_per_m: 0.3,
            ..StageParams::THESIS
        },
    ] {
        let mech = mechanics(&p);
        for f in freqs() {
            let imp = Imp::new(&p, f);
            let g = mech.freq_response(2.0 * PI * f).unwrap();
            // motor force → x2 − xg (the sensor gap) and → x1
            close(
                g[(1, 0)],
                imp.x2_per_motor_force(C::new(0.0, 0.0)),
                "F_motor→gap",
                f,
            );
            close(
                g[(3, 0)],
                imp.x2_per_motor_force(C::new(0.0, 0.0)) * imp.tool_over_m2(),
                "F_motor→x1",
                f,
            );
            // cutting force → true tool position
            close(
                g[(0, 1)],
                imp.x1_per_cut_force(C::new(0.0, 0.0)),
                "F_cut→tool",
                f,
            );
            // base displacement (with its velocity ẋg = s·xg) → true tool position
            close(
                g[(0, 2)] + imp.s() * g[(0, 3)],
                imp.tool_rel_per_base(),
                "xg→tool",
                f,
            );
        }
    }
}

#[test]
fn full_model_composes_actuator_sensor_and_noise_filters() {
    let params = PlantParams::default();
    let model = PlantModel::new(&params).unwrap();
    let (a, capa, n) = (params.actuator, params.capa, params.noise);
    for f in freqs() {
        let imp = Imp::new(&params.stage, f);
        let s = imp.s();
        let wi = 2.0 * PI * a.current_bandwidth_hz;
        let h_i =
            a.current_gain_a_per_v * wi * wi / (s * s + 2.0 * a.current_damping * wi * s + wi * wi);
        let wc = 2.0 * PI * capa.bandwidth_hz;
        let h_capa = capa.sensitivity_v_per_m * wc * wc / (s * s + 2f64.sqrt() * wc * s + wc * wc);
        let g = model.sys.freq_response(2.0 * PI * f).unwrap();
        let want = h_i * a.kt_n_per_a * imp.x2_per_motor_force(C::new(0.0, 0.0)) * h_capa;
        close(
            g[(output::SENSOR_V, input::COMMAND_V)],
            want,
            "command→sensor",
            f,
        );
        close(
            g[(output::TOOL_M, input::CUTTING_FORCE_N)],
            imp.x1_per_cut_force(C::new(0.0, 0.0)),
            "F_cut→tool",
            f,
        );
        // Base: Wg(s)·Butterworth roll-off → mechanics (DESIGN.md noise table).
        let eps = 2.0 * PI * 0.1;
        let wb = 2.0 * PI * n.base_rolloff_hz;
        let wg = n.base_m_per_rt_hz * (s + 2000.0 * PI) / (s + eps) * wb * wb
            / (s * s + 2f64.sqrt() * wb * s + wb * wb);
        close(
            g[(output::TOOL_M, input::BASE_WHITE)],
            wg * imp.tool_rel_per_base(),
            "w_g→tool",
            f,
        );
        // Current noise: Wi(s)·K_T → force.
        let w = 2.0 * PI * 7748.0;
        let wi_f = n.current_a_per_rt_hz * (s * s + 0.1 * w * s + w * w)
            / (s * s + 0.005 * w * s + w * w)
            * (s + 200.0 * PI)
            / (s + eps);
        close(
            g[(output::MOTOR_FORCE_N, input::CURRENT_WHITE)],
            wi_f * a.kt_n_per_a,
            "w_i→force",
            f,
        );
    }
}

#[test]
fn static_deflection_of_the_spring_network() {
    let p = StageParams::THESIS;
    let mech = mechanics(&p);
    let g = mech.freq_response(0.0).unwrap();
    // A constant motor force loads k2 and k3 in series (k4's mass is free, k5 = 0).
    let x2 = 1.0 / p.k2_n_per_m + 1.0 / p.k3_n_per_m;
    assert!((g[(1, 0)].re - x2).abs() < 1e-12 * x2);
    // A cutting force adds the shank k1 in series.
    let x1 = x2 + 1.0 / p.k1_n_per_m;
    assert!((g[(0, 1)].re - x1).abs() < 1e-12 * x1);
}

#[test]
fn static_gain_from_the_dac_to_the_tool() {
    // The full model (current loop, mechanics) at DC, for both stages, against the closed form
    // the machine protection's retract uses.
    for params in [PlantParams::default(), PlantParams::heavy()] {
        let model = PlantModel::new(&params).unwrap();
        let g = model.sys.freq_response(0.0).unwrap();
        let want = params.dc_gain_m_per_v();
        for out in [output::TOOL_M, output::GAP_M] {
            let got = g[(out, input::COMMAND_V)].re;
            assert!((got - want).abs() < 1e-9 * want, "{got} vs {want}");
        }
        // 0.167 mm/V on the prototype: K_T / (k2 ∥-series k3) = 3.6658 / 21 955 N/m.
        assert!((want - 1.6697e-4).abs() < 1e-7, "{want}");
    }
}

/// Natural frequencies (Hz) of the mechanics, ascending.
fn modes(p: &StageParams) -> Vec<f64> {
    let mech = mechanics(p);
    let mut f: Vec<f64> = mech
        .a
        .complex_eigenvalues()
        .iter()
        .filter(|l| l.im > 0.0)
        .map(|l| l.norm() / (2.0 * PI))
        .collect();
    f.sort_by(f64::total_cmp);
    f
}

#[test]
fn suspension_and_tool_modes() {
    let p = StageParams::THESIS;
    let f = modes(&p);
    // Suspension: the moving mass (m1 + m2 + m4) on k2 in series with k3: ≈ 82 Hz.
    let k_eff = 1.0 / (1.0 / p.k2_n_per_m + 1.0 / p.k3_n_per_m);
    let suspension = (k_eff / p.suspended_mass_kg()).sqrt() / (2.0 * PI);
    assert!((suspension - 82.4).abs() < 0.5, "{suspension}");
    let lowest = f[0];
    assert!(
        (lowest / suspension - 1.0).abs() < 0.02,
        "lowest mode {lowest} Hz vs {suspension} Hz"
    );
    // Tool mode near 11.7 kHz (§5.7.4); m1 against m2 raises √(k1/m1) by √(1 + m1/m2).
    let tool = f
        .iter()
        .copied()
        .find(|x| (10e3..14e3).contains(x))
        .expect("a tool mode");
    let two_body = (p.k1_n_per_m * (1.0 / p.m1_kg + 1.0 / p.m2_kg)).sqrt() / (2.0 * PI);
    assert!((tool / two_body - 1.0).abs() < 0.01, "{tool} vs {two_body}");
    assert!((tool / 11.7e3 - 1.0).abs() < 0.03, "tool mode {tool} Hz");
}

/// The anti-aliasing stage multiplies both converter channels by `1/(1 + s/ω_a)` and leaves
/// every other output alone.
#[test]
fn anti_aliasing_stage_is_a_first_order_low_pass_on_both_channels() {
    let plain = PlantParams::heavy();
    let mut filtered = plain;
    filtered.adc.anti_alias_hz = 30e3;
    let (a, b) = (
        PlantModel::new(&plain).unwrap(),
        PlantModel::new(&filtered).unwrap(),
    );
    for f in freqs() {
        let (ga, gb) = (
            a.sys.freq_response(2.0 * PI * f).unwrap(),
            b.sys.freq_response(2.0 * PI * f).unwrap(),
        );
        let lp = C::new(1.0, 0.0) / C::new(1.0, f / 30e3);
        for out in [output::SENSOR_V, output::ACCEL_V] {
            let (got, want) = (
                gb[(out, input::COMMAND_V)],
                ga[(out, input::COMMAND_V)] * lp,
            );
            close(got, want, "anti-aliased channel", f);
        }
        close(
            gb[(output::TOOL_M, input::COMMAND_V)],
            ga[(output::TOOL_M, input::COMMAND_V)],
            "tool",
            f,
        );
    }
}
