#!/usr/bin/env python3
"""Turns criterion's estimates (target/criterion) into the README performance table.

Usage: cargo bench && python3 benches/report.py
Ratios: against the same-run nalgebra baseline, the thesis DSP (Table 6-1 cycles at 1 GHz, i.e.
cycles = ns) and the FMA bound of this CPU (N² + 2N FMAs for an N-state SISO tick, 2 FMA units x
4 f64 lanes with AVX2, at the nominal clock read from /proc/cpuinfo).
"""
import json
import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parent.parent / "target" / "criterion"
THESIS_CYCLES = {"pid": 430, "state_space_8": 3045, "state_space_13": 7128, "state_space_27": 28204}


def mean_ns(group, bench):
    path = ROOT / group / bench / "new" / "estimates.json"
    if not path.exists():  # `c.bench_function("group/bench")` lands in "group_bench"
        path = ROOT / f"{group}_{bench}" / "new" / "estimates.json"
    if not path.exists():
        return None
    return json.loads(path.read_text())["mean"]["point_estimate"]


def cpu_ghz():
    text = pathlib.Path("/proc/cpuinfo").read_text()
    mhz = re.search(r"cpu MHz\s*:\s*([\d.]+)", text)
    return float(mhz.group(1)) / 1000.0 if mhz else None


def main():
    ghz = cpu_ghz()
    print(f"| tick | ns/tick | vs nalgebra baseline | vs thesis DSP (Table 6-1) | vs FMA bound ({ghz:.1f} GHz, AVX2) |")
    print("|---|---|---|---|---|")
    for group in ["pid", "cascade", "biquad", "state_space_8", "state_space_13", "state_space_27"]:
        ns = mean_ns(group, "servo_core")
        if ns is None:
            continue
        base = mean_ns(group, "nalgebra_baseline")
        vs_base = f"{base / ns:.2f}x faster ({base:.1f} ns)" if base else "-"
        cycles = THESIS_CYCLES.get(group)
        vs_dsp = f"{cycles / ns:.0f}x faster ({cycles} ns)" if cycles else "-"
        m = re.match(r"state_space_(\d+)", group)
        if m and ghz:
            n = int(m.group(1))
            bound_ns = (n * n + 2 * n) / 8.0 / ghz
            vs_fma = f"{ns / bound_ns:.2f}x the bound ({bound_ns:.1f} ns)"
        else:
            vs_fma = "-"
        print(f"| {group} | {ns:.1f} | {vs_base} | {vs_dsp} | {vs_fma} |")
    sim = mean_ns("sim_step", "plant_sim")
    if sim:
        base = mean_ns("sim_step", "nalgebra_baseline")
        rate = 1e9 / sim
        print()
        print("| simulator | ns/step | steps/s | x real time at 199.6 kHz | vs dense nalgebra step |")
        print("|---|---|---|---|---|")
        print(f"| heavy stage, all noise, intermittent cut | {sim:.0f} | {rate / 1e6:.2f} M | {rate / 199_600:.1f}x "
              f"| {base / sim:.2f}x faster ({base:.0f} ns) |")


def recorder():
    mcap = mean_ns("recorder_1s", "mcap_zstd")
    if not mcap:
        return
    raw = mean_ns("recorder_1s", "raw_file_baseline")
    print()
    print("| recorder | time per simulated second | x real time | raw file baseline (same run) |")
    print("|---|---|---|---|")
    print(f"| 199 600 frames, 399 200 messages, zstd-1 | {mcap / 1e6:.0f} ms | {1e9 / mcap:.1f}x | {raw / 1e6:.0f} ms |")


def synthesis():
    h2 = mean_ns("synthesis", "h2_29_states")
    if not h2:
        return
    dare = mean_ns("synthesis", "dare_baseline")
    print()
    print("| synthesis | time | vs one DARE of the same plant (same run) |")
    print("|---|---|---|")
    print(f"| H2, 29 states at 20 kHz (model, 2 DAREs, closed-loop norm) | {h2 / 1e6:.2f} ms | {h2 / dare:.1f}x ({dare / 1e6:.2f} ms) |")


if __name__ == "__main__":
    main()
    recorder()
    synthesis()
