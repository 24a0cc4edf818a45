#!/usr/bin/env python3
"""What a tick costs on the Cortex-M7: builds the firmware three times (f64 in hardware,
FPv5-D16; the same with the state-space order capped at 16; and the thumbv7em default, f64 in
software), runs each controller of thesis Table 6-1 under QEMU (`servo run --pil`, >= 1 000
ticks each) and prints the cost table, the footprint and the stack, in Markdown.

    python3 scripts/pil_cost.py            # from the checkout; needs qemu-system-arm and
                                           # the thumbv7em-none-eabihf target

Instructions are counted by QEMU (`-icount shift=5`: 32 ns of the emulated clock per
instruction) through the firmware's SysTick (25 MHz: 1.25 instructions a count), around
`Servo::tick` in the tick interrupt; "in all" divides every instruction the target ran over
the run (the tick, its interrupt, the link) by the ticks. Cycles are an estimate: the timed
instructions of a traced run replayed through a model of the M7's dual issue and FPU
latencies (`scripts/m7_cycles.py`). DSP cycles (thesis) and M7 instructions are different
units.
"""

from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

import m7_cycles

ROOT = Path(__file__).resolve().parent.parent
FIRMWARE = ROOT / "firmware"
SERVO = ROOT / "target" / "release" / "servo"
HARD = FIRMWARE / "target" / "thumbv7em-none-eabihf" / "release" / "fts-firmware"
CAPPED = FIRMWARE / "target" / "cap16" / "thumbv7em-none-eabihf" / "release" / "fts-firmware"
SOFT = FIRMWARE / "target" / "soft-f64" / "thumbv7em-none-eabihf" / "release" / "fts-firmware"
CAP = 16
CLOCK_HZ = 480e6

# (name, states, servo rate in Hz, thesis Table 6-1 DSP cycles or None, how to make it)
CASES = [
    ("PID (§7.5.3)", 0, 199_600, 430, None),
    ("PID + acceleration feedback (Ka 4)", 0, 199_600, None, None),
    ("H2, reduced to 8 states", 8, 20_000, 3045, ["--order", "8"]),
    ("H2, reduced to 13 states", 13, 20_000, 7128, ["--order", "13"]),
    ("H2, thesis weights (§6.3), full", 28, 20_000, 28204, ["--weights", "thesis"]),
    ("H2, exact model, full", 29, 20_000, None, []),
]


def build() -> None:
    """The three firmware builds (the config's Cortex-M7, the same capped at order 16, and
    RUSTFLAGS without a target CPU)."""
    quiet = ["cargo", "build", "--release", "--quiet"]
    subprocess.run(quiet, cwd=FIRMWARE, check=True)
    capped = dict(os.environ, FTS_SERVO_MAX_SS_ORDER=str(CAP))
    subprocess.run(quiet + ["--target-dir", "target/cap16"], cwd=FIRMWARE, env=capped, check=True)
    env = dict(os.environ, RUSTFLAGS="-C link-arg=-Tlink.x")
    subprocess.run(quiet + ["--target-dir", "target/soft-f64"], cwd=FIRMWARE, env=env, check=True)


def sections(elf: Path) -> tuple[dict[str, tuple[int, int]], list[str]]:
    """An ELF32's section sizes and addresses by name, and its symbol names."""
    data = elf.read_bytes()
    shoff, = struct.unpack_from("<I", data, 0x20)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x2E)
    headers = [struct.unpack_from("<IIIIIIIIII", data, shoff + i * shentsize) for i in range(shnum)]
    names = headers[shstrndx]

    def name(table, offset: int) -> str:
        start = table[4] + offset
        return data[start:data.index(b"\0", start)].decode()

    out, symbols = {}, []
    for h in headers:
        out[name(names, h[0])] = (h[3], h[5])  # addr, size
    for h in headers:
        if h[1] == 2:  # SHT_SYMTAB
            strtab = headers[h[6]]
            for off in range(h[4], h[4] + h[5], 16):
                symbols.append(name(strtab, struct.unpack_from("<I", data, off)[0]))
    return out, symbols


def footprint(elf: Path) -> tuple[int, int, int]:
    """Flash bytes (code, constants, initial data), RAM bytes (data, bss) and the stack."""
    s, symbols = sections(elf)
    size = lambda n: s.get(n, (0, 0))[1]
    flash = size(".vector_table") + size(".text") + size(".rodata") + size(".data")
    ram = size(".data") + size(".bss") + size(".uninit")
    allocators = [x for x in symbols if "__rust_alloc" in x or "__rdl_alloc" in x or "__rg_alloc" in x]
    if allocators:
        sys.exit(f"{elf}: an allocator is linked: {allocators[:3]}")
    return flash, ram, 512 * 1024 - ram


def run(elf: Path, args: list[str], rate: int, ticks: int = 1020, env: dict | None = None) -> dict:
    cmd = [str(SERVO), "run", "--pil", str(elf), "--rate", str(rate),
           "--duration", f"{ticks / rate:.6f}", "--no-record", "--json", "--quiet", "--force",
           *args]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True, env=env).stdout
    summary = json.loads(out)
    assert summary["ticks"] >= ticks - 20, summary["ticks"]
    return summary["meta"]["target"]


def cycles(elf: Path, args: list[str], rate: int, tmp: Path) -> tuple[float, float, float]:
    """The estimated cycles of the timed tick (mean, max) and the instructions the trace holds
    per tick: a short run under QEMU logging every instruction it runs (a wrapper first on
    PATH), replayed through the M7 model."""
    log = tmp / "trace.log"
    wrapper = tmp / "bin" / "qemu-system-arm"
    wrapper.parent.mkdir(exist_ok=True)
    real = shutil.which("qemu-system-arm")
    wrapper.write_text(f'#!/bin/sh\nexec {real} -singlestep -d in_asm,exec,nochain -D {log} "$@"\n')
    wrapper.chmod(0o755)
    env = dict(os.environ, PATH=f"{wrapper.parent}:{os.environ['PATH']}")
    run(elf, args, rate, ticks=12, env=env)
    mean, worst, instructions = m7_cycles.estimate(log)
    log.unlink()
    return mean, worst, instructions


def main() -> None:
    build()
    print("| controller | states | rate | thesis DSP cycles | FPv5-D16 instructions mean / max | M7 cycles (estimate) mean / max | µs at 480 MHz (estimate, max) | share of the period | in all, per tick | soft f64 instructions mean / max | ≥ µs at 480 MHz (soft, max) | stack |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    load_stack = {HARD: 0, SOFT: 0, CAPPED: 0}
    with tempfile.TemporaryDirectory() as tmp:
        for name, states, rate, dsp, synth in CASES:
            args = []
            if name.startswith("PID +"):
                args = ["--controller", "accel", "--ka", "4", "--mass", "heavy"]
            if synth is not None:
                file = Path(tmp) / f"h2_{states}.toml"
                subprocess.run([str(SERVO), "synth", "h2", "--rate", str(rate), "--out", str(file),
                                *synth], check=True, capture_output=True)
                args = ["--controller", "ss", "--ss-file", str(file)]
            hard, soft = run(HARD, args, rate), run(SOFT, args, rate)
            for elf, t in ((HARD, hard), (SOFT, soft)):
                load_stack[elf] = max(load_stack[elf], t["load_stack_bytes"])
            if states <= CAP:
                load_stack[CAPPED] = max(load_stack[CAPPED], run(CAPPED, args, rate, 60)["load_stack_bytes"])
            mean, worst, traced = cycles(HARD, args, rate, Path(tmp))
            # The trace and SysTick count the same instructions (to SysTick's resolution).
            assert abs(traced - hard["instructions_per_tick_mean"]) < 4, (traced, hard)
            period_us = 1e6 / rate
            cells = [name, str(states or "–"), f"{rate / 1e3:g} kHz", str(dsp or "–")]
            cells.append(f"{hard['instructions_per_tick_mean']:.0f} / {hard['instructions_per_tick_max']:.0f}")
            cells.append(f"{mean:.0f} / {worst:.0f}")
            cells.append(f"{worst / CLOCK_HZ * 1e6:.2f}")
            cells.append(f"{worst / CLOCK_HZ * 1e6 / period_us * 100:.0f} %")
            cells.append(f"{hard['instructions_per_tick_run']:.0f}")
            cells.append(f"{soft['instructions_per_tick_mean']:.0f} / {soft['instructions_per_tick_max']:.0f}")
            cells.append(f"{soft['instructions_per_tick_max'] / CLOCK_HZ * 1e6:.2f}")
            cells.append(f"{hard['stack_used_bytes']} B")
            print("| " + " | ".join(cells) + " |")
    print()
    for label, elf in (("FPv5-D16 build", HARD), (f"FPv5-D16, orders up to {CAP}", CAPPED),
                       ("soft f64 build", SOFT)):
        flash, ram, stack = footprint(elf)
        print(f"{label}: flash {flash / 1024:.1f} KiB, static RAM {ram / 1024:.1f} KiB, "
              f"stack region {stack / 1024:.0f} KiB (building the loop used "
              f"{load_stack[elf] / 1024:.1f} KiB of it); no allocator linked")


if __name__ == "__main__":
    main()
