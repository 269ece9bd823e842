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


def test_semicolon_file_with_decimal_commas_keeps_negative_readings_near_zero(tmp_path):
    """A European export: `;`, decimal commas, CRLF, a minus sign typed as U+2212 at rest."""
    rows = [(s, f) for s, f in ROWS]
    text = _csv(rows, sep=";", dec=",", eol="\r\n").replace(";-0,002", ";\u22120,002")
    c = read_measured_curve(_write(tmp_path, text))
    assert c.force[0] == -0.002
    np.testing.assert_array_equal(c.force[1:], [f for _, f in ROWS[1:]])


@pytest.mark.parametrize("step_back", [1e-16, 1e-6])
def test_strain_jitter_inside_an_unload_branch_with_direction_and_cycle_columns(tmp_path, step_back):
    """Inside an unloading branch the jitter is a step *up*: accepted with a direction and a cycle column,
    replayed as the running minimum; the branches are the columns' own."""
    rows = list(ROWS)
    i = 16 + 4                                        # (0.20, 0.063) inside the unloading branch
    rows[i] = (0.22 + step_back, rows[i][1])          # the extensometer reads a hair above the row before
    dirs = ["load,1"] * 16 + ["unload,1"] * 10
    text = _csv(rows, header="strain,force_per_wale_N,direction,cycle", extra=dirs)
    c = read_measured_curve(_write(tmp_path, text))
    assert list(c.direction) == [1] * 16 + [-1] * 10 and set(c.cycle) == {1}
    assert np.all(np.diff(c.strain[16:]) <= 0)        # the running minimum of the unloading branch
    assert c.strain_read[i] == rows[i][0]             # the strain as read is kept beside it



def test_a_logger_printing_a_coarse_digit_keeps_its_readings_of_one_digit_below_zero(tmp_path):
    """A load cell printing 0.01 N: a pull 0 -> 0.6 (0.034 + 0.23 strain N, noise 2 mN) and an unloading that goes
    slack, the zero at -2 mN, so that some readings at rest print -0.01.  Its noise is the rounding's (assumed,
    0.01 / sqrt(12) = 0.0029 N: noise.curve_noise); -0.01 is 3.5 of those sd below zero, a reading around zero, kept.
    Before, the noise was assumed at 0.5 % of the force range (0.00085 N) and the file refused at its first -0.01."""
    rng = np.random.default_rng(4)
    up = np.linspace(0.0, 0.6, 61)
    down = np.linspace(0.59, 0.1, 50)
    f = np.concatenate([0.034 + 0.23 * up, np.zeros(len(down))]) - 0.002 + rng.normal(0.0, 0.002, 111)
    rows = [(float(s), float(round(x, 2))) for s, x in zip(np.round(np.r_[up, down], 4), f)]
    assert min(x for _, x in rows) == -0.01
    c = read_measured_curve(_write(tmp_path, _csv(rows)))
    assert c.noise.sigma_N == pytest.approx(0.01 / np.sqrt(12.0)) and c.noise.method == "assumed"
    assert min(c.force) == -0.01 and len(c.force) == 111

def test_a_few_rows_without_a_noise_estimate_refuse_a_negative_spike(tmp_path):
    """Eight rows give no noise estimate (the reader assumes 0.5 % of the range and says so); a reading
    of -0.4 N is then not an outlier of a known noise but a wrong zero or sign: refused."""
    rows = [(0.02 * k, 0.01 * k) for k in range(1, 9)]
    rows[3] = (0.08, -0.4)
    p = _write(tmp_path, _csv(rows))
    with pytest.raises(KnitsimInputError) as info:
        read_measured_curve(p)
    msg = str(info.value)
    assert str(p) in msg and "row 5" in msg and "-0.4 N" in msg and "assumed" in msg


# every rejection of the reader: (file text, the row, the column, the value as typed, what to do); each file
# has the 4 rows a measured curve needs at least (MIN_CURVE_ROWS), so the rejection is its own
_BAD = [
    ("strain,force_per_wale_N\n0.1,0.2\n0.2,inf\n", "row 3", "force_per_wale_N", "'inf'", "fix or delete the row"),
    ("strain,force_per_wale_N\n0.1,0.2\n-1.5,0.2\n0.3,0.3\n0.4,0.4\n", "row 3", "strain", "-1.5", "is the column a strain"),
    ("strain,force_per_wale_N,direction\n0.1,0.1,load\n0.3,0.2,load\n0.2,0.2,load\n0.4,0.3,load\n", "row 4", "strain", "0.2",
     "check the direction column"),
    ("strain,force_per_wale_N,direction\n0.1,0.1,pull\n0.2,0.2,load\n0.3,0.3,load\n0.4,0.4,load\n", "row 2", "direction", "'pull'", "'load' or 'unload'"),
    ("strain,force_per_wale_N,rate_mm_s\n0.1,0.1,-0.5\n0.2,0.2,1\n0.3,0.3,1\n0.4,0.4,1\n", "row 2", "rate_mm_s", "-0.5", "must be > 0"),
    ("strain,force_per_wale_N,cycle\n0.1,0.1,1.5\n0.2,0.2,1\n0.3,0.3,1\n0.4,0.4,1\n", "row 2", "cycle", "1.5", "whole number"),
    ("strain;force_per_wale_N\n0,1;0,2\n0,2;-0,3\n0,3;-0,31\n0,4;-0,32\n", "row 3", "force_per_wale_N", "-0.3 N",
     "check the load cell's zero"),
]


@pytest.mark.parametrize("text, row, column, value, todo", _BAD)
def test_every_rejection_names_file_row_column_plain_value_and_what_to_do(tmp_path, text, row, column, value, todo):
    p = _write(tmp_path, text)
    with pytest.raises(KnitsimInputError) as info:
        read_measured_curve(p)
    msg = str(info.value)
    assert str(p) in msg and f"{row}, column {column}" in msg and value in msg and todo in msg, msg
    assert "np." not in msg and "float64" not in msg and "\n" not in msg


def _three_cycles(seed=4):
    """Hand-made cycles 0 -> 0.3 -> 0.1 -> 0.3 -> 0.1 -> 0.3, every branch on one strain grid (steps of
    0.005, an extensometer read at fixed steps), as measured (in time order): loading F = 2 s^2, unloading
    half of it, forces with a hand-set white scatter of 1 mN."""
    rng = np.random.default_rng(seed)
    k = np.arange(61)                                   # 0 .. 0.3 in steps of 0.005
    up0 = k
    down = np.arange(59, 19, -1)                        # 0.295 .. 0.1
    up = np.arange(21, 61)                              # 0.105 .. 0.3
    idx = np.concatenate([up0, down, up, down, up])
    load = np.concatenate([np.ones(len(up0)), np.zeros(len(down)), np.ones(len(up)), np.zeros(len(down)),
                           np.ones(len(up))])
    s = np.round(0.005 * idx, 6)
    f = np.where(load > 0, 2.0 * s ** 2, 1.0 * s ** 2) + rng.normal(0.0, 0.001, len(s))
    return s, f


def test_a_file_sorted_by_strain_is_refused_naming_two_rows_at_one_strain(tmp_path):
    """The same cycles in time order are read; sorted by strain (a spreadsheet sort, no cycle / direction
    columns) the loading and unloading rows at one strain sit next to each other, their forces 2 s^2 and s^2
    apart (hysteresis, 0.09 N at 0.3 against a scatter of 1 mN): read as one branch of repeated readings, a
    blind probe's such file had its noise estimated at 96.5 % of the force and an effect named with
    confidence.  Refused, naming two rows and the ratio of the differences to the scatter.  (Branches on
    grids of their own, interleaved by the sort, are not caught: the chords between them are no scatter
    either; the probe's file, like this one, had every branch on one grid.)"""
    s, f = _three_cycles()
    ok = _write(tmp_path, _csv(list(zip(s.round(6).tolist(), f.round(6).tolist()))), "timed.csv")
    assert read_measured_curve(ok).noise.method == "estimated"
    order = np.argsort(s, kind="stable")
    bad = _write(tmp_path, _csv(list(zip(s[order].round(6).tolist(), f[order].round(6).tolist()))), "sorted.csv")
    with pytest.raises(KnitsimInputError, match=r"sorted\.csv: rows \d+ and \d+ read .* at one strain .*readings of "
                                                r"different branches.*sorted by strain"):
        read_measured_curve(bad)


def test_a_relaxation_hold_at_a_few_strains_is_not_a_merged_file(tmp_path):
    """A pull with three holds (20 rows each at strains 0.1, 0.2, 0.3, the force relaxing by 2 % at each) is
    one branch measured in time: its rows at one strain are not other branches (only 3 strains repeat, below
    the 10 the refusal asks), and it is read."""
    rng = np.random.default_rng(9)
    s, f = [], []
    for a, b in ((0.0, 0.1), (0.1, 0.2), (0.2, 0.3)):
        g = np.linspace(a, b, 21)[1:]
        s += list(g)
        f += list(2.0 * g ** 2)
        s += [b] * 20
        f += list(2.0 * b * b * (1.0 - 0.02 * np.linspace(0, 1, 20)))
    f = np.array(f) + rng.normal(0.0, 0.001, len(f))
    p = _write(tmp_path, _csv(list(zip(np.round(s, 6).tolist(), f.round(6).tolist()))), "holds.csv")
    assert len(read_measured_curve(p).force) == len(s)


def _dense_pull():
    """A pull to 0.3 in steps of 0.005, its force 0.5 N per unit strain with a typed +-2 mN zigzag."""
    return [(round(0.005 * k, 3), round(0.5 * 0.005 * k + (0.002 if k % 2 else -0.002), 4)) for k in range(61)]


@pytest.mark.parametrize("typo", [0.5, -0.1])
def test_a_mistyped_strain_is_refused_not_read_as_a_cycle(tmp_path, typo):
    # a blind probe's typo (0.843 for 0.343) was read as an unloading and a second cycle, and an effect-free
    # specimen got a confident effect: the strain leaves both neighbours by 100 or 20 steps and returns, the
    # force does not move
    rows = _dense_pull()
    k = 40
    rows[k] = (round(rows[k][0] + typo, 3), rows[k][1])
    p = _write(tmp_path, _csv(rows))
    with pytest.raises(KnitsimInputError) as e:
        read_measured_curve(p)
    msg = str(e.value)
    assert f"row {k + 2}, column strain: {rows[k][0]:g} jumps from" in msg
    assert "typo" in msg and "Correct or delete the row" in msg


def test_a_mistyped_strain_at_the_first_row_is_refused_not_read_as_the_loading_going_on(tmp_path):
    """The first row's strain typed 0.6 for 0.0 (a pull from rest, rows 0.005 apart, its force rising on): the strain
    goes back from 0.6 to 0.005 while the force rises, so no unloading was read, and every row below 0.6 was read as
    the loading going on at 0.6 (the replayed strain is the branch's running extreme), without a word.  Expected:
    refused naming row 2 (header = 1) and its value.  A log that starts at its peak and unloads (the force falls with
    the strain) is read, as before (measured.unrecorded_loading)."""
    rows = _dense_pull()
    typo = [(0.6, rows[0][1])] + rows[1:]
    with pytest.raises(KnitsimInputError) as e:
        read_measured_curve(_write(tmp_path, _csv(typo), "first.csv"))
    msg = str(e.value)
    assert "row 2, column strain: 0.6 lies beyond the rows after it" in msg and "Correct or delete the row" in msg
    down = [(round(0.6 - 0.005 * k, 3), round(0.3 * (1.0 - k / 120.0) ** 3, 5)) for k in range(61)]
    up = [(round(0.305 + 0.005 * k, 3), round(0.0375 + 0.2625 * (k + 1) / 60.0, 5)) for k in range(60)]
    c = read_measured_curve(_write(tmp_path, _csv(down + up), "from_peak.csv"))
    assert np.all(c.direction[1:61] == -1) and np.all(c.direction[61:] == 1)


def test_a_block_of_rows_shifted_back_in_strain_is_refused_not_read_as_a_cycle(tmp_path):
    # a blind probe: four rows of an effect-free pull moved 0.046 back in strain (a slipped extensometer), the
    # force rising on through them, no direction column: read as an unloading and a second cycle, and the fit
    # collapsed (m 0.016 for 0.2) to a confident "unexplained".  Expected from the definition: the strain jumps
    # back by 15 steps at row k and forward again after four rows, the block's steps the neighbours', its force
    # within the noise of the chord -> refused naming the rows, the strains and the forces
    rows = _dense_pull()
    k = 30
    for j in range(k, k + 4):
        rows[j] = (round(rows[j][0] - 0.08, 3), rows[j][1])
    with pytest.raises(KnitsimInputError) as e:
        read_measured_curve(_write(tmp_path, _csv(rows)))
    msg = str(e.value)
    assert f"rows {k + 2}-{k + 5}, column strain: {rows[k][0]:g} .. {rows[k + 3][0]:g} jump from {rows[k - 1][0]:g}" in msg
    assert "slipped extensometer" in msg and "Correct or delete the rows" in msg
    # the same rows where the force follows the strain back (down to 0.02 N and up again): a turn of the test
    # recorded sparsely, read as the unloading and the reloading of a second cycle
    for j in range(k, k + 4):
        rows[j] = (rows[j][0], 0.02 + 0.001 * (j - k))
    c = read_measured_curve(_write(tmp_path, _csv(rows), "follows.csv"))
    assert list(np.unique(c.cycle)) == [1, 2]


def test_a_turn_recorded_by_one_row_whose_force_follows_is_a_cycle(tmp_path):
    # a logger that wrote one row at the bottom of an unloading (the force fell to zero there): a real
    # excursion, read as the unloading and the reloading of a second cycle
    rows = _dense_pull() + [(0.05, 0.0)] + [(round(0.05 + 0.005 * k, 3), round(0.0025 * k, 4)) for k in range(1, 11)]
    c = read_measured_curve(_write(tmp_path, _csv(rows)))
    assert list(np.unique(c.cycle)) == [1, 2]
    assert int(np.sum(c.direction == -1)) == 1


def test_a_spike_at_the_turning_row_does_not_read_a_slack_reload_as_the_unloading_going_on(tmp_path):
    """A file without a direction column: a loading to 0.3, an unloading to 0.1 that goes slack (~0 N from 0.24),
    a reload that stays slack to 0.22 and then rises.  The turning row (strain 0.10) reads 0.030 N, a spike
    (its neighbours read -0.002 and 0.001).  A reload is taken where the force does not fall below the force at
    the turn by more than 3 times its noise scale; that force was the spike's own, so the slack reload's rows
    (0.12 to 0.24, ~0 N) were read as the unloading going on, at a strain running the wrong way.  Expected (the
    rows typed): the unloading is the 10 rows 0.28 to 0.10, the reload every row after, cycle 2."""
    down = [(0.28, 0.060), (0.26, 0.020), (0.24, 0.004), (0.22, 0.001), (0.20, -0.002), (0.18, 0.002),
            (0.16, -0.001), (0.14, 0.002), (0.12, -0.002), (0.10, 0.030)]
    up = [(0.12, 0.001), (0.14, -0.002), (0.16, 0.002), (0.18, -0.001), (0.20, 0.002), (0.22, 0.003),
          (0.24, 0.010), (0.26, 0.040), (0.28, 0.090), (0.30, 0.150)]
    c = read_measured_curve(_write(tmp_path, _csv(_UP + down + up), "spike_at_turn.csv"))
    n = len(_UP)
    assert list(c.direction[n:n + len(down)]) == [-1] * len(down)
    assert list(c.direction[n + len(down):]) == [1] * len(up) and list(c.cycle[n + len(down):]) == [2] * len(up)


@pytest.mark.parametrize("offset, read", [(-0.012, True), (0.012, True), (-0.05, False)])
def test_a_load_cell_zero_below_zero_is_read_as_the_same_zero_above(tmp_path, offset, read):
    # a blind probe: 60 rows of 2 (s - 0.1)^2 N beyond s = 0.1, a +-2 mN zigzag, the zero at -12 mN, was
    # refused while the same file at +12 mN was read (and its offset fitted).  Up to 5 % of the peak
    # (0.32 N here: 16 mN) a zero below zero is a zero; -50 mN is not
    s = np.linspace(0.0, 0.5, 60)
    f = np.where(s < 0.1, 0.0, 2.0 * (s - 0.1) ** 2) + np.where(np.arange(60) % 2, 0.002, -0.002) + offset
    rows = [(round(float(a), 5), round(float(b), 5)) for a, b in zip(s, f)]
    p = _write(tmp_path, _csv(rows))
    if read:
        np.testing.assert_allclose(read_measured_curve(p).force, [b for _, b in rows])
    else:
        with pytest.raises(KnitsimInputError, match=r"row 2, column force_per_wale_N: -0.052 N is below zero"):
            read_measured_curve(p)


def _per_cent_twin(src, dst):
    """``src`` (a comma file whose first column is the strain as a fraction) written as Excel in a decimal-comma
    locale writes a test machine's per-cent export: UTF-8 BOM, ';', decimal commas, CRLF, a units row with
    '%'; each strain shifted by two decimal places as text (0.008043 -> 0.8043), so it is the same number."""
    from decimal import Decimal
    lines = src.read_text().splitlines()
    out = ["Strain [%];" + ";".join(lines[0].split(",")[1:]), "%;N;-;-"]
    for ln in lines[1:]:
        cells = ln.split(",")
        cells[0] = format(Decimal(cells[0]).scaleb(2), "f")
        out.append(";".join(c.replace(".", ",") for c in cells))
    dst.write_bytes(("\ufeff" + "\r\n".join(out) + "\r\n").encode("utf-8"))
    return dst


def test_knitsim_diagnose_reads_a_strain_in_per_cent_and_says_so_on_its_read_line(tmp_path, capsys):
    """The model's own single cycle (tests/diagnosis/data/README.md) and its per-cent twin (_per_cent_twin):
    ``knitsim diagnose`` reads the twin as the same numbers (the same read line, baseline and verdict) and
    says on its "read" line that the strain column was read in per cent."""
    from pathlib import Path

    from knitsim.cli import main
    scene = tmp_path / "s.toml"
    scene.write_text('[yarn]\nd = 0.58\nB = 0.31\n[knit]\nL = 14.1\nW0 = 4.4\nC0 = 2.7\n[friction]\nm = 0.25\n'
                     '[rules]\nunloading_rule = "dusserre"\nreload_rule = "mirror_unloading"\nforce_cap_N = 10.0\n'
                     '[diagnosis]\nfree = ["m", "phi0"]\neffects = ["bending_hysteresis"]\n')
    frac = Path(__file__).parent / "data" / "eglass_1cycle_m0.20_phi0.05_noise2mN.csv"
    pct = _per_cent_twin(frac, tmp_path / "pct.csv")
    c_frac, c_pct = read_measured_curve(frac), read_measured_curve(pct)
    np.testing.assert_allclose(c_pct.strain_read, c_frac.strain_read, rtol=1e-15, atol=0)
    np.testing.assert_array_equal(c_pct.force, c_frac.force)
    assert c_frac.notes == () and c_pct.notes == ("strain column 'Strain [%]' read in per cent (divided by 100)",)
    outs = []
    for csv in (frac, pct):
        assert main(["diagnose", str(csv), "--scene", str(scene), "--no-pair", "--quiet"]) == 0
        outs.append(capsys.readouterr().out.splitlines())
    assert outs[1][0] == (outs[0][0].replace(str(frac), str(pct))
                          + "; strain column 'Strain [%]' read in per cent (divided by 100)")
    same = [[ln.replace(str(csv), "CSV") for ln in out[1:-1]] for csv, out in zip((frac, pct), outs)]
    assert same[1] == same[0] and len(same[0]) > 5     # the fit, line by line (but the time, the last line)


def test_knitsim_calibrate_reads_a_strain_in_per_cent_and_says_so(tmp_path, capsys, e_glass_calibration):
    """A one-specimen calibration (tests/conftest.py) of a curve typed by hand in per cent (strains 0, 2.5, ...
    30 %: the fractions 0, 0.025, ... 0.3; total force 0.5 N a row): the specimen's strains are the fractions,
    and ``knitsim calibrate`` says, beside what it read (stderr), that the strain column was read in per cent."""
    from knitsim.calibration.scene import load_calibration_scene
    from knitsim.cli import main
    from knitsim.scene.schema import dumps
    (tmp_path / "a.csv").write_text("Strain [%],load_N\n" + "".join(f"{2.5 * k},{0.5 * k}\n" for k in range(13)))
    (tmp_path / "cal.toml").write_text(dumps(e_glass_calibration("per cent")))
    sp = load_calibration_scene(tmp_path / "cal.toml").specimens[0]
    assert abs(sp.strain[-1] - 0.3) < 1e-12        # the rows (every row_step = 0.02) end at 30 % = 0.3, not 30
    rc = main(["calibrate", str(tmp_path / "cal.toml"), "--out", str(tmp_path / "out"), "--no-progress"])
    err = capsys.readouterr().err
    assert rc in (0, 1), err                        # read and fitted (a fit of 2 evaluations may be flagged)
    assert f"knitsim calibrate: tight: {tmp_path / 'a.csv'}: strain column 'Strain [%]' read in per cent " \
           "(divided by 100)" in err.splitlines(), err


def test_knitsim_calibrate_names_a_per_cent_header_over_fractions_when_the_data_end_too_early(tmp_path,
                                                                                           e_glass_calibration):
    """The same hand-typed curve with its strains as fractions (0, 0.025, ... 0.3) under a ``Strain [%]``
    header: read in per cent it ends at strain 0.003, less than 4 rows of 0.02, and the refusal says that the
    column was read in per cent, that its values look like fractions, and how to state them."""
    from knitsim.calibration.scene import load_calibration_scene
    from knitsim.errors import KnitsimInputError
    from knitsim.scene.schema import dumps
    (tmp_path / "a.csv").write_text("Strain [%],load_N\n" + "".join(f"{0.025 * k:g},{0.5 * k}\n" for k in range(13)))
    (tmp_path / "cal.toml").write_text(dumps(e_glass_calibration("per cent")))
    with pytest.raises(KnitsimInputError) as e:
        load_calibration_scene(tmp_path / "cal.toml")
    msg = str(e.value)
    assert "the data end at strain 0.003, fewer than 4 rows of 0.02" in msg, msg
    assert "strain column 'Strain [%]' read in per cent (divided by 100); its largest value is 0.3 %: if the " \
           "column holds fractions (0.6 for 60 %), state its unit as [-], or none" in msg, msg


def test_a_test_machines_column_names_with_units_are_read_by_diagnose_and_calibrate(tmp_path, e_glass_calibration):
    """Hand-made exports with a machine's names (Instron Bluehill's ``Tensile strain (%)`` and ``Load (N)``,
    Zwick's ``Standard force (N)``) beside columns that are not read: the same curve and the same fitted rows
    as their twins with the package's names (the strains divided by 100 exactly), and the reading said."""
    from knitsim.calibration.scene import load_calibration_scene
    from knitsim.scene.schema import dumps
    s_pct = [2.5 * k for k in range(13)]
    # diagnose: the force per wale has no machine name, the strain has
    (tmp_path / "m.csv").write_text("Time (s),Tensile strain (%),force_per_wale_N\n"
                                    + "".join(f"{k},{s},{0.01 * k * k}\n" for k, s in enumerate(s_pct)))
    (tmp_path / "twin.csv").write_text("strain,force_per_wale_N\n"
                                       + "".join(f"{s / 100:g},{0.01 * k * k}\n" for k, s in enumerate(s_pct)))
    lab, twin = read_measured_curve(tmp_path / "m.csv"), read_measured_curve(tmp_path / "twin.csv")
    np.testing.assert_allclose(lab.strain, twin.strain, rtol=1e-15, atol=0)
    np.testing.assert_array_equal(lab.force, twin.force)
    assert lab.notes[0] == "column 'Tensile strain (%)' read as strain", lab.notes
    # calibrate: strain and total force under a machine's names (Bluehill; Zwick's standard force)
    rows = {}
    for name, header in (("bluehill", "Time (s),Load (N),Tensile strain (%)"),
                         ("zwick", "Time (s),Standard force (N),Tensile strain (%)"),
                         ("twin", "time,load_N,strain")):
        scale = 100.0 if name != "twin" else 1.0
        (tmp_path / "a.csv").write_text(header + "\n" + "".join(f"{k},{0.5 * k},{2.5 * k / 100 * scale:g}\n"
                                                               for k in range(13)))
        (tmp_path / "cal.toml").write_text(dumps(e_glass_calibration(name)))
        sp = load_calibration_scene(tmp_path / "cal.toml").specimens[0]
        rows[name] = (sp.strain, sp.target_N)
    for name in ("bluehill", "zwick"):
        np.testing.assert_allclose(rows[name][0], rows["twin"][0], rtol=1e-15, atol=0)
        np.testing.assert_allclose(rows[name][1], rows["twin"][1], rtol=1e-15, atol=0)


def test_calibrate_refuses_two_strain_or_two_force_columns_and_says_why_a_machine_column_was_not_read(tmp_path):
    """A blind probe's hand-made files: a total force under two names of different size (Load (N) and Standard
    force (N)), a strain under two (Tensile strain (%) and strain_mm_per_mm): which one to fit is not said, so
    the file is refused naming both; a force in kN under a machine's name is not read as N, and the refusal
    says why."""
    from knitsim.calibration.specimen import read_table
    from knitsim.errors import KnitsimInputError
    rows = "".join(f"{k},{0.5 * k},{0.05 * k},{2.5 * k}\n" for k in range(6))
    (tmp_path / "f.csv").write_text("Time (s),Load (N),Standard force (N),Tensile strain (%)\n" + rows)
    with pytest.raises(KnitsimInputError, match="both load_N and force_N are present .*keep one column"):
        read_table(tmp_path / "f.csv")
    (tmp_path / "s.csv").write_text("Tensile strain (%),strain_mm_per_mm,load_N\n"
                                    + "".join(f"{2.5 * k},{0.025 * k},{0.5 * k}\n" for k in range(6)))
    with pytest.raises(KnitsimInputError, match="both strain and strain_mm_per_mm are present"):
        read_table(tmp_path / "s.csv")
    (tmp_path / "k.csv").write_text("Time (s),Load (kN),Tensile strain (%)\n"
                                    + "".join(f"{k},{0.0005 * k},{2.5 * k}\n" for k in range(6)))
    with pytest.raises(KnitsimInputError, match=r"no force column .*'Load \(kN\)' is not read as load_N: 'kN' is "
                                                r"not its unit"):
        read_table(tmp_path / "k.csv")


def test_a_machine_export_with_a_total_force_is_refused_showing_its_header_and_what_to_do(tmp_path):
    # a blind probe's Bluehill export (a preamble, then Time / Extension / Load / Tensile strain over a units row)
    # was refused as "found: Results Table 1" (the preamble's first line), nothing said of the total force it had
    text = ('"Results Table 1"\n"Specimen label","EG-05"\n\n"Time","Extension","Load","Tensile strain"\n'
            '"(s)","(mm)","(N)","(%)"\n' + "".join(f"{0.5 * k:.2f},{0.19 * k:.4f},{0.5 + 0.3 * k:.5f},{0.38 * k:.4f}\n"
                                                 for k in range(12)))
    with pytest.raises(KnitsimInputError) as e:
        read_measured_curve(_write(tmp_path, text, "bluehill.csv"))
    msg = str(e.value)
    assert "missing column(s) force_per_wale_N (found: Time, Extension, Load, Tensile strain;" in msg
    assert "the file holds a total force (read as load_N)" in msg and "knitsim calibrate" in msg


def test_a_file_of_several_specimens_stacked_is_refused_naming_the_column_and_where_each_starts(tmp_path):
    """A probe's lab file held specimens A1 and A2 one under the other (a `specimen` column, as a tester's
    export of a test series writes it): diagnose read it as two cycles of one curve, the drop from A1's last
    row to A2's first as an unloading, without a word; calibrate refused it as a strain that decreases.
    Hand-made: the loading rows above twice, under specimen A1 and A2.  Expected: refused by both readers naming
    the column and the row where each specimen starts (rows 2 and 18: 16 rows each); one specimen's label on
    every row (or on the first only), or a logger's row counter named Sample (1, 2, 3, ...), is read as before."""
    from knitsim.calibration.specimen import read_table
    up = "".join(f"{s!r},{f!r}\n" for s, f in _UP)
    body = "".join(f"A1,{ln}\n" for ln in up.splitlines()) + "".join(f"A2,{ln}\n" for ln in up.splitlines())
    p = _write(tmp_path, "specimen,strain,force_per_wale_N\n" + body, "two.csv")
    with pytest.raises(KnitsimInputError, match=r"two\.csv: column specimen holds 2 specimens or tests "
                                                r"\('A1' from row 2, 'A2' from row 18\)"):
        read_measured_curve(p)
    with pytest.raises(KnitsimInputError, match=r"column specimen holds 2 .*'A2' from row 18"):
        read_table(p)
    one = _write(tmp_path, "Sample;strain;force_per_wale_N\n" + "".join(
        f"{'A1' if i == 0 else ''};{s!r};{f!r}\n" for i, (s, f) in enumerate(_UP)), "one.csv")
    assert len(read_measured_curve(one)) == len(_UP) and len(read_table(one).strain) == len(_UP)
    # (the reading of row 6 pasted again as row 7, under the next count: still a copy, left out)
    rows = _UP[:5] + _UP[4:]
    counter = _write(tmp_path, "Sample,strain,force_per_wale_N\n" + "".join(
        f"{i + 1},{s!r},{f!r}\n" for i, (s, f) in enumerate(rows)), "counter.csv")
    assert len(read_measured_curve(counter)) == len(_UP) and len(read_table(counter).strain) == len(_UP)


def test_a_logger_file_of_many_rows_is_read_and_said_to_be_slow(tmp_path):
    """A logger's pull: 5,001 rows of time, strain [%] (decimal commas) and force with a little noise
    (hand-written lines).  Read as it is (every row kept), with a note that every row is an increment of each
    simulation and how to thin it: one row in 3 (5,001 / THINNED_CURVE_ROWS = 2,000, rounded up) keeps 1,667
    rows.  5,000 rows (LONG_CURVE_ROWS) get no such note."""
    rng = np.random.default_rng(2)
    strain = np.linspace(0.0, 40.0, 5001)
    force = 0.5 * (strain / 100.0) ** 2 + 0.001 + 2e-4 * rng.standard_normal(5001)
    lines = ["Time (s);Strain (%);force_per_wale_N"] + [
        f"{0.01 * i:.2f};{s:.5f};{f:.6f}".replace(".", ",") for i, (s, f) in enumerate(zip(strain, force))]
    c = read_measured_curve(_write(tmp_path, "\n".join(lines) + "\n", name="logger.csv"))
    assert len(c) == 5001
    (note,) = [n for n in c.notes if "rows: each is an increment" in n]
    assert note.startswith("5001 rows") and "one row in 3 of the file" in note and "~1667 rows" in note
    short = read_measured_curve(_write(tmp_path, "\n".join(lines[:5001]) + "\n", name="short.csv"))
    assert len(short) == 5000 and not [n for n in short.notes if "rows: each is an increment" in n]


@pytest.mark.parametrize("load, unload", [("up", "down"), ("Up", "Down"), ("L", "U"), ("l", "u"), ("U", "D"),
                                          ("loading", "unloading"), ("LOADING", "UNLOADING"), ("Load", "Unload"),
                                          ("load", "unload"), ("+", "-"), ("1", "-1"), ("+1", "-1")])
def test_a_direction_column_in_a_labs_own_words_reads_as_load_and_unload(tmp_path, load, unload):
    """A blind probe's direction columns written up / down and L / U were refused (only load / unload and
    loading / unloading were read).  Hand-made: the two branches above (16 rows loading, 10 unloading) with the
    direction typed in each vocabulary.  Expected: the words typed, +1 for the first 16 rows and -1 for the last
    10, and the same curve as with load / unload; U is an unloading beside L and a loading beside D."""
    def curve(a, b, name):
        dirs = [a] * 16 + [b] * 10
        return read_measured_curve(_write(tmp_path, _csv(ROWS, header="strain,force_per_wale_N,direction",
                                                         extra=dirs), name))
    c, ref = curve(load, unload, "words.csv"), curve("load", "unload", "ref.csv")
    assert list(c.direction) == [1] * 16 + [-1] * 10
    np.testing.assert_array_equal(c.strain, ref.strain)
    np.testing.assert_array_equal(c.cycle, ref.cycle)


@pytest.mark.parametrize("word", ["hold", "Hold", "HOLD", "dwell", "pause", "relaxation"])
def test_a_hold_in_the_direction_column_is_the_branch_it_is_in(tmp_path, word):
    """A test program's segments written in the direction column: load, a hold at the peak (the grip stopped while the
    force relaxes), unload, a hold at the valley.  Before, 'hold' was refused as no direction.  Hand-made: the two
    branches above, with 3 rows at the peak strain 0.30 (0.153 -> 0.150 -> 0.148 -> 0.147 N) and 2 at the valley 0.10
    (0.018 -> 0.019 -> 0.020 N) labelled so.  Expected: each hold is the branch it is in (the row above's), so the
    directions are those of the same file labelled load / unload in its place (an identity), one cycle."""
    rows = _UP + [(0.30, 0.150), (0.30, 0.148), (0.30, 0.147)] + _DOWN + [(0.10, 0.019), (0.10, 0.020)]
    held = ["load"] * 16 + [word] * 3 + ["unload"] * 10 + [word] * 2
    plain = ["load"] * 19 + ["unload"] * 12
    c = read_measured_curve(_write(tmp_path, _csv(rows, header="strain,force_per_wale_N,direction", extra=held),
                                   "held.csv"))
    ref = read_measured_curve(_write(tmp_path, _csv(rows, header="strain,force_per_wale_N,direction", extra=plain),
                                     "plain.csv"))
    assert list(c.direction) == [1] * 19 + [-1] * 12
    np.testing.assert_array_equal(c.cycle, ref.cycle)
    np.testing.assert_array_equal(c.strain, ref.strain)


@pytest.mark.parametrize("dirs, row, value, why", [
    # U alone: load / unload's U or up / down's U, not said
    (["U"] * 26, "row 2", "'U'", "which one is meant is not said"),
    # U beside L and D alike
    (["L"] * 15 + ["U"] + ["D"] * 10, "row 17", "'U'", "which one is meant is not said"),
    # '-' without '+': a missing-value mark as often as an unloading
    (["load"] * 16 + ["-"] * 10, "row 18", "'-'", "missing value"),
    # a word that is no direction
    (["load"] * 16 + ["sideways"] * 10, "row 18", "'sideways'", "is not 'load' or 'unload'"),
    (["load"] * 16 + ["0"] * 10, "row 18", "'0'", "is not 'load' or 'unload'"),
])
def test_a_direction_that_is_not_said_is_refused_naming_row_column_and_value(tmp_path, dirs, row, value, why):
    # (expected: the row of the first such cell, header = row 1, as typed)
    p = _write(tmp_path, _csv(ROWS, header="strain,force_per_wale_N,direction", extra=dirs))
    with pytest.raises(KnitsimInputError) as e:
        read_measured_curve(p)
    msg = str(e.value)
    assert str(p) in msg and f"{row}, column direction: {value}" in msg and why in msg, msg


# the two branches above and a reloading to 0.2: a second cycle
_RELOAD = [(0.12, 0.031), (0.14, 0.042), (0.16, 0.049), (0.18, 0.063), (0.20, 0.071)]


def test_a_cycle_column_numbered_from_0_reads_as_the_same_cycles_and_says_so(tmp_path):
    """A logger that counts its cycles from 0 (0, 0, ..., 1, 1) was refused at its first row ("0 is not a whole
    number >= 1").  Hand-made: the branches above and a reloading (26 rows of cycle 0, 5 of cycle 1).  Expected:
    the cycles of the twin numbered from 1 and of the file without the column (inferred from the strain's
    turning points): 1 for the first 26 rows, 2 for the last 5; and a note on the read line."""
    rows = ROWS + _RELOAD
    c = read_measured_curve(_write(tmp_path, _csv(rows, header="strain,force_per_wale_N,cycle",
                                                  extra=["0"] * 26 + ["1"] * 5), "from0.csv"))
    one = read_measured_curve(_write(tmp_path, _csv(rows, header="strain,force_per_wale_N,cycle",
                                                    extra=["1"] * 26 + ["2"] * 5), "from1.csv"))
    bare = read_measured_curve(_write(tmp_path, _csv(rows), "bare.csv"))
    assert list(c.cycle) == [1] * 26 + [2] * 5
    np.testing.assert_array_equal(c.cycle, one.cycle)
    np.testing.assert_array_equal(c.cycle, bare.cycle)
    np.testing.assert_array_equal(c.direction, bare.direction)
    assert "column cycle numbered from 0: read as numbered from 1 (its cycle 0 is cycle 1)" in c.notes
    assert not any("cycle" in n for n in one.notes)


@pytest.mark.parametrize("cycles, where", [
    # a cycle that goes back (0 after 1): the 30th data row, row 31 (header = row 1)
    (["0"] * 26 + ["1"] * 3 + ["0"] * 2, "row 31, column cycle: 0 is below the cycle of row 30 (1)"),
    (["1"] * 26 + ["2"] * 3 + ["1"] * 2, "row 31, column cycle: 1 is below the cycle of row 30 (2)"),
    # not a whole number (the 27th data row, row 28), or below 0
    (["0"] * 26 + ["0.5"] * 5, "row 28, column cycle: 0.5 is not a whole number"),
    (["-1"] * 26 + ["0"] * 5, "row 2, column cycle: -1 is not a whole number"),
    # numbered from 0, but the new cycle written where the loading has not started again (row 20: the 19th data
    # row, unloading)
    (["0"] * 18 + ["1"] * 13, "row 20, column cycle: 1 does not match the branches"),
])
def test_a_wrong_cycle_column_is_refused_naming_row_column_and_its_own_value(tmp_path, cycles, where):
    p = _write(tmp_path, _csv(ROWS + _RELOAD, header="strain,force_per_wale_N,cycle", extra=cycles))
    with pytest.raises(KnitsimInputError) as e:
        read_measured_curve(p)
    assert str(p) in str(e.value) and where in str(e.value), str(e.value)


def _pull(step=0.01, end=0.5, noise=0.002, digits=5):
    """A hand-made pull: f = 0.5 s + 2 s^3 N (0.5 N at s = 0.5, the steepest at the top) plus a fixed +-``noise``
    pattern, printed to ``digits`` decimals."""
    s = np.round(np.arange(0.0, end + step / 2, step), 6)
    f = 0.5 * s + 2.0 * s ** 3 + noise * np.array([1, -1, 0.5, -0.5, 0])[np.arange(len(s)) % 5]
    return s, np.round(f, digits)


def test_a_force_flat_at_its_largest_reading_is_said_a_saturated_load_cell(tmp_path):
    """A load cell that saturated at 80 % of the pull's peak (every reading above it written as the limit) read as
    a misfit only, the clipping never named.  Hand-made: _pull() clipped at 0.4 N; the rows above it are counted
    from the formula (independent of the check).  Expected: calibrate's read note and the diagnosis' name the
    force, its rows (header = row 1) and strains; the diagnosis lists the rows (no verdict confident).  Not said:
    the pull unclipped, the top held at one strain for 5 rows (a step-and-hold's frames: Singal 2024's acrylic
    stockinette X run 3 holds 29.38 N over 5 rows), and the same pull read every 0.005 and printed to 0.1 N, whose
    top 0.5 N runs over 6 rows because it rises by less than a printed digit there."""
    from knitsim.calibration.specimen import read_table
    s, f = _pull()
    flat = np.flatnonzero(f > 0.4)
    assert flat[-1] == len(s) - 1 and len(flat) >= 4
    clipped = np.minimum(f, 0.4)
    p = _write(tmp_path, _csv(list(zip(s.tolist(), clipped.tolist())), header="strain,load_N"), "clip.csv")
    rows = f"rows {flat[0] + 2}-{flat[-1] + 2} (strain {s[flat[0]]:.4g} to 0.5)"
    note = [n for n in read_table(p).notes if "flat" in n]
    assert len(note) == 1 and f"the force column load_N is flat at 0.4 N, its largest reading, over {rows}" in note[0]
    assert "a saturated load cell" in note[0], note
    assert f"end_strain stops below them ({s[flat[0] - 1]:.4g}, its last row below" in note[0], note
    w = _write(tmp_path, _csv(list(zip(s.tolist(), clipped.tolist()))), "clip_wale.csv")
    c = read_measured_curve(w)
    assert list(c.flat_top) == [int(i) + 2 for i in flat]
    assert any(f"is flat at 0.4 N per wale, its largest reading, over {rows}" in n for n in c.notes), c.notes
    held = list(zip(s.tolist(), f.tolist())) + [(0.5, float(f[-1]))] * 4
    fine, coarse = _pull(step=0.005, digits=1)
    assert np.count_nonzero(coarse == coarse.max()) >= 4
    for rows_ in (list(zip(s.tolist(), f.tolist())), held, list(zip(fine.tolist(), coarse.tolist()))):
        q = _write(tmp_path, _csv(rows_, header="strain,load_N"), "ok.csv")
        assert not any("flat" in n for n in read_table(q).notes)


def test_rows_pasted_again_after_later_rows_are_refused_as_a_copy(tmp_path):
    """A hand-made loading (_UP, 16 rows from strain 0 to 0.30) with its data rows 5-8 (strains 0.08-0.14, file rows
    6-9) pasted again after data row 12 (file row 13): the strain steps back from 0.22 to 0.08 and on, the forces
    those of the rows copied.  diagnose read it without a word (a probe's 10 such rows, 0.047 back, as a hold at
    the running maximum: the strain held, the forces falling and rising again); calibrate refused it only as a
    loading whose strain goes back.  Expected: both name the copy, rows 14-17 repeating rows 6-9; the same file
    with the block's forces changed in their last digit (a reload that retraces the loading) is no copy."""
    from knitsim.calibration.specimen import read_table
    rows = _UP[:12] + _UP[4:8] + _UP[12:]
    p = _write(tmp_path, _csv(rows), "pasted.csv")
    for read in (read_measured_curve, read_table):
        with pytest.raises(KnitsimInputError) as e:
            read(p)
        assert str(p) in str(e.value) and "rows 14-17 repeat rows 6-9 in strain and force: rows pasted twice?" \
            in str(e.value), str(e.value)
    other = _UP[:12] + [(s, f + 0.001) for s, f in _UP[4:8]] + _UP[12:]
    with pytest.raises(KnitsimInputError) as e:
        read_table(_write(tmp_path, _csv(other), "reload.csv"))
    assert "pasted twice" not in str(e.value), str(e.value)
    assert not any("pasted twice" in n for n in read_measured_curve(_write(tmp_path, _csv(other), "reload.csv")).notes)


def test_a_cycle_column_that_changes_inside_a_loading_is_refused_by_calibrate_as_by_diagnose(tmp_path):
    """A hand-made loading (_UP, 16 rows, the strain rising throughout) with a cycle column 1 on its first 9 rows and 2
    on the last 7 (a ramp program's step counter, or two logs pasted one after the other): calibrate read it
    without a word (the column was not read).  Expected: both readers refuse it at the first row of cycle 2, the
    10th data row, row 11 (header = row 1), naming the column, the file's value and the row it changed from; the
    same column all 1 (one loading, one cycle) is read by both."""
    from knitsim.calibration.specimen import read_table
    p = _write(tmp_path, _csv(_UP, header="strain,force_per_wale_N,cycle", extra=["1"] * 9 + ["2"] * 7))
    for read in (read_table, read_measured_curve):
        with pytest.raises(KnitsimInputError) as e:
            read(p)
        assert str(p) in str(e.value), str(e.value)
        assert "row 11, column cycle: 2 does not match the branches: it changes from 1 (row 10) where no new " \
               "loading branch starts" in str(e.value), str(e.value)
    one = _write(tmp_path, _csv(_UP, header="strain,force_per_wale_N,cycle", extra=["1"] * 16), "one.csv")
    assert len(read_table(one).strain) == 16
    assert list(read_measured_curve(one).cycle) == [1] * 16
    # calibrate, which reads no cycle, reads a count written only where a cycle starts (blank below: the cycle of
    # the row above) and a column of words as before; 2 written half way is refused there too
    for extra in (["1"] + [""] * 15, ["ramp"] * 16):
        assert len(read_table(_write(tmp_path, _csv(_UP, header="strain,force_per_wale_N,cycle", extra=extra),
                                     "blank.csv")).strain) == 16
    with pytest.raises(KnitsimInputError, match="row 11, column cycle: 2 does not match"):
        read_table(_write(tmp_path, _csv(_UP, header="strain,force_per_wale_N,cycle",
                                         extra=["1"] + [""] * 8 + ["2"] + [""] * 6), "blank2.csv"))


@pytest.mark.parametrize("header", ["force_per_wale_N [N/wale]", "Force per wale [N/wale]", "force [N/wale]"])
def test_diagnose_and_calibrate_read_a_force_in_N_per_wale_as_the_force_per_wale(tmp_path, header):
    """A blind probe's three headers of a force per wale in N/wale were refused by diagnose.  Expected: the curve of
    the twin typed with force_per_wale_N (the same numbers); calibrate reads it as a force per wale, not a total."""
    from knitsim.calibration.specimen import read_table
    p = _write(tmp_path, _csv(_UP, header=f"strain,{header}"), "wale.csv")
    c = read_measured_curve(p)
    ref = read_measured_curve(_write(tmp_path, _csv(_UP), "ref.csv"))
    np.testing.assert_array_equal(c.force, ref.force)
    np.testing.assert_array_equal(c.strain, ref.strain)
    t = read_table(p)
    assert not t.total and np.array_equal(t.force, read_table(tmp_path / "ref.csv").force)


@pytest.mark.parametrize("direction", [None, "unload", "load"])
def test_rows_in_reverse_order_are_refused_by_diagnose_and_calibrate_saying_so(tmp_path, direction):
    """A blind probe's pull with its rows reversed (sorted descending by Excel: the strain only decreasing from its
    first row) got a confident `unexplained` from diagnose, read as a loading to 0.3 that no row records and an
    unloading; calibrate refused it at its second row as a strain that decreases.  Hand-made: the loading rows
    above, last first (rows 2-17: 0.3 down to 0).  Expected: both refuse it naming the file, the first and the last
    row with their strains, and saying the rows look reversed or the log starts at the peak; with a direction
    column too (every row unload, or load), where it was refused as a strain that "increases within an unload
    branch" (or decreases within a load branch).  The same rows in order are read (the test above)."""
    from knitsim.calibration.specimen import read_table
    rows = _UP[::-1]
    if direction is None:
        text = _csv(rows)
    else:
        text = _csv(rows, header="strain,force_per_wale_N,direction", extra=[direction] * len(rows))
    p = _write(tmp_path, text, "reversed.csv")
    said = (f"{p}: column strain: the strain only decreases, from 0.3 at row 2 to 0 at row 17: the rows look "
            "reversed (sorted descending")
    for read in (read_measured_curve, read_table):
        with pytest.raises(KnitsimInputError) as e:
            read(p)
        assert said in str(e.value) and "the log starts at the peak" in str(e.value), str(e.value)
    # a log whose strain goes down and back up is no reversed file (read as before: the strain does not only
    # decrease), all 20 rows; the same rows as arrays in Python keep the replay's convention (the first row ends a
    # loading from rest: one loading row, 15 unloading)
    assert len(read_measured_curve(_write(tmp_path, _csv(_DOWN + _UP[6:]), "down_then_up.csv"))) == 20
    from knitsim.diagnosis.measured import curve_from_arrays
    assert list(curve_from_arrays(*np.array(rows).T).direction) == [1] + [-1] * 15


def test_a_log_that_starts_by_unloading_is_read_and_says_its_loading_is_not_in_the_file(tmp_path):
    """A log started at the peak of a cycled test (hand-written rows: 0.6 down to 0.3, up to 0.6, down again):
    read as before, the first row the end of a loading from rest that the replay makes up, and now said on the read
    line with its strain, row and force (a blind probe: such a file was read without a word).  Expected values are
    the file's own first row.  A log that starts by loading, from rest or from a pretension at 0.1 (the paper's
    cycles run 0.1 - 0.6), gets no such note."""
    lines = ["strain,force_per_wale_N", "0.600,4.40", "0.550,1.20", "0.500,0.61", "0.450,0.30", "0.400,0.12",
             "0.350,0.05", "0.300,0.01", "0.350,0.08", "0.400,0.20", "0.450,0.45", "0.500,1.00", "0.550,2.10",
             "0.600,4.30", "0.550,1.10", "0.500,0.58", "0.450,0.28", "0.400,0.11"]
    c = read_measured_curve(_write(tmp_path, "\n".join(lines) + "\n", "peak_first.csv"))
    (note,) = [n for n in c.notes if "starts by unloading" in n]
    assert note.startswith("starts by unloading from strain 0.6 (row 2, 4.4 N per wale)") and "not in the file" in note
    assert list(c.direction[:3]) == [1, -1, -1]
    for first in (["0.000,0.00", "0.100,0.05", "0.200,0.10"], ["0.100,0.05", "0.200,0.10"]):
        rows = ["strain,force_per_wale_N"] + first + ["0.300,0.15", "0.400,0.40", "0.500,1.00", "0.600,4.30",
                                                      "0.550,1.10", "0.500,0.58", "0.450,0.28", "0.400,0.11"]
        loads = read_measured_curve(_write(tmp_path, "\n".join(rows) + "\n", "loads_first.csv"))
        assert not [n for n in loads.notes if "starts by unloading" in n]


def test_a_total_forces_name_with_a_per_wale_unit_is_refused_saying_the_unit_is_the_problem(tmp_path):
    """A helper's probe: `load_N [N/wale]` (a force per wale under a total force's name, or a total force with a
    wrong unit: the file cannot say which) was refused by diagnose as a missing force_per_wale_N only.  Expected
    (the reading rules: a unit must be the one the name implies): the refusal names the header cell and its unit
    and says both ways out."""
    p = _write(tmp_path, "strain,load_N [N/wale]\n0,0\n0.1,0.01\n0.2,0.03\n0.3,0.08\n0.2,0.02\n", "ln.csv")
    with pytest.raises(KnitsimInputError) as e:
        read_measured_curve(p)
    msg = str(e.value)
    assert "missing column(s) force_per_wale_N" in msg
    assert ("row 1, column 'load_N [N/wale]': the unit 'N/wale' is not that of load_N (its name says its unit); name "
            "the column force_per_wale_N if it holds a force per wale, else convert it to the total force in N") in msg
