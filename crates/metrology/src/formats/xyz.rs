//! Zygo `XYZ Data File - Format 1` text: the fourteen lines of MetroPro's ASCII header
//! (line 4: the phase origin and size in pixels; line 8: the wavelength and the camera
//! resolution, m per pixel), `#`, then one `x y z` line per pixel — `x, y` the camera pixel
//! (origin included), `z` the height in µm or the words `No Data` — ending at `#`.

use super::Raw;

/// Decodes an `.xyz` file's text.
pub(super) fn read(text: &str) -> Result<Raw, String> {
    let lines: Vec<&str> = text.lines().collect();
    if !lines
        .first()
        .is_some_and(|l| l.trim_start().starts_with("Zygo XYZ Data File"))
    {
        return Err("not a Zygo XYZ file (line 1 is not 'Zygo XYZ Data File - Format 1')".into());
    }
    let marker = lines
        .iter()
        .take(64)
        .position(|l| l.trim() == "#")
        .ok_or("no '#' after the header in its first 64 lines")?;
    if marker < 13 {
        return Err(format!("the header has {marker} lines (14 expected)"));
    }
    let numbers = |line: usize| -> Vec<f64> {
        lines[line]
            .split_whitespace()
            .map_while(|w| w.parse::<f64>().ok())
            .collect()
    };
    let phase = numbers(3);
    let [ox, oy, w, h] = phase[..] else {
        return Err(format!(
            "line 4 '{}': expected the phase origin and size (4 integers)",
            lines[3]
        ));
    };
    let (cols, rows) = (w as usize, h as usize);
    super::check_size(rows, cols)?;
    let optics = numbers(7);
    let wavelength_m = optics.get(2).copied().filter(|v| *v > 0.0);
    let res = optics.get(6).copied().filter(|v| v.is_finite() && *v > 0.0);
    let mut heights = vec![f64::NAN; rows * cols];
    for (n, line) in lines.iter().enumerate().skip(marker + 1) {
        let line = line.trim();
        if line == "#" {
            break;
        }
        if line.is_empty() {
            continue;
        }
        let bad = || {
            format!(
                "line {}: '{line}' (expected 'x y height_um' or 'x y No Data')",
                n + 1
            )
        };
        let mut words = line.split_whitespace();
        let mut index = || words.next().and_then(|v| v.parse::<f64>().ok());
        let (x, y) = (index().ok_or_else(bad)?, index().ok_or_else(bad)?);
        let rest: Vec<&str> = words.collect();
        let (c, r) = (x - ox, y - oy);
        if !(c >= 0.0 && r >= 0.0 && (c as usize) < cols && (r as usize) < rows) {
            return Err(format!(
                "line {}: pixel ({x}, {y}) outside the phase rectangle",
                n + 1
            ));
        }
        let at = r as usize * cols + c as usize;
        match rest[..] {
            ["No", "Data"] => {}
            [z] => {
                heights[at] = z
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(bad)?
            }
            _ => return Err(bad()),
        }
    }
    Ok(Raw {
        rows,
        cols,
        heights,
        unit_m: Some(1e-6),
        pitch_m: res.map(|p| [p, p]),
        wavelength_m,
    })
}
