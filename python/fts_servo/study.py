"""Design-space studies (thesis §6.5) from Python, distributed with Ray.

A study is the TOML file ``servo study`` reads: a run configuration (the operating point) plus a
``[study]`` table. Its text is all a worker needs: each Ray task gets the text and a group of
point indices and returns their table rows, computed by the same Rust code as ``servo study``
(so the table is the same, bit for bit, whichever engine computed it). Rows go into the study
folder's journal as tasks finish — the journal ``servo study`` itself resumes — so an
interrupted run, Ray or not, continues where it stopped, and the finished table, Parquet file
and summary are written by the same code as ``servo study merge`` (the plots too come from
``servo study merge OUT_DIR --out-dir OUT_DIR``; the package draws none).

Every node of the cluster needs ``fts_servo`` installed (``pip install ./python``, or a Ray
``runtime_env``).
"""

from __future__ import annotations

import os
from typing import Callable, Dict, List, Optional, Sequence, Union

from . import _native

PathLike = Union[str, "os.PathLike[str]"]


def _text(study: PathLike) -> str:
    """The description: the file's text (a path) or the text itself (a string with a newline)."""
    if isinstance(study, str) and "\n" in study:
        return study
    with open(study, "r", encoding="utf-8") as f:
        return f.read()


def study_info(study: PathLike) -> Dict[str, object]:
    """``{"points": n, "columns": [...]}`` of a study (file or text)."""
    points, header = _native.study_info(_text(study))
    return {"points": points, "columns": header.split(",")}


def study_rows(study: PathLike, indices: Sequence[int]) -> List[str]:
    """The table rows (CSV lines) of points ``indices``, computed in this process."""
    return _native.study_rows(_text(study), [int(i) for i in indices])


def run_study_ray(
    study: PathLike,
    out_dir: PathLike,
    *,
    address: Optional[str] = None,
    points_per_task: int = 8,
    progress: Optional[Callable[[int, int], None]] = None,
) -> List[str]:
    """Runs a study on a Ray cluster and writes its results into ``out_dir``.

    ``address``: the cluster (``"auto"``, ``"ray://head:10001"``, ``"10.0.0.1:6379"``); ``None``
    starts a local one when Ray is not yet initialised. Points are grouped into tasks of
    ``points_per_task`` (larger groups pay Ray's per-task overhead less often; smaller ones
    balance better). Rows are appended to the folder's journal as tasks finish; points already
    there (an interrupted run's) are not computed again. ``progress(done, total)`` is called as
    rows arrive. Returns the paths written (``study.csv``, ``study.parquet``, ``study.json``,
    ``sensitivity.csv``; ``servo study merge out_dir --out-dir out_dir`` adds the plots).
    """
    import ray

    if points_per_task < 1:
        raise ValueError(f"points_per_task = {points_per_task}: allowed 1 or more")
    text = _text(study)
    total, _ = _native.study_info(text)
    journal, pending = _native.study_open(text, os.fspath(out_dir))
    started = False
    if not ray.is_initialized():
        ray.init(address=address, log_to_driver=False)
        started = True
    try:
        # Each task: study_rows on a worker, which builds every model from the description.
        task = ray.remote(study_rows)
        shared = ray.put(text)
        groups = [pending[i : i + points_per_task] for i in range(0, len(pending), points_per_task)]
        waiting = [task.remote(shared, g) for g in groups]
        done = total - len(pending)
        if progress:
            progress(done, total)
        with open(journal, "a", encoding="utf-8") as f:
            while waiting:
                ready, waiting = ray.wait(waiting, num_returns=1)
                for rows in ray.get(ready):
                    f.write("".join(rows))
                    f.flush()
                    done += len(rows)
                    if progress:
                        progress(done, total)
    finally:
        if started:
            ray.shutdown()
    return [os.fspath(p) for p in _native.study_finish([os.fspath(out_dir)], os.fspath(out_dir))]
