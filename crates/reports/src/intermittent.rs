//! `intermittent.csv` and `intermittent.json` of the intermittent-cut study.

use std::fmt::Write as _;
use std::path::Path;
use studies::report::{data, ReportError, Written};

/// `intermittent.csv` and `intermittent.json`: the Ka table of the intermittent cut.
pub fn write(rows: &[studies::intermittent::KaRow], dir: &Path) -> Result<Written, ReportError> {
    let mut csv = String::from(
        "ka_v_per_v,pid_scale,peak_following_error_m,edge_form_error_m,following_rms_m\n",
    );
    for r in rows {
        writeln!(
            csv,
            "{},{:.6},{:.6e},{:.6e},{:.6e}",
            r.ka, r.pid_scale, r.peak_following_error_m, r.edge_form_error_m, r.following_rms_m
        )
        .unwrap();
    }
    data(
        dir,
        "intermittent",
        "the §7.6 intermittent cut per acceleration gain (servo intermittent-cut)",
        &csv,
        rows,
    )
}
