#!/usr/bin/env python3
"""What a tick costs on the Cortex-M7: builds the firmware twice (f64 in hardware, FPv5-D16;
and the thumbv7em default, f64 in software), runs each controller of thesis Table 6-1 on both
under QEMU (`servo run --pil`, >= 1 000 ticks each) and prints the cost table, the footprint
and the stack, in Markdown.

    python3 scripts/pil_cost.py            # from the checkout; needs qemu-system-arm and
                                           # the thumbv7em-none-eabihf target

Instructions are counted by QEMU (`-icount shift=5`: 32 ns of the emulated clock per
instruction) through the firmware's SysTick (25 MHz: 1.25 instructions a count), around
`Servo::tick` in the tick interrupt. Time on a 480 MHz STM32H7 assumes one cycle per
instruction: QEMU models no pipeline, dual issue, cache or FPU latency (for the state-space
tick, a floor). DSP cycles (thesis) and M7 instructions are different units.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FIRMWARE = ROOT / "firmware"
SERVO = ROOT / "target" / "release" / "servo"
HARD = FIRMWARE / "target" / "thumbv7em-none-eabihf" / "release" / "fts-firmware"
SOFT = FIRMWARE / "target" / "soft-f64" / "thumbv7em-none-eabihf" / "release" / "fts-firmware"
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
    """Both firmware builds (the config's Cortex-M7, and RUSTFLAGS without a target CPU)."""
    quiet = ["cargo", "build", "--release", "--quiet"]
    subprocess.run(quiet, cwd=FIRMWARE, check=True)
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


def run(elf: Path, args: list[str], rate: int) -> dict:
    ticks = 1020
    cmd = [str(SERVO), "run", "--pil", str(elf), "--rate", str(rate),
           "--duration", f"{ticks / rate:.6f}", "--no-record", "--json", "--quiet", "--force",
           *args]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    summary = json.loads(out)
    assert summary["ticks"] >= 1000, summary["ticks"]
    return summary["meta"]["target"]


def main() -> None:
    build()
    print("| controller | states | rate | thesis DSP cycles | FPv5-D16 instructions mean / max | ≥ µs at 480 MHz (max) | soft f64 instructions mean / max | ≥ µs at 480 MHz (max) | stack |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    load_stack = {HARD: 0, SOFT: 0}
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
            cells = [name, str(states or "–"), f"{rate / 1e3:g} kHz", str(dsp or "–")]
            for t in (hard, soft):
                cells.append(f"{t['instructions_per_tick_mean']:.0f} / {t['instructions_per_tick_max']:.0f}")
                cells.append(f"{t['tick_max_s'] * 1e6:.2f}")
            cells.append(f"{hard['stack_used_bytes']} B")
            print("| " + " | ".join(cells) + " |")
    print()
    for label, elf in (("FPv5-D16", HARD), ("soft f64", SOFT)):
        flash, ram, stack = footprint(elf)
        print(f"{label} build: flash {flash / 1024:.1f} KiB, static RAM {ram / 1024:.1f} KiB, "
              f"stack region {stack / 1024:.0f} KiB (building the loop used "
              f"{load_stack[elf] / 1024:.0f} KiB of it); no allocator linked")


if __name__ == "__main__":
    main()
