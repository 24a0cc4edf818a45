"""fts-servo from Python: the simulated fast tool servo, its models and its recordings.

Every function takes a configuration the way ``servo`` does: ``None`` (the thesis prototype's
defaults), a path to a TOML file, or a dict of the same tables; keyword tables merge on top,
key by key (``run("my.toml", run={"duration_s": 0.2})``). Units are SI and every key and
column name says which (``duration_s``, ``following_error_m``, ``control_v``).

Errors raise :class:`ServoError` with the message the ``servo`` CLI prints: the file, the key
and the allowed range.

Tick by tick: :class:`Servo` is the controller a daemon embeds (from the deployment ``servo
deploy`` writes; ``tick(seq, gap_v, accel_v)`` gives the command and its flags, ``telemetry()``,
``status()``, ``set_gain``, ``reset``, ``load``), :class:`Plant` the simulated stage of a
configuration (``initial()``, ``step(dac_v)``). For trying a controller idea in a notebook: each
tick crosses into Python (microseconds), far from real time.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from typing import Any, Dict, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _native
from ._native import Plant, Servo, ServoError
from .study import run_study_ray, study_info, study_rows

__all__ = [
    "read_map",
    "ServoError",
    "Servo",
    "Plant",
    "Run",
    "Recording",
    "Model",
    "run",
    "run_hil",
    "qualify_host",
    "control",
    "replay",
    "read_recording",
    "models",
    "budget",
    "loop_response",
    "prescription_sag",
    "resolved_config",
    "tune",
    "synth_h2",
    "identify",
    "fit_frd",
    "study_info",
    "study_rows",
    "run_study_ray",
]

Config = Union[None, str, "os.PathLike[str]", Mapping[str, Any]]


def _args(config: Config, tables: Mapping[str, Any]) -> Tuple[Any, Optional[Dict[str, Any]]]:
    if config is not None and not isinstance(config, Mapping):
        config = os.fspath(config)
    elif isinstance(config, Mapping):
        config = dict(config)
    return config, (dict(tables) if tables else None)


@dataclass(frozen=True)
class Run:
    """A closed-loop run: the summary ``servo run --json`` prints and every tick's signals.

    ``telemetry`` holds what the controller saw and did (``reference_m``, ``measured_m``,
    ``following_error_m``, ``control_v``, ``accel_m_s2``, ``flags``), ``truth`` what the
    simulator knows (``tool_m``, ``true_error_m``, ``gap_m``, ``motor_force_n``, …): float32
    arrays, as recorded; ``time_s`` is float64, one entry per servo tick.
    """

    summary: Dict[str, Any]
    time_s: np.ndarray
    telemetry: Dict[str, np.ndarray]
    truth: Dict[str, np.ndarray]
    config_toml: str
    controller: str


@dataclass(frozen=True)
class Recording(Run):
    """A recording read back (:func:`read_recording`): a :class:`Run` plus how it ended."""

    end: Dict[str, str]
    finished: bool
    read: str


class Model(tuple):
    """``(A, B, C, D, dt)`` — ``control.ss(*model)`` takes it — with the signal names.

    ``dt`` is the sampling period in s, or 0 for continuous time. ``inputs`` and ``outputs``
    name the columns of ``B``/``D`` and the rows of ``C``/``D`` with their units.
    """

    inputs: Tuple[str, ...]
    outputs: Tuple[str, ...]
    what: str

    def __new__(cls, abcd_dt: Sequence[Any], inputs: Sequence[str], outputs: Sequence[str], what: str) -> "Model":
        m = super().__new__(cls, tuple(abcd_dt))
        m.inputs, m.outputs, m.what = tuple(inputs), tuple(outputs), what
        return m

    @property
    def A(self) -> np.ndarray:  # noqa: N802 (the control-engineering name)
        """State matrix."""
        return self[0]

    @property
    def B(self) -> np.ndarray:  # noqa: N802
        """Input matrix."""
        return self[1]

    @property
    def C(self) -> np.ndarray:  # noqa: N802
        """Output matrix."""
        return self[2]

    @property
    def D(self) -> np.ndarray:  # noqa: N802
        """Feed-through matrix."""
        return self[3]

    @property
    def dt(self) -> float:
        """Sampling period in s (0: continuous time)."""
        return self[4]

    def ss(self, name: Optional[str] = None) -> Any:
        """The model as a named ``control.StateSpace`` (python-control): its inputs and outputs
        carry the signal names, so ``control.interconnect`` joins models by name."""
        import control

        return control.ss(
            self.A, self.B, self.C, self.D, self.dt,
            inputs=list(self.inputs), outputs=list(self.outputs), name=name,
        )

    def __repr__(self) -> str:
        kind = f"dt = {self.dt:.6g} s" if self.dt else "continuous"
        return (
            f"Model({self.what}; {self.A.shape[0]} states, {kind}; "
            f"inputs {list(self.inputs)}; outputs {list(self.outputs)})"
        )


def _run_of(d: Dict[str, Any]) -> Dict[str, Any]:
    return dict(
        summary=json.loads(d["summary_json"]),
        time_s=d["time_s"],
        telemetry=d["telemetry"],
        truth=d["truth"],
        config_toml=d.get("config_toml", ""),
        controller=d.get("controller", ""),
    )


def run(config: Config = None, **tables: Any) -> Run:
    """Runs the closed loop of ``config`` (with ``tables`` merged on top) to its end.

    The same loop, seed and numbers as ``servo run`` with that configuration; nothing is
    recorded (``servo run --out`` records). Example: ``run(run={"duration_s": 0.2})``.
    """
    return Run(**_run_of(_native.run(*_args(config, tables))))


def _servo_binary(servo: Union[None, str, "os.PathLike[str]"]) -> str:
    """The ``servo`` executable: ``servo``, else ``$FTS_SERVO_BIN``, else ``servo`` on PATH."""
    import shutil

    found = servo or os.environ.get("FTS_SERVO_BIN") or shutil.which("servo")
    if not found:
        raise ServoError("the servo binary: pass servo=..., set FTS_SERVO_BIN or put servo on PATH")
    return os.fspath(found)


def run_hil(
    config: Config = None,
    out: Union[None, str, "os.PathLike[str]"] = None,
    overwrite: bool = False,
    prefix: Optional[str] = None,
    realtime: bool = False,
    servo: Union[None, str, "os.PathLike[str]"] = None,
    **tables: Any,
) -> Dict[str, Any]:
    """Runs ``config`` as ``servo run --hil`` does: plant, controller and recorder as three
    processes of the ``servo`` binary over shared memory (in lockstep, or paced by the wall
    clock with ``realtime``), recorded to ``out`` (None: not recorded). Returns the recorder's
    summary (``servo run --hil --json``); a lockstep run equals :func:`run` bit for bit. A
    failing process raises :class:`ServoError` naming it and its exit code."""
    config, overrides = _args(config, tables)
    path = None if out is None else os.fspath(out)
    return json.loads(
        _native.run_hil(_servo_binary(servo), config, overrides, path, overwrite, prefix, realtime)
    )


def qualify_host(
    config: Config = None, rate_hz: Optional[float] = None, duration_s: float = 5.0, **tables: Any
) -> Dict[str, Any]:
    """Qualifies this host for real time as ``servo latency --json`` does: the loop's pacing
    alone at ``rate_hz`` (default: the configuration's loop rate) for ``duration_s`` with the
    configuration's ``[realtime]`` settings, its start lateness in ns, the overruns, the stall
    the configuration's loop survives and whether this host ``holds``. The dict, saved as JSON,
    is what ``servo run --hil --realtime --qualification`` reads."""
    config, overrides = _args(config, tables)
    return json.loads(_native.qualify_host(config, overrides, rate_hz, duration_s))


def control(
    prefix: str,
    request: str,
    value: Optional[float] = None,
    file: Union[None, str, "os.PathLike[str]"] = None,
    timeout_s: float = 5.0,
) -> str:
    """Steers the HIL run on ``prefix`` as ``servo ctl`` does: ``"start"``, ``"stop"``,
    ``"gain"`` with ``value`` (a scale the controller applies only when the loop keeps its
    6 dB gain margin) or ``"load"`` with ``file`` (a controller file, checked against the
    running loop). Returns what the run did; a refusal, no run on the prefix or no answer
    within ``timeout_s`` raises :class:`ServoError` saying which."""
    path = None if file is None else os.fspath(file)
    return _native.control(prefix, request, value, path, timeout_s)


def replay(
    file: Union[str, "os.PathLike[str]"],
    out: Union[None, str, "os.PathLike[str]"] = None,
    overwrite: bool = False,
    plant: Union[None, str, "os.PathLike[str]"] = None,
    salvage: bool = False,
) -> Dict[str, Any]:
    """Runs a recording again from what it holds, as ``servo replay --json`` does: its
    configuration, seed and embedded input files — on the plant file ``plant`` when given (a
    recording of a DAQ daemon or a real stage replays only on a plant model) — recorded to
    ``out`` (None: not recorded). Returns ``identical`` (the data channels bit for bit, None when
    the recording holds every n-th tick), ``first_difference_frame``, ``frames_compared``, the
    ``recorded`` and ``replayed`` summaries, and ``design``: the recorded deployment (which the
    replay runs) beside this machine's design of it — ``"same"``, ``{"apart": relative
    difference}`` (another processor's rounding), ``"other_form"``, ``"not_recorded"`` (an older
    recording, designed again) or None (a changed configuration)."""
    path = None if out is None else os.fspath(out)
    plant_path = None if plant is None else os.fspath(plant)
    return json.loads(_native.replay(os.fspath(file), path, overwrite, plant_path, salvage))


def read_recording(path: Union[str, "os.PathLike[str]"], salvage: bool = False) -> Recording:
    """Reads an MCAP recording of ``servo run`` / ``servo record`` into NumPy arrays.

    The summary is recomputed from the frames (as ``servo inspect`` does) and every byte of the
    file is checked: a damaged or unfinished file raises :class:`ServoError` naming the damage.
    With ``salvage=True`` it is read as far as it is intact (a killed run up to its last
    complete record); ``finished`` and ``read`` then say what was skipped.
    """
    d = _native.read_recording(os.fspath(path), salvage)
    return Recording(**_run_of(d), end=dict(d["end"]), finished=d["finished"], read=d["read"])


def models(config: Config = None, **tables: Any) -> Dict[str, Model]:
    """The models of ``config``: ``mechanics`` and ``plant`` (continuous time), and at the servo
    period ``plant_sampled`` (exact: hold, delay, averaging; no controller; the DAC
    ``command_v`` in, the readings ``gap_v`` and ``accel_v`` out), ``controller`` (``gap_v``,
    ``accel_v`` in, ``command_v`` out), ``loop_gain`` (L broken at the DAC command, for
    ``control.margin``), ``sensitivity`` and ``complementary_sensitivity`` (reference to
    following error and to measured position) and ``closed_loop``. Each is a :class:`Model`:
    ``control.ss(*m)``, or named for ``control.interconnect`` with ``m.ss("plant")``."""
    return {k: Model(**v) for k, v in _native.models(*_args(config, tables)).items()}


def budget(config: Config = None, points: int = 400, **tables: Any) -> Dict[str, Any]:
    """The error budget of ``config`` (``servo budget --json``'s ``budget``: RMS following and
    true error per noise source, in m, with their PSDs), the loop's stability ``margins``
    (degrees, dB, Hz) and its −3 dB ``bandwidth_hz``."""
    config, overrides = _args(config, tables)
    return json.loads(_native.budget(config, overrides, points))


def loop_response(freq_hz: Sequence[float], config: Config = None, **tables: Any) -> Dict[str, np.ndarray]:
    """Complex frequency responses of the sampled loop at ``freq_hz`` (Hz): ``plant_m_per_v``
    (measured position per DAC volt, no controller), ``closed_loop`` (measured / reference) and
    ``sensitivity`` (following error / reference)."""
    config, overrides = _args(config, tables)
    return _native.loop_response([float(f) for f in freq_hz], config, overrides)


def resolved_config(config: Config = None, **tables: Any) -> str:
    """The configuration with every default filled in, as TOML (what a recording embeds)."""
    return _native.resolved_config(*_args(config, tables))


def tune(
    config: Config = None, bandwidth_hz: float = 1000.0, ms: float = 1.5, mt: float = 1.3, **tables: Any
) -> Dict[str, Any]:
    """``servo tune``: the PID with the largest integral gain under ``|S| <= ms``, ``|T| <= mt``
    and a -3 dB bandwidth of at least ``bandwidth_hz`` (Hz), on the exact sampled plant.

    Returns the report (``reference`` and ``tuned`` gains with their margins, bandwidths and
    predicted RMS errors in m) and ``controller_toml``: the fragment ``servo run -c`` takes,
    stamped with the plant it was made for.
    """
    config, overrides = _args(config, tables)
    report, toml_text = _native.tune(bandwidth_hz, ms, mt, config, overrides)
    return {**json.loads(report), "controller_toml": toml_text}


def synth_h2(
    config: Config = None,
    effort_weight: Optional[float] = None,
    thesis_weights: bool = False,
    sensor_noise_scale: float = 1.0,
    order: Optional[int] = None,
    **tables: Any,
) -> Dict[str, Any]:
    """``servo synth h2``: the discrete H2-optimal controller of the exact sampled plant.

    ``effort_weight`` weighs the command against the error (default 1 nm/V, or 1000 with the
    §6.3 ``thesis_weights``); ``sensor_noise_scale`` scales the sensor noise the design assumes;
    ``order`` reduces the controller by balanced truncation. Returns ``controller`` (a
    :class:`Model`: position error in V to command in V), ``controller_toml`` (the file
    ``servo run --controller ss`` loads, stamped with its plant and rate and its loop's checked
    gain range), ``h2_norm``, ``spectral_radius`` and ``prediction`` — what ``servo synth h2
    --json`` prints (states, bandwidth, predicted RMS errors in m, the stability range and the
    margins), computed by the same function.
    """
    config, overrides = _args(config, tables)
    weight = effort_weight if effort_weight is not None else (1000.0 if thesis_weights else 1.0)
    d = _native.synth_h2(weight, thesis_weights, float(sensor_noise_scale), order, config, overrides)
    return {
        "controller": Model(d["abcd_dt"], d["inputs"], d["outputs"], d["what"]),
        "controller_toml": d["controller_toml"],
        "h2_norm": d["h2_norm"],
        "spectral_radius": d["spectral_radius"],
        "prediction": json.loads(d["prediction"]),
    }


def _frf(
    frf: Union[str, "os.PathLike[str]", Sequence[float]], measured_m_per_v: Optional[np.ndarray]
) -> Tuple[Any, Optional[np.ndarray]]:
    """An FRF as the native module takes it: a ``frf.csv`` path, or the frequencies in Hz as
    floats with the complex response as a contiguous ``complex128`` array."""
    if measured_m_per_v is None:
        return os.fspath(frf), None  # type: ignore[arg-type]
    freq = [float(f) for f in frf]  # type: ignore[union-attr]
    return freq, np.ascontiguousarray(measured_m_per_v, dtype=np.complex128)


def identify(
    frf: Union[str, "os.PathLike[str]", Sequence[float]],
    measured_m_per_v: Optional[np.ndarray] = None,
    config: Config = None,
    **tables: Any,
) -> Dict[str, Any]:
    """``servo identify``: Table 5-2's parameters fitted to a measured FRF.

    ``frf`` is the ``frf.csv`` ``servo frf`` writes, or the frequencies in Hz with
    ``measured_m_per_v`` the complex response (measured position per DAC volt). Returns the
    report (``names``, ``fitted``, ``rel_std``, ``misfits``, …) and ``model_toml``: the plant
    file ``servo … --plant`` takes.
    """
    config, overrides = _args(config, tables)
    frf, measured_m_per_v = _frf(frf, measured_m_per_v)
    report, model = _native.identify(frf, measured_m_per_v, config, overrides)
    return {**json.loads(report), "model_toml": model}


def fit_frd(
    frf: Union[str, "os.PathLike[str]", Sequence[float]],
    measured_m_per_v: Optional[np.ndarray] = None,
    uncertainty_m_per_v: Optional[np.ndarray] = None,
    order: Optional[int] = None,
    max_order: int = 30,
    config: Config = None,
    **tables: Any,
) -> Dict[str, Any]:
    """``servo fit``: a stable rational model of a measured FRF, and the modes the plant lacks.

    ``frf`` is the ``frf.csv`` ``servo frf`` writes, or the frequencies in Hz with
    ``measured_m_per_v`` the complex response (m/V) and ``uncertainty_m_per_v`` each bin's 1σ
    radius (m/V; required: the fit is weighted and its order chosen by it). Returns the report
    (``order``, ``within``, ``weighted_rms``, ``resonances``, ``extra_modes``, and ``fit``: the
    rational model ``H(z) = direct + Σ r/(z − p)`` as ``period_s``, ``direct_m_per_v``,
    ``poles_z``, ``residues_m_per_v``) and ``model_toml``: the configured plant with the extra
    modes, the plant file ``servo … --plant`` takes.
    """
    config, overrides = _args(config, tables)
    frf, measured_m_per_v = _frf(frf, measured_m_per_v)
    if uncertainty_m_per_v is not None:
        uncertainty_m_per_v = np.ascontiguousarray(uncertainty_m_per_v, dtype=np.float64)
    report, model = _native.fit_frd(
        frf, measured_m_per_v, uncertainty_m_per_v, order, max_order, config, overrides
    )
    return {**json.loads(report), "model_toml": model}


def prescription_sag(
    path: Union[str, "os.PathLike[str]"], x_m: Sequence[float], y_m: Sequence[float]
) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A surface prescription's sag and slopes, as ``servo machine`` and ``servo toolpath``
    cut it.

    ``path`` is a prescription file (TOML in Zemax's conventions, lengths in mm: the book's
    "Cutting an optical prescription" page); ``x_m``, ``y_m`` the points in m in the part's
    frame. Returns the sag z in m (along +z from the vertex plane) and its slopes ∂z/∂x, ∂z/∂y.
    """
    x = np.ascontiguousarray(x_m, dtype=np.float64).ravel()
    y = np.ascontiguousarray(y_m, dtype=np.float64).ravel()
    return _native.prescription_sag(os.fspath(path), x, y)


def read_map(
    path: Union[str, "os.PathLike[str]"],
    height_unit: Optional[str] = None,
    pitch_m: Optional[float] = None,
) -> Dict[str, Any]:
    """A measured surface map read as ``servo register`` reads it.

    ``path`` is a Zygo ``.datx``, MetroPro ``.dat``, Zygo ``.xyz``, NumPy ``.npy`` or CSV grid;
    ``height_unit`` (``"m"``, ``"mm"``, ``"um"``, ``"nm"``) and ``pitch_m`` (m) only for a file
    that does not state them. Returns ``heights_m`` (rows × cols, image order: row 0 at +y,
    NaN without data), ``pitch_m`` (x, y) and ``format``.
    """
    heights, pitch, fmt = _native.read_map(os.fspath(path), height_unit, pitch_m)
    return {"heights_m": heights, "pitch_m": pitch, "format": fmt}
