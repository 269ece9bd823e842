"""reduce_history (a sweep's per-cell numbers and flags, issue 15's host side) judges many cells at once: its
arrays must be those of knitsim.io.results.cell_summary run cell by cell, every array equal, NaN where NaN.

Where the expected values come from: the oracle is ``cell_summary`` itself, read into arrays exactly as
reduce_history did cell by cell before it judged cells at once (``_by_cell_summary`` below is that loop, kept
here).  The batch is chosen to reach the ends a sweep meets (asserted, so that the comparison covers them):
Dusserre's E-glass / basalt-like cells (Table 1, section 2.2) scattered a few per cent, Coulomb and Dahl
friction, both unloading rules, the head-gap criterion (heads past each other), yarn compaction, a small cap
(stopped at the cap), a 30 % thicker yarn under a cap of 1e12 N (fails up the jammed branch, as the bundled
E-glass specimen does past 0.85), a 20 % shorter loop (no rest state); the paper's 3-cycle program, and cycles of
growing amplitude whose reloads past the earlier maximum are judged against a monotonic pull (``reference``).
"""
from __future__ import annotations

import copy
import math
import warnings

import numpy as np
import pytest

from knitsim.cell.effects import EffectSet
from knitsim.cell.engine import simulate
from knitsim.cell.history import STATUS_FORCE_CAP, STATUS_NO_CONVERGENCE, STATUS_NO_REST_STATE, STATUS_OK
from knitsim.cell.load_program import cycles, piecewise_linear
from knitsim.cell.material import CellParams
from knitsim.io import checks
from knitsim.io.jsonable import json_text
from knitsim.io.results import cell_summary, first_loading, first_loading_curve, summarise
from knitsim.sweep import runner
from knitsim.sweep.runner import CYCLE_FLAGS, CYCLE_VARS, reduce_history


def _cells(n: int = 40, seed: int = 3) -> list[CellParams]:
    rng = np.random.default_rng(seed)
    knits = [(0.31, 0.58, 14.1), (0.20, 0.56, 13.1)]
    out = []
    for i in range(n):
        B, d, L = knits[i % 2]
        s = 1.0 + rng.uniform(-0.02, 0.02, 5)
        m = float(rng.uniform(0.0, 0.4))
        p = CellParams(B=B * s[0], d=d * s[1], L=L * s[2], W0=4.4 * s[3], C0=2.7 * s[4], m=m,
                       phi0=float(rng.uniform(-1, 1)) * math.atan(m),
                       unloading_rule=("dusserre", "hong_constant_t")[i % 2], force_cap_N=10.0)
        k = i % 8
        if k == 1:
            p = p.replace(friction="dahl", dahl_sigma=float(rng.uniform(20.0, 80.0)))
        elif k == 3:
            p = p.replace(jamming_criterion="head_gap")
        elif k == 4:
            p = p.replace(effects=EffectSet(on=("yarn_compaction",), compaction_k=2.0, compaction_min=0.7))
        elif k == 5:
            p = p.replace(force_cap_N=float(rng.uniform(0.05, 0.3)))
        elif k == 6:
            p = p.replace(d=1.3 * p.d, force_cap_N=1e12)
        elif k == 7 and i % 16 == 7:
            p = p.replace(L=0.8 * p.L, force_cap_N=1e12)
        out.append(p)
    return out


def _by_cell_summary(history, n_cycles, reference=None) -> dict:
    """reduce_history's arrays from cell_summary, cell by cell (its loop before it judged cells at once)."""
    n = history.n_cells
    out = {k: np.full((n, n_cycles), np.nan) for k in CYCLE_VARS}
    out.update({k: np.full((n, n_cycles), -1, dtype=np.int8) for k in CYCLE_FLAGS})
    kind_code = {v: k for k, v in runner.ENERGY_KINDS.items()}
    out["strain_at_first_jamming"] = np.full(n, np.nan)
    out["final_status"] = np.asarray(history.status[-1, :], dtype=np.int32)
    for k in ("expected_end", "loop_creates_energy", "rest_state_compressive") + runner._WARNING_FLAGS:
        out[k] = np.zeros(n, dtype=np.int8)
    for k in runner._STOP_VARS:
        out[k] = np.full(n, np.nan)
    for c in range(n):
        s = cell_summary(history, c, reference=first_loading_curve(reference, c))
        for cy in s["cycles"]:
            j = cy["cycle"] - 1
            for k in CYCLE_VARS:
                out[k][c, j] = np.nan if cy[k] is None else cy[k]
            out["energy_kind"][c, j] = kind_code[cy["energy_kind"]]
            out["closed"][c, j] = int(cy["closed"])
            out["peak_at_force_cap"][c, j] = 0
        status = np.asarray(history.status[:, c])
        if status[-1] == STATUS_FORCE_CAP:
            stop = int(np.nonzero(status != STATUS_OK)[0][0])
            out["peak_at_force_cap"][c, int(history.cycle[stop]) - 1] = 1
        jam = s["strain_at_first_jamming"]
        out["strain_at_first_jamming"][c] = np.nan if jam is None else jam
        out["expected_end"][c] = 1 if s["expected_end"] else 0
        codes = {w["code"] for w in s["warnings"]}
        for k in ("loop_creates_energy", "rest_state_compressive") + runner._WARNING_FLAGS:
            out[k][c] = int(k in codes)
        for k in runner._STOP_VARS:
            out[k][c] = np.nan if s[k] is None else s[k]
    F = np.array(history.force_per_wale.T, dtype=np.float64)
    for c in range(n):
        status = np.asarray(history.status[:, c])
        bad = np.nonzero(status != STATUS_OK)[0]
        F[c, (int(bad[0]) + 1 if len(bad) else len(status)):] = np.nan
    out["force_per_wale_N"] = F
    return out


def _differ(fast: dict, slow: dict) -> list[str]:
    bad = sorted(set(fast) ^ set(slow))
    for k in sorted(set(fast) & set(slow)):
        a, b = fast[k], slow[k]
        if a.dtype != b.dtype or a.shape != b.shape or not np.array_equal(a, b, equal_nan=a.dtype.kind == "f"):
            bad.append(k)
    return bad


@pytest.fixture(scope="module")
def batches():
    cells = _cells()
    paper = cycles(0.10, 0.60, 3, 0.02)
    growing = piecewise_linear([0.0, 0.3, 0.1, 0.45, 0.1, 0.6], 0.02)
    return {"paper": (simulate(cells, paper), None, 3),
            "growing": (simulate(cells, growing), first_loading(cells, growing), 3)}


def test_the_batch_reaches_the_ends_a_sweep_meets(batches):
    h, ref, n_cycles = batches["paper"]
    final = set(np.asarray(h.status[-1]).tolist())
    assert {STATUS_OK, STATUS_FORCE_CAP, STATUS_NO_CONVERGENCE, STATUS_NO_REST_STATE} <= final
    assert any(p.friction == "dahl" for p in h.params)
    assert any(e.get("kind") == "slack" for e in h.events) and any(e.get("kind") == "jam" for e in h.events)
    red = reduce_history(h, n_cycles, curves=True)
    for flag in ("loop_creates_energy", "heads_interpenetrate", "zero_force_cycle", "reload_below_earlier_loading",
                 "reload_loss_continues", "reload_above_first_loading", "rest_state_compressive"):
        assert red[flag].any(), flag
    assert (red["peak_at_force_cap"] == 1).any() and np.isnan(red["residual_strain"]).any()
    assert set(np.unique(red["energy_kind"]).tolist()) >= {-1, 0, 1, 2}
    h, ref, n_cycles = batches["growing"]
    assert ref is not None and reduce_history(h, n_cycles, reference=ref)["reload_below_first_loading"].any()


@pytest.mark.parametrize("program", ["paper", "growing"])
def test_reduce_history_equals_cell_summary_cell_by_cell(batches, program):
    h, ref, n_cycles = batches[program]
    assert _differ(reduce_history(h, n_cycles, curves=True, reference=ref), _by_cell_summary(h, n_cycles, ref)) == []


def test_reduce_history_judges_cells_in_blocks_as_at_once(batches, monkeypatch):
    """Blocks of a few cells (a GPU chunk's 10^5 cells are judged in blocks of REDUCE_BLOCK values) give the
    same arrays, the cells of one stop row split between blocks."""
    h, ref, n_cycles = batches["growing"]
    whole = reduce_history(h, n_cycles, curves=True, reference=ref)
    monkeypatch.setattr(runner, "REDUCE_BLOCK", 3 * len(h.strain))
    assert _differ(reduce_history(h, n_cycles, curves=True, reference=ref), whole) == []


def test_summarise_gives_each_cells_cell_summary(batches):
    h, ref, _ = batches["growing"]
    s = summarise(h, reference=ref)
    # (as JSON: a cell without a rest state has NaN numbers)
    assert json_text(s["cells"]) == json_text([cell_summary(h, c, f"cell {c}", reference=first_loading_curve(ref, c))
                                               for c in range(h.n_cells)])


def test_cycle_checks_of_many_columns_equal_the_checks_of_each(batches):
    """load_cycle_warnings_of (columns with different finite rows grouped) against load_cycle_warnings of each
    column: the same warnings, messages included."""
    h, _, _ = batches["paper"]
    F = np.array(h.force_per_wale, float)
    F[200:, 1] = np.nan                                 # a column whose later rows are not run
    F[5, 2] = np.nan                                    # one lost row
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)             # (the cell without a rest state: all NaN)
        peaks = [[(k, float(np.nanmax(F[h.cycle == k, c]))) for k in (1, 2, 3)] for c in range(h.n_cells)]
    many = checks.load_cycle_warnings_of(peaks, h.strain, F, h.cycle, h.direction)
    each = [checks.load_cycle_warnings(peaks[c], h.strain, F[:, c], h.cycle, h.direction) for c in range(h.n_cells)]
    assert [[w.as_dict() for w in ws] for ws in many] == [[w.as_dict() for w in ws] for ws in each]
    assert sum(len(ws) for ws in each) > 10


def test_rows_past_a_cells_stop_are_not_judged(batches):
    """The rows after a cell's stop hold its stopped state (the engine's); rows that hold something else there
    (overlapping heads, W below 4 w, another force) must still not count, as cell_summary reads only the rows
    up to the stop."""
    h, ref, n_cycles = batches["paper"]
    h = copy.deepcopy(h)
    status = np.asarray(h.status)
    stopped = [c for c in range(h.n_cells) if status[-1, c] in (STATUS_FORCE_CAP, STATUS_NO_CONVERGENCE)
               and (status[:, c] != STATUS_OK).argmax() + 2 < len(h.strain)]
    assert len(stopped) >= 4
    for c in stopped:
        after = (status[:, c] != STATUS_OK).argmax() + 1
        h.values["interpenetrating"][after:, c] = 1.0
        h.values["head_gap"][after:, c] = 0.0
        h.values["W"][after:, c] = 0.1
        h.values["F"][after:, c] = -1.0
    red = reduce_history(h, n_cycles, curves=True)
    assert _differ(red, _by_cell_summary(h, n_cycles)) == []
