//! `export`: the `.npz` holds exactly the recorded values (read back through the zip and the
//! `.npy` headers, as NumPy does), the CSV the same rows; window and decimation keep the right
//! ticks; bad selections and existing outputs are refused with a clear message.

use crate::common;

use common::{frames, tmp, write};
use recorder::export::{export, Format, Selection};
use recorder::{Overwrite, TelemetryRecord};
use std::io::Read;

/// The arrays of an `.npz`: name → (dtype, raw little-endian values).
fn npz(path: &std::path::Path) -> Vec<(String, String, Vec<u8>)> {
    let mut zip = zip::ZipArchive::new(std::fs::File::open(path).unwrap()).unwrap();
    (0..zip.len())
        .map(|i| {
            let mut f = zip.by_index(i).unwrap();
            let name = f.name().trim_end_matches(".npy").to_string();
            let mut bytes = Vec::new();
            f.read_to_end(&mut bytes).unwrap();
            assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
            let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
            assert_eq!((10 + header_len) % 64, 0, "data 64-aligned");
            let header = String::from_utf8(bytes[10..10 + header_len].to_vec()).unwrap();
            let dtype = header.split('\'').nth(3).unwrap().to_string();
            let data = bytes[10 + header_len..].to_vec();
            let size = if dtype == "<f8" { 8 } else { 4 };
            assert!(
                header.contains(&format!("'shape': ({},)", data.len() / size)),
                "{header}"
            );
            (name, dtype, data)
        })
        .collect()
}

#[test]
fn npz_holds_every_recorded_value() {
    let data = frames(5_000);
    let rec = tmp("export.mcap");
    write(&rec, &data);
    let out = tmp("export.npz");
    let done = export(
        &rec,
        &out,
        Format::Npz,
        &Selection::default(),
        Overwrite::Refuse,
    )
    .unwrap();
    assert_eq!(done.rows, 5_000);
    let arrays = npz(&out);
    assert_eq!(arrays.len(), 1 + 7 + 9);
    let (_, dtype, time) = &arrays[0];
    assert_eq!((arrays[0].0.as_str(), dtype.as_str()), ("time_s", "<f8"));
    let t: Vec<f64> = time
        .chunks(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert_eq!(t[4_999], data[4_999].time_ns as f64 * 1e-9);
    let (name, dtype, values) = &arrays[1 + 2];
    assert_eq!(name, "telemetry.following_error_m");
    assert_eq!(dtype, "<f4");
    let expected: Vec<u8> = data
        .iter()
        .flat_map(|f| f.telemetry.following_error_m.to_le_bytes())
        .collect();
    assert!(values == &expected);
}

#[test]
fn csv_window_and_decimation_keep_the_right_ticks() {
    let data = frames(10_000);
    let rec = tmp("window.mcap");
    write(&rec, &data);
    let out = tmp("window.csv");
    let selection = Selection {
        truth: false,
        from_s: 0.01,
        to_s: 0.03,
        every: 7,
        ..Default::default()
    };
    export(&rec, &out, Format::Csv, &selection, Overwrite::Refuse).unwrap();
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    let header: Vec<_> = lines.next().unwrap().split(',').collect();
    assert_eq!(header.len(), 1 + TelemetryRecord::FIELDS.len());
    let kept: Vec<_> = data
        .iter()
        .filter(|f| (0.01..=0.03).contains(&(f.time_ns as f64 * 1e-9)))
        .step_by(7)
        .collect();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), kept.len());
    for (row, f) in rows.iter().zip(&kept) {
        assert_eq!(row[0], f.time_ns as f64 * 1e-9);
        assert_eq!(row[2] as f32, f.telemetry.measured_m);
    }
}

#[test]
fn bad_selections_and_existing_outputs_are_refused() {
    let rec = tmp("refuse.mcap");
    write(&rec, &frames(100));
    let out = tmp("refuse.csv");
    let mixed = Selection {
        overview: true,
        ..Default::default()
    };
    let e = export(&rec, &out, Format::Csv, &mixed, Overwrite::Refuse).unwrap_err();
    assert!(e.to_string().contains("topics"), "{e}");
    let backwards = Selection {
        from_s: 2.0,
        to_s: 1.0,
        ..Default::default()
    };
    let e = export(&rec, &out, Format::Csv, &backwards, Overwrite::Refuse).unwrap_err();
    assert!(e.to_string().contains("from_s"), "{e}");
    assert!(!out.exists());
    std::fs::write(&out, "keep me").unwrap();
    let e = export(
        &rec,
        &out,
        Format::Csv,
        &Selection::default(),
        Overwrite::Refuse,
    )
    .unwrap_err();
    assert!(e.to_string().contains("overwrite"), "{e}");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "keep me");
    export(
        &rec,
        &out,
        Format::Csv,
        &Selection::default(),
        Overwrite::Replace,
    )
    .unwrap();
    assert_ne!(std::fs::read_to_string(&out).unwrap(), "keep me");
}
