//! Zygo MetroPro binary `.dat` (MetroPro Reference Guide, ch. 12): a big-endian header, the
//! intensity frames (u16), then the connected phase (i32, image order), heights
//! `phase · W·S·O / R` m for wavelength W, interferometric scale factor S, obliquity O and
//! the phase resolution R; values ≥ 2 147 483 640 are no data.

use super::Raw;

/// The header's magic number.
const MAGIC: u32 = 0x881B_036F;

/// Phase values at or above this are no data.
const INVALID_PHASE: i32 = 2_147_483_640;

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn f32_at(b: &[u8], at: usize) -> f64 {
    f64::from(f32::from_bits(u32_at(b, at)))
}

/// Decodes a `.dat` file's bytes.
pub(super) fn read(b: &[u8]) -> Result<Raw, String> {
    if b.len() < 834 || u32_at(b, 0) != MAGIC {
        return Err("not a MetroPro .dat file (no header magic 0x881B036F)".into());
    }
    let header = u32_at(b, 6) as usize;
    if !(834..=65_536).contains(&header) || header > b.len() {
        return Err(format!(
            "header size {header} bytes (allowed 834 … 65536, within the file)"
        ));
    }
    let (iw, ih) = (usize::from(u16_at(b, 52)), usize::from(u16_at(b, 54)));
    let buckets = usize::from(u16_at(b, 56)).max(1);
    let (cols, rows) = (usize::from(u16_at(b, 68)), usize::from(u16_at(b, 70)));
    super::check_size(rows, cols)?;
    let intensity_bytes = iw * ih * buckets * 2;
    let start = header + intensity_bytes;
    let need = start + rows * cols * 4;
    if b.len() < need {
        return Err(format!(
            "truncated: the phase data needs {need} bytes, the file has {}",
            b.len()
        ));
    }
    let (s, w, o) = (f32_at(b, 164), f32_at(b, 168), f32_at(b, 176));
    let resolution = match u16_at(b, 218) {
        0 => 4096.0,
        1 => 32768.0,
        2 => 131_072.0,
        r => return Err(format!("phase resolution code {r} (allowed 0, 1, 2)")),
    };
    for (name, v) in [
        ("wavelength", w),
        ("scale factor", s),
        ("obliquity factor", o),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(format!("header {name} {v} (must be positive)"));
        }
    }
    let lateral = f32_at(b, 184);
    let per_count = w * s * o / resolution;
    let heights = b[start..need]
        .chunks_exact(4)
        .map(|c| {
            let v = i32::from_be_bytes([c[0], c[1], c[2], c[3]]);
            if v >= INVALID_PHASE {
                f64::NAN
            } else {
                f64::from(v) * per_count
            }
        })
        .collect();
    Ok(Raw {
        rows,
        cols,
        heights,
        unit_m: Some(1.0),
        pitch_m: (lateral.is_finite() && lateral > 0.0).then_some([lateral, lateral]),
        wavelength_m: Some(w),
    })
}
