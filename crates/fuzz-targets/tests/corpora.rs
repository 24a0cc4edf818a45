//! Every committed input of every fuzz target replayed: the seeds made from our own files
//! (`fuzz/seeds/`, each accepted all the way: built, opened, read intact), the campaigns'
//! minimised corpora (`fuzz/corpus/`) and the inputs that once found a fault
//! (`fuzz/regressions/`, each fixed). A target that panics on one fails here with the file's
//! name.

use std::path::{Path, PathBuf};

/// The files of `fuzz/<kind>/<target>/`, sorted (none when the folder is absent).
fn inputs(kind: &str, target: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fuzz")
        .join(kind)
        .join(target);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map(|d| d.map(|e| e.expect("a readable entry").path()).collect())
        .unwrap_or_default();
    files.sort();
    files
}

/// Runs `target` on the file `path`; whether it accepted it, or the panic's message.
fn replay(
    scratch: &fuzz_targets::Scratch,
    target: fuzz_targets::Target,
    path: &Path,
) -> Result<bool, String> {
    let data = std::fs::read(path).expect("a readable input");
    std::panic::catch_unwind(|| target(scratch, &data)).map_err(|e| {
        e.downcast_ref::<String>()
            .cloned()
            .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_default()
    })
}

#[test]
fn every_seed_is_accepted_all_the_way() {
    let scratch = fuzz_targets::Scratch::new().expect("a scratch folder");
    for (name, target) in fuzz_targets::TARGETS {
        let seeds = inputs("seeds", name);
        assert!(
            !seeds.is_empty(),
            "target {name} has seeds in fuzz/seeds/{name}"
        );
        for path in &seeds {
            assert_eq!(
                replay(&scratch, target, path),
                Ok(true),
                "target {name} on its seed {}",
                path.display()
            );
        }
    }
}

#[test]
fn every_corpus_and_regression_input_is_survived() {
    let scratch = fuzz_targets::Scratch::new().expect("a scratch folder");
    for (name, target) in fuzz_targets::TARGETS {
        for path in inputs("corpus", name)
            .iter()
            .chain(&inputs("regressions", name))
        {
            if let Err(panic) = replay(&scratch, target, path) {
                panic!("target {name} failed on {}: {panic}", path.display());
            }
        }
    }
}
