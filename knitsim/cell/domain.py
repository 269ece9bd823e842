"""The parameter domain the quarter-stitch cell is meant for, stated in one place.

The elastica of the cell is scale-free: its shape depends on the lengths only
through their ratios to the yarn diameter d, and its forces scale as B / d^2
(eqs 6-9).  The domain is therefore stated as two scales (d, B) and
dimensionless ratios of the knit, plus the friction (m, phi0):

============================  ===============  ==========================================
quantity                      range            why
============================  ===============  ==========================================
d [mm]                        0.1 .. 2.0       technical rovings and spun yarns
B [N mm^2]                    0.001 .. 10      fine spun yarns .. heavy glass rovings
W0 / d_jam                    5.5 .. 9         loops well clear of jamming at rest
                                               (W0 > 4 d_jam; the calibrated jersey 5.6,
                                               the paper's knits 7.6-7.9)
C0 / d                        4.0 .. 5.2       course length of plain knits (the paper's
                                               4.7-4.8; Munden's loop shape)
L / (2 C0 + W0 - 4 d)         1.6 .. 2.1       the yarn closes the loop (> 1: check_knit);
                                               below ~1.62-1.76 Hong's rest shape ends
                                               (alpha = gamma), above ~1.93 with large
                                               C0 / d its contact pulls (R < 0)
m                             0.05 .. 0.5      eq 10 over measured coiling angles / mu_k
phi0 [rad]                    |phi0| <= atan m  inside the friction cone (section 3.3.1)
strain                        0 .. 0.6         the paper's cyclic program (jamming by 0.7)
============================  ===============  ==========================================

The box is drawn around the knits the model was checked on; the edges of the
L ratio are where the rest state stops existing or stops being a contact
(below), so that corners of the box may still lack a rest state.  Outside
the box the model extrapolates (a warning, not a refusal).

The paper's knits (Dusserre 2015, Table 1 and section 2.2: E-glass W0/d = 7.6,
C0/d = 4.7, L ratio 1.89; basalt 7.9, 4.8, 1.73) lie inside, and so does the
calibrated specimen (W0 / in-plane width = 5.6).  The diagnosis scenes of
real jerseys (W0/d ~ 4.3-4.5, L ratio ~ 2.4-2.6) lie outside: they are fitted,
not swept, and are not checked against this domain.

The box is not the whole statement: a cell of the box is in the model's
domain only if it has an admissible rest state (:func:`rest_state_problem`:
Table 4's initial state exists and its contact force is compressive, R >= 0).
Continuation in L from a known rest state shows that both failures seen in
the box's corners are of this kind, not of too few starts: tight loops whose
rest branch ends at alpha = gamma (the inflection A meets the contact B), and
loose loops with large C0 / d whose rest contact would pull (R < 0; loading
them drove the stick to phi -> -pi/2 and refused it).  Such cells are
flagged ``no_rest_state`` before any increment (Warp batch and NumPy
reference alike) and ``knitsim cell`` refuses them with that reason; a cell
outside the box, or a program beyond its strains, runs with an
``outside_domain`` (extrapolation) warning in its summary.

Measured (benchmarks/bench_convergence.py --no-sweeps --cells 300, 2-core CPU):
before 26 of 300 failed (16 no rest state found, 10 refused on first loading);
after 0 failed, 34 no_rest_state (the 26, and 8 that had reached the force cap
from a pulling contact), 187 ok, 79 force_cap.

The rest state (Table 4's initial state at C0, W0, L, phi0) must exist as
well; :func:`check_rest_state` solves it (float64 reference) and names the
cell that has none.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

from ..errors import KnitsimInputError
from .material import CellParams


@dataclass(frozen=True)
class ParameterDomain:
    """Closed ranges of the cell's scales and dimensionless knit ratios (see the module table)."""

    d: tuple[float, float] = (0.1, 2.0)
    B: tuple[float, float] = (1.0e-3, 10.0)
    W0_over_djam: tuple[float, float] = (5.5, 9.0)
    C0_over_d: tuple[float, float] = (4.0, 5.2)
    L_over_closing: tuple[float, float] = (1.6, 2.1)
    m: tuple[float, float] = (0.05, 0.5)
    #: largest imposed strain of the course length a load program may ask for
    strain: tuple[float, float] = (0.0, 0.6)

    def ratios(self, p: CellParams) -> dict[str, float]:
        """The cell's values of the domain's quantities (d, B, ratios, m)."""
        closing = 2.0 * p.C0 + p.W0 - 4.0 * p.d
        return {"d": p.d, "B": p.B, "W0_over_djam": p.W0 / p.d_jam, "C0_over_d": p.C0 / p.d,
                "L_over_closing": p.L / closing if closing > 0 else math.inf, "m": p.m}

    def why_outside(self, p: CellParams) -> str | None:
        """None inside the domain, otherwise a one-line reason naming the first quantity outside."""
        names = {"d": "d", "B": "B", "W0_over_djam": "W0 / d_jam", "C0_over_d": "C0 / d",
                 "L_over_closing": "L / (2 C0 + W0 - 4 d)", "m": "m"}
        for key, v in self.ratios(p).items():
            lo, hi = getattr(self, key)
            if not (lo * (1.0 - 1e-9) <= v <= hi * (1.0 + 1e-9)):   # bounds closed, to rounding
                return f"{names[key]} = {v:.4g} outside the model's domain [{lo:g}, {hi:g}] (knitsim.cell.domain)"
        if abs(p.phi0) > p.phimax + 1e-12:
            return f"phi0 = {p.phi0:.4g} rad outside the friction cone [-atan m, atan m] = +/-{p.phimax:.4g}"
        return None

    def why_program_outside(self, strains) -> str | None:
        """None when every imposed strain lies in :attr:`strain`, otherwise the reason."""
        lo, hi = self.strain
        s_min, s_max = float(min(strains)), float(max(strains))
        if s_min < lo or s_max > hi:
            return (f"load strains [{s_min:.4g}, {s_max:.4g}] outside the model's domain [{lo:g}, {hi:g}] "
                    "(knitsim.cell.domain)")
        return None


#: the domain the model is meant for (module docstring)
DOMAIN = ParameterDomain()


def check_domain(p: CellParams, where: str = "cell", domain: ParameterDomain = DOMAIN) -> None:
    """Raise :class:`KnitsimInputError` (one line, naming ``where``) for a cell outside ``domain``."""
    why = domain.why_outside(p)
    if why is not None:
        raise KnitsimInputError(f"{where}: {why}")


def rest_state_problem(p: CellParams) -> str | None:
    """None when the cell has an admissible rest state, otherwise why not (one line).

    The rest state is Table 4's initial state {C = C0, W = W0, L, phi = phi0}
    (float64 reference, :func:`knitsim.cell.inverse.initial_state`).  It is
    admissible when it exists and its contact force is compressive, R >= 0:
    the contact at B is unilateral (two yarns press, they cannot pull), so a
    rest state with R < 0 is an equilibrium of the equations but not of a knit
    (the loops would open at B, a configuration the quarter-stitch cell does
    not describe).  Both ends were found by continuation in L from a known rest
    state (L / (2 C0 + W0 - 4 d) = 1.9) over the domain's box:

    - tight loops (small L ratio): the rest branch ends where alpha - gamma -> 0,
      the inflection point A reaching the contact point B (the A-B arc of
      Hong's quarter loop vanishes), with R ~ 10-17 B / d^2; below that L the
      cell's shape does not exist, whatever the start;
    - loose loops (large L ratio, large C0 / d): the branch goes on but R
      changes sign; loading such a cell drove the stick (Rn frozen < 0)
      to phi -> -pi/2.

    Where the default starts find no state, the continuation in L is run here
    as the independent check; if it does reach L the state is used (the starts
    were too few), otherwise the reason names where the branch ended.
    """
    from .inverse import continue_along, initial_state

    closing = 2.0 * p.C0 + p.W0 - 4.0 * p.d
    res, ok = _solve_rest_state(p)
    if not ok:
        res = None
        try:
            L1 = 1.9 * closing
            s1 = initial_state(p.C0, p.W0, L1, 0.0, p.B, p.d)
            path = continue_along({"C": p.C0, "W": p.W0, "L": L1, "phi": 0.0}, "L", L1, p.L, s1, p.B, p.d,
                                  n_steps=40, max_halvings=14)
            good = [r for r in path if r.success]
            if path and path[-1].success and p.phi0 != 0.0:
                path = continue_along({"C": p.C0, "W": p.W0, "L": p.L, "phi": 0.0}, "phi", 0.0, p.phi0,
                                      path[-1], p.B, p.d, n_steps=max(1, int(math.ceil(abs(p.phi0) / 0.05))))
            if path and path[-1].success:
                res = path[-1]
            elif good:
                last = good[-1]
                return (f"no rest state: the quarter loop at C0 = {p.C0:g}, W0 = {p.W0:g} mm exists only down to "
                        f"L / (2 C0 + W0 - 4 d) = {last.state.L / closing:.4g} (there alpha - gamma = "
                        f"{last.x[0] - last.x[2]:.2g} rad: the inflection A meets the contact B), "
                        f"L = {p.L:g} mm asks for {p.L / closing:.4g}")
        except (RuntimeError, KnitsimInputError):
            pass
    if res is None:
        return (f"no rest state: C = C0 = {p.C0:g}, W = W0 = {p.W0:g}, L = {p.L:g} mm, phi = phi0 = {p.phi0:g} rad "
                "has no equilibrium of the quarter loop")
    R = float(res.state.R)
    if R < 0.0:
        return (f"no rest state: the contact at B would pull (R = {R:.3g} N < 0 at C0 = {p.C0:g}, W0 = {p.W0:g}, "
                f"L = {p.L:g} mm): the loop is too loose to press on its neighbour")
    return None


def check_rest_state(p: CellParams, where: str = "cell") -> None:
    """Raise :class:`KnitsimInputError` when the cell has no admissible rest state (:func:`rest_state_problem`)."""
    why = rest_state_problem(p)
    if why is not None:
        raise KnitsimInputError(f"{where}: {why}")


#: codes of :func:`check_cells` (stored per cell as int8 in sweep datasets): inside the domain; outside
#: its box (solved, an extrapolation); no admissible rest state (not solved: outside the model)
DOMAIN_INSIDE = 0
DOMAIN_OUTSIDE_BOX = 1
DOMAIN_NO_REST_STATE = 2
DOMAIN_NAMES = {DOMAIN_INSIDE: "inside", DOMAIN_OUTSIDE_BOX: "outside_domain",
                DOMAIN_NO_REST_STATE: "no_rest_state"}


@dataclass(frozen=True)
class DomainCheck:
    """Where each cell of a list stands with the model's domain, found before any solve.

    Attributes
    ----------
    outside : list of (str or None)
        Per cell, why it lies outside the domain's box (:meth:`ParameterDomain.why_outside`), else None.
    no_rest : list of (str or None)
        Per cell, why it has no admissible rest state (Table 4's initial state not found by the
        engine that would run it, or its contact force pulls, R < 0), else None.
    """

    outside: list
    no_rest: list
    #: per cell, the force per wale of its rest state [N] (NaN without one)
    rest_F: list = field(default_factory=list)

    def at_cap(self, caps) -> list:
        """Per cell, why its rest state already carries its force cap ``caps[i]`` (force_cap_N), else None:
        a load program cannot start from it (:func:`rest_at_cap_problem`)."""
        return [rest_at_cap_problem(F, cap) for F, cap in zip(self.rest_F, caps)]

    @property
    def codes(self):
        """Per cell :data:`DOMAIN_NO_REST_STATE`, else :data:`DOMAIN_OUTSIDE_BOX`, else :data:`DOMAIN_INSIDE` [int8]."""
        import numpy as np

        return np.array([DOMAIN_NO_REST_STATE if r is not None else DOMAIN_OUTSIDE_BOX if o is not None
                         else DOMAIN_INSIDE for o, r in zip(self.outside, self.no_rest)], dtype=np.int8)

    def reasons(self) -> list:
        """Per cell the reason of its code (None inside the domain)."""
        return [r if r is not None else o for o, r in zip(self.outside, self.no_rest)]

    def outside_quantities(self) -> dict[str, int]:
        """How many cells lie outside the box, by the first quantity outside (the name in the reason)."""
        out: dict[str, int] = {}
        for why in self.outside:
            if why is not None:
                name = why.split(" = ")[0]
                out[name] = out.get(name, 0) + 1
        return out


def _rest_key(p: CellParams) -> tuple:
    # the rest state depends on the geometry, the stiffness and phi0 only (Table 4's initial state)
    return (p.B, p.d, p.L, p.W0, p.C0, p.phi0)


def _solve_rest_state(p):
    """Table 4's initial state of ``p`` by the NumPy inverse solve: ``(result, converged)``; solved once per
    geometry (:func:`rest_state_problem` and :func:`rest_force_per_wale` both ask for it)."""
    return _solve_rest_state_of(_rest_key(p))


@functools.lru_cache(maxsize=4096)
def _solve_rest_state_of(key: tuple):
    from .inverse import initial_state
    B, d, L, W0, C0, phi0 = key
    try:
        res = initial_state(C0, W0, L, phi0, B, d)
        return res, bool(res.success)
    except (RuntimeError, KnitsimInputError):
        return None, False


def rest_at_cap_problem(F_rest: float, cap: float) -> str | None:
    """Why a rest state of force per wale ``F_rest`` cannot be loaded under ``cap`` (force_cap_N), else None.

    The engines stop such a cell at rest with status force_cap (knitsim.cell.history.rest_at_cap_reason),
    so a program run from it has no curve; a scene refuses it before any work."""
    if not (F_rest >= cap):     # also a NaN rest force: no rest state, said by no_rest
        return None
    return (f"its force per wale at rest, {F_rest:.4g} N, is already at or above force_cap_N = {cap:.4g} N: "
            "no load program can start from it; raise force_cap_N above the rest force")


def rest_force_per_wale(p: CellParams) -> float:
    """The force per wale of ``p``'s rest state (Table 4's initial state, the NumPy reference) [N], NaN
    without one."""
    res, ok = _solve_rest_state(p)
    return float(res.state.F) if ok else float("nan")


def _no_rest_reason(R: float | None) -> str:
    """Why a cell has no rest state: its contact force R at rest pulls (R < 0), or no equilibrium (R None)."""
    if R is not None and R < 0.0:
        return (f"no rest state: the contact at B would pull (R = {R:.3g} N < 0 at rest): "
                "the loop is too loose to press on its neighbour")
    return "no rest state: Table 4's initial state (C0, W0, L, phi0) has no equilibrium of the quarter loop"


def check_cells(params, engine: str = "warp", device: str = "cpu",
                domain: ParameterDomain = DOMAIN) -> DomainCheck:
    """The domain of every cell, before any increment is solved (sweep planner, patch runs).

    The rest state is decided by the engine that would run the cells, with its own test, so that a
    cell flagged here is exactly one the engine would flag ``no_rest_state`` at rest: the Warp batch
    (:meth:`knitsim.cell.batch.CellModel.state`, every distinct cell in one launch) or the NumPy
    reference (:func:`knitsim.cell.inverse.initial_state` and R >= 0, as
    :meth:`knitsim.cell.cycle.CellCycle.run`).  Identical geometries are solved once.

    Parameters
    ----------
    params : sequence of CellParams
    engine : {"warp", "reference"}
    device : str
        Warp device (warp engine).
    domain : ParameterDomain
        The box a cell must lie in to be inside the domain (default :data:`DOMAIN`).

    Returns
    -------
    DomainCheck
    """
    params = list(params)
    outside = [domain.why_outside(p) for p in params]
    keys, first = {}, []
    for p in params:
        k = _rest_key(p)
        if k not in keys:
            keys[k] = len(first)
            first.append(p)
    why_u: list = [None] * len(first)
    if first and engine == "warp":
        import numpy as np

        from .. import warp_runtime
        from .batch import CellModel
        from .history import STATUS_NO_REST_STATE

        warp_runtime.init()                  # quiet, stable kernel cache: before any kernel module loads
        from .quantities import CODE

        st = CellModel.from_params(first, device=device).state()
        status0 = np.asarray(st.status.numpy())
        R = np.asarray(st.q.numpy()[:, CODE["R"]])
        F_u = [float(v) for v in st.q.numpy()[:, CODE["F"]]]
        # CellModel.state has set NO_REST_STATE where the solve failed or R < 0: a finite R < 0 says which
        for i in np.nonzero(status0 == STATUS_NO_REST_STATE)[0]:
            why_u[i] = _no_rest_reason(float(R[i]) if np.isfinite(R[i]) else None)
    elif first:
        F_u = []
        for i, p in enumerate(first):
            res, ok = _solve_rest_state(p)
            F_u.append(float(res.state.F) if ok else float("nan"))
            if not ok or float(res.state.R) < 0.0:
                why_u[i] = _no_rest_reason(float(res.state.R) if ok else None)
    no_rest = [why_u[keys[_rest_key(p)]] for p in params]
    rest_F = [float("nan") if why_u[keys[_rest_key(p)]] is not None else F_u[keys[_rest_key(p)]] for p in params]
    return DomainCheck(outside, no_rest, rest_F)
