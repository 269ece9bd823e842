"""Reading a specimen's files onto the rows of the fit (knitsim.calibration.specimen), from hand-made files."""
from __future__ import annotations

import numpy as np

from knitsim.calibration.specimen import specimen_from_files

KNIT = {"L": 14.1, "W0": 4.4, "C0": 2.7}


def _write(path, s, f):
    path.write_text("strain,load_N\n" + "".join(f"{x:.6f},{y:.5f}\n" for x, y in zip(s, f)))
    return path


def _force(s):
    return 2.0 * s + 8.0 * s ** 3 + 0.002 * np.cos(37.0 * np.arange(len(s)))


def _gap_notes(path):
    sp = specimen_from_files("k", width_mm=50.0, gauge_length_mm=100.0, knit=KNIT, curve=path)
    return [n for src, n in sp.read_notes if "no reading between" in n]


def test_a_gap_in_the_strain_is_said_naming_its_readings_and_the_rows_made_up(tmp_path):
    """A pull read every 0.01 to 0.5 with its readings from 0.11 to 0.29 lost: the fit's rows (every 0.005) between
    0.10 and 0.30 were the chord between two readings, weighed as rows between close readings, without a word.
    Expected (counted by hand): the gap 0.1 (row 12: header row 1, strain 0 row 2) to 0.3 (row 13), 40 % of the
    strain range and 20 times the median step (0.01), 39 rows of the fit strictly inside (0.105 .. 0.295).  Not
    said: the same pull complete, steps of 0.01 +- 50 % (irregular), and a log of steps 1e-4 with 4 jumps of 0.01
    (5 % of its range, 100 times its median step: a step-and-hold test's moves between holds, as Singal 2024's
    video frames step by up to 5.3 %)."""
    s = np.round(np.arange(0.0, 0.5 + 1e-9, 0.01), 6)
    keep = (s <= 0.1 + 1e-9) | (s >= 0.3 - 1e-9)
    notes = _gap_notes(_write(tmp_path / "gap.csv", s[keep], _force(s[keep])))
    assert len(notes) == 1, notes
    assert notes[0].startswith("no reading between strain 0.1 (row 12) and 0.3 (row 13), 40 % of its strain range "
                               "and 20 times its median step: the fit's 39 row(s) there are the straight line"), notes
    assert not _gap_notes(_write(tmp_path / "full.csv", s, _force(s)))
    rng = np.random.default_rng(0)
    irregular = np.r_[0.0, np.cumsum(0.01 * (1.0 + 0.5 * rng.uniform(-1, 1, 50)))]
    assert not _gap_notes(_write(tmp_path / "irregular.csv", irregular, _force(irregular)))
    steps = np.full(1600, 1e-4)
    steps[[300, 700, 1100, 1500]] = 0.01
    holds = np.r_[0.0, np.cumsum(steps)]
    assert not _gap_notes(_write(tmp_path / "holds.csv", holds, _force(holds)))


def test_one_test_given_as_both_envelopes_of_a_band_is_refused(tmp_path):
    """band = [a.csv, a copy of it]: a band of no width, every row weighed by the machine's accuracy (0.5 % of the
    force) as if the tests did not scatter; fitted without a word.  Expected: refused naming the key and both files;
    two envelopes that differ (the copy's forces +2 %) are read."""
    import pytest
    from knitsim.errors import KnitsimInputError
    s = np.round(np.arange(0.0, 0.5 + 1e-9, 0.01), 6)
    a = _write(tmp_path / "a.csv", s, _force(s))
    (tmp_path / "a_copy.csv").write_text(a.read_text())
    with pytest.raises(KnitsimInputError) as e:
        specimen_from_files("k", width_mm=50.0, gauge_length_mm=100.0, knit=KNIT, band=(a, tmp_path / "a_copy.csv"),
                            where="specimens[0]")
    assert str(e.value).startswith(f"specimens[0].band: {a} and {tmp_path / 'a_copy.csv'} hold the same rows"), e.value
    hi = _write(tmp_path / "hi.csv", s, 1.02 * _force(s))
    sp = specimen_from_files("k", width_mm=50.0, gauge_length_mm=100.0, knit=KNIT, band=(a, hi))
    assert sp.has_band and np.all(sp.band_high_N > sp.band_low_N)
