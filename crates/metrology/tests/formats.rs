//! Every format reads the same map (written independently of this crate by
//! scripts/make_metrology_testdata.py), a real MetroPro file reads as prysm reads it, and bad
//! files are refused naming the reason.

use crate::support::{synthetic, testdata, PITCH_M};
use metrology::{read_map, LengthUnit, ReadOptions};
use std::io::Write;

#[test]
fn every_format_reads_the_same_heights_pixels_and_pitch() {
    let reference = synthetic("datx");
    assert_eq!((reference.rows, reference.cols), (160, 160));
    let valid = reference.heights_m.iter().filter(|h| h.is_finite()).count();
    assert_eq!(valid, 15_334, "the generator's count");
    assert_eq!(reference.pitch_m, [PITCH_M; 2]);
    assert_eq!(reference.wavelength_m, Some(632.8e-9));
    // Each format's rounding (absolute, relative): .dat counts of λ·S/32768 = 9.7 pm with λ
    // stored in f32 (6e-8); .csv 1e-4 nm; .xyz 1e-7 µm.
    for (ext, absolute, relative) in [
        ("npy", 1e-18, 0.0),
        ("csv", 0.6e-13, 0.0),
        ("xyz", 0.6e-13, 0.0),
        ("dat", 4.9e-12, 6e-8),
    ] {
        let m = synthetic(ext);
        assert_eq!((m.rows, m.cols), (160, 160), "{ext}");
        assert!(
            (m.pitch_m[0] - PITCH_M).abs() < 1e-11,
            "{ext}: {:?}",
            m.pitch_m
        );
        for (a, b) in reference.heights_m.iter().zip(&m.heights_m) {
            assert_eq!(
                a.is_finite(),
                b.is_finite(),
                "{ext}: a missing pixel differs"
            );
            if a.is_finite() {
                let tolerance = absolute + relative * a.abs();
                assert!((a - b).abs() <= tolerance, "{ext}: {a} against {b}");
            }
        }
    }
}

#[test]
fn a_real_metropro_file_reads_as_prysm_reads_it() {
    // prysm 0.21.1 `io.read_zygo_dat` on its own sample file (MIT licence): shape (432, 425),
    // 136 359 valid pixels, phase −250.5187 … 80.1814 nm, lateral resolution 1.17924e-4 m.
    let m = read_map(&testdata("prysm_sample.dat"), &ReadOptions::default()).expect("reads");
    assert_eq!((m.rows, m.cols), (432, 425));
    let valid: Vec<f64> = m
        .heights_m
        .iter()
        .copied()
        .filter(|h| h.is_finite())
        .collect();
    assert_eq!(valid.len(), 136_359);
    let min = valid.iter().copied().fold(f64::INFINITY, f64::min);
    let max = valid.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    assert!((min * 1e9 + 250.518_730).abs() < 1e-5, "{}", min * 1e9);
    assert!((max * 1e9 - 80.181_443).abs() < 1e-5, "{}", max * 1e9);
    assert!((m.pitch_m[0] - 1.179_242_026e-4).abs() < 1e-12);
}

/// The reason `read_map` gives for `bytes` written as `name` with `options`.
fn refusal(name: &str, bytes: &[u8], options: ReadOptions) -> String {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join(name);
    std::fs::File::create(&path)
        .and_then(|mut f| f.write_all(bytes))
        .expect("writes");
    let e = read_map(&path, &options).expect_err("refused");
    assert!(
        e.to_string().starts_with(&path.display().to_string()),
        "{e}"
    );
    e.reason
}

#[test]
fn bad_files_are_refused_naming_the_reason() {
    let npy = std::fs::read(testdata("synthetic.npy")).expect("reads");
    let units = refusal("a.npy", &npy, ReadOptions::default());
    assert!(units.contains("map.height_unit"), "{units}");
    let pitch = refusal(
        "a.npy",
        &npy,
        ReadOptions {
            height_unit: Some(LengthUnit::Nanometre),
            pitch_m: None,
        },
    );
    assert!(pitch.contains("map.pitch_m"), "{pitch}");
    let dat = std::fs::read(testdata("synthetic.dat")).expect("reads");
    let stated = refusal(
        "a.dat",
        &dat,
        ReadOptions {
            height_unit: Some(LengthUnit::Micrometre),
            pitch_m: None,
        },
    );
    assert!(
        stated.contains("map.height_unit") && stated.contains("states"),
        "{stated}"
    );
    let truncated = refusal("a.dat", &dat[..dat.len() - 10], ReadOptions::default());
    assert!(truncated.contains("truncated"), "{truncated}");
    let garbage = refusal("a.datx", b"not hdf5 at all", ReadOptions::default());
    assert!(garbage.contains("HDF5"), "{garbage}");
    let kind = refusal("a.tif", b"II*", ReadOptions::default());
    assert!(kind.contains("allowed: .datx"), "{kind}");
    let wrong = refusal(
        "a.csv",
        b"# heights in m, pitch 0.1 mm\n1,2\n3,4\n",
        ReadOptions::default(),
    );
    assert!(wrong.contains("a wrong unit"), "{wrong}");
    let ragged = refusal(
        "a.csv",
        b"# heights in nm, pitch 0.1 mm\n1,2\n3\n",
        ReadOptions::default(),
    );
    assert!(ragged.contains("line 3"), "{ragged}");
}
