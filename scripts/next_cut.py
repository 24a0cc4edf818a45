#!/usr/bin/env python3
"""The next cut of a compensation cycle, as an operator makes it: the tool moved by the
correction `servo register` reported, the prescription given the compensation `servo
compensate` wrote.

    python3 scripts/next_cut.py CUT.toml REGISTRATION.json COMPENSATION.csv K

writes cut-K.toml (CUT.toml with [scenario] tool_centre_height_m and tool_x_offset_m moved by
the registration's setting_correction, unmoved when it fitted none, and its prescription path set
to prescription-K.toml)
and prescription-K.toml (the design, i.e. CUT.toml's prescription without a [compensation],
with [compensation] path = COMPENSATION.csv and the grid's pitch from its first line).
Needs Python 3.11 (tomllib).
"""
import json
import re
import sys
import tomllib
from pathlib import Path


def main():
    cut_path, registration, compensation, k = sys.argv[1:5]
    cut_text = Path(cut_path).read_text()
    cut = tomllib.loads(cut_text)
    scenario = cut["scenario"]
    # None when the registration fitted no setting errors (no --setting-errors): the tool stays.
    correction = json.loads(Path(registration).read_text())["setting_correction"] or {
        "centre_height_m": 0.0, "x_offset_m": 0.0}
    for key, move in [("tool_centre_height_m", correction["centre_height_m"]),
                      ("tool_x_offset_m", correction["x_offset_m"])]:
        value = scenario.get(key, 0.0) + move
        line = f"{key} = {value!r}"
        if re.search(rf"^{key} = .*$", cut_text, re.M):
            cut_text = re.sub(rf"^{key} = .*$", line, cut_text, flags=re.M)
        else:
            cut_text = cut_text.replace('kind = "machine"\n', f'kind = "machine"\n{line}\n', 1)
    old = scenario["surface"]["path"]
    design = Path(old).read_text()
    design = design.split("[compensation]")[0].rstrip() + "\n"
    pitch = re.search(r"pitch ([0-9.eE+-]+) mm", Path(compensation).read_text().splitlines()[0]).group(1)
    Path(f"prescription-{k}.toml").write_text(
        f'{design}\n[compensation]\npath = "{compensation}"\npitch_mm = [{pitch}, {pitch}]\n')
    cut_text = cut_text.replace(f'path = "{old}"', f'path = "prescription-{k}.toml"')
    Path(f"cut-{k}.toml").write_text(cut_text)


if __name__ == "__main__":
    main()
