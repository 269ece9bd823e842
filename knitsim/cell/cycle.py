"""The load cycle of one cell: Table 4 sequencing under strain control (NumPy reference).

:func:`run_cell` drives one quarter-stitch cell through a
:class:`~knitsim.cell.load_program.LoadProgram` of strains of the course length,
``C = C0 (1 + strain)``.  Each increment solves the stage's four conditions
(:mod:`knitsim.cell.stages`) with :func:`~knitsim.cell.inverse.solve_state`;
stage changes are *events* located inside the increment by a root search on C
(brentq on the event function along the stage's branch), never overshot:

- ``slide``: phi reaches +phimax (loading) / -phimax (unloading);
- ``jam``: W reaches 4 d_jam (``jamming_criterion = "w_4d"``, Hong) or the
  centreline distance between neighbouring heads reaches d_jam
  (``"head_gap"``, :mod:`knitsim.cell.head_gap`: the loops touch); the soft
  condition is then replaced by the active contact, W = 4 d_jam or head gap =
  d_jam (d_jam the in-plane width, d by default);
- ``unjam``: while unloading jammed, the unjammed branch is clear of contact
  again (W >= 4 d_jam, or head gap >= d_jam);
- ``slack``: the force per wale reaches 0 while unloading;
- ``cone``: in SF- with beta frozen, phi reaches +phimax (the stick branch
  leaves the friction cone on the far side); beta is released and T frozen
  (``stick_closure``, :mod:`knitsim.cell.stages`);
- ``force_cap``: the force per wale reaches ``force_cap_N`` (the cell stops).

Dahl friction (``friction = "dahl"``) replaces the stick/slide switch by the
Dahl update of tan(phi) with the slip xi = -s_BC (Dahl 1976, alpha = 1):
``tan(phi) = s m + (tan(phi_old) - s m) exp(-sigma |dxi| / m)``; the slip of an
increment is found by a scalar root search on the slip, each trial a solve
with s_BC imposed.  This nested method is deliberately different from the Warp
kernel, which solves the Dahl relation as a fifth Newton residual: the two are
independent checks of each other.

Every recorded row also carries ``head_gap`` (W - 2 X_max, mm) and
``interpenetrating`` (1.0 where head_gap < d_jam, else 0.0; d_jam is the
in-plane width ``in_plane_width``, d by default) in ``values``, as the Warp
batch does: W = 4d lets the heads overlap before it is reached (docs/model.md,
"Jamming").

Frictionless cells (m = 0, Coulomb) keep the soft condition of the loading
branch on reversal: without friction nothing can dissipate, and with the
same four conditions loading and unloading retrace one curve.

A solve that lands on another branch (|phi| >= pi/2: the contact force would
point out of the loop head) counts as failed and the increment is halved.

A failed solve is retried on a halved sub-step, down to SUBSTEP_FLOOR C0 (at
most ``max_halvings`` halvings in a row; :mod:`knitsim.cell.stages`); if it
still fails the cell stops, flagged with its reason, and its later rows repeat
the last converged state with the flag set: no NaN is reported as a result.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from ..friction.dahl import dahl_increment
from .head_gap import head_gap
from .inverse import TOL_STALLED, initial_state, solve_state
from .load_program import LoadProgram
from .material import CellParams
from .quantities import UNKNOWN_NAMES
from ..errors import KnitsimInputError
from .stages import (
    EVENT_TOL, MAX_DAHL_HALVINGS, MAX_HALVINGS, OPENING_BISECTIONS, OPENING_XTOL, PROBE_STEP, REACHED_RTOL,
    RELOAD_RHO_SEED, STICK_CLOSURES, SUBSTEP_FLOOR, ZERO_CONTACT, Stage, stage_label,
)

from .history import (  # noqa: E402  (re-exported)
    HEAD_GAP_QUANTITIES, HISTORY_QUANTITIES, STATUS_EVENT_NOT_LOCATED, STATUS_FORCE_CAP, STATUS_NAMES,
    STATUS_NO_REST_STATE,
    STATUS_NO_CONVERGENCE, STATUS_OK, BatchHistory, head_gap_values, rest_at_cap_reason, solver_stop_reason,
)


@dataclass
class CellState:
    """Evolving state of one cell (everything the next increment needs).

    ``x`` = (alpha, beta, gamma, phi, P); ``C`` the cell's course length (it
    stays at ``C_slack`` while slack); ``frozen_sbc`` and ``frozen_soft`` are
    the values frozen at the entry of the stage, ``soft`` the name of the soft
    condition.
    """

    x: np.ndarray
    q: dict
    stage: Stage
    jammed: bool
    soft: str
    frozen_soft: float
    frozen_sbc: float
    C: float
    status: int = STATUS_OK
    reason: str = ""

    def copy(self) -> "CellState":
        """An independent copy (``x`` and ``q`` copied)."""
        return CellState(self.x.copy(), dict(self.q), self.stage, self.jammed, self.soft,
                         self.frozen_soft, self.frozen_sbc, self.C, self.status, self.reason)


#: quantities of the located state stored with each stage-change event
EVENT_QUANTITIES = ("phi", "W", "F", "T", "head_gap")


class _SolveFailed(Exception):
    pass


def _with_gap(q: dict, x, B: float, d: float) -> dict:
    """Add the head gap to a solved state's quantities (costly: only where needed)."""
    if "head_gap" not in q:
        q["head_gap"] = float(head_gap(*x, B, d, a=float(x[0] - x[2])))
    return q


def _q(result, B: float, d: float, gap: bool = True) -> dict:
    st = result.state
    q = {n: float(getattr(st, n)) for n in
         ("alpha", "beta", "gamma", "phi", "P", "W", "C", "L", "s_AB", "s_BC", "T", "M", "R", "Rn", "Rt", "F")}
    return _with_gap(q, result.x, B, d) if gap else q



def _no_contact(q: dict) -> bool:
    """|R| <= ZERO_CONTACT P: no contact force, phi undetermined (stages.ZERO_CONTACT)."""
    return abs(q["R"]) <= ZERO_CONTACT * max(abs(q["P"]), 1e-12)


def _seed_contact(x: np.ndarray, q: dict) -> np.ndarray:
    """Newton start at a zero-contact state with R/P = RELOAD_RHO_SEED (singular at 0).

    R/P = -sin(gamma) / cos(beta + phi) (eq 7), so gamma moves, alpha - gamma kept.
    """
    if not _no_contact(q):
        return x
    alpha, beta, gamma, phi, P = x
    g = math.asin(max(-1.0, min(1.0, -RELOAD_RHO_SEED * math.cos(beta + phi))))
    return np.array([g + (alpha - gamma), beta, g, phi, P])


def _slack_function(q_end: dict):
    """The function a fired slack event is located on, from the sub-step's end ``q_end``: -F, or -Rn where
    only the contact opened there (Rn < 0 while F >= 0: F only touched 0, or dipped below it and came
    back inside the sub-step; R = 0 is a zero of F too, eq 7).  The Warp kernel decides the same way
    (event_condition_at)."""
    if q_end["F"] >= 0.0 and q_end["Rn"] < 0.0:
        return lambda q: -q["Rn"]
    return lambda q: -q["F"]


class CellCycle:
    """Advance one cell through a strain program (NumPy reference).

    Parameters
    ----------
    params : CellParams
        The cell (validated here).
    max_halvings : int
        Most halvings in a row of a failed sub-step before the cell is flagged
        (halving also stops at SUBSTEP_FLOOR C0: :mod:`knitsim.cell.stages`).
    stick_closure : str
        What gives way when a stick stage whose soft condition is beta (Table 4
        SF-, or the mirror SF+ on reloading) asks for a friction angle beyond
        the cone on the far side: ``"release_beta"`` (default: event ``cone``,
        the stick stays and beta is released for T / Rn) or ``"table4"`` (as
        printed: no such event).  See :mod:`knitsim.cell.stages`.
    """

    def __init__(self, params: CellParams, max_halvings: int = MAX_HALVINGS, stick_closure: str = "release_beta"):
        self.p = params.validated()
        if self.p.effects.on:
            raise KnitsimInputError(f"effects = {list(self.p.effects.on)!r}: the model extensions run in the Warp "
                                    "batch only (engine = 'warp'), not in the NumPy reference")
        if stick_closure not in STICK_CLOSURES:
            raise KnitsimInputError(f"stick_closure = {stick_closure!r}: expected one of {', '.join(STICK_CLOSURES)}")
        self.stick_closure = stick_closure
        self.max_halvings = max_halvings
        self.phimax = self.p.phimax
        self.floor_steps_left = MAX_FLOOR_STEPS          # (reset by each increment: advance, _advance_dahl)

    # ----------------------------------------------------------------- set-up
    def initial(self) -> CellState:
        """Table 4 initialisation: C = C0, W = W0, L, phi = phi0."""
        p = self.p
        try:
            res = initial_state(p.C0, p.W0, p.L, p.phi0, p.B, p.d)
        except RuntimeError as exc:
            # no start of the inverse converged: no rest state, flagged as the Warp batch flags it (a tight
            # loop, L = 10.3 with the paper's W0 and C0, raised this out of run_cell: a blind probe)
            raise _SolveFailed(f"initial state: {exc}") from None
        if not res.success:
            raise _SolveFailed("initial state: " + res.message)
        q = _q(res, p.B, p.d)
        st = CellState(res.x, q, Stage.SF_LOAD, False, "Rn", q["Rn"], q["s_BC"], q["C"])
        if p.friction == "coulomb" and p.phi0 >= self.phimax - 1e-12:
            # phi0 = phimax: at the sliding limit already; m = 0 (frictionless,
            # phi0 = 0 = phimax) slides from the start
            st.stage = Stage.S_LOAD
        return st

    # ------------------------------------------------------------ conditions
    def conditions(self, st: CellState, C: float) -> dict:
        """The four imposed quantities of the cell's stage at course length C."""
        p = self.p
        cond = {"L": p.L, "C": C}
        if st.stage in (Stage.SF_LOAD, Stage.SF_UNLOAD):
            cond["s_BC"] = st.frozen_sbc
        elif st.stage is Stage.S_LOAD:
            cond["phi"] = self.phimax
        elif st.stage is Stage.S_UNLOAD:
            cond["phi"] = -self.phimax
        if st.jammed:
            cond.update(self._contact())
        else:
            cond[st.soft] = st.frozen_soft
        return cond

    def _contact(self) -> dict:
        """The condition of the active jamming contact: W = 4 d_jam, or head gap = d_jam."""
        p = self.p
        return {"head_gap": p.d_jam} if p.jamming_criterion == "head_gap" else {"W": 4.0 * p.d_jam}

    def _clearance(self, q: dict) -> float:
        """How far a state is from jamming [mm] (>= 0 clear): W - 4 d_jam, or head gap - d_jam."""
        p = self.p
        if p.jamming_criterion == "head_gap":
            return q["head_gap"] - p.d_jam
        return q["W"] - 4.0 * p.d_jam

    def _solve(self, cond: dict, guess) -> tuple[np.ndarray, dict]:
        res = solve_state(cond, guess, self.p.B, self.p.d,
                          tol_stalled=TOL_STALLED if self.floor_steps_left > 0 else 0.0)
        if res.status == 2:
            self.floor_steps_left -= 1
        if not res.success:
            raise _SolveFailed(res.message)
        phi = float(res.x[3])
        # a contact force beyond the tangent plane at B (|phi| >= pi/2) is another
        # branch of the equations, not the continuation of this one
        if not abs(phi) < 0.5 * math.pi:
            raise _SolveFailed(f"solution left the branch (phi = {phi:.4g} rad)")
        # the head gap is only needed on every solve by the head-gap criterion;
        # otherwise it is added to accepted states (rows and events) only
        return res.x, _q(res, self.p.B, self.p.d, gap=self.p.jamming_criterion == "head_gap")

    def _dahl_solve(self, st: CellState, C: float, guess) -> tuple[np.ndarray, dict]:
        """Solve one Dahl increment: find the slip whose Dahl update matches phi."""
        p = self.p
        base = {"L": p.L, "C": C}
        if st.jammed:
            base.update(self._contact())
        else:
            base[st.soft] = st.frozen_soft
        t_old = math.tan(st.q["phi"])
        s_old = st.q["s_BC"]
        cache = {}

        def at_slip(xi):
            cond = dict(base, s_BC=s_old - xi)
            x, q = self._solve(cond, cache.get("x", guess))
            cache["x"], cache[xi] = x, (x, q)
            return math.tan(q["phi"]) - float(dahl_increment(t_old, xi, p.dahl_sigma, p.m))

        r0 = at_slip(0.0)
        if r0 == 0.0:
            return cache[0.0]
        s = 1.0 if r0 > 0 else -1.0        # stick would raise tan(phi): slip forward
        hi = 1e-4 * p.d
        for _ in range(60):
            try:
                rh = at_slip(s * hi)
            except _SolveFailed:
                hi *= 0.5
                cache.pop("x", None)
                continue
            if rh * r0 <= 0:
                break
            hi *= 2.0
        else:
            raise _SolveFailed("Dahl slip not bracketed")
        xi = brentq(at_slip, 0.0, s * hi, xtol=1e-14, rtol=1e-13, maxiter=200)
        return cache[xi] if xi in cache else self._solve(dict(base, s_BC=s_old - xi), cache["x"])

    def solve_at(self, st: CellState, C: float, guess=None) -> tuple[np.ndarray, dict]:
        """Equilibrium of the cell's current stage at course length C."""
        guess = st.x if guess is None else guess
        if self.p.friction == "dahl":
            return self._dahl_solve(st, C, guess)
        return self._solve(self.conditions(st, C), guess)

    # ---------------------------------------------------------------- events
    def event_functions(self, st: CellState) -> dict:
        """Signed event functions of the stage, positive once the event happened."""
        p = self.p
        ev = {}
        loading = st.stage in (Stage.SF_LOAD, Stage.S_LOAD)
        if p.friction == "coulomb":
            if st.stage is Stage.SF_LOAD and p.m > 0:
                ev["slide"] = lambda q: q["phi"] - self.phimax
            elif st.stage is Stage.SF_UNLOAD and p.m > 0:
                ev["slide"] = lambda q: -self.phimax - q["phi"]
                if st.soft == "beta" and self.stick_closure == "release_beta":
                    # SF- (beta frozen) asks for friction beyond the cone on the far
                    # side (+phimax): the beta closure, not the stick, gives way
                    ev["cone"] = lambda q: q["phi"] - self.phimax
        if not st.jammed:
            # Hong's W = 4 d_jam, or the heads touch (module head_gap)
            ev["jam"] = lambda q: -self._clearance(q)
        if loading:
            ev["force_cap"] = lambda q: q["F"] - p.cap_N
        else:
            # the load vanishes (F -> 0) or the contact opens (Rn -> 0): eq 7, R_Y = -R cos(beta + phi) =
            # P sin(gamma), gives F = -2 R cos(beta + phi), so R = 0 is F = 0 and the cell goes slack
            # there.  Where beta + phi passes pi/2 at the same point, F only touches 0 (both factors change
            # sign) and the branch goes on with a pulling contact, R < 0 (outside the model: the contact at
            # B is unilateral); Rn changes sign there, and the event is located on it when only Rn has
            # crossed at the sub-step's end (_slack_function).  Missing it let
            # a reload freeze a tensile Rn, and the SF+ stick then left the cone on the far side
            # (tan(phi) = Rt / Rn falls to -m as loading raises Rt: stages.py, "far side")
            ev["slack"] = lambda q: max(-q["F"], -q["Rn"])
        return ev

    def _transition(self, st: CellState, kind: str) -> None:
        """Apply the stage change of a located event (state already at the event)."""
        q = st.q
        if kind == "slide":
            if st.stage is Stage.SF_LOAD:
                # Table 4 S+ freezes Rn; a reload that mirrors the unloading (beta frozen in SF+,
                # entered at zero contact) mirrors S- too and freezes T: its Rn is ~0 there, and
                # {L, C, phi, Rn = 0} is solved by the zero-contact family at F = 0 for every C
                # (stages.py, "reload_rule")
                st.stage, st.soft = Stage.S_LOAD, ("T" if st.soft == "beta" else "Rn")
            else:
                st.stage, st.soft = Stage.S_UNLOAD, "T"
            st.frozen_soft = q[st.soft]
        elif kind == "cone":
            # stick kept (s_BC frozen), the beta closure released: SF- goes on with
            # T frozen (Hong's rule) from here
            st.soft = "T"
            st.frozen_soft = q[st.soft]
        elif kind == "jam":
            st.jammed = True
        elif kind == "unjam":
            st.jammed = False
        elif kind == "slack":
            st.stage = Stage.SLACK
        elif kind == "force_cap":
            st.status, st.reason = STATUS_FORCE_CAP, "force per wale reached force_cap_N"

    def reverse(self, st: CellState, direction: int) -> None:
        """Load reversal: enter SF- (unloading) or SF+ (reloading), freezing values."""
        p, q = self.p, st.q
        st.frozen_sbc = q["s_BC"]
        if p.friction == "coulomb" and p.m == 0:
            # frictionless: one curve for loading and unloading (no dissipation),
            # so the soft condition of the loading branch stays frozen
            st.stage = Stage.S_LOAD if direction > 0 else Stage.S_UNLOAD
            return
        if direction < 0 and _no_contact(q):
            # no contact force to unload (e.g. reloaded at zero force after going
            # slack): the cell is slack at once
            st.stage = Stage.SLACK
            return
        if direction < 0:
            st.stage = Stage.SF_UNLOAD
            st.soft = "T" if (p.unloading_rule == "hong_constant_t" or p.friction == "dahl") else "beta"
        else:
            st.stage = Stage.SF_LOAD
            tiny = abs(q["Rn"]) < ZERO_CONTACT * max(q["P"], 1e-12)
            # the mirror of the unloading from zero contact: SF- freezes beta (Coulomb; S+ then T), Dahl's
            # unloading T throughout (Rn frozen at ~0 is the zero-contact family, where a Dahl solve is singular)
            mirror = tiny and p.reload_rule == "mirror_unloading"
            st.soft = ("T" if p.friction == "dahl" else "beta") if mirror else "Rn"
        st.frozen_soft = q[st.soft]

    # --------------------------------------------------------------- advance
    def _try_unjam(self, st: CellState, C_target: float):
        """Active set: the unjammed branch at C_target, if it is clear of contact (W >= 4 d_jam, or
        head gap >= d_jam).  Where it has no solution (it can end while the jammed one goes on: the
        beta-frozen SF- stick runs to phi = pi/2) the cell stays jammed."""
        if not st.jammed or st.stage in (Stage.SF_LOAD, Stage.S_LOAD):
            return None
        trial = st.copy()
        trial.jammed = False
        try:
            x, q = self.solve_at(trial, C_target)
        except _SolveFailed:
            return None
        return (x, q) if self._clearance(_with_gap(q, x, self.p.B, self.p.d)) >= 0.0 else None

    def _unjam_at_start(self, st: CellState, C_goal: float) -> bool:
        """Whether a jammed unloading cell whose jammed branch has no solution toward C_goal unjams at its
        C itself: the unjammed branch passes through its state (clearance >= -EVENT_TOL d_jam there) and
        is clear of contact at C_goal (the kernel's unjam_at_start; the jammed S- after a slide has no
        solution on unloading while the unjammed S- passes through the slide point and opens)."""
        if not st.jammed or st.stage in (Stage.SF_LOAD, Stage.S_LOAD):
            return False
        trial = st.copy()
        trial.jammed = False
        try:
            xa, qa = self.solve_at(trial, st.C)
        except _SolveFailed:
            return False
        if self._clearance(_with_gap(qa, xa, self.p.B, self.p.d)) < -self._event_tol("unjam"):
            return False
        start = st.copy()                       # jammed, at the unjammed branch's state (the guess)
        start.x, start.q = xa, qa
        return self._try_unjam(start, C_goal) is not None

    def _sign_change(self, st: CellState, C_goal: float, name) -> tuple[float, np.ndarray, dict]:
        """The last state of the branch before ``Rn`` (the contact opens), ``F``, or a function of the state
        (``name`` callable: phimax - phi, the cone) turns negative inside
        the sub-step st.C -> C_goal, the quantity >= 0 at st.C and < 0 at C_goal: bisection on its sign,
        each point solved from the last state where it is >= 0; a point with no solution counts as past
        the change (the kernel's branch_sign_change).

        Why not a root search with Newton: R = 0 is singular (phi drops out of every equation), Rn = 0
        is met at phi = -pi/2 as well (any R), and where the branch reaches Rn = 0 at |phi| -> pi/2
        (a stick stage whose tangential force outlives the normal one: SF- with beta frozen) it leaves
        the chart |phi| < pi/2 there and comes back with R < 0.  Along the branch the sign of Rn is
        what the unilateral contact needs, and it is well defined at every converged state.

        Returns (C_a, x_a, q_a), the quantity >= 0 at C_a, within OPENING_XTOL max(1, C) of where it is < 0
        (C_a the solved course length of q_a; st.C where the quantity is < 0 at every point tried)."""
        Ca, xa, qa = st.C, st.x, st.q
        Cb = C_goal
        for _ in range(OPENING_BISECTIONS):
            if abs(Cb - Ca) <= OPENING_XTOL * max(1.0, abs(Cb)):
                break
            Cm = 0.5 * (Ca + Cb)
            try:
                xm, qm = self.solve_at(st, Cm, xa)
            except _SolveFailed:
                Cb = Cm
                continue
            if (name(qm) if callable(name) else qm[name]) >= 0.0:
                Ca, xa, qa = Cm, xm, qm
            else:
                Cb = Cm
        return (Ca if Ca == st.C else qa["C"]), xa, dict(qa)

    def _may_halve(self, failures: int, step: float) -> bool:
        """Whether a failed sub-step is retried on half its length: at most ``max_halvings`` times in
        a row, and not below SUBSTEP_FLOOR C0 (stages.SUBSTEP_FLOOR)."""
        return failures <= self.max_halvings and 0.5 * abs(step) >= SUBSTEP_FLOOR * self.p.C0

    def _event_tol(self, kind: str) -> float:
        """Tolerance below which an event function counts as zero (stages.EVENT_TOL, in the cell's units: rad,
        d for W, B / d^2 for F and Rn)."""
        force = self.p.B / self.p.d ** 2
        unit = {"slide": 1.0, "cone": 1.0, "jam": self.p.d, "unjam": self.p.d, "slack": force, "force_cap": force}[kind]
        return EVENT_TOL * unit

    def _locate(self, st: CellState, C_a: float, C_b: float, name: str, fun, unjam=False):
        """Root of an event function on [C_a, C_b] along the stage's branch.

        An event whose function is already zero (within :data:`EVENT_TOL`) at
        the start of the sub-step happens at the start (e.g. unjamming at the
        reversal from a jammed state, where the unjammed branch passes through
        the jammed state itself): no root search, whose bracket rounding could
        miss.
        """
        trial = st.copy()
        if unjam:
            trial.jammed = False

        def e(C):
            x, q = self.solve_at(trial, C, trial.x)
            trial.x = x                      # continuation guess only (Dahl reads trial.q)
            return fun(q) if not unjam else self._clearance(_with_gap(q, x, self.p.B, self.p.d))

        tol = self._event_tol(name)
        if unjam:
            try:
                fa = e(C_a)
            except _SolveFailed:
                fa = None
        else:
            fa = fun(st.q)                   # the state at C_a is the cell's own
        if fa is not None and fa < -tol and not unjam and _no_contact(st.q):
            # phi is undetermined at a zero-contact start: judge the event on a probe
            # step (the new branch's limit); if it holds there, or the probe fails,
            # the event happens at the start
            C_p = C_a + math.copysign(PROBE_STEP * self.p.C0, C_b - C_a)
            try:
                _, q_p = self.solve_at(trial, C_p, _seed_contact(st.x, st.q))
                if fun(q_p) >= -tol:
                    fa = 0.0
            except _SolveFailed:
                fa = 0.0
        if fa is not None and fa >= -tol and name == "cone" and not _no_contact(st.q):
            # zero at the start, but _cone_at_start's probe stayed inside the cone: the branch dips into
            # the cone and leaves it further on, located by bisection on the sign of phimax - phi
            Ce, xe, qe = self._sign_change(st, C_b, lambda q: self.phimax - q["phi"])
            if Ce == st.C:
                raise _SolveFailed("event cone: zero at the start, inside the cone on the probe")
            return Ce, xe, qe
        if fa is not None and fa >= -tol:
            # the event holds at the start of the sub-step (e.g. reloading from
            # slack, where R = 0 and the contact force leaves the friction cone at
            # once, or unjamming at the reversal point): it happens there
            return C_a, st.x, dict(st.q)
        if fa is None:
            raise _SolveFailed(f"event {name}: no solution at the start of the sub-step")
        trial.x = st.x
        fb = e(C_b)
        if fa * fb > 0:
            raise _SolveFailed(f"event {name} not bracketed")
        try:
            Ce = brentq(e, C_a, C_b, xtol=1e-13 * max(1.0, abs(C_b)), rtol=1e-14, maxiter=200)
        except ValueError as exc:           # the branch moved under the search
            raise _SolveFailed(f"event {name}: {exc}") from None
        x, q = self.solve_at(trial, Ce, trial.x)
        return Ce, x, q

    def _cone_at_start(self, st: CellState, C_target: float) -> bool:
        """Whether the ``cone`` event happens at the cell's C itself.

        At a reversal from sliding (phi = +/-phimax) the cone function is zero
        at the start; whether the beta-frozen stick branch leaves the cone is
        then judged on a probe step of PROBE_STEP C0 toward the target (or the
        branch does not continue at all: the closure gives way as well).
        """
        fun = self.event_functions(st).get("cone")
        if fun is None or abs(fun(st.q)) > self._event_tol("cone"):
            return False
        C_p = st.C + math.copysign(PROBE_STEP * self.p.C0, C_target - st.C)
        try:
            _, q = self.solve_at(st, C_p)
        except _SolveFailed:
            return True
        return fun(q) > 0

    def _slide_at_start(self, st: CellState, C_target: float) -> bool:
        """Whether a stick stage starting at zero contact force slides at once.

        With R = 0 (e.g. reloading from slack) phi is undetermined at the start,
        so whether the contact force of the new branch lies in the friction cone
        is judged on a probe step of PROBE_STEP C0 toward the target (Newton from
        R/P = RELOAD_RHO_SEED); if the probe has no solution the contact cannot
        stick either (stages.ZERO_CONTACT).
        """
        if self.p.friction != "coulomb" or st.stage not in (Stage.SF_LOAD, Stage.SF_UNLOAD):
            return False
        fun = self.event_functions(st).get("slide")
        if fun is None or not _no_contact(st.q):
            return False
        C_p = st.C + math.copysign(PROBE_STEP * self.p.C0, C_target - st.C)
        try:
            _, q = self.solve_at(st, C_p, _seed_contact(st.x, st.q))
        except _SolveFailed:
            return True
        # with no contact force no tangential force can be held: a probe beyond either edge of the cone
        # slides (the far edge only reflects the sign of the seed's R, not a direction of slip: the
        # imposed motion sets that, toward +phimax when loading; stages.py, "far side")
        tol = self._event_tol("slide")
        return fun(q) >= -tol or abs(q["phi"]) >= self.phimax - tol

    def advance(self, st: CellState, C_target: float, events: list, increment: int) -> CellState:
        """Move the cell from its C to ``C_target`` on its branch, handling events.

        The increment is walked in sub-steps: a failed solve halves the
        sub-step (up to ``max_halvings`` times in a row), a successful one
        doubles it back, and events are checked and located on every sub-step,
        so that an event whose branch ends soon after it (e.g. SF- beyond
        phi = -phimax) is found from the last converged sub-step.
        """
        if st.status != STATUS_OK:
            return st
        # the increment's budget of floor-accepted solves (MAX_FLOOR_STEPS), here so that every caller (run, the
        # patch coupling's reference backend, a trial of it) has it per increment
        self.floor_steps_left = MAX_FLOOR_STEPS
        if st.stage is Stage.SLACK:
            if C_target - st.C <= REACHED_RTOL * C_target:
                return st
            self.reverse(st, +1)
            st.x = _seed_contact(st.x, st.q)
            events.append({"increment": increment, "kind": "reload", "C": st.C})
        step = C_target - st.C
        failures = 0
        n_events = 0
        while True:
            C_from = st.C
            if abs(C_target - C_from) <= REACHED_RTOL * C_target:
                return st
            if abs(step) > abs(C_target - C_from):
                step = C_target - C_from
            C_goal = C_from + step
            at_start = ("cone" if self._cone_at_start(st, C_target)
                        else "slide" if self._slide_at_start(st, C_target) else None)
            if at_start is not None:
                before = stage_label(st.stage, st.jammed)
                self._transition(st, at_start)
                events.append({"increment": increment, "kind": at_start, "C": st.C, "from": before,
                               "to": stage_label(st.stage, st.jammed),
                               **{k: _with_gap(st.q, st.x, self.p.B, self.p.d)[k] for k in EVENT_QUANTITIES}})
                n_events += 1
                continue
            try:
                x, q = self.solve_at(st, C_goal)
            except _SolveFailed:
                if self._unjam_at_start(st, C_goal):
                    # the jammed branch ends here on unloading, the unjammed one opens: unjam at the start
                    before = stage_label(st.stage, st.jammed)
                    self._transition(st, "unjam")
                    events.append({"increment": increment, "kind": "unjam", "C": st.C, "from": before,
                                   "to": stage_label(st.stage, st.jammed),
                                   **{k: _with_gap(st.q, st.x, self.p.B, self.p.d)[k] for k in EVENT_QUANTITIES}})
                    n_events += 1
                    continue
                failures += 1
                if not self._may_halve(failures, step):
                    raise _SolveFailed(f"no convergence from C = {C_from:.6g} to {C_goal:.6g} mm "
                                       f"(sub-step {abs(step):.3g} mm, {failures - 1} halvings)") from None
                step *= 0.5
                continue
            opened = st.stage not in (Stage.SF_LOAD, Stage.S_LOAD) and q["Rn"] < 0.0
            if opened:
                # the trial end pulls: the contact opened inside the sub-step (the branch went through
                # Rn = 0 and on with R < 0, outside the model).  The sub-step ends where it opens, and every
                # event is judged on that part of the branch (a stick leaves the cone there first)
                C_goal, x, q = self._sign_change(st, C_goal, "Rn")
            evs = self.event_functions(st)
            if opened:
                evs.pop("slack", None)          # decided below, on the part of the branch before the opening
            fired = [(k, _slack_function(q) if k == "slack" else f) for k, f in evs.items()
                     if f(q) > 0 and f(st.q) <= self._event_tol(k)]
            unjam = self._try_unjam(st, C_goal)
            if unjam is not None:
                fired.append(("unjam", None))
            best = None
            if opened:
                # eq 7, F = -2 R cos(beta + phi), with R -> 0+ at the opening: where cos(beta + phi) > 0
                # there, F is < 0 just before it, so F reached 0 first at beta + phi = pi/2 (R > 0, a
                # regular zero): bisection on its sign; else the cell goes slack where the contact opens,
                # if R -> 0 there (the friction angle inside the cone); else (Rn -> 0 with a tangential
                # force left and no cone or slide event) the sub-step is halved, like an event that
                # cannot be located
                fired.append(("slack", None))
                if math.cos(q["beta"] + q["phi"]) > 0.0 and st.q["F"] > 0.0:
                    best = ("slack",) + self._sign_change(st, C_goal, "F")
                elif _no_contact(q):
                    best = ("slack", C_goal, x, q)
            if not fired:
                failures = 0
                st.x, st.q, st.C = x, q, C_goal
                step *= 2.0
                continue
            # locate each fired event; the first along the path wins
            for kind, fun in fired:
                if fun is None and kind == "slack":
                    continue
                try:
                    Ce, xe, qe = self._locate(st, C_from, C_goal, kind, fun, unjam=(kind == "unjam"))
                except _SolveFailed:
                    continue
                if best is None or abs(Ce - C_from) < abs(best[1] - C_from):
                    best = (kind, Ce, xe, qe)
            if best is None:
                # the trial end fired an event that its own branch cannot reach: the
                # solve jumped to another branch; retried on a halved sub-step
                failures += 1
                if not self._may_halve(failures, step):
                    st.status, st.reason = STATUS_EVENT_NOT_LOCATED, f"could not locate {fired[0][0]}"
                    return st
                step *= 0.5
                continue
            failures = 0
            kind, Ce, xe, qe = best
            before = stage_label(st.stage, st.jammed)
            st.x, st.q, st.C = xe, qe, Ce
            self._transition(st, kind)
            events.append({"increment": increment, "kind": kind, "C": Ce,
                           "from": before, "to": stage_label(st.stage, st.jammed),
                           **{k: _with_gap(qe, xe, self.p.B, self.p.d)[k] for k in EVENT_QUANTITIES}})
            if st.status != STATUS_OK or st.stage is Stage.SLACK:
                return st
            n_events += 1
            if n_events >= 12:                    # at most a few events per increment
                return st
            step = C_target - st.C

    def run(self, program: LoadProgram, progress: Callable | None = None) -> BatchHistory:
        """Run the whole program; see :func:`run_cell`."""
        p = self.p
        try:
            st = self.initial()
            why = None if st.q["R"] >= 0.0 else f"the contact at B would pull at rest (R = {st.q['R']:.3g} N < 0)"
        except _SolveFailed as exc:
            why = str(exc)
        if why is not None:
            return self._no_rest_state(program, why)
        if st.q["F"] >= p.cap_N:
            st.status, st.reason = STATUS_FORCE_CAP, rest_at_cap_reason(st.q["F"], p.cap_N)
        rest = {k: np.array([st.q[k]]) for k in HISTORY_QUANTITIES}
        rest.update(stage=np.array([int(st.stage)], np.int32), jammed=np.array([int(st.jammed)], np.int32))
        n = len(program)
        stage = np.zeros(n, np.int32)
        jammed = np.zeros(n, np.int32)
        status = np.zeros(n, np.int32)
        vals = {k: np.zeros(n) for k in HISTORY_QUANTITIES + HEAD_GAP_QUANTITIES}
        events: list = []
        direction = +1
        for i in range(n):
            d_i = int(program.direction[i])
            if d_i != direction and st.status == STATUS_OK and st.stage is not Stage.SLACK:
                self.reverse(st, d_i)
                events.append({"increment": i, "kind": "reversal", "C": st.C})
            direction = d_i
            C_target = p.C0 * (1.0 + float(program.strain[i]))
            try:
                if p.friction == "dahl" and st.stage is not Stage.SLACK:
                    st = self._advance_dahl(st, C_target, events, i)
                else:
                    st = self.advance(st, C_target, events, i)
            except _SolveFailed as exc:
                # st is the last converged state (a failed solve leaves it)
                st.status = STATUS_NO_CONVERGENCE
                st.reason = solver_stop_reason(STATUS_NO_CONVERGENCE, st.C / p.C0 - 1.0, float(program.strain[i]),
                                               stage_label(st.stage, st.jammed), float(st.q["F"]), p.cap_N,
                                               d_i > 0) + f" ({exc})"
            if p.friction == "dahl":
                self._label_dahl(st)
            stage[i], jammed[i], status[i] = int(st.stage), int(st.jammed), st.status
            for k in HISTORY_QUANTITIES:
                vals[k][i] = st.q[k]
            _with_gap(st.q, st.x, p.B, p.d)
            vals["head_gap"][i] = st.q["head_gap"]
            if st.stage is Stage.SLACK:
                vals["F"][i] = 0.0
            if st.status != STATUS_OK and not any(e.get("kind") == "flag" for e in events):
                events.append({"increment": i, "kind": "flag", "reason": st.reason,
                               "status": STATUS_NAMES[st.status]})
            if progress is not None:
                progress(i + 1)
        vals.update(head_gap_values(vals["head_gap"], p.d_jam))
        return BatchHistory(np.asarray(program.strain), np.asarray(program.cycle),
                            np.asarray(program.direction), stage[:, None], jammed[:, None],
                            status[:, None], {k: v[:, None] for k, v in vals.items()},
                            [dict(e, cell=0) for e in events], [p], rest)

    def _no_rest_state(self, program: LoadProgram, why: str) -> BatchHistory:
        """History of a cell without an admissible rest state (knitsim.cell.domain.rest_state_problem):
        status no_rest_state on every row, NaN values (there is no state), flagged at increment 0."""
        n = len(program)
        vals = {k: np.full((n, 1), np.nan) for k in HISTORY_QUANTITIES + HEAD_GAP_QUANTITIES}
        rest = {k: np.array([np.nan]) for k in HISTORY_QUANTITIES}
        rest.update(stage=np.array([int(Stage.SF_LOAD)], np.int32), jammed=np.array([0], np.int32))
        events = [{"increment": 0, "kind": "flag", "reason": f"no rest state: {why}",
                   "status": STATUS_NAMES[STATUS_NO_REST_STATE], "cell": 0}]
        return BatchHistory(np.asarray(program.strain), np.asarray(program.cycle), np.asarray(program.direction),
                            np.full((n, 1), int(Stage.SF_LOAD), np.int32), np.zeros((n, 1), np.int32),
                            np.full((n, 1), STATUS_NO_REST_STATE, np.int32), vals, events, [self.p], rest)

    # ------------------------------------------------------------------ Dahl
    def _label_dahl(self, st: CellState) -> None:
        """Dahl has no switch: label sliding once tan(phi) is within 5 % of +/-m."""
        if st.stage is Stage.SLACK:
            return
        loading = st.stage in (Stage.SF_LOAD, Stage.S_LOAD)
        sat = self.p.m if loading else -self.p.m
        sliding = abs(math.tan(st.q["phi"]) - sat) <= 0.05 * self.p.m
        if loading:
            st.stage = Stage.S_LOAD if sliding else Stage.SF_LOAD
        else:
            st.stage = Stage.S_UNLOAD if sliding else Stage.SF_UNLOAD

    def _advance_dahl(self, st: CellState, C_target: float, events: list, increment: int) -> CellState:
        """Dahl increment: the Dahl state moves with the solution (sub-stepped events).

        A failed attempt is retried on 2, 4, ... equal sub-increments from the
        same start; the events of a failed attempt are dropped (each attempt
        collects its own).
        """
        if st.status != STATUS_OK:
            return st
        self.floor_steps_left = MAX_FLOOR_STEPS         # per increment, as in advance
        C_from = st.C
        n = 1
        for _ in range(min(self.max_halvings, MAX_DAHL_HALVINGS) + 1):
            trial = st.copy()
            attempt: list = []
            try:
                for k in range(1, n + 1):
                    C_k = C_from + (C_target - C_from) * k / n
                    trial = self._dahl_step(trial, C_k, attempt, increment)
                    if trial.status != STATUS_OK or trial.stage is Stage.SLACK:
                        break
                events.extend(attempt)
                return trial
            except _SolveFailed:
                n *= 2
        raise _SolveFailed(f"Dahl: no convergence from C = {C_from:.6g} to {C_target:.6g} mm")

    def _dahl_step(self, st: CellState, C_target: float, events: list, increment: int) -> CellState:
        """One Dahl sub-step to C_target; events located by brentq on C (unjam: at C_target)."""
        for _ in range(12):                       # at most a few events per sub-step
            x, q = self.solve_at(st, C_target)
            evs = self.event_functions(st)
            fired = [(k, _slack_function(q) if k == "slack" else f) for k, f in evs.items()
                     if f(q) > 0 and f(st.q) <= self._event_tol(k)]
            unjam = self._try_unjam(st, C_target)
            if not fired and unjam is None:
                st.x, st.q, st.C = x, q, C_target
                return st
            best = None
            for kind, fun in fired:
                if fun(st.q) >= -self._event_tol(kind):
                    Ce = st.C                      # already satisfied at the start
                else:
                    # event along the Dahl path: each trial from the same start state
                    def e(C, fun=fun):
                        return fun(self.solve_at(st, C)[1])
                    try:
                        Ce = brentq(e, st.C, C_target, xtol=1e-12 * C_target, maxiter=200)
                    except ValueError as exc:      # not bracketed: the sub-step fails
                        raise _SolveFailed(f"Dahl event {kind}: {exc}") from None
                if best is None or abs(Ce - st.C) < abs(best[1] - st.C):
                    best = (kind, Ce)
            if unjam is not None and (best is None or abs(C_target - st.C) < abs(best[1] - st.C)):
                # active set, resolved to the sub-step: the cell takes the unjammed
                # solution at the sub-step's end, where it has W >= W_jam
                best = ("unjam", C_target)
            kind, Ce = best
            if kind == "unjam":
                x, q = unjam
            elif Ce == st.C:
                x, q = st.x, dict(st.q)
            else:
                x, q = self.solve_at(st, Ce)
            before = stage_label(st.stage, st.jammed)
            st.x, st.q, st.C = x, q, Ce
            self._transition(st, kind)
            events.append({"increment": increment, "kind": kind, "C": Ce, "from": before,
                           "to": stage_label(st.stage, st.jammed)})
            if st.status != STATUS_OK or st.stage is Stage.SLACK or Ce == C_target:
                return st
        return st


#: most solves of one increment that a load step's Newton ends at its residuals' rounding floor
#: (knitsim.cell.inverse.TOL_STALLED); past them the increment asks for the full tolerance again.  Where the
#: floor is reached on every solve the branch is steeper than this engine's chart resolves (a jammed force
#: near its asymptote): the accepted states random-walked there in sub-steps of ~1e-9 mm, 6,000 solves and
#: 320 s an increment, toward a cap the Warp engine reaches (a blind probe's random domain cells)
MAX_FLOOR_STEPS = 64


def run_cell(params: CellParams, program: LoadProgram, max_halvings: int = MAX_HALVINGS,
             stick_closure: str = "release_beta", progress: Callable | None = None) -> BatchHistory:
    """Run one cell through a strain program (NumPy reference).

    Parameters
    ----------
    params : CellParams
        The cell; validated before any solve.
    program : LoadProgram
        Imposed strains of the course length, ``C = C0 (1 + strain)``.
    max_halvings : int
        Most halvings in a row of a failed sub-step (also bounded by SUBSTEP_FLOOR C0).
    stick_closure : str
        ``"release_beta"`` (default) or ``"table4"``; see :mod:`knitsim.cell.stages`.
    progress : callable, optional
        ``progress(done_increments)`` after each increment (a hard increment of this float64 reference can take
        minutes: a Dahl cell from a compressive rest state took 25-56 s an increment).

    Returns
    -------
    BatchHistory
        One row per increment, one column; ``events`` lists located stage changes.
    """
    if not isinstance(program, LoadProgram) or len(program) == 0:
        # as run_batch: a list of strains raised AttributeError inside, an empty program gave an empty history
        raise KnitsimInputError(f"program = {program!r}: expected a non-empty LoadProgram (knitsim.cell.load_program)")
    if not isinstance(params, CellParams):
        # (a dict raised AttributeError inside: a blind probe)
        raise KnitsimInputError(f"params = {params!r}: expected a CellParams (knitsim.cell.material)")
    return CellCycle(params, max_halvings, stick_closure).run(program, progress)


def run_cells_reference(params: list[CellParams], program: LoadProgram,
                        max_halvings: int = MAX_HALVINGS, stick_closure: str = "release_beta") -> BatchHistory:
    """Run many cells one at a time with the NumPy reference (the Warp batch's oracle)."""
    return BatchHistory.stack([run_cell(p, program, max_halvings, stick_closure) for p in params])


def dissipated_energy(strain: np.ndarray, force: np.ndarray) -> float:
    """``oint F d(strain)`` over a path [N per unit strain], positive when the loop dissipates.

    Trapezoidal rule over the recorded increments (the curve is piecewise smooth
    between increments); for a closed loop traversed load-then-unload this is
    the area enclosed, which must be >= 0 (second law).
    """
    strain = np.asarray(strain, float)
    force = np.asarray(force, float)
    if strain.ndim != 1 or force.shape != strain.shape:
        # numpy would broadcast a strain and a force of other lengths into a number (a blind probe)
        raise KnitsimInputError(f"dissipated_energy: strain {strain.shape} and force {force.shape} must be 1-D arrays "
                                "of one length")
    return float(dissipated_energies(strain[None, :], force[None, :])[0])


def dissipated_energies(strain: np.ndarray, force: np.ndarray) -> np.ndarray:
    """:func:`dissipated_energy` of each row of ``strain`` and ``force`` [k, n] (paths of one length), at once.

    Each row's trapezoids are summed as NumPy sums a 1-D array (a C-contiguous row reduced along it: the same
    pairwise summation), so a row's value is :func:`dissipated_energy`'s of that row, to the last bit."""
    return (0.5 * (force[:, 1:] + force[:, :-1]) * (strain[:, 1:] - strain[:, :-1])).sum(axis=1)


def dissipated_energy_error(strain: np.ndarray, force: np.ndarray) -> float:
    """Estimated error of :func:`dissipated_energy` over the same rows [N per unit strain] (>= 0).

    Richardson's estimate at order 1: the trapezoids over every row against those over every other row of
    each branch (the path split where the strain turns; each branch keeps its first and last row), ``|E_h -
    E_2h|`` of each branch, summed over the branches (of the whole path, a loading branch's difference and an
    unloading branch's cancelled: a patch's cycle 18 % under-resolved read as 2 %).  Exact for a piecewise
    linear force with its kinks on the rows (both sums agree); of the size of the error where a kink (a slide
    onset, a reversal's steep drop) falls between rows, which the trapezoids cut off at the order of the
    increment.  0 for a path of fewer than three rows.
    """
    s = np.asarray(strain, float)
    f = np.asarray(force, float)
    if len(s) < 3:
        return 0.0
    ds = np.sign(np.diff(s))
    ends = [k for k in range(1, len(s) - 1) if ds[k] != ds[k - 1]] + [len(s) - 1]
    keep, start = [0], 0
    for end in ends:
        rows = list(range(start, end + 1, 2))
        if rows[-1] != end:
            rows.append(end)
        keep += rows[1:]
        start = end
    # each branch's |E_h - E_2h|, summed: the branches' differences do not cancel (a loading branch's kink cut by
    # +a and an unloading branch's by -a are an error of about 2a where the branches differ, not 0)
    k = np.asarray(keep)
    bounds = np.concatenate([[0], np.searchsorted(k, ends)])
    return float(sum(abs(dissipated_energy(s[k[a]:k[b] + 1], f[k[a]:k[b] + 1]) - dissipated_energy(s[k[a:b + 1]],
                                                                                                    f[k[a:b + 1]]))
                     for a, b in zip(bounds[:-1], bounds[1:])))
