"""Our map readers against prysm's on the same files (prysm 0.21.1, io.read_zygo_dat and
io.read_zygo_datx): heights to rounding, the lateral scale, the missing pixels; the files are
prysm's own MetroPro sample and the synthetic map scripts/make_metrology_testdata.py writes."""

from pathlib import Path

import numpy as np
import pytest

import fts_servo

prysm_io = pytest.importorskip("prysm.io")
pytest.importorskip("h5py")

DATA = Path(__file__).resolve().parents[2] / "crates" / "metrology" / "testdata"


def _same(ours, theirs_nm, rtol=0.0, atol_nm=1e-9):
    heights = ours["heights_m"] * 1e9
    assert heights.shape == theirs_nm.shape
    assert np.array_equal(np.isnan(heights), np.isnan(theirs_nm))
    valid = ~np.isnan(heights)
    np.testing.assert_allclose(heights[valid], theirs_nm[valid], rtol=rtol, atol=atol_nm)


def test_metropro_dat_reads_as_prysm_reads_it():
    for name in ["prysm_sample.dat", "synthetic.dat"]:
        ours = fts_servo.read_map(DATA / name)
        theirs = prysm_io.read_zygo_dat(DATA / name)
        # prysm computes in float32 where the file's factors are: agree to its rounding.
        _same(ours, np.asarray(theirs["phase"], dtype=float), rtol=1e-6, atol_nm=1e-6)
        assert ours["pitch_m"][0] == pytest.approx(theirs["meta"]["lateral_resolution"], rel=1e-7)


def test_datx_reads_as_prysm_reads_it():
    ours = fts_servo.read_map(DATA / "synthetic.datx")
    theirs = prysm_io.read_zygo_datx(DATA / "synthetic.datx")
    _same(ours, np.asarray(theirs["phase"], dtype=float))
    assert ours["pitch_m"][0] == pytest.approx(theirs["meta"]["Lateral Resolution"], rel=1e-12)


def test_every_format_reads_the_same_map():
    reference = fts_servo.read_map(DATA / "synthetic.datx")["heights_m"] * 1e9
    for name, options in [
        ("synthetic.npy", {"height_unit": "m", "pitch_m": 70e-6}),
        ("synthetic.csv", {}),
        ("synthetic.xyz", {}),
    ]:
        _same(fts_servo.read_map(DATA / name, **options), reference, atol_nm=1e-4)
    # The .npy written by NumPy itself is NumPy's array.
    npy = np.load(DATA / "synthetic.npy")
    _same(fts_servo.read_map(DATA / "synthetic.npy", "m", 70e-6), npy * 1e9, atol_nm=0.0)


def test_a_file_without_units_is_refused_naming_the_key():
    with pytest.raises(fts_servo.ServoError, match="map.height_unit"):
        fts_servo.read_map(DATA / "synthetic.npy")
