//! Every configuration in `examples/` (the README points newcomers at them) parses, validates
//! and builds a stable loop, as `servo run -c` would.

use runner::config::Loaded;
use runner::Plan;
use std::path::Path;

#[test]
fn every_example_config_builds_a_stable_run() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let mut seen = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
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
    assert!(seen >= 4, "{seen} example configs in {}", dir.display());
}
