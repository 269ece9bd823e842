"""The load cycle of one cell: Table 4 sequencing under strain control (NumPy reference).

:func:`run_cell` drives one quarter-stitch cell through a
:class:`~knitsim.cell.load_program.LoadProgram` of strains of the course length,
``C = C0 (1 + strain)``.  Each increment solves the stage's four conditions
(:mod:`knitsim.cell.stages`) with :func:`~knitsim.cell.inverse.solve_state`;
stage changes are *events* located inside the increment by a root search on C
(brentq on the event function along the stage's branch), never overshot:

- ``slide``: phi reaches +phimax (loading) / -phimax (unloading);
- ``jam``: W reaches 4d (the soft condition is then replaced by W = 4d);
- ``unjam``: while unloading jammed, the unjammed branch has W >= 4d again;
- ``slack``: the force per wale reaches 0 while unloading;
- ``force_cap``: the force per wale reaches ``force_cap_N`` (the cell stops).

Dahl friction (``friction = "dahl"``) replaces the stick/slide switch by the
Dahl update of tan(phi) with the slip xi = -s_BC (Dahl 1976, alpha = 1):
``tan(phi) = s m + (tan(phi_old) - s m) exp(-sigma |dxi| / m)``; the slip of an
increment is found by a scalar root search on the slip, each trial a solve
with s_BC imposed.  This nested method is deliberately different from the Warp
kernel, which solves the Dahl relation as a fifth Newton residual: the two are
independent checks of each other.

A failed solve is retried on halved increments (``max_halvings``); if it still
fails the cell stops, flagged with its reason, and its later rows repeat the
last converged state with the flag set: no NaN is reported as a result.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from ..friction.dahl import dahl_increment
from .inverse import initial_state, solve_state
from .load_program import LoadProgram
from .material import CellParams
from .quantities import UNKNOWN_NAMES
from .stages import Stage, stage_label

from .history import (  # noqa: E402  (re-exported)
    HISTORY_QUANTITIES, STATUS_EVENT_NOT_LOCATED, STATUS_FORCE_CAP, STATUS_NAMES,
    STATUS_NO_CONVERGENCE, STATUS_OK, BatchHistory,
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
        return CellState(self.x.copy(), dict(self.q), self.stage, self.jammed, self.soft,
                         self.frozen_soft, self.frozen_sbc, self.C, self.status, self.reason)


class _SolveFailed(Exception):
    pass


def _q(result) -> dict:
    st = result.state
    return {n: float(getattr(st, n)) for n in
            ("alpha", "beta", "gamma", "phi", "P", "W", "C", "L", "s_AB", "s_BC", "T", "M", "R", "Rn", "Rt", "F")}


class CellCycle:
    """Advance one cell through a strain program (NumPy reference).

    Parameters
    ----------
    params : CellParams
        The cell (validated here).
    max_halvings : int
        How often a failed increment is halved before the cell is flagged.
    """

    def __init__(self, params: CellParams, max_halvings: int = 6):
        self.p = params.validated()
        self.max_halvings = max_halvings
        self.phimax = self.p.phimax

    # ----------------------------------------------------------------- set-up
    def initial(self) -> CellState:
        """Table 4 initialisation: C = C0, W = W0, L, phi = phi0."""
        p = self.p
        res = initial_state(p.C0, p.W0, p.L, p.phi0, p.B, p.d)
        if not res.success:
            raise _SolveFailed("initial state: " + res.message)
        q = _q(res)
        st = CellState(res.x, q, Stage.SF_LOAD, False, "Rn", q["Rn"], q["s_BC"], q["C"])
        if p.friction == "coulomb" and p.phi0 >= self.phimax - 1e-12 and p.m > 0:
            st.stage = Stage.S_LOAD          # phi0 = phimax: at the sliding limit already
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
            cond["W"] = 4.0 * p.d
        else:
            cond[st.soft] = st.frozen_soft
        return cond

    def _solve(self, cond: dict, guess) -> tuple[np.ndarray, dict]:
        res = solve_state(cond, guess, self.p.B, self.p.d)
        if not res.success:
            raise _SolveFailed(res.message)
        return res.x, _q(res)

    def _dahl_solve(self, st: CellState, C: float, guess) -> tuple[np.ndarray, dict]:
        """Solve one Dahl increment: find the slip whose Dahl update matches phi."""
        p = self.p
        base = {"L": p.L, "C": C}
        if st.jammed:
            base["W"] = 4.0 * p.d
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
        if not st.jammed:
            ev["jam"] = lambda q: 4.0 * p.d - q["W"]
        if loading:
            ev["force_cap"] = lambda q: q["F"] - p.force_cap_N
        else:
            ev["slack"] = lambda q: -q["F"]
        return ev

    def _transition(self, st: CellState, kind: str) -> None:
        """Apply the stage change of a located event (state already at the event)."""
        q = st.q
        if kind == "slide":
            if st.stage is Stage.SF_LOAD:
                st.stage, st.soft = Stage.S_LOAD, "Rn"
            else:
                st.stage, st.soft = Stage.S_UNLOAD, "T"
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
        if direction < 0:
            st.stage = Stage.SF_UNLOAD
            st.soft = "T" if (p.unloading_rule == "hong_constant_t" or p.friction == "dahl") else "beta"
        else:
            st.stage = Stage.SF_LOAD
            tiny = abs(q["Rn"]) < 1e-9 * max(q["P"], 1e-12)
            st.soft = "beta" if (tiny and p.reload_rule == "mirror_unloading" and p.friction == "coulomb") else "Rn"
        st.frozen_soft = q[st.soft]
        if p.friction == "coulomb" and p.m == 0:
            st.stage = Stage.S_LOAD if direction > 0 else Stage.S_UNLOAD
            st.soft = "Rn" if direction > 0 else "T"
            st.frozen_soft = q[st.soft]

    # --------------------------------------------------------------- advance
    def _try_unjam(self, st: CellState, C_target: float):
        """Active set: the unjammed branch at C_target, if it has W >= 4d."""
        if not st.jammed or st.stage in (Stage.SF_LOAD, Stage.S_LOAD):
            return None
        trial = st.copy()
        trial.jammed = False
        try:
            x, q = self.solve_at(trial, C_target)
        except _SolveFailed:
            return None
        return (x, q) if q["W"] >= 4.0 * self.p.d else None

    def _locate(self, st: CellState, C_a: float, C_b: float, name: str, fun, unjam=False):
        """Root of an event function on [C_a, C_b] along the stage's branch."""
        trial = st.copy()
        if unjam:
            trial.jammed = False

        def e(C):
            x, q = self.solve_at(trial, C, trial.x)
            trial.x = x                      # continuation guess only (Dahl reads trial.q)
            return fun(q) if not unjam else q["W"] - 4.0 * self.p.d

        fa, fb = e(C_a), e(C_b)
        if fa * fb > 0:
            raise _SolveFailed(f"event {name} not bracketed")
        try:
            Ce = brentq(e, C_a, C_b, xtol=1e-13 * max(1.0, abs(C_b)), rtol=1e-14, maxiter=200)
        except ValueError as exc:           # the branch moved under the search
            raise _SolveFailed(f"event {name}: {exc}") from None
        x, q = self.solve_at(trial, Ce, trial.x)
        return Ce, x, q

    def advance(self, st: CellState, C_target: float, events: list, increment: int) -> CellState:
        """Move the cell from its C to ``C_target`` on its branch, handling events."""
        if st.status != STATUS_OK:
            return st
        if st.stage is Stage.SLACK:
            if C_target <= st.C:
                return st
            self.reverse(st, +1)
            events.append({"increment": increment, "kind": "reload", "C": st.C})
        for _ in range(12):                        # at most a few events per increment
            C_from = st.C
            if abs(C_target - C_from) <= 1e-15 * C_target:
                return st
            x, q = self._solve_halving(st, C_from, C_target)
            evs = self.event_functions(st)
            fired = [(k, f) for k, f in evs.items() if f(q) > 0 and f(st.q) <= 0]
            unjam = self._try_unjam(st, C_target)
            if unjam is not None:
                fired.append(("unjam", None))
            if not fired:
                st.x, st.q, st.C = x, q, C_target
                return st
            # locate each fired event; the first along the path wins
            best = None
            for kind, fun in fired:
                try:
                    Ce, xe, qe = self._locate(st, C_from, C_target, kind, fun, unjam=(kind == "unjam"))
                except _SolveFailed:
                    continue
                if best is None or abs(Ce - C_from) < abs(best[1] - C_from):
                    best = (kind, Ce, xe, qe)
            if best is None:
                st.status, st.reason = STATUS_EVENT_NOT_LOCATED, f"could not locate {fired[0][0]}"
                return st
            kind, Ce, xe, qe = best
            before = stage_label(st.stage, st.jammed)
            st.x, st.q, st.C = xe, qe, Ce
            self._transition(st, kind)
            events.append({"increment": increment, "kind": kind, "C": Ce,
                           "from": before, "to": stage_label(st.stage, st.jammed)})
            if st.status != STATUS_OK or st.stage is Stage.SLACK:
                return st
        return st

    def _solve_halving(self, st: CellState, C_from: float, C_to: float):
        """Solve at C_to, walking there in halved sub-increments if needed."""
        try:
            return self.solve_at(st, C_to)
        except _SolveFailed:
            pass
        n = 2
        for _ in range(self.max_halvings):
            x, ok = st.x, True
            trial = st.copy()
            try:
                for k in range(1, n + 1):
                    x, q = self.solve_at(trial, C_from + (C_to - C_from) * k / n, x)
                    if self.p.friction == "dahl":
                        trial.x, trial.q = x, q
                return x, q
            except _SolveFailed:
                n *= 2
        raise _SolveFailed(f"no convergence from C = {C_from:.6g} to {C_to:.6g} mm after {self.max_halvings} halvings")

    def run(self, program: LoadProgram) -> BatchHistory:
        """Run the whole program; see :func:`run_cell`."""
        p = self.p
        st = self.initial()
        n = len(program)
        stage = np.zeros(n, np.int32)
        jammed = np.zeros(n, np.int32)
        status = np.zeros(n, np.int32)
        vals = {k: np.zeros(n) for k in HISTORY_QUANTITIES}
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
                st.status, st.reason = STATUS_NO_CONVERGENCE, str(exc)
            if p.friction == "dahl":
                self._label_dahl(st)
            stage[i], jammed[i], status[i] = int(st.stage), int(st.jammed), st.status
            for k in HISTORY_QUANTITIES:
                vals[k][i] = st.q[k]
            if st.stage is Stage.SLACK:
                vals["F"][i] = 0.0
            if st.status != STATUS_OK and not any(e.get("kind") == "flag" for e in events):
                events.append({"increment": i, "kind": "flag", "reason": st.reason,
                               "status": STATUS_NAMES[st.status]})
        return BatchHistory(np.asarray(program.strain), np.asarray(program.cycle),
                            np.asarray(program.direction), stage[:, None], jammed[:, None],
                            status[:, None], {k: v[:, None] for k, v in vals.items()},
                            [dict(e, cell=0) for e in events], [p])

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
        """Dahl increment: the Dahl state moves with the solution (sub-stepped events)."""
        if st.status != STATUS_OK:
            return st
        C_from = st.C
        n = 1
        for _ in range(self.max_halvings + 1):
            trial = st.copy()
            try:
                for k in range(1, n + 1):
                    C_k = C_from + (C_target - C_from) * k / n
                    trial = self._dahl_step(trial, C_k, events, increment)
                    if trial.status != STATUS_OK or trial.stage is Stage.SLACK:
                        break
                return trial
            except _SolveFailed:
                n *= 2
        raise _SolveFailed(f"Dahl: no convergence from C = {C_from:.6g} to {C_target:.6g} mm")

    def _dahl_step(self, st: CellState, C_target: float, events: list, increment: int) -> CellState:
        x, q = self.solve_at(st, C_target)
        evs = self.event_functions(st)
        fired = [(k, f) for k, f in evs.items() if f(q) > 0 and f(st.q) <= 0]
        unjam = self._try_unjam(st, C_target)
        if not fired and unjam is None:
            st.x, st.q, st.C = x, q, C_target
            return st
        kinds = [k for k, _ in fired] + (["unjam"] if unjam is not None else [])
        funs = dict(fired)

        # event along the Dahl path: bisection on C, each trial from the same start state
        def e(C, kind):
            _, qq = self.solve_at(st, C)
            return funs[kind](qq) if kind != "unjam" else 0.0

        best = None
        for kind in kinds:
            if kind == "unjam":
                Ce = C_target
            else:
                Ce = brentq(lambda C: e(C, kind), st.C, C_target, xtol=1e-12 * C_target, maxiter=200)
            if best is None or abs(Ce - st.C) < abs(best[1] - st.C):
                best = (kind, Ce)
        kind, Ce = best
        x, q = self.solve_at(st, Ce)
        before = stage_label(st.stage, st.jammed)
        st.x, st.q, st.C = x, q, Ce
        self._transition(st, kind)
        events.append({"increment": increment, "kind": kind, "C": Ce, "from": before,
                       "to": stage_label(st.stage, st.jammed)})
        if st.status == STATUS_OK and st.stage is not Stage.SLACK and Ce != C_target:
            return self._dahl_step(st, C_target, events, increment)
        return st


def run_cell(params: CellParams, program: LoadProgram, max_halvings: int = 6) -> BatchHistory:
    """Run one cell through a strain program (NumPy reference).

    Parameters
    ----------
    params : CellParams
        The cell; validated before any solve.
    program : LoadProgram
        Imposed strains of the course length, ``C = C0 (1 + strain)``.
    max_halvings : int
        Retries of a failed increment on halved sub-increments.

    Returns
    -------
    BatchHistory
        One row per increment, one column; ``events`` lists located stage changes.
    """
    return CellCycle(params, max_halvings).run(program)


def run_cells_reference(params: list[CellParams], program: LoadProgram,
                        max_halvings: int = 6) -> BatchHistory:
    """Run many cells one at a time with the NumPy reference (the Warp batch's oracle)."""
    return BatchHistory.stack([run_cell(p, program, max_halvings) for p in params])


def dissipated_energy(strain: np.ndarray, force: np.ndarray) -> float:
    """``oint F d(strain)`` over a path [N per unit strain], positive when the loop dissipates.

    Trapezoidal rule over the recorded increments (the curve is piecewise smooth
    between increments); for a closed loop traversed load-then-unload this is
    the area enclosed, which must be >= 0 (second law).
    """
    strain = np.asarray(strain, float)
    force = np.asarray(force, float)
    return float(np.sum(0.5 * (force[1:] + force[:-1]) * np.diff(strain)))
