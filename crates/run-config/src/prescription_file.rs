//! A surface prescription file (TOML) as an optical designer writes it: Zemax's conventions —
//! sag along +z from the vertex plane, a positive radius bending the surface toward +z,
//! lengths in **mm** — converted to SI (`optics`) when read. Every table is optional
//! and the present ones add up (a base conic plus freeform departures):
//!
//! ```toml
//! aperture_radius_mm = 10.0       # clear aperture on the part
//! decenter_mm = [0.0, 0.0]        # the part's centre on the parent surface (off-axis segment)
//! [base]                          # Zemax "Even Asphere"
//! radius_mm = 250.0               # vertex radius (0: a plane)
//! conic = 0.0
//! even_asphere = [0.0, 1e-8]      # α₁ r² + α₂ r⁴ + …, in mm^(1−2i)
//! [zernike]                       # "Zernike Standard Sag" / "Zernike Fringe Sag"
//! order = "fringe"                # or "standard" (Noll, unit RMS)
//! norm_radius_mm = 10.0
//! coefficients_mm = [0.0, 0.0, 0.0, 0.0, 0.002]   # term j at position j
//! [xy]                            # Σ C (x/R)^i (y/R)^j
//! norm_radius_mm = 10.0
//! terms = [{ x = 2, y = 1, coefficient_mm = 0.001 }]
//! [grid]                          # "Grid Sag": CSV of sag in mm, row 0 at +y, column 0 at −x
//! path = "departure.csv"
//! pitch_mm = [0.25, 0.25]
//! [compensation]                  # a previous cut's error map (part − design, part frame), subtracted
//! path = "part_error.csv"
//! pitch_mm = [0.15625, 0.15625]
//! ```

use super::{input_file, ConfigError, Origin};
use optics::polynomial::XyTerm;
use optics::zernike::FRINGE_TERMS;
use optics::{
    Conic, Prescription, SagGrid, XyPolynomial, Zernike, ZernikeOrder, MAX_ASPHERE_TERMS,
    MAX_GRID_NODES, MAX_XY_DEGREE, MAX_XY_TERMS, MAX_ZERNIKE_ORDER,
};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// Metres per millimetre.
const M_PER_MM: f64 = 1e-3;

/// Largest Noll index read (radial order [`MAX_ZERNIKE_ORDER`]).
const MAX_STANDARD_TERMS: usize =
    (MAX_ZERNIKE_ORDER as usize + 1) * (MAX_ZERNIKE_ORDER as usize + 2) / 2;

/// Largest sag grid file, bytes.
const MAX_GRID_BYTES: u64 = 128 << 20;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    aperture_radius_mm: f64,
    #[serde(default, deserialize_with = "servo_config::exact_array")]
    decenter_mm: [f64; 2],
    base: Option<BaseFile>,
    zernike: Option<ZernikeFile>,
    xy: Option<XyFile>,
    grid: Option<GridFile>,
    compensation: Option<GridFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BaseFile {
    radius_mm: f64,
    #[serde(default)]
    conic: f64,
    #[serde(default)]
    even_asphere: Vec<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ZernikeFile {
    order: ZernikeOrder,
    norm_radius_mm: f64,
    coefficients_mm: Vec<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct XyFile {
    norm_radius_mm: f64,
    terms: Vec<XyTermFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct XyTermFile {
    x: u32,
    y: u32,
    coefficient_mm: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GridFile {
    path: PathBuf,
    #[serde(deserialize_with = "servo_config::exact_array")]
    pitch_mm: [f64; 2],
}

/// Reads and checks the prescription of `path` (its grid file relative to it), in SI.
/// Errors name the file, line, key and the allowed range.
pub fn read_prescription(path: &Path) -> Result<Prescription, ConfigError> {
    let text = input_file::read_text(path)?;
    let file: File = toml::from_str(&text).map_err(|e| ConfigError::Parse {
        path: path.to_owned(),
        message: format!(
            "a surface prescription (aperture_radius_mm and [base], [zernike], [xy], [grid], [compensation] tables): {}",
            servo_config::toml_message(&text, &e)
        ),
    })?;
    let at = Origin {
        path: Some(path.to_owned()),
        text: Some(text),
    };
    let within = |key: &str, v: f64, lo: f64, hi: f64| {
        if v > lo && v <= hi {
            Ok(v * M_PER_MM)
        } else {
            Err(at.invalid(key, v, &format!("({lo}, {hi}] mm")))
        }
    };
    let finite = |key: &str, v: &[f64], max: f64, unit: &str| match v
        .iter()
        .position(|c| !(c.is_finite() && c.abs() <= max))
    {
        Some(i) => Err(at.invalid(
            &format!("{key}[{i}]"),
            v[i],
            &format!("[-{max}, {max}] {unit}"),
        )),
        None => Ok(()),
    };
    let aperture = within("aperture_radius_mm", file.aperture_radius_mm, 0.0, 500.0)?;
    finite("decenter_mm", &file.decenter_mm, 1000.0, "mm")?;
    let decenter_m = file.decenter_mm.map(|v| v * M_PER_MM);
    let reach = aperture + libm::hypot(decenter_m[0], decenter_m[1]);
    let base = match file.base {
        None => None,
        Some(b) => {
            if !(b.radius_mm == 0.0 || (b.radius_mm.abs() >= 0.1 && b.radius_mm.abs() <= 1e6)) {
                return Err(at.invalid(
                    "base.radius_mm",
                    b.radius_mm,
                    "0 (a plane) or 0.1 ≤ |R| ≤ 1e6 mm",
                ));
            }
            finite("base.conic", &[b.conic], 1e3, "")?;
            if b.even_asphere.len() > MAX_ASPHERE_TERMS {
                return Err(at.invalid(
                    "base.even_asphere",
                    format!("{} terms", b.even_asphere.len()),
                    &format!("at most {MAX_ASPHERE_TERMS} terms"),
                ));
            }
            finite("base.even_asphere", &b.even_asphere, 1e30, "mm^(1−2i)")?;
            // In m the coefficients must stay finite too (αᵢ × 1000^(2i−1)).
            if let Some(i) = (0..b.even_asphere.len())
                .find(|&i| !(b.even_asphere[i] * 1e3f64.powi(2 * i as i32 + 1)).is_finite())
            {
                return Err(at.invalid(
                    &format!("base.even_asphere[{i}]"),
                    b.even_asphere[i],
                    "a coefficient finite in m^(1−2i) (|αᵢ| · 1000^(2i−1) below 1.8e308)",
                ));
            }
            let conic = Conic {
                curvature_per_m: if b.radius_mm == 0.0 {
                    0.0
                } else {
                    1.0 / (b.radius_mm * M_PER_MM)
                },
                conic: b.conic,
                // αᵢ in mm^(1−2i) → m^(1−2i): × 1000^(2i−1).
                even_asphere: b
                    .even_asphere
                    .iter()
                    .enumerate()
                    .map(|(k, a)| a * 1e3f64.powi(2 * (k as i32 + 1) - 1))
                    .collect(),
            };
            if conic.limit_radius_m() <= reach {
                return Err(at.invalid(
                    "base.conic",
                    b.conic,
                    &format!(
                        "a conic defined out to the aperture's edge at {:.4} mm from the axis (this one ends at {:.4} mm)",
                        reach / M_PER_MM,
                        conic.limit_radius_m() / M_PER_MM
                    ),
                ));
            }
            Some(conic)
        }
    };
    let zernike = match file.zernike {
        None => None,
        Some(z) => {
            let max = match z.order {
                ZernikeOrder::Standard => MAX_STANDARD_TERMS,
                ZernikeOrder::Fringe => FRINGE_TERMS,
            };
            if z.coefficients_mm.len() > max {
                return Err(at.invalid(
                    "zernike.coefficients_mm",
                    format!("{} terms", z.coefficients_mm.len()),
                    &format!("at most {max} terms in {:?} order", z.order),
                ));
            }
            finite("zernike.coefficients_mm", &z.coefficients_mm, 1.0, "mm")?;
            Some(Zernike {
                order: z.order,
                norm_radius_m: within("zernike.norm_radius_mm", z.norm_radius_mm, 0.0, 1000.0)?,
                coefficients_m: z.coefficients_mm.iter().map(|c| c * M_PER_MM).collect(),
            })
        }
    };
    let xy = match file.xy {
        None => None,
        Some(p) => {
            if p.terms.len() > MAX_XY_TERMS {
                return Err(at.invalid(
                    "xy.terms",
                    format!("{} terms", p.terms.len()),
                    &format!("at most {MAX_XY_TERMS} terms"),
                ));
            }
            let mut terms = Vec::with_capacity(p.terms.len());
            for (i, t) in p.terms.iter().enumerate() {
                if u64::from(t.x) + u64::from(t.y) > u64::from(MAX_XY_DEGREE) {
                    return Err(at.invalid(
                        &format!("xy.terms[{i}]"),
                        format!("x = {}, y = {}", t.x, t.y),
                        &format!("a total degree x + y ≤ {MAX_XY_DEGREE}"),
                    ));
                }
                finite(
                    &format!("xy.terms[{i}].coefficient_mm"),
                    &[t.coefficient_mm],
                    1.0,
                    "mm",
                )?;
                terms.push(XyTerm {
                    x_power: t.x,
                    y_power: t.y,
                    coefficient_m: t.coefficient_mm * M_PER_MM,
                });
            }
            Some(XyPolynomial {
                norm_radius_m: within("xy.norm_radius_mm", p.norm_radius_mm, 0.0, 1000.0)?,
                terms,
            })
        }
    };
    let dir = path.parent().unwrap_or(Path::new("."));
    let grid = match file.grid {
        None => None,
        Some(g) => Some(grid_table(&at, dir, "grid", &g, decenter_m, aperture)?),
    };
    let compensation = match file.compensation {
        None => None,
        Some(g) => Some(grid_table(
            &at,
            dir,
            "compensation",
            &g,
            [0.0; 2],
            aperture,
        )?),
    };
    let p = Prescription {
        base,
        zernike,
        xy,
        grid,
        compensation,
        decenter_m,
        aperture_radius_m: aperture,
    };
    // What the checks above missed (they name the file's keys; this names the part).
    p.validate()
        .map_err(|(key, allowed)| at.invalid(&key, "(this table)", &allowed))?;
    Ok(p)
}

/// The grid of table `name` (`grid`: the parent's frame, centred `decenter_m` from the part;
/// `compensation`: the part's frame), read relative to `dir` and checked to cover the
/// aperture.
fn grid_table(
    at: &Origin,
    dir: &Path,
    name: &str,
    g: &GridFile,
    decenter_m: [f64; 2],
    aperture: f64,
) -> Result<SagGrid, ConfigError> {
    let key = |k: &str| format!("{name}.{k}");
    let pitch = |v: f64| {
        if v > 0.0 && v <= 100.0 {
            Ok(v * M_PER_MM)
        } else {
            Err(at.invalid(&key("pitch_mm"), v, "(0, 100] mm"))
        }
    };
    let pitch_m = [pitch(g.pitch_mm[0])?, pitch(g.pitch_mm[1])?];
    let grid_path = dir.join(&g.path);
    let grid = read_grid(&grid_path, pitch_m)
        .map_err(|e| at.invalid(&key("path"), grid_path.display(), &e))?;
    let [hx, hy] = grid.half_extent_m();
    let [dx, dy] = decenter_m;
    if !grid.covers(decenter_m, aperture) {
        return Err(at.invalid(
            &key("path"),
            grid_path.display(),
            &format!(
                "a grid covering the aperture (±{:.4} × ±{:.4} mm about the part's centre; this one spans ±{:.4} × ±{:.4} mm)",
                (dx.abs() + aperture) / M_PER_MM,
                (dy.abs() + aperture) / M_PER_MM,
                hx / M_PER_MM,
                hy / M_PER_MM
            ),
        ));
    }
    Ok(grid)
}

/// A CSV of sag values in mm (rows of equal length, no header; `#` lines are comments) as a
/// grid of `pitch_m`.
fn read_grid(path: &Path, pitch_m: [f64; 2]) -> Result<SagGrid, String> {
    let text = daq_io::input_file::read_regular_text(path, MAX_GRID_BYTES)
        .map_err(|e| format!("a readable UTF-8 CSV file ({e})"))?;
    let (mut sag_m, mut columns, mut rows) = (Vec::new(), 0usize, 0usize);
    for (line_no, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let before = sag_m.len();
        for cell in line.split(',') {
            let v: f64 = cell
                .trim()
                .parse()
                .map_err(|_| format!("numbers in mm (line {}: {cell:?})", line_no + 1))?;
            if !(v.is_finite() && v.abs() <= 1000.0) {
                return Err(format!(
                    "sag values within ±1000 mm (line {}: {v})",
                    line_no + 1
                ));
            }
            sag_m.push(v * M_PER_MM);
            if sag_m.len() > MAX_GRID_NODES {
                return Err(format!("at most {MAX_GRID_NODES} nodes"));
            }
        }
        let width = sag_m.len() - before;
        if rows > 0 && width != columns {
            return Err(format!(
                "rows of equal length (line {} has {width} values, the first row {columns})",
                line_no + 1
            ));
        }
        columns = width;
        rows += 1;
    }
    if rows < 4 || columns < 4 {
        return Err(format!(
            "at least 4 × 4 nodes (this one {columns} × {rows})"
        ));
    }
    Ok(SagGrid {
        pitch_m,
        columns,
        rows,
        sag_m,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> std::path::PathBuf {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn millimetres_become_metres_and_each_table_adds() {
        let dir = tempfile::tempdir().unwrap();
        write(
            &dir,
            "grid.csv",
            "# z in mm\n0,0,0,0\n0,0.001,0.001,0\n0,0.001,0.001,0\n0,0,0,0\n",
        );
        let p = write(
            &dir,
            "p.toml",
            "aperture_radius_mm = 1.0\ndecenter_mm = [0.5, 0.0]\n[base]\nradius_mm = 100.0\nconic = -1.0\neven_asphere = [0.0, 2e-6]\n[zernike]\norder = \"standard\"\nnorm_radius_mm = 2.0\ncoefficients_mm = [0.0, 0.0, 0.0, 0.001]\n[xy]\nnorm_radius_mm = 2.0\nterms = [{ x = 1, y = 1, coefficient_mm = 0.002 }]\n[grid]\npath = \"grid.csv\"\npitch_mm = [1.0, 1.0]\n",
        );
        let rx = read_prescription(&p).unwrap();
        let b = rx.base.as_ref().unwrap();
        assert!((b.curvature_per_m - 10.0).abs() < 1e-12);
        // α₂ r⁴: 2e-6 mm⁻³ = 2e-6 · 1e9 m⁻³.
        assert!((b.even_asphere[1] - 2e3).abs() < 1e-9);
        assert_eq!(rx.decenter_m, [0.5e-3, 0.0]);
        assert!((rx.zernike.as_ref().unwrap().coefficients_m[3] - 1e-6).abs() < 1e-18);
        assert!((rx.xy.as_ref().unwrap().terms[0].coefficient_m - 2e-6).abs() < 1e-18);
        let g = rx.grid.as_ref().unwrap();
        assert_eq!((g.columns, g.rows), (4, 4));
        assert!((g.sag_m[5] - 1e-6).abs() < 1e-18);
    }

    #[test]
    fn errors_name_the_file_and_key() {
        let dir = tempfile::tempdir().unwrap();
        let p = write(
            &dir,
            "p.toml",
            "aperture_radius_mm = 10.0\n[base]\nradius_mm = 5.0\n",
        );
        let e = read_prescription(&p).unwrap_err().to_string();
        assert!(
            e.contains("p.toml") && e.contains("base.conic") && e.contains("aperture"),
            "{e}"
        );
        let p = write(&dir, "q.toml", "aperture_radius_mm = 1.0\n[zernike]\norder = \"fringe\"\nnorm_radius_mm = 1.0\ncoefficients_mm = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\n");
        let e = read_prescription(&p).unwrap_err().to_string();
        assert!(
            e.contains("zernike.coefficients_mm") && e.contains("37"),
            "{e}"
        );
        write(&dir, "small.csv", "0,0,0,0\n0,0,0,0\n0,0,0,0\n0,0,0,0\n");
        let p = write(
            &dir,
            "r.toml",
            "aperture_radius_mm = 5.0\n[grid]\npath = \"small.csv\"\npitch_mm = [1.0, 1.0]\n",
        );
        let e = read_prescription(&p).unwrap_err().to_string();
        assert!(
            e.contains("grid.path") && e.contains("covering the aperture"),
            "{e}"
        );
        let p = write(&dir, "t.toml", "aperture_radius_mm = 5.0\n[xy]\nnorm_radius_mm = 5.0\nterms = [{ x = 4294967295, y = 1, coefficient_mm = 0.001 }]\n");
        let e = read_prescription(&p).unwrap_err().to_string();
        assert!(e.contains("xy.terms[0]") && e.contains("20"), "{e}");
        let p = write(
            &dir,
            "u.toml",
            &format!(
                "aperture_radius_mm = 5.0\n[base]\nradius_mm = 100.0\neven_asphere = [{}]\n",
                vec!["0.0"; 17].join(", ")
            ),
        );
        let e = read_prescription(&p).unwrap_err().to_string();
        assert!(e.contains("base.even_asphere") && e.contains("16"), "{e}");
        let p = write(&dir, "s.toml", "aperture_radius_mm = 5.0\nradius = 3\n");
        assert!(read_prescription(&p)
            .unwrap_err()
            .to_string()
            .contains("s.toml"));
    }
}
