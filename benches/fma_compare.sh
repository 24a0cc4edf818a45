#!/usr/bin/env bash
# The state-space tick of the default build (portable: baseline ISA, vector width chosen at run
# time, separate multiply and add) beside a native build with fused multiply-add
# (`-C target-cpu=native`, servo-core's `fma` feature), in one session, alternating twice.
#
#   bash benches/fma_compare.sh            # prints one table row per state-space order
set -euo pipefail
cd "$(dirname "$0")/.."
filter='state_space_[0-9]+/servo_core'
native=(env CARGO_TARGET_DIR=target/fma-native RUSTFLAGS="-C target-cpu=native"
  cargo bench -q --bench servo_core --features servo-core/fma)
cargo bench -q --bench servo_core --no-run 2>/dev/null
"${native[@]}" --no-run 2>/dev/null
for round in 1 2; do
  cargo bench -q --bench servo_core -- "$filter" --save-baseline "portable$round" >/dev/null
  "${native[@]}" -- "$filter" --save-baseline "native$round" >/dev/null
done
python3 - <<'PY'
import json, pathlib
def best(root, group, bench, tag):
    ns = []
    for r in (1, 2):
        p = pathlib.Path(root) / "criterion" / group / bench / f"{tag}{r}" / "estimates.json"
        ns.append(json.loads(p.read_text())["mean"]["point_estimate"])
    return min(ns)
print("| tick | portable, dispatched (ns) | portable, baseline ISA (ns) | native FMA build (ns) | dispatched / native |")
print("|---|---|---|---|---|")
for n in (8, 13, 27):
    g = f"state_space_{n}"
    d = best("target", g, "servo_core", "portable")
    b = best("target", g, "servo_core_baseline_isa", "portable")
    f = best("target/fma-native", g, "servo_core", "native")
    print(f"| `StateSpace<{n},1,1>` | {d:.1f} | {b:.1f} | {f:.1f} | {d / f:.2f} |")
PY
