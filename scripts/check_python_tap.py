#!/usr/bin/env python3
"""CI check: the Python iceoryx2 tap (examples/python/tap_telemetry.py) sees every tick of a
lockstep HIL run and computes the same RMS following error as the run's own summary.

Usage: python3 scripts/check_python_tap.py target/release/servo
"""
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main() -> int:
    servo = sys.argv[1]
    prefix = f"pytap-{os.getpid()}"
    tap = subprocess.Popen(
        [sys.executable, os.path.join(ROOT, "examples/python/tap_telemetry.py"), "--prefix", prefix],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert tap.stdout.readline().strip() == "ready", "tap did not start"
    run = subprocess.run(
        [servo, "run", "--hil", "--prefix", prefix, "--duration", "1", "--no-record", "-q", "--json"],
        capture_output=True,
        text=True,
        check=True,
    )
    summary = json.loads(run.stdout)
    got = json.loads(tap.stdout.readline())
    assert tap.wait(timeout=30) == 0
    assert summary["meta"]["settle_s"] == 0.1, "the tap's default --settle-s"
    ticks = summary["ticks"]
    assert got["ticks"] == ticks and got["first_seq"] == 0 and got["last_seq"] == ticks - 1, got
    want = summary["following_error_m"]["rms"]  # from float32 frames
    rel = abs(got["following_error_rms_m"] / want - 1.0)
    assert rel < 1e-5, f"tap RMS {got['following_error_rms_m']} vs summary {want}"
    print(f"python tap: {ticks} ticks, RMS following error {want * 1e9:.4f} nm (rel. diff {rel:.1e})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
