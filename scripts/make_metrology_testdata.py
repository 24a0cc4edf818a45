#!/usr/bin/env python3
"""Writes the synthetic measured map of crates/metrology/testdata in every format the
metrology crate reads (.datx, .dat, .xyz, .npy, .csv), independently of fts-servo's code:
the design (a sphere with Standard Zernike astigmatism and trefoil) is evaluated here in NumPy,
placed on the instrument with a known pose, with noise and missing pixels.

The pose (the registration test's truth, crates/metrology/tests/registration.rs):
piston 120 nm, tilt (30, -20) µrad, decentre (0.21, -0.13) mm, rotation 7°; each pixel the
mean of the surface over its area (3 x 3 points).
Needs numpy and h5py. Run from the project root: python3 scripts/make_metrology_testdata.py
"""
import struct
from pathlib import Path

import h5py
import numpy as np

OUT = Path("crates/metrology/testdata")
ROWS = COLS = 160
PITCH_M = 70e-6
APERTURE_M = 5e-3
CURVATURE = 1 / 0.2  # 1/m
Z6_M = 2e-6  # Standard (Noll) 6: sqrt(6) rho^2 cos 2theta
Z10_M = 1e-6  # Standard (Noll) 10: sqrt(8) rho^3 cos 3theta
PISTON_M, TILT, DECENTRE_M, ROT = 120e-9, (30e-6, -20e-6), (0.21e-3, -0.13e-3), np.deg2rad(7.0)
NOISE_M = 0.5e-9
WAVELENGTH_M = 632.8e-9


def design_height(x, y):
    """Height toward the instrument, m: minus the sag."""
    r2 = x * x + y * y
    sphere = CURVATURE * r2 / (1 + np.sqrt(1 - CURVATURE**2 * r2))
    rho, th = np.sqrt(r2) / APERTURE_M, np.arctan2(y, x)
    zern = Z6_M * np.sqrt(6) * rho**2 * np.cos(2 * th) + Z10_M * np.sqrt(8) * rho**3 * np.cos(3 * th)
    return -(sphere + zern)


def measured():
    rng = np.random.default_rng(57)
    col, row = np.meshgrid(np.arange(COLS), np.arange(ROWS))
    u = (col - (COLS - 1) / 2) * PITCH_M
    v = ((ROWS - 1) / 2 - row) * PITCH_M
    c, s = np.cos(ROT), np.sin(ROT)

    def part(u, v):
        wx, wy = u - DECENTRE_M[0], v - DECENTRE_M[1]
        return c * wx + s * wy, -s * wx + c * wy

    # A pixel reads the mean height over its area (3 x 3 points), as an instrument integrates.
    offsets = [(i + 0.5) / 3 - 0.5 for i in range(3)]
    h = sum(design_height(*part(u + du * PITCH_M, v + dv * PITCH_M))
            for du in offsets for dv in offsets) / 9
    qx, qy = part(u, v)
    h += PISTON_M + TILT[0] * u + TILT[1] * v
    h += NOISE_M * rng.standard_normal(h.shape)
    missing = (np.hypot(qx, qy) > APERTURE_M) | (rng.random(h.shape) < 0.03)
    missing |= (np.abs(qx - 1.5e-3) < 0.4e-3) & (np.abs(qy + 2e-3) < 0.6e-3)  # a dust patch
    h[missing] = np.nan
    return h


def write_npy(h):
    np.save(OUT / "synthetic.npy", h)


def write_csv(h):
    with open(OUT / "synthetic.csv", "w") as f:
        f.write(f"# heights in nm, row 0 at +y, column 0 at -x, pitch {PITCH_M * 1e3} mm\n")
        for r in h * 1e9:
            f.write(",".join("" if np.isnan(v) else f"{v:.4f}" for v in r) + "\n")


def ascii_header(first):
    return [
        first,
        '0 0 0 0 "Mon Nov 30 19:00:00 2026      "',
        "0 0 0 0 0 0",
        f"0 0 {COLS} {ROWS}",
        '"' + " " * 81 + '"',
        '"' + " " * 39 + '"',
        '"' + " " * 39 + '"',
        f"0 0.5 {WAVELENGTH_M} 0 1 0 {PITCH_M} 1796065200",
        f"{COLS} {ROWS} 0 0 0 0 " + '"' + " " * 9 + '"',
        "0 0 0 0 0 0 0 0 0 0",
        "1 1 20 2 0 0 0 0 0",
        '0 "' + " " * 12 + '"',
        "1 0",
        '"' + " " * 7 + '"',
    ]


def write_xyz(h):
    lines = ascii_header("Zygo XYZ Data File - Format 1") + ["#"]
    for r in range(ROWS):
        for c in range(COLS):
            v = h[r, c]
            lines.append(f"{c} {r} No Data" if np.isnan(v) else f"{c} {r} {v * 1e6:.7f}")
    lines.append("#")
    (OUT / "synthetic.xyz").write_text("\n".join(lines) + "\n")


def write_dat(h):
    header = bytearray(834)
    struct.pack_into(">I", header, 0, 0x881B036F)
    struct.pack_into(">H", header, 4, 1)
    struct.pack_into(">I", header, 6, 834)
    struct.pack_into(">HH", header, 68, COLS, ROWS)
    struct.pack_into(">I", header, 72, ROWS * COLS * 4)
    struct.pack_into(">ffff", header, 164, 0.5, WAVELENGTH_M, 0.0, 1.0)
    struct.pack_into(">f", header, 184, PITCH_M)
    struct.pack_into(">H", header, 218, 1)
    per_count = WAVELENGTH_M * 0.5 * 1.0 / 32768
    raw = np.where(np.isnan(h), 2147483640, np.round(np.nan_to_num(h) / per_count)).astype(">i4")
    (OUT / "synthetic.dat").write_bytes(bytes(header) + raw.tobytes())


def write_datx(h):
    with h5py.File(OUT / "synthetic.datx", "w") as f:
        no_data = np.finfo(np.float64).max
        d = f.create_dataset("Data/Surface/{00000000-0000-0000-0000-000000000000}",
                             data=np.where(np.isnan(h), no_data, h * 1e9))
        d.attrs["Unit"] = np.array([b"NanoMeters"])
        d.attrs["No Data"] = np.array([no_data])
        d.attrs["Wavelength"] = np.array([WAVELENGTH_M])
        d.attrs["Interferometric Scale Factor"] = np.array([0.5])
        d.attrs["Obliquity Factor"] = np.array([1.0])
        g = f.create_group("Attributes/{00000000-0000-0000-0000-000000000001}")
        g.attrs["Data Context.Lateral Resolution:Value"] = np.array([PITCH_M])
        g.attrs["Data Context.Lateral Resolution:Unit"] = np.array([b"m"])


if __name__ == "__main__":
    h = measured()
    for write in (write_npy, write_csv, write_xyz, write_dat, write_datx):
        write(h)
    print(f"{np.isfinite(h).sum()} valid pixels of {h.size}")
