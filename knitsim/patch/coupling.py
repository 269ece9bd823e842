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
launch per trial, on the cells of the columns not yet converged: a cell's step
reads only its own rows): the unknowns are the cells' course lengths C_g (one per
group of identical cells, :meth:`~knitsim.patch.model.PatchModel.grouping`,
counted n_g times).  Each cell answers a trial step of the cell solver from
its committed state to C_g (``CellSolver.step`` on the committed state does
not modify it), giving f_g(C_g) along its own path-dependent branch (Table 4
stages, events, hysteresis).

*The column as a scalar problem in its force.*  Within one increment every
cell's branch is monotone: on a stable branch the force never falls as the
length grows (a stick branch is stiff, a sliding one a plateau with
df/dC ~ 0, a slack cell has f = 0 over a range of C, a jammed one stiffens), so
its inverse C_g(f) is a monotone (non-decreasing) function, flat where the cell
is stiff and steep on a plateau.  The column's equilibrium is one equation in
its total force F::

    Phi(F) = sum_g n_g (C_g(F / p_g) - C0_g) - u = 0,        F >= 0,

with Phi monotone in F: one root, or none with F > 0 when Phi(0) >= 0 (the
column is slack: F = 0, and the grips leave ``-Phi(0)`` over).  C_g(f) is not
known in closed form; every trial adds one exact point (C, f) of each cell's
branch and its slope k = df/dC there (the cell's own tangent from the Jacobian
of its converged Newton, implicit function theorem,
:mod:`knitsim.kernels.cell_tangent`; NaN where undefined: Dahl, effects, the
reference engine, slack).  :class:`BranchPoints` keeps these points (the committed
state is the first, with the tangent of the stage a reversal enters) and builds
from them a monotone model Cm_g(f) that passes through every point:

- between two neighbouring points (sorted by force) the tangent lines of both
  ends, their upper envelope where the slopes dC/df grow across the interval
  (C(f) convex there: a stick cell that starts to slide), their lower envelope
  where they fall (concave: a cell that jams), the chord where the tangents
  contradict the chord;
- beyond the lowest and highest points, the tangent line of the end point
  (else the secant of the two end points, else the last increment's tangent),
  bent by the branch's curvature d2C/df2 where it is known and smooth (from the
  tangents of the two end points when their slopes agree within a factor 1.5,
  else, with one point, from the cell's last two committed states on the same
  stage and direction), its slope kept within [s/4, 4 s] of the tangent's s: a
  second-order predictor, so that a column's first trial lands ~100x closer
  (median spread after it on a 23 x 10 random patch: 2,300 -> 14 times the
  tolerance);
- points that contradict monotonicity (a later trial at a longer length with a
  lower force) are dropped, the newer kept; of the zero-force (slack) points
  only the longest.

The column force of the next trial is the root of the model Phi-hat(F) (safeguarded
Newton on the monotone scalar function, bisection where the Newton step leaves
the bracket), and each cell is sent to Cm_g(F / p_g): the lengths add up to u
(where the model has a step, the lengths between the bracket's ends that add
up to u).  This is Newton's method on the column's equations where every cell's
tangent line at its latest point is the active piece, and it keeps a bracket:
since Cm_g interpolates monotonically, a trial whose lengths add up to u has
``min_g F_g <= F* <= max_g F_g`` and the model's next root stays inside every
such bracket (while its points are kept), so a plateau cell (dC/df huge) can no longer be sent the wrong
way: it is only asked for lengths between its known points or along its own
tangent.  Where a cell's trials keep landing on one side of the column's force
without closing the gap fourfold (a tangent that misleads across a kink, a
one-sided regula falsi) its model bisects its bracket in C instead (Illinois /
bisection fallback), or, outside its points, doubles its extrapolation slope
until its trials straddle the force.

*Slack.*  A column with Phi-hat(0) >= 0 is asked for zero force: each cell is
driven just past its zero-force point (where the cell solver locates its slack
event and keeps its slack length); the column converges when no cell carries
force (slack, or out of slack at F = 0 to rounding).

*Direction.*  When the committed state is an equilibrium (equal forces), no
cell of the solution moves against the increment (the column force follows
the grips and every cell's length follows its force): the model's lengths are
kept on the increment's side of the committed ones.  Not so at the rest state
(the cells' rest forces differ) nor after a flagged increment.

*Failed trials, sub-increments.*  A cell whose trial fails at a length (its
solver stops: no convergence over one long step) bounds its model halfway
between that length and its nearest good trial (bisection towards the
failure).  A trial from the committed state may fail where shorter steps do
not (on SF- near R = 0, benchmarks/README.md, "Where the patch's time goes", cause 1): a
column that has not converged after its trials (or after 8 of them when a cell
of it failed in the last) is taken back to its committed state and brought to u in
``sub_increments`` equal sub-increments, each solved and committed in turn.
A cell whose force jumps across the column's force within 1e-11 C0 (a
discontinuity no column force meets) stops its column early.

*Scales.*  The coupling's absolute tolerances and bounds (``force_tol``, the
tangent bounds, the force search's start and ceiling) are stated for the usual
knits and taken to a patch's own force scale B / d^2 and course length C0 by
powers of two (:class:`CouplingScale`: 1 for the usual knits), so that a patch
of B times k solves as the patch itself, its forces times k.

A column converges when its cells' forces agree to ``force_tol + force_rtol
|F|``; converged columns are committed, the others iterate up to
``max_iterations`` trials and are then committed as they stand and flagged
(unless a cell failed in the last trial: the column then keeps its state).  A
cell that stops (force cap, no convergence) stops its column: the column keeps
its last state and is flagged.

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

from ..cell.history import STATUS_FORCE_CAP, STATUS_OK
from ..cell.quantities import CODE
from ..cell.stages import MAX_HALVINGS, Stage
from ..errors import KnitsimInputError
from ..io.checks import FORCE_CAP_RTOL
from ..kernels.branch_points import COLUMN_FORCE_MAX, COLUMN_FORCE_START, JUMP_RTOL, TANGENT_MAX, TANGENT_MIN
from ..kernels.branch_points import SIZE as DEVICE_BRANCH_SIZE
from .model import Grouping

#: bounds of the tangent dF/dC of a cell [N/mm] (those of the device's branch model, one place), at the usual
#: knits' scales (a patch far from them: times its CouplingScale.tangent)
K_MIN, K_MAX = TANGENT_MIN, TANGENT_MAX
#: a column carrying force closes when its lengths add up to the grip displacement within this share of its rest
#: length (rounding: the trial lengths are sent to add up to it exactly)
LENGTH_RTOL = 1e-9
#: largest column force [N] the scalar search of a column's force grows its bracket to, and its first guess where
#: it has no lower bound yet, at the usual knits' scale (a patch far from it: times its CouplingScale.force)
FORCE_SEARCH_MAX, FORCE_SEARCH_START = COLUMN_FORCE_MAX, COLUMN_FORCE_START
#: the tangent dF/dC [N/mm] a cell starts from where its first probe gives none, at the usual knits' scales
#: (times CouplingScale.tangent)
PROBE_TANGENT_FALLBACK = 1.0
#: the force scale B / d^2 [N] and the course length C0 [mm] about which the coupling's absolute tolerances and
#: bounds (force_tol, K_MIN .. K_MAX, the force search's start and ceiling) are stated, and the powers of two
#: either side of them over which a patch keeps them as they are (CouplingScale): B / d^2 from 0.011 to 5.7 N,
#: C0 from 0.35 to 11 mm.  The force band's low end keeps the default force_tol (1e-10 N) at most force_rtol
#: (1e-8) of the force scale (0.01 N); it holds every bundled scene and material (B / d^2 0.048 N, a do2020
#: specimen's own yarn, to 0.92 N, Dusserre's E-glass), 4x inside its ends.  The length band holds the cell
#: domain's course lengths (C0 / d 4 .. 5.2 at d 0.1 .. 2 mm: knitsim.cell.domain) and the bundled 0.88 .. 2.7 mm
FORCE_SCALE_REF, FORCE_SCALE_BAND = 0.25, 4
LENGTH_SCALE_REF, LENGTH_SCALE_BAND = 2.0, 2
#: column flags
COL_OK, COL_NOT_CONVERGED, COL_STOPPED = 0, 1, 2
COLUMN_STATUS_NAMES = {COL_OK: "ok", COL_NOT_CONVERGED: "not_converged", COL_STOPPED: "stopped"}
#: a column that failed to converge in this many loading increments in a row is not tried again until the grip
#: turns: it holds its state, flagged (a blind probe's 2 x 4 patch pulled past its jammed branch's reach spent
#: 2.4 s on each of its last 42 increments retrying two columns that never converged again)
HELD_RETRIES = 3
#: halvings of the grip displacement by which a column that cannot pass a cell's force cap is brought to it
#: (PatchSolver._approach_force_cap): 2^-20 of an increment
CAP_BISECTIONS = 20


# ===================================================================== the patch's scales
def power_of_two_scale(value: float, ref: float, band: int) -> float:
    """2^n, n = round(log2(value / ref)) brought ``band`` towards 0 (0 while |n| <= band): 1 for a value within
    2^(band + 1/2) of ``ref``, else the power of two nearest to value / edge, the edge ``ref`` 2^+-band on the
    value's side (1 for a value that is not finite and positive)."""
    if not (np.isfinite(value) and value > 0.0):
        return 1.0
    n = int(round(float(np.log2(value / ref))))
    n = (1 if n > 0 else -1) * max(abs(n) - int(band), 0)
    return float(np.ldexp(1.0, n))


def _weighted_median(values: np.ndarray, weights: np.ndarray) -> float:
    """The lower weighted median: the least value whose weights with the smaller ones' reach half the total."""
    order = np.argsort(values, kind="stable")
    cum = np.cumsum(np.asarray(weights, dtype=np.float64)[order])
    return float(np.asarray(values)[order][min(int(np.searchsorted(cum, 0.5 * cum[-1])), len(order) - 1)])


@dataclass(frozen=True)
class CouplingScale:
    """The factors that take the coupling's absolute tolerances and bounds to a patch's own scales.

    A patch of B times k and every length times s is the same patch, its forces times k / s^2
    (``tests/patch/test_patch_invariances.py``, module docstring); the coupling's relative tolerances follow,
    its absolute ones do not: ``force_tol`` (a column at zero force, the agreement of its forces near it), the
    tangent bounds K_MIN .. K_MAX [N/mm] and the force search's start and ceiling [N].  At B / d^2 = 9e-7 N the
    force_tol of 1e-10 N was 1e-4 of the force scale, and the grip force near the slack 7.7 % off the patch
    scaled.  Those are stated for the usual knits and taken to a patch's own scale by

    - sigma_F (``force``): :func:`power_of_two_scale` of the median B / d^2 of the patch's stitches [N]
      about :data:`FORCE_SCALE_REF` (times force_tol and the force search's start and ceiling);
    - sigma_L (``length``): that of their median C0 [mm] about :data:`LENGTH_SCALE_REF`;
    - sigma_F / sigma_L (``tangent``): times the tangent bounds (a tangent is a force over a length).

    Powers of two: a quantity times one only moves its exponent (exact), so a factor 1 leaves the constants'
    bits as they were, and two patches beyond a band on the same side, one with 2^n times the other's B, get
    tolerances exactly 2^n apart.  Within the bands (:data:`FORCE_SCALE_BAND`, :data:`LENGTH_SCALE_BAND` powers
    of two either side of the references) both factors are 1: every bundled scene and material is inside and
    solves bit for bit as before the scales were introduced (rounding to the nearest power of two alone could
    not do that: their B / d^2 span a factor 19, their C0 a factor 3).  Beyond the bands the absolute tolerances
    keep the weight, relative to the patch's forces, that they have at the band's nearer end (within sqrt 2): at
    most ~9e-9 of B / d^2 for force_tol (1.1e-10 for E-glass).

    One scale per patch, not per cell or column: the kernels take one set of scalars, and a column's tolerance
    meets the forces of all of its cells.  The usual mixed patches (E-glass beside basalt, B / d^2 0.92 and
    0.64 N) lie well inside one band; a patch whose columns differ in force scale by more than the band's width
    (2^9) solves all of them with its median stitch's tolerances, off the scale of a column far from that median
    as the constants in newtons were off a patch's.

    Attributes
    ----------
    force, length : float
        sigma_F and sigma_L (powers of two; 1 for the usual knits).
    force_scale, length_scale : float
        The medians they were taken from: B / d^2 [N] and C0 [mm] of the patch's stitches (NaN: none given).
    """

    force: float = 1.0
    length: float = 1.0
    force_scale: float = float("nan")
    length_scale: float = float("nan")

    @property
    def tangent(self) -> float:
        """sigma_F / sigma_L: the factor of a tangent dF/dC (a power of two)."""
        return self.force / self.length

    @classmethod
    def of(cls, grouping: "Grouping") -> "CouplingScale":
        """The scales of a patch's groups: the medians over its stitches (each group weighted by the stitches it
        stands for: its courses in series, its wales in parallel and the columns of its class, so that a patch
        gives the same scale grouped or cell by cell)."""
        c = grouping.cells
        B, d, C0 = (np.asarray(c[n], dtype=np.float64) for n in ("B", "d", "C0"))
        if B.size == 0:
            return cls()
        columns = np.bincount(grouping.column_class, minlength=grouping.n_classes)[grouping.group_column]
        w = np.asarray(grouping.group_count, np.float64) * np.asarray(grouping.group_wales, np.float64) * columns
        F_s, L_s = _weighted_median(B / (d * d), w), _weighted_median(C0, w)
        return cls(power_of_two_scale(F_s, FORCE_SCALE_REF, FORCE_SCALE_BAND),
                   power_of_two_scale(L_s, LENGTH_SCALE_REF, LENGTH_SCALE_BAND), F_s, L_s)


# ===================================================================== backends
class WarpBackend:
    """Trial steps of all groups in one launch of the batched cell kernel (:mod:`knitsim.cell.batch`).

    A backend of the coupling: ``committed``, ``trial``, ``tangent``, ``begin_increment``, ``accept``,
    ``end_increment`` (and ``get_state`` / ``set_state``).  With ``partial_trials`` its ``trial`` and
    ``tangent`` take a ``mask`` of the groups to step (the others are neither stepped nor read)."""

    partial_trials = True

    def __init__(self, grouping: "Grouping | list", device: str = "cpu", max_halvings: int = MAX_HALVINGS):
        from .. import warp_runtime
        warp_runtime.init()
        import warp as wp

        from ..cell.batch import CellBatchState, CellModel, CellSolver
        from ..kernels.cell_step import EV_RELOAD, EV_REVERSAL, EV_SLIDE
        self.wp = wp
        self._ev_slide, self._ev_reversal, self._ev_reload = EV_SLIDE, EV_REVERSAL, EV_RELOAD
        if isinstance(grouping, (list, tuple)):   # a CellParams per trial cell
            self.model = CellModel.from_params(grouping, device)
            c = {"C0": [p.C0 for p in grouping]}
        else:
            # from the groups' arrays (validated vectorised; an error names the patch cell), not from a
            # CellParams per group: 10^6 cells in a second, not minutes
            c = grouping.cells
            self.model = CellModel.from_arrays(
                c["B"], c["d"], c["L"], c["W0"], c["C0"], c["m"], c["phi0"], friction=c["friction"],
                dahl_sigma=c["dahl_sigma"], unloading_rule=c["unloading_rule"], reload_rule=c["reload_rule"],
                jamming_criterion=c["jamming_criterion"], force_cap_N=np.asarray(c["force_cap_N"], dtype=np.float64),
                in_plane_width=c["in_plane_width"], effects=c["effects"], device=device, where=grouping.where)
        self.device = self.model.device
        self.n = self.model.cell_count
        self.solver = CellSolver(self.model, max_halvings)
        self.C0 = np.asarray(c["C0"], dtype=np.float64)
        self.s0 = self.model.state()
        self.s1 = CellBatchState.empty(self.n, self.device)
        self.res = CellBatchState.empty(self.n, self.device)
        self.control = self.model.control()
        self.control.strain = wp.zeros(self.n, dtype=wp.float64, device=self.device)
        # the cells whose trial row (s1) is a converged trial of this increment that fired no event and kept
        # the committed stage: their next trial's Newton starts from it (CellControl.warm)
        self.control.warm = wp.zeros(self.n, dtype=wp.int32, device=self.device)
        self._warm = np.zeros(self.n, bool)
        self._committed_branch = None            # the committed (stage, jammed), read once per increment
        self._mask = wp.zeros(self.n, dtype=wp.int32, device=self.device)
        self._all = wp.ones(self.n, dtype=wp.int32, device=self.device)
        self._k = wp.zeros(self.n, dtype=wp.float64, device=self.device)
        # the trial step's own slopes dF/dC (from its last Newton's Jacobian: CellSolver.step's slope_out)
        self._slope = wp.zeros(self.n, dtype=wp.float64, device=self.device)
        self._k_step = np.full(self.n, np.nan)
        self._status = wp.zeros(self.n, dtype=wp.int32, device=self.device)
        # imported once (an import inside the per-trial call cost ~0.3 ms a call)
        from ..kernels.cell_arrays import select_state_kernel
        from ..kernels.cell_tangent import branch_tangent_kernel
        self._tangent_kernel = branch_tangent_kernel
        self._select_kernel = select_state_kernel
        from ..kernels import state_read
        self._state_read = state_read
        self._read_dev = self._read_host = None     # the packed read's buffers, made on the first read
        # tangents known at the trial (1), committed (0) and result (r) states, and where they are known
        self._k1, self._k0, self._kr = (np.full(self.n, np.nan) for _ in range(3))
        self._k1_ok, self._k0_ok, self._kr_ok = (np.zeros(self.n, bool) for _ in range(3))
        #: the device mode's result tangents (kr) hold the committed ones (_k0): begin_increment sends none
        self._kr_on_device = False
        #: the trials' slide onsets, warm starts and tangents kept on the device (:mod:`knitsim.kernels.
        #: backend_trials`; set once, before the first trial, by a coupling whose bookkeeping runs there):
        #: ``trial`` then reads only each cell's stage, jammed flag and status to the host and
        #: ``tangent(True)`` gives a device array
        self.device_trials = False
        self._dev = None

    def _device_arrays(self):
        """The device mode's arrays (made on first use): the trial tangents k1 and the results' kr (with
        their flags), the slide onsets, each cell's last event, the masks and the launched tangents."""
        if self._dev is None:
            from types import SimpleNamespace

            from ..kernels import backend_trials
            wp, n, dev = self.wp, self.n, self.device
            f = lambda: wp.zeros(n, dtype=wp.float64, device=dev)  # noqa: E731
            i = lambda: wp.zeros(n, dtype=wp.int32, device=dev)  # noqa: E731
            self._dev = SimpleNamespace(
                k=backend_trials, k1=wp.array(self._k1, dtype=wp.float64, device=dev),
                k1_ok=wp.array(self._k1_ok.astype(np.int32), dtype=wp.int32, device=dev), kr=f(), kr_ok=i(),
                kt=f(), slide_C=f(), slide_F=f(), last=i(), entered=i(), other=i(), stepped=i(), use=i(),
                masked_status=i(), count=wp.zeros(1, dtype=wp.int32, device=dev))
        return self._dev

    def _pack(self, st) -> tuple:
        """State ``st`` packed on the device (:mod:`knitsim.kernels.state_read`): the device arrays (reals,
        integers), also :attr:`last_read`."""
        wp, sr = self.wp, self._state_read
        if self._read_dev is None:
            n, dev = self.n, self.device
            self._read_dev = (wp.empty((sr.N_READ_REALS, n), dtype=wp.float64, device=dev),
                              wp.empty((sr.N_READ_INTS, n), dtype=wp.int32, device=dev))
            on_host = wp.get_device(dev).is_cpu
            self._read_host = self._read_dev if on_host else (
                wp.empty((sr.N_READ_REALS, n), dtype=wp.float64, device="cpu", pinned=True),
                wp.empty((sr.N_READ_INTS, n), dtype=wp.int32, device="cpu", pinned=True),
                wp.empty((n, 5), dtype=wp.float64, device="cpu", pinned=True))
        wp.launch(sr.pack_state_read_kernel, dim=self.n,
                  inputs=[st.arrays(), CODE["F"], CODE["phi"], CODE["W"], CODE["s_AB"], int(Stage.SLACK)],
                  outputs=list(self._read_dev), device=self.device)
        return self._read_dev

    def packed_committed(self) -> tuple:
        """The committed states packed on the device (reals, integers; :mod:`knitsim.kernels.state_read`),
        not copied to the host."""
        return self._pack(self.s0)

    def _read(self, st) -> dict:
        """C, F (0 while slack), phi, W, stage, jammed, status and head gap of every group of state ``st``, and
        its state vector x [n, 5] and s_AB: packed on the device and copied through pinned host buffers
        (:mod:`knitsim.kernels.state_read`)."""
        wp, sr = self.wp, self._state_read
        reals, ints = self._pack(st)
        on_host = self._read_host is self._read_dev
        if not on_host:
            wp.copy(self._read_host[0], reals)
            wp.copy(self._read_host[1], ints)
            wp.copy(self._read_host[2], st.x)
            wp.synchronize_device(self.device)
        # field-major: each quantity's copy out of the (reused) buffers is one contiguous block
        r, k = self._read_host[0].numpy(), self._read_host[1].numpy()
        return {"C": r[sr.READ_C].copy(), "F": r[sr.READ_F].copy(), "phi": r[sr.READ_PHI].copy(),
                "W": r[sr.READ_W].copy(), "stage": k[sr.READ_STAGE].copy(), "jammed": k[sr.READ_JAMMED].copy(),
                "status": k[sr.READ_STATUS].copy(), "head_gap": r[sr.READ_GAP].copy(),
                "x": (st.x if on_host else self._read_host[2]).numpy().copy(), "s_AB": r[sr.READ_S_AB].copy()}

    @property
    def last_read(self) -> tuple:
        """The device arrays (reals, integers) of the last state read (:mod:`knitsim.kernels.state_read`): a
        trial's, until the committed states are read."""
        return self._read_dev

    def committed(self) -> dict:
        """Each group's committed state, arrays of shape [n]: ``C`` [mm], ``F`` [N] (0 while slack),
        ``phi`` [rad], ``W`` [mm], ``stage``, ``jammed``, ``status`` and ``head_gap`` [mm], and its state
        vector ``x`` [n, 5] and ``s_AB`` [mm]."""
        return self._read(self.s0)

    def _tangent_launch(self, st, dir_new: int, mask: np.ndarray | None) -> np.ndarray:
        """The tangent kernel on the states ``st`` (of the groups in ``mask``; NaN elsewhere)."""
        state = st.arrays()
        if mask is not None and not np.all(mask):
            # the kernel gives NaN, after reading the cell's parameters only, where a state is not ok:
            # the groups outside the mask are passed a status that is not (the states are not changed)
            status = np.where(mask, st.status.numpy(), STATUS_OK + 1).astype(np.int32)
            self._status.assign(status)
            state.status = self._status
        self.wp.launch(self._tangent_kernel, dim=self.n, inputs=[self.model.arrays(), state, dir_new],
                       outputs=[self._k], device=self.device)
        return self._k.numpy().copy()

    def tangent(self, trial: bool, direction: int = 0, mask: np.ndarray | None = None) -> np.ndarray:
        """dF/dC of every group on its branch (:mod:`knitsim.kernels.cell_tangent`; NaN where undefined),
        at the last trial's states (``trial``) or at the committed ones, there of the stage that a
        reversal to ``direction`` enters; with ``mask``, of those groups only (NaN elsewhere).

        The tangents of the trial states are kept: a committed state that is an accepted trial has
        the tangent computed at that trial (the same kernel on the same state row; the direction only
        matters where it reverses the state's own), so only the others are launched.  At a trial, the
        cells whose step gave its slope (``CellSolver.step``'s ``slope_out``: the same formula, from the
        Jacobian of the step's last solve, or of a warm short step's start, O(1e-6) in the Newton
        variables away) are not launched either."""
        if trial and self.device_trials:
            return self._trial_tangent_on_device(mask)
        if trial:
            have = np.ones(self.n, bool) if mask is None else np.asarray(mask, bool)
            # the trial step gave the slope of the cells whose last solve converged on their stage without an
            # event (the same formula, from that solve's Jacobian): only the others are launched
            known = have & np.isfinite(self._k_step)
            k = self._k_step if np.all(known[have]) else np.where(
                known, self._k_step, self._tangent_launch(self.s1, 0, have & ~known))
            k = np.where(have, k, np.nan)
            self._k1 = np.where(have, k, self._k1)
            self._k1_ok |= have
            return k
        out = np.where(self._k0_ok, self._k0, np.nan)
        need = ~(self._k0_ok & (self.s0.direction.numpy() == int(direction)))
        if mask is not None:
            need &= mask
        if np.any(need):
            k = self._tangent_launch(self.s0, int(direction), need)
            out = np.where(need, k, out)
        if mask is not None:
            out = np.where(mask, out, np.nan)
        return out

    def good_trials(self) -> int:
        """The device mode's count of the last trial's stepped cells that it left ok (status ok), marked on the
        device as those whose tangents :meth:`good_trial_tangents` gives: the coupling's ``mask & (status ==
        ok)`` without reading the statuses to the host."""
        wp, d = self.wp, self._device_arrays()
        d.count.zero_()
        wp.launch(d.k.good_trials_kernel, dim=self.n, device=self.device,
                  inputs=[d.stepped, self.s1.status, STATUS_OK], outputs=[d.use, d.count])
        return int(d.count.numpy()[0])

    def good_trial_tangents(self) -> "wp.array":
        """``tangent(True, mask=good)`` in the device mode, for the cells :meth:`good_trials` marked."""
        return self._trial_tangent_on_device(None, marked=True)

    def _trial_tangent_on_device(self, mask: np.ndarray | None, marked: bool = False) -> "wp.array":
        """``tangent(True, mask=mask)`` in the device mode: the device array of the trial tangents (NaN
        outside ``mask``; ``marked``: outside the cells :meth:`good_trials` marked), kept as :meth:`tangent`'s
        NumPy lines keep them."""
        wp, d = self.wp, self._device_arrays()
        if not marked:
            d.use.assign((np.ones(self.n, bool) if mask is None else np.asarray(mask, bool)).astype(np.int32))
        d.count.zero_()
        wp.launch(d.k.tangent_need_kernel, dim=self.n, device=self.device,
                  inputs=[d.use, self._slope, self.s1.status, STATUS_OK + 1], outputs=[d.masked_status, d.count])
        launched = int(d.count.numpy()[0]) > 0
        if launched:
            state = self.s1.arrays()
            state.status = d.masked_status
            wp.launch(self._tangent_kernel, dim=self.n, inputs=[self.model.arrays(), state, 0], outputs=[self._k],
                      device=self.device)
        wp.launch(d.k.trial_tangent_kernel, dim=self.n, device=self.device,
                  inputs=[d.use, self._slope, self._k, int(launched)], outputs=[d.kt, d.k1, d.k1_ok])
        return d.kt

    def trial_state(self) -> dict:
        """The last trial's states as :meth:`committed` gives the committed ones (in the device mode
        :meth:`trial` returns stage, jammed and status only)."""
        return self._read(self.s1)

    @property
    def slide_onsets(self) -> tuple:
        """The device mode's slide onsets (C, F) of the last trial (device arrays; NaN: none)."""
        d = self._device_arrays()
        return d.slide_C, d.slide_F

    def _trial_reads_on_device(self, mask: np.ndarray | None) -> None:
        """The device mode's slide onsets, warm starts and forgotten trial tangents of a trial (the NumPy
        lines of :meth:`trial`, one thread per cell)."""
        wp, d = self.wp, self._device_arrays()
        d.stepped.assign((np.ones(self.n, bool) if mask is None else np.asarray(mask, bool)).astype(np.int32))
        d.last.fill_(-1)
        d.entered.zero_()
        d.other.zero_()
        n_ev, cap = self.solver.event_counts()
        if n_ev > cap:
            raise RuntimeError(f"event buffer overflow: {n_ev} events, capacity {cap}")
        ev = self.solver._ev
        if n_ev:
            wp.launch(d.k.last_events_kernel, dim=n_ev, device=self.device,
                      inputs=[ev[0], ev[2], self._ev_reversal, self._ev_reload], outputs=[d.last, d.entered, d.other])
        wp.launch(d.k.trial_reads_kernel, dim=self.n, device=self.device,
                  inputs=[self.s1.arrays(), self.s0.arrays(), d.stepped, d.last, d.entered, d.other, ev[2], ev[3],
                          ev[4], self._ev_slide, int(Stage.SLACK), int(Stage.S_LOAD), int(Stage.S_UNLOAD), STATUS_OK],
                  outputs=[d.slide_C, d.slide_F, self.control.warm, d.k1_ok])

    def trial(self, strain: np.ndarray, direction: int, increment: int, mask: np.ndarray | None = None) -> dict:
        """Step every group (with ``mask``: those in it) from its committed state to ``C = C0 (1 + strain)``
        (``strain`` [n]: host values, or the device array ``control.strain`` written in place);
        the committed state is kept.  The trial rows of groups outside ``mask`` are those of their
        last trial (not read by the coupling).  Returns the trial's states as :meth:`committed` gives them,
        with the slide onsets it crossed (``slide_C``, ``slide_F``); in the device mode nothing (an empty
        dict): the coupling reads the trial on the device (:attr:`last_read`, :attr:`slide_onsets`,
        :meth:`good_trials`), and :meth:`trial_state` copies it."""
        if strain is not self.control.strain:        # (DeviceTrials.set_strain writes it in place)
            self.control.strain.assign(np.ascontiguousarray(strain, dtype=np.float64))
        self.control.direction.fill_(int(direction))
        if not self.device_trials:               # (the device mode keeps control.warm there)
            self.control.warm.assign(self._warm.astype(np.int32))
        # the trial steps' events are not used (stage and status are read from the states): the
        # append buffer is reset so that repeated trials never overflow it (CellSolver keeps no API for this)
        self.solver._ev_count.zero_()
        cells = None if mask is None or np.all(mask) else np.flatnonzero(mask).astype(np.int32)
        self.solver.step(self.s0, self.s1, self.control, increment, cells=cells, slope_out=self._slope)
        if self.device_trials:
            # the coupling judges and books the trial on the device (last_read, good_trials): nothing is copied
            self._trial_reads_on_device(mask)
            self._pack(self.s1)
            return {}
        self._k_step = self._slope.numpy().copy() if mask is None else np.where(mask, self._slope.numpy(), np.nan)
        self._k1_ok &= False if mask is None else ~np.asarray(mask, bool)
        t = self._read(self.s1)
        ev = self.solver.event_arrays()
        last = np.flatnonzero(np.r_[ev["cell"][1:] != ev["cell"][:-1], True]) if len(ev["cell"]) else np.zeros(0, int)
        t["slide_C"], t["slide_F"] = slide_points(self.n, ev["cell"][last], ev["kind"][last] == self._ev_slide,
                                                  ev["C"][last], ev["F"][last], t)
        if self._committed_branch is None:
            self._committed_branch = (self.s0.stage.numpy().copy(), self.s0.jammed.numpy().copy())
        stage0, jammed0 = self._committed_branch
        # warm next time: converged on the committed branch without an event, or on the branch that a reversal or
        # a reload at the increment's start enters (those events happen at the committed state: the next trial
        # makes them again and starts its solve on that branch from this end).  Not a trial that ended slack: a
        # slack end is no start for a solve (the reload seeds the contact first), and whether the next trial
        # reloads depends on the length it asks
        at_start = (ev["kind"] == self._ev_reversal) | (ev["kind"] == self._ev_reload)
        entered = np.zeros(self.n, bool)
        entered[ev["cell"][at_start]] = True
        same_branch = ((t["status"] == STATUS_OK) & ((t["stage"] == stage0) | entered) & (t["jammed"] == jammed0)
                       & (t["stage"] != int(Stage.SLACK)))
        same_branch[ev["cell"][~at_start]] = False
        self._warm = same_branch if mask is None else np.where(mask, same_branch, self._warm)
        return t

    def stop_at_force_cap(self, mask: np.ndarray) -> None:
        """Stop the groups in ``mask`` at their committed state, at their force cap: status force_cap, as a
        cell the step stopped there (:meth:`PatchSolver.step`: a column of unlike cells that cannot pass it)."""
        status = self.s0.status.numpy().copy()
        status[np.asarray(mask, bool)] = STATUS_FORCE_CAP
        self.s0.status.assign(status)

    def _select(self, mask, src, dst):
        self.wp.launch(self._select_kernel, dim=self.n, inputs=[mask, src.arrays(), dst.arrays()], device=self.device)

    def begin_increment(self) -> None:
        """Start an increment: every group's result starts as its committed state."""
        self._select(self._all, self.s0, self.res)
        self._warm[:] = False                    # no trial of this increment yet
        self._committed_branch = None
        if self.device_trials:
            d = self._device_arrays()
            # (the device's result tangents are the committed ones where the last increment ended: not sent)
            if not self._kr_on_device:
                d.kr.assign(self._k0)
                d.kr_ok.assign(self._k0_ok.astype(np.int32))
            self.control.warm.zero_()
        else:
            self._kr, self._kr_ok = self._k0.copy(), self._k0_ok.copy()

    def accept(self, mask: np.ndarray) -> None:
        """Keep the last trial of the groups in ``mask`` as their result of this increment."""
        if np.any(mask):
            mask = np.asarray(mask, bool)
            self._mask.assign(mask.astype(np.int32))
            self._select(self._mask, self.s1, self.res)
            if self.device_trials:
                d = self._device_arrays()
                self.wp.launch(d.k.accept_tangents_kernel, dim=self.n, device=self.device,
                               inputs=[self._mask, d.k1, d.k1_ok, d.kr, d.kr_ok])
            else:
                self._kr = np.where(mask, self._k1, self._kr)
                self._kr_ok = np.where(mask, self._k1_ok, self._kr_ok)

    def end_increment(self) -> dict:
        """Commit the increment's results (accepted trials, else the committed states); they are returned
        as :meth:`committed`."""
        self.s0, self.res = self.res, self.s0
        if self.device_trials:
            d = self._device_arrays()
            self._kr, self._kr_ok = d.kr.numpy().copy(), d.kr_ok.numpy() != 0
            self._kr_on_device = True
        self._k0, self._k0_ok = self._kr, self._kr_ok
        return self.committed()

    def get_state(self) -> dict:
        """Host copies of the committed states and their tangents (a checkpoint; :meth:`set_state`)."""
        out = {f: a.numpy().copy() for f, a in zip(_STATE_FIELDS, self.s0._arrays() + [self.s0.eff])}
        # the committed states' tangents (those of the accepted trials): a resumed run reuses them, as the
        # uninterrupted run does, instead of recomputing them (a different rounding, another trial path)
        out["tangent"], out["tangent_ok"] = self._k0.copy(), self._k0_ok.copy()
        return out

    def set_state(self, saved: dict) -> None:
        """Restore the committed states and tangents saved by :meth:`get_state`."""
        for f, a in zip(_STATE_FIELDS, self.s0._arrays() + [self.s0.eff]):
            a.assign(saved[f])
        self._k0 = np.array(saved.get("tangent", np.full(self.n, np.nan)), dtype=float)
        self._k0_ok = np.array(saved.get("tangent_ok", np.zeros(self.n, bool)), dtype=bool)
        self._kr_on_device = False


_STATE_FIELDS = ("x", "q", "C", "stage", "jammed", "soft", "frozen_soft", "frozen_sbc", "status", "direction",
                 "head_gap", "eff")


class ReferenceBackend:
    """Trial steps with the NumPy reference cycle (:class:`knitsim.cell.cycle.CellCycle`), one group at a time.

    Mirrors :meth:`CellCycle.run` for one row: reversal when the direction
    changes, ``advance`` (or the Dahl path), failures flagged, Dahl labels.
    """

    partial_trials = True

    def __init__(self, params: list, max_halvings: int = MAX_HALVINGS):
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
        """Each group's committed state, as :meth:`WarpBackend.committed`."""
        return self._read(self.s0)

    def tangent(self, trial: bool, direction: int = 0, mask: np.ndarray | None = None) -> np.ndarray:
        """No cell tangent from the reference engine (NaN: the coupling keeps its secants)."""
        return np.full(self.n, np.nan)

    def trial(self, strain: np.ndarray, direction: int, increment: int, mask: np.ndarray | None = None) -> dict:
        """Step every group (with ``mask``: those in it) from its committed state to ``C = C0 (1 + strain)``;
        the committed state is kept.

        Parameters
        ----------
        strain : ndarray, shape [n]
            Strain of each group's course length.
        direction : int
            +1 loading, -1 unloading (a change reverses a group that is ok and not slack first).
        increment : int
            Index of the increment (recorded with its events).
        mask : ndarray of bool, shape [n], optional
            Groups to step; the others keep their last trial (not read by the coupling).

        Returns
        -------
        dict
            The trial states, as :meth:`WarpBackend.committed`, with ``slide_C`` [mm] and ``slide_F`` [N]
            (:func:`slide_points`).
        """
        from ..cell.cycle import STATUS_NO_CONVERGENCE, _SolveFailed
        out = []
        last_events: dict = {}
        for g, cyc in enumerate(self.cycles):
            if mask is not None and not mask[g]:
                out.append(self.s1[g])         # not stepped: its last trial stands (not read)
                continue
            st = self.s0[g].copy()
            if direction != self.dir0[g] and st.status == STATUS_OK and st.stage is not Stage.SLACK:
                cyc.reverse(st, direction)
            C_target = cyc.p.C0 * (1.0 + float(strain[g]))
            events: list = []
            last_events[g] = events
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
        t = self._read(out)
        cells = np.array([g for g, e in last_events.items() if e], dtype=np.int64)
        ends = [last_events[g][-1] for g in cells]
        t["slide_C"], t["slide_F"] = slide_points(
            len(out), cells, np.array([e["kind"] == "slide" for e in ends], bool),
            np.array([e["C"] for e in ends], float), np.array([e.get("F", np.nan) for e in ends], float), t)
        return t

    def stop_at_force_cap(self, mask: np.ndarray) -> None:
        """Stop the groups in ``mask`` at their committed state, at their force cap (as :class:`WarpBackend`)."""
        for g in np.flatnonzero(mask):
            st = self.s0[g].copy()
            st.status, st.reason = STATUS_FORCE_CAP, "force per wale reached force_cap_N"
            self.s0[g] = st

    def begin_increment(self) -> None:
        """Start an increment: every group's result starts as its committed state."""
        self.res = list(self.s0)
        self.dir_res = list(self.dir0)

    def accept(self, mask: np.ndarray) -> None:
        """Keep the last trial of the groups in ``mask`` as their result of this increment."""
        for g in np.nonzero(mask)[0]:
            self.res[g] = self.s1[g]
            self.dir_res[g] = self._dir1

    def end_increment(self) -> dict:
        """Commit the increment's results (accepted trials, else the committed states); they are returned
        as :meth:`committed`."""
        self.s0, self.dir0 = list(self.res), list(self.dir_res)
        return self.committed()

    def get_state(self) -> dict:
        """Copies of the committed states and directions (a checkpoint; :meth:`set_state`)."""
        return {"states": [s.copy() for s in self.s0], "dir": list(self.dir0)}

    def set_state(self, saved: dict) -> None:
        """Restore the committed states and directions saved by :meth:`get_state`."""
        self.s0 = [s.copy() for s in saved["states"]]
        self.dir0 = list(saved["dir"])


def slide_points(n: int, cells: np.ndarray, is_slide: np.ndarray, C: np.ndarray, F: np.ndarray,
                 trial: dict) -> tuple[np.ndarray, np.ndarray]:
    """(C, F) of each group's slide onset in its last trial, NaN elsewhere: where the trial's last event
    (``cells``, ``is_slide``, ``C``, ``F``: one per group that had events) is a slide and the trial ends
    sliding, not jammed.  There stick turned into sliding: the kink of the branch (:meth:`PatchSolver._solve`)."""
    sC, sF = np.full(n, np.nan), np.full(n, np.nan)
    cells = np.asarray(cells, np.int64)[np.asarray(is_slide, bool)]
    sC[cells], sF[cells] = np.asarray(C)[is_slide], np.asarray(F)[is_slide]
    sliding = ((trial["stage"] == int(Stage.S_LOAD)) | (trial["stage"] == int(Stage.S_UNLOAD))) & (trial["jammed"] == 0)
    return np.where(sliding, sC, np.nan), np.where(sliding, sF, np.nan)


def make_backend(engine: str, grouping: Grouping, device: str = "cpu", max_halvings: int = MAX_HALVINGS):
    """The trial-step backend of ``engine`` (``"warp"`` or ``"reference"``) for the groups' cells."""
    if engine == "warp":
        return WarpBackend(grouping, device, max_halvings)
    if engine == "reference":
        return ReferenceBackend(grouping.params, max_halvings)
    raise KnitsimInputError(f"engine = {engine!r}: expected one of warp, reference")


# ===================================================================== branch models
def column_length_tolerance(scale: np.ndarray) -> np.ndarray:
    """How close a column's model lengths must add up to the grip displacement [mm] (its rest length ``scale``
    to 16 roundings): the column solve's stop, in NumPy and on the device."""
    return 16.0 * np.finfo(float).eps * scale


class BranchPoints:
    """The points (C, f, df/dC) of every group's branch met within one increment, and the monotone
    model C(f) through them (module docstring, "The column as a scalar problem in its force").

    Parameters
    ----------
    C_ref : ndarray, shape [n]
        A length scale per group (its C0) for the tolerances [mm].
    k_fallback : ndarray, shape [n]
        dF/dC used to extrapolate where no slope of the group is known [N/mm].
    size : int
        Points kept per group (the farthest from the column's force is dropped when full).
    k_bounds : (float, float)
        The bounds a tangent dF/dC is clipped to [N/mm] (``PatchSolver.k_bounds``: :data:`K_MIN`, :data:`K_MAX`
        times the patch's :attr:`CouplingScale.tangent`).
    """

    #: whether the points live on a Warp device (:class:`~knitsim.patch.device_coupling.DeviceBranchPoints`)
    on_device = False

    def __init__(self, C_ref: np.ndarray, k_fallback: np.ndarray, size: int = 8,
                 k_bounds: tuple[float, float] = (K_MIN, K_MAX)):
        n = len(C_ref)
        self.C_ref, self.k_fallback = C_ref, k_fallback
        self.k_min, self.k_max = float(k_bounds[0]), float(k_bounds[1])
        self.C, self.F, self.K = (np.full((n, size), np.nan) for _ in range(3))
        self.valid = np.zeros((n, size), bool)
        self.C_min = np.full(n, -np.inf)          # the model's lengths are kept in [C_min, C_max]
        self.C_max = np.full(n, np.inf)
        self._rows = np.arange(n)
        self.rows = self._rows                   # the groups prepared (prepare)
        # trials of a cell that keep landing on one side of the column's force while the column does not
        # close in count as stalled (record): its model then overshoots
        self.stall = np.zeros(n, np.int64)
        self.side = np.zeros(n, np.int64)
        self.column_gap = None                   # set by the solver: each group's column's largest gap
        self.curvature = None                    # d2C/df2 of each group's branch at its last increment

    def record(self, mask: np.ndarray, F: np.ndarray, f_ref: np.ndarray, f_tol: np.ndarray,
               column_stalled: np.ndarray) -> None:
        """Update the stall counts from the trial forces ``F`` of the groups in ``mask``, asked for ``f_ref``.

        A group stalls when its column's spread of forces has not shrunk fourfold since the last
        trial (``column_stalled``, per group), it is among the cells that set that spread (its gap
        at least half its column's largest), and it lands on the same side as last time."""
        gap = np.abs(F - f_ref)
        side = np.where(gap <= f_tol, 0, np.sign(F - f_ref)).astype(np.int64)
        stalled = (side != 0) & (side == self.side) & column_stalled & (gap >= 0.5 * self.column_gap(gap, mask))
        self.stall = np.where(mask, np.where(stalled, self.stall + 1, 0), self.stall)
        self.side = np.where(mask, side, self.side)

    def add(self, mask: np.ndarray, C: np.ndarray, F: np.ndarray, K: np.ndarray, f_target: np.ndarray) -> None:
        """Add the point (C, F, K) of each group in ``mask`` (K: its dF/dC, NaN where unknown).

        The branch of a cell within an increment is monotone (F never falls as C grows on a stable
        branch): a kept point that contradicts the new one (higher C, lower F or the reverse) is
        dropped; of the zero-force points (slack) only the longest is kept (F = 0 up to at least it).
        Only the rows in ``mask`` are read and written (the cost goes with the groups still iterating)."""
        rows = np.flatnonzero(mask)
        if rows.size == 0:
            return
        every = rows.size == len(self._rows)     # (then the kept points are changed in place)
        if not every:
            C, F, K, f_target = C[rows], F[rows], K[rows], f_target[rows]
        Ck, Fk, Kk, valid = (a if every else a[rows] for a in (self.C, self.F, self.K, self.valid))
        C2, F2 = C[:, None], F[:, None]
        conflict = ((Fk < F2) & (Ck > C2)) | ((Fk > F2) & (Ck < C2))
        dup_zero = (Fk == 0.0) & (F2 == 0.0) & (Ck <= C2)
        valid &= ~(conflict | dup_zero | ((Fk == F2) & (Ck == C2)))
        # a zero-force point shorter than a kept one adds nothing
        dominated = (F == 0.0) & np.any(valid & (Fk == 0.0) & (Ck > C2), axis=1)
        put = ~dominated
        full = put & valid.all(axis=1)
        local = np.arange(rows.size)
        if np.any(full):
            # drop the point farthest (in force) from the column's force, on a side that keeps another
            side = Fk > f_target[:, None]
            n_hi = np.sum(side & valid, axis=1, keepdims=True)
            n_lo = np.sum(~side & valid, axis=1, keepdims=True)
            ok = valid & np.where(side, n_hi >= 2, n_lo >= 2)
            dist = np.where(ok, np.abs(Fk - f_target[:, None]), -1.0)
            drop = np.argmax(dist, axis=1)
            valid[local[full], drop[full]] = False
        slot = np.argmin(valid, axis=1)
        r, s = local[put], slot[put]
        Ck[r, s], Fk[r, s], Kk[r, s] = C[put], F[put], K[put]
        valid[r, s] = True
        if not every:
            self.C[rows], self.F[rows], self.K[rows], self.valid[rows] = Ck, Fk, Kk, valid

    def prepare(self, rows: np.ndarray | None = None) -> None:
        """Sort each group's points by force and set up its model (after the points of a trial are added).

        With ``rows`` (ascending group indices), of those groups only: :meth:`model` and :meth:`jump` then
        take and give values of these groups, in this order.  A group's model does not depend on the
        others', so it is the same either way; the work goes with the groups still iterating."""
        self.rows = self._rows if rows is None or len(rows) == len(self._rows) else np.asarray(rows)
        valid = self._prepared(self.valid)
        Fk = np.where(valid, self._prepared(self.F), np.inf)
        self.m = np.count_nonzero(valid, axis=1)
        # sorted, the valid points come first: the slots beyond the most points of any group are dropped
        M = max(int(self.m.max(initial=0)), 1)
        order = np.argsort(Fk, axis=1, kind="stable")[:, :M]
        take = functools.partial(np.take_along_axis, indices=order, axis=1)
        self.Fs, self.Cs = take(Fk), take(np.where(valid, self._prepared(self.C), np.nan))
        self.Ks = take(self._prepared(self.K))
        r, top = np.arange(self.rows.size), np.maximum(self.m - 1, 0)
        # each interval between neighbouring points: the tangent lines of its ends (slopes da, db = dC/df),
        # their upper envelope where the slopes grow across it (C(f) convex: a stick-slip kink), their
        # lower envelope where they fall (concave: jamming), the chord where they contradict it
        with np.errstate(invalid="ignore"):
            h = np.diff(self.Fs, axis=1)
        good_h = np.isfinite(h) & (h > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            delta = np.where(good_h, (self.Cs[:, 1:] - self.Cs[:, :-1]) / np.where(good_h, h, 1.0), 0.0)
            delta = np.maximum(delta, 0.0)
            inv_k = np.where(np.isfinite(self.Ks) & (self.Ks > 0), 1.0 / np.clip(self.Ks, self.k_min, self.k_max),
                             np.nan)
            da = np.where(np.isfinite(inv_k[:, :-1]), inv_k[:, :-1], delta)
            db = np.where(np.isfinite(inv_k[:, 1:]), inv_k[:, 1:], delta)
        # (to 1 % of the chord: a tangent that nearly passes through the other end still counts)
        lo_d, hi_d = 0.99 * delta, 1.01 * delta
        self.convex = (da <= hi_d) & (lo_d <= db) & (db >= da)
        self.concave = (da >= lo_d) & (hi_d >= db) & (db < da)
        chord = ~(self.convex | self.concave)
        self.da_raw, self.db_raw = da, db
        self.da = np.where(chord, delta, da)
        self.db = np.where(chord, delta, db)
        # slopes dC/df beyond the lowest and the highest point: the cell's tangent there, else the
        # secant of its two end points, else the fallback tangent
        fb = 1.0 / np.clip(self._prepared(self.k_fallback), self.k_min, self.k_max)

        def end_slope(i, j):
            s = inv_k[r, i]
            with np.errstate(divide="ignore", invalid="ignore"):
                sec = (self.Cs[r, j] - self.Cs[r, i]) / (self.Fs[r, j] - self.Fs[r, i])
            sec = np.where((self.m >= 2) & np.isfinite(sec) & (sec > 0), sec, fb)
            return np.clip(np.where(np.isfinite(s), s, sec), 1.0 / self.k_max, 1.0 / self.k_min)

        self.s_lo = end_slope(np.zeros_like(top), np.minimum(1, top))
        self.s_hi = end_slope(top, np.maximum(top - 1, 0))
        self.top = top
        # the curvature d2C/df2 of the extrapolations: from the tangents of the two end points where
        # both are known and agree with their chord (an interval that is convex or concave, not a kink
        # the chord stands for), else that of the cell's last increment (``curvature``, NaN: none)
        self.c_lo = self._end_curvature(inv_k, 0, self.convex[:, 0] | self.concave[:, 0] if M > 1 else None)
        j = np.maximum(top - 1, 0)
        self.c_hi = self._end_curvature(inv_k, j, (self.convex[r, j] | self.concave[r, j]) if M > 1 else None)

    def _prepared(self, a: np.ndarray) -> np.ndarray:
        """The prepared rows of the per-group array ``a`` (``a`` itself when every group is prepared)."""
        return a if self.rows is self._rows else a[self.rows]

    def _end_curvature(self, inv_k: np.ndarray, j: np.ndarray | int, smooth: np.ndarray | None) -> np.ndarray:
        """(dC/df at point j+1 - dC/df at point j) / (f_j+1 - f_j), where defined; else the history's
        (of the prepared rows)."""
        r = np.arange(self.rows.size)
        c = np.full(len(r), np.nan) if self.curvature is None else self._prepared(self.curvature).copy()
        if smooth is not None:
            j = np.broadcast_to(j, r.shape)
            with np.errstate(divide="ignore", invalid="ignore"):
                cj = (inv_k[r, j + 1] - inv_k[r, j]) / (self.Fs[r, j + 1] - self.Fs[r, j])
            # (a smooth bend: the slopes within a factor 1.5; across a kink, the envelope stands for it)
            ratio = inv_k[r, j + 1] / inv_k[r, j]
            ok = (self.m >= 2) & smooth & np.isfinite(cj) & (ratio <= 1.5) & (ratio >= 1.0 / 1.5)
            c = np.where(ok, cj, np.where(self.m >= 2, np.nan, c))
        return np.where(np.isfinite(c), c, 0.0)

    def model(self, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The model's length C(f) and dC/df of each prepared group (:meth:`prepare`) at its force ``f`` [N]."""
        stall, side = self._prepared(self.stall), self._prepared(self.side)
        j = np.count_nonzero(self.Fs <= f[:, None], axis=1)
        below, above = j == 0, j >= self.m
        C, dC = np.empty(len(f)), np.empty(len(f))
        r = np.flatnonzero(~(below | above))     # between two points (j in 1 .. m-1: never with one point)
        if r.size:
            ia = j[r] - 1
            fr = f[r]
            Fa, Ca, Fb, Cb = self.Fs[r, ia], self.Cs[r, ia], self.Fs[r, ia + 1], self.Cs[r, ia + 1]
            da, db = self.da[r, ia], self.db[r, ia]
            with np.errstate(invalid="ignore"):
                Ta, Tb = Ca + (fr - Fa) * da, Cb + (fr - Fb) * db
            upper = self.convex[r, ia]
            pick_a = np.where(upper, Ta >= Tb, Ta <= Tb)
            Ch = np.clip(np.where(pick_a, Ta, Tb), np.minimum(Ca, Cb), np.maximum(Ca, Cb))
            dCh = np.where(pick_a, da, db)
            ill = np.flatnonzero(stall[r] > 0)
            if ill.size:
                # a stalled cell (its trials keep landing on one side of the column's force without closing
                # in): the Newton step from its fresh end (the side its trials land on), 2^stall times as
                # long, but no further than the middle of its bracket (bisection where the tangent would
                # throw it across a kink): the trials overshoot into the other side or halve the bracket
                ri, ii = r[ill], ia[ill]
                Fa, Ca, Fb, Cb, fi = Fa[ill], Ca[ill], Fb[ill], Cb[ill], fr[ill]
                fresh_b = side[ri] > 0
                d_f = np.where(fresh_b, self.db_raw[ri, ii], self.da_raw[ri, ii]) * 2.0 ** stall[ri]
                with np.errstate(invalid="ignore"):
                    Tf = np.where(fresh_b, Cb + (fi - Fb) * d_f, Ca + (fi - Fa) * d_f)
                mid = 0.5 * (Ca + Cb)
                lo_C, hi_C = np.where(fresh_b, mid, Ca), np.where(fresh_b, Cb, mid)
                Ch[ill] = np.clip(Tf, lo_C, hi_C)
                dCh[ill] = np.where((Tf > lo_C) & (Tf < hi_C), d_f, 0.0)
            C[r] = Ch
            with np.errstate(invalid="ignore"):
                dC[r] = np.maximum(dCh, 0.0)
        # beyond the end points, the end tangent line bent by the branch's curvature; a stalled
        # extrapolation doubles its slope at each stall (the trials then overshoot into a bracket), unbent
        for rows, k, s_end, c_end in ((np.flatnonzero(below), 0, self.s_lo, self.c_lo),
                                      (np.flatnonzero(above), None, self.s_hi, self.c_hi)):
            if rows.size:
                k = self.top[rows] if k is None else k
                st = stall[rows]
                s_e = np.minimum(s_end[rows] * 2.0 ** st, 1.0 / self.k_min)
                d_e, sl_e = _bent_line(f[rows] - self.Fs[rows, k], s_e, np.where(st > 0, 0.0, c_end[rows]))
                C[rows] = self.Cs[rows, k] + d_e
                dC[rows] = sl_e
        C_min, C_max = self._prepared(self.C_min), self._prepared(self.C_max)
        clamped = (C < C_min) | (C > C_max)
        return np.clip(C, C_min, C_max), np.where(clamped, 0.0, dC)

    def jump(self, f: np.ndarray, f_tol: np.ndarray) -> np.ndarray:
        """Of the prepared groups, those whose points bracket ``f`` within a length ~1e-11 C0 while their
        forces differ by more than ``f_tol`` and than ``JUMP_RTOL f`` (below it: the cell solves' own
        resolution, kernels/branch_points.py): a discontinuity of the cell's force, which no column force
        between them meets."""
        r, M = np.arange(self.rows.size), self.Fs.shape[1]
        if M < 2:
            return np.zeros(len(f), bool)
        j = np.sum(self.Fs <= f[:, None], axis=1)
        inside = (j >= 1) & (j < self.m)
        ia = np.clip(j - 1, 0, M - 2)
        dC = self.Cs[r, ia + 1] - self.Cs[r, ia]
        dF = self.Fs[r, ia + 1] - self.Fs[r, ia]
        with np.errstate(invalid="ignore"):
            return inside & (dC <= 1e-11 * self._prepared(self.C_ref)) & (dF > np.maximum(f_tol, JUMP_RTOL * f))


def _bent_line(x: np.ndarray, s: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The increment and slope of a line of slope ``s`` > 0 bent by a curvature ``c`` at ``x`` from its
    point: ``s x + c x^2 / 2`` while the slope ``s + c x`` stays within [s/4, 4 s], straight at that
    bound beyond (monotone, and never far from the tangent line)."""
    bound = np.where(c * x < 0.0, 0.25 * s, 4.0 * s)
    with np.errstate(divide="ignore", invalid="ignore"):
        xb = np.where(c != 0.0, (bound - s) / np.where(c != 0.0, c, 1.0), np.inf)
    inside = np.abs(x) <= np.abs(xb)
    with np.errstate(invalid="ignore"):
        xi = np.where(inside, x, xb)
        d = s * xi + 0.5 * c * xi * xi + np.where(inside, 0.0, bound * (x - xb))
        slope = np.where(inside, s + c * x, bound)
    return d, slope


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
        A column converges when its cells' forces agree within ``force_tol sigma_F + force_rtol * |F|`` [N]
        (``force_tol`` stated at the usual knits' force scale, sigma_F the patch's :attr:`CouplingScale.force`:
        1 for them; the attribute ``force_tol`` is the product).
    max_iterations : int
        Trial steps per increment before a column is committed as it stands and flagged.
    max_halvings : int
        Passed to the cell solver: halvings in a row of a failed sub-step (default the cell's own,
        :data:`~knitsim.cell.stages.MAX_HALVINGS`, so that a cell of a patch reaches the lengths
        that the cell alone reaches; with 6 a trial from SF- near R = 0 failed 1e-3 mm short).

    Attributes
    ----------
    scale : CouplingScale
        The patch's scale factors (1 for the usual knits).
    force_tol : float
        The absolute force tolerance [N]: the ``force_tol`` given times ``scale.force``.
    k_bounds : (float, float)
        The bounds of a cell's tangent dF/dC [N/mm]: :data:`K_MIN`, :data:`K_MAX` times ``scale.tangent``.
    force_search : (float, float)
        The column force search's first guess where it has no lower bound and its ceiling [N]:
        :data:`FORCE_SEARCH_START`, :data:`FORCE_SEARCH_MAX` times ``scale.force``.
    branch_points : int
        Points of each cell's branch kept per increment (:class:`BranchPoints`).
    sub_increments : int
        Committed sub-increments of a column that has not converged in one (1: none).
    device_branch_points : bool
        The branch points, their model and the column solve on the cells' Warp device
        (:mod:`knitsim.patch.device_coupling`; the warp engine with 8 branch points), else in NumPy
        (:class:`BranchPoints`, their twin; the same results bit for bit on the CPU).
    jump_columns, cut_columns : ndarray of bool, shape [n_classes]
        Of the last increment: columns left unconverged by a jump of a cell's force, and columns
        that needed sub-increments.
    """

    #: the branch points, their model and the column solve on the cells' Warp device (DeviceBranchPoints,
    #: DeviceColumnSolve: the warp engine with 8 points), else in NumPy (BranchPoints, their twin)
    device_branch_points = True

    def __init__(self, grouping: Grouping, engine: str = "warp", device: str = "cpu",
                 force_tol: float = 1e-10, force_rtol: float = 1e-8, max_iterations: int = 40,
                 max_halvings: int = MAX_HALVINGS):
        self.g = grouping
        self.backend = make_backend(engine, grouping, device, max_halvings)
        # the absolute tolerances and bounds in the patch's own force and length scales (CouplingScale: powers of
        # two, 1 for the usual knits, whose solves are bit for bit those of the constants themselves)
        self.scale = sc = CouplingScale.of(grouping)
        self.force_tol = force_tol * sc.force
        self.force_rtol, self.max_iterations = force_rtol, int(max_iterations)
        self.k_bounds = (K_MIN * sc.tangent, K_MAX * sc.tangent)
        self.force_search = (FORCE_SEARCH_START * sc.force, FORCE_SEARCH_MAX * sc.force)
        self.C0 = np.asarray(grouping.cells["C0"], dtype=np.float64)
        #: each group's force cap per wale [N]
        self.force_cap = np.broadcast_to(np.asarray(grouping.cells["force_cap_N"], dtype=np.float64),
                                         self.C0.shape).copy()
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
        # per column, fixed by the grouping (each an O(groups) reduction, once per increment before): whether
        # it is a single group, its stitch count and its rest length [mm]
        self._single_cls = single
        self._col_count = self._colsum(self.cnt)
        self._col_length = self._colsum(self.cnt * self.C0)
        # per group: its column mounted at the reference length, and its rest length n C0 [mm] (u_single)
        self._at_ref_length = self.rest[self.col] == self.ref_length
        self._group_length = self.cnt * self.C0
        self.cells = self.backend.committed()
        self.k = np.full(self.backend.n, np.nan)
        self.direction = 1
        #: points of each cell's branch kept per increment (BranchPoints)
        self.branch_points = DEVICE_BRANCH_SIZE
        #: the coupling's branch points, column solve and trial bookkeeping on the cells' Warp device, and the
        #: backend's trial reads with them (device_branch_points with the warp engine): fixed here
        self.on_device = bool(self.device_branch_points) and isinstance(self.backend, WarpBackend)
        if self.on_device:
            self.backend.device_trials = True
        # the branch points and the column solve on the device (DeviceBranchPoints, DeviceColumnSolve), made once
        self._device_points = self._device_columns = self._device_trials = None
        self._committed_cols = None              # (the committed state read, _committed_columns of it)
        self._col_order = None                   # the groups sorted by column, for _colmax
        self.jump_columns = np.zeros(self.n_cls, bool)
        self.cut_columns = np.zeros(self.n_cls, bool)
        #: sub-increments of a column that has not converged in one (1: none)
        self.sub_increments = 4
        #: grip displacement of the last increment of each column [mm]
        self.u_prev = np.zeros(self.n_cls)
        #: increments in a row of the current direction in which each column did not converge (HELD_RETRIES)
        self.held = np.zeros(self.n_cls, dtype=np.int64)
        #: each group's force, dC/df, stage, jammed flag at the start of the last increment and its direction
        #: (with the device coupling kept on the device: DeviceTrials.branch_history)
        self._branch_history = None

    # ------------------------------------------------------------- helpers
    def _colsum(self, v: np.ndarray) -> np.ndarray:
        return np.bincount(self.col, weights=v, minlength=self.n_cls)

    def _colmax(self, v: np.ndarray, fill: float) -> np.ndarray:
        """Each column's largest value of ``v`` [n_groups], at least ``fill`` (a segmented maximum over the
        groups sorted by column: np.maximum.at took 0.6 s of a 10^6-group patch's 8 increments on the host)."""
        if self._col_order is None:
            order = np.argsort(self.col, kind="stable")
            filled = np.flatnonzero(np.bincount(self.col, minlength=self.n_cls) > 0)
            self._col_order = (order, np.searchsorted(self.col[order], filled), filled)
        order, starts, filled = self._col_order
        out = np.full(self.n_cls, fill, dtype=np.result_type(v, float))
        if len(order):
            # (the starts of the columns that have groups: strictly increasing, each segment its column's)
            out[filled] = np.maximum(np.maximum.reduceat(np.asarray(v)[order], starts), fill)
        return out

    def _device_objects(self):
        """The device coupling's points, column solve and trial bookkeeping (made once: 10^6 groups hold
        ~0.5 GB of points on the device)."""
        if self._device_trials is None:
            from .device_coupling import DeviceBranchPoints, DeviceColumnSolve, DeviceTrials
            be = self.backend
            self._device_points = DeviceBranchPoints(self.C0, self.k, self.branch_points, be.device, self.k_bounds)
            self._device_columns = DeviceColumnSolve(self.col, self.cnt, self.C0, self.p, self.n_cls, be.device,
                                                     self.force_search)
            self._device_trials = DeviceTrials(self._device_columns, self.single_group)
        return self._device_points, self._device_columns, self._device_trials

    def _committed_columns(self, c: dict) -> dict:
        """Of each column's committed state ``c``: ``F_max``, ``F_min`` of its groups' p F [N], the sums
        ``n_pF`` of n (p F) and ``np_F`` of (n p) F [N], ``n_dC`` of n (C - C0) [mm], and ``stopped`` (a cell's
        status not ok): on the device with the device coupling (``column_reads_kernel``), else NumPy
        (its twin; the same sums in the same order)."""
        # (one committed state serves an increment's end, the next one's start and its set-up: computed once)
        if self._committed_cols is not None and self._committed_cols[0] is c:
            return self._committed_cols[1]
        if self.on_device:
            out = self._device_objects()[2].committed_columns(self.backend.packed_committed(), STATUS_OK,
                                                              STATUS_FORCE_CAP)
        else:
            Ftot = self.p * c["F"]
            out = {"F_max": self._colmax(Ftot, -np.inf), "F_min": -self._colmax(-Ftot, -np.inf),
                   "n_pF": self._colsum(self.cnt * Ftot), "np_F": self._colsum(self.cnt * self.p * c["F"]),
                   "n_dC": self._colsum(self.cnt * (c["C"] - self.C0)),
                   "stopped": self._colmax((c["status"] != STATUS_OK).astype(float), 0.0) > 0}
        self._committed_cols = (c, out)
        return out

    def probe_tangent(self, strain: float = 1e-3) -> None:
        """Initial tangents dF/dC from a trial step of every cell to ``strain`` (loading)."""
        c = self.cells
        t = self.backend.trial(np.full(self.backend.n, strain), 1, -1)
        if "C" not in t:                      # (a backend in device mode reads the trial's lengths on demand)
            t = self.backend.trial_state()
        dC = t["C"] - c["C"]
        with np.errstate(divide="ignore", invalid="ignore"):
            k = (t["F"] - c["F"]) / dC
        ok = np.isfinite(k) & (k > 0) & (t["status"] == STATUS_OK)
        k_min, k_max = self.k_bounds
        self.k = np.clip(np.where(ok, k, PROBE_TANGENT_FALLBACK * self.scale.tangent), k_min, k_max)

    def get_state(self) -> dict:
        """The solver's state between increments (backend state, tangents, direction, cells, last grip
        displacements, branch history), for a checkpoint."""
        return {"backend": self.backend.get_state(), "k": self.k.copy(), "direction": self.direction,
                "cells": copy.deepcopy(self.cells), "u_prev": self.u_prev.copy(), "held": self.held.copy(),
                "branch_history": (self._device_objects()[2].branch_history() if self.on_device
                                   else copy.deepcopy(self._branch_history))}

    def set_state(self, s: dict) -> None:
        """Restore a state saved by :meth:`get_state`."""
        self.backend.set_state(s["backend"])
        self.k = np.array(s["k"])
        self.direction = int(s["direction"])
        self.u_prev = np.array(s.get("u_prev", np.zeros(self.n_cls)), dtype=float)
        self.held = np.array(s.get("held", np.zeros(self.n_cls)), dtype=np.int64)
        if self.on_device:
            self._device_objects()[2].set_branch_history(s.get("branch_history"))
        else:
            self._branch_history = s.get("branch_history")
        self.cells = self.backend.committed()

    # ---------------------------------------------------------------- step
    def step(self, grip_strain: float, direction: int, increment: int = 0) -> IncrementResult:
        """Solve one grip increment to ``grip_strain`` (u = grip_strain x ref_length) and commit it."""
        if np.any(np.isnan(self.k)):
            self.probe_tangent()
        be, c = self.backend, self.cells
        col, cnt, C0, p = self.col, self.cnt, self.C0, self.p
        u = float(grip_strain) * self.ref_length
        # columns with a stopped cell keep their state (flagged)
        stopped_cls = self._committed_columns(c)["stopped"]
        # columns that did not converge in HELD_RETRIES loading increments in a row hold until the grip turns:
        # loading further takes them further from the balance they could not reach.  Not while unloading: a
        # column held short of the grip converges again once the grip comes back to its cells' lengths
        # (it holds until then)
        if int(direction) != self.direction:
            self.held[:] = 0
        skip_cls = ~stopped_cls & (self.held >= HELD_RETRIES) & (int(direction) > 0)
        single_cls = self._single_cls
        if int(direction) < 0:
            # ... and while unloading, a column held short of the grip holds until the grip has come back to its
            # cells' lengths: before, solved at once on the grip's reversal, its cells were sent along their
            # unloading branches to lengths longer than they held (a blind probe's tight / loose column, held at
            # 0.003 N from grip strain 0.02 to 0.3, then its cells at 1,800 N per wale under a cap of 20 N)
            short = u > self._committed_columns(c)["n_dC"] + LENGTH_RTOL * self._col_length
            skip_cls |= ~stopped_cls & ~single_cls & short
        active_cls = ~stopped_cls & ~skip_cls
        # exact strain of a single-group (uniform) column: the cell itself at the grip strain
        u_single = np.where(self._at_ref_length, float(grip_strain), u / self._group_length)
        be.begin_increment()
        u_cls = np.full(self.n_cls, u)
        done_cls, iters, jump_cls, last_failed, last_capped = self._solve(u_cls, u_single, direction, increment,
                                                                          active_cls, give_up=self.sub_increments > 1)
        retry = active_cls & ~done_cls & ~single_cls
        self.cut_columns = retry.copy()
        if np.any(retry) and self.sub_increments > 1:
            # a column that has not converged: its converged neighbours are committed, and it goes from
            # its committed state to u in sub-increments (a trial from the committed state to u may fail
            # where shorter steps do not: README, cause 1), each solved and committed in turn
            self.cells = be.end_increment()
            u0 = self.u_prev
            for k in range(1, self.sub_increments + 1):
                be.begin_increment()
                u_k = u0 + (u - u0) * k / self.sub_increments
                d_k, it_k, j_k, lf_k, lc_k = self._solve(u_k, u_single, direction, increment, retry, history=False)
                iters += it_k
                jump_cls = np.where(retry, j_k, jump_cls)
                last_failed = np.where(retry, lf_k, last_failed)
                last_capped = np.where(retry, lc_k, last_capped)
                ok = retry & d_k
                if k < self.sub_increments:
                    self.cells = be.end_increment()
                    retry = ok
                    if not np.any(retry):
                        break
                else:
                    done_cls |= ok
        not_conv = active_cls & ~done_cls
        self.jump_columns = jump_cls & not_conv
        if np.any(not_conv):
            # committed as it stands and flagged, unless a cell failed in the last trial: then the
            # column keeps its previous state (flagged) and the next increment tries again from it.  So does a
            # column whose trials stopped a cell at its cap while loading (it is brought to the cap below):
            # committed as it stood, its cells at the cap beside cells above it, the column was stopped there
            # carrying more than its weakest cell's cap (E-glass cells at 6.17 N per wale beside one capped at 6 N)
            keep = last_failed | (last_capped & (int(direction) > 0))
            be.accept(not_conv[col] & ~keep[col])
        status = np.where(stopped_cls, COL_STOPPED, COL_OK)
        status = np.where(not_conv | skip_cls, COL_NOT_CONVERGED, status)
        self.held = np.where(not_conv | skip_cls, self.held + 1, 0)
        self.cells = c = be.end_increment()
        # a column of unlike cells whose trials stopped a cell at its force cap, held short of the cap: the grip
        # displacement where it reaches the cap is located (_approach_force_cap), so that the cap test below
        # judges the column at its cap, not at the last sub-increment it balanced
        if int(direction) > 0:
            approach = not_conv & last_capped & ~single_cls & ~self._near_force_cap(c)
            if np.any(approach):
                iters += self._approach_force_cap(approach, u, u_single, direction, increment)
                self.cells = c = be.committed()
        # a column of unlike cells that cannot pass a cell's force cap (its last trial stopped a cell there) and
        # holds within FORCE_CAP_RTOL of it stops there, as a uniform column's cell stops at its cap: before, it
        # held the cap while the grip moved on and resumed on the way back, reporting later cycles the knit never
        # ran (a blind probe's E-glass / basalt column; exit 0, no program_cut_by_force_cap)
        at_cap = self._near_force_cap(c, per_group=True) & (not_conv & last_capped)[col]
        if np.any(at_cap):
            be.stop_at_force_cap(at_cap)
            self.cells = c = be.committed()
            status = np.where(self._colmax(at_cap.astype(float), 0.0) > 0, COL_STOPPED, status)
        self.u_prev = np.where(active_cls, u, self.u_prev)
        cc = self._committed_columns(c)
        status = np.where(cc["stopped"] & (status == COL_OK), COL_STOPPED, status)
        self.direction = int(direction)
        n_cells = self._col_count
        # a single-group column carries its cell's force exactly (no rounding of n F / n)
        F_one = np.zeros(self.n_cls)
        F_one[col[self.single_group]] = p[self.single_group] * c["F"][self.single_group]
        F_col = np.where(single_cls, F_one, cc["np_F"] / n_cells)
        spread = cc["F_max"] + (-cc["F_min"])
        slack_len = np.maximum(0.0, cc["n_dC"] - u)
        slack_len = np.where(F_col == 0.0, slack_len, 0.0)
        return IncrementResult(F_col, status.astype(np.int32), slack_len, iters, spread, c)

    def _near_force_cap(self, c: dict, per_group: bool = False) -> np.ndarray:
        """Whether each group of the committed state ``c`` carries within FORCE_CAP_RTOL of its force cap [n_groups]
        (``per_group``), else whether a group of each column does [n_classes]."""
        near = c["F"] >= (1.0 - FORCE_CAP_RTOL) * self.force_cap
        return near if per_group else self._colmax(near.astype(float), 0.0) > 0

    def _approach_force_cap(self, cls: np.ndarray, u: float, u_single: np.ndarray, direction: int,
                            increment: int) -> np.ndarray:
        """Bring the columns ``cls`` [n_classes] (not converged at the grip displacement ``u`` [mm], a trial of theirs
        stopped at a cell's force cap) as close to the cap as they balance: bisection of the grip displacement
        between the committed state's (its lengths' sum) and ``u``, each balanced midpoint committed, until a cell
        carries within FORCE_CAP_RTOL of its cap or CAP_BISECTIONS halvings (the column's analogue of the cell's own
        location of its cap).  Before, the sub-increments stopped a quarter increment short, a jammed E-glass /
        basalt column at 9.43 N per wale under its cap of 10 N (0.30 N short of it a grip strain of 0.002 on,
        the jammed branch that steep): held as not converged, then resumed on the grip's reversal.
        Returns the trials spent, per column."""
        be = self.backend
        u_lo = self._committed_columns(self.cells)["n_dC"]
        u_hi = np.full(self.n_cls, float(u))
        iters = np.zeros(self.n_cls, dtype=np.int64)
        for _ in range(CAP_BISECTIONS):
            live = cls & ~self._near_force_cap(self.cells)
            if not np.any(live):
                break
            u_mid = 0.5 * (u_lo + u_hi)
            be.begin_increment()
            ok, it, _, _, _ = self._solve(u_mid, u_single, direction, increment, live, give_up=True, history=False)
            self.cells = be.end_increment()
            iters += it
            u_lo = np.where(live & ok, u_mid, u_lo)
            u_hi = np.where(live & ~ok, u_mid, u_hi)
        return iters

    def _solve(self, u_cls: np.ndarray, u_single: np.ndarray, direction: int, increment: int,
               active_cls: np.ndarray, give_up: bool = False,
               history: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Iterate the columns in ``active_cls`` to the grip displacements ``u_cls`` [n_classes] from the
        committed state; converged columns are accepted.  Returns (converged, trials, columns stopped on
        a jump of a cell's force, columns whose last trial failed, columns whose last trial stopped a cell at
        its force cap), each of shape [n_classes]."""
        be, c = self.backend, self.cells
        col, cnt, C0, p = self.col, self.cnt, self.C0, self.p
        u = u_cls
        done_cls = ~active_cls
        jump_cls = np.zeros(self.n_cls, bool)
        iters = np.zeros(self.n_cls, np.int64)
        single_cls = self._single_cls
        col_length = self._col_length              # each column's rest length [mm]
        # a backend that steps (and gives tangents of) a subset of the groups: only the live columns' cells
        partial = getattr(be, "partial_trials", False)
        # the committed state is a point of every cell's branch, with the tangent of the stage that a
        # reversal enters; the fallback tangents are the last increment's
        k_c = be.tangent(False, direction)
        on_dev = self.on_device
        if on_dev:
            pts, _, trials = self._device_objects()
            pts.reset(self.k, host_state=False)
            # the curvature of each branch and the kept committed point (the NumPy lines below, one thread per
            # group: ~30 passes over 10^6 groups were ~25 ms of an increment's host time)
            # (the committed states packed once for the set-up: the curvature and the trials' start read them)
            committed_reads = be.packed_committed()
            trials.branch_curvature(pts, committed_reads, k_c, direction, history)
        else:
            pts = BranchPoints(C0, self.k, self.branch_points, self.k_bounds)
            k_c = np.where(np.isfinite(k_c) & (k_c > 0), k_c, np.nan)
            # the curvature of each cell's branch from its last two committed points (their tangents), where
            # both are on one branch: the same stage, the same direction, a force that moved
            kinv_c = np.where(np.isfinite(k_c), 1.0 / np.clip(k_c, *self.k_bounds), np.nan)
            hist = self._branch_history if history else None
            if hist is not None and hist[4] == direction:
                F_h, kinv_h, stage_h, jam_h = hist[:4]
                with np.errstate(divide="ignore", invalid="ignore"):
                    curv = (kinv_c - kinv_h) / (c["F"] - F_h)
                same = (c["stage"] == stage_h) & (c["jammed"] == jam_h) & (c["F"] > 0) & (F_h > 0) & (c["F"] != F_h)
                with np.errstate(divide="ignore", invalid="ignore"):
                    same &= (kinv_c <= 1.5 * kinv_h) & (kinv_h <= 1.5 * kinv_c)
                pts.curvature = np.where(same & np.isfinite(curv), curv, np.nan)
            if history:
                self._branch_history = (c["F"].copy(), kinv_c, c["stage"].copy(), c["jammed"].copy(), int(direction))
        pts.column_gap = lambda gap, mask: self._colmax(np.where(mask, gap * p, 0.0), 0.0)[col] / p
        spread_last = np.full(self.n_cls, np.inf)
        cc = self._committed_columns(c)
        Fc_max, Fc_min = cc["F_max"], cc["F_min"]
        Fcol = np.maximum(cc["n_pF"] / self._col_count, 0.0)
        # the committed state is an equilibrium of the column (not so at the rest state, whose cells'
        # rest forces differ, nor after a flagged increment): only then do its cells move one way
        monotone_cls = (Fc_max - Fc_min) <= 1e3 * (self.force_tol + self.force_rtol * np.abs(Fc_max))
        if on_dev:
            # the committed point, the direction's bounds and the trials' bookkeeping (DeviceTrials) on the
            # device: the NumPy below is its twin
            trials.begin(pts, committed_reads, trials.k_c, self.k, Fcol, monotone_cls, direction, u_single,
                         (int(Stage.SF_LOAD), int(Stage.SF_UNLOAD)))
        else:
            pts.add(np.ones(be.n, bool), c["C"], c["F"], k_c, Fcol[col] / p)
            monotone = monotone_cls[col]
            dir_min = np.where(monotone & (direction > 0), c["C"], -np.inf)
            dir_max = np.where(monotone & (direction < 0), c["C"], np.inf)
            pts.C_min, pts.C_max = dir_min, dir_max
            # a committed stick state: a slide onset its trials cross is a point of its branch (below)
            stick = (c["stage"] == int(Stage.SF_LOAD)) | (c["stage"] == int(Stage.SF_UNLOAD))
            committed_strain = c["C"] / C0 - 1.0
            # lengths at which a cell's trial failed, and its good trials' extreme lengths: the model is kept
            # halfway between them (bisection towards the failure), never beyond
            fail_hi, fail_lo = np.full(be.n, np.inf), np.full(be.n, -np.inf)
            good_hi, good_lo = c["C"].copy(), c["C"].copy()
            C_last, F_last = c["C"].copy(), c["F"].copy()     # each cell's last good trial
        last = None
        prev_failed = np.zeros(self.n_cls, bool)
        prev_capped = np.zeros(self.n_cls, bool)
        for it in range(self.max_iterations):
            # a column whose last trial failed in a cell after 8 trials gives up early when it can still
            # be cut into sub-increments (step)
            live = active_cls & ~done_cls & ~(give_up & prev_failed & (iters >= 8))
            if not np.any(live):
                break
            g_live = live[col]
            # the models of the live columns' groups only (a converged column's are not read again)
            pts.prepare(np.flatnonzero(g_live))
            # (on the device the trial lengths stay there: C_try None)
            Fstar, C_try = self._solve_columns(pts, u, Fcol, live, host_lengths=not on_dev)
            Fcol = np.where(live, Fstar, Fcol)
            if it > 0:
                # a cell whose force jumps across the column's force (cause 1 of the README): flagged
                if on_dev:
                    jumped = live & trials.jumped_columns(pts, self.force_tol, self.force_rtol)
                else:
                    f_tol = (self.force_tol + self.force_rtol * Fstar[col]) / p
                    g_jump = np.zeros(be.n, bool)
                    g_jump[pts.rows] = pts.jump(Fstar[col[pts.rows]] / p[pts.rows], f_tol[pts.rows])
                    jumped = live & (self._colmax(g_jump.astype(float), 0.0) > 0)
                if np.any(jumped):
                    # committed as its last trial stands (unless a cell failed in it), flagged
                    be.accept((jumped & ~prev_failed)[col])
                jump_cls |= jumped
                live = live & ~jump_cls
                g_live = live[col]
                if not np.any(live):
                    break
            if on_dev:
                strain = be.control.strain
                trials.set_strain(live, strain)
            else:
                strain = np.where(self.single_group, u_single, C_try / C0 - 1.0)
                strain = np.where(g_live, strain, committed_strain)
            # only the cells of the live columns are stepped (the others' trial rows are stale, never read)
            t = be.trial(strain, direction, increment, g_live) if partial else be.trial(strain, direction, increment)
            last = t
            if on_dev:
                judged = trials.judge(be.last_read, live, STATUS_OK, STATUS_FORCE_CAP)
                any_failed, any_capped = judged["failed"], judged["capped"]
            else:
                failed = t["status"] != STATUS_OK
                any_failed = self._colmax((failed & g_live).astype(float), 0.0) > 0
                any_capped = self._colmax(((t["status"] == STATUS_FORCE_CAP) & g_live).astype(float), 0.0) > 0
            prev_failed = np.where(live, any_failed, prev_failed)
            # any trial of the increment, not only the last: the bisection towards a trial stopped at the cap keeps
            # the last one just below it (a blind probe's zone capped at 0.12 N: held, not stopped, then resumed
            # on the grip's reversal at 66 N per wale)
            prev_capped = prev_capped | (live & any_capped)
            iters[live] += 1
            # each good trial's own tangent (before the converged columns are accepted: the backend
            # keeps it as the committed state's); on the device the good trials are marked there
            if on_dev:
                kt = be.good_trial_tangents() if be.good_trials() else None
            else:
                use = g_live & ~failed
                kt = (be.tangent(True, mask=use) if partial else be.tangent(True)) if np.any(use) else None
            # convergence: equal forces at a positive column force (the lengths then add up to u by
            # construction), or every cell slack where the column was asked for zero force; a cell that
            # failed in the trial never converges its column
            if on_dev:
                Fmax, Fmin, gap = judged["F_max"], judged["F_min"], np.abs(judged["n_dC"] - u)
            else:
                Ftot = p * t["F"]                      # the total force each cell's block carries
                Fmax = self._colmax(np.where(g_live, Ftot, -np.inf), -np.inf)
                Fmin = -self._colmax(np.where(g_live, -Ftot, -np.inf), -np.inf)
                # a column carrying force must also close: its lengths add up to u.  By construction where
                # every cell reaches the length it was sent to; not where the direction kept them from it
                # (unloading from a column held short of the grip, which had not converged: the cells keep the
                # held lengths, their forces agree, and the grip is elsewhere; a blind probe found such rows
                # reported ok)
                gap = np.abs(self._colsum(np.where(g_live, cnt * (t["C"] - C0), 0.0)) - u)
            tol = self.force_tol + self.force_rtol * np.abs(Fmax)
            # a column asked for zero force: converged when no cell carries force (slack, or a cell
            # that has just left slack at F = 0 to rounding)
            all_slack = Fmax <= tol
            # a single-group column is the cell itself at the grip strain: its trial is final, failed
            # or not (a failed cell stops its column, flagged, exactly as the single cell stops)
            closes = gap <= LENGTH_RTOL * col_length
            conv = live & (single_cls | (~any_failed & ((((Fmax - Fmin) <= tol) & (Fstar > 0) & closes)
                                                         | (all_slack & (Fstar == 0)))))
            if np.any(conv):
                be.accept(conv[col])
                done_cls |= conv
            if kt is None:
                continue
            spread = np.where(live, Fmax - Fmin, np.inf)
            cls_stalled = spread > 0.25 * spread_last
            spread_last = np.where(live, spread, spread_last)
            if on_dev:
                # the NumPy lines below, one thread per group
                trials.book_trial(pts, be.last_read, live, kt, *be.slide_onsets, Fcol, cls_stalled,
                                  self.force_tol, self.force_rtol, direction, STATUS_OK, int(Stage.SLACK))
                continue
            col_stalled = cls_stalled[col]
            pts.record(use, t["F"], Fstar[col] / p, (self.force_tol + self.force_rtol * Fstar[col]) / p,
                       col_stalled)
            slack = t["stage"] == int(Stage.SLACK)
            kt = np.where(np.isfinite(kt) & (kt > 0) & ~slack, kt, np.nan)
            pts.add(use, t["C"], t["F"], kt, Fcol[col] / p)
            # the slide onset a trial crossed (its last event; it ends sliding) is a point of the cell's branch
            # exactly at its kink, where stick turns into sliding and the model's tangents disagree most: at the
            # rest-state start a column's cells slide one after another, and without these points its trials
            # crept onto each cell's kink (20-30 trials; 3-5 with them); its own slopes are not known (NaN)
            # (a backend that locates no events gives none). Only from a committed stick state: a trial from
            # slack goes through the reload first, and there the onset's force (a few mN, located to the cell
            # solver's tolerance) left the trials' spread stalled at 8x the column's tolerance
            sC, sF = t.get("slide_C"), t.get("slide_F")
            if sC is not None:
                kink = use & stick & np.isfinite(sC) & (sF > 0) & ((sC - t["C"]) * direction < 0)
                if np.any(kink):
                    pts.add(kink, sC, sF, np.full(be.n, np.nan), Fcol[col] / p)
            # the fallback tangent: the cell's own, else the secant from its last good trial
            dC = t["C"] - C_last
            with np.errstate(divide="ignore", invalid="ignore"):
                ks = (t["F"] - F_last) / dC
            ks = np.where(np.isfinite(ks) & (ks > 0) & (np.abs(dC) > 1e-12 * C0), ks, np.nan)
            knew = np.where(np.isfinite(kt), kt, ks)
            self.k = np.where(use & np.isfinite(knew), np.clip(np.nan_to_num(knew, nan=1.0), *self.k_bounds),
                              self.k)
            F_last = np.where(use, t["F"], F_last)
            C_last = np.where(use, t["C"], C_last)
            # a failed trial: no longer than halfway to it from the cell's last good length (or no shorter)
            # (the length asked of it: a failed cell reports the state it stopped in)
            gf = g_live & failed & ~self.single_group
            fail_hi = np.where(gf & (C_try > C_last), np.minimum(fail_hi, C_try), fail_hi)
            fail_lo = np.where(gf & (C_try < C_last), np.maximum(fail_lo, C_try), fail_lo)
            good_hi = np.where(use, np.maximum(good_hi, t["C"]), good_hi)
            good_lo = np.where(use, np.minimum(good_lo, t["C"]), good_lo)
            fail_hi = np.where(good_hi >= fail_hi, np.inf, fail_hi)
            fail_lo = np.where(good_lo <= fail_lo, -np.inf, fail_lo)
            pts.C_max = np.minimum(dir_max, np.where(np.isfinite(fail_hi), 0.5 * (good_hi + fail_hi), np.inf))
            pts.C_min = np.maximum(dir_min, np.where(np.isfinite(fail_lo), 0.5 * (good_lo + fail_lo), -np.inf))
        if on_dev:
            self.k = trials.fallback_tangents()
        # whether a cell of the column failed in the column's last trial (and whether one stopped at its cap in
        # any of its trials)
        last_failed = prev_failed if last is not None else np.zeros(self.n_cls, bool)
        return done_cls & active_cls, iters, jump_cls, last_failed, prev_capped

    def _solve_columns(self, pts: BranchPoints, u: float, F_guess: np.ndarray,
                       live: np.ndarray, host_lengths: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """The forces F [n_classes] of the columns in ``live`` at which the model lengths add up to u, and
        those lengths C [n_groups] (a slack column: F = 0, every cell a little short of its zero-force
        length); ``pts`` prepared for the live columns' groups.  Elsewhere F is ``F_guess`` and C the
        committed length (not read).  Without ``host_lengths`` (device points) C stays on the device
        (``DeviceColumnSolve.C``) and None is returned for it.

        Phi(F) = sum n_g (C_g(F / p_g) - C0_g) - u is monotone non-decreasing in F: safeguarded Newton
        on it, bisection (or doubling while no upper bound is known) where the Newton step leaves the
        bracket or the slope vanishes.  Each column's iteration is its own: the columns that are not
        live are left out of the sums (their groups are not prepared), not iterated."""
        if pts.on_device:
            return self._device_columns.solve(pts, u, F_guess, live, self.cells["C"] if host_lengths else None)
        rows = pts.rows
        col, cnt, C0, p = self.col[rows], self.cnt[rows], self.C0[rows], self.p[rows]
        colsum = lambda v: np.bincount(col, weights=v, minlength=self.n_cls)   # noqa: E731
        scale = colsum(cnt * C0)
        tol_len = column_length_tolerance(scale)

        def phi(F):
            C, dC = pts.model(F[col] / p)
            return C, colsum(cnt * (C - C0)) - u, colsum(cnt * dC / p)

        zero = np.zeros(self.n_cls)
        C_zero, phi0, _ = phi(zero)
        slack = live & (phi0 >= 0.0)
        lo, hi = zero.copy(), np.full(self.n_cls, np.inf)
        F = np.where(slack, 0.0, np.maximum(F_guess, 0.0))
        F = np.where(live, F, F_guess)
        done = slack | ~live
        C = C_zero
        for _ in range(200):
            C, r, dr = phi(F)
            done |= np.abs(r) <= tol_len
            if np.all(done):
                break
            lo = np.where(~done & (r < 0), F, lo)
            hi = np.where(~done & (r > 0), F, hi)
            with np.errstate(divide="ignore", invalid="ignore"):
                Fn = F - r / dr
            bad = ~np.isfinite(Fn) | (Fn <= lo) | (Fn >= hi)
            grow = np.where(lo > 0, 2.0 * lo, self.force_search[0])
            Fn = np.where(bad, np.where(np.isfinite(hi), 0.5 * (lo + hi), grow), Fn)
            done |= np.isfinite(hi) & (hi - lo <= 4.0 * np.finfo(float).eps * hi)
            # no root below the ceiling (a column held short of the grips, whose cells cannot lengthen
            # on unloading: its lengths never add up to u): the search stops there instead of doubling to
            # overflow; the column does not converge and is flagged, as before
            done |= ~np.isfinite(hi) & (lo >= self.force_search[1])
            F = np.where(done, F, Fn)
        C, r, _ = phi(F)
        # a model with a step (a cell's force jumps, or a stalled cell's clipped tangent) may have no exact
        # root: where the bracket has closed on it, the lengths between the bracket's ends that add up to u
        gap = ~slack & (np.abs(r) > tol_len) & np.isfinite(hi)
        if np.any(gap):
            C_a, r_a, _ = phi(np.where(gap, lo, F))
            C_b, r_b, _ = phi(np.where(gap, hi, F))
            with np.errstate(divide="ignore", invalid="ignore"):
                theta = np.clip(np.where(gap & (r_b > r_a), -r_a / (r_b - r_a), 0.0), 0.0, 1.0)
            C = np.where(gap[col], C_a + theta[col] * (C_b - C_a), C)
        # a column at zero force: drive each cell a little past its zero-force point, so that the
        # cell solver locates its slack event there (and keeps its slack length)
        C_slack = np.clip(C_zero - 1e-6 * C0, pts.C_min[rows], pts.C_max[rows])
        C = np.where(slack[col], C_slack, C)
        C_all = self.cells["C"].copy()
        C_all[rows] = C
        return F, C_all
