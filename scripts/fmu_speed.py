#!/usr/bin/env python3
"""What the FMI boundary costs: the stage and controller units (``servo fmu``) closed around
each other by FMPy for 0.1 s of run (19 960 ticks at 199.6 kHz), and the stage alone through
FMPy against libfts_plant's ``fts_plant_step`` called from the same Python process — the same
simulator behind both, so the difference is the FMI boundary and FMPy's wrappers.

    python3 scripts/fmu_speed.py [--servo target/release/servo]

Needs FMPy (``pip install fmpy``) and libfts_plant.so beside the servo binary.
"""

from __future__ import annotations

import argparse
import ctypes
import subprocess
import tempfile
import time
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

ROOT = Path(__file__).resolve().parents[1]


class Sensor(ctypes.Structure):
    _fields_ = [
        ("seq", ctypes.c_uint64),
        ("time_s", ctypes.c_double),
        ("gap_v", ctypes.c_double),
        ("accel_v", ctypes.c_double),
        ("encoder_count", ctypes.c_uint64),
        ("flags", ctypes.c_uint32),
        ("reserved", ctypes.c_uint32),
        ("run_id", ctypes.c_uint64),
        ("published_ns", ctypes.c_uint64),
    ]


def open_unit(path: Path, version: str):
    md = read_model_description(str(path))
    cls = FMU2Slave if version == "2" else FMU3Slave
    ident = md.coSimulation.modelIdentifier
    unit = cls(guid=md.guid, unzipDirectory=extract(str(path)), modelIdentifier=ident, instanceName=ident)
    unit.instantiate()
    if version == "2":
        unit.setupExperiment(startTime=0.0)
        unit.enterInitializationMode()
    else:
        unit.enterInitializationMode(startTime=0.0)
    unit.exitInitializationMode()
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    get = unit.getReal if version == "2" else unit.getFloat64
    put = unit.setReal if version == "2" else unit.setFloat64
    return unit, vrs, get, put, float(md.defaultExperiment.stepSize)


def closed_loop(d: Path, version: str, ticks: int) -> float:
    stage, sv, sget, sput, h = open_unit(d / f"stage{version}.fmu", version)
    ctl, cv, cget, cput, _ = open_unit(d / f"controller{version}.fmu", version)
    readings, inputs, dac, command = [sv["gap_v"], sv["accel_v"]], [cv["gap_v"], cv["accel_v"]], [sv["dac_v"]], [cv["dac_v"]]
    started = time.perf_counter()
    t = 0.0
    for _ in range(ticks):
        cput(inputs, sget(readings))
        sput(dac, cget(command))
        ctl.doStep(t, h)
        stage.doStep(t, h)
        t += h
    took = time.perf_counter() - started
    for u in (stage, ctl):
        u.terminate()
        u.freeInstance()
    return took


def stage_alone(d: Path, version: str, ticks: int) -> float:
    stage, sv, sget, sput, h = open_unit(d / f"stage{version}.fmu", version)
    readings, dac = [sv["gap_v"], sv["accel_v"]], [sv["dac_v"]]
    started = time.perf_counter()
    t = 0.0
    for k in range(ticks):
        sput(dac, [1e-3 * (k % 7)])
        stage.doStep(t, h)
        sget(readings)
        t += h
    took = time.perf_counter() - started
    stage.terminate()
    stage.freeInstance()
    return took


def plant_alone(lib: ctypes.CDLL, run: Path, ticks: int) -> float:
    handle = ctypes.c_void_p()
    error = ctypes.create_string_buffer(512)
    assert lib.fts_plant_open(str(run).encode(), ctypes.byref(handle), error, 512) == 0, error.value
    lib.fts_plant_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.POINTER(Sensor), ctypes.c_void_p]
    s = Sensor()
    lib.fts_plant_initial(handle, ctypes.byref(s))
    started = time.perf_counter()
    for k in range(ticks):
        lib.fts_plant_step(handle, 1e-3 * (k % 7), ctypes.byref(s), None)
        (s.gap_v, s.accel_v)
    took = time.perf_counter() - started
    lib.fts_plant_close(handle)
    return took


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--servo", default=str(ROOT / "target" / "release" / "servo"))
    a = p.parse_args()
    servo = Path(a.servo).resolve()
    lib = ctypes.CDLL(str(servo.parent / "libfts_plant.so"))
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        run = d / "run.toml"
        run.write_text("[run]\nduration_s = 0.1\n")
        subprocess.run([servo, "deploy", "-c", run, "-o", d / "deploy.toml"], check=True, capture_output=True)
        for v in ("2", "3"):
            subprocess.run([servo, "fmu", "stage", "-c", run, "--fmi", v, "-o", d / f"stage{v}.fmu"], check=True, capture_output=True)
            subprocess.run([servo, "fmu", "controller", d / "deploy.toml", "--fmi", v, "-o", d / f"controller{v}.fmu"], check=True, capture_output=True)
        ticks = 19_960
        print(f"{ticks} ticks (0.1 s at 199.6 kHz), one process, Python {'.'.join(map(str, __import__('sys').version_info[:3]))}")
        for v in ("2", "3"):
            took = closed_loop(d, v, ticks)
            print(f"  FMI {v}.0 closed loop (stage + controller units, FMPy): took {took:.2f} s, {took / ticks * 1e6:.1f} us a tick")
        base = plant_alone(lib, run, ticks)
        print(f"  libfts_plant fts_plant_step through ctypes: took {base:.3f} s, {base / ticks * 1e6:.1f} us a tick")
        for v in ("2", "3"):
            took = stage_alone(d, v, ticks)
            print(f"  FMI {v}.0 stage unit alone (set, step, get; FMPy): took {took:.3f} s, {took / ticks * 1e6:.1f} us a tick, {(took - base) / ticks * 1e6:.1f} us over fts_plant_step")


if __name__ == "__main__":
    main()
