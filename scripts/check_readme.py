#!/usr/bin/env python3
"""The README as a tested document: runs every command it shows and fails on the first that
fails, naming it and the README line it came from.

What runs, in order, in one fresh folder (the first block makes the default run's `run.mcap`):
- every ```sh block, as a bash script, beside a link to `examples/` (`servo` and `cargo run … --example X` are the release
  binaries this checkout built: `cargo build --release -p servo-cli` and the examples); real-time runs (`--realtime`) run in lockstep, as CI machines are not tuned;
  `cargo test` and `pip install` lines are what .ci/run itself runs and are skipped here;
- every inline `servo …` example outside tables' syntax summaries: spans with no placeholder
  (`[…]`, `|`, `…`, `<…>`, or a single capital letter standing for a value).

    python3 scripts/check_readme.py [README.md]
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SERVO = ROOT / "target" / "release" / "servo"
TIMEOUT_S = 600
STANDALONE = {
    "run", "machine", "inspect", "replay", "export", "config", "budget", "spectrum", "frf",
    "identify", "tune", "synth", "stiffness", "intermittent-cut", "spindle-errors", "thesis",
    "completions",
}
# Examples the README shows failing on purpose, with the exit code it says they give.
EXPECTED_EXIT = {"servo run --scenario step --amplitude 40e-6": 5}

# Flags that take no value (a span ending in any other flag is a fragment of prose).
SWITCHES = {"--dump", "--hil", "--json", "--no-record", "--retune", "--sweep", "--overwrite"}
PLACEHOLDER = re.compile(r"[\[\]|…<>]|(^|\s)[A-Z]{1,2}(\s|$)|\bIN:OUT\b|\bDATE\b")


# Files a span may name: the commented configurations in examples/ (anything else is a file
# the reader makes first, shown in a block).
EXAMPLE_FILES = {f"examples/{p.name}" for p in (ROOT / "examples").glob("*.toml")}


def blocks(text: str):
    """(line number, script) of every ```sh block."""
    for m in re.finditer(r"^```sh\n(.*?)^```", text, re.S | re.M):
        yield text[: m.start()].count("\n") + 2, m.group(1)


def inline_examples(text: str):
    """(line number, command) of every runnable inline `servo …` span."""
    in_block = False
    for n, line in enumerate(text.splitlines(), 1):
        if line.startswith("```"):
            in_block = not in_block
            continue
        if in_block:
            continue
        for span in re.findall(r"`(servo [^`]+)`", line):
            words = span.split()
            # An example invocation: a command of its own (not a HIL process that needs its
            # peers, nor the real-time qualification) with at least one flag; a bare
            # `servo synth` in prose names the command, it does not show how to run it.
            if (
                len(words) < 3
                or words[1] not in STANDALONE
                or not any(w.startswith("-") for w in words[2:])
                or PLACEHOLDER.search(span)
                or "--help" in words
                or (words[-1].startswith("-") and words[-1] not in SWITCHES)
                or any(w.endswith(".toml") and w not in EXAMPLE_FILES for w in words)
                or ("ss" in words and "--ss-file" not in words)
            ):
                continue
            yield n, span


def script_of(block: str) -> str:
    lines = []
    for line in block.splitlines():
        bare = line.split("#", 1)[0].strip()
        # What .ci/run itself builds and installs (at the checkout's root, not in this folder).
        if bare.startswith(("cargo test", "pip install", "cargo build", "make -C examples")):
            continue
        line = line.replace("--realtime", "--lockstep")
        # `cargo run` of this checkout's binaries: the ones CI built (a cargo run from another
        # folder would miss the checkout's .cargo/config.toml and rebuild without it).
        line = re.sub(r"cargo run --release -p servo-cli --", "servo", line)
        line = re.sub(
            r"cargo run --release -p [\w-]+ (?:--features [\w,-]+ )?--example (\w+) --",
            lambda m: str(ROOT / "target" / "release" / "examples" / m.group(1)),
            line,
        )
        lines.append(line)
    return "\n".join(lines)


def run(what: str, where: int, script: str, cwd: Path, expect: int = 0) -> None:
    env = dict(os.environ, PATH=f"{SERVO.parent}:{os.environ['PATH']}")
    started = time.monotonic()
    bash = f"set -euo pipefail\n{script}\nwait\n" if expect == 0 else script
    p = subprocess.run(["bash", "-c", bash], cwd=cwd, env=env, capture_output=True, text=True, timeout=TIMEOUT_S)
    took = time.monotonic() - started
    if p.returncode != expect:
        print(f"FAILED README.md:{where} ({what}, exit {p.returncode}, {took:.1f} s):\n{script}")
        print("--- stdout\n" + p.stdout[-4000:] + "\n--- stderr\n" + p.stderr[-4000:])
        sys.exit(1)
    print(f"ok  README.md:{where:<5} {took:6.1f} s  {script.splitlines()[0][:100] if script else what}")


def main() -> None:
    args = [a for a in sys.argv[1:] if a != "--list"]
    readme = Path(args[0] if args else ROOT / "README.md")
    text = readme.read_text()
    if "--list" in sys.argv:
        for line, block in blocks(text):
            print(f"README.md:{line}: block\n{script_of(block)}")
        for line, command in inline_examples(text):
            print(f"README.md:{line}: {command}")
        return
    if not SERVO.exists():
        sys.exit(f"{SERVO} is missing: cargo build --release -p servo-cli first")
    work = Path(tempfile.mkdtemp(prefix="readme-"))
    try:
        # `servo` must resolve to this checkout's binary, under the name the README uses.
        (work / "bin").mkdir()
        os.symlink(SERVO, work / "bin" / "servo")
        os.environ["PATH"] = f"{work / 'bin'}:{os.environ['PATH']}"
        # The reader runs the README from the checkout's root, where examples/ is.
        os.symlink(ROOT / "examples", work / "examples")
        count = 0
        for line, block in blocks(text):
            script = script_of(block)
            if script.strip():
                run("sh block", line, script, work)
                count += 1
        for line, command in inline_examples(text):
            # Each in a folder of its own (with the default run's recording if it reads it).
            own = Path(tempfile.mkdtemp(dir=work))
            if "run.mcap" in command.split():
                shutil.copy(work / "run.mcap", own / "run.mcap")
            os.symlink(ROOT / "examples", own / "examples")
            run("inline example", line, command, own, EXPECTED_EXIT.get(command, 0))
            count += 1
        print(f"README.md: {count} commands and blocks ran and succeeded")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
