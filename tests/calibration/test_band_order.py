"""A specimen's band given upper envelope first is read as the band, and said; envelopes that cross only
on a few rows (two tests' curves, noise) say nothing.

The envelopes are written here by hand as a lab exports them: total force F(s) = 40 s + 300 s^3 N, times
0.95 (lower) and 1.05 (upper), every 0.01 of strain to 0.4; the fit's rows every 0.02 fall on readings.
"""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.calibration.specimen import specimen_from_files

KNIT = {"L": 14.1, "W0": 4.4, "C0": 2.7}


def _curve(s):
    return 40.0 * s + 300.0 * s ** 3


def _envelope(path, factor, wiggle=None):
    rows = []
    for k in range(41):
        s = 0.01 * k
        rows.append(f"{s:.4f},{factor * _curve(s) + (wiggle(k) if wiggle else 0.0):.6f}")
    path.write_text("strain,load_N\n" + "\n".join(rows) + "\n")
    return path


def _specimen(band):
    return specimen_from_files("s", width_mm=50.0, gauge_length_mm=100.0, knit=KNIT, band=band, row_step=0.02)


def test_a_band_given_upper_first_is_the_same_band_and_is_said(tmp_path):
    lo, hi = _envelope(tmp_path / "low.csv", 0.95), _envelope(tmp_path / "high.csv", 1.05)
    ordered, swapped = _specimen((lo, hi)), _specimen((hi, lo))
    strain = 0.02 * np.arange(1, 21)
    # the band is each row's lower and upper file, whatever the order (by hand: 0.95 and 1.05 x F)
    for sp in (ordered, swapped):
        assert sp.band_low_N == pytest.approx(0.95 * _curve(strain), abs=1e-5)
        assert sp.band_high_N == pytest.approx(1.05 * _curve(strain), abs=1e-5)
    assert ordered.read_notes == ()
    (src, note), = swapped.read_notes
    # both files named, the rows (every one of the 20, grip strain 0.02 to 0.4) and what was done
    assert src == str(hi) and f"band[1] ({lo})" in note
    assert "on 20 of 20 rows (grip strain 0.02 .. 0.4" in note and "read as the upper envelope" in note


def test_envelopes_that_cross_on_a_few_rows_say_nothing(tmp_path):
    # the lower file above the upper one on 4 of the 20 rows (strains 0.10 .. 0.16: two tests crossing, or
    # noise), below it on the others
    bump = lambda k: 0.15 * _curve(0.01 * k) if 10 <= k <= 16 else 0.0           # noqa: E731
    lo, hi = _envelope(tmp_path / "low.csv", 0.95, bump), _envelope(tmp_path / "high.csv", 1.05)
    sp = _specimen((lo, hi))
    strain = 0.02 * np.arange(1, 21)
    crossed = (strain > 0.09) & (strain < 0.17)
    assert np.count_nonzero(crossed) == 4
    assert sp.band_high_N[crossed] == pytest.approx(1.10 * _curve(strain[crossed]), abs=1e-5)
    assert sp.read_notes == ()


def test_a_pair_above_on_most_rows_is_said_with_its_runs(tmp_path):
    # the upper file given first, but crossing the other on rows 0.10 .. 0.16 (the 4 rows above): above on
    # the other 16 of 20
    dip = lambda k: -0.15 * _curve(0.01 * k) if 10 <= k <= 16 else 0.0           # noqa: E731
    hi, lo = _envelope(tmp_path / "high.csv", 1.05, dip), _envelope(tmp_path / "low.csv", 0.95)
    (src, note), = _specimen((hi, lo)).read_notes
    assert "on 16 of 20 rows (grip strain 0.02 .. 0.08, 0.18 .. 0.4;" in note
