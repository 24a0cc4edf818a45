//! NumPy `.npy` (format 1.0–3.0): a 2-D array of `f8` or `f4`, either byte order, C or
//! Fortran order, read as an image (row 0 at +y: a y-up array, as prysm's, is flipped with
//! `np.flipud` before saving); NaN is no data. The file states neither unit nor pitch.

use super::Raw;

/// Decodes an `.npy` file's bytes.
pub(super) fn read(b: &[u8]) -> Result<Raw, String> {
    if b.len() < 10 || &b[..6] != b"\x93NUMPY" {
        return Err("not a NumPy .npy file (no \\x93NUMPY magic)".into());
    }
    let (len, start) = match b[6] {
        1 => (usize::from(u16::from_le_bytes([b[8], b[9]])), 10),
        2 | 3 if b.len() >= 12 => (u32::from_le_bytes([b[8], b[9], b[10], b[11]]) as usize, 12),
        v => return Err(format!(".npy format version {v} (allowed 1, 2, 3)")),
    };
    let header = b
        .get(start..start + len)
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or("a truncated or non-text .npy header")?;
    let value = |key: &str| -> Option<&str> {
        let at = header.find(&format!("'{key}'"))? + key.len() + 2;
        Some(
            header[at..]
                .trim_start()
                .trim_start_matches(':')
                .trim_start(),
        )
    };
    let descr = value("descr")
        .and_then(|v| v.strip_prefix('\''))
        .and_then(|v| v.split('\'').next())
        .ok_or("no 'descr' in the .npy header")?;
    let (big, size) = match descr {
        "<f8" => (false, 8),
        ">f8" => (true, 8),
        "<f4" => (false, 4),
        ">f4" => (true, 4),
        d => {
            return Err(format!(
                "dtype '{d}' (allowed: f8 or f4, either byte order)"
            ))
        }
    };
    let fortran = value("fortran_order").is_some_and(|v| v.starts_with("True"));
    let shape: Vec<usize> = value("shape")
        .and_then(|v| v.strip_prefix('('))
        .and_then(|v| v.split(')').next())
        .map(|v| v.split(',').filter_map(|d| d.trim().parse().ok()).collect())
        .ok_or("no 'shape' in the .npy header")?;
    let [rows, cols] = shape[..] else {
        return Err(format!(
            "an array of shape {shape:?} (a 2-D array expected)"
        ));
    };
    super::check_size(rows, cols)?;
    let data = &b[start + len..];
    if data.len() < rows * cols * size {
        return Err(format!(
            "truncated: {} × {} values of {size} bytes need {} bytes, {} present",
            rows,
            cols,
            rows * cols * size,
            data.len()
        ));
    }
    let value_at = |k: usize| -> f64 {
        let c = &data[k * size..(k + 1) * size];
        match (size, big) {
            (8, false) => f64::from_le_bytes(c.try_into().unwrap_or_default()),
            (8, true) => f64::from_be_bytes(c.try_into().unwrap_or_default()),
            (_, false) => f64::from(f32::from_le_bytes(c.try_into().unwrap_or_default())),
            (_, true) => f64::from(f32::from_be_bytes(c.try_into().unwrap_or_default())),
        }
    };
    let heights = (0..rows * cols)
        .map(|i| {
            let (r, c) = (i / cols, i % cols);
            let v = value_at(if fortran { c * rows + r } else { i });
            if v.is_finite() {
                v
            } else {
                f64::NAN
            }
        })
        .collect();
    Ok(Raw {
        rows,
        cols,
        heights,
        unit_m: None,
        pitch_m: None,
        wavelength_m: None,
    })
}
