#!/usr/bin/env python3
"""Fails (exit 1) when the workspace has an import circle, between crates or between files.

Crates: the normal (non-dev) dependencies between workspace members, from `cargo metadata`.
Files: inside each crate, an edge A → B when file A names module B through `crate::b…`,
`super::b…` or `self::b…` (in `use` lines and in paths in the code). Module declarations
(`mod b;`) and re-exports in a crate root or a folder's `mod.rs` (`pub use b::X;`, the facade a
reader sees) are not edges. A file's own `#[cfg(test)] mod tests` may `use super::*` freely.

Usage: scripts/check_import_cycles.py [workspace root]   (prints the circles it finds)
"""

import json
import re
import subprocess
import sys
from pathlib import Path

IDENT = r"[A-Za-z_][A-Za-z0-9_]*"
PATH_RE = re.compile(rf"\b(crate|super|self)((?:::{IDENT})+)")
USE_GROUP_RE = re.compile(r"\buse\s+(crate|super|self)::\{([^;]*)\}\s*;", re.S)


def strip_comments(text: str) -> str:
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    text = re.sub(r"//[^\n]*", "", text)
    return re.sub(r'"(?:\\.|[^"\\])*"', '""', text)


def strip_test_module(text: str) -> str:
    """Drops `#[cfg(test)] mod tests { … }` (its `use super::*` is the file itself)."""
    m = re.search(r"#\[cfg\(test\)\]\s*mod\s+\w+\s*\{", text)
    if not m:
        return text
    depth, i = 1, m.end()
    while i < len(text) and depth:
        depth += {"{": 1, "}": -1}.get(text[i], 0)
        i += 1
    return text[: m.start()] + text[i:]


def module_of(src: Path, file: Path) -> tuple:
    rel = file.relative_to(src).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] in ("lib", "main", "mod"):
        parts = parts[:-1]
    return tuple(parts)


def facade(file: Path, line: str) -> bool:
    """A declaration or re-export in a crate root or a folder's mod.rs."""
    stripped = line.strip()
    if re.match(rf"(pub(\([^)]*\))?\s+)?mod\s+{IDENT}\s*;", stripped):
        return True
    root = file.name in ("lib.rs", "main.rs", "mod.rs")
    return root and re.match(r"pub(\([^)]*\))?\s+use\s", stripped) is not None


def edges_of(src: Path, file: Path, modules: set) -> set:
    me = module_of(src, file)
    here = me if file.name in ("lib.rs", "main.rs", "mod.rs") else me[:-1]
    text = strip_test_module(strip_comments(file.read_text()))
    kept = "\n".join(l for l in text.split(";") if not facade(file, l + ";"))

    def resolve(base: str, rest: list) -> tuple:
        start = {"crate": (), "self": here, "super": here[:-1]}[base]
        while rest and rest[0] == "super":
            start, rest = start[:-1], rest[1:]
        target = start + tuple(rest)
        while target and target not in modules:
            target = target[:-1]
        return target

    found = set()
    for base, tail in PATH_RE.findall(kept):
        found.add(resolve(base, tail.strip(":").split("::")))
    for base, group in USE_GROUP_RE.findall(kept):
        for item in re.split(r"[,\s]+", group):
            head = item.split("::")[0].strip("{} ")
            if re.fullmatch(IDENT, head):
                found.add(resolve(base, [head]))
    return {t for t in found if t and t != me and not (me[: len(t)] == t)}


def cycles(graph: dict) -> list:
    """Strongly connected components with more than one node (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in list(graph):
        if v not in index:
            visit(v)
    return out


def main() -> int:
    root = Path(sys.argv[1] if len(sys.argv) > 1 else ".").resolve()
    meta = json.loads(
        subprocess.run(
            ["cargo", "metadata", "--format-version", "1", "--no-deps"],
            cwd=root, check=True, capture_output=True, text=True,
        ).stdout
    )
    members = {p["name"]: p for p in meta["packages"]}
    crate_graph = {
        name: {d["name"] for d in p["dependencies"] if d["name"] in members and d["kind"] is None}
        for name, p in members.items()
    }
    bad = [("crates", c) for c in cycles(crate_graph)]
    files = 0
    for name, p in members.items():
        src = Path(p["manifest_path"]).parent / "src"
        if not src.is_dir():
            continue
        rs = sorted(src.rglob("*.rs"))
        files += len(rs)
        modules = {module_of(src, f) for f in rs}
        graph = {module_of(src, f): edges_of(src, f, modules) for f in rs}
        for c in cycles(graph):
            bad.append((name, ["::".join(m) or "(root)" for m in c]))
    for where, c in bad:
        print(f"import circle in {where}: {' ↔ '.join(map(str, c))}")
    print(f"import circles: {len(bad)} ({len(members)} crates, {files} files checked)")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
