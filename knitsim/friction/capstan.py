"""Capstan test of Dusserre (2015) section 2.4: eqs 1-5, Tables 2-3.

A yarn slides over two cylinders, each wrapped by ``pi/2``; the dead weight
``F0`` hangs on the lower strand and the load cell reads ``F1`` on the upper
strand.  Each cylinder (10 mm diameter) is covered with 16 coils of the same
yarn laid parallel to its axis, so the sliding yarn crosses yarns at right
angles: the contacts are discrete crossings, not a continuous belt.

Equations (reading of the garbled extraction)
---------------------------------------------
eq 1  ``F1/F0 = exp(mu_k (theta0 + theta1))`` on ascent (crosshead up, F1 > F0);
      on descent the roles are inverted, ``F0/F1 = exp(mu_k (theta0 + theta1))``.
eq 2  Howell's law at one crossing, ``Ft = a Fn^n``.
eq 3  Exact balance of one crossing (derived below).
eq 4  eq 3 without the factor ``(1 +/- dF/(2F))^n``.
eq 5  ``mu_k = Ft/Fn = b V^p Fn^(n-1)``, i.e. ``a = b V^p``.

Derivation of eq 3.  At a crossing the yarn is deflected by ``dtheta``; the
tension is ``F`` on the incoming side and ``F + s dF`` on the outgoing side
(``s = +1`` ascent: tension grows along the yarn from ``F0``; ``s = -1``
descent: it falls).  Both strand tensions point away from the crossing at
``dtheta/2`` from the crossing's tangent plane, so the normal load is their
sum projected on the bisector and the tangential load their difference
projected on the tangent:

    Fn = (2F + s dF) sin(dtheta/2),     Ft = dF cos(dtheta/2) = a Fn^n,

hence ``dF cos(dtheta/2) = 2^n a F^n (1 + s dF/(2F))^n sin^n(dtheta/2)``,
the extracted eq 3 for ascent (``s = +1``).  This is implicit in ``dF``;
:func:`crossing_update` solves it with ``brentq`` (for ``n <= 1`` the
residual is monotone past its single root).  Eq 4 drops the bracket and is
explicit: ``dF = 2^n a F^n sin^n(dtheta/2) / cos(dtheta/2)``.

Crossings: number and pitch (derivation)
----------------------------------------
The 16 coils lie parallel to the cylinder axis and cover its circumference,
so the strands sit at the angular pitch ``2 pi / 16 = pi/8`` whatever radius
one takes: the wrapped yarn's centreline radius (``5 mm + d + d/2`` with the
strand and the sliding yarn) changes the arc length per strand, not the angle
between neighbouring strands.  The radius would matter only if the strand
count were derived from the covering (``2 pi r / width``), which the paper's
"16 coils" makes unnecessary.  Over a wrap ``pi/2`` the yarn path is a
polygon whose vertices are strands; its total deflection ``pi/2`` is shared
between the strands it touches:

* ``"aligned"``: the straight spans leave along polygon edges, so the wrap is
  4 full crossings of ``pi/8`` per cylinder (8 in all), the set-up's default;
* ``"straddle"``: a strand sits at each end of the wrap; the end strands are
  shared with the free span and take half a pitch: 3 full crossings plus two
  of ``pi/16`` per cylinder (the mean of the random phase of the two ends);
* ``n_strands = 32``: the other reading of "coils" (each coil through a
  diametral hole shows two strands on the surface), pitch ``pi/16``.

A continuous limit does not exist for ``n < 1``: with ``N`` crossings of
``Theta/N`` the sum of ``(Theta/N)^n`` grows as ``N^(1-n)``, so the crossing
count is physics, not a numerical step.  :func:`predict_f1_continuous` gives
Howell's continuous capstan ``dF/dtheta = a F^n`` for comparison only.

Table 2 versus Table 3 (measured with this module; see the report)
-------------------------------------------------------------------
No crossing count derivable from the set-up reproduces Table 2 from Table 3
to better than 0.015 in ``mu_k``: the model is low by 0.01-0.025 (16
strands: max 0.025 with eq 3, 0.022 with eq 4; 32 strands: 0.018 / 0.016).
A uniform finite-difference march of 24 steps per cylinder (3.75 deg, not a
strand count; found by scanning, so an inference about the paper's numerics,
not physics) reproduces Table 2 to 0.005.  Fitting Table 2 recovers Table
3's ``n`` and ``p`` for every eq-3 discretisation (they are set by the
ascent/descent, F0 and V contrasts); ``b`` scales with the step count
roughly as ``N^(1-n)`` and agrees with Table 3 only for 20-28 steps per
cylinder; with eq 4 and 24 steps all three parameters land within one
standard error of Table 3.  The paper's "eq 4 differs from eq 3 by less than
0.2 %" also needs fine steps: at the 16-strand crossings the difference in
F1 is 1.6 %, at 24 steps 0.3 %, at 40 steps 0.2 %.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from scipy.optimize import brentq, least_squares

from ..errors import KnitsimInputError, require_finite
from .identification import at_bound, covariance, parameter_status, rounding_sd  # noqa: F401  (at_bound: re-exported)

#: Wrap angle on each cylinder, theta0 = theta1 = pi/2 (section 2.4).
THETA_EACH = 0.5 * np.pi
#: Number of cylinders of the set-up (Fig. 2).
CYLINDERS = 2
#: Coils of yarn parallel to the axis on each cylinder (section 2.4).
COILS_PER_CYLINDER = 16

ASCENT = "ascent"
DESCENT = "descent"
DIRECTIONS = (ASCENT, DESCENT)


# --------------------------------------------------------------------------
# input checks
# --------------------------------------------------------------------------
def direction_sign(direction: str) -> int:
    """``+1`` for ``"ascent"``, ``-1`` for ``"descent"``; anything else is an error."""
    d = str(direction).strip().lower()
    if d == ASCENT:
        return 1
    if d == DESCENT:
        return -1
    raise KnitsimInputError(f"direction = {direction!r}: expected 'ascent' or 'descent'")


def _check_positive(name: str, value: float) -> float:
    v = float(value)
    if not np.isfinite(v):
        raise KnitsimInputError(f"{name} = {value!r}: not a finite number")
    if v <= 0.0:
        raise KnitsimInputError(f"{name} = {v:g}: must be positive")
    return v


def check_record(F0: float, F1: float, direction: str, where: str = "") -> int:
    """Validate one capstan record; return the direction sign.

    Raises :class:`KnitsimInputError` on a NaN or non-positive tension, on
    ``F1 < F0`` for an ascent and on ``F1 > F0`` for a descent (friction
    always opposes the sliding, eq 1).
    """
    pre = f"{where}: " if where else ""
    try:
        _check_positive("F0_N", F0)
        _check_positive("F1_N", F1)
    except KnitsimInputError as exc:
        raise KnitsimInputError(pre + str(exc)) from None
    s = _sign_where(direction, pre)
    if s > 0 and F1 < F0:
        raise KnitsimInputError(f"{pre}F1_N = {F1:g} < F0_N = {F0:g} on ascent (friction must raise F1)")
    if s < 0 and F1 > F0:
        raise KnitsimInputError(f"{pre}F1_N = {F1:g} > F0_N = {F0:g} on descent (friction must lower F1)")
    return s


def _sign_where(direction: str, pre: str) -> int:
    try:
        return direction_sign(direction)
    except KnitsimInputError as exc:
        raise KnitsimInputError(pre + str(exc)) from None


# --------------------------------------------------------------------------
# eq 1: drive-belt formula
# --------------------------------------------------------------------------
def mu_k_eq1(F0: float, F1: float, direction: str, theta0: float = THETA_EACH,
             theta1: float = THETA_EACH) -> float:
    """Kinetic friction coefficient from the strand tensions (eq 1).

    Parameters
    ----------
    F0, F1 : float
        Dead weight and load-cell tension [N].
    direction : {"ascent", "descent"}
        Crosshead direction: ascent ``F1 = F0 exp(mu (theta0+theta1))``,
        descent ``F0 = F1 exp(mu (theta0+theta1))``.
    theta0, theta1 : float
        Wrap angles on the two cylinders [rad], ``pi/2`` each in the paper.

    Returns
    -------
    float
        ``mu_k`` (dimensionless, >= 0).
    """
    s = check_record(F0, F1, direction)
    wrap = _check_positive("theta0", theta0) + _check_positive("theta1", theta1)
    return s * float(np.log(F1 / F0)) / wrap


def f1_eq1(F0: float, mu_k: float, direction: str, wrap: float = CYLINDERS * THETA_EACH) -> float:
    """Load-cell tension ``F1`` [N] from ``F0`` [N] and ``mu_k`` (eq 1 solved for F1)."""
    _check_positive("F0_N", F0)
    mu = float(mu_k)
    if not np.isfinite(mu) or mu < 0.0:
        raise KnitsimInputError(f"mu_k = {mu_k!r}: must be finite and >= 0")
    return float(F0) * float(np.exp(direction_sign(direction) * mu * wrap))


# --------------------------------------------------------------------------
# eqs 2 and 5: Howell's law
# --------------------------------------------------------------------------
def _check_finite(name: str, value: float) -> float:
    v = float(value)
    if not np.isfinite(v):
        raise KnitsimInputError(f"{name} = {value!r}: not a finite number")
    return v


#: Largest normal-load exponent of eqs 2 and 5, n = 1: Amontons (friction proportional to the normal load).  Howell's
#: n comes from the real contact area growing as Fn^n, 2/3 (elastic) to 1 (plastic); Table 3's are 0.93-0.95.  An
#: n > 1 makes mu_k = b V^p Fn^(n-1) grow without bound with the load, and Howell's capstan dF/dtheta = a F^n blow
#: up at a finite wrap (F^(1-n) = F0^(1-n) - (n-1) a theta reaches 0): no tension at all beyond it.  The upper
#: end of the fit's box (FIT_UPPER) and the check of every law given (:func:`predict_f1`, ``capstan predict``)
HOWELL_N_MAX = 1.0


def _check_howell_n(n: float) -> float:
    """Howell's index: ``Ft = a Fn^n`` with ``0 < n <= HOWELL_N_MAX = 1`` (n = 1 is Amontons; n <= 0 would make the
    friction force fall as the normal load rises; n > 1: :data:`HOWELL_N_MAX`)."""
    v = _check_positive("n", n)
    if v > HOWELL_N_MAX:
        raise KnitsimInputError(
            f"n = {v:.10g}: the normal-load exponent of eq 5 is at most {HOWELL_N_MAX:g} (Amontons: friction "
            "proportional to the normal load); n > 1 makes mu_k = b V^p Fn^(n-1) grow without bound with the load, "
            "and the capstan's tension diverge at a finite wrap (dF/dtheta = a F^n)")
    return v


def howell_a(b: float, p: float, V: float) -> float:
    """Velocity-dependent Howell coefficient ``a = b V^p`` (section 2.4, before eq 5).

    ``b`` > 0 and the sliding speed ``V`` > 0 [mm/s] (``V^p`` of a speed <= 0 is not a real number), ``p``
    finite; anything else is refused (:class:`KnitsimInputError`).
    """
    return _check_positive("b", b) * _check_positive("V_mm_s", V) ** _check_finite("p", p)


def tangential_load_eq2(Fn, b: float, p: float, n: float, V: float):
    """Tangential load at one crossing, ``Ft = a Fn^n`` with ``a = b V^p`` (eqs 2, 5) [N]; ``Fn`` >= 0 [N]."""
    return howell_a(b, p, V) * require_finite("Fn_N", Fn, ">=0") ** _check_howell_n(n)


def mu_k_eq5(b: float, p: float, n: float, V, Fn):
    """Friction coefficient ``mu_k = b V^p Fn^(n-1)`` (eq 5); ``V`` > 0 [mm/s], ``Fn`` > 0 [N]."""
    _check_positive("b", b)
    _check_finite("p", p)
    return b * require_finite("V_mm_s", V, ">0") ** p * require_finite("Fn_N", Fn, ">0") ** (
        _check_howell_n(n) - 1.0)


# --------------------------------------------------------------------------
# crossings
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class Discretisation:
    """How the wrapped arcs are split into crossings.

    Attributes
    ----------
    n_strands : int
        Strands around each cylinder's circumference (16 coils -> 16).
    layout : {"aligned", "straddle", "uniform"}
        ``aligned``: whole pitches only; ``straddle``: half pitches at both
        ends of each wrap; ``uniform``: ``steps`` equal steps over each wrap
        (a numerical march, not a strand count).
    exact : bool
        Solve eq 3 at each crossing (True) or use eq 4 (False).
    steps : int
        Steps per cylinder for ``layout = "uniform"``.
    """

    n_strands: int = COILS_PER_CYLINDER
    layout: str = "aligned"
    exact: bool = True
    steps: int = 4
    label: str = field(default="", compare=False)

    def describe(self) -> str:
        """A short label for tables and reports."""
        if self.label:
            return self.label
        upd = "eq 3 exact" if self.exact else "eq 4"
        if self.layout == "uniform":
            return f"{self.steps} uniform steps per cylinder, {upd}"
        return f"{self.n_strands} strands, {self.layout}, {upd}"


#: Default reading of the set-up: 16 strands, 4 crossings of pi/8 per cylinder, eq 3.
DEFAULT_DISCRETISATION = Discretisation()


def crossing_angles(disc: Discretisation = DEFAULT_DISCRETISATION, wrap_each: float = THETA_EACH,
                    cylinders: int = CYLINDERS) -> np.ndarray:
    """Deflection angle [rad] of each crossing met by the sliding yarn, in order.

    The strands sit at the pitch ``2 pi / n_strands`` (see the module
    docstring); the deflections of one cylinder always sum to ``wrap_each``.
    """
    if disc.layout == "uniform":
        if int(disc.steps) < 1:
            raise KnitsimInputError(f"steps = {disc.steps!r}: must be >= 1")
        one = np.full(int(disc.steps), wrap_each / int(disc.steps))
    else:
        if int(disc.n_strands) < 1:
            raise KnitsimInputError(f"n_strands = {disc.n_strands!r}: must be >= 1")
        pitch = 2.0 * np.pi / int(disc.n_strands)
        whole = int(np.floor(wrap_each / pitch + 1e-9))
        rest = wrap_each - whole * pitch
        if disc.layout == "aligned":
            one = np.full(whole, pitch)
            if rest > 1e-12:
                one = np.append(one, rest)
        elif disc.layout == "straddle":
            # one pitch is split between the two end strands of the wrap
            inner = np.full(max(whole - 1, 0), pitch)
            end = 0.5 * (wrap_each - inner.sum())
            one = np.concatenate([[end], inner, [end]])
        else:
            raise KnitsimInputError(f"layout = {disc.layout!r}: expected 'aligned', 'straddle' or 'uniform'")
    return np.tile(one, cylinders)


class FrictionLawError(KnitsimInputError):
    """A friction law that gives no physical tension after a crossing: on ascent the tension has no
    finite value (``n = 1`` with ``a tan(dtheta/2) >= 1``), on descent it would fall to zero or below
    (the crossing holds more than the tension: the yarn stops).  The fit treats such a law as outside
    its search, not as a user mistake."""


def crossing_update(F: float, dtheta: float, a: float, n: float, sign: int, exact: bool = True) -> float:
    """Tension after one crossing of deflection ``dtheta`` (eq 3 exact or eq 4).

    Parameters
    ----------
    F : float
        Tension before the crossing [N] (the side nearer ``F0``), > 0.
    dtheta : float
        Deflection of the yarn at the crossing [rad].
    a, n : float
        Howell coefficient and exponent (eq 2).
    sign : int
        ``+1`` ascent (tension grows), ``-1`` descent (tension falls).
    exact : bool
        Solve ``dF cos(h) = a ((2F + sign dF) sin h)^n``, ``h = dtheta/2``
        (eq 3); else ``dF = 2^n a F^n sin^n(h)/cos(h)`` (eq 4).

    Returns
    -------
    float
        Tension after the crossing [N].

    Raises
    ------
    FrictionLawError
        On descent when the law would take the tension to 0 or below (the root of eq 3 lies
        beyond ``dF = F``: with ``n = 1`` that is ``a tan(h) >= 1``; for ``n < 1`` it happens at low
        tension first, ``F^(1-n) <= a tan(h) sin^(n-1)(h)``); on ascent when eq 3 has no finite root.
    """
    if not (np.isfinite(F) and F > 0.0):
        raise FrictionLawError(f"friction law (a={a:g}, n={n:g}) gives a tension F = {F:g} N inside the wrap")
    h = 0.5 * dtheta
    c, sn = np.cos(h), np.sin(h)
    if not exact:
        dF = (2.0 ** n) * a * F ** n * sn ** n / c
        if not np.isfinite(dF):
            raise FrictionLawError(f"friction law (a={a:g}, n={n:g}) has no finite tension after a crossing")
        if sign < 0 and dF >= F:
            raise FrictionLawError(f"friction law (a={a:g}, n={n:g}) stops the yarn at F = {F:g} N on descent")
        return F + sign * dF

    def residual(dF: float) -> float:
        return dF * c - a * ((2.0 * F + sign * dF) * sn) ** n

    if sign > 0:
        hi = max(F, 1e-12)
        while residual(hi) < 0.0:
            hi *= 2.0
            if hi > 1e12 * max(F, 1.0):
                raise FrictionLawError(f"friction law (a={a:g}, n={n:g}) has no finite tension after a crossing")
        dF = brentq(residual, 0.0, hi, xtol=1e-15 * max(F, 1.0), rtol=1e-15)
    else:
        # residual is strictly increasing on [0, 2F] (slope c + a n sn ((2F - dF) sn)^(n-1) > 0) and
        # residual(2F) = 2F c > 0; its root lies below F (a tension left after the crossing) only where
        # residual(F) > 0.  Beyond F the tension would turn negative (then NaN for a fractional n).
        if not residual(F) > 0.0:
            raise FrictionLawError(f"friction law (a={a:g}, n={n:g}) stops the yarn at F = {F:g} N on descent "
                                   "(one crossing holds more than the tension)")
        dF = brentq(residual, 0.0, F, xtol=1e-15 * max(F, 1.0), rtol=1e-15)
    return F + sign * dF


def predict_f1(F0: float, V: float, direction: str, b: float, p: float, n: float,
               disc: Discretisation = DEFAULT_DISCRETISATION) -> float:
    """Load-cell tension ``F1`` [N] predicted by the crossing-by-crossing law (eqs 2-5).

    The march starts at the dead weight ``F0`` and crosses every strand in
    order: tension rises on ascent and falls on descent.
    """
    s = direction_sign(direction)
    F0 = _check_positive("F0_N", F0)
    V = _check_positive("V_mm_s", V)
    a = howell_a(_check_positive("b", b), float(p), V)
    n = _check_howell_n(n)
    F = F0
    for dth in crossing_angles(disc):
        F = crossing_update(F, dth, a, n, s, disc.exact)
    return F


def predict_f1_continuous(F0: float, V: float, direction: str, b: float, p: float, n: float,
                          wrap: float = CYLINDERS * THETA_EACH) -> float:
    """Howell's continuous capstan ``dF/dtheta = +/- a F^n`` (comparison only).

    Closed form ``F1^(1-n) = F0^(1-n) +/- (1-n) a wrap``.
    """
    s = direction_sign(direction)
    F0 = _check_positive("F0_N", F0)
    n = _check_howell_n(n)
    a = howell_a(b, p, V)
    if abs(1.0 - n) < 1e-12:
        return F0 * np.exp(s * a * wrap)
    base = F0 ** (1.0 - n) + s * (1.0 - n) * a * wrap
    if base <= 0.0:
        raise KnitsimInputError(f"friction law (a={a:g}, n={n:g}) stops the yarn on descent")
    return float(base ** (1.0 / (1.0 - n)))


def predict_mu_k(F0: float, V: float, direction: str, b: float, p: float, n: float,
                 disc: Discretisation = DEFAULT_DISCRETISATION) -> float:
    """``mu_k`` that eq 1 assigns to the predicted ``F1`` (what Table 2 reports)."""
    F1 = predict_f1(F0, V, direction, b, p, n, disc)
    return mu_k_eq1(F0, F1, direction)


# --------------------------------------------------------------------------
# paper data
# --------------------------------------------------------------------------
FIBRES = ("e_glass", "basalt")


def table3_params(fibre: str) -> tuple[float, float, float]:
    """``(b, p, n)`` of Table 3 for ``"e_glass"`` or ``"basalt"``."""
    from ..data import dusserre2015

    law = dusserre2015()["friction_law"]
    if fibre not in law:
        raise KnitsimInputError(f"fibre = {fibre!r}: expected one of {', '.join(FIBRES)}")
    return float(law[fibre]["b"]), float(law[fibre]["p"]), float(law[fibre]["n"])


def table2_rows(fibre: str | None = None) -> list[dict]:
    """Rows of Table 2 as dicts ``{fibre, F0_N, direction, V_mm_s, mu_k}``."""
    from ..data import dusserre2015

    t = dusserre2015()["capstan"]["table2"]
    rows = [dict(zip(t["columns"], r)) for r in t["rows"]]
    if fibre is not None:
        if fibre not in FIBRES:
            raise KnitsimInputError(f"fibre = {fibre!r}: expected one of {', '.join(FIBRES)}")
        rows = [r for r in rows if r["fibre"] == fibre]
    return rows


def table2_records(fibre: str) -> dict[str, np.ndarray]:
    """Table 2 of one fibre as capstan records: ``F1 = F0 exp(+/- mu_k pi)`` (eq 1)."""
    rows = table2_rows(fibre)
    F0 = np.array([r["F0_N"] for r in rows], dtype=float)
    d = np.array([r["direction"] for r in rows], dtype=object)
    V = np.array([r["V_mm_s"] for r in rows], dtype=float)
    F1 = np.array([f1_eq1(r["F0_N"], r["mu_k"], r["direction"]) for r in rows])
    return {"F0_N": F0, "F1_N": F1, "V_mm_s": V, "direction": d}


# --------------------------------------------------------------------------
# identification (Table 3)
# --------------------------------------------------------------------------
@dataclass
class FitResult:
    """Result of :func:`fit_friction_law` (SciPy-style: ``success``, ``message``).

    ``params`` is ``(b, p, n)``; ``stderr`` their standard errors (0 for a
    parameter held fixed); ``corr`` the 3x3 correlation matrix (NaN rows for
    fixed parameters); ``rms_N`` the residual RMS of F1 [N]; ``dof`` the
    residual degrees of freedom; ``param_status`` per parameter
    ``"identified"``, ``"fixed"``, ``"at_lower_bound"``, ``"at_upper_bound"``
    or ``"not_identified"``; ``warnings`` what makes the result less than
    believable (shown to the user).
    """

    params: tuple[float, float, float]
    stderr: tuple[float, float, float]
    corr: np.ndarray
    rms_N: float
    dof: int
    success: bool
    message: str
    discretisation: str
    residuals_N: np.ndarray
    #: per parameter: ``"identified"``, ``"fixed"``, ``"at_lower_bound"``,
    #: ``"at_upper_bound"`` or ``"not_identified"`` (see :func:`parameter_status`); n may be
    #: ``"amontons_limit"``: at n = 1, the law's physical limit, usable (not a flag)
    param_status: dict = field(default_factory=dict)
    #: sentences for the user: why a parameter is not identified, optimiser failure
    warnings: list = field(default_factory=list)
    #: the warnings that make the law not usable (a parameter not identified, the optimiser's failure,
    #: residuals beyond the test's scatter): ``usable`` is False and ``knitsim capstan fit`` exits 1
    flags: list = field(default_factory=list)
    #: :func:`goodness_of_fit` without its flags: the scatter scale, the test and its P value
    goodness_of_fit: dict = field(default_factory=dict)

    @property
    def usable(self) -> bool:
        """True when nothing flags the law (see ``flags``)."""
        return not self.flags

    @property
    def identified(self) -> bool:
        """True when every free parameter is identified (none at a bound, finite non-zero stderr)."""
        return all(v in ("identified", "fixed") for v in self.param_status.values())

    def as_dict(self) -> dict:
        """The fit as a JSON-ready dict (``knitsim capstan fit --json``): b, p, n with their ``*_stderr``
        and ``*_status``, ``corr``, ``rms_N`` [N], ``dof`` and the optimiser's outcome."""
        b, p, n = self.params
        sb, sp, sn = self.stderr
        st = {k: self.param_status.get(k, "identified") for k in PARAM_NAMES}
        return {"b": b, "p": p, "n": n, "b_stderr": sb, "p_stderr": sp, "n_stderr": sn,
                "b_status": st["b"], "p_status": st["p"], "n_status": st["n"],
                "corr": self.corr, "rms_N": self.rms_N, "dof": self.dof, "success": self.success,
                "message": self.message, "discretisation": self.discretisation,
                "warnings": list(self.warnings), "usable": self.usable, "flags": list(self.flags),
                "goodness_of_fit": dict(self.goodness_of_fit)}


#: Names of the parameters of eq 5, in the order of ``FitResult.params``.
PARAM_NAMES = ("b", "p", "n")
#: Search box of :func:`fit_friction_law` for ``(b, p, n)``: ``b > 0`` (a
#: friction coefficient), ``|p| <= 1`` (a weak velocity dependence), ``n`` in
#: ``[0.3, 1]`` (Howell's exponent for fibres; ``n = 1`` is Amontons' law).
FIT_LOWER = (1e-6, -1.0, 0.3)
FIT_UPPER = (10.0, 1.0, HOWELL_N_MAX)
#: n at its upper bound 1 (the Amontons limit) is a usable law when the data pull beyond it by at most this many
#: standard errors of n (:func:`fit_friction_law`)
AMONTONS_PULL_SE = 2.0
#: ... and bound from below, ``n >= 1 - z se`` (one-sided 95 %), inside the box (not below FIT_LOWER's n)
AMONTONS_ONE_SIDED_Z = 1.645


def decimal_resolution(cell: str) -> float:
    """Half a unit of the last digit written in a numeric cell (``"6.31"`` -> 0.005).

    Decimal commas and exponents are understood (``"0,125"``, ``"1.2e-3"``);
    a cell that is not a plain decimal number gives 0.
    """
    from decimal import Decimal, InvalidOperation

    c = str(cell).strip().replace("\u2212", "-")
    if "," in c and "." not in c:
        c = c.replace(",", ".")
    try:
        exp = Decimal(c).as_tuple().exponent
    except (InvalidOperation, ValueError):
        return 0.0
    if not isinstance(exp, int):
        return 0.0
    return 0.5 * 10.0 ** exp


#: Two values within this share of their size are one value, equal up to float rounding (a dead weight converted
#: from cN as 631 * 0.01 is 6.3100000000000005 beside a typed 6.31); a test's written digits are far coarser
FLOAT_EQUAL_RTOL = 1e-9


def one_value_each(x) -> np.ndarray:
    """``x`` with values equal within :data:`FLOAT_EQUAL_RTOL` replaced by the smallest of them: what tells test
    conditions apart (F0_N, V_mm_s).  A probe's records at 6.31 and 6.3100000000000005 N, one direction, passed as two
    normal loads and gave n = 1 +/- 0.53, exit 0, where the same records written 6.31 are refused."""
    x = np.asarray(x, dtype=float)
    out = x.copy()
    order = np.argsort(x, kind="stable")
    first = None
    for i in order:
        if first is None or abs(x[i] - first) > FLOAT_EQUAL_RTOL * max(abs(x[i]), abs(first)):
            first = x[i]
        out[i] = first
    return out


def check_friction_present(F0, F1, resolution_N=None, source: str = "records") -> None:
    """Refuse records that carry no friction: ``F1 = F0`` on every row.

    ``F1`` equals ``F0`` within ``resolution_N`` (scalar or per row; default:
    1e-9 of the tension, i.e. equal up to float rounding) on every record
    means the load cell saw the dead weight itself: eq 1 gives ``mu_k = 0``
    and no value of ``b`` (nor ``p``, ``n``) is identified.
    """
    F0 = np.asarray(F0, dtype=float)
    F1 = np.asarray(F1, dtype=float)
    tol = FLOAT_EQUAL_RTOL * np.maximum(np.abs(F0), np.abs(F1))
    if resolution_N is not None:
        tol = np.maximum(tol, np.broadcast_to(np.asarray(resolution_N, dtype=float), F0.shape))
    if F0.size and np.all(np.abs(F1 - F0) <= tol):
        raise KnitsimInputError(
            f"{source}: F1_N = F0_N on every row (within the data's resolution): the records carry no "
            "friction (eq 1 gives mu_k = 0), so b, p and n cannot be identified; check that F1_N is the "
            "load-cell reading, not the dead weight")


def validate_records(F0: Sequence[float], F1: Sequence[float], V: Sequence[float],
                     direction: Sequence[str], source: str = "records", rows=None) -> np.ndarray:
    """Check capstan records row by row; return the direction signs.

    Rows are numbered as in a CSV file with a header (first data row = 2),
    or as given by ``rows`` (the spreadsheet row of each record).
    """
    F0, F1, V = (np.asarray(x, dtype=float) for x in (F0, F1, V))
    direction = list(direction)
    if not (len(F0) == len(F1) == len(V) == len(direction)):
        raise KnitsimInputError(f"{source}: F0_N, F1_N, V_mm_s and direction have different lengths")
    if rows is None or len(rows) != len(F0):
        rows = np.arange(len(F0)) + 2
    signs = np.empty(len(F0), dtype=int)
    for i in range(len(F0)):
        where = f"{source}: row {int(rows[i])}"
        signs[i] = check_record(F0[i], F1[i], direction[i], where)
        if not np.isfinite(V[i]) or V[i] <= 0.0:
            raise KnitsimInputError(f"{where}: V_mm_s = {V[i]:g}: must be positive")
    return signs


def fit_friction_law(F0, F1, V, direction, disc: Discretisation = DEFAULT_DISCRETISATION,
                     fix_p: float | None = None, x0: Sequence[float] = (0.15, 0.01, 0.93),
                     source: str = "records", resolution_N=None, rows=None,
                     reading_resolution_N=None) -> FitResult:
    """Identify ``(b, p, n)`` of eq 5 from capstan records (Table 3).

    Least squares on the load-cell tension ``F1`` (the paper fitted its raw F1
    records) with :func:`scipy.optimize.least_squares` inside the box
    :data:`FIT_LOWER` - :data:`FIT_UPPER`.  Standard errors are
    ``sqrt(diag(s^2 (J^T J)^-1))`` with ``s^2 = SSR / (m - k)`` (:func:`~knitsim.friction.identification.covariance`,
    shared with the Dahl fit: infinite where ``J`` is singular), or, from :data:`HC_MIN_DOF` residual
    degrees of freedom on, the sandwich (HC3) ones where larger: they hold when the noise grows
    with the tension, as a load cell's does.

    Records with ``F1 = F0`` on every row (within ``resolution_N``) carry no
    friction and are refused before fitting.  A parameter that ends at a bound
    of the box, or whose standard error is not finite (or 0 with a non-zero
    residual), is reported as not identified in ``param_status`` and ``warnings``.

    Parameters
    ----------
    F0, F1, V : array_like
        Tensions [N] and sliding velocity [mm/s] of each record.
    direction : sequence of str
        ``"ascent"`` or ``"descent"`` per record.
    disc : Discretisation
        Crossing layout and update (eq 3 or eq 4).
    fix_p : float, optional
        Hold ``p`` at this value (the paper's basalt has ``p = 0``).
    x0 : (b, p, n)
        Starting point.
    source : str
        Name of the data (file) used in error messages.
    resolution_N : float or array_like, optional
        Resolution of the tensions (e.g. half the last digit written); used
        only to recognise records without friction.
    rows : array_like of int, optional
        Spreadsheet row of each record, for error messages.
    reading_resolution_N : float or array_like, optional
        Half the last digit written of each ``F1`` [N] (``"10.45"``: 0.005): the readings' rounding, a variance
        ``h^2 / 3`` each (a uniform error in ``[-h, h]``).  Where ``s^2`` is below its mean (residuals below what
        the written digits allow), the covariance is the rounding's, ``A J^T diag(h^2 / 3) J A``, ``A = (J^T J)^-1``:
        the standard errors the written digits allow, not ~0.
    """
    if fix_p is not None:
        fp = float(fix_p)
        if not np.isfinite(fp) or not FIT_LOWER[1] <= fp <= FIT_UPPER[1]:
            raise KnitsimInputError(f"fix_p = {fix_p!r}: must be a finite number in [{FIT_LOWER[1]:g}, "
                                    f"{FIT_UPPER[1]:g}] (the fit's box for the velocity exponent p)")
    signs = validate_records(F0, F1, V, direction, source, rows)
    F0, F1, V = (np.asarray(x, dtype=float) for x in (F0, F1, V))
    check_friction_present(F0, F1, resolution_N, source)
    dirs = [DIRECTIONS[0] if s > 0 else DIRECTIONS[1] for s in signs]
    free = [0, 2] if fix_p is not None else [0, 1, 2]
    m, k = len(F0), len(free)
    if m <= k:
        raise KnitsimInputError(f"{source}: {m} record(s) cannot identify {k} parameters (need more than {k})")
    # conditions told apart beyond float rounding (one_value_each): 6.31 and 6.3100000000000005 N are one dead weight
    F0c, Vc = one_value_each(F0), one_value_each(V)
    if fix_p is None and len(np.unique(Vc)) < 2:
        raise KnitsimInputError(f"{source}: all records have V_mm_s = {V[0]:g}; the velocity exponent p needs two "
                                "velocities: hold it fixed (knitsim capstan fit --fix-p P; fix_p=P in Python)")
    # records repeating one test condition are one equation: the residuals' Jacobian has as many distinct rows as
    # conditions, and its pseudo-inverse gave finite standard errors to parameters the data do not set (a probe's
    # five repeats of one condition, p fixed: b and n "+- 0.00045" and "+- 8.7e-05", corr(b, n) = 1.000, exit 0)
    loads = {(f, s) for f, s in zip(F0c.tolist(), signs)}
    if len(loads) < 2:
        raise KnitsimInputError(f"{source}: all records have F0_N = {F0[0]:g} on {dirs[0]}; the load exponent n "
                                "needs two normal loads at the crossings: add records at a second dead weight F0, or "
                                "of the other direction")
    conditions = len({(f, v, s) for f, v, s in zip(F0c.tolist(), Vc.tolist(), signs)})
    if conditions < k:
        raise KnitsimInputError(f"{source}: the records hold {conditions} test conditions (F0_N, V_mm_s, direction; "
                                f"repeats of one are one), which cannot identify {k} parameters: add conditions"
                                + (", or hold p fixed (knitsim capstan fit --fix-p P; fix_p=P in Python)"
                                   if fix_p is None else ""))

    def full(x):
        return (x[0], float(fix_p), x[1]) if fix_p is not None else tuple(x)

    def residuals(x):
        # a law of the box whose tension stops (descent) or diverges (ascent) at a crossing is outside the
        # laws that make these records: infinite residuals, which least_squares (trf) answers by shrinking
        # its step instead of accepting the point
        b, p, n = full(x)
        try:
            return np.array([predict_f1(F0[i], V[i], dirs[i], b, p, n, disc) for i in range(m)]) - F1
        except FrictionLawError:
            return np.full(m, np.inf)

    lo = np.array(FIT_LOWER)[free]
    hi = np.array(FIT_UPPER)[free]
    start = np.array([x0[i] for i in free], dtype=float)
    # a start whose law stops the yarn on a descent record (large friction at a high speed, e.g. a fixed
    # p = 1 at V = 100 mm/s): halve b until every record has a tension
    while not np.all(np.isfinite(residuals(start))):
        if start[0] <= lo[0]:
            raise KnitsimInputError(
                f"{source}: cannot be fitted: even b = {lo[0]:g} gives no physical tension on every record "
                f"(p = {full(start)[1]:g}, n = {start[-1]:g}; speeds up to V_mm_s = {V.max():g})")
        start[0] = max(0.5 * start[0], lo[0])

    def jacobian(x):
        # forward differences as scipy's "2-point" (step sqrt(eps) max(1, |x|), reversed at a bound of the
        # box), reversed also where the forward point's law has no tension (a fit against that limit)
        f0 = residuals(x)
        J = np.empty((m, len(x)))
        for j in range(len(x)):
            h = np.sqrt(np.finfo(float).eps) * (1.0 if x[j] >= 0 else -1.0) * max(1.0, abs(x[j]))
            if not lo[j] <= x[j] + h <= hi[j]:
                h = -h
            for step in (h, -h):
                xh = x.copy()
                xh[j] = x[j] + step
                fh = residuals(xh)
                if np.all(np.isfinite(fh)):
                    J[:, j] = (fh - f0) / (xh[j] - x[j])
                    break
            else:
                raise FrictionLawError("no finite-difference step")
        return J

    try:
        res = least_squares(residuals, start, jac=jacobian, bounds=(lo, hi), x_scale="jac", xtol=1e-14,
                            ftol=1e-14, gtol=1e-14)
    except FrictionLawError:
        res = None
    if res is None or not np.all(np.isfinite(res.fun)) or not np.all(np.isfinite(res.jac)):
        raise KnitsimInputError(
            f"{source}: cannot be fitted: the best law the search reached sits where eq 5's law stops the yarn "
            "on a descent record or loses a finite tension on an ascent one (friction ratios F1/F0 beyond "
            "what a law of the fit's box (b <= 10, |p| <= 1, 0.3 <= n <= 1) makes over the crossings)")
    dof = m - k
    s2 = 2.0 * res.cost / dof
    # the readings' rounding: F1 written to 0.01 N is known to +-0.005 N at best, a variance h^2 / 3 per reading
    # that no fit removes.  Residuals below it (records that fit to the last digit, e.g. made by a model and
    # rounded) set s^2 below what the written digits allow: a probe's 4 rounded records, 1 dof, gave b, p and n
    # "+/- 1e-16", identified
    q = np.zeros(m)
    if reading_resolution_N is not None:
        h = np.broadcast_to(np.asarray(reading_resolution_N, dtype=float), F1.shape)
        q = rounding_sd(2.0 * np.where(np.isfinite(h), h, 0.0)) ** 2    # (h: half a digit)
    rounding_floor = s2 < float(np.mean(q))
    J = res.jac
    cov = covariance(J, s2)                       # infinite where J is singular: the data do not set the parameters
    if rounding_floor:
        # the rounding's own covariance, each reading's h_i^2 / 3 carried through the least-squares estimate:
        # (J^T J)^-1 J^T diag(q) J (J^T J)^-1 (one q for every reading: q (J^T J)^-1)
        A = covariance(J, 1.0)
        cov = A @ (J.T * q) @ J @ A if np.all(np.isfinite(A)) else A
    # the sandwich (HC3) covariance holds where the noise is not one sd for every record: a load cell's
    # scatter grows with its reading, and the paper's records span 6.31 to 12.62 N.  With 0.5 % relative
    # noise the pooled s^2 gave p's standard error at half its spread over 60 noise draws, and a 5 SE
    # "velocity dependence" of data without any (a blind probe).  Each parameter keeps the larger of the
    # two: with one sd for every record they agree (the HC3 one within its own scatter).  Below
    # HC_MIN_DOF residual degrees of freedom the sandwich is itself too scattered to use (Table 2's 8
    # records of e-glass: 5), and the pooled one stands
    cov_hc3 = _sandwich_hc3(J, res.fun)
    se_pooled = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    se_robust = np.sqrt(np.clip(np.diag(cov_hc3), 0.0, None))
    if dof >= HC_MIN_DOF and np.all(np.isfinite(se_robust)) and np.any(se_robust > se_pooled):
        scale_se = np.maximum(se_pooled, se_robust) / np.where(se_pooled > 0, se_pooled, 1.0)
        cov = cov * np.outer(scale_se, scale_se)
    se_free = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    se = np.zeros(3)
    se[free] = se_free
    corr = np.full((3, 3), np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        c = cov / np.outer(se_free, se_free)
    for a_i, i in enumerate(free):
        for a_j, j in enumerate(free):
            corr[i, j] = c[a_i, a_j]
    params = tuple(float(v) for v in full(res.x))
    status, warns = parameter_status(PARAM_NAMES, params, se, FIT_LOWER, FIT_UPPER,
                                     fixed=("p",) if fix_p is not None else (),
                                     exact_fit=res.cost == 0.0 and not np.any(q > 0.0),
                                     positive=("b",))
    # what makes the law not usable: a parameter the data do not set, the optimiser's failure, residuals
    # beyond the test's scatter (the zero-residual note is a caveat on the standard errors, not a flag)
    # (parameter_status gives one sentence per parameter not identified, in order, before the note)
    flags = list(warns[:sum(status.get(nm) not in ("identified", "fixed") for nm in PARAM_NAMES)])
    # n = 1 is not an arbitrary end of the box but the law's physical limit (eq 5 with n = 1: friction
    # proportional to the normal load, Amontons; n <= 1): data that sit there, not pulling beyond it by more
    # than AMONTONS_PULL_SE standard errors (the Gauss-Newton step from the bound), are an Amontons yarn, a
    # usable law bounded from one side (a blind probe's exact n = 1 yarn was called "NOT A FRICTION LAW YOU
    # CAN USE"); data that need n > 1 (friction growing faster than the load) stay flagged at the bound
    pull = float(-(np.linalg.pinv(J) @ res.fun)[-1]) if free[-1] == 2 else math.inf
    # (and its one-sided bound inside the box: a bound below every n the fit searches bounds nothing; a probe's dead
    # weights 6.31 and 6.3101 N, one direction, gave "n >= 0.13", usable, and speeds proportional to the dead weight
    # "n >= -504")
    if (status.get("n") == "at_upper_bound" and res.success and np.isfinite(se[2]) and se[2] > 0
            and 1.0 - AMONTONS_ONE_SIDED_Z * float(se[2]) >= FIT_LOWER[2]
            and pull <= AMONTONS_PULL_SE * float(se[2])):
        text = next(w for w in warns if w.startswith("n = "))
        flags.remove(text)
        status["n"] = "amontons_limit"
        warns[warns.index(text)] = (
            f"n = 1, the Amontons limit (friction proportional to the normal load; the law's n <= 1): the data sit "
            f"at it, n >= {1.0 - AMONTONS_ONE_SIDED_Z * float(se[2]):.4g} (one-sided 95 %, from its standard error "
            f"{float(se[2]):.2g})")
    if not res.success:
        warns.append(f"the optimiser did not converge: {res.message}")
        flags.append(warns[-1])
    if rounding_floor:
        warns.append(f"the residuals (RMS {np.sqrt(2.0 * res.cost / m):.3g} N) are below the rounding of the F1 "
                     f"readings as written (RMS {math.sqrt(float(np.mean(q))):.2g} N, half a last digit over sqrt(3) "
                     "each): the standard errors are those of that rounding, the least the written digits allow")
    gof = goodness_of_fit(F0, F1, V, signs, res.fun, dof)
    for w in gof.pop("flags"):
        warns.append(w)
        flags.append(w)
    warns.extend(gof.pop("notes"))
    return FitResult(params=params, stderr=tuple(float(v) for v in se),
                     corr=corr, rms_N=float(np.sqrt(2.0 * res.cost / m)), dof=dof, success=bool(res.success),
                     message=str(res.message), discretisation=disc.describe(), residuals_N=res.fun,
                     param_status=status, warnings=warns, flags=flags, goodness_of_fit=gof)


#: Significance below which the residuals (or the repeated rows) are flagged as beyond the capstan
#: test's scatter: a chi2 (or F) this improbable under that scatter happens once in a thousand fits.
GOF_ALPHA = 1e-3
#: The tension at which the paper states its largest sd of F1 (``capstan.max_std_F1_N`` = 0.13 N at
#: 10 mm/s, F0 = 6.31 N): mean F1 = 10.7 N (e-glass) and 9.94 N (basalt).  The lower of the two gives
#: the larger relative sd (1.3 %), i.e. the more lenient scale.
PAPER_SD_AT_F1_N = 9.94


def paper_scatter_N(F1) -> np.ndarray:
    """Measurement scatter (sd) of each F1 [N] as the paper states it: its largest sd of F1, 0.13 N
    (section 2.4; ``capstan.max_std_F1_N``), growing in proportion to F1 above the tension where it was
    stated (a load cell's scatter is a share of its reading), never below 0.13 N."""
    from ..data import dusserre2015

    sd = float(dusserre2015()["capstan"]["max_std_F1_N"])
    return sd * np.maximum(1.0, np.asarray(F1, dtype=float) / PAPER_SD_AT_F1_N)


def goodness_of_fit(F0, F1, V, signs, residuals, dof: int) -> dict:
    """Whether the fit's residuals are within the capstan test's scatter; the sentences that flag them.

    Scale: the paper's sd of F1 (:func:`paper_scatter_N`, the largest it states, so lenient).  Rows
    repeated at one condition (same ``F0_N``, ``V_mm_s``, direction) give the file's own scatter (pooled
    sd, "pure error"); where it exceeds the paper's sd significantly it becomes the scale, and the
    repeats themselves are flagged (rows that should agree within the test's scatter do not: two yarns
    or set-ups in one file?).  Tests (significance :data:`GOF_ALPHA`): with the paper's scale,
    ``chi2 = sum (r_i / sd_i)^2`` on ``dof`` degrees of freedom; with the repeats' scale, the lack-of-fit
    F test (the residual of the repeated means against the pure error; Draper & Smith, Applied
    Regression Analysis, section 2.1), which needs ``dof`` above the repeats' degrees of freedom.

    Returns a dict: ``scale`` ("paper_sd" or "repeats"), ``scale_sd_N`` (the typical sd used: the
    paper's at the median F1, or the repeats' pooled sd), ``statistic``, ``test`` ("chi2" or "F"),
    ``p_value``, ``repeat_sd_N`` and ``repeat_dof`` (None without repeats), ``flags`` (sentences).
    """
    from scipy import stats

    F0, F1, V, r = (np.asarray(x, dtype=float) for x in (F0, F1, V, residuals))
    F0, V = one_value_each(F0), one_value_each(V)            # one condition, whatever the float rounding
    sd = paper_scatter_N(F1)
    out = {"scale": "paper_sd", "scale_sd_N": float(np.median(sd)), "test": "chi2", "statistic": None,
           "p_value": None, "repeat_sd_N": None, "repeat_dof": None, "flags": [], "notes": []}
    paper_txt = ("the paper's largest sd of F1, 0.13 N (Dusserre 2015 section 2.4), growing with F1 above "
                 f"{PAPER_SD_AT_F1_N:g} N")
    groups: dict = {}
    for i, key in enumerate(zip(F0, V, np.asarray(signs))):
        groups.setdefault(key, []).append(i)
    rep = [np.array(ix) for ix in groups.values() if len(ix) > 1]
    ss_pe = sum(float(np.sum((F1[ix] - F1[ix].mean()) ** 2)) for ix in rep)
    df_pe = sum(len(ix) - 1 for ix in rep)
    use_repeats = False
    if df_pe > 0:
        s_pe = float(np.sqrt(ss_pe / df_pe))
        out["repeat_sd_N"], out["repeat_dof"] = s_pe, int(df_pe)
        chi_pe = sum(float(np.sum(((F1[ix] - F1[ix].mean()) / sd[ix]) ** 2)) for ix in rep)
        p_pe = float(stats.chi2.sf(chi_pe, df_pe))
        if p_pe < GOF_ALPHA:
            use_repeats = True
            out["flags"].append(
                f"rows repeated at the same F0_N, V_mm_s and direction scatter with sd {s_pe:.3g} N ({df_pe} dof), "
                f"far above the capstan test's repeatability ({paper_txt}; chi2 = {chi_pe:.3g}, P = {p_pe:.1g} < "
                f"{GOF_ALPHA:g}): are they one yarn on one set-up?")
    # the lack-of-fit F test against the file's own repeats, wherever they are enough (a re-probe: repeats
    # scattering *less* than the paper's sd left a two-yarn file's 11 x misfit unflagged, n 12 SE off)
    df_lof = dof - df_pe
    lof_flagged = False
    if df_pe >= 2 and df_lof >= 1 and ss_pe > 0.0:
        ss_lof = max(float(np.sum(r ** 2)) - ss_pe, 0.0)
        F = (ss_lof / df_lof) / (ss_pe / df_pe)
        p = float(stats.f.sf(F, df_lof, df_pe))
        out.update(lack_of_fit_F=F, lack_of_fit_p=p)
        if use_repeats:
            out.update(statistic=F, p_value=p)
        if p < GOF_ALPHA:
            lof_flagged = True
            out["flags"].append(
                f"the residuals (RMS {np.sqrt(np.mean(r ** 2)):.3g} N) are far above the scatter of the file's "
                f"repeated rows (sd {out['repeat_sd_N']:.3g} N; lack-of-fit F = {F:.3g} on ({df_lof}, {df_pe}) "
                f"dof, P = {p:.1g} < {GOF_ALPHA:g}): eq 5 with one (b, p, n) does not describe these records (two "
                "yarns in one file? a parameter held at its bound or fixed?)")
    if use_repeats:
        out.update(scale="repeats", scale_sd_N=out["repeat_sd_N"], test="F")
        return out
    floor = float(paper_scatter_N(0.0))          # the paper's own sd of F1: tensions below it cannot be judged
    if float(np.median(F1)) < floor:
        # the paper's scale cannot judge tensions below its own scatter; and a capstan test on yarn pulls
        # newtons (Dusserre: F0 6.31 and 12.6 N): kN read as N gives exactly this (a blind probe's file fitted
        # silently, chi2 1e-6)
        out["notes"].append(
            f"the tensions are below the capstan test's scatter (median F1 {float(np.median(F1)):.3g} N against "
            f"its sd of {floor:.2g} N; Dusserre 2015 pulls F0 = 6.31 and 12.6 N): the fit cannot be judged against "
            f"that scatter; if the columns hold kN (or another unit), give newtons under the _N headers")
    if dof >= 1:
        chi = float(np.sum((r / sd) ** 2))
        p = float(stats.chi2.sf(chi, dof))
        out.update(statistic=chi, p_value=p)
        low = float(stats.chi2.cdf(chi, dof))
        if low < GOF_ALPHA and float(np.median(F1)) >= floor:
            out["notes"].append(
                f"the residuals (RMS {np.sqrt(np.mean(r ** 2)):.3g} N) are far below the capstan test's scatter "
                f"(chi2 = {chi:.3g} on {dof} dof, P(chi2 this small) = {low:.1g}): a more repeatable test than "
                "the paper's, or records that are not raw measurements (averaged, rounded, or made by a model); "
                "the standard errors rest on the residuals (or the readings' rounding, where larger), not on that scatter")
        if p < GOF_ALPHA and not lof_flagged:
            out["flags"].append(
                f"the residuals (RMS {np.sqrt(np.mean(r ** 2)):.3g} N) are far above the capstan test's scatter "
                f"({paper_txt}; chi2 = {chi:.3g} on {dof} dof, {np.sqrt(chi / dof):.2g} x that sd, P = {p:.1g} < "
                f"{GOF_ALPHA:g}): eq 5 with one (b, p, n) does not describe these records (two yarns in one file? "
                "a parameter held at its bound or fixed?)")
    return out


#: residual degrees of freedom from which the sandwich (HC3) standard errors are used (fit_friction_law)
HC_MIN_DOF = 10


def _sandwich_hc3(J: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Heteroscedasticity-consistent covariance of least-squares parameters (HC3, MacKinnon and White
    1985): ``(J^T J)^-1 J^T diag(r_i^2 / (1 - h_i)^2) J (J^T J)^-1``, h the leverages ``diag(J (J^T J)^-1
    J^T)``.  Valid whatever the noise of each record; infinite where a record has leverage 1 (it alone
    sets a parameter)."""
    A = covariance(J, 1.0)
    if not np.all(np.isfinite(A)):
        return A
    h = np.einsum("ij,jk,ik->i", J, A, J)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = (r / (1.0 - h)) ** 2
    if not np.all(np.isfinite(w)):
        return np.full(A.shape, np.inf)
    return A @ (J.T * w) @ J @ A


# --------------------------------------------------------------------------
# Table 2 reproduction
# --------------------------------------------------------------------------
#: Readings compared in :func:`table2_reproduction` (the first is the default).
READINGS: dict[str, Discretisation] = {
    "16 strands aligned, eq 3": Discretisation(16, "aligned", True),
    "16 strands aligned, eq 4": Discretisation(16, "aligned", False),
    "16 strands straddle, eq 3": Discretisation(16, "straddle", True),
    "16 strands straddle, eq 4": Discretisation(16, "straddle", False),
    "32 strands aligned, eq 3": Discretisation(32, "aligned", True),
    "32 strands aligned, eq 4": Discretisation(32, "aligned", False),
    "24 uniform steps per cylinder, eq 3": Discretisation(layout="uniform", exact=True, steps=24),
    "24 uniform steps per cylinder, eq 4": Discretisation(layout="uniform", exact=False, steps=24),
}


def table2_reproduction(disc: Discretisation = DEFAULT_DISCRETISATION) -> list[dict]:
    """Table 2 beside the forward law with Table 3 parameters, row by row.

    Returns rows ``{fibre, F0_N, direction, V_mm_s, mu_k_paper, mu_k_model}``.
    """
    out = []
    for r in table2_rows():
        b, p, n = table3_params(r["fibre"])
        mu = predict_mu_k(r["F0_N"], r["V_mm_s"], r["direction"], b, p, n, disc)
        out.append({"fibre": r["fibre"], "F0_N": r["F0_N"], "direction": r["direction"],
                    "V_mm_s": r["V_mm_s"], "mu_k_paper": r["mu_k"], "mu_k_model": mu})
    return out


def table2_max_error(disc: Discretisation = DEFAULT_DISCRETISATION, continuous: bool = False) -> float:
    """Largest ``|mu_k model - mu_k paper|`` over Table 2 for one reading."""
    if not continuous:
        return max(abs(r["mu_k_model"] - r["mu_k_paper"]) for r in table2_reproduction(disc))
    err = 0.0
    for r in table2_rows():
        b, p, n = table3_params(r["fibre"])
        F1 = predict_f1_continuous(r["F0_N"], r["V_mm_s"], r["direction"], b, p, n)
        err = max(err, abs(mu_k_eq1(r["F0_N"], F1, r["direction"]) - r["mu_k"]))
    return err
