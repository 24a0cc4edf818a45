#!/usr/bin/env python3
"""Soak: one HIL run held for DURATION seconds of wall time with everything a lab does to it.

    python3 scripts/soak.py DURATION [--servo PATH] [--split-s S] [--out DIR] [--json FILE]

(`scripts/soak.sh DURATION` runs it.) One lockstep `servo run --hil` (plant, controller and
recorder under it) records in parts (`--split-s`, 1 s of run each by default) beside a
`servo view` served over TLS; while it runs, on a schedule:

- the official Foxglove client (`scripts/mcap-js/soak_client.mjs`: `npm ci --prefix
  scripts/mcap-js` first) connects over `wss://` with the token and the pinned fingerprint,
  reads the overview and the parameters, and leaves (every 10 s);
- `servo ctl gain` changes the gain scale (every 7 s) and `servo ctl load` swaps in a
  controller (every 30 s, two `servo tune` designs in turn);
- the recorder is paused with SIGSTOP for 0.3 s and resumed with SIGCONT (every 13 s): the
  plant holds the loop for it (up to 0.5 s at a time; a longer pause loses what runs meanwhile);
- every finished part is checked (`servo inspect`: every CRC and index, and the ticks it holds
  against its `end` record), its ticks followed on from the part before, then deleted — an
  hour at full rate is ~140 GB, more than a disk holds;
- the resident memory and open descriptors of the five processes are sampled (every 2 s).

At the end (`servo ctl stop`) it checks that the run ended as stopped, that the parts hold
every tick of the run once (frames recorded = ticks, 0 lost), that each process's memory and
descriptors at the end are within 5 % of the end of the first minute (memory on soaks of 10
minutes or more: before, it is warm-up; descriptors always, against the first third of a
shorter soak), and that `/dev/shm` holds nothing of the run. It prints a report, writes it as
JSON (`--json`), and exits 1 if any check failed.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fault_injection import processes  # noqa: E402  (the HIL processes of a prefix, by role)

ROOT = Path(__file__).resolve().parents[1]
CLIENT = ROOT / "scripts" / "mcap-js" / "soak_client.mjs"
ROLES = ("run", "plant", "controller", "recorder", "view")
# What is done, and how often (s of wall time).
EVERY = {"client": 10.0, "gain": 7.0, "load": 30.0, "pause": 13.0, "sample": 2.0, "parts": 1.0}
# Shorter than the lockstep plant's patience with a recorder (daq_io::recorder_pace::PATIENCE,
# 0.5 s): a pause the plant holds through. A longer one loses the ticks run meanwhile.
PAUSE_S = 0.3
TOLERANCE = 0.05
# Memory is judged on soaks this long or longer: in a shorter one the end of its first third
# is still the warm-up (the compressors' buffers, the first controller load, the allocator's
# arenas); it is reported all the same. Descriptors are judged on every soak.
JUDGED_AFTER_S = 600.0


def resources(pid: int) -> tuple[int, int] | None:
    """(resident memory in kB, open descriptors) of `pid`, None once it is gone."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
        rss = next(int(line.split()[1]) for line in status.splitlines() if line.startswith("VmRSS:"))
        return rss, len(os.listdir(f"/proc/{pid}/fd"))
    except (OSError, StopIteration):
        return None


def shm_of(prefix: str) -> list[str]:
    """The `/dev/shm` entries naming `prefix` (iceoryx2 names its segments after the service)."""
    return sorted(n for n in os.listdir("/dev/shm") if prefix in n)


class Parts:
    """The finished parts of the recording, checked in order and deleted."""

    def __init__(self, servo: str, out: Path):
        self.servo, self.out = servo, out
        self.next = 0          # the next part's index
        self.ticks = 0         # ticks held by the parts checked so far
        self.bytes = 0
        self.problems: list[str] = []
        self.end: dict = {}    # the last part's end record (the run's)

    def path(self, index: int) -> Path:
        return self.out.with_name(f"{self.out.stem}_{index:05d}.mcap")

    def check_ready(self) -> None:
        """Checks and deletes every part moved into place since the last call."""
        while self.path(self.next).exists():
            self.check(self.path(self.next))

    def check(self, path: Path) -> None:
        p = subprocess.run([self.servo, "inspect", "--json", str(path)], capture_output=True, text=True)
        if p.returncode != 0:
            self.problems.append(f"{path.name}: {p.stderr.strip()[-300:]}")
            end = {}
        else:
            end = json.loads(p.stdout)["end"]
            if end.get("part") != str(self.next) or end.get("part_first_tick") != str(self.ticks):
                self.problems.append(f"{path.name}: part {end.get('part')} from tick {end.get('part_first_tick')}, "
                                     f"expected part {self.next} from tick {self.ticks}")
            self.ticks += int(end.get("part_ticks", 0))
        self.bytes += path.stat().st_size
        self.end = end
        path.unlink()
        self.next += 1


def run_soak(a: argparse.Namespace, work: Path) -> dict:
    servo, prefix = a.servo, f"soak-{os.getpid()}"
    out = work / "soak.mcap"
    for name, bandwidth in (("pid_a.toml", "500"), ("pid_b.toml", "800")):
        subprocess.run([servo, "tune", "--bandwidth-hz", bandwidth, "--out", str(work / name)],
                       check=True, stdout=subprocess.DEVNULL)
    run = subprocess.Popen([servo, "run", "--hil", "-q", "--json", "--prefix", prefix, "--duration", "86400",
                            "--out", str(out), "--split-s", str(a.split_s)],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    view_txt = work / "view.txt"
    with open(view_txt, "w") as vo, open(work / "view.err", "w") as ve:
        view = subprocess.Popen([servo, "view", "--prefix", prefix, "--host", "0.0.0.0", "--port", "0",
                                 "--every", "10"], stdout=vo, stderr=ve)
    parts = Parts(servo, out)
    actions = {k: 0 for k in EVERY}
    failed_actions: list[str] = []
    samples: list[dict] = []
    t0 = time.monotonic()
    due = {k: t0 + v for k, v in EVERY.items()}
    url = pin = None
    loads = 0
    visits: list[tuple[float, subprocess.Popen]] = []
    while time.monotonic() - t0 < a.duration and run.poll() is None:
        now = time.monotonic()
        procs = processes(prefix)
        if url is None and view_txt.read_text().count("\n") >= 2:
            url, _, pin = view_txt.read_text().split()[:3]
        for what in [k for k, at in due.items() if now >= at]:
            due[what] = now + EVERY[what]
            ok = True
            if what == "parts":
                parts.check_ready()
                continue
            if what == "sample":
                row = {"t_s": round(now - t0, 1)}
                for role in ROLES:
                    got = resources(procs[role]) if role in procs else None
                    if got:
                        row[role] = got
                samples.append(row)
                continue
            if what == "client" and url:
                # A visit lasts as long as 20 samples take: it goes on beside the rest.
                visits.append((now - t0, subprocess.Popen(["node", str(CLIENT), url, pin, "20"],
                                                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)))
            elif what == "gain":
                scale = ("1.1", "0.9", "1.0")[actions["gain"] % 3]
                ok = subprocess.run([servo, "ctl", "--prefix", prefix, "gain", scale],
                                    capture_output=True).returncode == 0
            elif what == "load":
                loads += 1
                file = work / ("pid_b.toml" if loads % 2 else "pid_a.toml")
                ok = subprocess.run([servo, "ctl", "--prefix", prefix, "load", str(file)],
                                    capture_output=True).returncode == 0
            elif what == "pause" and "recorder" in procs:
                os.kill(procs["recorder"], signal.SIGSTOP)
                time.sleep(PAUSE_S)
                os.kill(procs["recorder"], signal.SIGCONT)
            else:
                continue
            actions[what] += 1
            if not ok:
                failed_actions.append(f"{what} at {now - t0:.1f} s")
        for visit in [v for v in visits if v[1].poll() is not None]:
            visits.remove(visit)
            if visit[1].returncode != 0:
                why = visit[1].stderr.read().decode(errors="replace").strip()
                failed_actions.append(f"client at {visit[0]:.1f} s: {why}")
        time.sleep(0.05)
    for _, visit in visits:  # the run's end closes the visits still open: not a failure
        visit.kill()
        visit.wait()
    stopped = subprocess.run([servo, "ctl", "--prefix", prefix, "stop"], capture_output=True).returncode == 0
    try:
        stdout, stderr = run.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        run.kill()
        stdout, stderr = run.communicate()
    try:
        view_code = view.wait(timeout=30)
    except subprocess.TimeoutExpired:
        view.kill()
        view_code = None
    wall = time.monotonic() - t0
    parts.check_ready()
    left = shm_of(prefix)
    summary = json.loads(stdout) if run.returncode == 0 and stdout.strip() else {}
    return {"prefix": prefix, "wall_s": round(wall, 1), "split_s": a.split_s, "run_exit": run.returncode,
            "view_exit": view_code, "stopped": stopped, "stderr": stderr.strip().splitlines()[-5:],
            "summary": summary, "end": parts.end, "parts": parts.next, "part_ticks": parts.ticks,
            "recorded_bytes": parts.bytes, "part_problems": parts.problems, "actions": actions,
            "failed_actions": failed_actions, "samples": samples, "shm_left": left}


def baseline_and_end(samples: list[dict], role: str, first_s: float) -> tuple[tuple, tuple] | None:
    """(resources at the end of the first period, at the end) of `role`."""
    rows = [s for s in samples if role in s]
    early = [s for s in rows if s["t_s"] <= first_s]
    if not early or len(rows) < 2:
        return None
    return tuple(early[-1][role]), tuple(rows[-1][role])


def judge(r: dict, duration: float) -> list[str]:
    wrong = []
    if r["run_exit"] != 0:
        wrong.append(f"run exit {r['run_exit']}: {r['stderr']}")
    if r["end"].get("reason") != "stopped":
        wrong.append(f"end reason {r['end'].get('reason')}")
    ticks = int(r["end"].get("ticks", -1))
    if r["part_ticks"] != ticks:
        wrong.append(f"the parts hold {r['part_ticks']} ticks, the run ran {ticks}")
    meta = r["summary"].get("meta", {})
    hil = meta.get("hil") or {}
    lost = {"frames dropped by the recorder": meta.get("dropped_frames"),
            "ticks with truth but no telemetry": hil.get("truth_only_ticks"),
            "bad blocks": hil.get("bad_blocks")}
    for what, n in lost.items():
        if n != 0:
            wrong.append(f"{what}: {n}")
    if meta.get("recorded_messages") != 2 * ticks:
        wrong.append(f"{meta.get('recorded_messages')} messages recorded for {ticks} ticks (two each)")
    wrong += r["part_problems"] + [f"refused: {f}" for f in r["failed_actions"]]
    if r["shm_left"]:
        wrong.append(f"/dev/shm entries left: {r['shm_left']}")
    first = min(60.0, duration / 3)
    for role in ROLES:
        pair = baseline_and_end(r["samples"], role, first)
        if pair is None:
            wrong.append(f"{role}: not sampled")
            continue
        (rss0, fd0), (rss1, fd1) = pair
        if duration >= JUDGED_AFTER_S and rss1 > rss0 * (1 + TOLERANCE):
            wrong.append(f"{role}: resident memory {rss0} → {rss1} kB")
        if fd1 > fd0 * (1 + TOLERANCE):
            wrong.append(f"{role}: open descriptors {fd0} → {fd1}")
    return wrong


def report(r: dict, wrong: list[str], duration: float) -> None:
    ticks = int(r["end"].get("ticks", 0))
    print(f"soak: {r['wall_s']:.0f} s of wall time, {ticks} ticks ({ticks / 199_600:.1f} s of run at 199.6 kHz), "
          f"{r['parts']} parts of {r['split_s']} s checked and deleted ({r['recorded_bytes'] / 1e9:.2f} GB), "
          f"frames recorded {r['part_ticks']} = ticks {ticks}: {'yes' if r['part_ticks'] == ticks else 'NO'}")
    meta = r["summary"].get("meta", {})
    hil = meta.get("hil") or {}
    print(f"  lost: {meta.get('dropped_frames')} frames dropped, {hil.get('truth_only_ticks')} ticks without "
          f"telemetry, {hil.get('bad_blocks')} bad blocks; {meta.get('recorded_messages')} messages recorded")
    acts = r["actions"]
    print(f"  done while running: {acts['client']} Foxglove client visits over wss, {acts['gain']} gain changes, "
          f"{acts['load']} controller loads, {acts['pause']} recorder pauses (SIGSTOP {PAUSE_S:g} s)")
    first = min(60.0, duration / 3)
    print(f"  {'process':<11} {'RSS at ' + format(first, '.0f') + ' s':>14} {'RSS at end':>12} {'fds':>5} {'fds end':>8}")
    for role in ROLES:
        pair = baseline_and_end(r["samples"], role, first)
        if pair:
            (rss0, fd0), (rss1, fd1) = pair
            print(f"  {role:<11} {rss0 / 1024:11.1f} MB {rss1 / 1024:9.1f} MB {fd0:5d} {fd1:8d}")
    print(f"  /dev/shm entries of the run left: {len(r['shm_left'])}; run exit {r['run_exit']}, "
          f"end reason {r['end'].get('reason')}")
    print("soak: passed" if not wrong else "soak: FAILED\n  " + "\n  ".join(wrong))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("duration", type=float, help="wall-clock seconds")
    ap.add_argument("--servo", default=str(ROOT / "target" / "release" / "servo"))
    ap.add_argument("--split-s", type=float, default=1.0, help="run seconds per recording part")
    ap.add_argument("--out", type=Path, help="working folder (default: a temporary one, removed)")
    ap.add_argument("--json", type=Path, help="write the report here")
    a = ap.parse_args()
    if shutil.which("node") is None or not (CLIENT.parent / "node_modules").exists():
        print("soak: needs node and `npm ci --prefix scripts/mcap-js` (the Foxglove client)", file=sys.stderr)
        return 2
    work = a.out or Path(tempfile.mkdtemp(prefix="soak-"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        r = run_soak(a, work)
    finally:
        if a.out is None:
            shutil.rmtree(work, ignore_errors=True)
    wrong = judge(r, a.duration)
    r["wrong"] = wrong
    report(r, wrong, a.duration)
    if a.json:
        a.json.write_text(json.dumps(r, indent=1))
    return 0 if not wrong else 1


if __name__ == "__main__":
    sys.exit(main())
