//! Zygo Mx `.datx` (HDF5): the first dataset of the group `Data/Surface`, its attributes
//! `Unit` (`NanoMeters`, `MicroMeters`, `Meters`, or `Fringes` with `Wavelength`,
//! `Interferometric Scale Factor` and `Obliquity Factor`) and `No Data` (values at or above it
//! are no data); the lateral resolution from the last group under `Attributes`,
//! `Data Context.Lateral Resolution:Value` (m per pixel), as Mx writes them and prysm reads
//! them. The image is stored in image order (row 0 at +y).

use super::Raw;
use hdf5_reader::{Dataset, Hdf5File};

/// The first element of a numeric attribute of `d`.
fn number(d: &Dataset, name: &str) -> Option<f64> {
    let a = d.attribute(name).ok()?;
    a.read_as_f64()
        .ok()
        .or_else(|| a.read_1d::<f64>().ok()?.first().copied())
        .or_else(|| a.read_1d::<f32>().ok()?.first().map(|v| f64::from(*v)))
}

/// The first string of an attribute of `d`.
fn string(d: &Dataset, name: &str) -> Option<String> {
    let a = d.attribute(name).ok()?;
    a.read_string()
        .ok()
        .or_else(|| a.read_strings().ok()?.into_iter().next())
        .map(|s| s.trim_end_matches('\0').trim().to_string())
}

/// Decodes a `.datx` file's bytes.
pub(super) fn read(bytes: Vec<u8>) -> Result<Raw, String> {
    let file = Hdf5File::from_vec(bytes).map_err(|e| format!("not a readable HDF5 file: {e}"))?;
    let surface = file
        .group("/Data/Surface")
        .and_then(|g| g.datasets())
        .ok()
        .and_then(|d| d.into_iter().next())
        .ok_or("no dataset under /Data/Surface (not a Zygo .datx map)")?;
    let shape = surface.shape().to_vec();
    let [rows, cols] = shape[..] else {
        return Err(format!("/Data/Surface has shape {shape:?} (2-D expected)"));
    };
    let (rows, cols) = (rows as usize, cols as usize);
    super::check_size(rows, cols)?;
    let values = surface
        .read_array::<f64>()
        .map_err(|e| format!("/Data/Surface: {e}"))?;
    let no_data = number(&surface, "No Data").unwrap_or(f64::INFINITY);
    let unit = string(&surface, "Unit").ok_or("/Data/Surface has no 'Unit' attribute")?;
    let wavelength_m = number(&surface, "Wavelength");
    let unit_m = match unit.as_str() {
        "NanoMeters" => 1e-9,
        "MicroMeters" => 1e-6,
        "MilliMeters" => 1e-3,
        "Meters" => 1.0,
        "Fringes" => {
            let w = wavelength_m.ok_or("'Fringes' without a 'Wavelength'")?;
            let s = number(&surface, "Interferometric Scale Factor").unwrap_or(1.0);
            let o = number(&surface, "Obliquity Factor").unwrap_or(1.0);
            w * s * o
        }
        u => {
            return Err(format!(
                "/Data/Surface unit '{u}' (allowed: NanoMeters, MicroMeters, MilliMeters, Meters, Fringes)"
            ))
        }
    };
    let heights = values
        .iter()
        .map(|&v| {
            if v.is_finite() && v < no_data {
                v
            } else {
                f64::NAN
            }
        })
        .collect();
    let pitch = file
        .group("/Attributes")
        .and_then(|g| g.groups())
        .ok()
        .and_then(|g| g.into_iter().last())
        .and_then(|g| {
            let a = g.attribute("Data Context.Lateral Resolution:Value").ok()?;
            a.read_as_f64()
                .ok()
                .or_else(|| a.read_1d::<f64>().ok()?.first().copied())
        })
        .filter(|p| p.is_finite() && *p > 0.0);
    Ok(Raw {
        rows,
        cols,
        heights,
        unit_m: Some(unit_m),
        pitch_m: pitch.map(|p| [p, p]),
        wavelength_m,
    })
}
