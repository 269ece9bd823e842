"""The effects the diagnosis can add, as fit variables (issue 6).

Each effect of :data:`knitsim.cell.effects.EFFECT_NAMES` is a set of fit
variables with bounds and a start where the effect vanishes (or nearly:
Dahl at 10^2.5 / mm is close to Coulomb switching, and at its largest stiffness,
10^6 / mm, one of its further starts, Coulomb switching to 1e-6 N, with Hong's constant-T
unloading, its limit, not the default ``dusserre`` rule: :data:`DAHL_LIMIT_UNLOADING_RULE`),
so that its fit starts from the baseline it extends, and a map from their values to the
:class:`~knitsim.cell.material.CellParams` of the model with the effect on.
The laws themselves live in :mod:`knitsim.cell.effects` (Python description)
and :mod:`knitsim.kernels.effects` (device code).

Baseline variables: ``m``, ``phi0`` (as a fraction of phimax = atan(m), so
that its bounds hold while m moves, section 3.3.1), ``B``, ``d``, the yarn's
in-plane width (default bounds d .. W0/4: a flattened roving jams wider than it
bends; kept inside [d, W0/4) as d and W0 move), and the knit geometry ``L``,
``W0``, ``C0`` (default bounds +-5 %: specimen-to-specimen scatter, which an
effect would otherwise absorb).

``coiling_angle_friction`` *replaces* ``m``: m follows eq 10 from the loop's
coiling angle, so the effect adds ``coil_mu_k`` and removes ``m`` (no extra
parameter).  Its rest value (which sets the range of phi0 and the initial
stage) is eq 10 at the rest state's beta, which does not depend on m (the
rest state imposes C0, W0, L and phi0 only).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..cell.effects import EFFECT_BITS, EFFECT_NAMES
from ..cell.material import CellParams
from ..cell.stages import DAHL_SIGMA_MAX
from ..errors import KnitsimInputError
from ..friction.coiling import m_eq10


@dataclass(frozen=True)
class Variable:
    """A fitted variable: default bounds and a start computed from the base parameters."""

    name: str
    bounds: tuple[float, float]
    start: Callable[[CellParams], float]
    unit: str
    doc: str
    #: the ends of its search beyond which lies more of the effect ("lower", "upper"): a fit stopped there may
    #: be short of the data (:func:`knitsim.diagnosis.diagnose.capped_candidates`); the other end is where the
    #: effect vanishes (0 of a compliance; Coulomb switching, the sharp end of the Dahl stiffness) or, for m's
    #: replacement mu_k, not the effect's strength
    more: tuple[str, ...] = ()


def _mu_for_m(m: float, theta: float) -> float:
    # eq 10 solved for mu_k: tanh(mu theta / 2) = m / tan(theta / 2)
    r = min(max(m, 1e-3) / math.tan(0.5 * theta), 0.999)
    return 2.0 * math.atanh(r) / theta


#: solved rest states (key: B, d, L, W0, C0) that warm-start the next solve
_REST_CACHE: dict[tuple, np.ndarray] = {}
_REST_CACHE_MAX = 512
#: a cached rest state warm-starts a geometry within this relative distance (the state is smooth in it)
_REST_WARM_REL = 0.05


def rest_beta(B: float, d: float, L: float, W0: float, C0: float) -> float:
    """Tangent angle at the crossing in the rest state (phi = 0) [rad].

    The rest state (Table 4: C = C0, W = W0, L, phi = 0) is solved by Newton
    from the nearest rest state solved before (a fit perturbs the geometry by
    a hair: 8 ms instead of the 0.3 s of the multistart of
    :func:`knitsim.cell.inverse.initial_state`, which is kept for the first
    geometry and whenever the warm start fails).  The paper's knits have a
    single rest state (every converging start reaches it), so both give the
    same beta to the solver's tolerance.
    """
    from ..cell.inverse import initial_state, solve_state

    key = (float(B), float(d), float(L), float(W0), float(C0))
    if key in _REST_CACHE:
        return float(_REST_CACHE[key][1])
    x = None
    if _REST_CACHE:
        ref = np.array(key)
        keys = np.array(list(_REST_CACHE))
        dist = np.max(np.abs(keys / ref - 1.0), axis=1)
        j = int(np.argmin(dist))
        if dist[j] <= _REST_WARM_REL:
            res = solve_state({"C": C0, "W": W0, "L": L, "phi": 0.0}, _REST_CACHE[tuple(keys[j])], B, d,
                              fallback=False)
            if res.success:
                x = np.asarray(res.x, float)
    if x is None:
        res = initial_state(C0, W0, L, 0.0, B, d)
        if not res.success:
            raise KnitsimInputError(f"knit (L = {L}, W0 = {W0}, C0 = {C0}, d = {d}): no rest state found")
        x = np.asarray(res.x, float)
    if len(_REST_CACHE) >= _REST_CACHE_MAX:
        _REST_CACHE.pop(next(iter(_REST_CACHE)))
    _REST_CACHE[key] = x
    return float(x[1])


def _beta0(p: CellParams) -> float:
    return rest_beta(p.B, p.d, p.L, p.W0, p.C0)


BASELINE_VARIABLES: dict[str, Variable] = {
    "m": Variable("m", (0.0, 1.0), lambda p: p.m, "-", "friction ratio tan(phimax) (eq 10)"),
    "phi0": Variable("phi0", (-1.0, 1.0), lambda p: (p.phi0 / p.phimax if p.phimax > 0 else 0.0), "-",
                     "initial friction angle as a fraction of phimax"),
    "B": Variable("B", (0.0, 0.0), lambda p: p.B, "N mm^2", "bending stiffness"),
    "d": Variable("d", (0.0, 0.0), lambda p: p.d, "mm", "yarn diameter"),
    "L": Variable("L", (0.0, 0.0), lambda p: p.L, "mm", "yarn length per stitch"),
    "W0": Variable("W0", (0.0, 0.0), lambda p: p.W0, "mm", "wale width at rest"),
    "C0": Variable("C0", (0.0, 0.0), lambda p: p.C0, "mm", "course length at rest"),
    "in_plane_width": Variable("in_plane_width", (0.0, 0.0), lambda p: p.d_jam, "mm",
                               "the yarn's in-plane width that jams loops (W = 4 w), in [d, W0/4)"),
}

#: a factor k on the measured strain (an extensometer's gauge length or factor off: the strain read is k times the
#: knit's): the replay runs at strain / k.  Not a parameter of the knit, and no scene frees it:
#: :func:`knitsim.diagnosis.calibrate.calibrate_baseline` applies it to the strain it replays, and the diagnosis
#: weighs it against an effect or the baseline as it weighs a force scale (:func:`knitsim.diagnosis.diagnose.scale_step`)
STRAIN_SCALE = Variable("strain_scale", (0.8, 1.25), lambda p: 1.0, "-",
                        "factor on the measured strain: the replay at strain / k")

#: baseline parameters the blind study's diagnosis calibrates: the friction (m, phi0) and the geometry
#: that its generator scatters from specimen to specimen (d, L, C0; W0 moves the curve least), which an
#: effect would otherwise absorb (a false alarm); defined here so that the CLI needs no study import
DEFAULT_STUDY_FREE = ("m", "phi0", "d", "L", "C0")


@dataclass(frozen=True)
class EffectSpec:
    """One effect as the diagnosis sees it."""

    name: str
    variables: tuple[Variable, ...]
    replaces: tuple[str, ...] = ()
    min_rates: int = 1
    doc: str = ""
    #: further starts of its variables (its least squares has local minima)
    extra_starts: tuple = ()
    #: the model equals the baseline bit for bit where the effect vanishes (a start of its fit)
    nests_baseline: bool = True
    #: multiples of the variable's start at which the diagnosis profiles the fit (its variable held,
    #: the baseline's refitted from the scene's geometry) before the race (:mod:`knitsim.diagnosis.diagnose`)
    profile: tuple = ()


#: the unloading rule of the Coulomb cell that a Dahl cell reaches as its stiffness sigma grows: a Dahl cell holds T
#: through the whole unloading (:mod:`knitsim.cell.stages`), Hong's rule, at every sigma.  Against a baseline of
#: another rule (the default ``dusserre``: SF- freezes beta, and the force falls at once) the Dahl candidate does not
#: contain the baseline at any sigma, so its chi^2 may lie far above the baseline's (an effect-free E-glass file made
#: with the dusserre rule: the baseline 314, the Dahl cell at the baseline's m and phi0 95,060 at sigma 10^2.5 and
#: 94,944 at 10^6, Coulomb with Hong's rule 94,944); against a ``hong_constant_t`` baseline it does, up to the
#: approach of its search's upper end (10^6 / mm: chi^2 0.008 above the limit on a Hong-made file)
DAHL_LIMIT_UNLOADING_RULE = "hong_constant_t"


def dahl_limit_note(base: CellParams) -> str:
    """Why the Dahl candidate does not contain a baseline of another unloading rule than its limit's ("" where it
    does: :data:`DAHL_LIMIT_UNLOADING_RULE`)."""
    if base.unloading_rule == DAHL_LIMIT_UNLOADING_RULE:
        return ""
    return (f"not nested in this baseline: at any Dahl stiffness, Coulomb's limit included, its cell holds T through "
            f"the whole unloading (unloading_rule = \"{DAHL_LIMIT_UNLOADING_RULE}\", Hong's), where the baseline's "
            f"rule is \"{base.unloading_rule}\"")


EFFECT_SPECS: dict[str, EffectSpec] = {
    "dahl_transition": EffectSpec(
        "dahl_transition",
        # searched up to the largest stiffness a cell takes, where the law is Coulomb's (with Hong's unloading) to
        # 1e-6 N, and started there too: with its search ending at 10^3 / mm the candidate stopped 9.3 in chi^2 above
        # a Hong baseline it contains (an effect-free Hong-made file: 390.1 against 380.8; the Dahl cell at the
        # baseline's m and phi0: 390.7 at 10^3, 381.6 at 10^4, 380.78 at 10^6, Coulomb-Hong 380.77)
        (Variable("log10_dahl_sigma", (-0.5, math.log10(DAHL_SIGMA_MAX)), lambda p: 2.5, "log10(1/mm)",
                  "Dahl stiffness of tan(phi) per unit slip (Dahl 1976)", more=("lower",)),),
        doc="Dahl friction state instead of Coulomb switching (smooth stick-slip)",
        extra_starts=({"log10_dahl_sigma": math.log10(DAHL_SIGMA_MAX)}, {"log10_dahl_sigma": 1.0},
                      {"log10_dahl_sigma": 0.4}), nests_baseline=False),
    "coiling_angle_friction": EffectSpec(
        "coiling_angle_friction",
        (Variable("coil_mu_k", (0.01, 2.0), lambda p: _mu_for_m(p.m, _beta0(p)), "-",
                  "kinetic friction coefficient of eq 10"),),
        replaces=("m",), doc="m follows eq 10 with the coiling angle of the current loop",
        extra_starts=({"coil_mu_k": 0.1}, {"coil_mu_k": 0.5}), nests_baseline=False,
        # it replaces m: mu_k and the yarn diameter trade along narrow valleys with many local minima
        # (a lab specimen: basins at mu_k = 0.09, 0.12, 0.16, 0.23), which a profile over mu_k finds
        profile=(0.7, 0.85, 1.0, 1.15, 1.3)),
    "normal_load_friction": EffectSpec(
        "normal_load_friction",
        (Variable("load_n", (0.4, 1.6), lambda p: 1.0, "-", "normal-load exponent n of eq 5", more=("lower", "upper")),),
        doc="mu_k = b Fn^(n-1) at the crossing (eq 5)",
        # Table 3: n < 1 (0.948 E-glass, 0.909 basalt); from n = 1 the fit has to cross a valley of d and L
        extra_starts=({"load_n": 0.8}, {"load_n": 0.65})),
    "velocity_friction": EffectSpec(
        "velocity_friction",
        (Variable("rate_p", (-0.4, 0.4), lambda p: 0.0, "-", "velocity exponent p of eq 5", more=("lower", "upper")),),
        min_rates=2, doc="mu_k = b V^p with V from the test rate (eq 5)",
        extra_starts=({"rate_p": 0.1},)),  # Table 3: p > 0 (0.025 E-glass)
    "yarn_compaction": EffectSpec(
        "yarn_compaction",
        (Variable("compaction_k", (0.0, 200.0), lambda p: 0.0, "1/N", "transverse compliance at the crossing",
                  more=("upper",)),),
        doc="yarn diameter at the crossing shrinks with the contact load; jamming at W = 4 d_eff",
        # a baseline may have absorbed compaction by a thinner yarn: from k = 0 the fit must raise d and k together
        extra_starts=({"compaction_k": 20.0},)),
    "bending_hysteresis": EffectSpec(
        "bending_hysteresis",
        (Variable("bend_h", (0.0, 0.6), lambda p: 0.0, "-", "saturated friction moment / elastic moment",
                  more=("upper",)),),
        doc="friction inside the yarn, a Dahl element on the bending moment",
        extra_starts=({"bend_h": 0.2}, {"bend_h": 0.45})),
    "yarn_extension": EffectSpec(
        "yarn_extension",
        (Variable("ext_c", (0.0, 0.05), lambda p: 0.0, "1/N", "tensile compliance 1/(EA)", more=("upper",)),),
        doc="finite tensile stiffness: L grows with the yarn tension",
        extra_starts=({"ext_c": 0.01},)),
}
assert tuple(EFFECT_SPECS) == EFFECT_NAMES


def check_effects(names, where: str = "diagnosis.effects") -> tuple[str, ...]:
    """Validate a list of effect names (errors name the bad one)."""
    names = tuple(names)
    for n in names:
        if n not in EFFECT_SPECS:
            raise KnitsimInputError(f"{where}: unknown effect {n!r}; expected {', '.join(EFFECT_NAMES)}")
    if len(set(names)) != len(names):
        raise KnitsimInputError(f"{where} = {list(names)!r}: an effect is listed twice")
    return names


def variables_for(free: tuple[str, ...], effects: tuple[str, ...]) -> tuple[Variable, ...]:
    """The fit variables of the baseline ``free`` set with ``effects`` added."""
    drop = {r for e in effects for r in EFFECT_SPECS[e].replaces}
    out = [STRAIN_SCALE if n == STRAIN_SCALE.name else BASELINE_VARIABLES[n] for n in free if n not in drop]
    for e in effects:
        out.extend(EFFECT_SPECS[e].variables)
    return tuple(out)


def parameter_unit(name: str) -> str:
    """The unit of a fitted parameter as the diagnosis reports it (``""`` if not one of its variables): phi0
    in rad (the fit searches it as a fraction of phimax, the results give the angle)."""
    if name == "phi0":
        return "rad"
    var = BASELINE_VARIABLES.get(name) or next((v for e in EFFECT_SPECS.values() for v in e.variables
                                                if v.name == name), None)
    return var.unit if var is not None else ""


def build_params(base: CellParams, effects: tuple[str, ...], values: dict, fixed: dict | None = None) -> CellParams:
    """The cell of the model with ``effects`` on and the fitted ``values`` (validated).

    ``fixed`` holds effect parameters that are not fitted (reference load and
    rate, compaction limit, bending Dahl rate: :class:`~knitsim.cell.effects.EffectSet`
    field names).
    """
    ch = {k: float(values[k]) for k in ("B", "d", "L", "W0", "C0") if k in values}
    if "in_plane_width" in values:
        d, W0 = ch.get("d", base.d), ch.get("W0", base.W0)
        ch["in_plane_width"] = min(max(float(values["in_plane_width"]), d), 0.999 * W0 / 4.0)
    m = float(values.get("m", base.m))
    kernel_on = tuple(e for e in effects if e in EFFECT_BITS)
    eff = {k: v for k, v in (fixed or {}).items()}
    for e in kernel_on:
        for v in EFFECT_SPECS[e].variables:
            if v.name in values:
                eff[v.name] = float(values[v.name])
    if "coiling_angle_friction" in effects:
        geo = base.replace(**ch) if ch else base
        m = float(m_eq10(_beta0(geo), eff.get("coil_mu_k", geo.effects.coil_mu_k)))
    ch["m"] = m
    if "phi0" in values:
        ch["phi0"] = float(values["phi0"]) * math.atan(m)
    else:
        ch["phi0"] = max(-math.atan(m), min(math.atan(m), base.phi0))
    if "dahl_transition" in effects:
        ch["friction"] = "dahl"
        ch["dahl_sigma"] = 10.0 ** float(values["log10_dahl_sigma"])
        if m <= 0:
            ch["m"] = 1e-3  # Dahl saturates at tan(phi) = m > 0
    ch["effects"] = base.effects.with_on(*kernel_on, **eff) if (kernel_on or eff) else base.effects
    return base.replace(**ch)
