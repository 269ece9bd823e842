"""Switchable model extensions of the quarter-stitch cell (issue 6; Dusserre 2015 sections 4-5).

Dusserre lists what his model leaves out and why its curves are too sharp.
Six of those effects act in the batched kernels by changing, at each load
increment, the parameters the stage logic reads (``m``, ``d``, ``L``, ``B``);
the seventh, ``dahl_transition``, is the Dahl friction state that already
replaces the Coulomb switching (``CellParams.friction = "dahl"``).

For a Coulomb cell the friction ratio of the coiling angle and of the normal
load is read at the solution itself (implicit): the sliding condition of S+/S-
becomes ``phi = +/-atan(m(beta, Rn))`` and the slide and cone events are judged
on the edge of the state's own cone (kernels.cell_step.friction_ratio), so the
curve carries no increment error (issue 12: lagged by one increment, near F = 0
on unloading, where Rn -> 0 raises the ratio when n < 1, it moved a cell's slack
point by 0.1 mm from one halving of the increment to the next).  Under Dahl
friction the ratio, and in every cell the velocity factor (the rate of the
increment), are computed from the state at the increment's start (an explicit,
increment-lagged coupling, a first-order error in the increment).  The bending
stiffness B is that of each state's own course length C: the bending Dahl state
in its closed form from the increment's start to C (exact over a monotone
stretch), also at a located event, where B and the event's C are solved together
(kernels.cell_step.stiffness_at, bending_fixed_point); before, B was that of the
sub-step's end and the cycle moved by up to 0.02 N per halving of the increment
(tests/cell/test_increment_convergence.py).  The two laws that change the geometry, the
compacted jam width and the extensible yarn's length, are implicit: they
replace a condition of Table 4 (W = 4 d, L) by one that reads the load at the
solution itself, so they carry no increment error.  Every effect is *off* by default
and then leaves the baseline bit-for-bit unchanged (the kernel does not touch
the parameters at all).

=========================  ====================================================  =================
effect                     law (lagged, unless said implicit)                  parameters
=========================  ====================================================  =================
coiling_angle_friction     ``m = eq10(theta, mu_k)``, theta = beta, the tangent  coil_mu_k
                           angle at the crossing B (eq 11's coiling angle in
                           the jammed geometry of Fig. 6c); implicit (Coulomb)
normal_load_friction       ``m <- m (Rn / Fn_ref)^(n - 1)`` (eq 5, b absorbed    load_n, load_ref_N
                           in m: m is the ratio at Fn_ref); implicit (Coulomb)
velocity_friction          ``m <- m (V / V_ref)^p`` (eq 5), V the test rate of   rate_p, rate_ref_mm_s
                           the increment (the sliding velocity at the crossing
                           is taken proportional to the crosshead rate; the
                           constant is absorbed in m)
yarn_compaction            jamming at ``W = 4 d_eff``,                           compaction_k, compaction_min
                           ``d_eff = d clamp((1 + k Rn_0) / (1 + k Rn), c_min, 1)``
                           (d is the diameter at the rest load), with Rn read
                           at the solution itself (implicit: a lagged width
                           oscillates on the stiff jammed branch); the bending
                           and crossing geometry keep d
bending_hysteresis         ``B <- B (1 + h z)``, z a Dahl state (alpha = 1) in   bend_h, bend_sigma
                           the strain: ``z = s + (z_old - s) exp(-sigma |de|)``,
                           de from the increment's start to the state's own C
                           (implicit)
                           (Dahl 1976; a friction moment proportional to the
                           elastic one, saturating at h of it)
yarn_extension             the length condition becomes                          ext_c
                           ``L = L_0 (1 + c (P - P_0))``, P the yarn force at
                           the inflection point A (moment-free there), read at
                           the solution itself (implicit: the lagged length
                           was, at increments of 0.01 strain, a hundred noise
                           variances off the converged curve on the jammed
                           branch, and read as compaction by the diagnosis)
=========================  ====================================================  =================

Known limitation: ``bending_hysteresis`` scales B, which scales the force
only where the stage's conditions are all geometric; with Table 4's frozen
normal load (S+, and the frictionless cell) it is not, and a frictionless
cell's loop then runs the non-dissipative way (tests/cell/test_effects.py).
A friction moment added to the elastica's moment equation would be exact.

``Rn_0`` and ``P_0`` are the values of the initial state (Table 4's rest
state), so that the given d and L are those of the knit at rest.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace

import numpy as np

from ..errors import KnitsimInputError

#: bit of each kernel effect in the per-cell mask
EFFECT_BITS: dict[str, int] = {
    "coiling_angle_friction": 1,
    "normal_load_friction": 2,
    "velocity_friction": 4,
    "yarn_compaction": 8,
    "bending_hysteresis": 16,
    "yarn_extension": 32,
}

#: every effect the diagnosis knows, in a stable order (dahl_transition is CellParams.friction = "dahl")
EFFECT_NAMES: tuple[str, ...] = ("dahl_transition",) + tuple(EFFECT_BITS)

#: column of each parameter in the kernels' per-cell parameter row
PARAM_COLUMNS: tuple[str, ...] = (
    "coil_mu_k", "load_n", "load_ref_N", "rate_p", "rate_ref_mm_s",
    "compaction_k", "compaction_min", "bend_h", "bend_sigma", "ext_c",
)

#: the parameters of each effect (the module's table): a parameter of an effect that is off changes nothing
EFFECT_PARAMETERS: dict[str, tuple[str, ...]] = {
    "coiling_angle_friction": ("coil_mu_k",), "normal_load_friction": ("load_n", "load_ref_N"),
    "velocity_friction": ("rate_p", "rate_ref_mm_s"), "yarn_compaction": ("compaction_k", "compaction_min"),
    "bending_hysteresis": ("bend_h", "bend_sigma"), "yarn_extension": ("ext_c",),
}

#: columns of the per-cell effective state (knitsim.kernels.effects)
EFFECT_STATE: tuple[str, ...] = ("m_eff", "d_eff", "L_eff", "B_eff", "z_bend", "P_rest", "Rn_rest")

#: largest effective friction ratio (eq 5 with n < 1 grows without bound as Rn -> 0): a ratio the Table 4 cell
#: converges at.  Measured (benchmarks/bench_convergence.py's 300 domain cells with m replaced, the paper's
#: program at 0.01): m = 1, every cell with a rest state finishes; 1.1: 3 fail; 1.5: 52; 2: 115; 5: all (the
#: T-frozen stick after a reversal leaves the cone by its + edge and runs to the contact's opening).  At the
#: cap 5 that was, normal-load friction n = 0.5 failed on 46 of those cells, n = 0.8 on 4; now 0.  A ratio of 1
#: is a friction angle of 45 degrees, beyond the apparent ratios 0.06-0.6 of Dusserre's section 3.4 (eq 10 over
#: the coiling angles at rest and jammed) and the domain's 0.05-0.5
M_EFF_MAX = 1.0

#: each effect's strength and the value at which the effect changes nothing (eq 5 with n = 1 or p = 0; a rigid,
#: an inextensible yarn; no bending friction); coiling_angle_friction has none (eq 10 at the current angle)
NEUTRAL_STRENGTH: dict[str, tuple[str, float]] = {
    "normal_load_friction": ("load_n", 1.0), "velocity_friction": ("rate_p", 0.0),
    "yarn_compaction": ("compaction_k", 0.0), "bending_hysteresis": ("bend_h", 0.0), "yarn_extension": ("ext_c", 0.0),
}


@dataclass(frozen=True)
class EffectSet:
    """Which kernel effects are on, and their parameters (immutable).

    Attributes
    ----------
    on : tuple of str
        Names from :data:`EFFECT_BITS` that are switched on.
    coil_mu_k : float
        Kinetic friction coefficient of eq 10 [-].
    load_n : float
        Normal-load exponent n of eq 5 [-] (1: no effect).
    load_ref_N : float
        Normal load at which the ratio equals ``m`` [N].
    rate_p : float
        Velocity exponent p of eq 5 [-] (0: no effect).
    rate_ref_mm_s : float
        Test rate at which the ratio equals ``m`` [mm/s].
    compaction_k : float
        Transverse compliance of the yarn at the crossing [1/N] (0: rigid).
    compaction_min : float
        Smallest d_eff / d (the compacted yarn's packing limit) [-].
    bend_h : float
        Saturated friction moment as a fraction of the elastic one [-].
    bend_sigma : float
        Dahl rate of the bending friction per unit strain [-].
    ext_c : float
        Tensile compliance 1/(EA) of the yarn [1/N].
    """

    on: tuple = ()
    coil_mu_k: float = 0.3
    load_n: float = 1.0
    load_ref_N: float = 0.1
    rate_p: float = 0.0
    rate_ref_mm_s: float = 1.0
    compaction_k: float = 0.0
    compaction_min: float = 0.5
    bend_h: float = 0.0
    bend_sigma: float = 20.0
    ext_c: float = 0.0

    @property
    def mask(self) -> int:
        """Bit mask of the effects that are on."""
        return int(sum(EFFECT_BITS[n] for n in self.on))

    def row(self) -> np.ndarray:
        """The parameters in :data:`PARAM_COLUMNS` order (float64)."""
        return np.array([float(getattr(self, c)) for c in PARAM_COLUMNS], np.float64)

    def inert(self) -> tuple[str, ...]:
        """The effects switched on whose strength is at the value where they change nothing
        (:data:`NEUTRAL_STRENGTH`: yarn_compaction with compaction_k = 0, its default, runs as if it were off)."""
        return tuple(n for n in self.on if n in NEUTRAL_STRENGTH
                     and getattr(self, NEUTRAL_STRENGTH[n][0]) == NEUTRAL_STRENGTH[n][1])

    def with_on(self, *names: str, **params) -> "EffectSet":
        """A copy with ``names`` switched on too and some parameters changed (validated)."""
        on = tuple(dict.fromkeys(tuple(self.on) + tuple(names)))
        return replace(self, on=on, **params).validated()

    def as_dict(self) -> dict:
        """Fields by name, ``on`` as a list."""
        d = asdict(self)
        d["on"] = list(self.on)
        return d

    def validated(self, where: str = "effects") -> "EffectSet":
        """Check every field; raise :class:`KnitsimInputError` naming the first bad one."""
        if isinstance(self.on, str) or not all(isinstance(n, str) for n in self.on):
            raise KnitsimInputError(f"{where}.on = {self.on!r}: expected a list of effect names")
        for n in self.on:
            if n not in EFFECT_BITS:
                extra = " (dahl_transition is friction = 'dahl')" if n == "dahl_transition" else ""
                raise KnitsimInputError(f"{where}.on: unknown effect {n!r}{extra}; expected {', '.join(EFFECT_BITS)}")
        for f in fields(self):
            if f.name == "on":
                continue
            v = getattr(self, f.name)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
                raise KnitsimInputError(f"{where}.{f.name} = {v!r}: must be a finite number")
        checks = (
            ("coil_mu_k", self.coil_mu_k > 0, "must be > 0"),
            ("load_ref_N", self.load_ref_N > 0, "must be > 0"),
            ("load_n", 0 < self.load_n <= 2, "expected 0 < n <= 2 (eq 5; n = 1 is Amontons)"),
            ("rate_ref_mm_s", self.rate_ref_mm_s > 0, "must be > 0"),
            ("rate_p", abs(self.rate_p) <= 1, "expected |p| <= 1"),
            ("compaction_k", self.compaction_k >= 0, "must be >= 0"),
            ("compaction_min", 0 < self.compaction_min <= 1, "expected 0 < d_min/d <= 1"),
            ("bend_h", 0 <= self.bend_h < 1, "expected 0 <= h < 1"),
            ("bend_sigma", self.bend_sigma > 0, "must be > 0"),
            ("ext_c", self.ext_c >= 0, "must be >= 0"),
        )
        for name, ok, why in checks:
            if not ok:
                raise KnitsimInputError(f"{where}.{name} = {getattr(self, name)!r}: {why}")
        return self


NO_EFFECTS = EffectSet()


def effect_set_codes(sets: np.ndarray) -> tuple[np.ndarray, list]:
    """An integer per element of a 1-d object array of :class:`EffectSet`, and the distinct sets in the
    order of the codes (the order in which the elements first hold them).

    Without a Python loop over the elements (10^6 cells of a patch hold a few distinct sets, often one
    object shared by all): the elements are first told apart by the identity of their object, and only
    the distinct objects are compared by value (two equal sets are one code).
    """
    flat = np.asarray(sets, dtype=object).ravel()
    ids = np.fromiter(map(id, flat), dtype=np.int64, count=flat.size)
    _, first, inverse = np.unique(ids, return_index=True, return_inverse=True)
    by_value: dict = {}
    obj_code = np.empty(len(first), np.int64)
    uniq: list = []
    # the distinct objects in the order the elements first hold them: codes independent of where the
    # objects lie in memory
    for k in np.argsort(first, kind="stable"):
        e = flat[first[k]]
        if e not in by_value:
            by_value[e] = len(uniq)
            uniq.append(e)
        obj_code[k] = by_value[e]
    return obj_code[inverse.ravel()], uniq
