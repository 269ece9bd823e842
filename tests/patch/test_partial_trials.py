"""The coupling's cheaper calls of the unchanged cell kernels, against the full calls they replace.

- a trial step of a subset of the cells (``WarpBackend.trial(..., mask)``, one launch on the
  subset's indices) gives, for each of those cells, exactly the row that a trial of every cell
  gives (each cell's step reads only its own rows), and leaves the other rows as they were;
- a later trial of an increment, whose Newton starts from the last trial's state where that trial
  fired no event and kept its stage (``CellControl.warm``), meets the equilibrium of a trial from
  the committed state: the same stages, the same lengths, forces within the Newton tolerance;
- at a reversal, a later trial of a cell whose only event was the reversal starts from the last trial's
  end, on the branch the reversal entered, and meets the trial from the committed state;
- a later trial a short Newton step away (taken without evaluating its end) is the root to the
  cell step's tolerance, and its slope dF/dC, given by the step, is the tangent kernel's to O(|dz|);
- the tangent of a subset (the other cells passed a status that is not ok) equals the full
  launch's on the subset and is NaN elsewhere;
- the trial step's own tangent (the Jacobian of its last Newton iterate) equals the tangent kernel's
  at the state it returns to rounding; the committed state's tangent reused from the accepted trial
  likewise, and at a reversal it is the kernel's;
- the bent extrapolation of the column model (``_bent_line``) is the quadratic s x + c x^2 / 2
  while its slope stays within [s/4, 4 s], then straight and continuous (an identity of its
  definition), hence monotone.
"""
from __future__ import annotations

import numpy as np

from knitsim.cell.material import CellParams
from knitsim.patch.coupling import WarpBackend, _bent_line

# Table 1 / section 2.2 / section 3.4 (dusserre2015.toml), with phi0 of a random patch
PHI0 = (-0.15, -0.05, 0.0, 0.05, 0.1, 0.19)
PARAMS = [CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, phi0=p, force_cap_N=10.0) for p in PHI0]
N = len(PARAMS)
ROWS = ("C", "F", "phi", "W", "stage", "jammed", "status", "head_gap")


def _loaded(strain_end: float) -> WarpBackend:
    be = WarpBackend(PARAMS)
    for i, e in enumerate(np.arange(0.01, strain_end + 1e-9, 0.01)):
        be.begin_increment()
        be.trial(np.full(N, e), 1, i)
        be.accept(np.ones(N, bool))
        be.end_increment()
    return be


def test_a_subset_trial_gives_the_rows_of_the_full_trial():
    be = _loaded(0.2)
    strain = 0.2 + np.linspace(0.002, 0.012, N)
    # each trial the first of its increment (from the committed state: a later one starts from the last)
    be.begin_increment()
    full = be.trial(strain, 1, 20)
    k_full = be.tangent(True)
    be.begin_increment()
    before = be.trial(np.full(N, 0.205), 1, 20)
    mask = np.array([True, False, True, True, False, True])
    be.begin_increment()
    part = be.trial(strain, 1, 20, mask)
    for name in ROWS:
        np.testing.assert_array_equal(part[name][mask], full[name][mask], err_msg=name)
        np.testing.assert_array_equal(part[name][~mask], before[name][~mask], err_msg=name)
    k_part = be.tangent(True, mask=mask)
    np.testing.assert_array_equal(k_part[mask], k_full[mask])
    assert np.all(np.isnan(k_part[~mask]))
    assert np.all(np.isfinite(k_full))


def test_a_later_trial_starts_from_the_last_and_meets_the_trial_from_the_committed_state():
    be = _loaded(0.3)
    first = 0.3 + np.linspace(0.002, 0.008, N)
    corrected = first * (1.0 + np.linspace(-2e-5, 3e-5, N))     # a column's correction: a little each way
    be.begin_increment()
    t1 = be.trial(first, 1, 30)
    warm = be._warm.copy()
    # warm where the first trial converged without an event and kept the committed stage (the cells of this
    # patch at 0.3 slide on: every one of them)
    assert np.all(warm == ((t1["status"] == 0) & (t1["stage"] == be.s0.stage.numpy())))
    assert np.all(warm)
    later = be.trial(corrected, 1, 30)
    be.begin_increment()
    cold = be.trial(corrected, 1, 30)
    for name in ("stage", "jammed", "status", "C"):
        np.testing.assert_array_equal(later[name], cold[name], err_msg=name)
    # the same equilibrium to the Newton's tolerance (every scaled residual <= 1e-11, NEWTON_TOL)
    np.testing.assert_allclose(later["F"], cold["F"], rtol=1e-9, atol=0)
    np.testing.assert_allclose(later["phi"], cold["phi"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(later["W"], cold["W"], rtol=1e-9, atol=0)


def test_a_later_trial_a_short_newton_step_away_is_the_root_and_gives_its_slope():
    """A correction so small that the warm Newton's first step is shorter than WARM_STEP_MAX: the step is
    taken without evaluating its end (kernels.cell_step.newton_solve).  Its end is the root to Newton's
    error |r''| |dz|^2 (~1e-14 here), so it meets the trial from the committed state within the cell
    step's own tolerance (its residuals <= 1e-11: F within 1e-10 relative; 1e-15 measured); its
    quantities are carried along the step to first order, and without that (the start's quantities kept)
    F would be off by k dC, 2e-8 to 6e-8 of F, more than 100 times the tolerance checked.  Its slope is
    the start's Jacobian's: O(|dz|) ~ 1e-7 from the tangent kernel's at the end (3e-9 measured)."""
    be = _loaded(0.3)
    first = 0.3 + np.linspace(0.002, 0.008, N)
    corrected = first * (1.0 + np.array([-1.0, 1.5, -2.0, 1.0, 2.0, -1.2]) * 1e-7)
    be.begin_increment()
    t1 = be.trial(first, 1, 30)
    later = be.trial(corrected, 1, 30)
    k_step = be.tangent(True)
    np.testing.assert_array_equal(k_step, be._k_step)       # the step gave every slope: no tangent launch
    fresh = be._tangent_launch(be.s1, 0, None)               # the tangent kernel at the end state
    np.testing.assert_allclose(k_step, fresh, rtol=1e-7, atol=0)
    # the short step was taken for every cell: its slope is its start's, O(|dz|) from the end's (3e-9),
    # where a solve iterated to the end gives the end's own to rounding (1e-13: the next test)
    assert np.all(np.abs(k_step - fresh) > 1e-11 * np.abs(fresh))
    be.begin_increment()
    cold = be.trial(corrected, 1, 30)
    for name in ("stage", "jammed", "status", "C"):
        np.testing.assert_array_equal(later[name], cold[name], err_msg=name)
    # the correction moved F by far more than the tolerance checked below (the carried quantities matter)
    assert np.all(np.abs(later["F"] - t1["F"]) > 100 * 1e-10 * cold["F"])
    np.testing.assert_allclose(later["F"], cold["F"], rtol=1e-10, atol=0)
    np.testing.assert_allclose(later["phi"], cold["phi"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(later["W"], cold["W"], rtol=1e-9, atol=0)
    np.testing.assert_allclose(later["head_gap"], cold["head_gap"], rtol=0, atol=1e-9)


def test_a_later_trial_of_a_reversal_starts_from_the_last_on_the_branch_the_reversal_entered():
    """At the increment that reverses (loading -> unloading at 0.3), every cell makes the reversal event at its
    committed state, whatever the length asked (Table 4: SF- entered from S+), and those that fire nothing else
    end on SF-: their next trial starts its Newton from that end (``CellControl.warm``), on the branch the
    reversal enters, and meets the trial from the committed state (same stages and lengths, F within the
    Newton's tolerance).  Cells that fired another event (here four of six slide on, S-) start cold."""
    from knitsim.kernels.cell_step import EV_REVERSAL
    be = _loaded(0.3)
    first = 0.3 - np.linspace(0.0005, 0.002, N)
    corrected = first * (1.0 + np.array([-1.0, 1.5, -2.0, 1.0, 2.0, -1.2]) * 1e-5)
    be.begin_increment()
    t1 = be.trial(first, -1, 30)
    ev = be.solver.event_arrays()
    only_reversal = np.array([np.all(ev["kind"][ev["cell"] == i] == EV_REVERSAL) for i in range(N)])
    assert np.all(np.isin(np.arange(N), ev["cell"][ev["kind"] == EV_REVERSAL]))    # every cell reversed
    assert np.any(only_reversal) and np.all(t1["stage"][only_reversal] != be.s0.stage.numpy()[only_reversal])
    np.testing.assert_array_equal(be._warm, only_reversal & (t1["status"] == 0))
    later = be.trial(corrected, -1, 30)
    be.begin_increment()
    cold = be.trial(corrected, -1, 30)
    for name in ("stage", "jammed", "status", "C"):
        np.testing.assert_array_equal(later[name], cold[name], err_msg=name)
    np.testing.assert_allclose(later["F"], cold["F"], rtol=1e-9, atol=0)
    np.testing.assert_allclose(later["phi"], cold["phi"], rtol=0, atol=1e-9)


def test_the_committed_tangent_reused_from_the_accepted_trial_equals_a_fresh_launch():
    """The trial's tangent is the step's own (CellSolver.step's slope_out: the Jacobian of its last Newton
    iterate, the state it returns); the tangent kernel evaluates the same formula at that state again,
    rebuilt from the stored (alpha, beta, gamma, phi, P): the same to rounding (1e-13 relative, 1e-16
    measured).  At a reversal the committed state's tangent is the kernel's, of the stage entered."""
    be = _loaded(0.3)
    be.begin_increment()
    be.trial(np.full(N, 0.305), 1, 30)
    k_trial = be.tangent(True)             # known at the trial: kept for the accepted cells
    np.testing.assert_array_equal(k_trial, be._k_step)     # given by the step, every cell
    mask = np.array([True, True, False, True, False, True])
    be.accept(mask)
    be.end_increment()
    for direction in (1, -1):              # the same direction, and a reversal (SF- entered)
        cached = be.tangent(False, direction)
        fresh = be._tangent_launch(be.s0, direction, None)
        if direction == 1:
            np.testing.assert_allclose(cached, fresh, rtol=1e-13, atol=0)
        else:
            np.testing.assert_array_equal(cached, fresh)
        assert np.all(np.isfinite(fresh))


def test_the_bent_extrapolation_is_the_quadratic_then_straight_and_monotone():
    s, c = 2.0, np.array([-3.0, 0.0, 5.0])
    x = np.linspace(-2.0, 2.0, 4001)
    for ci in c:
        d, slope = _bent_line(x, np.full_like(x, s), np.full_like(x, ci))
        quad = s * x + 0.5 * ci * x * x
        inside = (s + ci * x >= 0.25 * s) & (s + ci * x <= 4.0 * s)
        np.testing.assert_allclose(d[inside], quad[inside], rtol=0, atol=1e-14)
        np.testing.assert_allclose(slope[inside], (s + ci * x)[inside], rtol=0, atol=1e-14)
        assert np.all((slope >= 0.25 * s - 1e-14) & (slope <= 4.0 * s + 1e-14))
        assert np.all(np.diff(d) > 0)                       # monotone
        # continuous: the increments follow the slopes (trapezoid rule of the slope, exact for a
        # piecewise-linear slope up to the one interval holding the kink)
        trap = np.cumsum(0.5 * (slope[1:] + slope[:-1]) * np.diff(x))
        np.testing.assert_allclose(d[1:] - d[0], trap, atol=1e-6)
