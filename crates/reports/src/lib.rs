//! # reports
//!
//! What each study of the `studies` crate writes for a person to look at: its data files
//! (CSV, JSON, through `studies::report`) and its plots (PNG and SVG, drawn with plotters).
//! The `servo` binary writes them; the studies' compute core and the Python wheel do not
//! compile any of it.

pub mod budget;
pub mod design_space;
pub mod fit;
pub mod form;
pub mod frf;
pub mod intermittent;
pub mod measured;
pub mod plot;
pub mod spectrum;
pub mod spindle;
pub mod stiffness;
pub mod sweep;
pub mod toolpath;

use plot::Figure;
use std::path::{Path, PathBuf};

/// Writes the plots, or returns the reason they were skipped (no font) as a note.
pub(crate) fn plot_files(
    figs: &[(Figure, &str)],
    dir: &Path,
    written: &mut Vec<PathBuf>,
) -> Option<String> {
    figs.iter()
        .find_map(|(fig, stem)| plot_file(fig, &dir.join(stem), written))
}

/// Writes one drawing as `stem.png` and `stem.svg` (their paths go to `written`), or returns
/// the reason it was skipped as a note.
pub(crate) fn plot_file<D: plot::Drawing>(
    item: &D,
    stem: &Path,
    written: &mut Vec<PathBuf>,
) -> Option<String> {
    match plot::write(item, stem) {
        Ok(paths) => {
            written.extend(paths);
            None
        }
        Err(e) => Some(e.to_string()),
    }
}
