#!/usr/bin/env python3
"""Reads a `servo run` recording with the official Python readers (PyPI `mcap` and
`mcap-ros2-support`), decodes every message, and checks the count against the run's summary;
reads every record again with the stream reader validating CRCs, and checks what Foxglove's
indexed reader needs (profile `ros2`, message indexes) and the `end` record.

Usage: python3 scripts/check_mcap.py run.mcap summary.json
"""
import json
import math
import sys

from mcap.reader import make_reader
from mcap.records import Header, MessageIndex
from mcap.stream_reader import StreamReader
from mcap_ros2.decoder import DecoderFactory


def main(path, summary_path):
    summary = json.load(open(summary_path))
    counts = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == "/telemetry":
                assert math.isfinite(decoded.following_error_m), "non-finite following error"
            elif channel.topic == "/truth":
                assert math.isfinite(decoded.tool_m), "non-finite tool position"
            elif channel.topic == "/overview":
                assert decoded.min.following_error_m <= decoded.max.following_error_m
    total = counts["/telemetry"] + counts["/truth"]
    expected = summary["meta"]["recorded_messages"]
    ticks = summary["ticks"]
    assert total == expected, f"decoded {total} messages, the run reported {expected}"
    assert counts["/telemetry"] == ticks and counts["/truth"] == ticks, counts
    # The 1 kHz overview: one message per started millisecond of run.
    assert abs(counts["/overview"] - ticks / 199.6) <= 2, counts
    assert meta["run"]["seed"] == str(summary["meta"]["seed"]), meta["run"]["seed"]
    assert meta["end"]["reason"] == summary["meta"]["end_reason"], meta["end"]
    assert meta["end"]["ticks"] == str(ticks), meta["end"]
    with open(path, "rb") as f:
        records = list(StreamReader(f, validate_crcs=True).records)
    header = next(r for r in records if isinstance(r, Header))
    assert header.profile == "ros2", header.profile
    indexes = sum(isinstance(r, MessageIndex) for r in records)
    assert indexes > 0, "no message indexes"
    print(f"{path}: decoded all {total} messages with the Python mcap readers "
          f"({counts['/telemetry']} telemetry, {counts['/truth']} truth, "
          f"{counts['/overview']} overview), as the run reported; "
          f"CRCs valid, profile ros2, {indexes} message indexes, ended {meta['end']['reason']}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
