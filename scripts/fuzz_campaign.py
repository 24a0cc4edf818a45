#!/usr/bin/env python3
"""A fuzzing campaign over every target of crates/fuzz-targets (cargo-fuzz, libFuzzer).

    python3 scripts/fuzz_campaign.py [--seconds S] [--runs N] [--jobs J] [--out DIR]
                                     [--merge] [--planted] [TARGET ...]

Each target runs until it has executed `--runs` inputs (default 10 000 000) or for `--seconds`
of wall time (default 1200), whichever comes first, from its committed seeds
(fuzz/seeds/<target>) and corpus (fuzz/corpus/<target>), under a 10 s per-input timeout and a
2 GiB memory limit. `--jobs` targets run at once (default 1; this machine has 2 cores). It
prints a table per target — executions, wall time, executions per second, corpus size, peak
memory, findings — writes it as Markdown and JSON into `--out`, and exits 1 when any target
found a crash, a timeout or an out-of-memory input (kept in `--out`/artifacts/<target>/ to be
fixed and committed to fuzz/regressions/<target>/).

`--merge` adds the inputs that reached new coverage to fuzz/corpus/<target> (what the test
suite replays; recordings only up to 8 KiB). `--planted` builds the planted fault
(fuzz-targets' `planted` feature) and runs only `pil_link`: the campaign must find it (exit 0
when it does, 1 when it does not). The planted build replaces the targets' binaries until the
next campaign builds them again: do not run it beside a campaign.

Needs a nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz`).
"""

from __future__ import annotations

import argparse
import concurrent.futures
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FUZZ = ROOT / "fuzz"
TARGETS = sorted(p.stem for p in (FUZZ / "fuzz_targets").glob("*.rs"))
STAT = re.compile(r"^stat::(\w+):\s+(\d+)", re.M)
DONE = re.compile(r"^Done (\d+) runs in (\d+) second", re.M)
# The committed corpus keeps a target's inputs up to this size (recordings grow large).
KEPT_MAX_BYTES = {"mcap": 8192}


def cargo_fuzz(*args: str, features: list[str]) -> list[str]:
    extra = ["--features", ",".join(features)] if features else []
    return ["cargo", "+nightly", "fuzz", *args, "--fuzz-dir", str(FUZZ), *extra]


def run_target(name: str, args: argparse.Namespace, features: list[str], out: Path) -> dict:
    work = out / "corpus" / name
    artifacts = out / "artifacts" / name
    work.mkdir(parents=True, exist_ok=True)
    artifacts.mkdir(parents=True, exist_ok=True)
    committed = [d for d in (FUZZ / "corpus" / name, FUZZ / "seeds" / name) if d.is_dir()]
    scratch = Path(tempfile.mkdtemp(prefix=f"fts-fuzz-{name}-"))
    log = out / f"{name}.log"
    cmd = cargo_fuzz("run", name, features=features) + [
        str(work), *map(str, committed), "--",
        f"-runs={args.runs}", f"-max_total_time={args.seconds}",
        "-timeout=10", "-rss_limit_mb=2048", "-malloc_limit_mb=2048",
        "-print_final_stats=1", f"-artifact_prefix={artifacts}/",
    ]
    env = {**os.environ, "FTS_FUZZ_SCRATCH": str(scratch)}
    with open(log, "w") as f:
        code = subprocess.call(cmd, stdout=f, stderr=subprocess.STDOUT, cwd=ROOT, env=env)
    text = log.read_text(errors="replace")
    stats = {k: int(v) for k, v in STAT.findall(text)}
    # libFuzzer's own count of its fuzzing time (the build before it is not the target's);
    # a target stopped by a finding has no "Done" line: its time is up to the finding.
    done = DONE.findall(text)
    wall = float(done[-1][1]) if done else float(stats.get("number_of_executed_units", 0)) / max(
        stats.get("average_exec_per_sec", 1), 1)
    findings = sorted(p.name for p in artifacts.iterdir())
    if args.merge and not findings:
        dest = FUZZ / "corpus" / name
        dest.mkdir(parents=True, exist_ok=True)
        subprocess.check_call(
            cargo_fuzz("run", name, features=features)
            + [str(dest), str(work), "--", "-merge=1"],
            cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        for kept in dest.iterdir():
            if kept.stat().st_size > KEPT_MAX_BYTES.get(name, 1 << 30):
                kept.unlink()
    shutil.rmtree(scratch, ignore_errors=True)
    return {
        "target": name,
        "executions": stats.get("number_of_executed_units", 0),
        "wall_s": round(wall, 1),
        "exec_per_s": stats.get("average_exec_per_sec", 0),
        "corpus": sum(1 for _ in work.iterdir()),
        "peak_rss_mb": stats.get("peak_rss_mb", 0),
        "exit": code,
        "findings": findings,
        "panic": next(iter(re.findall(r"panicked at [^\n]*\n([^\n]*)", text)), ""),
    }


def table(rows: list[dict]) -> str:
    lines = [
        "| target | executions | wall time | exec/s | corpus | peak RSS | findings |",
        "|---|---:|---:|---:|---:|---:|---|",
    ]
    for r in rows:
        found = ", ".join(r["findings"]) or "none"
        lines.append(
            f"| `{r['target']}` | {r['executions']:,} | {r['wall_s'] / 60:.1f} min | "
            f"{r['exec_per_s']:,} | {r['corpus']:,} | {r['peak_rss_mb']} MB | {found} |")
    return "\n".join(lines)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("targets", nargs="*", metavar="TARGET", help=f"of {', '.join(TARGETS)}")
    p.add_argument("--seconds", type=int, default=1200)
    p.add_argument("--runs", type=int, default=10_000_000)
    p.add_argument("--jobs", type=int, default=1)
    p.add_argument("--out", type=Path)
    p.add_argument("--merge", action="store_true")
    p.add_argument("--planted", action="store_true")
    args = p.parse_args()
    unknown = sorted(set(args.targets) - set(TARGETS))
    if unknown:
        p.error(f"no target {', '.join(unknown)}: the targets are {', '.join(TARGETS)}")
    features = ["planted"] if args.planted else []
    targets = ["pil_link"] if args.planted else (args.targets or TARGETS)
    out = args.out or Path(tempfile.mkdtemp(prefix="fts-fuzz-campaign-"))
    out.mkdir(parents=True, exist_ok=True)
    subprocess.check_call(cargo_fuzz("build", features=features), cwd=ROOT)
    print(f"{len(targets)} target(s), up to {args.runs:,} executions or {args.seconds} s each, "
          f"{args.jobs} at a time; logs in {out}", flush=True)
    rows = []
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        futures = {pool.submit(run_target, t, args, features, out): t for t in targets}
        for f in concurrent.futures.as_completed(futures):
            r = f.result()
            rows.append(r)
            print(f"  {r['target']}: {r['executions']:,} executions in {r['wall_s']:.0f} s, "
                  f"findings: {', '.join(r['findings']) or 'none'} {r['panic']}", flush=True)
    rows.sort(key=lambda r: targets.index(r["target"]))
    md = table(rows)
    (out / "campaign.md").write_text(md + "\n")
    (out / "campaign.json").write_text(json.dumps(rows, indent=2) + "\n")
    print(md)
    found = any(r["findings"] for r in rows)
    if args.planted:
        return 0 if found else 1
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
