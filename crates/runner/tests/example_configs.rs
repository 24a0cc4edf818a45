//! Every configuration in `examples/` (the README points newcomers at them) and every cut of
//! `examples/prescriptions/` parses, validates (its prescription read and its tool path
//! planned) and builds a stable loop, as `servo run -c` would.

use run_config::Loaded;
use runner::Plan;
use std::path::Path;

#[test]
fn every_example_config_builds_a_stable_run() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let cuts = std::fs::read_dir(dir.join("prescriptions"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("cut-"))
        });
    let mut seen = 0;
    let configs = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path());
    for path in configs.chain(cuts) {
        if path.extension().is_some_and(|e| e == "toml") {
            let loaded = Loaded::from_file(&path).unwrap_or_else(|e| panic!("{e}"));
            let plan = Plan::new(&loaded).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let radius = plan
                .check_stable()
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert!(radius < 1.0, "{}", path.display());
            seen += 1;
        }
    }
    assert!(seen >= 5, "{seen} example configs in {}", dir.display());
}
