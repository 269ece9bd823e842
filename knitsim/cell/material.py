"""Immutable description of one quarter-stitch cell: yarn, knit, friction, rules.

The evolving state (angles, P, stage, frozen values) lives in
:mod:`knitsim.cell.cycle`; this module only describes the cell and validates it,
so that bad input is refused before any solve.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import asdict, dataclass, replace

import numpy as np

from ..errors import KnitsimInputError
from .effects import NO_EFFECTS, EffectSet
#: the default force cap per wale, in units of the yarn's own force scale B / d^2 (the elastica's forces
#: scale so, eqs 6-9).  Measured over 2,000 random cells of the domain (knitsim.cell.domain) pulled
#: monotonically to strain 1.2 with no cap, at increments 0.02, 0.005 and 0.001: the rest states carry
#: at most 29.7 B / d^2 (README: up to ~32 for the tightest loops), and the solver follows every
#: jammed branch to at least 79 B / d^2 (median 145-235) before alpha - gamma underflows.  50 B / d^2
#: lies between them: any cell of the domain loads from rest and stops at the cap, an expected end,
#: not a failure.  (The earlier default, 50 N, is 54 B / d^2 for the paper's E-glass but 540 B / d^2
#: for a yarn of a tenth of its B: such a cell failed up the jammed branch at ~164 B / d^2, exit 1.)
FORCE_CAP_PER_FORCE_SCALE = 50.0


def default_force_cap_N(B: float, d: float) -> float:
    """The default force cap per wale [N]: :data:`FORCE_CAP_PER_FORCE_SCALE` x B / d^2 (B [N mm^2], d [mm];
    scalars, or arrays of shape [N])."""
    if np.ndim(B) == 0 and np.ndim(d) == 0:
        return FORCE_CAP_PER_FORCE_SCALE * float(B) / float(d) ** 2
    return FORCE_CAP_PER_FORCE_SCALE * np.asarray(B, float) / np.asarray(d, float) ** 2


#: how a default cap is described in outputs
DEFAULT_FORCE_CAP_TEXT = f"default: {FORCE_CAP_PER_FORCE_SCALE:g} B / d^2, the yarn's own force scale"


from .stages import (DAHL_SIGMA_MAX, DAHL_SIGMA_TOO_STIFF, FRICTION_MODELS, JAMMING_CRITERIA, M_MAX, M_TOO_LARGE,
                     RELOAD_RULES, UNLOADING_RULES)


@dataclass(frozen=True)
class CellParams:
    """One cell's material, knit geometry, friction law and sequencing rules.

    Attributes
    ----------
    B : float
        Yarn bending stiffness [N mm^2] (Dusserre Table 1).
    d : float
        Yarn diameter [mm]; jamming at W = 4 d (Hong et al. 2002).
    L : float
        Yarn length per stitch [mm] (inextensible).
    W0, C0 : float
        Wale width and course length of the knit at rest [mm].
    m : float
        Apparent tangent-to-normal ratio at the crossing, m = tan(phimax) (eq 10).
    phi0 : float
        Initial friction angle [rad], in [-phimax, phimax] (section 3.3.1).
    friction : str
        ``"coulomb"`` (Table 4 switching) or ``"dahl"`` (smooth stick-slip).
    dahl_sigma : float
        Dahl stiffness of tan(phi) per unit slip [1/mm] (``friction = "dahl"``).
    unloading_rule, reload_rule, jamming_criterion : str
        See :mod:`knitsim.cell.stages`.
    force_cap_N : float or None
        Force per wale at which a jammed cell stops (the jammed branch diverges) [N]; None (the
        default) is :func:`default_force_cap_N`, 50 B / d^2, resolved with the cell's own B and d
        (:attr:`cap_N`), so that a copy with another B or d keeps a default cap of its own.
    in_plane_width : float or None
        In-plane yarn width used for jamming [mm] (W = 4 in_plane_width, or head
        gap = in_plane_width); None means d.  The paper's d is the compact hexagonal
        packing diameter, used for bending; a loose roving is wider in the
        plane of the knit (docs/model.md, "Jamming"), hence >= d.
    effects : EffectSet
        Model extensions switched on (:mod:`knitsim.cell.effects`; Warp batch
        only); none by default.
    """

    B: float
    d: float
    L: float
    W0: float
    C0: float
    m: float = 0.0
    phi0: float = 0.0
    friction: str = "coulomb"
    dahl_sigma: float = 0.0
    unloading_rule: str = "dusserre"
    reload_rule: str = "mirror_unloading"
    jamming_criterion: str = "w_4d"
    force_cap_N: float | None = None
    in_plane_width: float | None = None
    effects: EffectSet = NO_EFFECTS

    @property
    def d_jam(self) -> float:
        """Yarn width that jams neighbouring loops [mm]: ``in_plane_width`` or d."""
        return self.d if self.in_plane_width is None else float(self.in_plane_width)

    @property
    def cap_N(self) -> float:
        """The force cap per wale in force [N]: ``force_cap_N``, or the default 50 B / d^2 where it is None."""
        return default_force_cap_N(self.B, self.d) if self.force_cap_N is None else float(self.force_cap_N)

    @property
    def cap_is_default(self) -> bool:
        """True where the cap is the default (``force_cap_N`` None)."""
        return self.force_cap_N is None

    @property
    def phimax(self) -> float:
        """Friction angle at sliding, atan(m) [rad]."""
        return math.atan(self.m)

    def replace(self, **changes) -> "CellParams":
        """A copy with some fields changed (validated)."""
        return replace(self, **changes).validated()

    def as_dict(self) -> dict:
        """Fields by name (a default force cap as its value in N); ``effects`` only when some are on."""
        d = asdict(self)
        if self.force_cap_N is None:
            d["force_cap_N"] = self.cap_N
        d.pop("effects")
        if self.effects.on:
            d["effects"] = self.effects.as_dict()
        return d

    def validated(self, where: str = "cell") -> "CellParams":
        """Check every field; raise :class:`KnitsimInputError` naming the first bad one."""
        def bad(name, why):
            raise KnitsimInputError(f"{where}.{name} = {getattr(self, name)!r}: {why}")

        # a NumPy number (np.float32(0.31), np.int64(15), a 0-d array) is a number: read as a Python float
        # (it was refused as "must be a finite number", a blind probe of the API)
        numeric = ("B", "d", "L", "W0", "C0", "m", "phi0", "dahl_sigma", "force_cap_N", "in_plane_width")
        conv = {}
        for name in numeric:
            v = getattr(self, name)
            if isinstance(v, (numbers.Real, np.ndarray)) and not isinstance(v, (bool, np.bool_, float)) \
                    and np.ndim(v) == 0 and np.issubdtype(np.asarray(v).dtype, np.number):
                conv[name] = float(v)
        if conv:
            return replace(self, **conv).validated(where)
        for name in ("B", "d", "L", "W0", "C0", "m", "phi0", "dahl_sigma", "force_cap_N"):
            v = getattr(self, name)
            if name == "force_cap_N" and v is None:
                continue
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
                bad(name, "must be a finite number")
        for name in ("B", "d", "L", "W0", "C0", "force_cap_N"):
            if getattr(self, name) is not None and getattr(self, name) <= 0:
                bad(name, "must be > 0")
        if self.m < 0:
            bad("m", "the friction ratio must be >= 0")
        if self.m > M_MAX:
            bad("m", M_TOO_LARGE)
        if self.in_plane_width is not None:
            v = self.in_plane_width
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
                bad("in_plane_width", "must be a finite number or None")
            if v < self.d:
                bad("in_plane_width", f"the in-plane width cannot be below the compact diameter d = {self.d} mm")
            if self.W0 < 4.0 * v:
                bad("in_plane_width", f"loops jammed at rest: W0 = {self.W0} < 4 in_plane_width")
        if self.W0 < 4.0 * self.d:
            bad("W0", f"the wale width at rest must be >= 4 d = {4.0 * self.d:.4g} mm (loops jammed already)")
        lmin = 2.0 * self.C0 + self.W0 - 4.0 * self.d
        if self.L <= lmin:
            bad("L", f"too short to close a loop: needs > 2 C0 + W0 - 4 d = {lmin:.4g} mm")
        if abs(self.phi0) > self.phimax + 1e-12:
            bad("phi0", f"must lie in [-phimax, phimax] = [{-self.phimax:.4g}, {self.phimax:.4g}] rad (m = {self.m})")
        if self.friction not in FRICTION_MODELS:
            bad("friction", f"expected one of {', '.join(FRICTION_MODELS)}")
        if self.friction == "dahl" and self.dahl_sigma <= 0:
            bad("dahl_sigma", "Dahl friction needs a stiffness > 0 (1/mm)")
        if self.friction == "dahl" and self.dahl_sigma > DAHL_SIGMA_MAX:
            bad("dahl_sigma", DAHL_SIGMA_TOO_STIFF)
        if self.unloading_rule not in UNLOADING_RULES:
            bad("unloading_rule", f"expected one of {', '.join(UNLOADING_RULES)}")
        if self.reload_rule not in RELOAD_RULES:
            bad("reload_rule", f"expected one of {', '.join(RELOAD_RULES)}")
        if self.jamming_criterion not in JAMMING_CRITERIA:
            bad("jamming_criterion", f"expected one of {', '.join(JAMMING_CRITERIA)}")
        if not isinstance(self.effects, EffectSet):
            bad("effects", "expected an EffectSet (knitsim.cell.effects)")
        self.effects.validated(where=f"{where}.effects")
        return self


#: the numeric fields of :class:`CellParams`, as :meth:`CellParams.validated` reads them
NUMERIC_FIELDS = ("B", "d", "L", "W0", "C0", "m", "phi0", "dahl_sigma", "force_cap_N", "in_plane_width")


def phimax_of(m) -> np.ndarray:
    """atan(m) of each element [rad]: :attr:`CellParams.phimax` bit for bit (math.atan; NumPy's arctan may differ
    from it in the last bit, and a cell at the cone's edge would then be judged otherwise), computed once per
    distinct value (a patch holds few)."""
    u, inverse = np.unique(np.asarray(m, dtype=np.float64), return_inverse=True)
    return np.array([math.atan(v) for v in u.tolist()], dtype=np.float64)[inverse.ravel()]


def _plain_numbers(values, n: int, none: bool) -> tuple[np.ndarray, np.ndarray]:
    """``values`` (a scalar or an array of ``n``) as float64 [n], and where the per-object check might refuse
    the value as a number: anything but a Python int or float (a bool is not one), or not finite.  ``none``:
    None (a float NaN in an array of floats) is the field's absent value, not flagged, NaN in the floats."""
    a = np.asarray(values)
    if a.dtype.kind in "fiu":
        x = np.broadcast_to(a.astype(np.float64), (n,))
        bad = ~np.isfinite(x)
        return x, (bad & ~np.isnan(x)) if none else bad
    lst = np.broadcast_to(np.asarray(values, dtype=object), (n,)).tolist()
    types = set(map(type, lst))
    if all(issubclass(t, (int, float)) and not issubclass(t, bool) for t in types):
        try:
            x = np.array(lst, dtype=np.float64)
        except OverflowError:                   # an int too large for a float: the slow path says which
            pass
        else:
            return x, ~np.isfinite(x)
    # the rare array of other things (NumPy numbers, None, text): told apart one element at a time; a NumPy
    # number is flagged, and CellParams.validated (which reads it as a float) then passes it
    x = np.full(n, np.nan)
    bad = np.zeros(n, bool)
    for i, v in enumerate(lst):
        if v is None and none:
            continue
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            try:
                x[i] = float(v)
            except OverflowError:
                bad[i] = True
                continue
            bad[i] = not math.isfinite(x[i])
        else:
            bad[i] = True
            try:
                x[i] = float(v)
            except (TypeError, ValueError, OverflowError):
                pass
    return x, bad


def _not_one_of(values, n: int, allowed: tuple) -> np.ndarray:
    """Where ``values`` (a scalar or an array of ``n``) is not one of the names ``allowed`` [bool, n]; the
    distinct values are compared, not every element (a patch's rules are mostly one name)."""
    lst = np.broadcast_to(np.asarray(values, dtype=object), (n,)).tolist()
    try:
        if set(lst) <= set(allowed):
            return np.zeros(n, bool)
    except TypeError:                          # an unhashable value: compared one by one below
        pass
    return np.array([not (isinstance(v, str) and v in allowed) for v in lst], dtype=bool)


def may_refuse(cells: dict, n: int) -> np.ndarray:
    """Per cell, whether :meth:`CellParams.validated` may refuse it, from per-cell arrays and without a
    :class:`CellParams` per cell [bool, n].

    A superset, never fewer: every condition of :meth:`CellParams.validated` is tested here on the arrays, in
    the same arithmetic (so that a valid cell of float fields is not flagged), and a value the arrays cannot
    tell (a NumPy number in an array of objects) is flagged.  The per-object check stays the one statement of
    the rules and of their messages: a caller validates only the flagged cells, in order, with it (building
    and validating a CellParams per cell was most of the 2.6 s that ``knitsim run``'s domain check of a
    300 x 300 random patch spent besides its rest-state launch, on a 2-core box).

    Parameters
    ----------
    cells : dict of str to array
        :data:`NUMERIC_FIELDS` (floats, or objects; ``force_cap_N`` and ``in_plane_width`` None or NaN:
        absent), the rules ``friction``, ``unloading_rule``, ``reload_rule``, ``jamming_criterion`` (names)
        and ``effects`` (:class:`~knitsim.cell.effects.EffectSet`), each a scalar or an array of ``n``.
    n : int
        Cells.
    """
    x, flag = {}, np.zeros(n, bool)
    for name in NUMERIC_FIELDS:
        x[name], bad = _plain_numbers(cells[name], n, none=name in ("force_cap_N", "in_plane_width"))
        flag |= bad
    with np.errstate(invalid="ignore"):
        for name in ("B", "d", "L", "W0", "C0"):
            flag |= ~(x[name] > 0)
        flag |= x["force_cap_N"] <= 0
        flag |= ~(x["m"] >= 0) | (x["m"] > M_MAX)
        w = x["in_plane_width"]
        given = ~np.isnan(w)
        flag |= given & ((w < x["d"]) | (x["W0"] < 4.0 * w))
        flag |= x["W0"] < 4.0 * x["d"]
        flag |= x["L"] <= 2.0 * x["C0"] + x["W0"] - 4.0 * x["d"]
        flag |= np.abs(x["phi0"]) > phimax_of(x["m"]) + 1e-12
    flag |= _not_one_of(cells["friction"], n, FRICTION_MODELS)
    dahl = np.broadcast_to(np.asarray(cells["friction"], dtype=object) == "dahl", (n,))
    flag |= dahl & ~((x["dahl_sigma"] > 0) & (x["dahl_sigma"] <= DAHL_SIGMA_MAX))
    for name, allowed in (("unloading_rule", UNLOADING_RULES), ("reload_rule", RELOAD_RULES),
                          ("jamming_criterion", JAMMING_CRITERIA)):
        flag |= _not_one_of(cells[name], n, allowed)
    # the effect sets: each distinct object validated once (a patch holds a few, often one shared by all)
    eff = np.broadcast_to(np.asarray(cells["effects"], dtype=object), (n,))
    ids = np.fromiter(map(id, eff.tolist()), dtype=np.int64, count=n)
    _, first, inverse = np.unique(ids, return_index=True, return_inverse=True)
    bad_set = np.zeros(len(first), bool)
    for k, i in enumerate(first):
        e = eff[i]
        try:
            bad_set[k] = not isinstance(e, EffectSet)
            if not bad_set[k]:
                e.validated()
        except KnitsimInputError:
            bad_set[k] = True
    flag |= bad_set[inverse.ravel()]
    return flag
