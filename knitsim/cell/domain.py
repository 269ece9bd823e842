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
from dataclasses import dataclass

import numpy as np

from ..errors import KnitsimInputError
from .material import CellParams, phimax_of


#: the box's quantities (:class:`ParameterDomain` fields), in the order a cell is judged, and their names in
#: the reasons; phi0 (the friction cone, not a range of the box) is judged after them
QUANTITIES = (("d", "d"), ("B", "B"), ("W0_over_djam", "W0 / d_jam"), ("C0_over_d", "C0 / d"),
              ("L_over_closing", "L / (2 C0 + W0 - 4 d)"), ("m", "m"))


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

    def ratio_arrays(self, d, B, L, W0, C0, m, d_jam) -> dict[str, np.ndarray]:
        """The domain's quantities of many cells at once, float64 [N] each (keys :data:`QUANTITIES`; per-cell
        arrays of the :class:`CellParams` fields and of its ``d_jam``).  The one statement of the ratios:
        :meth:`ratios` is this for one cell."""
        d, C0, W0, L = (np.asarray(v, dtype=np.float64) for v in (d, C0, W0, L))
        closing = 2.0 * C0 + W0 - 4.0 * d
        with np.errstate(divide="ignore", invalid="ignore"):
            return {"d": d, "B": np.asarray(B, dtype=np.float64), "W0_over_djam": W0 / np.asarray(d_jam, np.float64),
                    "C0_over_d": C0 / d, "L_over_closing": np.where(closing > 0, L / closing, np.inf),
                    "m": np.asarray(m, dtype=np.float64)}

    def outside_arrays(self, d, B, L, W0, C0, m, phi0, d_jam, phimax) -> tuple[np.ndarray, np.ndarray]:
        """Where many cells stand with the box, without a Python loop over them.

        Parameters
        ----------
        d, B, L, W0, C0, m, phi0, d_jam : array_like, shape [N]
            The cells' :class:`CellParams` fields and jamming widths.
        phimax : array_like, shape [N]
            atan(m) of each cell, as :attr:`CellParams.phimax` gives it (math.atan: the friction cone's
            edge that :meth:`CellParams.validated` checks).

        Returns
        -------
        code : ndarray of int8, shape [N]
            -1 inside; else the index in :data:`QUANTITIES` of the first quantity outside its range, or
            ``len(QUANTITIES)`` for phi0 outside the friction cone.
        value : ndarray of float64, shape [N]
            That quantity's value (NaN inside): with ``phimax``, :meth:`reason` words it.
        """
        ratios = self.ratio_arrays(d, B, L, W0, C0, m, d_jam)
        n = len(ratios["d"])
        code = np.full(n, -1, np.int8)
        value = np.full(n, np.nan)
        for k, (key, _) in enumerate(QUANTITIES):
            lo, hi = getattr(self, key)
            v = np.broadcast_to(ratios[key], (n,))
            with np.errstate(invalid="ignore"):
                out = (code < 0) & ~((lo * (1.0 - 1e-9) <= v) & (v <= hi * (1.0 + 1e-9)))  # closed, to rounding
            code[out], value[out] = k, v[out]
        phi0 = np.broadcast_to(np.asarray(phi0, dtype=np.float64), (n,))
        out = (code < 0) & (np.abs(phi0) > np.asarray(phimax, dtype=np.float64) + 1e-12)
        code[out], value[out] = len(QUANTITIES), phi0[out]
        return code, value

    def reason(self, code: int, value: float, phimax: float) -> str | None:
        """The one-line reason of :meth:`outside_arrays`' ``code`` and ``value`` for a cell (None inside)."""
        code = int(code)
        if code < 0:
            return None
        if code == len(QUANTITIES):
            return (f"phi0 = {float(value):.4g} rad outside the friction cone [-atan m, atan m] = "
                    f"+/-{float(phimax):.4g}")
        key, name = QUANTITIES[code]
        lo, hi = getattr(self, key)
        return f"{name} = {float(value):.4g} outside the model's domain [{lo:g}, {hi:g}] (knitsim.cell.domain)"

    def ratios(self, p: CellParams) -> dict[str, float]:
        """The cell's values of the domain's quantities (d, B, ratios, m): :meth:`ratio_arrays` of one cell."""
        r = self.ratio_arrays([p.d], [p.B], [p.L], [p.W0], [p.C0], [p.m], [p.d_jam])
        return {key: float(r[key][0]) for key, _ in QUANTITIES}

    def why_outside(self, p: CellParams) -> str | None:
        """None inside the domain, otherwise a one-line reason naming the first quantity outside
        (:meth:`outside_arrays` of one cell, worded by :meth:`reason`)."""
        phimax = p.phimax
        code, value = self.outside_arrays([p.d], [p.B], [p.L], [p.W0], [p.C0], [p.m], [p.phi0], [p.d_jam], [phimax])
        return self.reason(code[0], value[0], phimax)

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


#: L / (2 C0 + W0 - 4 d) of the known rest state the ends of the rest branch are searched from
REST_RATIO_KNOWN = 1.9


def _tightest_rest_ratio(p: CellParams, device: str) -> float | None:
    """The smallest L / (2 C0 + W0 - 4 d) down to which the Warp engine's rest-state solve finds the cell's rest
    state, searched from :data:`REST_RATIO_KNOWN` towards the cell's own ratio; None where it finds none there.

    Batched launches of :func:`check_cells` (a grid of 32 ratios, then two finer grids about the first one
    without a rest state: a last step of (1.9 - the cell's ratio) / 31^3): ~0.3 s, where the reference's continuation in L took
    ~20 s to word a tight cell's refusal (a cell at ratio 1.2 on the CPU)."""
    closing = 2.0 * p.C0 + p.W0 - 4.0 * p.d
    lo, hi = p.L / closing, REST_RATIO_KNOWN
    if lo >= hi:
        return None
    found = None
    for _ in range(3):
        ratios = np.linspace(lo, hi, 32)
        ok = ~check_cells([p.replace(L=float(r * closing)) for r in ratios], engine="warp",
                          device=device).no_rest_mask
        if not ok[-1]:
            return found
        first = int(np.nonzero(~ok)[0][-1]) + 1 if not ok.all() else 0     # the branch from hi down, unbroken
        found = float(ratios[first])
        if first == 0:
            return found
        lo, hi = float(ratios[first - 1]), found
    return found


def rest_state_problem(p: CellParams, engine: str = "reference", device: str = "cpu") -> str | None:
    """None when the cell has an admissible rest state, otherwise why not (one line).

    ``engine``: the engine whose verdict the words are for; with ``"warp"`` (its rest-state solve already found
    none) a tight loop's refusal says down to which L ratio that engine finds the loop (batched on ``device``,
    :func:`_tightest_rest_ratio`), without the reference's continuation.

    The rest state is Table 4's initial state {C = C0, W = W0, L, phi = phi0}
    (float64 reference, :func:`knitsim.cell.inverse.initial_state`).  It is
    admissible when it exists and its contact force is compressive, R >= 0:
    the contact at B is unilateral (two yarns press, they cannot pull), so a
    rest state with R < 0 is an equilibrium of the equations but not of a knit
    (the loops would open at B, a configuration the quarter-stitch cell does
    not describe).  Both ends were found by continuation in L from a known rest
    state (L / (2 C0 + W0 - 4 d) = 1.9) over the domain's box:

    - tight loops (small L ratio): the rest branch runs towards alpha - gamma -> 0,
      the inflection point A approaching the contact point B, with R ~ 10-17 B / d^2
      and more; this float64 continuation stops near there (a blind probe's shooting
      solver and the Warp engine, whose Newton runs in ln(alpha - gamma), follow it
      further: L ratio 1.775 at d = 0.1, B = 10, W0 = 5.5 d, C0 = 4 d, where this one
      stops at 1.78), so ``knitsim cell`` with the Warp engine asks that engine too;
    - loose loops (large L ratio, large C0 / d): the branch goes on but R
      changes sign; loading such a cell drove the stick (Rn frozen < 0)
      to phi -> -pi/2.

    Where the default starts find no state, the continuation in L is run here
    as the independent check; if it does reach L the state is used (the starts
    were too few), otherwise the reason names where the branch ended.
    """
    from .inverse import continue_along, initial_state

    closing = 2.0 * p.C0 + p.W0 - 4.0 * p.d
    if engine == "warp" and p.L < REST_RATIO_KNOWN * closing:
        tightest = _tightest_rest_ratio(p, device)
        if tightest is None:
            return None           # the engine's own reason stands (check_cells: no equilibrium found)
        return (f"no rest state found: the Warp engine's rest-state solve finds the quarter loop at C0 = {p.C0:g}, "
                f"W0 = {p.W0:g} mm, phi0 = {p.phi0:g} rad down to L / (2 C0 + W0 - 4 d) = {tightest:.4g} (L = "
                f"{tightest * closing:.4g} mm), L = {p.L:g} mm asks "
                f"for {p.L / closing:.4g}")
    res, ok = _solve_rest_state(p)
    if not ok:
        res = None
        try:
            L1 = REST_RATIO_KNOWN * closing
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
                # (not "the loop exists only down to": a blind probe's shooting solver, and the Warp engine, found
                # a rest state at 1.775 where this branch had stopped at 1.78, alpha - gamma 4.4e-4 there)
                return (f"no rest state found: the quarter loop at C0 = {p.C0:g}, W0 = {p.W0:g} mm, continued in L "
                        f"from L / (2 C0 + W0 - 4 d) = 1.9, was followed down to {last.state.L / closing:.4g} (there "
                        f"alpha - gamma = {last.x[0] - last.x[2]:.2g} rad: the inflection A close to the contact B), "
                        f"L = {p.L:g} mm asks for {p.L / closing:.4g}; "
                        + ("the Warp engine's rest-state solve, which reaches tighter loops, found none either"
                           if engine == "warp" else
                           "the Warp engine's rest-state solve (engine = \"warp\") may reach tighter loops"))
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


class DomainCheck:
    """Where each cell of a list stands with the model's domain, found before any solve.

    Held as per-cell arrays (:func:`check_cell_arrays`: a patch's 10^6 cells); the per-cell lists of
    reasons (:attr:`outside`, :attr:`no_rest`) are worded on first use, and only for the cells that have one.

    Attributes
    ----------
    outside_code, outside_value, phimax : ndarray, shape [N]
        :meth:`ParameterDomain.outside_arrays` of each cell (-1: inside the box) and its atan(m), which
        :meth:`ParameterDomain.reason` words.
    rest_of_cell : ndarray of int, shape [N]
        Each cell's rest geometry (B, d, L, W0, C0, phi0: Table 4's initial state), an index into the next two.
    rest_why : list of (str or None)
        Per distinct rest geometry, why it has no admissible rest state (Table 4's initial state not found
        by the engine that would run it, or its contact force pulls, R < 0), else None.
    rest_F_unique : ndarray, shape [n_rest]
        Per distinct rest geometry, the force per wale of its rest state [N] (read only where it has one).
    domain : ParameterDomain
        The box the cells were judged against.
    """

    def __init__(self, outside_code, outside_value, phimax, rest_of_cell, rest_why, rest_F_unique,
                 domain: ParameterDomain | None = None):
        self.outside_code = np.asarray(outside_code, dtype=np.int8)
        self.outside_value = np.asarray(outside_value, dtype=np.float64)
        self.phimax = np.asarray(phimax, dtype=np.float64)
        self.rest_of_cell = np.asarray(rest_of_cell, dtype=np.int64)
        self.rest_why = list(rest_why)
        self.rest_F_unique = np.asarray(rest_F_unique, dtype=np.float64)
        self.domain = DOMAIN if domain is None else domain
        self._no_rest_mask = np.array([w is not None for w in self.rest_why], dtype=bool)[self.rest_of_cell]
        self._lists: dict = {}

    def __len__(self) -> int:
        return len(self.outside_code)

    @property
    def outside_mask(self) -> np.ndarray:
        """Per cell, whether it lies outside the domain's box [bool]."""
        return self.outside_code >= 0

    @property
    def no_rest_mask(self) -> np.ndarray:
        """Per cell, whether it has no admissible rest state [bool]."""
        return self._no_rest_mask.copy()

    @property
    def rest_F_array(self) -> np.ndarray:
        """Per cell, the force per wale of its rest state [N] (NaN without one)."""
        return np.where(self.no_rest_mask, np.nan, self.rest_F_unique[self.rest_of_cell])

    def outside_reason(self, i: int) -> str | None:
        """Why cell ``i`` lies outside the domain's box (:meth:`ParameterDomain.why_outside`), else None."""
        return self.domain.reason(self.outside_code[i], self.outside_value[i], self.phimax[i])

    def no_rest_reason(self, i: int) -> str | None:
        """Why cell ``i`` has no admissible rest state, else None."""
        return self.rest_why[int(self.rest_of_cell[i])]

    @property
    def outside(self) -> list:
        """Per cell, why it lies outside the domain's box (:meth:`ParameterDomain.why_outside`), else None."""
        if "outside" not in self._lists:
            out = [None] * len(self)
            for i in np.nonzero(self.outside_mask)[0]:
                out[i] = self.outside_reason(i)
            self._lists["outside"] = out
        return self._lists["outside"]

    @property
    def no_rest(self) -> list:
        """Per cell, why it has no admissible rest state, else None."""
        if "no_rest" not in self._lists:
            self._lists["no_rest"] = [self.rest_why[k] for k in self.rest_of_cell.tolist()]
        return self._lists["no_rest"]

    @property
    def rest_F(self) -> list:
        """Per cell, the force per wale of its rest state [N] (NaN without one)."""
        return self.rest_F_array.tolist()

    def at_cap_mask(self, caps) -> np.ndarray:
        """Per cell, whether its rest state already carries its force cap ``caps[i]`` (:func:`rest_at_cap_problem`)."""
        return _at_cap(self.rest_F_array, np.asarray(caps, dtype=np.float64))

    def at_cap_reason(self, i: int, cap: float) -> str | None:
        """Why cell ``i``'s rest state cannot be loaded under ``cap`` (:func:`rest_at_cap_problem`), else None."""
        return rest_at_cap_problem(float(self.rest_F_array[i]), float(cap))

    def at_cap(self, caps) -> list:
        """Per cell, why its rest state already carries its force cap ``caps[i]`` (force_cap_N), else None:
        a load program cannot start from it (:func:`rest_at_cap_problem`)."""
        caps = np.broadcast_to(np.asarray(caps, dtype=np.float64), (len(self),))
        F = self.rest_F_array
        out = [None] * len(self)
        for i in np.nonzero(_at_cap(F, caps))[0]:
            out[i] = rest_at_cap_problem(float(F[i]), float(caps[i]))
        return out

    @property
    def codes(self):
        """Per cell :data:`DOMAIN_NO_REST_STATE`, else :data:`DOMAIN_OUTSIDE_BOX`, else :data:`DOMAIN_INSIDE` [int8]."""
        return np.where(self.no_rest_mask, DOMAIN_NO_REST_STATE,
                        np.where(self.outside_mask, DOMAIN_OUTSIDE_BOX, DOMAIN_INSIDE)).astype(np.int8)

    def reasons(self) -> list:
        """Per cell the reason of its code (None inside the domain)."""
        return [r if r is not None else o for o, r in zip(self.outside, self.no_rest)]

    def outside_counts(self, weights=None) -> dict[str, int]:
        """Cells outside the box by the first quantity outside (the name in the reason), in the order the
        cells first name them; ``weights``: what each cell counts for (a patch's group: its cells)."""
        code = self.outside_code
        present = np.unique(code[code >= 0])
        firsts = [int(np.argmax(code == c)) for c in present]
        w = np.ones(len(code), np.int64) if weights is None else np.asarray(weights)
        return {quantity_name(int(c)): int(w[code == c].sum()) for _, c in sorted(zip(firsts, present))}

    def outside_quantities(self) -> dict[str, int]:
        """How many cells lie outside the box, by the first quantity outside (the name in the reason)."""
        return self.outside_counts()


def quantity_name(code: int) -> str:
    """The name a reason of :meth:`ParameterDomain.outside_arrays`' ``code`` starts with (``"phi0"`` for the cone)."""
    return "phi0" if code == len(QUANTITIES) else QUANTITIES[code][1]


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


def _at_cap(F_rest, cap):
    """Whether a rest state of force per wale ``F_rest`` is at or above ``cap`` (scalars or arrays; False for a
    NaN rest force): the one test of :func:`rest_at_cap_problem` and :meth:`DomainCheck.at_cap_mask`."""
    return np.greater_equal(F_rest, cap)


def rest_at_cap_problem(F_rest: float, cap: float) -> str | None:
    """Why a rest state of force per wale ``F_rest`` cannot be loaded under ``cap`` (force_cap_N), else None.

    The engines stop such a cell at rest with status force_cap (knitsim.cell.history.rest_at_cap_reason),
    so a program run from it has no curve; a scene refuses it before any work."""
    if not _at_cap(F_rest, cap):     # also a NaN rest force: no rest state, said by no_rest
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


def _first_rows(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct rows of ``keys`` [N, k], numbered in the order the rows first appear: (each row's number,
    the index of each number's first row).  Equal as floats are equal (0.0 and -0.0 are one, as in a tuple
    key)."""
    from ..arrays import row_ids

    if len(keys) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    _, first, inverse = np.unique(row_ids(keys), return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty(len(first), np.int64)
    rank[order] = np.arange(len(first))
    return rank[inverse.ravel()], first[order]


def check_cell_arrays(cells: dict, engine: str = "warp", device: str = "cpu",
                      domain: ParameterDomain = DOMAIN) -> DomainCheck:
    """The domain of every cell, from per-cell arrays, before any increment is solved (``knitsim run``'s
    check of a patch, :func:`check_cells`).

    No Python object per cell: the box is judged on the arrays (:meth:`ParameterDomain.outside_arrays`),
    and the rest state is decided by the engine that would run the cells, with its own test, so that a
    cell flagged here is exactly one the engine would flag ``no_rest_state`` at rest: the Warp batch
    (:meth:`knitsim.cell.batch.CellModel.state` of a model built by
    :meth:`~knitsim.cell.batch.CellModel.from_arrays`, every distinct cell in one launch) or the NumPy
    reference (:func:`knitsim.cell.inverse.initial_state` and R >= 0, as
    :meth:`knitsim.cell.cycle.CellCycle.run`).  Identical geometries (B, d, L, W0, C0, phi0) are solved once,
    with the fields of the first cell that holds them.  (``knitsim run``'s check of a 300 x 300 random-phi0
    patch on a 2-core box: 4.6-5.0 s with a CellParams per cell, validated twice, and a per-cell why_outside;
    2.1-2.4 s from the arrays, of which 2.0-2.2 s the rest-state launch of 90,000 states on the CPU.)

    Parameters
    ----------
    cells : dict of str to ndarray, shape [N]
        Validated cells (:meth:`CellParams.validated`; :meth:`knitsim.patch.model.Grouping.validate`) as
        :attr:`knitsim.patch.model.Grouping.cells` holds them: ``B, d, L, W0, C0, m, phi0, dahl_sigma``
        and ``in_plane_width`` (NaN: none, the cell jams at d) as floats, ``force_cap_N`` numbers [N],
        the rules ``friction, unloading_rule, reload_rule, jamming_criterion`` (names) and ``effects``
        (:class:`~knitsim.cell.effects.EffectSet` objects).
    engine : {"warp", "reference"}
    device : str
        Warp device (warp engine).
    domain : ParameterDomain
        The box a cell must lie in to be inside the domain (default :data:`DOMAIN`).

    Returns
    -------
    DomainCheck
    """
    f = {k: np.atleast_1d(np.asarray(cells[k], dtype=np.float64))
         for k in ("B", "d", "L", "W0", "C0", "m", "phi0", "dahl_sigma", "in_plane_width")}
    n = len(f["d"])
    f = {k: np.broadcast_to(v, (n,)) for k, v in f.items()}
    # a non-finite width is no width (NaN), as Grouping.cell_params reads it for CellParams
    w = np.where(np.isfinite(f["in_plane_width"]), f["in_plane_width"], np.nan)
    phimax = phimax_of(f["m"])
    code, value = domain.outside_arrays(f["d"], f["B"], f["L"], f["W0"], f["C0"], f["m"], f["phi0"],
                                        np.where(np.isnan(w), f["d"], w), phimax)
    # the distinct rest geometries (_rest_key), numbered in the order the cells first hold them
    rest_of_cell, first = _first_rows(np.stack([f[k] for k in ("B", "d", "L", "W0", "C0", "phi0")], axis=1))
    why_u: list = [None] * len(first)
    F_u = np.full(len(first), np.nan)
    if len(first) and engine == "warp":
        from .. import warp_runtime
        from .batch import CellModel
        from .history import STATUS_NO_REST_STATE

        warp_runtime.init()                  # quiet, stable kernel cache: before any kernel module loads
        from .quantities import CODE

        def col(k):
            return np.broadcast_to(np.asarray(cells[k], dtype=object), (n,))[first]

        st = CellModel.from_arrays(
            f["B"][first], f["d"][first], f["L"][first], f["W0"][first], f["C0"][first], f["m"][first],
            f["phi0"][first], friction=col("friction"), dahl_sigma=f["dahl_sigma"][first],
            unloading_rule=col("unloading_rule"), reload_rule=col("reload_rule"),
            jamming_criterion=col("jamming_criterion"),
            force_cap_N=np.broadcast_to(np.asarray(cells["force_cap_N"], dtype=np.float64), (n,))[first],
            in_plane_width=w[first], effects=col("effects"), device=device).state()
        status0 = np.asarray(st.status.numpy())
        q = st.q.numpy()
        R = np.asarray(q[:, CODE["R"]])
        F_u = np.asarray(q[:, CODE["F"]], dtype=np.float64)
        # CellModel.state has set NO_REST_STATE where the solve failed or R < 0: a finite R < 0 says which
        for i in np.nonzero(status0 == STATUS_NO_REST_STATE)[0]:
            why_u[i] = _no_rest_reason(float(R[i]) if np.isfinite(R[i]) else None)
    elif len(first):
        for k, i in enumerate(first):
            res, ok = _solve_rest_state_of(tuple(float(f[c][i]) for c in ("B", "d", "L", "W0", "C0", "phi0")))
            if ok:
                F_u[k] = float(res.state.F)
            if not ok or float(res.state.R) < 0.0:
                why_u[k] = _no_rest_reason(float(res.state.R) if ok else None)
    return DomainCheck(code, value, phimax, rest_of_cell, why_u, F_u, domain)


def check_cells(params, engine: str = "warp", device: str = "cpu",
                domain: ParameterDomain = DOMAIN) -> DomainCheck:
    """The domain of every cell of a list of :class:`CellParams`, before any increment is solved (sweep
    planner): :func:`check_cell_arrays` of their fields.

    Each cell is validated first (:meth:`CellParams.validated`, the error naming ``cells[i]``; only the cells
    that :func:`~knitsim.cell.material.may_refuse` flags are asked).

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
    from .material import NUMERIC_FIELDS, may_refuse

    params = list(params)
    n = len(params)
    for i, p in enumerate(params):
        if not isinstance(p, CellParams):
            raise KnitsimInputError(f"cells[{i}] = {p!r}: expected a CellParams")
    names = NUMERIC_FIELDS + ("friction", "unloading_rule", "reload_rule", "jamming_criterion", "effects")
    cells = {k: np.fromiter((getattr(p, k) for p in params), dtype=object, count=n) for k in names}
    for i in np.nonzero(may_refuse(cells, n))[0]:
        params[i] = params[i].validated(where=f"cells[{i}]")   # (a NumPy number: read as a float)
        for k in names:
            cells[k][i] = getattr(params[i], k)
    cells["in_plane_width"] = np.array([np.nan if v is None else v for v in cells["in_plane_width"]], np.float64)
    cells["force_cap_N"] = np.array([p.cap_N for p in params], dtype=np.float64)
    return check_cell_arrays(cells, engine, device, domain)
