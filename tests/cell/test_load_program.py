"""Tests of strain-controlled load programs (sampling, cycle numbers, refused input).

Expected values: the paper's cyclic programme 0 -> 0.60 -> 0.10 three times
(Dusserre 2015 section 2.3, dusserre2015.toml [tensile_test]) and arithmetic
of the piecewise-linear sampling.
"""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.cell.load_program import cycles, monotonic, piecewise_linear
from knitsim.data import dusserre2015
from knitsim.errors import KnitsimInputError


def test_paper_cycles():
    t = dusserre2015()["tensile_test"]
    prog = cycles(t["cycle_lower_strain"], t["cycle_upper_strain"], t["cycles"], 0.05)
    assert prog.waypoints == (0.0, 0.6, 0.1, 0.6, 0.1, 0.6, 0.1)
    # 0.6/0.05 + 5 branches of 0.5/0.05 = 12 + 50 increments
    assert len(prog) == 62
    assert prog.cycle.max() == 3 and prog.cycle.min() == 1
    # direction is +1 exactly where the strain increased
    steps = np.diff(np.concatenate([[0.0], prog.strain]))
    np.testing.assert_array_equal(prog.direction, np.sign(steps).astype(int))
    assert prog.strain[-1] == pytest.approx(0.1)


def test_increments_never_exceed_max_and_hit_waypoints():
    prog = piecewise_linear([0.0, 0.37, 0.05], 0.02)
    steps = np.abs(np.diff(np.concatenate([[0.0], prog.strain])))
    assert steps.max() <= 0.02 + 1e-15
    assert 0.37 in np.round(prog.strain, 15) and prog.strain[-1] == pytest.approx(0.05)


def test_monotonic():
    prog = monotonic(0.45, 0.005)
    assert len(prog) == 90 and np.all(prog.direction == 1) and np.all(prog.cycle == 1)


@pytest.mark.parametrize("call", [
    lambda: cycles(0.6, 0.6, 3), lambda: cycles(0.7, 0.6, 3), lambda: cycles(-0.1, 0.6, 3),
    lambda: cycles(0.1, 0.6, 0), lambda: cycles(0.1, float("nan"), 3),
    lambda: piecewise_linear([0.0, -1.0]), lambda: piecewise_linear([0.0, float("nan")]),
    lambda: piecewise_linear([]), lambda: piecewise_linear([0.0, 0.0]),
    lambda: piecewise_linear([0.0, 0.5], max_increment=0.0), lambda: monotonic(-0.2),
    lambda: monotonic(float("inf")),
])
def test_unreachable_programs_refused(call):
    with pytest.raises(KnitsimInputError):
        call()


def test_a_hand_built_program_is_checked_before_any_work():
    """A LoadProgram built by hand, as the API allows: a rising strain labelled unloading ran "ok" to 92.8 N
    past a 50 N cap, and direction / cycle arrays shorter than the strain were read past their end (a blind
    probe).  Each is refused naming the field, the index and the value; a step of 5e-4 against the
    direction (a patch cell at the rest state, replayed) is not."""
    from knitsim.cell.load_program import LoadProgram
    from knitsim.errors import KnitsimInputError

    s = np.array([0.05, 0.10, 0.15])
    with pytest.raises(KnitsimInputError, match=r"LoadProgram.direction\[0\] = -1 but the strain goes from 0.0 to 0.05"):
        LoadProgram(s, np.ones(3, int), -np.ones(3, int), (0.0,))
    with pytest.raises(KnitsimInputError, match=r"LoadProgram.direction: expected one value per increment \(3"):
        LoadProgram(s, np.ones(3, int), np.ones(2, int), (0.0,))
    with pytest.raises(KnitsimInputError, match=r"LoadProgram.strain\[1\] = nan"):
        LoadProgram(np.array([0.05, np.nan, 0.1]), np.ones(3, int), np.ones(3, int), (0.0,))
    with pytest.raises(KnitsimInputError, match="LoadProgram.cycle: expected whole numbers >= 1 that never decrease"):
        LoadProgram(s, np.array([2, 1, 1]), np.ones(3, int), (0.0,))
    with pytest.raises(KnitsimInputError, match=r"LoadProgram.direction\[1\] = 0"):
        LoadProgram(s, np.ones(3, int), np.array([1, 0, 1]), (0.0,))
    ok = LoadProgram([-5e-4, 0.05, 0.05], [1, 1, 1], [1, 1, -1], (0.0,))       # lists, a held strain either way
    assert ok.strain.dtype == np.float64 and ok.direction.tolist() == [1, 1, -1]


def test_the_reference_engine_and_cycles_refuse_what_the_batch_refuses():
    """run_cell(c, [0, 0.1]) raised AttributeError inside and an empty program gave an empty history, where
    run_batch refuses both; cycles(0.1, 0.6, True) ran one cycle (a blind probe of the API)."""
    from knitsim.cell.cycle import run_cell
    from knitsim.cell.load_program import LoadProgram, cycles
    from knitsim.cell.material import CellParams
    from knitsim.errors import KnitsimInputError

    c = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, phi0=0.0)
    for prog in ([0.0, 0.1], LoadProgram(np.zeros(0), np.zeros(0, int), np.zeros(0, int), (0.0,))):
        with pytest.raises(KnitsimInputError, match="expected a non-empty LoadProgram"):
            run_cell(c, prog)
    with pytest.raises(KnitsimInputError, match="load.cycles = True: must be a whole number >= 1"):
        cycles(0.1, 0.6, True)


@pytest.mark.parametrize("make", [lambda: monotonic(0.6, 1e-9), lambda: cycles(0.1, 0.6, 10**9, 0.01),
                                  lambda: piecewise_linear([0.3, 0.0, 0.3], 1e-8)])
def test_a_program_too_long_is_refused_before_it_is_built(make):
    # through the Python API a blind probe's monotonic(0.6, 1e-9) grew to 24 GB before anything refused it;
    # the limit is the scene's (MAX_INCREMENTS rows)
    with pytest.raises(KnitsimInputError, match=r"increments \(more than 1000000\)"):
        make()


@pytest.mark.parametrize("waypoints", [0.3, ["a", 0.3]])
def test_waypoints_that_are_not_strains_are_refused_naming_the_field(waypoints):
    # a blind probe's piecewise_linear(0.3) raised TypeError, ["a", 0.3] a ValueError without the field
    with pytest.raises(KnitsimInputError, match=r"^load\.waypoints = .*: expected a sequence of strains"):
        piecewise_linear(waypoints)


def test_run_cell_of_a_dict_is_refused_naming_the_argument():
    # a blind probe's run_cell(dict(...), program) raised AttributeError inside
    from knitsim.cell.cycle import run_cell
    with pytest.raises(KnitsimInputError, match=r"^params = \{.*\}: expected a CellParams"):
        run_cell({"B": 0.31}, monotonic(0.02, 0.01))
