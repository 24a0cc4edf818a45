"""The fts_servo package against independent truth: the servo CLI's own numbers, python-control,
the four-mass stage's impedance transfer functions, the PyPI mcap reader, located errors."""

from __future__ import annotations

import json
import os
import struct
import subprocess
import tomllib
from pathlib import Path

import control
import numpy as np
import pytest

import fts_servo as fs

ROOT = Path(__file__).resolve().parents[2]
SERVO = os.environ.get("FTS_SERVO_BIN", str(ROOT / "target" / "release" / "servo"))

CONFIG = """
# A short sine run on the heavy stage, seeded.
[run]
duration_s = 0.05
seed = 7

[scenario]
kind = "sine"
amplitude_m = 1e-6
frequency_hz = 300.0
"""


def servo(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([SERVO, *args], capture_output=True, text=True, check=True)


@pytest.fixture()
def config_file(tmp_path: Path) -> Path:
    p = tmp_path / "sine.toml"
    p.write_text(CONFIG)
    return p


def test_a_run_equals_the_cli_for_the_same_config_and_seed(config_file: Path) -> None:
    cli = json.loads(servo("run", "-q", "--json", "--no-record", "-c", str(config_file)).stdout)
    ours = fs.run(config_file)
    for key in ("ticks", "following_error_m", "true_error_m", "control_v", "saturated_ticks"):
        assert ours.summary[key] == cli[key], key
    # The arrays are the run the summary describes: ticks, and its RMS after settling.
    assert len(ours.time_s) == cli["ticks"]
    settle = ours.time_s >= ours.time_s[0] + cli["simulated_s"] - cli["stats_ticks"] / 199_600.0
    e = ours.telemetry["following_error_m"][settle].astype(np.float64)
    assert np.sqrt(np.mean(e**2)) == pytest.approx(cli["following_error_m"]["rms"], rel=1e-5)


def test_keyword_tables_merge_over_a_dict_or_a_file(config_file: Path) -> None:
    from_file = fs.run(config_file, run={"duration_s": 0.02})
    as_dict = fs.run(tomllib.loads(CONFIG), run={"duration_s": 0.02})
    assert from_file.summary["ticks"] == round(0.02 * 199_600)
    assert from_file.summary["following_error_m"] == as_dict.summary["following_error_m"]
    assert tomllib.loads(from_file.config_toml)["run"]["seed"] == 7


def test_every_model_is_a_python_control_system() -> None:
    models = fs.models()
    for name, m in models.items():
        sys = control.ss(*m)
        assert sys.ninputs == len(m.inputs) and sys.noutputs == len(m.outputs), name
        assert (sys.dt or 0.0) == m.dt, name
    # The sampled closed loop is stable and agrees with the loop's own frequency response.
    cl = control.ss(*models["closed_loop"])
    assert np.max(np.abs(cl.poles())) < 1.0
    f = np.array([10.0, 300.0, 2000.0, 20000.0])
    ours = fs.loop_response(f)["closed_loop"]
    i = models["closed_loop"].inputs.index("reference_m")
    o = models["closed_loop"].outputs.index("measured_m")
    z = np.exp(2j * np.pi * f * cl.dt)
    theirs = np.array([cl(zk)[o, i] for zk in z])
    np.testing.assert_allclose(ours, theirs, rtol=1e-9)


@pytest.mark.parametrize("tables", [{}, {"controller": {"kind": "accel"}}])
def test_the_loop_gain_gives_the_budgets_margins_and_the_named_models_close_the_loop(
    tmp_path: Path, tables: dict
) -> None:
    """python-control's own margin search on the exported loop gain gives `servo budget`'s
    margins; the plant and controller joined by signal name are the recorded closed loop."""
    models = fs.models(**tables)
    loop = control.ss(*models["loop_gain"])
    # On the state space itself control.margin's polynomial method is ill-conditioned for this
    # stiff loop (poles within 1e-3 of z = 1) and falls back to a coarse grid: give it the
    # response on a dense grid over the range `servo budget` searches (1 Hz to Nyquist).
    f = np.logspace(0, np.log10(0.499 / loop.dt), 20000)
    gm, pm, wcg, wcp = control.margin(control.frd(loop, 2 * np.pi * f))
    config = tmp_path / "loop.toml"
    config.write_text("\n".join(f"[{t}]\n" + "\n".join(f'{k} = "{v}"' for k, v in kv.items()) for t, kv in tables.items()))
    cli = json.loads(servo("budget", "--json", "-c", str(config), "--out-dir", str(tmp_path / "b")).stdout)
    margins = cli["margins"]
    assert 20 * np.log10(gm) == pytest.approx(margins["gain_margin_db"], abs=1e-6)
    assert pm == pytest.approx(margins["phase_margin_deg"], abs=1e-6)
    assert wcg / (2 * np.pi) == pytest.approx(margins["phase_crossover_hz"], rel=1e-6)
    assert wcp / (2 * np.pi) == pytest.approx(margins["gain_crossover_hz"], rel=1e-6)
    # S = 1/(1 + L) for the gap-only PID (the reference enters as the gap does); with
    # acceleration feedback L holds the inner loop and S is the outer loop's alone.
    sens = control.ss(*models["sensitivity"])
    z = np.exp(2j * np.pi * np.array([30.0, 700.0, 5000.0]) * loop.dt)
    if not tables:
        np.testing.assert_allclose([sens(zk) for zk in z], [1 / (1 + loop(zk)) for zk in z], rtol=1e-9)
    # Joined by name (command_v, gap_v, accel_v), plant and controller have the closed
    # loop's poles: the loop driven by the cutting force, seen at the tool.
    joined = control.interconnect(
        [models["plant_sampled"].ss("plant"), models["controller"].ss("controller")],
        inplist=["cutting_force_n"], outlist=["tool_m"], check_unused=False,
    )
    closed = control.ss(*models["closed_loop"])
    i, o = models["closed_loop"].inputs.index("cutting_force_n"), models["closed_loop"].outputs.index("tool_m")
    np.testing.assert_allclose([complex(joined(zk)) for zk in z], [closed(zk)[o, i] for zk in z], rtol=1e-8)


def impedance_responses(p: dict, f_hz: np.ndarray) -> dict:
    """The stage's transfer functions from mechanical impedances (node equations in the
    frequency domain, thesis eq 5-4..5-7): m1 and m4 hang on m2, m3 sits between k2 and k3."""
    s = 2j * np.pi * f_hz
    k = {i: p[f"k{i}_n_per_m"] + p[f"c{i}_n_s_per_m"] * s for i in (1, 2, 3, 4, 5)}
    m1, m2, m3, m4 = (p[f"m{i}_kg"] for i in (1, 2, 3, 4))

    def hanging(m, kc):
        return kc * m * s**2 / (m * s**2 + kc)

    z1, z4 = hanging(m1, k[1]), hanging(m4, k[4])
    m3s = m3 * s**2 + k[3]
    z3 = k[2] * m3s / (m3s + k[2])
    rest = m2 * s**2 + z3 + z4 + k[5]
    tool_over_m2 = k[1] / (m1 * s**2 + k[1])
    x2_per_f = 1.0 / (rest + z1)
    zm2 = m2 * s**2 + z1 + z4 + k[5] + k[2]
    x3 = k[3] / (m3 * s**2 + k[3] + k[2] - k[2] ** 2 / zm2)
    x2_from_k5 = k[5] / (zm2 - k[2] ** 2 / (m3 * s**2 + k[3] + k[2]))
    return {
        "motor_force_to_gap": x2_per_f,
        "motor_force_to_x1": x2_per_f * tool_over_m2,
        "cut_force_to_tool": 1.0 / (m1 * s**2 + k[1] * rest / (rest + k[1])),
        "base_to_tool": (k[2] * x3 / zm2 + x2_from_k5) * tool_over_m2 - 1.0,
    }


@pytest.mark.parametrize("tables", [{}, {"plant": {"stage": {"m2_kg": 0.17, "k5_n_per_m": 300.0, "c5_n_s_per_m": 0.3}}}])
def test_the_exported_mechanics_equal_the_impedance_transfer_functions(tables: dict) -> None:
    m = fs.models(**tables)["mechanics"]
    stage = tomllib.loads(fs.resolved_config(**tables))["plant"]["stage"]
    f = np.logspace(0.5, 5.2, 60)
    want = impedance_responses(stage, f)
    sys = control.ss(*m)
    g = np.array([sys(2j * np.pi * fk) for fk in f])  # (freq, outputs, inputs)
    col = {n: i for i, n in enumerate(m.inputs)}
    row = {n: i for i, n in enumerate(m.outputs)}
    got = {
        "motor_force_to_gap": g[:, row["gap_m"], col["motor_force_n"]],
        "motor_force_to_x1": g[:, row["x1_m"], col["motor_force_n"]],
        "cut_force_to_tool": g[:, row["tool_m"], col["cutting_force_n"]],
        # Base displacement with its velocity (ẋg = s·xg).
        "base_to_tool": g[:, row["tool_m"], col["base_m"]]
        + 2j * np.pi * f * g[:, row["tool_m"], col["base_velocity_m_s"]],
    }
    for name in want:
        np.testing.assert_allclose(got[name], want[name], rtol=1e-9, err_msg=name)


def test_a_recording_read_through_the_package_equals_the_mcap_reader(tmp_path: Path) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    rec = tmp_path / "run.mcap"
    servo("run", "-q", "--duration", "0.02", "--scenario", "sine", "--out", str(rec))
    ours = fs.read_recording(rec)
    assert ours.finished
    theirs: dict = {"telemetry": {}, "truth": {}, "time_ns": []}
    with open(rec, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        for _, channel, message, msg in reader.iter_decoded_messages(topics=["/telemetry", "/truth"]):
            group = channel.topic.strip("/")
            for field in ours.telemetry if group == "telemetry" else ours.truth:
                theirs[group].setdefault(field, []).append(getattr(msg, field))
            if group == "telemetry":
                theirs["time_ns"].append(message.log_time)
    for group in ("telemetry", "truth"):
        mine = getattr(ours, group)
        assert set(mine) == set(theirs[group])
        for field, values in theirs[group].items():
            np.testing.assert_array_equal(mine[field], np.asarray(values, dtype=np.float32), err_msg=field)
    t0 = theirs["time_ns"][0] - round(ours.time_s[0] * 1e9)
    np.testing.assert_array_equal(np.round(ours.time_s * 1e9).astype(np.int64), np.asarray(theirs["time_ns"]) - t0)
    cli = json.loads(servo("inspect", "--json", str(rec)).stdout)
    assert ours.summary["following_error_m"] == cli["summary"]["following_error_m"]


def test_a_damaged_recording_raises_unless_salvaged(tmp_path: Path) -> None:
    rec = tmp_path / "run.mcap"
    servo("run", "-q", "--duration", "0.05", "--out", str(rec))
    data = bytearray(rec.read_bytes())
    # The second chunk of messages (records: opcode, uint64 length, body; chunks are 0x06).
    at, chunks = 8, []
    while at + 9 <= len(data) and data[at] != 0x02:  # up to the footer
        length = struct.unpack_from("<Q", data, at + 1)[0]
        if data[at] == 0x06:
            chunks.append((at, 9 + length))
        at += 9 + length
    start, length = chunks[1]
    data[start + length // 2] ^= 0x01
    hit = tmp_path / "hit.mcap"
    hit.write_bytes(bytes(data))
    with pytest.raises(fs.ServoError, match="hit.mcap.*damaged.*salvage"):
        fs.read_recording(hit)
    salvaged = fs.read_recording(hit, salvage=True)
    assert "chunk CRC mismatch" in salvaged.read
    whole = fs.read_recording(rec)
    assert 0 < len(salvaged.time_s) < len(whole.time_s)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(rec.read_bytes()[:-1])  # the closing magic's last byte
    with pytest.raises(fs.ServoError, match="closing magic"):
        fs.read_recording(cut)


def test_errors_raise_with_the_located_message(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[run]\nduration_s = -1.0\n")
    with pytest.raises(fs.ServoError) as e:
        fs.run(bad)
    message = str(e.value)
    assert str(bad) in message and ":2" in message, message
    assert "run.duration_s" in message and "(0, 86400] s" in message, message
    with pytest.raises(fs.ServoError, match="unknown field"):
        fs.run({"run": {"duraton_s": 1.0}})
    with pytest.raises(fs.ServoError, match=r"run\.duration_s: a set is not a TOML value"):
        fs.run(run={"duration_s": {1.0}})
    with pytest.raises(fs.ServoError, match="No such file|not found|cannot read"):
        fs.read_recording(tmp_path / "missing.mcap")


def test_tuning_equals_the_cli_and_its_fragment_runs(tmp_path: Path) -> None:
    out = tmp_path / "pid.toml"
    cli = json.loads(servo("tune", "--json", "--bandwidth-hz", "1200", "-o", str(out)).stdout)
    ours = fs.tune(bandwidth_hz=1200.0)
    assert ours["tuned"] == cli["tuned"] and ours["reference"] == cli["reference"]
    assert ours["controller_toml"] == out.read_text()
    # What the tuning promised is what the loop of its fragment has.
    fragment = tmp_path / "ours.toml"
    fragment.write_text(ours["controller_toml"])
    b = fs.budget(fragment)
    assert b["bandwidth_hz"] == pytest.approx(ours["tuned"]["bandwidth_hz"], rel=1e-6)
    assert b["budget"]["following_rms_m"] == pytest.approx(ours["tuned"]["following_rms_m"], rel=1e-6)


def test_the_h2_controller_closes_a_stable_loop_and_runs_as_the_cli_runs_it(tmp_path: Path) -> None:
    rate = {"plant": {"timing": {"servo_rate_hz": 20000.0}}}
    d = fs.synth_h2(**rate)
    k = control.ss(*d["controller"])
    assert k.dt == pytest.approx(5e-5) and np.max(np.abs(k.poles())) < 1.0 + 1e-12
    ss_file = tmp_path / "h2.toml"
    ss_file.write_text(d["controller_toml"])
    tables = {**rate, "run": {"duration_s": 0.2}, "controller": {"kind": "ss", "ss_file": str(ss_file)}}
    ours = fs.run(**tables)
    cli = json.loads(
        servo(
            "run", "-q", "--json", "--no-record", "--rate", "20000", "--duration", "0.2",
            "--controller", "ss", "--ss-file", str(ss_file),
        ).stdout
    )
    assert ours.summary["following_error_m"] == cli["following_error_m"]
    # The closed loop of the design is stable (the run's own check) and sub-nanometre.
    assert ours.summary["meta"]["spectral_radius"] < 1.0
    assert ours.summary["following_error_m"]["rms"] < 2e-9


def test_budget_and_synthesis_are_the_clis_numbers_from_the_same_function(tmp_path: Path) -> None:
    """`servo budget --json` and `fs.budget`, `servo synth h2 --json` and `fs.synth_h2`: one
    library function each (studies::budget::analyse, studies::synth::synthesize), so the same
    numbers to the last bit — margins, stability range and the file included."""
    cli = json.loads(
        servo("budget", "--json", "--points", "400", "--mass", "heavy", "--out-dir", str(tmp_path / "b")).stdout
    )
    ours = fs.budget(plant={"stage": {"m2_kg": 0.17}})
    assert ours["budget"] == cli["budget"] and ours["margins"] == cli["margins"]
    assert ours["margins"]["gain_margin_db"] > 6.0
    out = tmp_path / "h2.toml"
    cli = json.loads(
        servo("synth", "h2", "--json", "--rate", "20000", "--order", "13", "--out", str(out)).stdout
    )
    d = fs.synth_h2(order=13, plant={"timing": {"servo_rate_hz": 20000.0}})
    assert d["prediction"] == cli["prediction"]
    assert d["controller_toml"] == out.read_text()
    p = d["prediction"]
    assert p["states"] == 13 and 0 < p["stability"]["unstable_below"] < 1 < p["stability"]["unstable_above"]
    assert "[stability]" in d["controller_toml"]


def test_identification_recovers_a_known_stage_from_its_frequency_response() -> None:
    drawn = {"k2_n_per_m": 21965.0 * 1.1, "m4_kg": 0.0088, "c4_n_s_per_m": 7.0}
    f = np.logspace(np.log10(20.0), 4.0, 80)
    g = fs.loop_response(f, plant={"stage": drawn})["plant_m_per_v"]
    r = fs.identify(f, g)
    fitted = dict(zip(r["names"], r["fitted"]))
    assert fitted["k2 N/m"] == pytest.approx(drawn["k2_n_per_m"], rel=1e-6)
    assert fitted["m4 kg"] == pytest.approx(drawn["m4_kg"], rel=1e-6)
    assert fitted["c4 N·s/m"] == pytest.approx(drawn["c4_n_s_per_m"], rel=1e-5)
    assert "k2_n_per_m" in r["model_toml"]


def test_a_rational_fit_names_the_mode_the_model_lacks() -> None:
    """fit_frd on the exact response of a stage with an extra mode at 3 kHz, complex noise of a
    known 1σ radius added: the fit is as close as the noise allows, its poles are stable, and the
    mode the model (the same stage without it) lacks is named within 2 % and written into the
    plant file."""
    stage = {"k2_n_per_m": 21965.0 * 1.1}
    mode = {"at": "sensor", "hz": 3000.0, "zeta": 0.01, "zero_hz": 3000.0, "zero_zeta": 0.03}
    f = np.logspace(np.log10(20.0), 4.0, 120)
    g = fs.loop_response(f, plant={"stage": stage, "modes": [mode]})["plant_m_per_v"]
    sigma = 1e-3 * np.abs(g)
    rng = np.random.default_rng(7)
    noise = rng.standard_normal(len(f)) + 1j * rng.standard_normal(len(f))
    r = fs.fit_frd(f, g + sigma * noise / np.sqrt(2), sigma, plant={"stage": stage})
    assert r["weighted_rms"] < 1.2
    poles = np.array(r["fit"]["poles_z"])
    assert (np.hypot(poles[:, 0], poles[:, 1]) < 1.0).all()
    [extra] = r["extra_modes"]
    assert extra["hz"] == pytest.approx(3000.0, rel=0.02)
    assert "[[plant.modes]]" in r["model_toml"]


def test_a_python_loop_of_servo_and_plant_is_servo_runs_loop(tmp_path: Path) -> None:
    """Servo and Plant tick by tick close the loop `servo run --digest` closes: the same
    samples and commands, bit for bit (the FNV-1a digest, written again here)."""

    run = tmp_path / "run.toml"
    run.write_text("[run]\nduration_s = 0.02\n")
    deployment = tmp_path / "deploy.toml"
    servo("deploy", "-c", str(run), "-o", str(deployment))
    want = json.loads(servo("run", "-q", "--no-record", "--json", "--digest", "-c", str(run)).stdout)
    loop = fs.Servo(str(deployment))
    plant = fs.Plant(run)
    h = 0xCBF29CE484222325
    seq, _, gap, accel, _, flags = plant.initial()
    for _ in range(plant.ticks):
        dac, _ = loop.tick(seq, gap, accel, flags=flags)
        for word in struct.pack("<Qddd", seq, gap, accel, dac):
            h = ((h ^ word) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
        seq, _, gap, accel, _, flags = plant.step(dac)
    assert f"{h:016x}" == want["meta"]["loop_digest"]
    assert loop.status()["ticks"] == plant.ticks and loop.status()["trip"] is None
    t = loop.telemetry()
    assert t["following_error_m"] == pytest.approx(t["reference_m"] - t["measured_m"], abs=1e-15)
    with pytest.raises(fs.ServoError, match="allowed"):
        loop.set_gain(100.0)
