//! Writing a map as a Zygo `XYZ Data File - Format 1` (the text format every Zygo instrument
//! exports and [`super::read_map`] reads back): heights in µm, `No Data` where there is none.

use crate::map::MeasuredMap;
use std::fmt::Write as _;

/// `map` as the text of a Zygo `.xyz` file.
pub fn to_zygo_xyz(map: &MeasuredMap) -> String {
    let (w, h) = (map.cols, map.rows);
    let wavelength = map.wavelength_m.unwrap_or(632.8e-9);
    let mut s = String::with_capacity(w * h * 24 + 1024);
    let header = [
        "Zygo XYZ Data File - Format 1".to_string(),
        "0 0 0 0 \"fts-servo simulated instrument\"".into(),
        "0 0 0 0 0 0".into(),
        format!("0 0 {w} {h}"),
        "\"\"".into(),
        "\"\"".into(),
        "\"\"".into(),
        format!("0 0.5 {wavelength:e} 0 1 0 {:e} 0", map.pitch_m[0]),
        format!("{w} {h} 0 0 0 0 \"\""),
        "0 0 0 0 0 0 0 0 0 0".into(),
        "1 1 20 2 0 0 0 0 0".into(),
        "0 \"\"".into(),
        "1 0".into(),
        "\"\"".into(),
        "#".into(),
    ];
    for line in header {
        s += &line;
        s.push('\n');
    }
    for (i, v) in map.heights_m.iter().enumerate() {
        let (r, c) = (i / w, i % w);
        if v.is_finite() {
            let _ = writeln!(s, "{c} {r} {:.7}", v * 1e6);
        } else {
            let _ = writeln!(s, "{c} {r} No Data");
        }
    }
    s += "#\n";
    s
}
