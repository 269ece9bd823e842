"""Measured files as a laboratory writes them, hand-made here (not from the study's generator).

Each file kind of issue 12 is read, or refused with a message that names the file, the
spreadsheet row, the column and the plain value.  Expected values: the numbers typed into
the files themselves (a semicolon / decimal-comma file reads as the same numbers as its
comma twin), and the definitions of the reader (knitsim.diagnosis.measured: forces down to
5 noise sd below zero are readings around zero; strain jitter up to 1e-3 of the strain
range inside a branch is not a reversal).
"""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.diagnosis.measured import read_measured_curve
from knitsim.errors import KnitsimInputError

# a loading branch to 0.3 and an unloading branch to 0.1, forces with a hand-typed +-3 mN scatter
_UP = [(0.0, -0.002), (0.02, 0.013), (0.04, 0.018), (0.06, 0.033), (0.08, 0.038), (0.10, 0.053), (0.12, 0.058),
       (0.14, 0.073), (0.16, 0.078), (0.18, 0.093), (0.20, 0.098), (0.22, 0.113), (0.24, 0.118), (0.26, 0.133),
       (0.28, 0.138), (0.30, 0.153)]
_DOWN = [(0.28, 0.103), (0.26, 0.098), (0.24, 0.083), (0.22, 0.078), (0.20, 0.063), (0.18, 0.058), (0.16, 0.043),
         (0.14, 0.038), (0.12, 0.023), (0.10, 0.018)]
ROWS = _UP + _DOWN


def _write(tmp_path, text: str, name="m.csv", encoding="utf-8"):
    p = tmp_path / name
    p.write_bytes(text.encode(encoding))
    return p


def _csv(rows, sep=",", dec=".", header="strain,force_per_wale_N", eol="\n", extra=None):
    head = header.replace(",", sep)
    lines = [head]
    for i, (s, f) in enumerate(rows):
        cells = [repr(s).replace(".", dec), repr(f).replace(".", dec)]
        if extra is not None:
            cells.append(extra[i])
        lines.append(sep.join(cells))
    return eol.join(lines) + eol


def test_plain_file_reads_two_branches_and_keeps_a_slightly_negative_reading(tmp_path):
    c = read_measured_curve(_write(tmp_path, _csv(ROWS)))
    assert list(c.cycle) == [1] * len(ROWS)
    assert list(c.direction) == [1] * 16 + [-1] * 10
    assert c.force[0] == -0.002                       # a load cell's reading at rest, kept
    assert c.noise.method == "estimated" and 0.001 < c.noise.sigma_N < 0.01


def test_excel_bom_crlf_and_quoted_header(tmp_path):
    text = "\ufeff" + _csv(ROWS, header='"strain","force_per_wale_N"', eol="\r\n")
    c = read_measured_curve(_write(tmp_path, text))
    ref = read_measured_curve(_write(tmp_path, _csv(ROWS), "ref.csv"))
    np.testing.assert_array_equal(c.strain, ref.strain)
    np.testing.assert_array_equal(c.force, ref.force)


@pytest.mark.parametrize("sep, dec", [(";", ","), (";", "."), ("\t", ","), ("\t", ".")])
def test_semicolon_tab_and_decimal_comma(tmp_path, sep, dec):
    c = read_measured_curve(_write(tmp_path, _csv(ROWS, sep=sep, dec=dec)))
    np.testing.assert_array_equal(c.force, [f for _, f in ROWS])
    np.testing.assert_array_equal(c.strain, [max(s, 0.0) for s, _ in ROWS])


def test_windows_1252_file_is_read(tmp_path):
    text = _csv(ROWS, header="strain,force_per_wale_N,comment", extra=["ok"] * 25 + ["\u00e9prouvette"])
    c = read_measured_curve(_write(tmp_path, text, encoding="cp1252"))
    assert len(c) == len(ROWS)


def test_forces_far_below_zero_are_refused_with_file_row_column_and_value(tmp_path):
    """A wrong zero (every force 0.05 N low) or sign: many rows far below zero, refused naming the first."""
    rows = [(s, f - 0.05) for s, f in ROWS]
    p = _write(tmp_path, _csv(rows))
    with pytest.raises(KnitsimInputError) as info:
        read_measured_curve(p)
    msg = str(info.value)
    assert str(p) in msg and "row 2" in msg and "force_per_wale_N" in msg and "-0.052 N" in msg
    assert "np.float64" not in msg and "noise sd" in msg and "zero" in msg


def test_one_negative_spike_is_an_outlier_not_an_error(tmp_path):
    rows = list(ROWS)
    rows[5] = (0.10, -0.4)
    c = read_measured_curve(_write(tmp_path, _csv(rows)))
    assert c.force[5] == -0.4          # kept as read: the diagnosis leaves isolated outliers out


@pytest.mark.parametrize("step_back", [1e-16, 1e-6])
def test_strain_jitter_inside_a_branch_is_not_a_reversal(tmp_path, step_back):
    rows = list(ROWS)
    rows[6] = (0.10 - step_back, rows[6][1])            # steps back from 0.10 inside the loading branch
    c = read_measured_curve(_write(tmp_path, _csv(rows)))
    assert list(c.direction[:16]) == [1] * 16 and c.cycle.max() == 1
    assert np.all(np.diff(c.strain[:16]) >= 0)        # replayed as the running maximum
    assert c.strain_read[6] == rows[6][0]
    # with a direction column the same jitter is accepted too
    dirs = ["load"] * 16 + ["unload"] * 10
    c2 = read_measured_curve(_write(tmp_path, _csv(rows, header="strain,force_per_wale_N,direction", extra=dirs),
                                    "d.csv"))
    np.testing.assert_array_equal(c2.strain, c.strain)


def test_a_step_back_beyond_the_tolerance_with_a_direction_column_names_the_row(tmp_path):
    rows = list(ROWS)
    rows[6] = (0.05, rows[6][1])                      # back by 0.05 inside a branch marked load
    dirs = ["load"] * 16 + ["unload"] * 10
    p = _write(tmp_path, _csv(rows, header="strain,force_per_wale_N,direction", extra=dirs))
    with pytest.raises(KnitsimInputError, match=r"row 8, column strain: 0.05 decreases within a load branch"):
        read_measured_curve(p)


def test_a_reversal_needs_the_force_to_follow(tmp_path):
    # the strain goes back by 0.02 (beyond the tolerance) while the force keeps rising: a strain
    # glitch, not an unloading; the real unloading after 0.30 is found
    rows = list(ROWS)
    rows[6] = (0.08, 0.100)
    c = read_measured_curve(_write(tmp_path, _csv(rows)))
    assert list(c.direction) == [1] * 16 + [-1] * 10


def test_text_in_a_number_cell_names_the_spreadsheet_row(tmp_path):
    text = _csv(ROWS)
    lines = text.split("\n")
    lines.insert(3, "")                               # a blank line: row numbers stay the spreadsheet's
    lines[5] = "0.06,n/a"
    p = _write(tmp_path, "\n".join(lines))
    with pytest.raises(KnitsimInputError, match=r"row 6, column force_per_wale_N: 'n/a' is not a number"):
        read_measured_curve(p)


def test_missing_column_lists_what_was_found_and_the_delimiter(tmp_path):
    p = _write(tmp_path, _csv(ROWS, header="strain;force", sep=";"))
    with pytest.raises(KnitsimInputError, match=r"missing column\(s\) force_per_wale_N \(found: strain, force; "
                                                r"read as semicolon-separated\)"):
        read_measured_curve(p)


def test_a_digitised_curve_says_its_noise_cannot_be_estimated(tmp_path):
    smooth = [(float(s), float(0.5 * s)) for s in np.round(np.linspace(0.01, 0.3, 30), 6)]
    c = read_measured_curve(_write(tmp_path, _csv(smooth)))
    assert c.noise.method == "assumed" and not c.noise.estimable
    assert "digitised" in c.noise.note
