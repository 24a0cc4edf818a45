"""Bench: decoding one simulated second of a recording in Python — the fts_servo package
against the PyPI mcap reader (mcap + mcap-ros2-support) in the same run.

    pip install ./python mcap mcap-ros2-support && python3 benches/python_decode.py

Prints each reader's best of five wall times and the ratio; exits 1 if the two disagree.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

import fts_servo as fs

ROOT = Path(__file__).resolve().parents[1]


def with_mcap(path: Path) -> dict:
    """Every /telemetry and /truth field as arrays, through the official reader."""
    cols: dict = {}
    with open(path, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        for _, channel, _, msg in reader.iter_decoded_messages(topics=["/telemetry", "/truth"]):
            for field in msg.__slots__:
                cols.setdefault((channel.topic, field), []).append(getattr(msg, field))
    return {k: np.asarray(v, dtype=np.float32) for k, v in cols.items()}


def best_of(n: int, f) -> tuple:
    times, out = [], None
    for _ in range(n):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return min(times), out


def main() -> int:
    with tempfile.TemporaryDirectory() as d:
        rec = Path(d) / "one_second.mcap"
        servo = ROOT / "target" / "release" / "servo"
        subprocess.run([str(servo), "run", "-q", "--duration", "1", "--out", str(rec)], check=True)
        t_ours, ours = best_of(5, lambda: fs.read_recording(rec))
        t_mcap, theirs = best_of(5, lambda: with_mcap(rec))
    same = all(
        np.array_equal(getattr(ours, topic.strip("/"))[field], values)
        for (topic, field), values in theirs.items()
    )
    ticks = len(ours.time_s)
    print(f"one simulated second: {ticks} ticks, {2 * ticks} messages")
    print(f"  fts_servo.read_recording   {t_ours * 1e3:9.1f} ms")
    print(f"  mcap + mcap-ros2-support   {t_mcap * 1e3:9.1f} ms")
    print(f"  ratio                      {t_mcap / t_ours:9.1f}x  (target >= 20x)")
    print(f"  same values: {same}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
