//! `spindle.csv`, `spindle.json` and the profile plots of the spindle error separation.

use crate::plot::{Figure, Series};
use crate::plot_files;
use std::fmt::Write as _;
use std::path::Path;
use studies::report::{to_json, write_files, ReportError, Written};

/// `spindle.json`, `spindle.csv` (one revolution: truth and every estimate),
/// `harmonic_weighting.csv`, and the pictures `harmonic_weighting` (Fig D-2), `artefact`
/// (Fig D-7) and `x_motion` (Fig D-8).
pub fn write(
    r: &studies::spindle::SpindleReport,
    p: &studies::spindle::SpindleProfiles,
    max_harmonic: usize,
    dir: &Path,
) -> Result<Written, ReportError> {
    let sets = p.sets.len();
    let mut csv = String::from("angle_deg,artefact_true_m,x_true_m,y_true_m");
    for i in 1..=sets {
        write!(
            csv,
            ",artefact_set{i}_m,artefact_set{i}_modified_m,x_set{i}_m"
        )
        .unwrap();
    }
    csv.push_str(",artefact_synthesised_m,x_synthesised_m,y_synthesised_m\n");
    for (j, a) in p.angle_deg.iter().enumerate() {
        write!(
            csv,
            "{a:.4},{:.6e},{:.6e},{:.6e}",
            p.truth[0][j], p.truth[1][j], p.truth[2][j]
        )
        .unwrap();
        for (s, m) in p.sets.iter().zip(&p.modified) {
            write!(
                csv,
                ",{:.6e},{:.6e},{:.6e}",
                s.artefact[j], m.artefact[j], s.x[j]
            )
            .unwrap();
        }
        let y = &p.synthesised;
        writeln!(csv, ",{:.6e},{:.6e},{:.6e}", y.artefact[j], y.x[j], y.y[j]).unwrap();
    }
    let ks: Vec<f64> = (2..=max_harmonic).map(|k| k as f64).collect();
    let h: Vec<Vec<f64>> = p
        .sets
        .iter()
        .map(|s| {
            (2..=max_harmonic)
                .map(|k| design::spindle::harmonic_weighting(&s.angles, k).norm())
                .collect()
        })
        .collect();
    let mut hcsv = String::from("harmonic_upr");
    for i in 1..=sets {
        write!(hcsv, ",abs_h_set{i}").unwrap();
    }
    hcsv.push('\n');
    for (i, k) in ks.iter().enumerate() {
        write!(hcsv, "{k}").unwrap();
        for hs in &h {
            write!(hcsv, ",{:.6}", hs[i]).unwrap();
        }
        hcsv.push('\n');
    }
    let mut out = write_files(
        dir,
        &[
            ("spindle.csv", &csv),
            (
                "spindle.json",
                &to_json(
                    "spindle error separation, thesis Appendix D (servo spindle-errors)",
                    "report",
                    r,
                ),
            ),
            ("harmonic_weighting.csv", &hcsv),
        ],
    )?;
    let nm = |v: &[f64]| v.iter().map(|x| x * 1e9).collect::<Vec<f64>>();
    let weighting = Figure {
        title: "Harmonic weighting |H(k)| of the three angle sets (thesis Fig D-2)".into(),
        x_label: "harmonic (UPR)".into(),
        y_label: "|H(k)|".into(),
        log_x: false,
        log_y: false,
        series: h
            .into_iter()
            .enumerate()
            .map(|(i, y)| Series::line(format!("angle set #{}", i + 1), ks.clone(), y))
            .collect(),
    };
    let mut artefact = vec![Series::line(
        "true artefact",
        p.angle_deg.clone(),
        nm(&p.truth[0]),
    )];
    artefact.extend(p.sets.iter().enumerate().map(|(i, s)| {
        Series::line(
            format!("set #{} alone", i + 1),
            p.angle_deg.clone(),
            nm(&s.artefact),
        )
    }));
    artefact.push(Series::line(
        "synthesised",
        p.angle_deg.clone(),
        nm(&p.synthesised.artefact),
    ));
    let artefact = Figure {
        title: "Separated artefact form (thesis Fig D-7)".into(),
        x_label: "spindle angle (°)".into(),
        y_label: "form (nm)".into(),
        log_x: false,
        log_y: false,
        series: artefact,
    };
    let x_motion = Figure {
        title: "Synchronous X radial error motion (thesis Fig D-8)".into(),
        x_label: "spindle angle (°)".into(),
        y_label: "X (nm)".into(),
        log_x: false,
        log_y: false,
        series: vec![
            Series::line("true", p.angle_deg.clone(), nm(&p.truth[1])),
            Series::line("synthesised", p.angle_deg.clone(), nm(&p.synthesised.x)),
        ],
    };
    out.note = plot_files(
        &[
            (weighting, "harmonic_weighting"),
            (artefact, "artefact"),
            (x_motion, "x_motion"),
        ],
        dir,
        &mut out.files,
    );
    Ok(out)
}
