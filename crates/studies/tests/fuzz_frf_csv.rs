//! `servo identify`'s FRF CSV reader on generated files (property-based): headers with missing
//! or extra columns, rows with missing cells, non-numbers, NaN/inf/1e300, frequencies out of
//! order or past Nyquist, and magnitudes of every size are read only when valid (every value
//! then checked) and otherwise refused with an error naming the file — never a panic.

use proptest::prelude::*;
use run_config::frf_file::read_frf;

const NYQUIST_HZ: f64 = 99_800.0;

fn cell() -> impl Strategy<Value = String> {
    prop_oneof![
        4 => (1.0f64..99_000.0).prop_map(|x| format!("{x}")),
        3 => (1e-9f64..1e-3).prop_map(|x| format!("{x:e}")),
        2 => (-180.0f64..180.0).prop_map(|x| format!("{x}")),
        1 => prop_oneof![
            Just("nan"), Just("inf"), Just("-inf"), Just("1e300"), Just(""), Just("x"),
            Just("true"), Just("-0"), Just("1e-320"), Just("200000")
        ].prop_map(str::to_string),
    ]
}

fn csv() -> impl Strategy<Value = String> {
    let header = prop_oneof![
        3 => Just("freq_hz,magnitude_m_per_v,phase_deg"),
        1 => Just("freq_hz,magnitude_m_per_v,phase_deg,clipped"),
        1 => Just("freq_hz,magnitude_m_per_v,phase_deg,coherence,uncertainty_m_per_v"),
        1 => Just("freq_hz,phase_deg"),
        1 => Just("magnitude_m_per_v,freq_hz,phase_deg,excitation_v"),
        1 => Just(""),
    ];
    let row = prop::collection::vec(cell(), 0..5).prop_map(|c| c.join(","));
    (header, prop::collection::vec(row, 0..40))
        .prop_map(|(h, rows)| format!("{h}\n{}\n", rows.join("\n")))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn frf_files_are_read_or_refused_with_the_file_named(text in csv()) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("fuzz-frf.csv");
        std::fs::write(&path, &text).unwrap();
        match read_frf(&path, NYQUIST_HZ) {
            Ok(frf) => {
                let (f, g) = (&frf.freq_hz, &frf.response);
                prop_assert_eq!(f.len(), g.len());
                prop_assert_eq!(f.len(), frf.coherence.len());
                prop_assert!(frf.coherence.iter().all(|g| (0.0..=1.0).contains(g)), "{text}");
                prop_assert!(frf.uncertainty.iter().flatten().all(|u| *u >= 0.0), "{text}");
                prop_assert!(f.windows(2).all(|w| w[0] < w[1]) && f.iter().all(|&x| x > 0.0 && x < NYQUIST_HZ), "{text}");
                prop_assert!(g.iter().all(|z| z.re.is_finite() && z.im.is_finite()), "{text}");
            }
            Err(e) => prop_assert!(e.to_string().contains("fuzz-frf.csv"), "{e}\n{text}"),
        }
    }
}
