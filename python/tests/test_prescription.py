"""Prescription sag and slopes against an independent optics package (prysm, PyPI): Zernike
terms in Noll (Standard) and Fringe order with prysm's own index conversions and polynomials,
the conic with its slope, and an off-axis conic segment. Files in mm (Zemax), answers in m."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from prysm.experimental.raytracing.surfaces import conic_sag, conic_sag_der, off_axis_conic_sag
from prysm.polynomials import fringe_to_nm, noll_to_nm, zernike_nm, zernike_nm_der

import fts_servo as fs

RNG = np.random.default_rng(40)


def points(radius_m: float, count: int = 50) -> tuple[np.ndarray, np.ndarray]:
    r = radius_m * np.sqrt(RNG.uniform(0.0, 1.0, count))
    t = RNG.uniform(0.0, 2 * np.pi, count)
    return r * np.cos(t), r * np.sin(t)


def write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "rx.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    "order, to_nm, terms, norm",
    [("standard", noll_to_nm, 37, True), ("fringe", fringe_to_nm, 36, False)],
)
def test_zernike_terms_are_prysms(tmp_path: Path, order: str, to_nm, terms: int, norm: bool) -> None:
    # prysm's Fringe index goes on past 36 (its 37 is (6, 6)); the 37-term Fringe set of
    # Zemax and CODE V ends with the 12th-order spherical, checked in the Rust tests.
    norm_mm = 8.0
    coefficients_mm = RNG.uniform(-1e-3, 1e-3, terms)
    path = write(
        tmp_path,
        f'aperture_radius_mm = 8.0\n[zernike]\norder = "{order}"\nnorm_radius_mm = {norm_mm}\n'
        f"coefficients_mm = [{', '.join(repr(float(c)) for c in coefficients_mm)}]\n",
    )
    x, y = points(8e-3)
    z, dzdx, dzdy = fs.prescription_sag(path, x, y)
    rho, theta = np.hypot(x, y) / (norm_mm * 1e-3), np.arctan2(y, x)
    want = np.zeros_like(x)
    d_rho, d_theta = np.zeros_like(x), np.zeros_like(x)
    for j, c in enumerate(coefficients_mm, start=1):
        n, m = to_nm(j)
        want += c * 1e-3 * zernike_nm(n, m, rho, theta, norm=norm)
        dr, dt = zernike_nm_der(n, m, rho, theta, norm=norm)
        d_rho += c * 1e-3 * dr
        d_theta += c * 1e-3 * dt
    scale = np.abs(want).max()
    assert np.abs(z - want).max() < 1e-12 * scale * terms
    # Slopes by the chain rule from prysm's ∂/∂ρ and ∂/∂θ.
    big_r = norm_mm * 1e-3
    r = np.hypot(x, y)
    want_x = d_rho * np.cos(theta) / big_r - d_theta * np.sin(theta) / r
    want_y = d_rho * np.sin(theta) / big_r + d_theta * np.cos(theta) / r
    slope_scale = np.abs(want_x).max()
    assert np.abs(dzdx - want_x).max() < 1e-9 * slope_scale
    assert np.abs(dzdy - want_y).max() < 1e-9 * slope_scale


def test_the_conic_and_its_slope_are_prysms(tmp_path: Path) -> None:
    path = write(tmp_path, "aperture_radius_mm = 12.0\n[base]\nradius_mm = -85.0\nconic = -0.7\n")
    x, y = points(12e-3)
    z, dzdx, _ = fs.prescription_sag(path, x, y)
    c, r = 1 / -85e-3, np.hypot(x, y)
    want = conic_sag(c, -0.7, r * r)
    assert np.abs(z - want).max() < 1e-12 * np.abs(want).max()
    slope = conic_sag_der(c, -0.7, r)
    assert np.abs(dzdx - slope * x / r).max() < 1e-12 * np.abs(slope).max()


def test_an_off_axis_segment_is_prysms(tmp_path: Path) -> None:
    # A paraboloid segment 40 mm off axis: prysm's sag of the segment, less its centre's.
    path = write(
        tmp_path,
        "aperture_radius_mm = 10.0\ndecenter_mm = [40.0, 0.0]\n[base]\nradius_mm = 600.0\nconic = -1.0\n",
    )
    x, y = points(10e-3)
    z, _, _ = fs.prescription_sag(path, x, y)
    r, t = np.hypot(x, y), np.arctan2(y, x)
    want = off_axis_conic_sag(1 / 600e-3, -1.0, r, t, 40e-3)
    centre = off_axis_conic_sag(1 / 600e-3, -1.0, np.zeros(1), np.zeros(1), 40e-3)
    want = want - centre
    assert np.abs(z - want).max() < 1e-12 * np.abs(want).max()
