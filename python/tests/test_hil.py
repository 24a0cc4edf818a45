"""The HIL run and the host qualification from Python: the same library calls as
``servo run --hil`` and ``servo latency``, checked against the in-process loop and the CLI."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import numpy as np

import fts_servo as fs

ROOT = Path(__file__).resolve().parents[2]
SERVO = os.environ.get("FTS_SERVO_BIN", str(ROOT / "target" / "release" / "servo"))

TABLES = {
    "run": {"duration_s": 0.02, "seed": 3},
    "scenario": {"kind": "sine", "amplitude_m": 1e-6, "frequency_hz": 300.0},
}


def test_a_lockstep_hil_run_from_python_equals_the_in_process_loop(tmp_path: Path) -> None:
    out = tmp_path / "hil.mcap"
    summary = fs.run_hil(out=out, prefix=f"py-hil-{os.getpid()}", servo=SERVO, **TABLES)
    ran = fs.run(**TABLES)
    assert summary["ticks"] == ran.summary["ticks"] > 0
    recorded = fs.read_recording(out)
    assert recorded.finished
    # Three processes over shared memory, the same numbers as one process: bit for bit.
    for group in ("telemetry", "truth"):
        for name, values in getattr(ran, group).items():
            np.testing.assert_array_equal(getattr(recorded, group)[name], values, err_msg=name)


def test_a_failed_hil_process_raises_naming_it(tmp_path: Path) -> None:
    out = tmp_path / "exists.mcap"
    out.write_bytes(b"not to be replaced")
    try:
        fs.run_hil(out=out, servo=SERVO, **TABLES)
    except fs.ServoError as e:
        assert "exists" in str(e), e
    else:
        raise AssertionError("an existing recording was replaced without overwrite")
    assert out.read_bytes() == b"not to be replaced"


def qualification_refusal(tmp_path: Path, q: dict) -> str:
    path = tmp_path / "latency.json"
    path.write_text(json.dumps(q))
    run = subprocess.run(
        [SERVO, "run", "--hil", "--realtime", "--qualification", str(path), "--no-record", "--duration", "0.01"],
        capture_output=True,
        text=True,
    )
    assert run.returncode != 0, run
    return run.stderr


def test_a_qualification_from_python_is_the_file_a_realtime_run_reads(tmp_path: Path) -> None:
    q = fs.qualify_host(duration_s=0.1)
    lateness = q["lateness_ns"]
    assert q["ticks"] == round(0.1 * q["rate_hz"])
    assert lateness["min"] <= lateness["p50"] <= lateness["p99"] <= lateness["max"]
    assert q["host_stalls"]["worst_s"] == lateness["max"] * 1e-9
    assert q["holds"] == (q["survivable_stall_s"] >= 2 * q["host_stalls"]["worst_s"])
    # The CLI reads every field of it, and refuses it by the key that does not stand for this
    # run: another host, another rate, a day old.
    assert "host" in qualification_refusal(tmp_path, {**q, "host": "elsewhere"})
    assert "rate_hz" in qualification_refusal(tmp_path, {**q, "rate_hz": 1000.0})
    assert "measured_at" in qualification_refusal(tmp_path, {**q, "measured_at": "2020-01-01T00:00:00Z"})


def test_a_qualification_out_of_range_names_its_key() -> None:
    try:
        fs.qualify_host(duration_s=0.0)
    except fs.ServoError as e:
        assert "duration_s" in str(e), e
    else:
        raise AssertionError("a zero-length qualification was accepted")


def test_a_replay_from_python_reproduces_the_recording_bit_for_bit(tmp_path: Path) -> None:
    rec = tmp_path / "run.mcap"
    subprocess.run(
        [SERVO, "run", "-q", "--duration", "0.02", "--scenario", "sine", "--out", str(rec)], check=True
    )
    report = fs.replay(rec, out=tmp_path / "again.mcap")
    assert report["identical"] is True and not report["changed"] and report["design"] == "same"
    assert report["frames_compared"] == report["replayed"]["ticks"] > 0
    cli = json.loads(
        subprocess.run(
            [SERVO, "replay", str(rec), "--json", "--no-record"], capture_output=True, text=True, check=True
        ).stdout
    )
    for metric in ("following_error_m", "true_error_m", "control_v", "ticks"):
        assert cli["replayed"][metric] == report["replayed"][metric], metric
    np.testing.assert_array_equal(
        fs.read_recording(tmp_path / "again.mcap").telemetry["control_v"], fs.read_recording(rec).telemetry["control_v"]
    )


def test_a_run_is_steered_from_python_as_servo_ctl_steers_it(tmp_path: Path) -> None:
    prefix = f"py-ctl-{os.getpid()}"
    run = subprocess.Popen(
        [SERVO, "run", "--hil", "-q", "--json", "--duration", "60", "--prefix", prefix, "--out", str(tmp_path / "r.mcap")],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        # The run's processes start: bounded, a run that never serves fails the test.
        for _ in range(300):
            try:
                fs.control(prefix, "gain", 1.0)
                break
            except fs.ServoError:
                import time

                time.sleep(0.1)
        else:
            raise AssertionError("the run never answered")
        try:
            fs.control(prefix, "gain", 100.0)
        except fs.ServoError as e:
            assert "refused" in str(e) and "6 dB margin" in str(e), e
        else:
            raise AssertionError("an unstable gain was applied")
        assert fs.control(prefix, "gain", 0.8).startswith("gain ×0.8 applied from tick")
        assert fs.control(prefix, "stop").startswith("stop applied: the run ends at tick")
        out, _ = run.communicate(timeout=60)
    finally:
        run.kill()
    summary = json.loads(out)
    assert summary["ticks"] < 60 * 199_600, summary["ticks"]
