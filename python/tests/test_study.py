"""Design-space studies through Ray on a local cluster started by scripts/ray_local_cluster.sh:
the table equals `servo study`'s byte for byte, an interrupted run resumes, the Parquet table
holds the same numbers."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

import fts_servo as fs

ROOT = Path(__file__).resolve().parents[2]
SERVO = os.environ.get("FTS_SERVO_BIN", str(ROOT / "target" / "release" / "servo"))
CLUSTER = ROOT / "scripts" / "ray_local_cluster.sh"

STUDY = """
[study]
name = "ray check"
controllers = ["h2", "pid"]
bandwidth_hz = 1000.0
sampling = "latin-hypercube"
samples = 5
seed = 11

[[study.parameter]]
key = "plant.stage.k2_n_per_m"
from = 1e4
to = 1e5
spacing = "log"

[[study.parameter]]
key = "plant.stage.c2_n_s_per_m"
from = 1.0
to = 40.0
"""

# Ray reads its authentication mode at import: the head the script starts uses tokens
# (~/.ray/auth_token, as `ray start` made it).
os.environ.setdefault("RAY_AUTH_MODE", "token")

if os.environ.get("CI"):
    import ray  # CI installs Ray: a missing Ray fails here rather than skipping
else:
    ray = pytest.importorskip("ray")


@pytest.fixture(scope="module")
def cluster():
    """A Ray head on this machine, as a multi-node cluster's head is started; its address."""
    out = subprocess.run([str(CLUSTER), "start", "2"], capture_output=True, text=True)
    assert out.returncode == 0, f"the Ray head did not start:\n{out.stderr}"
    address, temp_dir = out.stdout.split()
    ray.init(address=address, log_to_driver=False)
    yield address
    ray.shutdown()
    subprocess.run([str(CLUSTER), "stop", temp_dir], check=True)


def test_ray_gives_the_table_servo_study_gives(cluster: str, tmp_path: Path) -> None:
    study = tmp_path / "study.toml"
    study.write_text(STUDY)
    cli = tmp_path / "cli"
    subprocess.run([SERVO, "study", str(study), "--out-dir", str(cli)], check=True, capture_output=True)
    seen = []
    files = fs.run_study_ray(study, tmp_path / "ray", points_per_task=3, progress=lambda d, t: seen.append((d, t)))
    assert seen[-1] == (10, 10)
    for name in ["study.csv", "sensitivity.csv"]:
        assert (cli / name).read_bytes() == (tmp_path / "ray" / name).read_bytes(), name
    assert str(tmp_path / "ray" / "study.parquet") in files

    import pyarrow.parquet as pq

    t = pq.read_table(tmp_path / "ray" / "study.parquet")
    assert t.num_rows == 10
    assert t.schema.metadata[b"fts_servo.study"].decode() == STUDY
    rows = (cli / "study.csv").read_text().splitlines()[1:]
    first = rows[0].split(",")
    header = (cli / "study.csv").read_text().splitlines()[0].split(",")
    col = header.index("following_rms_m")
    assert t.column("following_rms_m")[0].as_py() == float(first[col])


def test_an_interrupted_study_resumes_on_ray(cluster: str, tmp_path: Path) -> None:
    out = tmp_path / "resumed"
    text = STUDY.replace("seed = 11", "seed = 12")
    # An earlier run (here: this process) finished three points, the last line cut short.
    journal, pending = fs._native.study_open(text, str(out))
    assert pending == list(range(10))
    rows = fs.study_rows(text, [0, 4, 7])
    with open(journal, "a") as f:
        f.write("".join(rows) + rows[0][:20])
    seen = []
    fs.run_study_ray(text, out, points_per_task=2, progress=lambda d, t: seen.append(d))
    assert seen[0] == 3  # three points were there already
    whole = tmp_path / "whole"
    fs.run_study_ray(text, whole, points_per_task=10)
    assert (out / "study.csv").read_bytes() == (whole / "study.csv").read_bytes()


def test_a_bad_study_is_refused_with_its_key() -> None:
    with pytest.raises(fs.ServoError, match=r"study.bandwidth_hz = -5: allowed"):
        fs.study_info("[study]\nbandwidth_hz = -5.0\n")
