//! A comma-separated grid, row 0 at +y and column 0 at −x; an empty cell or `nan` is no data.
//! A first line `# heights in UNIT, …, pitch P mm` states the unit (m, mm, um, nm) and the
//! pitch; fts-servo's sag grids (`# … as sag … in mm … pitch P mm`, `servo toolpath`'s
//! `part_error.csv`) are read as heights `−sag`. Without such a line the options give both.

use super::Raw;
use crate::map::LengthUnit;

/// Decodes a CSV grid's text.
pub(super) fn read(text: &str) -> Result<Raw, String> {
    let mut lines = text.lines().peekable();
    let (mut unit_m, mut pitch_m) = (None, None);
    let mut sign = 1.0;
    if let Some(head) = lines.peek().and_then(|l| l.strip_prefix('#')) {
        let words: Vec<&str> = head.split([' ', ',']).filter(|w| !w.is_empty()).collect();
        let after = |key: &str| {
            let at = words.iter().position(|w| *w == key)?;
            Some(&words[at + 1..])
        };
        unit_m = after("in")
            .and_then(|rest| rest.first())
            .and_then(|u| LengthUnit::parse(u))
            .map(LengthUnit::metres);
        pitch_m = match after("pitch") {
            Some([p, unit, ..]) => {
                let unit =
                    LengthUnit::parse(unit).ok_or("the header's pitch has no unit (pitch P mm)")?;
                let p: f64 = p.parse().map_err(|_| format!("the header's pitch '{p}'"))?;
                Some([p * unit.metres(); 2])
            }
            Some(_) => return Err("the header's pitch has no unit (pitch P mm)".into()),
            None => None,
        };
        if words.contains(&"sag") {
            sign = -1.0;
        }
        lines.next();
    }
    let mut heights = Vec::new();
    let mut cols = 0usize;
    let mut rows = 0usize;
    for (n, line) in lines.enumerate() {
        if line.trim().is_empty() || line.starts_with('#') {
            continue;
        }
        let row: Vec<f64> = line
            .split(',')
            .map(|c| match c.trim() {
                "" | "nan" | "NaN" | "NAN" => Ok(f64::NAN),
                v => v
                    .parse::<f64>()
                    .map(|v| sign * v)
                    .map_err(|_| format!("line {}: cell '{v}' is not a number", n + 2)),
            })
            .collect::<Result<_, _>>()?;
        if rows == 0 {
            cols = row.len();
        } else if row.len() != cols {
            return Err(format!(
                "line {}: {} cells (the first row has {cols})",
                n + 2,
                row.len()
            ));
        }
        rows += 1;
        if rows.saturating_mul(cols) > super::MAX_PIXELS {
            return Err(format!("more than {} pixels", super::MAX_PIXELS));
        }
        heights.extend(row);
    }
    Ok(Raw {
        rows,
        cols,
        heights,
        unit_m,
        pitch_m,
        wavelength_m: None,
    })
}
