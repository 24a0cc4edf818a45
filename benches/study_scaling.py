"""Design-space study throughput: points per second with `servo study --jobs 1`, `--jobs 2`,
and through a Ray cluster on this machine (2 CPUs, started by scripts/ray_local_cluster.sh),
in one run; and what Ray costs per point (per-task overhead measured with empty tasks, and the
wall-clock difference to the native two-thread run). The three tables must be equal.

    python3 benches/study_scaling.py [--points-per-task 4]

Needs the `servo` binary (cargo build --release), the fts_servo package and Ray.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import tempfile
import time
from pathlib import Path

# Ray reads its authentication mode at import: the head the script starts uses tokens.
os.environ.setdefault("RAY_AUTH_MODE", "token")

import ray  # noqa: E402

import fts_servo as fs  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SERVO = os.environ.get("FTS_SERVO_BIN", str(ROOT / "target" / "release" / "servo"))
STUDY = """
[study]
name = "bench"
[[study.parameter]]
key = "plant.stage.k2_n_per_m"
from = 5e3
to = 5e5
points = 6
spacing = "log"
[[study.parameter]]
key = "plant.stage.c2_n_s_per_m"
from = 1.0
to = 300.0
points = 6
spacing = "log"
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points-per-task", type=int, default=4)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        study = tmp / "study.toml"
        study.write_text(STUDY)
        n = fs.study_info(study)["points"]
        wall = {}
        for jobs in (1, 2):
            t = time.perf_counter()
            subprocess.run([SERVO, "study", str(study), "--jobs", str(jobs), "--out-dir", str(tmp / f"j{jobs}")],
                           check=True, capture_output=True)
            wall[f"servo study --jobs {jobs}"] = time.perf_counter() - t
        out = subprocess.run([str(ROOT / "scripts" / "ray_local_cluster.sh"), "start", "2"],
                             capture_output=True, text=True, check=True)
        address, temp_dir = out.stdout.split()
        try:
            ray.init(address=address, log_to_driver=False)
            t = time.perf_counter()
            fs.run_study_ray(study, tmp / "ray", points_per_task=a.points_per_task)
            wall["Ray, 2 CPUs"] = time.perf_counter() - t
            noop = ray.remote(lambda: None)
            ray.get([noop.remote() for _ in range(20)])
            t = time.perf_counter()
            ray.get([noop.remote() for _ in range(400)])
            per_task = (time.perf_counter() - t) / 400 * 2  # CPU-seconds per task on 2 workers
            ray.shutdown()
        finally:
            subprocess.run([str(ROOT / "scripts" / "ray_local_cluster.sh"), "stop", temp_dir], check=True)
        tables = {k: (tmp / d / "study.csv").read_bytes() for k, d in (("j1", "j1"), ("j2", "j2"), ("ray", "ray"))}
        assert tables["j1"] == tables["j2"] == tables["ray"], "the tables differ"
        print(f"{n} points (H2 synthesis + exact budget + margins each, 199.6 kHz), plus 4 sensitivity loops")
        base = wall["servo study --jobs 1"]
        for k, w in wall.items():
            print(f"  {k:<22} {w:7.2f} s  {n / w:6.2f} points/s  ({base / w:4.2f}x one thread)")
        diff = (wall["Ray, 2 CPUs"] - wall["servo study --jobs 2"]) * 2 / n
        print(f"  Ray overhead: {per_task * 1e3:.2f} ms of worker time per (empty) task = "
              f"{per_task / a.points_per_task * 1e3:.2f} ms per point at {a.points_per_task} points per task; "
              f"measured against --jobs 2: {diff * 1e3:+.0f} ms of worker time per point")
        print("  tables: identical (servo study --jobs 1, --jobs 2, Ray)")


if __name__ == "__main__":
    main()
