"""Series / parallel coupling of the cells of a patch under rigid grips (one grip increment).

Mechanics (wale-wise stretching between rigid grips):

- the cells of one wale column are in *series*: they carry the same force per
  wale F_j, and their changes in course length add up to the column's
  elongation, ``sum_i (C_ij - C0_ij) = u`` (the grip displacement);
- the columns are in *parallel*: every column has the same grip displacement
  u, and the grip force is the sum of the column forces, ``F_grip = sum_j F_j``
  (each F_j is a force per wale, one wale per column).

There is no course-wise coupling (no shear or transverse force between
neighbouring columns; W of each cell follows from its own equilibrium).

A cell may stand for a block of stitches (:mod:`knitsim.patch.model`): n_g
courses in series and p_g wales in parallel.  The column is then a strip of
the specimen, its cells carry the same total force ``F = p_g f_g`` (f_g the
force per wale of the cell), and their course counts weight the lengths:
``sum_g n_g (C_g - C0_g) = u``.  With p_g = 1 (single stitches) this is the
column above, and the arithmetic is the same bit for bit.

Solution of one increment, per column (all columns together, one kernel
launch per iteration): the unknowns are the cells' course lengths C_g (one per
group of identical cells, :meth:`~knitsim.patch.model.PatchModel.grouping`,
counted n_g times).  Each cell answers a trial step of the cell solver from
its committed state to C_g (``CellSolver.step`` on the committed state does
not modify it), giving F_g(C_g) along its own path-dependent branch (Table 4
stages, events, hysteresis).  With the tangent k_g = dF/dC of each cell, the
linearised equations ``f_g + k_g (C_g' - C_g) = F / p_g`` and
``sum n_g (C_g' - C0_g) = u`` give::

    a_g = C_g - f_g / k_g                  (zero-force point of the linear model)
    F   = max(0, (u - sum n_g (a_g - C0_g)) / sum n_g / (p_g k_g))
    C_g' = a_g + F / (p_g k_g)

The tangent k_g is the cell's own dF/dC at the end of its trial step, from the
Jacobian of the cell Newton at that converged state (implicit function theorem,
:mod:`knitsim.kernels.cell_tangent`): the exact slope of the branch the cell is on,
so each column iterates as Newton's method on its equations.  The first iterate
of an increment uses the tangent at the committed state, of the stage that a
reversal enters (SF- / SF+) when the increment reverses the direction.  Where the
cell tangent is not defined (Dahl cells, cells with effects, the reference engine)
or not positive, the secant between successive trial steps is used (the first
iterate then uses the tangent of the last increment, the very first one a probe
step); tangents are clamped to [K_MIN, K_MAX].  A cell that is slack
(F = 0 over a range of C, :class:`~knitsim.cell.stages.Stage` SLACK) has
``a_g`` = its slack length: the complementarity ``F >= 0``, ``u - sum n_g
(C_g - C0_g) >= 0``, one of them 0, is solved by the clamp: a column whose
linear model asks for F < 0 carries zero force, each cell is driven just
past its zero-force point (where the cell solver locates its slack event and
keeps its slack length), and the length the grips leave over is reported as
the column's slack.  A column converges when its cells' forces agree to
``force_tol`` (or all its cells are slack with F = 0); converged columns are
committed, the others iterate up to ``max_iterations`` and are then committed
as they stand and flagged.  A cell that stops (force cap, no convergence)
stops its column: the column keeps its last state and is flagged.

A column made of one group (a uniform column) is driven at exactly the grip
strain ``u / rest length``, so a uniform patch reproduces the single cell
bit for bit.
"""
from __future__ import annotations

import copy
import functools
from dataclasses import dataclass

import numpy as np
import warp as wp

from ..cell.history import STATUS_OK
from ..cell.quantities import CODE
from ..cell.stages import LABEL_CODES, Stage
from ..errors import KnitsimInputError
from .model import Grouping

#: bounds of the tangent dF/dC of a cell [N/mm]
K_MIN, K_MAX = 1e-6, 1e6
#: column flags
COL_OK, COL_NOT_CONVERGED, COL_STOPPED = 0, 1, 2
COLUMN_STATUS_NAMES = {COL_OK: "ok", COL_NOT_CONVERGED: "not_converged", COL_STOPPED: "stopped"}


def label_codes(stage: np.ndarray, jammed: np.ndarray) -> np.ndarray:
    """Vectorised :func:`~knitsim.cell.stages.stage_label` codes (:data:`LABEL_CODES`)."""
    stage = np.asarray(stage)
    out = np.where(np.isin(stage, (int(Stage.S_LOAD), int(Stage.S_UNLOAD))), LABEL_CODES["sliding"],
                   LABEL_CODES["adherence"])
    out = np.where(np.asarray(jammed) != 0, LABEL_CODES["jamming"], out)
    return np.where(stage == int(Stage.SLACK), LABEL_CODES["slack"], out).astype(np.int8)


# ===================================================================== backends
class WarpBackend:
    """Trial steps of all groups in one launch of the batched cell kernel (:mod:`knitsim.cell.batch`)."""

    def __init__(self, params: list, device: str = "cpu", max_halvings: int = 6):
        from .. import warp_runtime
        warp_runtime.init()
        import warp as wp

        from ..cell.batch import CellBatchState, CellModel, CellSolver
        self.wp = wp
        self.model = CellModel.from_params(params, device)
        self.device = self.model.device
        self.n = self.model.cell_count
        self.solver = CellSolver(self.model, max_halvings)
        self.C0 = np.array([p.C0 for p in params])
        self.s0 = self.model.state()
        self.s1 = CellBatchState.empty(self.n, self.device)
        self.res = CellBatchState.empty(self.n, self.device)
        self.control = self.model.control()
        self.control.strain = wp.zeros(self.n, dtype=wp.float64, device=self.device)
        self._mask = wp.zeros(self.n, dtype=wp.int32, device=self.device)
        self._all = wp.ones(self.n, dtype=wp.int32, device=self.device)
        self._k = wp.zeros(self.n, dtype=wp.float64, device=self.device)

    @staticmethod
    def _read(st) -> dict:
        q = st.q.numpy()
        stage = st.stage.numpy().copy()
        F = np.where(stage == int(Stage.SLACK), 0.0, q[:, CODE["F"]])
        return {"C": st.C.numpy().copy(), "F": F, "phi": q[:, CODE["phi"]].copy(), "W": q[:, CODE["W"]].copy(),
                "stage": stage, "jammed": st.jammed.numpy().copy(), "status": st.status.numpy().copy(),
                "head_gap": st.head_gap.numpy().copy()}

    def committed(self) -> dict:
        return self._read(self.s0)

    def tangent(self, trial: bool, direction: int = 0) -> np.ndarray:
        """dF/dC of every group on its branch (:mod:`knitsim.kernels.cell_tangent`; NaN where undefined),
        at the last trial's states (``trial``) or at the committed ones, there of the stage that a
        reversal to ``direction`` enters."""
        from ..kernels.cell_tangent import branch_tangent_kernel
        st = self.s1 if trial else self.s0
        m = self.model
        self.wp.launch(branch_tangent_kernel, dim=self.n,
                       inputs=m._arrays() + [m.effect_mask] + st._arrays()[:10] + [0 if trial else int(direction)],
                       outputs=[self._k], device=self.device)
        return self._k.numpy().copy()

    def trial(self, strain: np.ndarray, direction: int, increment: int) -> dict:
        """Step every group from its committed state to ``C = C0 (1 + strain)``; the committed state is kept."""
        self.control.strain.assign(np.ascontiguousarray(strain, dtype=np.float64))
        self.control.direction.fill_(int(direction))
        # the trial steps' events are not used (stage and status are read from the states): the
        # append buffer is reset so that repeated trials never overflow it (CellSolver keeps no API for this)
        self.solver._ev_count.zero_()
        self.solver.step(self.s0, self.s1, self.control, increment)
        return self._read(self.s1)

    def _select(self, mask, src, dst):
        self.wp.launch(_select_kernel(), dim=self.n, inputs=[mask] + src._arrays() + [src.eff],
                       outputs=dst._arrays() + [dst.eff], device=self.device)

    def begin_increment(self) -> None:
        self._select(self._all, self.s0, self.res)

    def accept(self, mask: np.ndarray) -> None:
        """Keep the last trial of the groups in ``mask`` as their result of this increment."""
        if np.any(mask):
            self._mask.assign(np.asarray(mask, dtype=np.int32))
            self._select(self._mask, self.s1, self.res)

    def end_increment(self) -> dict:
        self.s0, self.res = self.res, self.s0
        return self.committed()

    def get_state(self) -> dict:
        return {f: a.numpy().copy() for f, a in zip(_STATE_FIELDS, self.s0._arrays() + [self.s0.eff])}

    def set_state(self, saved: dict) -> None:
        for f, a in zip(_STATE_FIELDS, self.s0._arrays() + [self.s0.eff]):
            a.assign(saved[f])


_STATE_FIELDS = ("x", "q", "C", "stage", "jammed", "soft", "frozen_soft", "frozen_sbc", "status", "direction",
                 "head_gap", "eff")


@functools.lru_cache(maxsize=None)
def _select_kernel():
    """``dst[i] = src[i]`` where ``mask[i]``, for every field of a CellBatchState (defined after Warp's init)."""

    @wp.kernel
    def select_state(mask: wp.array(dtype=wp.int32),
                     xa: wp.array2d(dtype=wp.float64), qa: wp.array2d(dtype=wp.float64), Ca: wp.array(dtype=wp.float64),
                     sa: wp.array(dtype=wp.int32), ja: wp.array(dtype=wp.int32), ka: wp.array(dtype=wp.int32),
                     fa: wp.array(dtype=wp.float64), ba: wp.array(dtype=wp.float64), ta: wp.array(dtype=wp.int32),
                     da: wp.array(dtype=wp.int32), ga: wp.array(dtype=wp.float64), ea: wp.array2d(dtype=wp.float64),
                     xb: wp.array2d(dtype=wp.float64), qb: wp.array2d(dtype=wp.float64), Cb: wp.array(dtype=wp.float64),
                     sb: wp.array(dtype=wp.int32), jb: wp.array(dtype=wp.int32), kb: wp.array(dtype=wp.int32),
                     fb: wp.array(dtype=wp.float64), bb: wp.array(dtype=wp.float64), tb: wp.array(dtype=wp.int32),
                     db: wp.array(dtype=wp.int32), gb: wp.array(dtype=wp.float64), eb: wp.array2d(dtype=wp.float64)):
        i = wp.tid()
        if mask[i] != 0:
            for k in range(xa.shape[1]):
                xb[i, k] = xa[i, k]
            for k in range(qa.shape[1]):
                qb[i, k] = qa[i, k]
            Cb[i] = Ca[i]
            sb[i] = sa[i]
            jb[i] = ja[i]
            kb[i] = ka[i]
            fb[i] = fa[i]
            bb[i] = ba[i]
            tb[i] = ta[i]
            db[i] = da[i]
            gb[i] = ga[i]
            for k in range(ea.shape[1]):
                eb[i, k] = ea[i, k]

    return select_state


class ReferenceBackend:
    """Trial steps with the NumPy reference cycle (:class:`knitsim.cell.cycle.CellCycle`), one group at a time.

    Mirrors :meth:`CellCycle.run` for one row: reversal when the direction
    changes, ``advance`` (or the Dahl path), failures flagged, Dahl labels.
    """

    def __init__(self, params: list, max_halvings: int = 6):
        from ..cell.cycle import CellCycle
        self.cycles = [CellCycle(p, max_halvings) for p in params]
        self.n = len(params)
        self.C0 = np.array([p.C0 for p in params])
        self.s0 = [c.initial() for c in self.cycles]
        self.dir0 = [1] * self.n
        self.s1 = list(self.s0)
        self.res = list(self.s0)
        self.dir_res = list(self.dir0)

    def _read(self, states) -> dict:
        from ..cell.cycle import _with_gap
        stage = np.array([int(s.stage) for s in states], np.int32)
        F = np.array([s.q["F"] for s in states])
        gap = np.array([_with_gap(s.q, s.x, c.p.B, c.p.d)["head_gap"] for s, c in zip(states, self.cycles)])
        return {"C": np.array([s.C for s in states]), "F": np.where(stage == int(Stage.SLACK), 0.0, F),
                "phi": np.array([s.q["phi"] for s in states]), "W": np.array([s.q["W"] for s in states]),
                "stage": stage, "jammed": np.array([int(s.jammed) for s in states], np.int32),
                "status": np.array([s.status for s in states], np.int32), "head_gap": gap}

    def committed(self) -> dict:
        return self._read(self.s0)

    def tangent(self, trial: bool, direction: int = 0) -> np.ndarray:
        """No cell tangent from the reference engine (NaN: the coupling keeps its secants)."""
        return np.full(self.n, np.nan)

    def trial(self, strain: np.ndarray, direction: int, increment: int) -> dict:
        from ..cell.cycle import STATUS_NO_CONVERGENCE, _SolveFailed
        out = []
        for g, cyc in enumerate(self.cycles):
            st = self.s0[g].copy()
            if direction != self.dir0[g] and st.status == STATUS_OK and st.stage is not Stage.SLACK:
                cyc.reverse(st, direction)
            C_target = cyc.p.C0 * (1.0 + float(strain[g]))
            events: list = []
            try:
                if cyc.p.friction == "dahl" and st.stage is not Stage.SLACK:
                    st = cyc._advance_dahl(st, C_target, events, increment)
                else:
                    st = cyc.advance(st, C_target, events, increment)
            except _SolveFailed as exc:
                st.status, st.reason = STATUS_NO_CONVERGENCE, str(exc)
            if cyc.p.friction == "dahl":
                cyc._label_dahl(st)
            out.append(st)
        self.s1 = out
        self._dir1 = int(direction)
        return self._read(out)

    def begin_increment(self) -> None:
        self.res = list(self.s0)
        self.dir_res = list(self.dir0)

    def accept(self, mask: np.ndarray) -> None:
        for g in np.nonzero(mask)[0]:
            self.res[g] = self.s1[g]
            self.dir_res[g] = self._dir1

    def end_increment(self) -> dict:
        self.s0, self.dir0 = list(self.res), list(self.dir_res)
        return self.committed()

    def get_state(self) -> dict:
        return {"states": [s.copy() for s in self.s0], "dir": list(self.dir0)}

    def set_state(self, saved: dict) -> None:
        self.s0 = [s.copy() for s in saved["states"]]
        self.dir0 = list(saved["dir"])


def make_backend(engine: str, params: list, device: str = "cpu", max_halvings: int = 6):
    """The trial-step backend of ``engine`` (``"warp"`` or ``"reference"``)."""
    if engine == "warp":
        return WarpBackend(params, device, max_halvings)
    if engine == "reference":
        return ReferenceBackend(params, max_halvings)
    raise KnitsimInputError(f"engine = {engine!r}: expected one of warp, reference")


# ===================================================================== solver
@dataclass
class IncrementResult:
    """Outcome of one grip increment.

    Attributes
    ----------
    column_force : ndarray, shape [n_classes]
        Total force carried by a column of each class [N] (n-weighted mean of its cells' p_g f_g):
        the force per wale of a column of single stitches.
    column_status : ndarray of int, shape [n_classes]
        :data:`COLUMN_STATUS_NAMES` codes.
    column_slack : ndarray, shape [n_classes]
        Length the grips leave over in a slack column [mm] (0 when it carries load).
    iterations : ndarray of int, shape [n_classes]
        Trial steps the column needed.
    force_spread : ndarray, shape [n_classes]
        max - min of the cells' forces in the column [N] (0 for one group).
    cells : dict
        Committed group arrays (C, F, phi, W, stage, jammed, status), shape [n_groups].
    """

    column_force: np.ndarray
    column_status: np.ndarray
    column_slack: np.ndarray
    iterations: np.ndarray
    force_spread: np.ndarray
    cells: dict


class PatchSolver:
    """Advance a patch by grip increments (series columns in parallel).

    Parameters
    ----------
    grouping : Grouping
        The groups of identical cells (:meth:`PatchModel.grouping`).
    engine : {"warp", "reference"}
    device : str
        Warp device (warp engine).
    force_tol, force_rtol : float
        A column converges when its cells' forces agree within
        ``force_tol + force_rtol * |F|`` [N].
    max_iterations : int
        Trial steps per increment before a column is committed as it stands and flagged.
    max_halvings : int
        Passed to the cell solver.
    """

    def __init__(self, grouping: Grouping, engine: str = "warp", device: str = "cpu",
                 force_tol: float = 1e-10, force_rtol: float = 1e-8, max_iterations: int = 40,
                 max_halvings: int = 6):
        self.g = grouping
        self.backend = make_backend(engine, grouping.params, device, max_halvings)
        self.force_tol, self.force_rtol, self.max_iterations = force_tol, force_rtol, int(max_iterations)
        self.C0 = np.array([p.C0 for p in grouping.params])
        self.col = grouping.group_column
        self.n_cls = grouping.n_classes
        self.cnt = grouping.group_count.astype(np.float64)
        # wales in parallel of each group: the column's total force is p f (1 for single stitches)
        self.p = np.asarray(grouping.group_wales, dtype=np.float64)
        rest = grouping.class_rest_length
        # grip displacement = grip strain x reference length: a specimen's gauge length, else the columns'
        # common rest length, or their mean when they differ (each column is mounted at its own rest length)
        self.ref_length = float(grouping.reference_length)
        self.rest = rest
        single = np.bincount(self.col, minlength=self.n_cls) == 1
        self.single_group = single[self.col]
        self.cells = self.backend.committed()
        self.k = np.full(self.backend.n, np.nan)
        self.direction = 1

    # ------------------------------------------------------------- helpers
    def _colsum(self, v: np.ndarray) -> np.ndarray:
        return np.bincount(self.col, weights=v, minlength=self.n_cls)

    def _colmax(self, v: np.ndarray, fill: float) -> np.ndarray:
        out = np.full(self.n_cls, fill)
        np.maximum.at(out, self.col, v)
        return out

    @staticmethod
    def _along(C: np.ndarray, C_committed: np.ndarray, direction: int) -> np.ndarray:
        """The trial lengths kept on the side of the committed ones that the increment goes to.

        The column force moves with the grips (it falls on unloading, rises on loading), and on a
        branch with dF/dC > 0 every cell's length moves with its force: no cell of the solution
        lengthens on unloading or shortens on loading.  The linear model of a cell that slides
        (dF/dC ~ 0 on a plateau) can ask for such a move, far along the wrong direction of a stiff
        stick branch; the trial is kept at the committed length instead."""
        return np.minimum(C, C_committed) if direction < 0 else np.maximum(C, C_committed)

    @staticmethod
    def _cell_tangent(kc: np.ndarray, fallback: np.ndarray) -> np.ndarray:
        """The cells' own tangents where defined and positive, clamped; ``fallback`` elsewhere."""
        ok = np.isfinite(kc) & (kc > 0)
        return np.where(ok, np.clip(np.where(ok, kc, 1.0), K_MIN, K_MAX), fallback)

    def probe_tangent(self, strain: float = 1e-3) -> None:
        """Initial tangents dF/dC from a trial step of every cell to ``strain`` (loading)."""
        c = self.cells
        t = self.backend.trial(np.full(self.backend.n, strain), 1, -1)
        dC = t["C"] - c["C"]
        with np.errstate(divide="ignore", invalid="ignore"):
            k = (t["F"] - c["F"]) / dC
        ok = np.isfinite(k) & (k > 0) & (t["status"] == STATUS_OK)
        self.k = np.clip(np.where(ok, k, 1.0), K_MIN, K_MAX)

    def get_state(self) -> dict:
        return {"backend": self.backend.get_state(), "k": self.k.copy(), "direction": self.direction,
                "cells": copy.deepcopy(self.cells)}

    def set_state(self, s: dict) -> None:
        self.backend.set_state(s["backend"])
        self.k = np.array(s["k"])
        self.direction = int(s["direction"])
        self.cells = self.backend.committed()

    # ---------------------------------------------------------------- step
    def step(self, grip_strain: float, direction: int, increment: int = 0) -> IncrementResult:
        """Solve one grip increment to ``grip_strain`` (u = grip_strain x ref_length) and commit it."""
        if np.any(np.isnan(self.k)):
            self.probe_tangent()
        be, c = self.backend, self.cells
        n = be.n
        col, cnt, C0 = self.col, self.cnt, self.C0
        u = float(grip_strain) * self.ref_length
        # columns with a stopped cell keep their state (flagged)
        stopped_cls = self._colmax((c["status"] != STATUS_OK).astype(float), 0.0) > 0
        active_cls = ~stopped_cls
        done_cls = stopped_cls.copy()
        iters = np.zeros(self.n_cls, np.int64)
        # exact strain of a single-group (uniform) column: the cell itself at the grip strain
        u_single = np.where(self.rest[col] == self.ref_length, float(grip_strain), u / (cnt * C0))
        committed_strain = c["C"] / C0 - 1.0
        be.begin_increment()
        # predictor from the committed state and the last tangents
        C_prev, F_prev = c["C"].copy(), c["F"].copy()
        k = self._cell_tangent(be.tangent(False, direction), self.k)
        a = C_prev - F_prev / k
        C_try, Fstar = self._update(a, k, u)
        # the committed state is an equilibrium of the column (not so at the rest state, whose cells'
        # rest forces differ, nor after a flagged increment): only then do its cells move one way
        Fc = self.p * c["F"]
        Fc_max, Fc_min = self._colmax(Fc, -np.inf), -self._colmax(-Fc, -np.inf)
        monotone = ((Fc_max - Fc_min) <= 1e3 * (self.force_tol + self.force_rtol * np.abs(Fc_max)))[col]
        C_try = np.where(monotone, self._along(C_try, c["C"], direction), C_try)
        # per-cell brackets of this increment, (C, F) with F below / above the column force,
        # for a regula falsi with the Illinois modification when the secant stalls at a kink
        # (e.g. a cell that jams right at the equilibrium)
        nan = np.full(n, np.nan)
        lo_C, lo_F, hi_C, hi_F = nan.copy(), nan.copy(), nan.copy(), nan.copy()
        kept = np.zeros(n, np.int64)        # +1: the hi point was kept last time, -1: the lo point
        last = None
        for it in range(self.max_iterations):
            live = active_cls & ~done_cls
            if not np.any(live):
                break
            g_live = live[col]
            strain = np.where(self.single_group, u_single, C_try / C0 - 1.0)
            strain = np.where(g_live, strain, committed_strain)
            t = be.trial(strain, direction, increment)
            last = t
            iters[live] += 1
            slack = t["stage"] == int(Stage.SLACK)
            failed = t["status"] != STATUS_OK
            # convergence: equal forces at a positive column force (the lengths then add up to u by
            # construction), or every cell slack where the column was asked for zero force; a cell that
            # failed in the trial never converges its column
            Ftot = self.p * t["F"]                      # the total force each cell's block carries
            Fmax = self._colmax(np.where(g_live, Ftot, -np.inf), -np.inf)
            Fmin = -self._colmax(np.where(g_live, -Ftot, -np.inf), -np.inf)
            spread = Fmax - Fmin
            tol = self.force_tol + self.force_rtol * np.abs(Fmax)
            all_slack = self._colmax(np.where(g_live, (~slack).astype(float), 0.0), 0.0) == 0
            any_failed = self._colmax(np.where(g_live, failed.astype(float), 0.0), 0.0) > 0
            single_cls = np.bincount(col, minlength=self.n_cls) == 1
            # a single-group column is the cell itself at the grip strain: its trial is final, failed
            # or not (a failed cell stops its column, flagged, exactly as the single cell stops)
            conv = live & (single_cls | (~any_failed & (((spread <= tol) & (Fstar > 0)) | (all_slack & (Fstar == 0)))))
            if np.any(conv):
                be.accept(conv[col])
                done_cls |= conv
            # tangents: secant from the previous iterate, or the chord of the bracket (Illinois);
            # Ft is the force per wale the column's linear model asks of each cell
            Ft = Fstar[col] / self.p
            use = g_live & ~slack & ~failed
            dC = t["C"] - C_prev
            with np.errstate(divide="ignore", invalid="ignore"):
                ks = (t["F"] - F_prev) / dC
            good = use & np.isfinite(ks) & (ks > 0) & (np.abs(dC) > 1e-12 * C0)
            k = np.where(good, np.clip(ks, K_MIN, K_MAX), k)
            # the cell's own tangent at the trial's end where it is defined (IFT; else the secant)
            k = np.where(use, self._cell_tangent(be.tangent(True), k), k)
            above = use & (t["F"] > Ft)
            below = use & ~above
            # Illinois: the side kept twice in a row has its residual halved
            halve_lo = above & (kept == -1)
            halve_hi = below & (kept == 1)
            lo_F = np.where(halve_lo, Ft + 0.5 * (lo_F - Ft), lo_F)
            hi_F = np.where(halve_hi, Ft + 0.5 * (hi_F - Ft), hi_F)
            hi_C = np.where(above, t["C"], hi_C)
            hi_F = np.where(above, t["F"], hi_F)
            lo_C = np.where(below, t["C"], lo_C)
            lo_F = np.where(below, t["F"], lo_F)
            kept = np.where(above, -1, np.where(below, 1, kept))
            both = use & np.isfinite(lo_C) & np.isfinite(hi_C) & (hi_C > lo_C) & (hi_F > lo_F)
            with np.errstate(divide="ignore", invalid="ignore"):
                kc = (hi_F - lo_F) / (hi_C - lo_C)
            kc = np.clip(np.where(both, kc, 1.0), K_MIN, K_MAX)
            a = np.where(slack, t["C"], t["C"] - t["F"] / k)
            a = np.where(both, lo_C - lo_F / kc, a)
            k_model = np.where(both, kc, k)
            C_prev = np.where(use, t["C"], C_prev)
            F_prev = np.where(use, t["F"], F_prev)
            C_new, Fstar = self._update(a, k_model, u)
            # a failed trial: retreat halfway towards the last good iterate
            C_new = np.where(monotone, self._along(C_new, c["C"], direction), C_new)
            C_try = np.where(failed, 0.5 * (C_try + C_prev), C_new)
        status = np.where(stopped_cls, COL_STOPPED, COL_OK)
        not_conv = active_cls & ~done_cls
        if np.any(not_conv) and last is not None:
            # committed as it stands and flagged, unless a cell failed in the last trial: then the
            # column keeps its previous state (flagged) and the next increment tries again from it
            failed_cls = self._colmax((last["status"] != STATUS_OK).astype(float), 0.0) > 0
            be.accept((not_conv & ~failed_cls)[col])
        status = np.where(not_conv, COL_NOT_CONVERGED, status)
        self.cells = c = be.end_increment()
        stopped_now = self._colmax((c["status"] != STATUS_OK).astype(float), 0.0) > 0
        status = np.where(stopped_now & (status == COL_OK), COL_STOPPED, status)
        self.k = np.where(active_cls[col], k, self.k)
        self.direction = int(direction)
        n_cells = self._colsum(cnt)
        # a single-group column carries its cell's force exactly (no rounding of n F / n)
        F_one = np.zeros(self.n_cls)
        F_one[col[self.single_group]] = self.p[self.single_group] * c["F"][self.single_group]
        single_cls = np.bincount(col, minlength=self.n_cls) == 1
        F_col = np.where(single_cls, F_one, self._colsum(cnt * self.p * c["F"]) / n_cells)
        Ftot = self.p * c["F"]
        spread = self._colmax(Ftot, -np.inf) + self._colmax(-Ftot, -np.inf)
        slack_len = np.maximum(0.0, self._colsum(cnt * (c["C"] - C0)) - u)
        slack_len = np.where(F_col == 0.0, slack_len, 0.0)
        return IncrementResult(F_col, status.astype(np.int32), slack_len, iters, spread, c)

    def _update(self, a: np.ndarray, k: np.ndarray, u: float) -> tuple[np.ndarray, np.ndarray]:
        # returns C [n_groups] and the column force F [n_classes]
        """Linearised column equations: the common total force F >= 0 and the course lengths
        C_g = a_g + F / (p_g k_g)."""
        cnt, C0, p = self.cnt, self.C0, self.p
        num = u - self._colsum(cnt * (a - C0))
        den = self._colsum(cnt / (p * k))
        F = np.maximum(num / den, 0.0)
        Fg = F[self.col]
        C = a + Fg / (p * k)
        # a column at zero force: drive each cell a little past its zero-force point, so that the
        # cell solver locates its slack event there (and keeps its slack length)
        C = np.where(Fg == 0.0, a - 1e-6 * C0, C)
        return C, F
