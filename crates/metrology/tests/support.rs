//! What the tests share: the test files and the design of the synthetic map.

use metrology::{read_map, LengthUnit, MeasuredMap, ReadOptions};
use optics::toolpath::ToolPath;
use optics::{Conic, Prescription, Zernike, ZernikeOrder};
use std::path::PathBuf;

/// A file of `testdata/`.
pub fn testdata(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("testdata")
        .join(name)
}

/// The synthetic map's pixel pitch, m (scripts/make_metrology_testdata.py).
pub const PITCH_M: f64 = 70e-6;

/// The synthetic map in `ext`, with what its file does not state.
pub fn synthetic(ext: &str) -> MeasuredMap {
    let options = if ext == "npy" {
        ReadOptions {
            height_unit: Some(LengthUnit::Metre),
            pitch_m: Some(PITCH_M),
        }
    } else {
        ReadOptions::default()
    };
    read_map(&testdata(&format!("synthetic.{ext}")), &options).expect("reads")
}

/// The synthetic map's design: a sphere of radius 200 mm with 2 µm of Standard Zernike 6
/// (astigmatism, cos 2θ) and 1 µm of Standard 10 (trefoil, cos 3θ) on a 5 mm aperture.
pub fn design() -> ToolPath {
    let aperture = 5e-3;
    let mut coefficients = vec![0.0; 10];
    coefficients[5] = 2e-6;
    coefficients[9] = 1e-6;
    let p = Prescription {
        base: Some(Conic {
            curvature_per_m: 5.0,
            conic: 0.0,
            even_asphere: vec![],
        }),
        zernike: Some(Zernike {
            order: ZernikeOrder::Standard,
            norm_radius_m: aperture,
            coefficients_m: coefficients,
        }),
        aperture_radius_m: aperture,
        ..Prescription::default()
    };
    ToolPath::new(p, 0.5e-3).expect("a nose that fits")
}
