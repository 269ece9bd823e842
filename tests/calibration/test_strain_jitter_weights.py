"""Errors in the strain weigh a calibration's rows (effective variance): a row read at a strain off by e carries
the force of strain - e, so its sd is sqrt(sd_F^2 + (dF/dstrain)^2 sd_strain^2).

Hand-made file: a straight 100 N per unit strain (the slope known), strain steps of 0.002 with a +-2e-4
alternating jitter (its sd as the reading estimates it from the column as typed: strain_jitter), the force's
noise stated (noise_N = 0.01 N)."""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.calibration.specimen import specimen_from_files
from knitsim.diagnosis.measured import strain_jitter

KNIT = {"L": 14.1, "W0": 4.4, "C0": 2.7}


def _file(tmp_path, jitter: float):
    k = np.arange(150)
    strain = 0.002 * k + jitter * (-1.0) ** k
    strain[0] = 0.0
    force = 100.0 * 0.002 * k                     # read at the true strain
    path = tmp_path / "a.csv"
    path.write_text("strain,load_N\n" + "".join(f"{float(s)!r},{float(f)!r}\n" for s, f in zip(strain, force)))
    return path, strain


def test_jitter_in_the_strain_adds_slope_times_jitter_to_each_rows_sd(tmp_path):
    path, strain = _file(tmp_path, 2e-4)
    sp = specimen_from_files("a", width_mm=50.0, gauge_length_mm=100.0, knit=KNIT, curve=path, row_step=0.01,
                             noise_N=0.01)
    jit = strain_jitter(strain)
    assert jit > 1e-4                                # the column's own jitter is seen
    inner = slice(2, -2)                             # (the slope of a straight line, away from the ends)
    np.testing.assert_allclose(sp.sigma_N[inner], np.hypot(0.01, 100.0 * jit), rtol=0.05)
    assert "jitter" in sp.sigma_rule


def test_no_jitter_no_change(tmp_path):
    path, _ = _file(tmp_path, 0.0)
    sp = specimen_from_files("a", width_mm=50.0, gauge_length_mm=100.0, knit=KNIT, curve=path, row_step=0.01,
                             noise_N=0.01)
    assert np.all(sp.sigma_N == pytest.approx(0.01)) and "jitter" not in sp.sigma_rule


def test_a_row_between_readings_across_a_knee_weighs_its_interpolation_error(tmp_path):
    """A knee (slope 300 -> 5 N per unit strain at strain 0.0045) read every 0.003: the row at 0.005 lies
    between the readings at 0.003 and 0.006, where the chord misses the curve by 0.1475 N (the exact curve
    minus the chord, computed here); its sd must cover that miss, and a row on a reading gets none."""
    from knitsim.calibration.specimen import _interp, _interpolation_sd, read_table
    knee = 0.0045

    def curve(e):
        return np.where(e <= knee, 300.0 * e, 300.0 * knee + 5.0 * (e - knee))
    s = 0.003 * np.arange(40)
    path = tmp_path / "k.csv"
    path.write_text("strain,load_N\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(s, curve(s))))
    t = read_table(path)
    rows = np.array([0.005, 0.006, 0.03])
    miss = np.abs(_interp(t, rows) - curve(rows))
    sd = _interpolation_sd(t, rows)
    assert miss[0] == pytest.approx(0.1475, rel=1e-9) and sd[0] >= miss[0]   # the knee's row: its miss covered
    assert sd[1] == 0.0 and miss[1] < 1e-12                 # on a reading
    assert sd[2] == 0.0                                     # a straight stretch: no change of slope


def test_a_band_row_between_readings_across_a_knee_weighs_the_envelopes_interpolation_error(tmp_path):
    """A band's mid-line is its envelopes interpolated between their readings, as a curve is: its rows take the
    same chord term (before, only a curve's did: a band's knee row kept the half-width alone).  Envelopes 0.95 and
    1.05 x g(s) = 2 + 100 max(0, s - 0.1) N, read every 0.04; the row at 0.10 lies between the readings at 0.08
    and 0.12, the slope 0 before and 100 x factor after: each envelope's term is 100 x factor x (0.02 x 0.02) /
    0.04 = factor, their mean 1.0 N; with the half-width 0.05 x 3 N: sd = sqrt(0.15^2 + 1) (by hand).  A row on a
    reading (0.12) and one on a straight stretch (0.30) keep the half-width."""
    def g(s):
        return 2.0 + 100.0 * np.maximum(0.0, s - 0.1)
    s = 0.04 * np.arange(11)
    for name, factor in (("lo.csv", 0.95), ("hi.csv", 1.05)):
        (tmp_path / name).write_text("strain,load_N\n" + "".join(f"{a:.4f},{factor * b:.6f}\n" for a, b in zip(s, g(s))))
    sp = specimen_from_files("b", width_mm=50.0, gauge_length_mm=100.0, knit=KNIT,
                             band=(tmp_path / "lo.csv", tmp_path / "hi.csv"), row_step=0.02)
    at = {round(float(x), 4): i for i, x in enumerate(sp.strain)}
    assert sp.sigma_N[at[0.1]] == pytest.approx(np.hypot(0.15, 1.0), rel=1e-6)
    assert sp.sigma_N[at[0.12]] == pytest.approx(0.05 * g(0.12), rel=1e-6)
    assert sp.sigma_N[at[0.3]] == pytest.approx(0.05 * g(0.3), rel=1e-6)
    assert "interpolation" in sp.sigma_rule
