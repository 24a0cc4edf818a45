#!/usr/bin/env python3
"""`servo fit` beside scikit-rf's vector fitting on the same measured FRF.

Exits 1 when scikit-rf's residual is the smaller. Reads the `fit.csv` that `servo fit` writes (each bin: the measurement, its 1σ radius and
our fit), fits the same data with `skrf.VectorFitting` (continuous-time, s-domain; the best
of several pole counts and start spacings up to `--max-poles`), and prints the weighted
residual `√(mean |e/σ|²)` of both (1 is the measurement's noise) and the share of bins within
their 95 % disk.

    pip install scikit-rf
    servo fit frf/frf.csv --plant model.toml
    python3 scripts/vector_fit_vs_skrf.py fit/fit.csv
"""

from __future__ import annotations

import argparse
import csv
import itertools
import math
import sys
import warnings

import numpy as np
import skrf

DISK_95 = math.sqrt(math.log(20.0))


def read(path: str):
    rows = [r for r in csv.DictReader(line for line in open(path) if not line.startswith("#"))]
    f = np.array([float(r["freq_hz"]) for r in rows])
    h = np.array([float(r["magnitude_m_per_v"]) * np.exp(1j * math.radians(float(r["phase_deg"]))) for r in rows])
    sigma = np.array([float(r["uncertainty_m_per_v"]) for r in rows])
    ours = np.array([float(r["fit_magnitude_m_per_v"]) * np.exp(1j * math.radians(float(r["fit_phase_deg"]))) for r in rows])
    return f, h, sigma, ours


def judge(fit, h, sigma):
    e = np.abs(fit - h) / sigma
    return math.sqrt(np.mean(e**2)), float(np.mean(e <= DISK_95))


def skrf_fit(f, h, real, cmplx, spacing, enforce_dc):
    # scikit-rf fits S-parameters (dimensionless, order 1): scale the plant to unit size.
    scale = np.max(np.abs(h))
    net = skrf.Network(frequency=skrf.Frequency.from_f(f, unit="hz"), s=(h / scale).reshape(-1, 1, 1))
    vf = skrf.vectorFitting.VectorFitting(net)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        vf.vector_fit(n_poles_real=real, n_poles_cmplx=cmplx, init_pole_spacing=spacing, fit_constant=True, fit_proportional=False, enforce_dc=enforce_dc)
    return scale * vf.get_model_response(0, 0, f), real + 2 * cmplx


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("fit_csv")
    ap.add_argument("--max-poles", type=int, default=30)
    args = ap.parse_args()
    f, h, sigma, ours = read(args.fit_csv)
    ours_rms, ours_within = judge(ours, h, sigma)
    best = None
    for cmplx in range(1, args.max_poles // 2 + 1):
        for real in (0, 1, 2):
            if real + 2 * cmplx > args.max_poles:
                continue
            for spacing, enforce_dc in itertools.product(("lin", "log"), (True, False)):
                try:
                    model, order = skrf_fit(f, h, real, cmplx, spacing, enforce_dc)
                except Exception:  # noqa: BLE001 - a pole count skrf cannot fit is skipped
                    continue
                rms, within = judge(model, h, sigma)
                if best is None or rms < best[0]:
                    best = (rms, within, order, spacing)
    print(f"{len(f)} bins, {f[0]:.0f}–{f[-1]:.0f} Hz")
    print(f"servo fit (z-domain, weighted by σ):      weighted RMS {ours_rms:.3f}, {100 * ours_within:.1f} % within the 95 % disk")
    if best is None:
        sys.exit("scikit-rf fitted no pole count")
    rms, within, order, spacing = best
    print(f"scikit-rf {skrf.__version__} VectorFitting (s-domain), best of ≤ {args.max_poles} poles: "
          f"weighted RMS {rms:.3f}, {100 * within:.1f} % within the 95 % disk ({order} poles, {spacing} start)")
    if rms < ours_rms:
        sys.exit("scikit-rf's fit is closer to the measurement than servo fit's")


if __name__ == "__main__":
    main()
