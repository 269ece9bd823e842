"""Reading a specimen's files onto the rows of the fit (knitsim.calibration.specimen), from hand-made files."""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.calibration.specimen import specimen_from_files
from knitsim.errors import KnitsimInputError

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


def test_a_hold_whose_strain_creeps_back_is_read_its_relaxed_rows_left_out(tmp_path):
    """A step-and-hold pull as a video-tracked or settling extensometer logs it: 0 -> 0.6 (steps 0.005, a total
    force 5 + 50 strain N, 0.05 N of noise), paused after strain 0.3 for 12 rows while the force relaxes by 10 %
    (exponentially, 3 rows' time) and the strain read creeps back by 0.0024, evenly (4 of the jitter tolerance,
    6e-4).  Before, calibrate refused it ("below the rows before by more than the jitter tolerance"), as it refused
    every one of Singal 2024's 21 raw stockinette runs; the diagnosis reads such a creep as a hold.  Expected, from
    the definitions (measured.infer_branches keeps a strain back by up to 10 tolerances in the loading,
    measured.force_holds): read, the hold said, its 12 relaxed rows left out, so that the rows read are exactly the
    pull's (an identity: the file without the 12 rows).  A strain that creeps back by 0.0066 (11 tolerances) is still
    refused, at its first row beyond 10 tolerances, 0.0066 x 11 / 12 = 0.00605 back: file row k + 13 = 73."""
    from knitsim.calibration.specimen import read_table
    rng = np.random.default_rng(6)
    s = np.arange(0.0, 0.6 + 1e-9, 0.005)
    f = 5.0 + 50.0 * s + rng.normal(0.0, 0.05, len(s))
    k, t = 60, np.arange(1, 13)
    relax = (5.0 + 50.0 * s[k]) * (1.0 - 0.1 * (1.0 - np.exp(-t / 3.0))) + rng.normal(0.0, 0.05, 12)
    sh, fh = np.r_[s[:k + 1], s[k] - 0.0024 * t / 12, s[k + 1:]], np.r_[f[:k + 1], relax, f[k + 1:]]
    table = read_table(_write(tmp_path / "hold.csv", sh, fh))
    pull = read_table(_write(tmp_path / "pull.csv", s, f))
    np.testing.assert_array_equal(table.rows, np.r_[np.arange(2, k + 3), np.arange(k + 15, len(sh) + 2)])
    np.testing.assert_array_equal(table.strain, pull.strain)
    np.testing.assert_array_equal(table.force, pull.force)
    said = "1 hold(s) whose force relaxes at one strain: rows 62-74 at strain 0.3"
    assert any(n.startswith(said) for n in table.notes), table.notes
    far = np.r_[s[:k + 1], s[k] - 0.0066 * t / 12, s[k + 1:]]
    with pytest.raises(KnitsimInputError, match=r"row 73, column strain: .*an unloading\?"):
        read_table(_write(tmp_path / "unload.csv", far, fh))
