//! A measured frequency response of the stage as `servo frf` writes it (`frf.csv`): the plant
//! `P`, DAC command (V) → measured position (m), per frequency, with the coherence and the
//! uncertainty of each bin when the file has them. What identification fits and what the
//! data-driven designs start from.

use std::path::{Path, PathBuf};

/// Largest plausible magnitude of an open-loop stage FRF, m/V: a nm-stage moves micrometres
/// per volt (the thesis prototype ≈ 2.5 µm/V static), so a response near 1 is a closed-loop T
/// or S (m/m), not a plant.
pub const MAX_PLANT_MAGNITUDE_M_PER_V: f64 = 1e-2;

/// Fewest usable rows a file must have.
pub const MIN_POINTS: usize = 7;

/// A measured open-loop FRF of the stage (m/V), frequencies strictly increasing.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasuredFrf {
    /// Frequencies in Hz.
    pub freq_hz: Vec<f64>,
    /// The response at each frequency, m/V (measured position per DAC volt).
    pub response: Vec<num_complex::Complex64>,
    /// Magnitude-squared coherence per frequency (1 where the file has no `coherence`).
    pub coherence: Vec<f64>,
    /// Each bin's uncertainty, m/V: the radius of its 63 % (complex 1σ) disk; None when the
    /// file has no `uncertainty_m_per_v` column (an FRF from elsewhere).
    pub uncertainty: Option<Vec<f64>>,
    /// The accelerometer reading's response to the same excitation, when the file has it
    /// (`accel_magnitude_v_per_v`, `accel_phase_deg`, `accel_uncertainty_v_per_v`).
    pub accel: Option<AccelFrf>,
    /// The file and the SHA-256 of its bytes, as designs quote their source.
    pub source: String,
}

/// The accelerometer's FRF measured with the stage's: reading per DAC volt, V/V.
#[derive(Debug, Clone, PartialEq)]
pub struct AccelFrf {
    /// The response at each of the FRF's frequencies, V/V.
    pub response: Vec<num_complex::Complex64>,
    /// Each bin's uncertainty, V/V (the radius of its 63 % disk).
    pub uncertainty: Vec<f64>,
}

/// Why an FRF file was refused.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FrfFileError {
    /// The file could not be read.
    #[error(transparent)]
    Read(#[from] servo_config::ConfigError),
    /// A line of the file is not a plant FRF row.
    #[error("{}:{line}: {what}", path.display())]
    Line {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        what: String,
    },
}

/// Reads an FRF CSV with columns `freq_hz`, `magnitude_m_per_v`, `phase_deg` and optionally
/// `coherence`, `uncertainty_m_per_v` and the accelerometer's `accel_magnitude_v_per_v`,
/// `accel_phase_deg`, `accel_uncertainty_v_per_v` (all three or none; others ignored; rows with `clipped = true` skipped; at
/// most [`crate::input_file::MAX_TEXT_BYTES`]). A comment line naming another quantity than
/// `P` (`servo frf --loop closed` writes `PS`) is refused. Every row must have every column;
/// values must be finite, frequencies strictly increasing and below `nyquist_hz`, magnitudes
/// those of a plant (0 < |G| ≤ [`MAX_PLANT_MAGNITUDE_M_PER_V`]), coherences in [0, 1] and
/// uncertainties ≥ 0. Errors name the file and line.
pub fn read_frf(path: &Path, nyquist_hz: f64) -> Result<MeasuredFrf, FrfFileError> {
    let bytes = crate::input_file::read_input(path, crate::input_file::MAX_TEXT_BYTES)?;
    parse_frf(&bytes, path, nyquist_hz)
}

/// [`read_frf`] of bytes already read (a recording's copy of the file at `path`).
pub fn parse_frf(bytes: &[u8], path: &Path, nyquist_hz: f64) -> Result<MeasuredFrf, FrfFileError> {
    let bad = |line: usize, what: &str| FrfFileError::Line {
        path: path.to_owned(),
        line,
        what: what.to_owned(),
    };
    let text = std::str::from_utf8(bytes).map_err(|_| bad(1, "not UTF-8 text"))?;
    let mut lines = text.lines().enumerate().peekable();
    // Comment lines first; `servo frf` says there which quantity the file holds.
    while let Some((i, line)) = lines.next_if(|(_, l)| l.starts_with('#')) {
        let quantity = line
            .split("quantity =")
            .nth(1)
            .and_then(|q| q.split_whitespace().next());
        if let Some(q) = quantity.filter(|&q| q != "P") {
            return Err(bad(
                i + 1,
                &format!(
                    "quantity {q}: the plant P is needed (an open-loop FRF: loop = open); this file holds {}",
                    line.split('(').nth(1).and_then(|d| d.split(')').next()).unwrap_or(q)
                ),
            ));
        }
    }
    let header_line = lines.peek().map_or(1, |(i, _)| i + 1);
    let header: Vec<&str> = lines
        .next()
        .map(|(_, h)| h.split(',').map(str::trim).collect())
        .unwrap_or_default();
    let find = |name: &str| header.iter().position(|h| *h == name);
    let col = |name: &str| {
        find(name).ok_or_else(|| {
            bad(
                header_line,
                &format!("no column `{name}` (header: {})", header.join(",")),
            )
        })
    };
    let (cf, cm, cp) = (
        col("freq_hz")?,
        col("magnitude_m_per_v")?,
        col("phase_deg")?,
    );
    let (cc, cg, cu) = (
        find("clipped"),
        find("coherence"),
        find("uncertainty_m_per_v"),
    );
    let accel_cols = match (
        find("accel_magnitude_v_per_v"),
        find("accel_phase_deg"),
        find("accel_uncertainty_v_per_v"),
    ) {
        (Some(m), Some(p), Some(u)) => Some((m, p, u)),
        (None, None, None) => None,
        _ => {
            return Err(bad(
                header_line,
                "the accelerometer's columns come together: accel_magnitude_v_per_v, accel_phase_deg, accel_uncertainty_v_per_v",
            ))
        }
    };
    let mut frf = MeasuredFrf {
        freq_hz: Vec::new(),
        response: Vec::new(),
        coherence: Vec::new(),
        uncertainty: cu.map(|_| Vec::new()),
        accel: accel_cols.map(|_| AccelFrf {
            response: Vec::new(),
            uncertainty: Vec::new(),
        }),
        source: format!("{} (SHA-256 {})", path.display(), crate::sha256_hex(bytes)),
    };
    for (i, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        if cells.len() != header.len() {
            return Err(bad(
                i + 1,
                &format!("{} columns; the header has {}", cells.len(), header.len()),
            ));
        }
        if cc.is_some_and(|c| cells[c] == "true") {
            continue;
        }
        let num = |c: usize| {
            cells[c]
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(i + 1, &format!("`{}` is not a finite number", cells[c])))
        };
        let (freq, mag, phase) = (num(cf)?, num(cm)?, num(cp)?);
        if freq <= 0.0 || freq >= nyquist_hz {
            return Err(bad(
                i + 1,
                &format!("freq_hz {freq}: must lie in (0, {nyquist_hz}) Hz, below the servo rate's Nyquist frequency"),
            ));
        }
        if frf.freq_hz.last().is_some_and(|&last| freq <= last) {
            return Err(bad(
                i + 1,
                &format!("freq_hz {freq}: frequencies must increase strictly (duplicated or unsorted rows)"),
            ));
        }
        if mag <= 0.0 || mag > MAX_PLANT_MAGNITUDE_M_PER_V {
            return Err(bad(
                i + 1,
                &format!(
                    "magnitude_m_per_v {mag}: an open-loop stage FRF lies in (0, {MAX_PLANT_MAGNITUDE_M_PER_V}] m/V \
                     (a closed-loop FRF, ≈ 1 m/m at low frequency, is not a plant)"
                ),
            ));
        }
        let coherence = cg.map(num).transpose()?.unwrap_or(1.0);
        if !(0.0..=1.0).contains(&coherence) {
            return Err(bad(
                i + 1,
                &format!("coherence {coherence}: must lie in [0, 1]"),
            ));
        }
        if let (Some(c), Some(u)) = (cu, frf.uncertainty.as_mut()) {
            // An unmeasurable bin's uncertainty is infinite; `inf` is allowed here.
            let sigma = cells[c]
                .parse::<f64>()
                .ok()
                .filter(|v| *v >= 0.0)
                .ok_or_else(|| {
                    bad(
                        i + 1,
                        &format!("uncertainty_m_per_v `{}`: must be ≥ 0 (m/V)", cells[c]),
                    )
                })?;
            u.push(sigma);
        }
        if let (Some((cm, cp, cu)), Some(a)) = (accel_cols, frf.accel.as_mut()) {
            let (mag, phase) = (num(cm)?, num(cp)?);
            let sigma = cells[cu]
                .parse::<f64>()
                .ok()
                .filter(|v| *v >= 0.0 && mag >= 0.0)
                .ok_or_else(|| {
                    bad(
                        i + 1,
                        &format!(
                            "accel_magnitude_v_per_v {mag}, accel_uncertainty_v_per_v `{}`: both must be ≥ 0 (V/V)",
                            cells[cu]
                        ),
                    )
                })?;
            a.response
                .push(num_complex::Complex64::from_polar(mag, phase.to_radians()));
            a.uncertainty.push(sigma);
        }
        frf.freq_hz.push(freq);
        frf.response
            .push(num_complex::Complex64::from_polar(mag, phase.to_radians()));
        frf.coherence.push(coherence);
    }
    if frf.freq_hz.len() < MIN_POINTS {
        return Err(bad(
            1,
            &format!(
                "{} usable rows; at least {MIN_POINTS} needed",
                frf.freq_hz.len()
            ),
        ));
    }
    Ok(frf)
}
