#!/usr/bin/env python3
"""Checks `servo export` against the official Python MCAP reader: the `.npz` arrays (loaded
with NumPy alone) equal the decoded messages value for value, the CSV equals the `.npz`, and
the 1 kHz overview's min/max/mean agree with the full-rate ticks of each millisecond.

Usage: python3 scripts/check_export.py run.mcap run.npz run.csv overview.npz
"""
import sys

import numpy as np
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def main(mcap_path, npz_path, csv_path, overview_path):
    fields = ["following_error_m", "control_v", "measured_m"]
    decoded = {f: [] for f in fields}
    times = []
    with open(mcap_path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        epoch = int(next(m for m in reader.iter_metadata() if m.name == "run")
                    .metadata["log_time_epoch_ns"])
        for _, channel, message, msg in reader.iter_decoded_messages(topics=["/telemetry"]):
            times.append((message.log_time - epoch) * 1e-9)
            for name in fields:
                decoded[name].append(getattr(msg, name))
    z = np.load(npz_path)
    assert z["time_s"].dtype == np.float64 and z["telemetry.control_v"].dtype == np.float32
    assert len(z["time_s"]) == len(times), (len(z["time_s"]), len(times))
    assert np.array_equal(z["time_s"], np.array(times)), "time_s differs"
    for name in fields:
        ours = z["telemetry." + name]
        theirs = np.array(decoded[name], dtype=np.float32)
        assert np.array_equal(ours, theirs), f"telemetry.{name} differs"
    csv = np.genfromtxt(csv_path, delimiter=",", names=True, dtype=None)
    for column in ["time_s", "telemetry.following_error_m", "truth.tool_m"]:
        key = column.replace(".", "")  # genfromtxt drops the dots from names
        expected = z[column]
        assert np.array_equal(csv[key].astype(expected.dtype), expected), f"CSV {column} differs"
    o = np.load(overview_path)
    t, err = z["time_s"], z["telemetry.following_error_m"]
    period = np.floor(np.round(t * 1e9) / 1e6)
    checked = 0
    for k, start in enumerate(o["overview.time_s"][:-1]):
        inside = err[period == round(start * 1e3)]
        assert o["overview.ticks"][k] == len(inside), (start, o["overview.ticks"][k], len(inside))
        assert o["overview.max.following_error_m"][k] == inside.max()
        assert o["overview.min.following_error_m"][k] == inside.min()
        mean = inside.astype(np.float64).mean()
        assert abs(o["overview.mean.following_error_m"][k] - mean) <= 1e-6 * abs(mean) + 1e-15
        checked += 1
    print(f"{npz_path}: {len(times)} ticks equal to the official reader's; {csv_path} equal to "
          f"the .npz; {checked} overview periods agree with their ticks")


if __name__ == "__main__":
    main(*sys.argv[1:5])
