#!/usr/bin/env python3
"""Links the executables a test build made to stable names, so that CI runs what the test stage
built instead of building again with other features (`cargo run -p X` resolves features for X
alone and recompiles the crates they change).

    cargo test --workspace --release --no-run --message-format=json | \
        python3 scripts/ci_artifacts.py DIR NAME...

Each NAME is a binary or example target of the workspace; `DIR/NAME` becomes a link to the
executable the build made for it. Exits 1 naming what the build did not make.
"""

import json
import os
import sys


def main() -> None:
    out, names = sys.argv[1], set(sys.argv[2:])
    found = {}
    for line in sys.stdin:
        try:
            m = json.loads(line)
        except json.JSONDecodeError:
            continue
        if m.get("reason") != "compiler-artifact" or not m.get("executable"):
            continue
        target = m["target"]
        if m["profile"]["test"] or not set(target["kind"]) & {"bin", "example"}:
            continue
        if target["name"] in names:
            found[target["name"]] = m["executable"]
    missing = names - found.keys()
    if missing:
        sys.exit(f"the test build made no executable for {', '.join(sorted(missing))}")
    os.makedirs(out, exist_ok=True)
    for name, exe in sorted(found.items()):
        link = os.path.join(out, name)
        if os.path.lexists(link):
            os.remove(link)
        os.symlink(exe, link)
        print(f"{link} -> {exe}")


if __name__ == "__main__":
    main()
