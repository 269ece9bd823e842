"""The patch coupling's per-group work on the Warp device of the cells (:mod:`knitsim.kernels.branch_points`,
:mod:`knitsim.kernels.column_trials`).

:class:`DeviceBranchPoints` is :class:`~knitsim.patch.coupling.BranchPoints` with its points and model kept on
the device: ``add``, ``prepare``, ``model`` and ``jump`` run one thread per group instead of NumPy over
[groups, points] arrays (on a 10^6-group patch those took ~1 s of host time per trial, several times the
cells' own trial on a GPU).  The NumPy class is its twin and test oracle
(``tests/patch/test_device_coupling.py``).  Used alone, ``record`` (stall counts) and the bounds the solver sets
stay on the host and are sent with ``prepare``; :class:`DeviceColumnSolve` is ``PatchSolver._solve_columns`` on
the device; :class:`DeviceTrials` keeps the bounds, the stall counts and the rest of each trial's bookkeeping
on the device (``PatchSolver._solve`` with the device coupling: the host reads per-column values only).
"""
from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels import branch_points as kbp
from .coupling import FORCE_SEARCH_MAX, FORCE_SEARCH_START, K_MAX, K_MIN, BranchPoints, column_length_tolerance


class DeviceBranchPoints(BranchPoints):
    """:class:`~knitsim.patch.coupling.BranchPoints` on a Warp device (the same parameters and methods).

    Parameters
    ----------
    C_ref, k_fallback : ndarray, shape [n]
        As :class:`~knitsim.patch.coupling.BranchPoints`.
    size : int
        Points kept per group: :data:`knitsim.kernels.branch_points.SIZE` (the only size compiled).
    device : str
        Warp device.
    k_bounds : (float, float)
        As :class:`~knitsim.patch.coupling.BranchPoints` (sent with the model's arrays: ``BranchArrays.k_min``,
        ``k_max``).
    """

    on_device = True
    _NOT_SENT = object()

    def __init__(self, C_ref: np.ndarray, k_fallback: np.ndarray, size: int = kbp.SIZE, device: str = "cpu",
                 k_bounds: tuple[float, float] = (K_MIN, K_MAX)):
        if size != kbp.SIZE:
            raise ValueError(f"DeviceBranchPoints keeps {kbp.SIZE} points per group, not {size}")
        n = len(C_ref)
        self.C_ref = C_ref
        self.k_min, self.k_max = float(k_bounds[0]), float(k_bounds[1])
        self.device = device
        self.n = n
        self._rows = np.arange(n)
        S = kbp.SIZE

        def arr(shape, dtype=wp.float64, fill=None):
            a = wp.empty(shape, dtype=dtype, device=device)
            if fill is not None:
                a.fill_(fill)
            return a

        b = kbp.BranchArrays()
        b.C, b.F, b.K = (arr((n, S)) for _ in range(3))         # (set by reset)
        b.valid = arr((n, S), wp.int32)
        b.Fs, b.Cs, b.Ks = (arr((n, S), fill=np.nan) for _ in range(3))
        b.m = arr(n, wp.int32, 0)
        b.da, b.db, b.da_raw, b.db_raw = (arr((n, S - 1), fill=0.0) for _ in range(4))
        b.convex, b.concave = (arr((n, S - 1), wp.int32, 0) for _ in range(2))
        b.s_lo, b.s_hi, b.c_lo, b.c_hi = (arr(n, fill=0.0) for _ in range(4))
        b.C_min, b.C_max, b.curvature = (arr(n) for _ in range(3))
        b.stall, b.side = arr(n, wp.int32), arr(n, wp.int32)
        b.k_fallback = arr(n)
        b.C_ref = wp.array(np.asarray(C_ref, dtype=np.float64), dtype=wp.float64, device=device)
        b.k_min, b.k_max = wp.float64(self.k_min), wp.float64(self.k_max)
        self.b = b
        self._all_rows = wp.array(self._rows.astype(np.int32), dtype=wp.int32, device=device)
        self.reset(k_fallback)

    def reset(self, k_fallback: np.ndarray, host_state: bool = True) -> None:
        """Forget every point (a new increment), with the fallback tangents ``k_fallback`` [N/mm]: the state of
        a new instance, without allocating its arrays again.  Without ``host_state`` the bounds and stall state
        are left to the device (``DeviceTrials.begin`` sets them there): no host arrays are made for them."""
        n, b = self.n, self.b
        self.k_fallback = k_fallback
        self.rows = self._rows
        self._rows_dev = self._all_rows
        if host_state:
            self.C_min = np.full(n, -np.inf)
            self.C_max = np.full(n, np.inf)
            self.stall = np.zeros(n, np.int64)
            self.side = np.zeros(n, np.int64)
        else:
            self.C_min = self.C_max = self.stall = self.side = None
        self.column_gap = None
        self.curvature = None
        self._curvature_sent = self._NOT_SENT
        #: the bounds C_min, C_max and the stall state are the host's attributes, sent by prepare (else kept on
        #: the device by DeviceTrials)
        self.host_state = bool(host_state)
        for a in (b.C, b.F, b.K):
            a.fill_(np.nan)
        b.valid.zero_()
        b.k_fallback.assign(np.ascontiguousarray(k_fallback, dtype=np.float64))

    # --------------------------------------------------------------- helpers
    def _send(self, a: np.ndarray, dtype=wp.float64) -> wp.array:
        np_type = np.float64 if dtype is wp.float64 else np.int32
        return wp.array(np.ascontiguousarray(a, dtype=np_type), dtype=dtype, device=self.device)

    def _row_list(self, rows: np.ndarray) -> wp.array:
        return self._all_rows if rows is self._rows else self._send(rows, wp.int32)

    # --------------------------------------------------------------- the twin's methods
    def add(self, mask: np.ndarray, C: np.ndarray, F: np.ndarray, K: np.ndarray, f_target: np.ndarray) -> None:
        rows = np.flatnonzero(mask)
        if rows.size == 0:
            return
        if rows.size == self.n:
            rows_dev, pick = self._all_rows, (lambda a: a)
        else:
            rows_dev, pick = self._send(rows, wp.int32), (lambda a: np.asarray(a)[rows])
        wp.launch(kbp.add_points_kernel, dim=rows.size, device=self.device,
                  inputs=[self.b, rows_dev, self._send(pick(C)), self._send(pick(F)), self._send(pick(K)),
                          self._send(pick(f_target))])

    def curvature_on_device(self) -> None:
        """The curvature of every group was written on the device (``DeviceTrials.branch_curvature``):
        :meth:`prepare` sends none."""
        self._curvature_sent = self.curvature

    def prepare(self, rows: np.ndarray | None = None) -> None:
        self.rows = self._rows if rows is None or len(rows) == self.n else np.asarray(rows)
        self._rows_dev = self._row_list(self.rows)
        b = self.b
        if self.host_state:
            # the bounds and stall state the solver keeps on the host (set between trials) go with the model
            b.C_min.assign(np.ascontiguousarray(self.C_min, dtype=np.float64))
            b.C_max.assign(np.ascontiguousarray(self.C_max, dtype=np.float64))
            b.stall.assign(self.stall.astype(np.int32))
            b.side.assign(self.side.astype(np.int32))
        if self._curvature_sent is not self.curvature:
            curv = np.full(self.n, np.nan) if self.curvature is None else self.curvature
            b.curvature.assign(np.ascontiguousarray(curv, dtype=np.float64))
            self._curvature_sent = self.curvature
        if self.rows.size:
            wp.launch(kbp.prepare_model_kernel, dim=self.rows.size, inputs=[b, self._rows_dev], device=self.device)

    def model(self, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = self.rows.size
        C = wp.empty(n, dtype=wp.float64, device=self.device)
        dC = wp.empty(n, dtype=wp.float64, device=self.device)
        if n:
            wp.launch(kbp.model_kernel, dim=n, inputs=[self.b, self._rows_dev, self._send(f)], outputs=[C, dC],
                      device=self.device)
        return C.numpy(), dC.numpy()

    def jump(self, f: np.ndarray, f_tol: np.ndarray) -> np.ndarray:
        n = self.rows.size
        out = wp.zeros(n, dtype=wp.int32, device=self.device)
        if n:
            wp.launch(kbp.jump_kernel, dim=n, inputs=[self.b, self._rows_dev, self._send(f), self._send(f_tol)],
                      outputs=[out], device=self.device)
        return out.numpy().astype(bool)

    def points(self) -> dict:
        """Host copies of the kept points (C, F, K, valid), as the twin's attributes of those names."""
        b = self.b
        return {"C": b.C.numpy(), "F": b.F.numpy(), "K": b.K.numpy(), "valid": b.valid.numpy().astype(bool)}


class DeviceColumnSolve:
    """``PatchSolver._solve_columns`` on the device of a :class:`DeviceBranchPoints` (its twin and oracle).

    The groups' models are evaluated one thread per group at their column's force, each column's sums one
    thread per column over its groups in ascending order (those of ``numpy.bincount``: the same sums), and
    the safeguarded Newton steps one thread per column (:mod:`knitsim.kernels.branch_points`, "the column's
    scalar solve"); the host reads one count per iteration (are columns still open).

    Parameters
    ----------
    col : ndarray of int, shape [n_groups]
        Each group's column.
    cnt, C0, p : ndarray, shape [n_groups]
        Courses in series, rest length [mm] and wales in parallel of each group.
    n_columns : int
    device : str
    force_search : (float, float)
        The search's first guess where a column has no lower bound and its ceiling [N]
        (``PatchSolver.force_search``; default :data:`~knitsim.patch.coupling.FORCE_SEARCH_START`,
        :data:`~knitsim.patch.coupling.FORCE_SEARCH_MAX`: a patch at the usual knits' scale).
    """

    MAX_ITERATIONS = 200            # the twin's

    def __init__(self, col: np.ndarray, cnt: np.ndarray, C0: np.ndarray, p: np.ndarray, n_columns: int,
                 device: str, force_search: tuple[float, float] = (FORCE_SEARCH_START, FORCE_SEARCH_MAX)):
        self.device, self.n_cls = device, int(n_columns)
        self.force_search = (float(force_search[0]), float(force_search[1]))
        n = len(col)
        f64 = lambda a: wp.array(np.ascontiguousarray(a, dtype=np.float64), dtype=wp.float64, device=device)  # noqa: E731
        i32 = lambda a: wp.array(np.ascontiguousarray(a, dtype=np.int32), dtype=wp.int32, device=device)  # noqa: E731
        self.col, self.cnt, self.C0, self.p = i32(col), f64(cnt), f64(C0), f64(p)
        counts = np.bincount(col, minlength=self.n_cls)
        self.col_start = i32(np.r_[0, np.cumsum(counts)])
        self.col_groups = i32(np.argsort(col, kind="stable"))
        scale = np.bincount(col, weights=np.asarray(cnt) * np.asarray(C0), minlength=self.n_cls)
        self.tol_len_host = column_length_tolerance(scale)
        self.tol_len = f64(self.tol_len_host)
        g = lambda: wp.zeros(n, dtype=wp.float64, device=device)  # noqa: E731
        self.C, self.dC, self.C_zero, self.C_a, self.C_b = g(), g(), g(), g(), g()
        k = lambda dtype=wp.float64: wp.zeros(self.n_cls, dtype=dtype, device=device)  # noqa: E731
        self.r, self.dr, self.r_a, self.r_b, self.F, self.F_x, self.lo, self.hi, self.u = (k() for _ in range(9))
        self.live, self.done, self.slack, self.gap = (k(wp.int32) for _ in range(4))
        self.still_open = wp.zeros(1, dtype=wp.int32, device=device)

    def _phi(self, pts: DeviceBranchPoints, F: wp.array, C: wp.array, r: wp.array, dr: wp.array) -> None:
        """C (and self.dC) of the prepared groups at their columns' forces F, and each live column's Phi, dPhi/dF."""
        n = pts.rows.size
        if n:
            wp.launch(kbp.model_at_column_force_kernel, dim=n, device=self.device,
                      inputs=[pts.b, pts._rows_dev, self.col, self.p, F], outputs=[C, self.dC])
        wp.launch(kbp.column_sums_kernel, dim=self.n_cls, device=self.device,
                  inputs=[self.col_start, self.col_groups, self.live, self.cnt, self.C0, self.p, C, self.dC, self.u],
                  outputs=[r, dr])

    def solve(self, pts: DeviceBranchPoints, u, F_guess: np.ndarray, live: np.ndarray,
              C_committed: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
        """The columns' forces [n_columns] and the groups' lengths [n_groups]: ``PatchSolver._solve_columns``.
        With ``C_committed`` None the lengths are left on the device (``self.C``, of the prepared groups), not
        copied back (None is returned for them)."""
        live = np.asarray(live, bool)
        self.live.assign(live.astype(np.int32))
        self.u.assign(np.ascontiguousarray(np.broadcast_to(np.asarray(u, dtype=np.float64), (self.n_cls,))))
        self.F.zero_()
        self._phi(pts, self.F, self.C_zero, self.r, self.dr)
        phi0 = self.r.numpy()
        slack = live & (phi0 >= 0.0)
        F = np.where(slack, 0.0, np.maximum(F_guess, 0.0))
        self.F.assign(np.where(live, F, F_guess))
        self.done.assign((slack | ~live).astype(np.int32))
        self.lo.zero_()
        self.hi.fill_(np.inf)
        for _ in range(self.MAX_ITERATIONS):
            self._phi(pts, self.F, self.C, self.r, self.dr)
            self.still_open.zero_()
            wp.launch(kbp.column_newton_kernel, dim=self.n_cls, device=self.device,
                      inputs=[self.r, self.dr, self.tol_len, self.F, self.lo, self.hi, self.done,
                              self.force_search[0], self.force_search[1], self.still_open])
            if int(self.still_open.numpy()[0]) == 0:
                break
        self._phi(pts, self.F, self.C, self.r, self.dr)
        F, r, lo, hi = self.F.numpy(), self.r.numpy(), self.lo.numpy(), self.hi.numpy()
        rows = pts.rows
        # a model with a step may have no exact root: where the bracket has closed on it, the lengths between
        # the bracket's ends that add up to u
        gap = live & ~slack & (np.abs(r) > self.tol_len_host) & np.isfinite(hi)
        if np.any(gap) and rows.size:
            self.F_x.assign(np.where(gap, lo, F))
            self._phi(pts, self.F_x, self.C_a, self.r_a, self.dr)
            self.F_x.assign(np.where(gap, hi, F))
            self._phi(pts, self.F_x, self.C_b, self.r_b, self.dr)
            self.gap.assign(gap.astype(np.int32))
            wp.launch(kbp.column_bridge_kernel, dim=rows.size, device=self.device,
                      inputs=[pts._rows_dev, self.col, self.gap, self.r_a, self.r_b, self.C_a, self.C_b, self.C])
        if np.any(slack) and rows.size:
            self.slack.assign(slack.astype(np.int32))
            wp.launch(kbp.column_slack_lengths_kernel, dim=rows.size, device=self.device,
                      inputs=[pts.b, pts._rows_dev, self.col, self.slack, self.C_zero, self.C0, self.C])
        if C_committed is None:
            return F, None
        C_all = np.array(C_committed, dtype=np.float64, copy=True)
        C_all[rows] = self.C.numpy()[rows]
        return F, C_all


class DeviceTrials:
    """The per-trial bookkeeping of ``PatchSolver._solve`` on the device (:mod:`knitsim.kernels.column_trials`).

    Between two trials of a patch's cells the coupling judges each column (its forces agree, its lengths add
    up, a cell failed) and updates each group's branch model (stall count, new points, fallback tangent, the
    bounds from its good and failed trials).  In NumPy over 10^6 groups that was ~0.2 s of host time a trial;
    here the groups' work runs one thread per group and the columns' one thread per column, and the host reads
    only per-column values.  The NumPy lines of ``_solve`` are the twin (``tests/patch/test_device_coupling.py``
    runs patches both ways: the same results bit for bit on the CPU).

    Parameters
    ----------
    columns : DeviceColumnSolve
        The column solve (its group and column arrays, its forces and lengths are read).
    single_group : ndarray of bool, shape [n_groups]
        Groups that are their column's only group (driven at the grip strain).
    """

    def __init__(self, columns: DeviceColumnSolve, single_group: np.ndarray):
        from ..kernels import column_trials as kct
        self.k = kct
        self.columns = columns
        dev = self.device = columns.device
        n, n_cls = len(single_group), columns.n_cls
        self.n = n
        g = lambda dtype=wp.float64: wp.zeros(n, dtype=dtype, device=dev)  # noqa: E731
        k = lambda dtype=wp.float64: wp.zeros(n_cls, dtype=dtype, device=dev)  # noqa: E731
        self.single = wp.array(np.asarray(single_group, dtype=np.int32), dtype=wp.int32, device=dev)
        book = kct.TrialBookArrays()
        book.C_last, book.F_last, book.good_hi, book.good_lo, book.fail_hi, book.fail_lo = (g() for _ in range(6))
        book.dir_min, book.dir_max, book.k = g(), g(), g()
        self.book = book
        self.stick, self.committed_strain, self.u_single = g(wp.int32), g(), g()
        self.kt, self.slide_C, self.slide_F, self.k_c = g(), g(), g(), g()
        self.live, self.col_stalled, self.jumped = k(wp.int32), k(wp.int32), k(wp.int32)
        self.F_col = k()
        self.F_max, self.F_min, self.force_gap = k(), k(), k()
        self.failed, self.capped = k(wp.int32), k(wp.int32)
        self.sum_n_pF, self.sum_np_F, self.sum_n_dC = k(), k(), k()
        self.all_live, self.monotone = k(wp.int32), k(wp.int32)
        self.all_live.fill_(1)
        # the last committed point of each branch (force, 1 / tangent, stage, jammed) and its direction (None: none)
        self.hist_F, self.hist_kinv, self.hist_stage, self.hist_jammed = g(), g(), g(wp.int32), g(wp.int32)
        self.hist_direction = None

    def _put(self, dst: wp.array, a) -> wp.array:
        """``a`` itself where it is a device array, else its values copied into ``dst``."""
        if isinstance(a, wp.array):
            return a
        dst.assign(np.ascontiguousarray(a, dtype=np.int32 if dst.dtype == wp.int32 else np.float64))
        return dst

    def _columns(self, reads: tuple, live: wp.array, status_ok: int, status_cap: int) -> dict:
        """``column_reads_kernel`` on the packed states ``reads`` of the columns in ``live``: host arrays
        [n_columns] ``F_max``, ``F_min`` of p F [N], ``failed`` (a status not ok), ``capped``, the sums ``n_pF``
        of n (p F), ``np_F`` of (n p) F [N] and ``n_dC`` of n (C - C0) [mm]."""
        c = self.columns
        wp.launch(self.k.column_reads_kernel, dim=c.n_cls, device=self.device,
                  inputs=[c.col_start, c.col_groups, live, c.cnt, c.C0, c.p, reads[0], reads[1], int(status_ok),
                          int(status_cap), c.F],
                  outputs=[self.F_max, self.F_min, self.failed, self.capped, self.sum_n_pF, self.sum_np_F,
                           self.sum_n_dC, self.force_gap])
        return {"F_max": self.F_max.numpy().copy(), "F_min": self.F_min.numpy().copy(),
                "failed": self.failed.numpy() != 0, "capped": self.capped.numpy() != 0,
                "n_pF": self.sum_n_pF.numpy().copy(), "np_F": self.sum_np_F.numpy().copy(),
                "n_dC": self.sum_n_dC.numpy().copy()}

    def committed_columns(self, reads: tuple, status_ok: int, status_cap: int) -> dict:
        """Of each column's committed state (``reads``: its packed read on the device): :meth:`_columns` of every
        column, ``failed`` named ``stopped`` (``PatchSolver._committed_columns``)."""
        out = self._columns(reads, self.all_live, status_ok, status_cap)
        out["stopped"] = out.pop("failed")
        return out

    def branch_curvature(self, pts: DeviceBranchPoints, reads: tuple, k_c: np.ndarray, direction: int,
                         history: bool) -> None:
        """Each group's branch curvature (``branch_curvature_kernel``) written into the model ``pts`` (its
        ``curvature``), from the committed state ``reads`` (its packed read), the tangents ``k_c`` (kept in
        :attr:`k_c` for :meth:`begin`) and the point kept at the last increment's start in the same direction;
        without ``history`` (a sub-increment) none (NaN), and that point is kept, else this one is."""
        use = history and self.hist_direction is not None and self.hist_direction == int(direction)
        self._put(self.k_c, k_c)
        wp.launch(self.k.branch_curvature_kernel, dim=self.n, device=self.device,
                  inputs=[self.k_c, reads[0], reads[1], int(use), int(bool(history)), self.hist_F, self.hist_kinv,
                          self.hist_stage, self.hist_jammed, pts.k_min, pts.k_max],
                  outputs=[pts.b.curvature])
        pts.curvature_on_device()
        if history:
            self.hist_direction = int(direction)

    def branch_history(self) -> tuple | None:
        """The kept points as ``PatchSolver``'s NumPy twin keeps them (F, 1 / k, stage, jammed, direction; host
        copies), for a checkpoint; None where none is kept."""
        if self.hist_direction is None:
            return None
        return (self.hist_F.numpy().copy(), self.hist_kinv.numpy().copy(), self.hist_stage.numpy().copy(),
                self.hist_jammed.numpy().copy(), self.hist_direction)

    def set_branch_history(self, hist: tuple | None) -> None:
        """Restore :meth:`branch_history` (or the NumPy twin's) from a checkpoint."""
        if hist is None:
            self.hist_direction = None
            return
        F, kinv, stage, jammed, direction = hist
        self.hist_F.assign(np.ascontiguousarray(F, dtype=np.float64))
        self.hist_kinv.assign(np.ascontiguousarray(kinv, dtype=np.float64))
        self.hist_stage.assign(np.ascontiguousarray(stage, dtype=np.int32))
        self.hist_jammed.assign(np.ascontiguousarray(jammed, dtype=np.int32))
        self.hist_direction = int(direction)

    def begin(self, pts: DeviceBranchPoints, reads: tuple, k_c: np.ndarray, k: np.ndarray, F_col: np.ndarray,
              monotone: np.ndarray, direction: int, u_single: np.ndarray, sf_stages: tuple) -> None:
        """Start the trials of an increment from the committed state (``reads``: its packed read on the
        device; ``begin_trials_kernel``): its point with the tangent ``k_c`` at the column force per wale
        ``F_col / p``, the direction's bounds where the column is ``monotone``, the last good trial and the
        good lengths the committed ones, no failure yet; the fallback tangents ``k``.  The model's bounds and
        stall state are kept here from now on (``pts.host_state`` off)."""
        bk, b, c = self.book, pts.b, self.columns
        self._put(self.k_c, k_c)
        self._put(self.F_col, F_col)
        self._put(self.monotone, monotone)
        self._put(bk.k, k)
        self._put(self.u_single, u_single)
        wp.launch(self.k.begin_trials_kernel, dim=self.n, device=self.device,
                  inputs=[b, bk, c.col, c.p, c.C0, reads[0], reads[1], self.k_c, self.F_col, self.monotone,
                          int(direction), int(sf_stages[0]), int(sf_stages[1])],
                  outputs=[self.committed_strain, self.stick])
        b.stall.zero_()
        b.side.zero_()
        pts.host_state = False

    def set_strain(self, live: np.ndarray, strain: wp.array) -> None:
        """Each group's trial strain (``trial_strain_kernel``) into ``strain``, from the lengths of the last
        column solve."""
        self._put(self.live, live)
        c = self.columns
        wp.launch(self.k.trial_strain_kernel, dim=self.n, device=self.device,
                  inputs=[c.col, self.live, self.single, self.u_single, c.C, c.C0, self.committed_strain],
                  outputs=[strain])

    def jumped_columns(self, pts: DeviceBranchPoints, force_tol: float, force_rtol: float) -> np.ndarray:
        """Columns with a prepared group whose force jumps across its column's (``BranchPoints.jump``)."""
        self.jumped.zero_()
        c = self.columns
        if pts.rows.size:
            wp.launch(self.k.column_jump_kernel, dim=pts.rows.size, device=self.device,
                      inputs=[pts.b, pts._rows_dev, c.col, c.p, c.F, float(force_tol), float(force_rtol)],
                      outputs=[self.jumped])
        return self.jumped.numpy().astype(bool)

    def judge(self, reads: tuple, live: np.ndarray, status_ok: int, status_cap: int) -> dict:
        """Each live column's trial (``reads``: its packed read): :meth:`_columns` of the columns in ``live``
        (meaningful there), and each one's largest force gap of a good cell kept for :meth:`book_trial`."""
        return self._columns(reads, self._put(self.live, live), status_ok, status_cap)

    def book_trial(self, pts: DeviceBranchPoints, reads: tuple, live: np.ndarray, kt, slide_C, slide_F,
                   F_col: np.ndarray, col_stalled: np.ndarray, force_tol: float, force_rtol: float, direction: int,
                   status_ok: int, stage_slack: int) -> None:
        """One trial's bookkeeping of every group (``trial_book_kernel``), after :meth:`judge`; ``kt`` (the
        trial tangents) and the slide onsets ``slide_C``, ``slide_F`` as host or device arrays [n_groups]."""
        live_d, F_col_d, stalled_d = (self._put(d, a) for d, a in ((self.live, live), (self.F_col, F_col),
                                                                  (self.col_stalled, col_stalled)))
        kt_d, sC_d, sF_d = (self._put(d, a) for d, a in ((self.kt, kt), (self.slide_C, slide_C),
                                                         (self.slide_F, slide_F)))
        c = self.columns
        wp.launch(self.k.trial_book_kernel, dim=self.n, device=self.device,
                  inputs=[pts.b, self.book, c.col, live_d, self.single, self.stick, c.p, c.C0, reads[0], reads[1],
                          int(status_ok), int(stage_slack), kt_d, sC_d, sF_d, c.C, c.F, F_col_d, stalled_d,
                          self.force_gap, float(force_tol), float(force_rtol), int(direction)])

    def fallback_tangents(self) -> np.ndarray:
        """Each group's fallback tangent dF/dC [N/mm] after the trials (host copy)."""
        return self.book.k.numpy().copy()
