//! `budget.csv`, `budget.json` and the PSD and CAS plots of the error budget (Fig 5-15, 5-16).

use crate::plot::{Figure, Series};
use crate::plot_files;
use loop_model::closed_loop::SOURCES;
use std::fmt::Write as _;
use std::path::Path;
use studies::budget::Budget;
use studies::report::{data, ReportError, Written};

/// What `budget.json` holds: the budget, what it was made for (the plant and rate, and the
/// controller) and the loop's stability margins.
#[derive(serde::Serialize)]
struct BudgetFile<'a> {
    made_for: &'a run_config::MadeFor,
    controller: &'a str,
    margins: Option<&'a design::loops::Margins>,
    #[serde(flatten)]
    budget: &'a Budget,
}

/// `budget.csv`, `budget.json` (with what it was made for: `made_for`, the plant and rate;
/// `controller`, its description; the loop's `margins` where they exist),
/// `budget_psd.{png,svg}`, `budget_cas.{png,svg}`.
pub fn write(
    b: &Budget,
    title: &str,
    (made_for, controller): (&run_config::MadeFor, &str),
    margins: Option<&design::loops::Margins>,
    dir: &Path,
) -> Result<Written, ReportError> {
    let mut csv = String::from("freq_hz");
    for (name, _) in SOURCES {
        let n = name.replace(' ', "_");
        write!(csv, ",following_psd_{n}_m2_per_hz,true_psd_{n}_m2_per_hz").unwrap();
    }
    csv.push_str(",following_cas_m,true_cas_m\n");
    for (i, f) in b.freq_hz.iter().enumerate() {
        write!(csv, "{f:.6e}").unwrap();
        for k in 0..SOURCES.len() {
            write!(
                csv,
                ",{:.6e},{:.6e}",
                b.following_psd[k][i], b.true_psd[k][i]
            )
            .unwrap();
        }
        writeln!(csv, ",{:.6e},{:.6e}", b.following_cas[i], b.true_cas[i]).unwrap();
    }
    let file = BudgetFile {
        made_for,
        controller,
        margins,
        budget: b,
    };
    let mut out = data(
        dir,
        "budget",
        "error budget of the loop, thesis §5.7.2 (servo budget)",
        &csv,
        &file,
    )?;
    let nm2 = |v: &Vec<f64>| v.iter().map(|x| x * 1e18).collect::<Vec<f64>>();
    let mut psd_series = vec![
        Series::line(
            "following error, total",
            b.freq_hz.clone(),
            nm2(&studies::budget::total_psd(&b.following_psd)),
        ),
        Series::line(
            "true error, total",
            b.freq_hz.clone(),
            nm2(&studies::budget::total_psd(&b.true_psd)),
        ),
    ];
    for (k, (name, _)) in SOURCES.iter().enumerate() {
        if b.contributions[k].following_rms_m > 1e-3 * b.following_rms_m {
            psd_series.push(Series::line(
                format!("following, {name}"),
                b.freq_hz.clone(),
                nm2(&b.following_psd[k]),
            ));
        }
    }
    let psd = Figure {
        title: format!("Error PSD budget (thesis Fig 5-15) — {title}"),
        x_label: "frequency (Hz)".into(),
        y_label: "PSD (nm²/Hz)".into(),
        log_x: true,
        log_y: true,
        series: psd_series,
    };
    let nm = |v: &Vec<f64>| v.iter().map(|x| x * 1e9).collect::<Vec<f64>>();
    let cas = Figure {
        title: format!("Cumulative amplitude spectrum (eq 5-16) — {title}"),
        x_label: "frequency (Hz)".into(),
        y_label: "CAS (nm RMS)".into(),
        log_x: true,
        log_y: false,
        series: vec![
            Series::line("following error", b.freq_hz.clone(), nm(&b.following_cas)),
            Series::line("true error", b.freq_hz.clone(), nm(&b.true_cas)),
        ],
    };
    out.note = plot_files(
        &[(psd, "budget_psd"), (cas, "budget_cas")],
        dir,
        &mut out.files,
    );
    Ok(out)
}
