#!/usr/bin/env python3
"""An estimate of the Cortex-M7 cycles of the firmware's timed tick, from an instruction trace.

QEMU counts instructions exactly but models no pipeline. This replays the instructions the
target ran between the tick's two SysTick readings (a QEMU `-d in_asm,exec,nochain
-one-insn-per-tb` log) through an in-order, dual-issue model of the Cortex-M7 built from the
machine model LLVM's ARM backend schedules the M7 with (llvm/lib/Target/ARM/ARMScheduleM7.td;
Arm publishes no cycle tables for the M7):

- two instructions issue per cycle, in order; an instruction issues when its operands are
  ready. Single-issue: 64-bit VFP loads and stores, load/store multiples (one cycle per 64
  bits moved), LDRD/STRD, TBB/TBH (two cycles), VMRS, divides and system instructions.
  Double-precision FP operations take both VFP ports and issue first in a pair.
- result latencies in cycles: integer ALU 1, multiply 2, divide 7, word load 2 (load-use),
  byte/halfword load 3, 64-bit VFP load 2; double precision add/sub/abs/neg/select/convert 4,
  multiply 7, multiply-accumulate 11 with the accumulator read 3 cycles late (8 between
  chained accumulations), divide and square root 30; single precision 3 (MAC 6, divide 16);
  VMOV 3.
- not modelled: wait states (code and data in TCM), cache misses, branch mispredictions
  (4-6 cycles each), interrupt entry. So the estimate is closer to the part than one cycle
  per instruction, and still an estimate: a board's DWT cycle counter is the measurement.
"""

from __future__ import annotations

import re
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

IN_ASM = re.compile(r"^0x([0-9a-f]+):\s+(?:[0-9a-f]{4}\s){1,2}\s*(\S+)\s*(.*)$")
EXEC = re.compile(r"^Trace \d+: \S+ \[[0-9a-f]+/([0-9a-f]+)/[^\]]*\] ?(\S*)")
REG = re.compile(r"\b(r\d+|sb|sl|fp|ip|sp|lr|pc|[ds]\d+)\b")
SYSTICK_CVR = (57368, 57344)  # movw #0xE018, movt #0xE000: SysTick's current value register


def parse(log: Path) -> tuple[dict[int, tuple[str, str]], list[int], set[int]]:
    """The disassembly QEMU logged (address -> mnemonic, operands), the executed addresses and
    those of the tick interrupt's handler (`TIMER0`)."""
    asm: dict[int, tuple[str, str]] = {}
    trace: list[int] = []
    handler: set[int] = set()
    with log.open(errors="replace") as f:
        for line in f:
            if line.startswith("Trace"):
                m = EXEC.match(line)
                if m:
                    pc = int(m.group(1), 16)
                    if m.group(2) == "TIMER0":
                        handler.add(pc)
                    # An instruction touching a device is retranslated and logged twice.
                    if not trace or trace[-1] != pc or asm.get(pc, ("", ""))[0].startswith("b"):
                        trace.append(pc)
            elif line.startswith("0x"):
                m = IN_ASM.match(line)
                if m:
                    asm[int(m.group(1), 16)] = (m.group(2).lower(), m.group(3).strip())
    return asm, trace, handler


def registers(text: str) -> list[str]:
    """The registers an operand list names, `s` registers as the `d` register holding them."""
    out = []
    for r in REG.findall(text):
        if r[0] == "s" and r[1:].isdigit():
            r = f"d{int(r[1:]) // 2}"
        out.append({"sb": "r9", "sl": "r10", "fp": "r11", "ip": "r12"}.get(r, r))
    return out


def reg_list(text: str) -> list[str]:
    """The registers of a `{...}` list, ranges expanded."""
    m = re.search(r"\{([^}]*)\}", text)
    if not m:
        return []
    out = []
    for part in m.group(1).split(","):
        part = part.strip()
        if "-" in part:
            a, b = part.split("-")
            kind = a[0]
            out += [f"{kind}{i}" for i in range(int(a[1:]), int(b[1:]) + 1)]
        elif part:
            out.append(part)
    return [registers(r)[0] for r in out if registers(r)]


@dataclass
class Op:
    """One instruction as the model sees it."""

    dests: list[str] = field(default_factory=list)
    srcs: list[str] = field(default_factory=list)
    latency: int = 1
    cycles: int = 1  # issue cycles it occupies alone (single issue when > 1 or `single`)
    single: bool = False
    first: bool = False  # issues only as the first of a pair
    fp64: bool = False  # takes both VFP ports
    unit: str = "alu"
    acc: str | None = None  # accumulator read late (FP multiply-accumulate)


def classify(mnem: str, ops: str) -> Op:
    """The model's view of one instruction (mnemonic with its suffixes, operand text)."""
    base = re.sub(r"\.(w|n)$", "", mnem)
    regs = registers(ops.split("[")[0]) if "[" in ops else registers(ops)
    addr = registers(ops[ops.index("["):]) if "[" in ops else []
    writeback = "!" in ops or re.search(r"\],\s*#", ops) is not None
    f64 = ".f64" in base or any(r.startswith("d") for r in regs) and base.startswith("v")
    stem = base.split(".")[0]
    flags = ["flags"]
    if stem == "vldr":
        op = Op(dests=regs, srcs=addr, latency=2 if f64 else 1, single=f64, fp64=f64, unit="load")
    elif stem == "vstr":
        op = Op(srcs=regs + addr, single=f64, fp64=f64, unit="store")
    elif stem in ("vldmia", "vldmdb", "vpop", "vldm"):
        lst = reg_list(ops)
        base_reg = registers(ops.split("{")[0])
        op = Op(dests=lst + (base_reg if writeback or stem == "vpop" else []),
                srcs=base_reg or ["sp"], latency=2, single=True, cycles=max(1, len(lst)), unit="load")
    elif stem in ("vstmia", "vstmdb", "vpush", "vstm"):
        lst = reg_list(ops)
        base_reg = registers(ops.split("{")[0]) or ["sp"]
        op = Op(dests=base_reg, srcs=lst + base_reg, single=True, cycles=max(1, len(lst)), unit="store")
    elif stem in ("ldm", "ldmia", "ldmdb", "pop"):
        lst = reg_list(ops)
        base_reg = registers(ops.split("{")[0]) or ["sp"]
        op = Op(dests=lst + base_reg, srcs=base_reg, latency=2, single=True,
                cycles=max(1, (len(lst) + 1) // 2), unit="load")
    elif stem in ("stm", "stmia", "stmdb", "push"):
        lst = reg_list(ops)
        base_reg = registers(ops.split("{")[0]) or ["sp"]
        op = Op(dests=base_reg, srcs=lst + base_reg, single=True,
                cycles=max(1, (len(lst) + 1) // 2), unit="store")
    elif stem == "ldrd":
        op = Op(dests=regs + (addr[:1] if writeback else []), srcs=addr, latency=2, single=True, unit="load")
    elif stem == "strd":
        op = Op(dests=addr[:1] if writeback else [], srcs=regs + addr, single=True, unit="store")
    elif stem.startswith("ldr"):
        slow = stem[3:4] in ("b", "h", "s")
        op = Op(dests=regs + (addr[:1] if writeback else []), srcs=addr, latency=3 if slow else 2,
                unit="load")
    elif stem.startswith("str"):
        op = Op(dests=addr[:1] if writeback else [], srcs=regs + addr, unit="store")
    elif stem in ("tbb", "tbh"):
        op = Op(srcs=addr, single=True, cycles=2, unit="branch")
    elif stem in ("b", "bl", "bx", "blx", "cbz", "cbnz") or re.fullmatch(r"b(eq|ne|cs|hs|cc|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le|al)", stem):
        srcs = regs + (flags if stem not in ("b", "bl", "bx", "blx", "cbz", "cbnz") else [])
        dests = ["lr"] if stem in ("bl", "blx") else []
        op = Op(dests=dests, srcs=srcs, unit="branch")
    elif stem.startswith("it"):
        op = Op(srcs=flags)
    elif stem in ("sdiv", "udiv"):
        op = Op(dests=regs[:1], srcs=regs[1:], latency=7, single=True)
    elif stem in ("mul", "mla", "mls", "umull", "smull", "umlal", "smlal"):
        n = 2 if stem in ("umull", "smull", "umlal", "smlal") else 1
        op = Op(dests=regs[:n], srcs=regs[n:] + (regs[:n] if stem.endswith("al") else []), latency=2, unit="mac")
    elif stem in ("vmrs", "vmsr", "mrs", "msr", "cpsid", "cpsie", "dsb", "isb", "dmb", "svc", "bkpt", "nop", "wfi", "wfe", "sev", "udf"):
        dests = flags if stem == "vmrs" and "apsr" in ops.lower() else []
        srcs = ["fpscr"] if stem == "vmrs" else []
        op = Op(dests=dests, srcs=srcs, latency=3 if stem != "vmrs" else 1, single=True)
    elif stem.startswith("v"):
        # Arithmetic on the VFP: the first register written, the rest read.
        name = stem
        dests, srcs = regs[:1], regs[1:]
        if name in ("vcmp", "vcmpe"):
            dests, srcs = ["fpscr"], regs
        if name == "vmov" and len(regs) == 3:  # vmov r, r, d / vmov d, r, r
            dests, srcs = (regs[:2], regs[2:]) if regs[0].startswith("r") else (regs[:1], regs[1:])
            return Op(dests=dests, srcs=srcs, latency=3, single=True, unit="vfp")
        if name.startswith("vsel"):
            srcs = srcs + flags
        lat32 = {"vdiv": 16, "vsqrt": 16, "vmla": 6, "vmls": 6, "vnmla": 6, "vnmls": 6,
                 "vfma": 5, "vfms": 5, "vfnma": 5, "vfnms": 5, "vmov": 3}
        lat64 = {"vdiv": 30, "vsqrt": 30, "vmul": 7, "vnmul": 7, "vmla": 11, "vmls": 11,
                 "vnmla": 11, "vnmls": 11, "vfma": 11, "vfms": 11, "vfnma": 11, "vfnms": 11,
                 "vmov": 3, "vcmp": 0, "vcmpe": 0}
        mac = name in ("vmla", "vmls", "vnmla", "vnmls", "vfma", "vfms", "vfnma", "vfnms")
        latency = (lat64.get(name, 4) if f64 else lat32.get(name, 3))
        op = Op(dests=dests, srcs=srcs + (dests if mac else []), latency=latency,
                first=f64, fp64=f64, unit="vfp", acc=dests[0] if mac and dests else None)
    else:
        # Integer data processing: the first register written (none for compares and tests),
        # the flags written by compares and `s` forms.
        compare = stem in ("cmp", "cmn", "tst", "teq")
        sets_flags = compare or (len(stem) > 3 and stem.endswith("s"))
        dests, srcs = ([], regs) if compare else (regs[:1], regs[1:])
        if stem.startswith(("adc", "sbc")):
            srcs = srcs + flags
        if stem in ("movt", "bfi", "bfc"):
            srcs = srcs + regs[:1]
        op = Op(dests=dests + (flags if sets_flags else []), srcs=srcs,
                first=stem in ("bfi", "bfc", "clz", "ubfx", "sbfx"))
    return op


def pairs(a: Op, b: Op) -> bool:
    """Whether `b` issues in the same cycle as `a`, `a` first."""
    if a.single or b.single or b.first or (a.fp64 and b.fp64):
        return False
    # One VFP pipe, store port, multiplier and branch unit; two loads and two ALUs.
    return not (a.unit == b.unit and a.unit in ("vfp", "store", "mac", "branch"))


def cycles(ops: list[Op]) -> int:
    """Cycles to issue `ops` in order on the model (the last issue's cycle + 1)."""
    ready: dict[str, int] = defaultdict(int)
    t = 0  # the earliest cycle the next instruction issues in
    alone: tuple[Op, int] | None = None  # an instruction issued alone so far, and its cycle
    last = 0
    for op in ops:
        # A multiply-accumulate reads its accumulator three cycles late.
        need = max([ready[r] - (3 if r == op.acc else 0) for r in op.srcs] + [0])
        if alone is not None and need <= alone[1] and pairs(alone[0], op):
            issue, alone = alone[1], None
        else:
            issue = max(need, t)
            alone = (op, issue) if not op.single and op.cycles == 1 else None
            t = issue + op.cycles
        for r in op.dests:
            ready[r] = max(ready[r], issue + op.latency)
        last = max(last, issue)
    return last + 1


def systick_accesses(asm: dict[int, tuple[str, str]], handler: set[int]) -> set[int]:
    """The handler's loads and stores through a register holding SysTick's current-value
    address (built by `movw`/`movt`; the compiler may build it more than once, in different
    registers), the handler's executed instructions scanned in address order."""
    low: set[str] = set()  # movw #0xE018 done
    held: set[str] = set()  # the whole address
    out: set[int] = set()
    for pc in sorted(handler):
        mnem, ops = asm.get(pc, ("", ""))
        imm = ops.replace("0xe018", "57368").replace("0xe000", "57344")
        regs = registers(ops)
        base = registers(ops[ops.index("["):])[:1] if "[" in ops else []
        if mnem.startswith(("ldr", "str")) and base and base[0] in held:
            out.add(pc)
        if mnem.startswith("movw") and f"#{SYSTICK_CVR[0]}" in imm:
            held.discard(regs[0])
            low.add(regs[0])
        elif mnem.startswith("movt") and f"#{SYSTICK_CVR[1]}" in imm and regs[0] in low:
            held.add(regs[0])
        else:
            for d in classify(mnem, ops).dests:
                held.discard(d)
                low.discard(d)
    return out


def windows(asm: dict[int, tuple[str, str]], trace: list[int], handler: set[int]) -> list[list[int]]:
    """Each tick's timed instructions: in the tick interrupt's handler, from the read of
    SysTick after the stopwatch's restart (a store to its current value register) to the next
    read — the firmware's `servo.tick` window."""
    accesses = systick_accesses(asm, handler)

    def touches(pc: int, kind: str) -> bool:
        return pc in accesses and asm[pc][0].startswith(kind)

    out, i = [], 0
    while i < len(trace):
        if touches(trace[i], "str"):
            j = i + 1
            while j < len(trace) and not touches(trace[j], "ldr"):
                j += 1
            k = j + 1
            while k < len(trace) and not touches(trace[k], "ldr"):
                k += 1
            if k < len(trace):
                out.append(trace[j + 1:k + 1])
            i = k + 1
        else:
            i += 1
    return out


def estimate(log: Path) -> tuple[float, float, float]:
    """Mean and worst estimated cycles of the timed ticks in `log` (the probe's and the closing
    sample's excluded), and their mean instruction count."""
    asm, trace, handler = parse(log)
    # The last tick is the closing sample's (no command to compute).
    ticks = windows(asm, trace, handler)[:-1]
    if not ticks:
        raise SystemExit(f"{log}: no timed tick found in the trace")
    counts = [cycles([classify(*asm[pc]) for pc in w if pc in asm]) for w in ticks]
    return sum(counts) / len(counts), max(counts), sum(len(w) for w in ticks) / len(ticks)


if __name__ == "__main__":
    import sys

    mean, worst, instructions = estimate(Path(sys.argv[1]))
    print(f"{instructions:.0f} instructions, {mean:.0f} cycles mean, {worst:.0f} max (estimate)")
