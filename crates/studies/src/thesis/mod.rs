//! `servo thesis`: every headline number of thesis Chapters 5–8 beside the value this model
//! computes for the same experiment, each computed afresh (budgets, sweeps, syntheses and
//! simulations), with the reason for any difference, and the variants tried on the one gap
//! the model does not close (the Ka 0 → 4 improvement of §7.6.2). The book's thesis map
//! (`docs/src/thesis-map.md`) shows this output.

mod ka_gap;

pub use ka_gap::KaVariant;

use crate::budget::Budget;
use crate::error::StudyError;
use crate::form::run_machining;
use crate::sweep::{scale_for_bandwidth, scaled, thesis_sweeps, SweepTuning};
use plant_sim::params::StageParams;
use run_config::presets::SurfacePreset;
use run_config::{ControllerKind, Loaded, Machining, Scenario};
use runner::run::RunOptions;
use runner::stop::StopRequest;
use runner::Plan;
use serde::Serialize;

/// One compared number.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// What is compared.
    pub quantity: &'static str,
    /// Where the thesis states it.
    pub section: &'static str,
    /// Its unit.
    pub unit: &'static str,
    /// The thesis's value.
    pub thesis: f64,
    /// This model's.
    pub ours: f64,
    /// Why they differ (or why they agree).
    pub reason: String,
}

impl Row {
    /// ours / thesis.
    pub fn ratio(&self) -> f64 {
        self.ours / self.thesis
    }
}

/// The default configuration on `stage` without accelerometer noise (Chapters 5 and 6 have
/// no accelerometer), `rate_hz`.
fn base(stage: StageParams, rate_hz: f64) -> Loaded {
    let mut l = Loaded::default();
    l.config.plant.stage = stage;
    l.config.plant.noise.accel = false;
    l.config.plant.timing.servo_rate_hz = rate_hz;
    l
}

/// `plan` with its PID scaled to the −3 dB bandwidth `hz`.
fn pid_at(plan: &Plan, hz: f64) -> Result<Plan, StudyError> {
    let (k, _) = scale_for_bandwidth(plan, hz)?
        .ok_or(StudyError::BandwidthUnreachable { bandwidth_hz: hz })?;
    scaled(plan, k)
}

fn nm(m: f64) -> f64 {
    m * 1e9
}

/// Runs a machining plan without recording and returns its form report.
fn machine(l: &Loaded) -> Result<crate::form::FormReport, StudyError> {
    let stop = StopRequest::new();
    let (_, a) = run_machining(
        &Plan::new(l)?,
        RunOptions {
            out: None,
            stop: &stop,
            progress: &mut |_, _| {},
            digest: false,
        },
    )?;
    Ok(a.report())
}

/// The comparison and the Ka-gap variants.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    /// The thesis's numbers beside the model's.
    pub rows: Vec<Row>,
    /// The intermittent cut with one element changed at a time (see the module doc).
    pub ka_gap: Vec<KaVariant>,
}

/// `base` with the sensor channel's first-order anti-aliasing stage at `corner_hz` and the
/// transport delay `delay_s`.
fn with_front_end(mut l: Loaded, corner_hz: f64, delay_s: f64) -> Loaded {
    l.config.plant.adc.anti_alias_hz = corner_hz;
    l.config.plant.timing.delay_s = delay_s;
    l
}

/// The highest bandwidth of the heavy stage's re-tuned sweep over `crossovers`, Hz.
fn highest_stable(l: &Loaded, crossovers: &[f64]) -> Result<f64, StudyError> {
    let s = crate::sweep::sweep(
        &Plan::new(l)?,
        "0.174 kg",
        crossovers,
        SweepTuning::Retuned,
        None,
        &mut |_, _| {},
    )?;
    Ok(s.points.iter().map(|p| p.bandwidth_hz).fold(0.0, f64::max))
}

/// Computes the comparison; `progress` gets (done, total) steps.
pub fn comparison(progress: &mut dyn FnMut(usize, usize)) -> Result<Comparison, StudyError> {
    const STEPS: usize = 7;
    let mut rows = Vec::new();
    // §5.7.4: the calibration point.
    progress(0, STEPS);
    let heavy = pid_at(
        &Plan::new(&base(StageParams::THESIS_HEAVY, 199.6e3))?,
        468.0,
    )?;
    let b = Budget::new(&heavy.closed_loop, 64)?;
    rows.push(Row {
        quantity: "following error, 0.174 kg at 468 Hz",
        section: "§5.7.4",
        unit: "nm RMS",
        thesis: 0.83,
        ours: nm(b.following_rms_m),
        reason: "calibration target: the thesis's measurement, one 20 ms record (noise gains, plant-sim README)".into(),
    });
    rows.push(Row {
        quantity: "true tool error, same loop",
        section: "§5.7.4",
        unit: "nm RMS",
        thesis: 0.23,
        ours: nm(b.true_rms_m),
        reason: "calibration target; the thesis's own model estimate (\"estimated … by the model prediction\"), not a measurement".into(),
    });
    // Fig 5-14, re-tuned at each crossover as §5.7.3 did.
    progress(1, STEPS);
    let crossovers = [
        200.0, 250.0, 300.0, 350.0, 400.0, 468.0, 550.0, 650.0, 750.0, 874.0, 1000.0, 1450.0,
        2000.0, 3000.0, 5000.0,
    ];
    let sweeps = thesis_sweeps(
        &Plan::new(&base(StageParams::THESIS, 199.6e3))?,
        &crossovers,
        SweepTuning::Retuned,
        None,
        &mut |_, _| {},
    )?;
    for (s, thesis, quantity) in [
        (&sweeps[0], 874.0, "optimal bandwidth, 0.074 kg"),
        (&sweeps[1], 468.0, "optimal bandwidth, 0.174 kg"),
    ] {
        rows.push(Row {
            quantity,
            section: "§5.7.3 Fig 5-14",
            unit: "Hz",
            thesis,
            ours: s.optimum_following.bandwidth_hz,
            reason: {
                let o = &s.optimum_following;
                let inside = thesis >= o.flat_hz[0] && thesis <= o.flat_hz[1];
                format!(
                    "PID re-tuned per crossover; the lowest following error is at {} — a flat optimum; the thesis's {thesis:.0} Hz lies {} that band",
                    o.describe(),
                    if inside { "inside" } else { "outside" }
                )
            },
        });
    }
    let stable_to = sweeps[1]
        .points
        .iter()
        .map(|p| p.bandwidth_hz)
        .fold(0.0, f64::max);
    // What the thesis's converter front end could do to that limit and to the noise.
    let heavy_base = base(StageParams::THESIS_HEAVY, 199.6e3);
    let measured_delay = highest_stable(
        &with_front_end(heavy_base.clone(), 0.0, 3.5e-6),
        &crossovers,
    )?;
    let slow_filter = highest_stable(
        &with_front_end(heavy_base.clone(), 2e3, 3.5e-6),
        &crossovers,
    )?;
    let filtered = pid_at(
        &Plan::new(&with_front_end(heavy_base, 30e3, 3.159e-6))?,
        468.0,
    )?;
    let filtered_following = Budget::new(&filtered.closed_loop, 64)?.following_rms_m;
    rows.push(Row {
        quantity: "highest stable bandwidth, 0.174 kg (ours: at least — the sweep ends at a 5 kHz crossover)",
        section: "§5.7.3",
        unit: "Hz",
        thesis: 1600.0,
        ours: stable_to,
        reason: format!(
            "not reproduced. The thesis names the cause: \"irregular dynamics at around 1.6 kHz\" (§6.4.2, footnote 13), a structural resonance at 1645 Hz that \"caused troubles when the PID gains are further increased\" (§6.3.2); the four-mass model has no mode there. The measured 3.5 µs delay (§4.4.4) instead of 3.159 µs: still stable to {:.0} Hz. The anti-aliasing filter (§4.4.4, §4.5.2: first order, corner not printed) stays off by default: a 2 kHz corner would set a limit (stable to {:.0} Hz), but the thesis's loop test sees the phase fall only beyond 20 kHz; a 30 kHz corner changes the 468 Hz following error by {:+.1} %",
            measured_delay,
            slow_filter,
            (filtered_following / b.following_rms_m - 1.0) * 100.0
        ),
    });
    // §6.4.2 at 20 kHz: the H2 controller and a PID of similar bandwidth.
    progress(2, STEPS);
    let light20 = Plan::new(&base(StageParams::THESIS, 20e3))?;
    let h2 = crate::synth::h2_design(&light20, 1.0)?;
    let mut ss = light20.config.controller.clone();
    ss.kind = ControllerKind::Ss;
    ss.ss_file = Some("h2.toml".into());
    let h2_loop = light20.with_controller_file(ss, Some(h2.to_toml().into_bytes()))?;
    let pid20 = pid_at(&light20, 1500.0)?;
    let (bh, bp) = (
        Budget::new(&h2_loop.closed_loop, 64)?,
        Budget::new(&pid20.closed_loop, 64)?,
    );
    rows.push(Row {
        quantity: "following error, H2 at 20 kHz",
        section: "§6.4.2",
        unit: "nm RMS",
        thesis: 0.68,
        ours: nm(bh.following_rms_m),
        reason: "the sensor's noise per conversion does not depend on the servo rate, so no controller gets the following error below its ≈ 0.8 nm; the thesis's 0.68 nm is below its own 0.83 nm at 199.6 kHz".into(),
    });
    rows.push(Row {
        quantity: "following error, PID at 1.5 kHz, 20 kHz",
        section: "§6.4.2",
        unit: "nm RMS",
        thesis: 1.19,
        ours: nm(bp.following_rms_m),
        reason: format!(
            "H2 still ahead of the PID, by less: in the model the PID's higher bandwidth costs it {:.0} %, the sensor noise dominating both; the thesis measured 75 % more",
            (bp.following_rms_m / bh.following_rms_m - 1.0) * 100.0
        ),
    });
    // §7.6: the intermittent cut, Kg-scaled PID on the heavy stage, Table 7-3's force.
    progress(3, STEPS);
    let mut cut = base(StageParams::THESIS_HEAVY, 199.6e3);
    cut.config.plant.noise.accel = true;
    cut.config.controller.kg_scaling = true;
    cut.config.scenario =
        run_config::presets::ScenarioKind::IntermittentCut.scenario(&Default::default(), 0.0);
    cut.config.run.duration_s = crate::intermittent::DEFAULT_DURATION_S;
    let ka = crate::intermittent::study(&Plan::new(&cut)?, &[0.0, 4.0])?;
    let (k0, k4) = (&ka[0], &ka[1]);
    let gain = |f: fn(&crate::intermittent::KaRow) -> f64| f(k0) / f(k4);
    let peak_gain = gain(|r| r.peak_following_error_m);
    let edge_gain = gain(|r| r.edge_form_error_m);
    progress(4, STEPS);
    let ka_gap = ka_gap::variants(&cut, k4.pid_scale)?;
    let peak = |i: usize| ka_gap[i].peak_following_nm;
    let chip_gpa = 5.0 * 75e-9 / k0.peak_following_error_m;
    for (quantity, thesis, ours, reason) in [
        (
            "intermittent cut peak following, Ka 0",
            75.0,
            k0.peak_following_error_m,
            format!("force from the chip area at 5 GPa (★, the thesis gives none), not fitted to this number: the peak is linear in it, 75 nm would take {chip_gpa:.1} GPa"),
        ),
        (
            "edge form error, Ka 0",
            106.0,
            k0.edge_form_error_m,
            "here the true tool error where the cut starts; the thesis's is measured on the part by interferometer, averaged over 0.2 mm".to_owned(),
        ),
        (
            "intermittent cut peak following, Ka 4",
            25.0,
            k4.peak_following_error_m,
            format!(
                "the model gains {peak_gain:.1}× from Ka 0 to 4 where the thesis gained 3×, with the PID × 1/Kg = {:.1} of §7.4.1. The variants below show that the PID's scale, not the acceleration loop, sets the peak (Ka 4 alone: {:.1} nm; the PID × 1/Kg alone: {:.1} nm; the PID × 3 with Ka 4: {:.1} nm). The thesis raised its PID \"accordingly\", prints no factor, and found higher gains gave \"ringing noise\" (§7.6.2) and could not be used without Ka (§7.5.3); the model has neither limit, so its Ka 4 loop runs gains the machine could not. Not identified",
                k4.pid_scale,
                peak(2),
                peak(3),
                peak(5)
            ),
        ),
        (
            "edge form error, Ka 4",
            27.0,
            k4.edge_form_error_m,
            format!("{edge_gain:.1}× from Ka 0 to 4 against the thesis's 3.9×, for the same reason"),
        ),
    ] {
        rows.push(Row {
            quantity,
            section: "§7.6.2",
            unit: "nm",
            thesis,
            ours: nm(ours),
            reason,
        });
    }
    // §8.5.4: the sinusoidal grid at the part's edge, three revolutions.
    progress(5, STEPS);
    let mut grid = Loaded::default();
    grid.config.run.duration_s = 3.0;
    grid.config.run.settle_s = Some(0.05);
    grid.config.scenario = Scenario::Machine(Machining::default());
    let g = machine(&grid)?;
    rows.push(Row {
        quantity: "grid motion frequency at the edge",
        section: "§8.5.4",
        unit: "Hz",
        thesis: 200.0,
        ours: g.max_motion_frequency_hz.unwrap_or(f64::NAN),
        reason: "the part's edge radius is chosen from it (31.8 mm; the part size is not printed)"
            .into(),
    });
    rows.push(Row {
        quantity: "grid peak-to-valley at the edge (10 µm nominal)",
        section: "§8.5.4",
        unit: "µm",
        thesis: 11.18,
        ours: g.grid.map_or(f64::NAN, |g| g.machined_pv_x_m * 1e6),
        reason: "the machined amplitude is the closed loop's gain at 200 Hz times the nominal; the real loop peaked more below its resonance".into(),
    });
    // §8.5.1: the flat face, Table 8-2, a 0.3 mm band for the 0.36 × 0.27 mm field.
    progress(6, STEPS);
    let mut flat = Loaded::default();
    let preset = SurfacePreset::Flat;
    let m = Machining {
        surface: run_config::SurfaceConfig::Flat,
        spindle_rpm: preset.spindle_rpm(),
        feed_m_per_rev: preset.feed_m_per_rev(),
        start_radius_m: 20e-3,
        ..Machining::default()
    };
    flat.config.run.duration_s = m.duration_to(20e-3 - 0.3e-3);
    flat.config.scenario = Scenario::Machine(m);
    let r = machine(&flat)?.roughness;
    rows.push(Row {
        quantity: "roughness Ra of the flat face",
        section: "§8.5.1",
        unit: "nm",
        thesis: 1.2,
        ours: r.map_or(f64::NAN, |r| nm(r.surface.ra_radial_m)),
        reason: "feed marks (f²/8R = 1 nm PV) and servo motion only: material, tool edge and the instrument's floor are not modelled".into(),
    });
    progress(STEPS, STEPS);
    Ok(Comparison { rows, ka_gap })
}

/// The comparison as Markdown: the table of numbers, then the Ka-gap variants.
pub fn markdown(c: &Comparison) -> String {
    format!(
        "{}\nThe intermittent cut (§7.6.2, 0.174 kg, Kg-scaled PID, Ha ★ first order at 300 Hz) with one element changed at a time:\n\n{}",
        rows_markdown(&c.rows),
        ka_gap::markdown(&c.ka_gap)
    )
}

/// The numbers as a Markdown table.
fn rows_markdown(rows: &[Row]) -> String {
    let mut s = String::from(
        "| quantity | thesis | ours | ours/thesis | section | why |\n|---|---|---|---|---|---|\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {} {} | {} {} | {:.2} | {} | {} |\n",
            r.quantity,
            sig(r.thesis),
            r.unit,
            sig(r.ours),
            r.unit,
            r.ratio(),
            r.section,
            r.reason
        );
    }
    s
}

/// Three significant digits.
fn sig(v: f64) -> String {
    if !v.is_finite() {
        return "–".into();
    }
    if v == 0.0 {
        return "0".into();
    }
    let digits = (2 - libm::log10(v.abs()).floor() as i32).max(0) as usize;
    format!("{v:.digits$}")
}

/// `thesis.md` (the table) and `thesis.json` in `dir`.
pub fn write(
    comparison: &Comparison,
    dir: &std::path::Path,
) -> Result<crate::report::Written, crate::report::ReportError> {
    crate::report::write_files(
        dir,
        &[
            ("thesis.md", &markdown(comparison)),
            (
                "thesis.json",
                &crate::report::to_json(
                    "the headline numbers of the thesis beside this model (servo thesis)",
                    "comparison",
                    comparison,
                ),
            ),
        ],
    )
}
