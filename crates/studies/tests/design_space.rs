//! Design-space studies (thesis §6.5) on the thesis prototype at 199.6 kHz: the trends of
//! Fig 6-14, 6-15…6-17 and 6-18 with the model's disturbances, failed points kept, and the
//! table independent of how it was computed (threads, interruptions, shards).

use studies::design_space::evaluate::{evaluate, Metrics, Point};
use studies::design_space::execute::run_shard;
use studies::design_space::journal::Shard;
use studies::design_space::sensitivity::sensitivities;
use studies::design_space::spec::Study;
use studies::design_space::{gather, optima, table};

/// Index of a source in the per-source columns (`loop_model::closed_loop::SOURCES`).
fn source(name: &str) -> usize {
    loop_model::closed_loop::SOURCES
        .iter()
        .position(|(n, _)| *n == name)
        .expect("a source")
}

fn study(text: &str) -> Study {
    Study::parse(text, None).expect("a valid study")
}

fn all(s: &Study) -> Vec<Point> {
    (0..s.points()).map(|i| evaluate(s, i)).collect()
}

fn ok(p: &Point) -> &Metrics {
    p.outcome
        .as_ref()
        .unwrap_or_else(|e| panic!("point {} failed: {e}", p.index))
}

fn strictly_falling(v: &[f64]) -> bool {
    v.windows(2).all(|w| w[1] < w[0])
}

const MASSES: &str = "[[study.parameter]]\nkey = \"plant.stage.moving_mass_kg\"\nvalues = [0.04, 0.074, 0.13, 0.2]\n";

#[test]
fn h2_optimal_error_and_its_bandwidth_fall_with_the_moving_mass() {
    // Fig 6-14 a: "the errors decrease with larger mass and the bandwidth (−3 dB) decreases
    // as well".
    let s = study(&format!("[study]\ncontrollers = [\"h2\"]\n{MASSES}"));
    let points = all(&s);
    let m: Vec<&Metrics> = points.iter().map(ok).collect();
    let col = |f: fn(&Metrics) -> f64| m.iter().map(|x| f(x)).collect::<Vec<_>>();
    let (following, truth, bw) = (
        col(|x| x.following_rms_m),
        col(|x| x.true_rms_m),
        col(|x| x.bandwidth_hz),
    );
    eprintln!("following {following:?}\ntrue {truth:?}\nbandwidth {bw:?}");
    assert!(strictly_falling(&following) && strictly_falling(&truth) && strictly_falling(&bw));
    // The force-driven terms fall with inertia; the sensor floor does not.
    let current = col(|x| x.true_by_source_m[source("current")]);
    assert!(strictly_falling(&current), "{current:?}");
    assert!(bw[0] / bw[3] > 1.5, "{bw:?}");
}

#[test]
fn at_a_fixed_bandwidth_mass_lowers_the_force_driven_terms_and_the_sensor_floor_stays() {
    // Fig 6-14 b: bandwidth held at 1.6 kHz. The current-noise term falls with mass as the
    // thesis says; the total is the sensor noise's (≥ 98 % of the power here), which a fixed
    // bandwidth holds: it moves by less than 1 % (the thesis's fall needs a current noise
    // comparable to the sensor's; see the closing note of issue 20).
    // (From about 0.12 kg no H2 design of this family has its first −3 dB crossing at
    // 1.6 kHz — 1.55 kHz at 0.12 kg, 1.50 kHz at 0.13 kg: those points fail, kept with the
    // bandwidth reached.)
    let s = study(
        "[study]\ncontrollers = [\"h2-bandwidth\"]\nbandwidth_hz = 1600.0\n\
         [[study.parameter]]\nkey = \"plant.stage.moving_mass_kg\"\nvalues = [0.04, 0.06, 0.08, 0.1]\n",
    );
    let points = all(&s);
    let m: Vec<&Metrics> = points.iter().map(ok).collect();
    for x in &m {
        assert!(
            (x.bandwidth_hz / 1600.0 - 1.0).abs() <= 2.1e-3,
            "{}",
            x.bandwidth_hz
        );
    }
    let current: Vec<f64> = m
        .iter()
        .map(|x| x.true_by_source_m[source("current")])
        .collect();
    assert!(strictly_falling(&current), "{current:?}");
    assert!(current[0] / current[3] > 2.0, "{current:?}");
    let total: Vec<f64> = m.iter().map(|x| x.following_rms_m).collect();
    let spread = total.iter().cloned().fold(f64::MIN, f64::max)
        / total.iter().cloned().fold(f64::MAX, f64::min);
    assert!(spread < 1.01, "{total:?}");
    let sensor_share = m[0].following_by_source_m[source("sensor")].powi(2) / total[0].powi(2);
    assert!(sensor_share > 0.95, "{sensor_share}");
}

#[test]
fn flexure_damping_trades_current_noise_for_base_vibration() {
    // Fig 6-16: more c2 transmits more base vibration and lowers the current-noise error;
    // with the model's disturbances the base term saturates below the current-noise saving,
    // so the total keeps falling.
    let s = study(
        "[study]\n[[study.parameter]]\nkey = \"plant.stage.c2_n_s_per_m\"\nvalues = [2.28, 100.0, 2000.0]\n",
    );
    let points = all(&s);
    let m: Vec<&Metrics> = points.iter().map(ok).collect();
    let term = |name: &str| {
        m.iter()
            .map(|x| x.true_by_source_m[source(name)])
            .collect::<Vec<_>>()
    };
    let (current, base) = (term("current"), term("base"));
    assert!(strictly_falling(&current), "{current:?}");
    assert!(base.windows(2).all(|w| w[1] > w[0]), "{base:?}");
    let total: Vec<f64> = m.iter().map(|x| x.true_rms_m).collect();
    assert!(strictly_falling(&total), "{total:?}");
}

#[test]
fn an_interior_flexure_optimum_exists_when_base_vibration_matters() {
    // Fig 6-17: "there exists an optimal pair of flexure stiffness k2 and damping c2 under
    // this disturbance situation". With base vibration at 5e-12 m/√Hz (12× the model's) the
    // optimum lies inside the grid, near the thesis's 1.1e5 N/m, 237.7 N·s/m.
    let s = study(
        "[plant.noise]\nbase_m_per_rt_hz = 5e-12\n[study]\n\
         [[study.parameter]]\nkey = \"plant.stage.k2_n_per_m\"\nvalues = [2e3, 2e4, 2e5, 2e6]\n\
         [[study.parameter]]\nkey = \"plant.stage.c2_n_s_per_m\"\nvalues = [0.2, 2.0, 20.0, 200.0, 2000.0]\n",
    );
    let points = all(&s);
    let best = &optima(&s, &points)[0];
    let (k2, c2) = (best.values[0].1, best.values[1].1);
    eprintln!(
        "optimum {:.4} nm at k2 = {k2}, c2 = {c2}",
        best.following_rms_m * 1e9
    );
    assert!(
        (2e4..=2e5).contains(&k2) && (20.0..=200.0).contains(&c2),
        "{k2} {c2}"
    );
    // Every point on the grid's edge is worse.
    let edge = points.iter().filter(|p| {
        let (a, b) = (p.values[0], p.values[1]);
        a == 2e3 || a == 2e6 || b == 0.2 || b == 2000.0
    });
    for p in edge {
        assert!(
            ok(p).following_rms_m > best.following_rms_m * 1.0005,
            "{p:?}"
        );
    }
}

#[test]
fn a_stronger_motor_raises_current_noise_and_transmits_less_base_vibration() {
    // Fig 6-18: with a larger K_T "the error caused by the current loop noise will be larger
    // … low frequency vibrations are less transmitted to the tool".
    let s = study(
        "[study]\n[[study.parameter]]\nkey = \"plant.actuator.kt_n_per_a\"\nfrom = 1.0\nto = 12.0\npoints = 2\nspacing = \"log\"\n",
    );
    let e = &sensitivities(&s, 2, &mut |_, _| {})[0];
    assert!(e.failed.is_none());
    assert!(e.true_by_source[source("current")] > 0.1, "{e:?}");
    assert!(e.true_by_source[source("base")] < 0.0, "{e:?}");
    assert!(e.following_by_source[source("base")] < 0.0, "{e:?}");
}

#[test]
fn failed_points_are_kept_with_their_reason() {
    let s = study(
        "[study]\ncontrollers = [\"pid\"]\nbandwidth_hz = 1600.0\n\
         [[study.parameter]]\nkey = \"plant.stage.k2_n_per_m\"\nvalues = [-1.0, 21965.0]\n",
    );
    let points = all(&s);
    let reasons: Vec<&String> = points
        .iter()
        .filter_map(|p| p.outcome.as_ref().err())
        .collect();
    assert_eq!(reasons.len(), 2, "{points:?}");
    assert!(
        reasons[0].contains("plant.stage.k2_n_per_m"),
        "{}",
        reasons[0]
    );
    assert!(reasons[1].contains("out of reach"), "{}", reasons[1]);
    let csv = table::csv(&s, &points);
    assert_eq!(csv.lines().filter(|l| l.contains(",failed,")).count(), 2);
}

#[test]
fn threads_interruptions_and_shards_give_the_same_table() {
    let text = "[study]\nsampling = \"latin-hypercube\"\nsamples = 6\nseed = 3\n\
                [[study.parameter]]\nkey = \"plant.stage.k2_n_per_m\"\nfrom = 1e4\nto = 1e5\nspacing = \"log\"\n\
                [[study.parameter]]\nkey = \"plant.stage.c2_n_s_per_m\"\nfrom = 1.0\nto = 50.0\n";
    let s = study(text);
    let one = all(&s);
    let reference = table::csv(&s, &one);
    let tmp = tempfile::tempdir().unwrap();
    // Two threads, interrupted after two points, then resumed.
    let dir = tmp.path().join("resumed");
    let taken = std::sync::atomic::AtomicUsize::new(0);
    let stop = || taken.fetch_add(1, std::sync::atomic::Ordering::SeqCst) >= 2;
    let first = run_shard(&s, &dir, Shard::ALL, 2, &stop, &mut |_, _| {}).unwrap();
    assert!(!first.complete() && first.points.len() >= 2, "{first:?}");
    // A crash mid-write leaves the last row torn, cut inside a character (the first byte of
    // "µ"): the row is dropped and its point computed again.
    let journal = dir.join(Shard::ALL.file_name());
    let bytes = std::fs::read(&journal).unwrap();
    let last = bytes[..bytes.len() - 1]
        .iter()
        .rposition(|&b| b == b'\n')
        .unwrap()
        + 1;
    let mut torn = bytes[..last].to_vec();
    torn.extend_from_slice(&bytes[last..last + (bytes.len() - last) / 2]);
    torn.push("µ".as_bytes()[0]);
    std::fs::write(&journal, &torn).unwrap();
    let rest = run_shard(&s, &dir, Shard::ALL, 2, &|| false, &mut |_, _| {}).unwrap();
    assert!(rest.complete());
    assert_eq!(rest.evaluated as usize + first.points.len() - 1, 6);
    assert_eq!(table::csv(&s, &rest.points), reference);
    // A complete row that is not a point of this study is refused, naming its line.
    let whole = std::fs::read(&journal).unwrap();
    let mut foreign_row = whole.clone();
    let row = String::from_utf8(bytes[last..].to_vec()).unwrap();
    let (_, fields) = row.split_once(',').unwrap();
    foreign_row.extend_from_slice(format!("99,{fields}").as_bytes());
    std::fs::write(&journal, &foreign_row).unwrap();
    let e = run_shard(&s, &dir, Shard::ALL, 1, &|| false, &mut |_, _| {}).unwrap_err();
    assert!(e.to_string().contains("not a point of shard"), "{e}");
    std::fs::write(&journal, &whole).unwrap();
    // Three shards in three folders, merged.
    let dirs: Vec<_> = (1..=3)
        .map(|i| {
            let d = tmp.path().join(format!("shard{i}"));
            let shard = Shard { index: i, count: 3 };
            assert!(run_shard(&s, &d, shard, 1, &|| false, &mut |_, _| {})
                .unwrap()
                .complete());
            d
        })
        .collect();
    let (merged_study, merged) = gather(&dirs).unwrap();
    assert_eq!(merged_study.sha256, s.sha256);
    assert_eq!(table::csv(&s, &merged), reference);
    // A missing shard is named.
    let e = gather(&dirs[..2]).unwrap_err().to_string();
    assert!(
        e.contains("2 of 6 points are missing") && e.contains("shard 3/3"),
        "{e}"
    );
    // A folder of another study is refused, not overwritten.
    let other = study(&text.replace("seed = 3", "seed = 4"));
    let e = run_shard(&other, &dir, Shard::ALL, 1, &|| false, &mut |_, _| {}).unwrap_err();
    assert!(e.to_string().contains("another study"), "{e}");
}

#[test]
fn the_parquet_table_holds_the_csv_values() {
    use parquet::file::reader::{FileReader, SerializedFileReader};
    use parquet::record::RowAccessor;
    let s = study(
        "[study]\ncontrollers = [\"h2\", \"pid\"]\nbandwidth_hz = 1600.0\n\
         [[study.parameter]]\nkey = \"plant.stage.c2_n_s_per_m\"\nvalues = [2.28]\n",
    );
    let points = all(&s);
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("t.parquet");
    studies::design_space::columnar::write(&s, &points, &path).unwrap();
    let reader = SerializedFileReader::new(std::fs::File::open(&path).unwrap()).unwrap();
    let meta = reader.metadata().file_metadata();
    assert_eq!(meta.num_rows(), 2);
    let kv = meta.key_value_metadata().unwrap();
    assert!(kv.iter().any(
        |k| k.key == "fts_servo.study_sha256" && k.value.as_deref() == Some(s.sha256.as_str())
    ));
    let rows: Vec<_> = reader
        .get_row_iter(None)
        .unwrap()
        .map(|r| r.unwrap())
        .collect();
    // index, controller, c2, status, reason, bandwidth_hz, following_rms_m …
    assert_eq!(rows[0].get_long(0).unwrap(), 0);
    assert_eq!(rows[0].get_string(1).unwrap(), "h2");
    assert_eq!(rows[0].get_string(3).unwrap(), "ok");
    assert_eq!(
        rows[0].get_double(6).unwrap(),
        ok(&points[0]).following_rms_m
    );
    assert_eq!(rows[1].get_string(3).unwrap(), "failed");
    assert!(
        rows[1].get_double(6).is_err(),
        "a failed point's metrics are null"
    );
}

#[test]
fn every_example_study_parses_and_the_tolerance_study_spans_ten_percent() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/studies");
    let mut seen = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let s = Study::from_file(&path).unwrap_or_else(|e| panic!("{e}"));
        assert!(s.points() > 0, "{}", path.display());
        if path.ends_with("tolerances.toml") {
            for p in &s.table.parameters {
                let op = s.operating_value(p);
                let (a, b) = (p.from.unwrap(), p.to.unwrap());
                assert!(
                    (a / op - 0.9).abs() < 1e-9 && (b / op - 1.1).abs() < 1e-9,
                    "{}",
                    p.key
                );
            }
        }
        seen += 1;
    }
    assert_eq!(seen, 4);
}
