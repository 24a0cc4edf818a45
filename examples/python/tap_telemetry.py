#!/usr/bin/env python3
"""Tap the live telemetry of an fts-servo HIL run from Python.

Uses the `iceoryx2` package from PyPI (the 0.10 line, like the crate): zero-copy shared memory,
no fts-servo code needed. The message layout is daq-io's contract (crates/daq-io/src/contract.rs);
the type names must match the Rust `#[type_name]`s and the service settings the Rust side's
(`daq_io::ipc::settings`), or opening the service fails with a clear iceoryx2 error.

    pip install "iceoryx2==0.10.*"
    python3 examples/python/tap_telemetry.py --prefix demo &   # attach before the run starts
    servo run --hil --prefix demo --duration 2

Prints one JSON line when the run ends: ticks seen, first and last tick, and the RMS and peak
following error (m) over the ticks at or after --settle-s.
"""
import argparse
import os
import ctypes
import json
import math
import sys
import time

import iceoryx2 as iox2

BLOCK_TICKS = 64
END = 1 << 16  # daq_io::flags::END


class Telemetry(ctypes.Structure):
    """daq_io::Telemetry: what the controller saw and did on one tick (SI units)."""

    _fields_ = [
        ("seq", ctypes.c_uint64),
        ("time_s", ctypes.c_double),
        ("reference_m", ctypes.c_double),
        ("measured_m", ctypes.c_double),
        ("following_error_m", ctypes.c_double),
        ("controller_error_m", ctypes.c_double),
        ("control_v", ctypes.c_double),
        ("accel_m_s2", ctypes.c_double),
        ("flags", ctypes.c_uint32),
        ("reserved", ctypes.c_uint32),
    ]

    @staticmethod
    def type_name() -> str:
        return "fts_servo::v6::Telemetry"


class TelemetryBlock(ctypes.Structure):
    """daq_io::TelemetryBlock: up to 64 consecutive ticks."""

    _fields_ = [
        ("block", ctypes.c_uint64),
        ("count", ctypes.c_uint32),
        ("flags", ctypes.c_uint32),
        ("run_id", ctypes.c_uint64),
        ("ticks", Telemetry * BLOCK_TICKS),
    ]

    @staticmethod
    def type_name() -> str:
        return "fts_servo::v6::TelemetryBlock"


def open_subscriber(prefix: str):
    """Subscribes to fts-servo/<prefix>/telemetry with daq-io's settings for that service."""
    # Named as every fts-servo process names its node (contract version 6), so peers see a
    # tap of this version on the run.
    node = (
        iox2.NodeBuilder.new()
        .name(iox2.NodeName.new(f"fts-servo/v6/{prefix}/tap-{os.getpid()}"))
        .create(iox2.ServiceType.Ipc)
    )
    service = (
        node.service_builder(iox2.ServiceName.new(f"fts-servo/{prefix}/telemetry"))
        .publish_subscribe(TelemetryBlock)
        .subscriber_max_buffer_size(1024)
        .history_size(0)
        .enable_safe_overflow(True)
        .max_publishers(1)
        .max_subscribers(3)
        .max_nodes(8)
        .open_or_create()
    )
    return node, service, service.subscriber_builder().create()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--prefix", required=True, help="run prefix (servo --prefix)")
    parser.add_argument("--settle-s", type=float, default=0.1, help="statistics start, s")
    parser.add_argument("--timeout-s", type=float, default=60.0, help="give up after, s")
    args = parser.parse_args()

    _node, _service, subscriber = open_subscriber(args.prefix)
    print("ready", flush=True)
    settle_ns = math.floor(args.settle_s * 1e9 + 0.5)
    ticks, first, last, n, sum_sq, peak = 0, None, None, 0, 0.0, 0.0
    deadline = time.monotonic() + args.timeout_s
    while time.monotonic() < deadline:
        sample = subscriber.receive()
        if sample is None:
            time.sleep(0.001)
            continue
        block = sample.payload().contents
        for t in block.ticks[: block.count]:
            ticks += 1
            first = t.seq if first is None else first
            last = t.seq
            if math.floor(t.time_s * 1e9 + 0.5) >= settle_ns:
                n += 1
                sum_sq += t.following_error_m**2
                peak = max(peak, abs(t.following_error_m))
        if block.flags & END:
            print(
                json.dumps(
                    {
                        "ticks": ticks,
                        "first_seq": first,
                        "last_seq": last,
                        "following_error_rms_m": math.sqrt(sum_sq / max(n, 1)),
                        "following_error_peak_m": peak,
                    }
                ),
                flush=True,
            )
            return 0
    print("no end of run within the timeout", file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())
