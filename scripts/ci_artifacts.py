#!/usr/bin/env python3
"""Links what a test build made to stable names, so that CI runs what the test stage built
instead of building again with other features (`cargo run -p X` or `cargo build -p X` resolves
features for X alone and recompiles the crates they change).

    cargo test --workspace --release --no-run --message-format=json | \
        python3 scripts/ci_artifacts.py DIR NAME... [--libs LIBDIR LIB...]

Each NAME is a binary or example target of the workspace; `DIR/NAME` becomes a link to the
executable the build made for it. Each LIB is a library target whose shared and static
libraries (`libLIB.so`, `libLIB.a`) are linked into LIBDIR, beside the pkg-config files their
build scripts wrote there (a test build leaves them in `deps/`). Exits 1 naming what the build
did not make.
"""

import json
import os
import sys


def link(src: str, dest: str) -> None:
    if os.path.lexists(dest):
        os.remove(dest)
    os.symlink(os.path.abspath(src), dest)
    print(f"{dest} -> {src}")


def main() -> None:
    args = sys.argv[1:]
    libs_at = args.index("--libs") if "--libs" in args else len(args)
    out, names = args[0], set(args[1:libs_at])
    lib_dir, lib_names = (args[libs_at + 1], set(args[libs_at + 2 :])) if libs_at < len(args) else (None, set())
    found, libraries = {}, {}
    for line in sys.stdin:
        try:
            m = json.loads(line)
        except json.JSONDecodeError:
            continue
        if m.get("reason") != "compiler-artifact" or m["profile"]["test"]:
            continue
        target = m["target"]
        kinds = set(target["kind"])
        if m.get("executable") and kinds & {"bin", "example"} and target["name"] in names:
            found[target["name"]] = m["executable"]
        if kinds & {"cdylib", "staticlib"} and target["name"] in lib_names:
            libraries[target["name"]] = [
                f for f in m["filenames"] if f.endswith((".so", ".a"))
            ]
    missing = (names - found.keys()) | (lib_names - libraries.keys())
    if missing:
        sys.exit(f"the test build made nothing for {', '.join(sorted(missing))}")
    os.makedirs(out, exist_ok=True)
    for name, exe in sorted(found.items()):
        link(exe, os.path.join(out, name))
    for files in libraries.values():
        for f in files:
            link(f, os.path.join(lib_dir, os.path.basename(f)))


if __name__ == "__main__":
    main()
