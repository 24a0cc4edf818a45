//! Writes the Riccati and H2 problems that `scripts/riccati_compare.py` solves again with SciPy
//! and SLICOT, with our solutions and times:
//!
//! ```text
//! cargo run --release -p design --example riccati_export -- DIR
//! python3 scripts/riccati_compare.py DIR
//! ```
//!
//! `DIR/problems.json`: random CARE and DARE problems, n = 20 … 160 (with a cross term at
//! n = 40), each with our `X`, relative residual, forward-error estimate and times (the fastest run, of
//! the solve, and of the solve with its sensitivity estimate).
//! `DIR/h2_plants.json`: random continuous generalized plants, n = 4 … 64 (n/4 controls and
//! measurements), with our H2-optimal closed-loop norm. Existing files are not overwritten.

#[path = "../../lti/tests/common/random.rs"]
mod random;

use design::h2::{h2syn_continuous, GeneralizedPlant};
use lti::riccati::{care, dare, Riccati, RiccatiError, Solver};
use nalgebra::DMatrix;
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;
use random::{gaussian, problem, Data};
use serde_json::{json, Value};
use std::path::Path;
use std::time::{Duration, Instant};

fn rows(m: &DMatrix<f64>) -> Value {
    json!((0..m.nrows())
        .map(|i| m.row(i).iter().copied().collect::<Vec<f64>>())
        .collect::<Vec<_>>())
}

/// The solution and the fastest of at least five runs (about 0.3 s of them): on a shared
/// machine noise only adds time (the comparison script times SciPy and SLICOT the same way).
fn timed(
    solve: impl Fn() -> Result<Riccati, RiccatiError>,
) -> (Result<Riccati, RiccatiError>, f64) {
    let mut times = Vec::new();
    let mut out = solve();
    while times.len() < 5
        || (times.iter().sum::<Duration>() < Duration::from_millis(300) && times.len() < 25)
    {
        let t0 = Instant::now();
        out = solve();
        times.push(t0.elapsed());
    }
    let fastest = times.into_iter().min().unwrap_or_default();
    (out, fastest.as_secs_f64())
}

fn riccati_problems() -> Vec<Value> {
    let mut out = Vec::new();
    for (kind, solver, discrete) in [
        ("care", care as Solver, false),
        ("dare", dare as Solver, true),
    ] {
        for (n, cross) in [
            (20, false),
            (40, false),
            (40, true),
            (80, false),
            (160, false),
        ] {
            let Data { a, b, q, r, s } = problem(n, n as u64, cross, discrete);
            let (x, seconds) = timed(|| solver(&a, &b, &q, &r, s.as_ref()));
            // The solve and the sensitivity estimate together (what SB02OD and SB02QD/SB02SD
            // compute between them).
            let (_, with_estimate) = timed(|| {
                solver(&a, &b, &q, &r, s.as_ref()).inspect(|x| {
                    x.sensitivity();
                })
            });
            let ours = match x {
                Ok(x) => json!({
                    "x": rows(&x.x),
                    "residual": x.residual,
                    "forward_error": x.sensitivity().forward_error,
                    "condition": x.sensitivity().condition,
                    "seconds": seconds,
                    "seconds_with_estimate": with_estimate,
                }),
                Err(e) => json!({ "error": e.to_string() }),
            };
            let name = format!(
                "random {kind} n = {n}{}",
                if cross { ", cross term" } else { "" }
            );
            eprintln!("{name}: {seconds:.4} s");
            out.push(json!({
                "name": name,
                "family": if cross { "random, cross" } else { "random" },
                "kind": kind,
                "a": rows(&a), "b": rows(&b), "q": rows(&q), "r": rows(&r),
                "s": s.as_ref().map(rows),
                "ours": ours,
            }));
        }
    }
    out
}

/// A random continuous generalized plant: n states (some unstable), n/2 disturbances, n/4
/// controls and n/4 measurements (at least two), z = [C x; u].
fn plant(n: usize, seed: u64) -> GeneralizedPlant {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let io = (n / 4).max(2);
    let (nw, nu, ny, p) = ((n / 2).max(1), io, io, (n / 2).max(1));
    let a = gaussian(&mut rng, n, n) * (1.0 / (n as f64).sqrt());
    let mut c1 = DMatrix::zeros(p + nu, n);
    c1.view_mut((0, 0), (p, n))
        .copy_from(&gaussian(&mut rng, p, n));
    let mut d12 = DMatrix::zeros(p + nu, nu);
    d12.view_mut((p, 0), (nu, nu)).fill_with_identity();
    let mut b1 = DMatrix::zeros(n, nw + ny);
    b1.view_mut((0, 0), (n, nw))
        .copy_from(&gaussian(&mut rng, n, nw));
    let mut d21 = DMatrix::zeros(ny, nw + ny);
    d21.view_mut((0, nw), (ny, ny))
        .copy_from(&(DMatrix::identity(ny, ny) * 0.1));
    GeneralizedPlant {
        a,
        b1,
        b2: gaussian(&mut rng, n, nu),
        c1,
        c2: gaussian(&mut rng, ny, n),
        d12,
        d21,
    }
}

fn h2_plants() -> Vec<Value> {
    [4usize, 8, 16, 32, 64]
        .iter()
        .map(|&n| {
            let p = plant(n, 100 + n as u64);
            let ours = match h2syn_continuous(&p) {
                Ok(k) => json!({ "h2_norm": k.h2_norm }),
                Err(e) => json!({ "error": e.to_string() }),
            };
            json!({
                "name": format!("random plant n = {n}"),
                "a": rows(&p.a), "b1": rows(&p.b1), "b2": rows(&p.b2), "c1": rows(&p.c1),
                "c2": rows(&p.c2), "d12": rows(&p.d12), "d21": rows(&p.d21),
                "ours": ours,
            })
        })
        .collect()
}

fn write(dir: &Path, name: &str, value: &Value) -> Result<(), String> {
    let path = dir.join(name);
    let file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&path)
        .map_err(|e| format!("{}: {e} (not overwritten)", path.display()))?;
    serde_json::to_writer(file, value).map_err(|e| format!("{}: {e}", path.display()))
}

fn main() -> Result<(), String> {
    let dir = std::env::args()
        .nth(1)
        .ok_or("usage: riccati_export DIR (new files problems.json and h2_plants.json in it)")?;
    let dir = Path::new(&dir);
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    write(dir, "problems.json", &json!(riccati_problems()))?;
    write(dir, "h2_plants.json", &json!(h2_plants()))?;
    eprintln!("wrote {}/problems.json and h2_plants.json", dir.display());
    Ok(())
}
