"""The stage and the controller as FMI units (``servo fmu``), loaded by FMPy as Simulink or a
Modelica tool would load them: validated, simulated, closed around each other bit for bit as
``servo run`` closes its loop, the stage bit for bit as libfts_plant, and every refusal an FMI
error whose message names the key."""

from __future__ import annotations

import ctypes
import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from fmpy import dump, extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

ROOT = Path(__file__).resolve().parents[2]
SERVO = os.environ.get("FTS_SERVO_BIN", str(ROOT / "target" / "release" / "servo"))
PERIOD = 1.0 / 199_600.0
VERSIONS = ("2", "3")


def servo(*args: str) -> str:
    run = subprocess.run([SERVO, *args], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    return run.stdout


@pytest.fixture(scope="module")
def units(tmp_path_factory) -> dict:
    """Both units in both versions, of a 0.1 s run of the default loop (seed 5)."""
    d = tmp_path_factory.mktemp("fmu")
    run = d / "run.toml"
    run.write_text("[run]\nduration_s = 0.1\nseed = 5\n")
    servo("deploy", "-c", str(run), "-o", str(d / "deploy.toml"))
    out = {"dir": d, "run": run}
    for v in VERSIONS:
        out[f"stage{v}"] = d / f"stage{v}.fmu"
        out[f"controller{v}"] = d / f"controller{v}.fmu"
        servo("fmu", "stage", "-c", str(run), "--fmi", v, "-o", str(out[f"stage{v}"]))
        servo("fmu", "controller", str(d / "deploy.toml"), "--fmi", v, "-o", str(out[f"controller{v}"]))
    return out


class Log:
    """The messages a unit logs, for FMPy's instantiate."""

    def __init__(self) -> None:
        self.messages: list[str] = []

    def fmi3(self, _env, _status, _category, message) -> None:
        self.messages.append(message.decode())

    def fmi2(self, _env, _name, _status, _category, message) -> None:
        self.messages.append(message.decode())

    def text(self) -> str:
        return "\n".join(self.messages)


def open_unit(path: Path, version: str, log: Log | None = None):
    """An instantiated unit (FMPy's slave classes, as a master program would use them)."""
    md = read_model_description(str(path))
    unzipped = extract(str(path))
    cls = FMU2Slave if version == "2" else FMU3Slave
    identifier = md.coSimulation.modelIdentifier
    unit = cls(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=identifier, instanceName=identifier)
    log = log or Log()
    if version == "2":
        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(log.fmi2)
        callbacks.allocateMemory = defaultCallbacks.allocateMemory
        callbacks.freeMemory = defaultCallbacks.freeMemory
        unit._log_keep = callbacks  # kept alive as long as the unit
        unit.instantiate(callbacks=callbacks)
    else:
        unit.instantiate(logMessage=log.fmi3)
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    return unit, vrs, log


def start(unit, version: str) -> None:
    if version == "2":
        unit.setupExperiment(startTime=0.0)
        unit.enterInitializationMode()
        unit.exitInitializationMode()
    else:
        unit.enterInitializationMode(startTime=0.0)
        unit.exitInitializationMode()


def get_real(unit, version: str, vrs: list[int]) -> list[float]:
    return unit.getReal(vrs) if version == "2" else unit.getFloat64(vrs)


def set_real(unit, version: str, vrs: list[int], values: list[float]) -> None:
    if version == "2":
        unit.setReal(vrs, values)
    else:
        unit.setFloat64(vrs, values)


def fnv(h: int, word: int) -> int:
    for i in range(8):
        h ^= (word >> (8 * i)) & 0xFF
        h = (h * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return h


def bits(x: float) -> int:
    return int(np.float64(x).view(np.uint64))


@pytest.mark.parametrize("version", VERSIONS)
def test_fmpy_validates_dumps_and_simulates_both_units(units: dict, version: str, capsys) -> None:
    for kind in ("stage", "controller"):
        path = str(units[f"{kind}{version}"])
        assert validate_fmu(path) == [], (kind, validate_fmu(path))
        dump(path)
        assert f"FMI Version        {version}.0" in capsys.readouterr().out
        md = read_model_description(path)
        assert md.coSimulation.canHandleVariableCommunicationStepSize is False
        assert md.defaultExperiment.stepSize == str(PERIOD) or float(md.defaultExperiment.stepSize) == PERIOD
        result = simulate_fmu(path, stop_time=0.002, step_size=PERIOD, output_interval=PERIOD)
        assert len(result) == 400, len(result)
    stage = read_model_description(str(units[f"stage{version}"]))
    m2 = next(v for v in stage.modelVariables if v.name == "plant.stage.m2_kg")
    assert (m2.causality, float(m2.start), float(m2.min), float(m2.max)) == ("parameter", 0.070, 1e-6, 1e3)
    assert m2.unit == "kg" or (m2.declaredType is None and "kg" in (m2.unit or ""))


@pytest.mark.parametrize("version", VERSIONS)
def test_the_units_closed_in_the_loops_order_equal_servo_run_bit_for_bit(units: dict, version: str) -> None:
    want = json.loads(servo("run", "-q", "--no-record", "--json", "--digest", "-c", str(units["run"])))
    stage, sv, _ = open_unit(units[f"stage{version}"], version)
    ctl, cv, _ = open_unit(units[f"controller{version}"], version)
    start(stage, version)
    start(ctl, version)
    readings = [sv["gap_v"], sv["accel_v"]]
    ticks = want["ticks"]
    digest = 0xCBF29CE484222325
    t = 0.0
    for k in range(ticks):
        gap, accel = get_real(stage, version, readings)  # reading k
        set_real(ctl, version, [cv["gap_v"], cv["accel_v"]], [gap, accel])
        (dac,) = get_real(ctl, version, [cv["dac_v"]])  # command k
        digest = fnv(fnv(fnv(fnv(digest, k), bits(gap)), bits(accel)), bits(dac))
        set_real(stage, version, [sv["dac_v"]], [dac])
        ctl.doStep(t, PERIOD)
        stage.doStep(t, PERIOD)  # holds command k over tick k
        t += PERIOD
    assert f"{digest:016x}" == want["meta"]["loop_digest"], (ticks, want["meta"]["loop_digest"])
    for u in (stage, ctl):
        u.terminate()
        u.freeInstance()


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


@pytest.mark.parametrize("version", VERSIONS)
def test_the_stage_unit_reads_as_libfts_plant_bit_for_bit(units: dict, version: str) -> None:
    lib = ctypes.CDLL(str(Path(SERVO).resolve().parent / "libfts_plant.so"))
    handle = ctypes.c_void_p()
    error = ctypes.create_string_buffer(512)
    assert lib.fts_plant_open(str(units["run"]).encode(), ctypes.byref(handle), error, 512) == 0, error.value
    lib.fts_plant_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.POINTER(Sensor), ctypes.c_void_p]
    stage, sv, _ = open_unit(units[f"stage{version}"], version)
    start(stage, version)
    s = Sensor()
    lib.fts_plant_initial(handle, ctypes.byref(s))
    dac = np.random.default_rng(11).uniform(-2.0, 2.0, 3000)
    out = [sv["gap_v"], sv["accel_v"]]
    assert get_real(stage, version, out) == [s.gap_v, s.accel_v]
    t = 0.0
    for k, u in enumerate(dac):
        assert lib.fts_plant_step(handle, u, ctypes.byref(s), None) == 0
        set_real(stage, version, [sv["dac_v"]], [u])
        stage.doStep(t, PERIOD)
        t += PERIOD
        got = get_real(stage, version, out)
        assert got == [s.gap_v, s.accel_v], (k, got, s.gap_v, s.accel_v)
    lib.fts_plant_close(handle)
    stage.terminate()
    stage.freeInstance()


@pytest.mark.parametrize("version", VERSIONS)
def test_each_refusal_is_an_fmi_error_naming_its_key(units: dict, version: str) -> None:
    # A parameter out of its range: refused where it is set.
    stage, sv, log = open_unit(units[f"stage{version}"], version)
    with pytest.raises(FMICallException):
        set_real(stage, version, [sv["plant.stage.m1_kg"]], [-1.0])
    assert "plant.stage.m1_kg = -1 is outside its allowed range [1e-6, 1e3] kg" in log.text(), log.text()
    # An input with a range: the force on the tool.
    with pytest.raises(FMICallException):
        set_real(stage, version, [sv["force_n"]], [1e4])
    assert "force_n = 10000 is outside its allowed range [-1e3, 1e3] N" in log.text(), log.text()
    # A value reference the unit does not have.
    with pytest.raises(FMICallException):
        set_real(stage, version, [99999], [1.0])
    assert "value reference 99999 is not a variable of this unit" in log.text()
    # A value within the table's range that the stage narrows: the delay beyond one period.
    set_real(stage, version, [sv["plant.timing.delay_s"]], [1e-3])
    with pytest.raises(FMICallException):
        start(stage, version)
    assert "plant.timing.delay_s = 0.001 is outside its allowed range [0, 5.01002004008016e-6] s" in log.text(), log.text()
    stage.freeInstance()

    # A step that is not a whole number of ticks: refused, not interpolated.
    stage, sv, log = open_unit(units[f"stage{version}"], version)
    start(stage, version)
    with pytest.raises(FMICallException):
        stage.doStep(0.0, 1.5 * PERIOD)
    assert "is not a whole number of ticks" in log.text(), log.text()
    with pytest.raises(FMICallException):
        stage.doStep(0.0, 2e6 * PERIOD)
    assert "at most 1e6 ticks a step" in log.text(), log.text()
    stage.doStep(0.0, 3 * PERIOD)  # three ticks are a step
    (plant_sha256,) = stage.getString([sv["plant_sha256"]])
    plant_sha256 = plant_sha256.decode() if isinstance(plant_sha256, bytes) else plant_sha256
    assert len(plant_sha256) == 64, plant_sha256
    stage.freeInstance()

    # A controller made for another plant than the stage's: refused at initialisation.
    heavy = units["dir"] / "heavy.toml"
    if not heavy.exists():
        servo("deploy", "--mass", "heavy", "-o", str(heavy))
    path = units["dir"] / f"heavy{version}.fmu"
    if not path.exists():
        servo("fmu", "controller", str(heavy), "--fmi", version, "-o", str(path))
    ctl, cv, log = open_unit(path, version)
    ctl.setString([cv["plant_sha256"]], [plant_sha256])
    with pytest.raises(FMICallException):
        start(ctl, version)
    assert "controller.made_for: the deployment was made for stage heavy" in log.text(), log.text()
    ctl.freeInstance()
    # The light stage's own controller takes the same digest.
    ctl, cv, log = open_unit(units[f"controller{version}"], version)
    ctl.setString([cv["plant_sha256"]], [plant_sha256])
    start(ctl, version)
    ctl.freeInstance()
