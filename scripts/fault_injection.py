#!/usr/bin/env python3
"""Fault injection: HIL runs whose processes are killed with SIGKILL at random moments.

    python3 scripts/fault_injection.py RUNS [--servo PATH] [--seed N] [--duration S] [--out DIR]

Each run is `servo run --hil` (plant, controller and recorder: three processes under it) with a
`servo view` beside it, on one shared-memory prefix for the whole campaign — so every run starts
where a killed process left its resources behind. One of the four processes, drawn at random,
is killed with SIGKILL at a moment drawn uniformly over the run's wall time (the median of three
unkilled runs first); a moment before the victim exists kills it as soon as it appears. Then it checks
what the book promises (docs/src/reference/exit-codes.md, docs/src/how-to/hil.md):

- the run ends, with the exit code its victim's row of the table below names (and the view,
  when it was not the victim, with 0);
- its recording is finished (`servo inspect` reads it whole, naming the end reason) or, when the
  recorder itself was killed, its `.partial` file is salvageable (`servo inspect --salvage`);
- no process of the prefix is left running;
- after the campaign, a clean run on the same prefix completes, and `/dev/shm` holds no more
  entries than before the campaign.

It prints a table of victims, exit codes and recording states, writes it as JSON beside the
recordings (`--out`, default a temporary folder, removed unless `--keep`), and exits 1 if any
run ended otherwise. CI runs a few; the book's validation page shows a campaign of 120.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
VICTIMS = ("plant", "controller", "recorder", "view")
# What the book documents for a killed process (docs/src/reference/exit-codes.md):
#   plant or controller killed mid-run: a lost peer — the recorder finishes the file with end
#     reason peer-lost and the run exits 3; killed after the loop's last tick, the file says
#     completed and the run exits 137 (128 + SIGKILL); killed before its first tick, the run
#     stops the others at once, nothing is recorded (the recorder says so) and it exits 137;
#   recorder killed: the run stops the loop (SIGTERM) and exits 137; the recording is the
#     recorder's `.partial` file, salvageable (`--salvage`) — none if it was killed before it
#     made the file, when the view, which never saw the run, ends 1 after its 30 s wait;
#   view killed: nothing happens to the run (0, completed).
REASON_CODES = {"completed": 0, "peer-lost": 3}
KILLED = 137


def documented(victim: str, end_reason: str, had_file: bool, before_start: bool) -> tuple[int | None, str, set[str]]:
    """(the run's exit code, the recording's state, the end reasons allowed) for `victim`
    (`had_file`: the recorder had made its file when it was killed; `before_start`: the
    recorder said the run ended before it began)."""
    if victim == "view":
        return 0, "finished", {"completed"}
    if victim == "recorder":
        return KILLED, "partial" if had_file else "missing", {""}
    if before_start:
        return KILLED, "missing", {""}
    code = REASON_CODES.get(end_reason)  # None: not an end the book documents for it
    if code == 0:
        code = KILLED  # completed: killed after the loop's last tick
    return code, "finished", set(REASON_CODES)


def processes(prefix: str) -> dict[str, int]:
    """PID of each process of `prefix` by role: plant, controller, recorder, view, run."""
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            args = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        args = [a.decode(errors="replace") for a in args if a]
        at = args.index("--prefix") if "--prefix" in args else None
        if at is None or args[at + 1 : at + 2] != [prefix]:
            continue
        found["recorder" if args[1] == "record" else args[1]] = int(entry.name)
    return found


def shm_entries() -> int:
    return len(os.listdir("/dev/shm"))


def recording_state(servo: str, path: Path) -> tuple[str, str]:
    """("finished", end reason) when the recording reads whole; ("partial", "") when only its
    `.partial` exists and is salvageable; ("missing"/"damaged", detail) otherwise."""
    if path.exists():
        p = subprocess.run([servo, "inspect", "--json", str(path)], capture_output=True, text=True)
        if p.returncode == 0:
            return "finished", json.loads(p.stdout)["end"].get("reason", "?")
        return "damaged", p.stderr.strip().splitlines()[-1] if p.stderr.strip() else ""
    partials = sorted(path.parent.glob(path.name + ".*.partial"))  # NAME.<pid>.partial
    if partials:
        p = subprocess.run([servo, "inspect", "--salvage", "--json", str(partials[0])], capture_output=True, text=True)
        return ("partial", "") if p.returncode == 0 else ("damaged", p.stderr.strip()[-200:])
    return "missing", ""


def start(servo: str, prefix: str, duration: float, out: Path) -> tuple[subprocess.Popen, subprocess.Popen]:
    run = subprocess.Popen([servo, "run", "--hil", "-q", "--prefix", prefix, "--duration", str(duration),
                            "--out", str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    view = subprocess.Popen([servo, "view", "--prefix", prefix, "--port", "0", "--every", "100"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    return run, view


def finish(p: subprocess.Popen, timeout: float) -> tuple[int | None, str]:
    try:
        _, err = p.communicate(timeout=timeout)
        return p.returncode, err
    except subprocess.TimeoutExpired:
        p.kill()
        _, err = p.communicate()
        return None, err


def one_run(servo: str, prefix: str, duration: float, out: Path, victim: str | None, at_s: float) -> dict:
    """One run; `victim` killed `at_s` after the start (None: no kill)."""
    t0 = time.monotonic()
    run, view = start(servo, prefix, duration, out)
    killed_at, phase, had_file = None, "none", True
    if victim is not None:
        while time.monotonic() - t0 < at_s and run.poll() is None:
            time.sleep(0.002)
        deadline = time.monotonic() + 30
        while killed_at is None and time.monotonic() < deadline and run.poll() is None:
            pid = processes(prefix).get(victim)
            if pid is None:
                time.sleep(0.001)
                continue
            had_file = any(out.parent.glob(out.name + ".*.partial"))
            try:
                os.kill(pid, signal.SIGKILL)
                killed_at = time.monotonic() - t0
                phase = "at its moment" if killed_at <= at_s + 0.05 else "on appearing"
            except ProcessLookupError:
                continue
        if killed_at is None:
            phase = "ended first"
    run_code, run_err = finish(run, 120)
    view_code, view_err = finish(view, 60)
    wall = time.monotonic() - t0
    left = processes(prefix)
    for pid in left.values():
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    state, reason = recording_state(servo, out)
    return {"victim": victim, "at_s": round(at_s, 3), "killed_at_s": killed_at and round(killed_at, 3),
            "phase": phase, "had_file": had_file, "run_exit": run_code, "view_exit": view_code, "recording": state,
            "end_reason": reason, "left_running": sorted(left), "wall_s": round(wall, 2),
            "stderr": run_err.strip().splitlines()[-4:], "view_stderr": view_err.strip().splitlines()[-1:]}


def judge(r: dict) -> list[str]:
    """What in run `r` is not as documented (empty: as documented)."""
    wrong = []
    if r["left_running"]:
        wrong.append(f"left running: {r['left_running']}")
    if r["phase"] == "ended first":
        return wrong  # the victim had ended before its moment: nothing was killed
    before_start = any("before the run began" in line for line in r["stderr"])
    code, state, reasons = documented(r["victim"], r["end_reason"], r["had_file"], before_start)
    if r["run_exit"] != code:
        wrong.append(f"run exit {r['run_exit']}, documented {code}")
    view_codes = {0, 1} if state == "missing" else {0}
    if r["victim"] != "view" and r["view_exit"] not in view_codes:
        wrong.append(f"view exit {r['view_exit']}")
    if r["recording"] != state or r["end_reason"] not in reasons:
        wrong.append(f"recording {r['recording']} ({r['end_reason']}), documented {state} {sorted(reasons)}")
    return wrong


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs", type=int)
    ap.add_argument("--servo", default=str(ROOT / "target" / "release" / "servo"))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--duration", type=float, default=1.0, help="simulated seconds per run")
    ap.add_argument("--out", type=Path)
    ap.add_argument("--keep", action="store_true")
    a = ap.parse_args()
    rng = random.Random(a.seed)
    work = a.out or Path(tempfile.mkdtemp(prefix="fault-injection-"))
    work.mkdir(parents=True, exist_ok=True)
    prefix = f"fi-{os.getpid()}"
    shm_before = shm_entries()
    walls = [one_run(a.servo, prefix, a.duration, work / f"base{i}.mcap", None, 0)["wall_s"] for i in range(3)]
    span = sorted(walls)[1]  # the median of three
    print(f"seed {a.seed}; unkilled runs take {span:.2f} s of wall time; killing over [0, {span:.2f}] s", flush=True)
    results, failures = [], 0
    for i in range(a.runs):
        victim = rng.choice(VICTIMS)
        at_s = rng.uniform(0, span)
        r = one_run(a.servo, prefix, a.duration, work / f"run{i}.mcap", victim, at_s)
        r["wrong"] = judge(r)
        failures += bool(r["wrong"])
        results.append(r)
        print(f"{i:4d} {victim:10s} at {at_s:6.3f} s ({r['phase']:13s}) run {r['run_exit']} view {r['view_exit']} "
              f"recording {r['recording']} {r['end_reason']}" + (f"  WRONG: {r['wrong']}" if r["wrong"] else ""),
              flush=True)
    last = one_run(a.servo, prefix, a.duration, work / "after.mcap", None, 0)
    after_ok = last["run_exit"] == 0 and last["recording"] == "finished" and last["end_reason"] == "completed"
    leaked = shm_entries() - shm_before
    table = collections.Counter((r["victim"], r["phase"], r["run_exit"], r["view_exit"], r["recording"], r["end_reason"])
                                for r in results)
    print(f"\n{a.runs} runs, {failures} not as documented; the run after them on the same prefix: "
          f"{'completed' if after_ok else last}; /dev/shm entries left: {leaked:+d}")
    print("| killed | moment | runs | run exit | view exit | recording | end reason |")
    print("|---|---|---|---|---|---|---|")
    for (victim, phase, run_exit, view_exit, rec, reason), n in sorted(table.items(), key=str):
        view = "—" if victim == "view" else view_exit
        print(f"| {victim} | {phase} | {n} | {run_exit} | {view} | {rec} | {reason or '—'} |")
    (work / "fault_injection.json").write_text(json.dumps({"runs": results, "after": last, "shm_leaked": leaked}, indent=1))
    if not a.keep and a.out is None:
        shutil.rmtree(work)
    return 0 if failures == 0 and after_ok and leaked <= 0 else 1


if __name__ == "__main__":
    sys.exit(main())
