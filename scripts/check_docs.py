#!/usr/bin/env python3
"""The README and the book as tested documents: every ```sh and ```python block runs, in
order, and what a block is shown to print is compared with what it prints.

    python3 scripts/check_docs.py                 # README.md and every page of docs/src/SUMMARY.md
    python3 scripts/check_docs.py PAGE.md ...     # these pages only
    python3 scripts/check_docs.py --list [PAGE]   # what would run, and what is not run and why
    python3 scripts/check_docs.py --self-test     # a copy of the README with one shown number
                                                  # changed must fail the check, a failed
                                                  # block must leave no process behind
    python3 scripts/check_docs.py --jobs N        # pages at once (default: the CPU count)
    python3 scripts/check_docs.py --update [PAGE] # writes what each block printed into its
                                                  # shown output where they differ (blocks
                                                  # with `…` are reported, not rewritten);
                                                  # read the diff before committing it

Each page runs in a fresh folder of its own (blocks of one page follow each other there; pages
run side by side, except that two pages naming the same HIL run `--prefix` never run at once), with
`examples/`, `firmware/` and `scripts/` of the checkout linked into it and this checkout's release binaries first on PATH
(`servo`; `cargo run --release -p servo-cli --` and `cargo run … --example X --` are rewritten
to them). Lines that build or install (`cargo build`, `cargo test`, `pip install`, `make -C
examples/c`, `cd firmware && cargo build`, `rustup target add`, `apt-get install`) are what
.ci/run itself does before this check, and are skipped. Real-time runs
(`--realtime`) run in lockstep: CI machines are not tuned.

Marks, as an HTML comment on the line before a block's fence:
- `<!-- not run: REASON -->`: the block is not run; the reason is required.
- `<!-- exit: N -->`: the block is expected to exit with code N (it shows a failure).
- `<!-- file: NAME -->`: the block (any language) is written to NAME in the page's folder.
- `<!-- tolerance: P% -->`: numbers in the next output block may differ by P % (default 2 %).

Shown output: a ```text block after a runnable block (before the next runnable one) is what
that block prints, stdout and stderr together. Lines are compared in order; a line `…` stands
for any number of lines, and `…` inside a line for any text. Numbers compare within the
tolerance, or within one unit of the last digit shown; numbers on lines about wall-clock time
(`wall`, `real time`, `elapsed`, `took`) are not compared; the page's folder prints as `.`.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

from book_pages import FENCE, ROOT, book_pages, read_page

RELEASE = ROOT / "target" / "release"
SERVO = RELEASE / "servo"
TIMEOUT_S = 600
DEFAULT_TOLERANCE = 0.02
RUNNABLE = {"sh", "bash", "python"}
WALL_CLOCK = re.compile(r"wall|real time|elapsed|took", re.I)
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
MARK = re.compile(r"<!--\s*(not run|exit|file|tolerance):\s*(.*?)\s*-->")
ELLIPSIS = "…"


@dataclass
class Block:
    """One fenced block of a page and the marks before it."""

    line: int
    lang: str
    text: str
    marks: dict[str, str]
    shown: Block | None = None  # the output block that follows a runnable block


@dataclass
class Page:
    path: Path
    blocks: list[Block] = field(default_factory=list)

    @property
    def name(self) -> str:
        try:
            return str(self.path.resolve().relative_to(ROOT))
        except ValueError:
            return str(self.path)


def parse(path: Path) -> Page:
    """The page's blocks, each runnable one paired with the output block shown after it."""
    text = read_page(path)
    page = Page(path)
    last_runnable: Block | None = None
    for m in FENCE.finditer(text):
        before = text[: m.start()].rstrip("\n").rsplit("\n", 1)[-1]
        marks = {k: v for k, v in MARK.findall(before)}
        lang = m.group(1)
        if not lang:
            sys.exit(f"{page.name}:{text[: m.start()].count(chr(10)) + 1}: a block without a "
                     "language: say what it is (sh, python, text, toml, rust, c …)")
        block = Block(text[: m.start()].count("\n") + 1, lang, m.group(2), marks)
        if "not run" in marks and not marks["not run"]:
            sys.exit(f"{page.name}:{block.line}: `not run` needs a reason")
        if lang in RUNNABLE:
            last_runnable = block if "not run" not in marks else None
        elif lang == "text" and last_runnable is not None and last_runnable.shown is None:
            last_runnable.shown = block
        page.blocks.append(block)
    return page


def script_of(block: Block) -> str:
    """The block as it runs here (build and install lines skipped, binaries rewritten)."""
    if block.lang == "python":
        return block.text
    lines = []
    for line in block.text.splitlines():
        bare = line.split("#", 1)[0].strip()
        if bare.startswith(("cargo test", "pip install", "cargo build", "make -C examples",
                            "cargo install", "cd firmware && cargo build",
                            "rustup target add", "apt-get install")):
            continue
        line = line.replace("--realtime", "--lockstep")
        line = re.sub(r"cargo run --release -p servo-cli --", "servo", line)
        line = re.sub(
            r"cargo run --release -p [\w-]+ (?:--features [\w,-]+ )?--example (\w+) --",
            lambda m: str(RELEASE / "examples" / m.group(1)),
            line,
        )
        lines.append(line)
    return "\n".join(lines)


def number_close(shown: str, got: str, tolerance: float) -> bool:
    a, b = float(shown), float(got)
    decimals = shown.lower().split("e")[0]
    unit = 10.0 ** -(len(decimals.split(".")[1]) if "." in decimals else 0)
    if "e" in shown.lower():
        unit *= 10.0 ** int(shown.lower().split("e")[1])
    return abs(a - b) <= max(tolerance * abs(a), unit)


def line_matches(shown: str, got: str, tolerance: float) -> bool:
    """Whether an actual line is the shown one (numbers within tolerance, `…` any text)."""
    pattern = ""
    numbers: list[str] = []
    for i, part in enumerate(shown.strip().split(ELLIPSIS)):
        if i:
            pattern += ".*?"
        pos = 0
        for m in NUMBER.finditer(part):
            pattern += literal(part[pos : m.start()])
            pattern += r"([-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?)"
            numbers.append(m.group())
            pos = m.end()
        pattern += literal(part[pos:])
    m = re.fullmatch(pattern, got.strip())
    if m is None:
        return False
    if WALL_CLOCK.search(shown):
        return True
    return all(number_close(s, g, tolerance) for s, g in zip(numbers, m.groups()))


def literal(text: str) -> str:
    return r"\s+".join(re.escape(w) for w in text.split(" ")) if text else ""


def compare(shown: list[str], got: list[str], tolerance: float) -> str | None:
    """None if the output is what is shown, else the first difference."""
    while got and not got[-1].strip():
        got.pop()
    while shown and not shown[-1].strip():
        shown.pop()
    i = 0
    skipping = False
    for n, want in enumerate(shown):
        if want.strip() == ELLIPSIS:
            skipping = True
            continue
        while i < len(got) and not line_matches(want, got[i], tolerance):
            if not skipping:
                return f"shown line {n + 1}:\n  shown: {want}\n  got:   {got[i]}"
            i += 1
        if i == len(got):
            return f"shown line {n + 1} never printed:\n  shown: {want}"
        skipping = False
        i += 1
    if not skipping and i < len(got):
        return f"printed more than shown, from:\n  got:   {got[i]}"
    return None


@dataclass
class Update:
    """`--update`: shown outputs to rewrite, and what could not be rewritten."""

    rewrites: list[tuple[Block, str]] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)


class PageFailed(Exception):
    """A block failed: what to print."""


def run_page(page: Page, stop_after_first_output: bool = False, update: Update | None = None,
             log=print) -> int:
    """Runs the page's blocks in a fresh folder; raises [`PageFailed`] on the first failure
    (with `update`, records the differing outputs instead). Blocks run."""
    work = Path(tempfile.mkdtemp(prefix="docs-"))
    try:
        (work / "bin").mkdir()
        os.symlink(SERVO, work / "bin" / "servo")
        os.symlink(ROOT / "examples", work / "examples")
        os.symlink(ROOT / "firmware", work / "firmware")
        os.symlink(ROOT / "scripts", work / "scripts")
        env = dict(os.environ, PATH=f"{work / 'bin'}:{os.environ['PATH']}")
        count = 0
        for block in page.blocks:
            if "file" in block.marks:
                (work / block.marks["file"]).write_text(block.text)
            if block.lang not in RUNNABLE or "not run" in block.marks:
                continue
            script = script_of(block)
            if not script.strip():
                continue
            expect = int(block.marks.get("exit", "0"))
            if block.lang == "python":
                command = [sys.executable, "-c", script]
            else:
                strict = "set -euo pipefail\n" if expect == 0 else ""
                command = ["bash", "-c", f"{strict}{script}\nstatus=$?\nwait\nexit $status\n"]
            started = time.monotonic()
            returncode, printed = run_block(command, work, env)
            took = time.monotonic() - started
            where = f"{page.name}:{block.line}"
            out = printed.replace(str(work) + "/", "").replace(str(work), ".")
            if returncode != expect:
                fail(where, f"exit {returncode}, expected {expect}", script,
                     out + side_logs(work))
            if block.shown is not None:
                tolerance = DEFAULT_TOLERANCE
                if "tolerance" in block.shown.marks:
                    tolerance = float(block.shown.marks["tolerance"].rstrip("%")) / 100
                diff = compare(block.shown.text.splitlines(), out.splitlines(), tolerance)
                if diff and update is not None:
                    where = f"{page.name}:{block.shown.line}"
                    if ELLIPSIS in block.shown.text:
                        update.failed.append(f"{where}: differs and shows `…`: edit by hand ({diff})")
                    else:
                        update.rewrites.append((block.shown, out if out.endswith("\n") else out + "\n"))
                        log(f"UPDATE {where}")
                elif diff:
                    fail(f"{page.name}:{block.shown.line}", "output differs from the page's",
                         script, out, diff)
            count += 1
            first = script.splitlines()[0][:90]
            log(f"ok  {where:<48} {took:6.1f} s  {first}")
            if stop_after_first_output and block.shown is not None:
                break
        return count
    finally:
        shutil.rmtree(work, ignore_errors=True)


def rewrite(page: Page, rewrites: list[tuple[Block, str]]) -> None:
    """Writes each shown block's new text into the page at the block's place."""
    text = page.path.read_text()
    for shown, new in sorted(rewrites, key=lambda r: -r[0].line):
        start = sum(len(line) for line in text.splitlines(keepends=True)[: shown.line])
        at = text.find(shown.text, start)
        if at < 0:
            sys.exit(f"{page.name}:{shown.line}: shown output not found in the file (an include?)")
        text = text[:at] + new + text[at + len(shown.text):]
    page.path.write_text(text)


def side_logs(work: Path) -> str:
    """The ends of the `.err` and `.log` files a failed block left in `work` (the stderr of
    its background processes, which the block's own output does not show)."""
    text = ""
    for f in sorted([*work.glob("*.err"), *work.glob("*.log")]):
        tail = f.read_text(errors="replace")[-2000:]
        text += f"\n--- {f.name}\n{tail}"
    return text


def run_block(command: list[str], work: Path, env: dict[str, str]) -> tuple[int, str]:
    """Runs one block in a process group of its own: its exit status and what it printed
    (stdout and stderr). A block waits for its own background jobs (every page's `&` jobs end
    within their block); whatever of its group still runs when it ends — the background
    processes of a block that failed before its `wait`, or of one that ran out of time — is
    ended with it, so that a failed page leaves no run or view behind."""
    p = subprocess.Popen(command, cwd=work, env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, start_new_session=True)
    with ACTIVE_LOCK:
        ACTIVE.add(p.pid)
    chunks: list[bytes] = []
    # Read while the block runs (a full pipe would stall it), until every writer is gone.
    reader = threading.Thread(target=lambda: chunks.extend(iter(p.stdout.readline, b"")),
                              daemon=True)
    reader.start()
    note = ""
    try:
        if not exited_within(p.pid, TIMEOUT_S):
            note = f"\n(the block ran out of its {TIMEOUT_S} s and was ended)"
    finally:
        # The shell is not reaped yet: its pid, the group's id, cannot be another's meanwhile.
        end_group(p.pid)
        returncode = p.wait()
        with ACTIVE_LOCK:
            ACTIVE.discard(p.pid)
    reader.join(timeout=10)
    return returncode, b"".join(chunks).decode(errors="replace") + note


ACTIVE: set[int] = set()
"""The process groups of the blocks running now (ended on Ctrl-C)."""
ACTIVE_LOCK = threading.Lock()


def exited_within(pid: int, timeout_s: float) -> bool:
    """Whether child `pid` exits within `timeout_s`, leaving it unreaped."""
    deadline = time.monotonic() + timeout_s
    while os.waitid(os.P_PID, pid, os.WEXITED | os.WNOWAIT | os.WNOHANG) is None:
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


def running(pid: int, pgid: int | None = None) -> bool:
    """Whether process `pid` runs (a zombie does not), in group `pgid` if given."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    state, _parent, group = stat[stat.rindex(")") + 2:].split()[:3]
    return state != "Z" and (pgid is None or int(group) == pgid)


def group_running(pgid: int) -> bool:
    """Whether any process of group `pgid` runs."""
    return any(running(int(d), pgid) for d in os.listdir("/proc") if d.isdigit())


def end_group(pgid: int) -> None:
    """Ends process group `pgid`: SIGTERM (a run finishes its recording), SIGKILL 5 s later."""
    for sig, grace_s in ((signal.SIGTERM, 5.0), (signal.SIGKILL, 1.0)):
        if not group_running(pgid):
            return
        try:
            os.killpg(pgid, sig)
        except ProcessLookupError:
            return
        deadline = time.monotonic() + grace_s
        while group_running(pgid) and time.monotonic() < deadline:
            time.sleep(0.05)


def fail(where: str, why: str, script: str, out: str, diff: str = "") -> None:
    text = f"FAILED {where}: {why}\n--- block\n{script}\n--- printed\n{out[-8000:]}"
    if diff:
        text += f"\n--- first difference, {diff}"
    raise PageFailed(text)


PREFIX = re.compile(r"--prefix[ =]([A-Za-z0-9_-]+)")


def run_pages(pages: list[Page], jobs: int, first_output: bool) -> int:
    """Runs `pages` `jobs` at a time (pages naming the same `--prefix` one after the other),
    printing each page's lines when it ends; exits on the first failure. Blocks run."""
    locks: dict[str, threading.Lock] = {}
    for page in pages:
        for b in page.blocks:
            for name in PREFIX.findall(b.text):
                locks.setdefault(name, threading.Lock())
    printing = threading.Lock()

    def one(page: Page) -> int:
        names = sorted({n for b in page.blocks for n in PREFIX.findall(b.text)})
        lines: list[str] = []
        for n in names:
            locks[n].acquire()
        try:
            return run_page(page, first_output, None, lines.append)
        except PageFailed as e:
            lines.append(str(e))
            raise
        finally:
            for n in reversed(names):
                locks[n].release()
            with printing:
                print("\n".join(lines), flush=True)

    # The pages with the most runnable blocks first: the long ones do not end up last.
    order = sorted(pages, key=lambda p: -sum(b.lang in RUNNABLE for b in p.blocks))
    with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        futures = [pool.submit(one, p) for p in order]
        total = 0
        failed = False
        for f in futures:
            try:
                total += f.result()
            except PageFailed:
                failed = True
    if failed:
        sys.exit(1)
    return total


def self_test() -> None:
    """A copy of the README whose first shown output has one number changed must fail; a
    failed block must end its background processes."""
    readme = ROOT / "README.md"
    page = parse(readme)
    shown = next(b.shown for b in page.blocks if b.shown is not None)
    m = next(m for m in NUMBER.finditer(shown.text) if float(m.group()) > 0
             and not WALL_CLOCK.search(shown.text[: m.start()].rsplit("\n", 1)[-1]))
    changed = shown.text[: m.start()] + repr(float(m.group()) * 1.5) + shown.text[m.end():]
    with tempfile.TemporaryDirectory() as d:
        copy = Path(d) / "README.md"
        copy.write_text(readme.read_text().replace(shown.text, changed, 1))
        p = subprocess.run([sys.executable, __file__, "--first-output", str(copy)],
                           capture_output=True, text=True)
    if p.returncode == 0 or "output differs" not in p.stdout:
        sys.exit(f"self-test: a changed number ({m.group()} → ×1.5) passed the check:\n{p.stdout}")
    print(f"self-test: the README with {m.group()} shown as {float(m.group()) * 1.5!r} fails the "
          "check, as it must")
    # A block failing under `set -e` before its `wait` ends with its background processes.
    with tempfile.TemporaryDirectory() as d:
        script = "set -euo pipefail\nsleep 300 &\necho $! > bg.pid\nfalse\nwait\n"
        started = time.monotonic()
        code, _ = run_block(["bash", "-c", script], Path(d), dict(os.environ))
        background = int((Path(d) / "bg.pid").read_text())
        if code != 1 or running(background) or time.monotonic() - started > 60:
            sys.exit("self-test: a failed block's background process outlived it")
    print("self-test: a block that fails leaves none of its background processes running")


def main() -> None:
    args = sys.argv[1:]
    if "--self-test" in args:
        return self_test()
    listing = "--list" in args
    first_output = "--first-output" in args
    update = Update() if "--update" in args else None
    values = {args[i + 1] for i, a in enumerate(args[:-1]) if a == "--jobs"}
    paths = [Path(a) for a in args if not a.startswith("--") and a not in values] or [
        ROOT / "README.md", *book_pages()]
    pages = [parse(p) for p in paths]
    if listing:
        for page in pages:
            for b in page.blocks:
                if b.lang in RUNNABLE:
                    state = f"not run: {b.marks['not run']}" if "not run" in b.marks else (
                        "runs, output checked" if b.shown else "runs")
                    print(f"{page.name}:{b.line}: {b.lang}, {state}")
        return
    if not SERVO.exists():
        sys.exit(f"{SERVO} is missing: cargo build --release -p servo-cli first")
    jobs = os.cpu_count() or 1
    for a in args:
        if a.startswith("--jobs"):
            jobs = int(a.split("=", 1)[1]) if "=" in a else int(args[args.index(a) + 1])
    if update is None:
        total = run_pages(pages, jobs, first_output)
    else:
        total = 0
        for page in pages:
            update.rewrites = []
            try:
                total += run_page(page, first_output, update)
            except PageFailed as e:
                sys.exit(str(e))
            if update.rewrites:
                rewrite(page, update.rewrites)
        if update.failed:
            sys.exit("not rewritten:\n" + "\n".join(update.failed))
    print(f"{len(pages)} pages: {total} blocks ran, their shown output as printed")


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:
        # The blocks run in sessions of their own, out of the terminal's reach: end them here.
        with ACTIVE_LOCK:
            groups = list(ACTIVE)
        for group in groups:
            end_group(group)
        print("interrupted: the running blocks were ended", file=sys.stderr)
        os._exit(130)
