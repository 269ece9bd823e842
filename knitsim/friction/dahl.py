"""Dahl (1976) rate-independent friction and its identification from a loop.

Source: ``../seeds/001_2969307b2af435f2.txt`` (Gemtex, "Modeling friction for
yarn/fabric simulation - application to bending hysteresis"), eqs 1-3, and the
parameters it identified from KES bending loops (``knitsim/data/dahl_kes.toml``).

The law (eq 1; the extracted text prints ``dF/dt`` on the left, but the paper
calls the model position dependent and derives eq 2 from ``dF/dx``)::

    dF/dx = sigma (1 - (F/Fc) s)^alpha,     s = sign(dx)

Integration over an increment
-----------------------------
Along one increment the direction ``s`` is fixed and ``p = |dx|`` grows.  With
``u = 1 - s F/Fc`` the law becomes ``du/dp = -(sigma/Fc) u^alpha``: separable.

* ``alpha = 1``: ``u = u0 exp(-sigma p/Fc)``, i.e. the exact update
  ``F_new = s Fc + (F_old - s Fc) exp(-sigma |dx| / Fc)``.
* ``alpha != 1``: ``u^(1-alpha) = u0^(1-alpha) + (alpha-1) (sigma/Fc) p``, written
  without infinities as ``u = u0 (1 + q)^(-1/(alpha-1))`` with
  ``q = (alpha-1) (sigma/Fc) p |u0|^(alpha-1)``.  For ``alpha > 1`` the force tends
  to ``s Fc`` only asymptotically; for ``alpha < 1`` it reaches it after the finite
  travel ``p* = u0^(1-alpha) Fc / ((1-alpha) sigma)`` (``1 + q <= 0``) and stays
  there (``u = 0`` is the physical branch of the non-Lipschitz ODE).
* ``|F| > Fc`` in the direction of motion (``u < 0``: a state left over after Fc
  dropped, e.g. a crossing whose ratio m fell) is not covered by eq 1 for
  non-integer alpha.  We extend the law oddly, ``dF/dx = sigma sign(u) |u|^alpha``,
  so the force relaxes back to ``s Fc`` by the same closed form applied to
  ``|u|``; for ``alpha = 1`` this is eq 1 itself.

``1 + q`` is formed with ``log1p`` so that alpha close to 1 loses no accuracy.

Dahl at the crossing
--------------------
The same function updates the friction ratio at a yarn crossing (``model.md``,
"Dahl at the crossing"): call :func:`dahl_increment` with ``F = tan(phi)``,
``dx = d xi`` (slip, positive in loading), ``Fc = m`` (the apparent ratio, eq 10
of Dusserre 2015) and ``sigma`` = the crossing's friction stiffness [1/mm].

Identification
--------------
:func:`fit_dahl_loop` fits ``F = B x + F_dahl(x history; sigma, Fc, alpha, F0)``
to a measured loop by nonlinear least squares (the paper's method) and reports
standard errors from the Jacobian.  It is unit-agnostic: ``sigma`` and ``B`` come
out in force-units per x-unit, ``Fc`` and ``F0`` in force-units.  For a KES
bending loop (M per width vs curvature) the paper's parameters are in
gf.cm^2/cm (sigma) and gf.cm/cm (Fc); see the module :mod:`knitsim.cli.dahl`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from ..errors import KnitsimInputError, require_finite
from .identification import covariance, parameter_status

#: Fewest samples accepted for an identification.
MIN_FIT_POINTS = 20
#: A reversal counts when x travels back by this fraction of its range.
REVERSAL_FRACTION = 0.05
#: Range of the shape exponent alpha accepted by :func:`fit_dahl_loop`, fixed or
#: fitted (the box the free fit searches).  Dahl (1976) and the KES paper use
#: alpha = 1; alpha < 1 reaches Fc after a finite travel, alpha > 1 only
#: asymptotically.  Beyond 50 the force stalls far below Fc for any travel a
#: loop can have (``u^50``), below 0.02 the law is a step: neither is a
#: friction law one can identify from a loop.
ALPHA_MIN = 0.02
ALPHA_MAX = 50.0
#: Lower bound of sigma and Fc in the fit's scaled units (data scaled to order 1).
_POSITIVE_FLOOR = 1e-12
#: More significant reversals than this fraction of the samples (and more than
#: :data:`REVERSAL_WARN_MIN`) is not a loop: the rows are probably out of order.
REVERSAL_WARN_FRACTION = 0.05
REVERSAL_WARN_MIN = 10
#: a loop whose circulation oint F dx is below -this x its bounding box (range of x times range of F) gains
#: energy, which a Dahl loop (sigma, Fc > 0) cannot: rows in reverse order, or a sign flipped
ENERGY_GAIN_REL = 0.01


@dataclass(frozen=True)
class DahlParams:
    """Parameters of the Dahl law, eq 1.

    Attributes
    ----------
    sigma : float
        Stiffness at zero force, dF/dx at F = 0 [force / displacement].
    Fc : float
        Coulomb (saturation) force [force].
    alpha : float
        Shape exponent (the paper uses 1).
    """

    sigma: float
    Fc: float
    alpha: float = 1.0

    def __post_init__(self) -> None:
        for name in ("sigma", "Fc", "alpha"):
            value = getattr(self, name)
            try:
                ok = math.isfinite(float(value)) and float(value) > 0.0
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise KnitsimInputError(f"Dahl parameter {name} = {value!r}: must be a finite number > 0")

    def response(self, x, F0: float = 0.0) -> np.ndarray:
        """Force history along the displacement history ``x`` (see :func:`dahl_response`)."""
        return dahl_response(x, self.sigma, self.Fc, self.alpha, F0)


# --------------------------------------------------------------------------
# eq 1 integrated over an increment
# --------------------------------------------------------------------------
def dahl_increment(F, dx, sigma, Fc, alpha=1.0):
    """Exact update of the Dahl force over a displacement increment (eq 1).

    Parameters
    ----------
    F : array_like
        Force before the increment [force]; at a crossing, ``tan(phi)``.
    dx : array_like
        Displacement increment [length]; at a crossing, the slip ``d xi``.
    sigma, Fc, alpha : array_like
        Dahl parameters (> 0); at a crossing ``Fc = m`` and ``sigma`` the
        friction stiffness.  All arguments broadcast together (struct of arrays).

    Returns
    -------
    ndarray
        Force after the increment, float64, broadcast shape.  ``dx = 0`` leaves
        ``F`` unchanged.  Exact for every alpha (closed form, module docstring).
    """
    F, dx, sigma, Fc, alpha = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (F, dx, sigma, Fc, alpha)))
    s = np.sign(dx)
    p = np.abs(dx)
    k = sigma / Fc
    one = alpha == 1.0
    # alpha = 1: F_new = s Fc + (F - s Fc) exp(-sigma |dx| / Fc)
    F1 = s * Fc + (F - s * Fc) * np.exp(-k * p)
    # alpha != 1: u = 1 - s F/Fc, |u| by the separable closed form, sign kept
    u = 1.0 - s * F / Fc
    w = np.abs(u)
    am1 = np.where(one, 1.0, alpha - 1.0)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        q = am1 * k * p * w ** am1
        w_new = np.where(q <= -1.0, 0.0, w * np.exp(-np.log1p(np.maximum(q, -1.0)) / am1))
    w_new = np.where(w == 0.0, 0.0, w_new)
    Fa = s * Fc * (1.0 - np.sign(u) * w_new)
    out = np.where(one, F1, Fa)
    out = np.where(s == 0.0, F, out)
    return out[()] if out.ndim == 0 else out


def dahl_slope(F, s, sigma, Fc, alpha=1.0):
    """Right-hand side of eq 1, dF/dx, extended oddly for ``|F| > Fc``.

    Parameters
    ----------
    F : array_like
        Force [force].
    s : array_like
        Direction of motion, +1 or -1.
    sigma, Fc, alpha : array_like
        Dahl parameters.

    Returns
    -------
    ndarray
        ``sigma sign(u) |u|^alpha`` with ``u = 1 - s F/Fc``.
    """
    u = 1.0 - np.asarray(s, dtype=float) * np.asarray(F, dtype=float) / Fc
    return sigma * np.sign(u) * np.abs(u) ** alpha


def dahl_response(x, sigma, Fc, alpha=1.0, F0=0.0):
    """Run a displacement history and return the Dahl force history.

    Parameters
    ----------
    x : array_like, shape (n,)
        Displacement samples [length].  Only the path matters (rate independence).
    sigma, Fc, alpha, F0 : array_like
        Parameters and initial force; they broadcast together to a batch shape S.

    Returns
    -------
    ndarray, shape S + (n,)
        ``F[..., 0] = F0``; later samples follow :func:`dahl_increment`.

    Notes
    -----
    Within a monotone run the closed form is applied to the travel since the
    run's start, which equals stepping sample by sample (the update is the exact
    flow of eq 1) and costs one vectorised call per run.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1 or x.size == 0:
        raise KnitsimInputError(f"displacement history x: expected a non-empty 1-D array, got shape {x.shape}")
    if not np.isfinite(x).all():
        raise KnitsimInputError(f"displacement history x: sample {int(np.flatnonzero(~np.isfinite(x))[0])} is "
                                "not a finite number")
    sigma, Fc, alpha, F0 = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (sigma, Fc, alpha, F0)))
    # eq 1: a stiffness, a limiting force (Fc <= 0 has no limit to approach) and an exponent
    for name, v in (("Dahl sigma", sigma), ("Dahl Fc", Fc), ("Dahl alpha", alpha)):
        require_finite(name, v, ">0")
    require_finite("Dahl F0", F0)
    shape = sigma.shape
    F = np.empty(shape + (x.size,))
    F[..., 0] = F0
    if x.size == 1:
        return F
    step_dir = np.sign(np.diff(x))
    # zero steps inherit the direction of the run they sit in
    nz = np.flatnonzero(step_dir)
    if nz.size == 0:
        F[...] = F0[..., None]
        return F
    idx = np.where(step_dir != 0, np.arange(step_dir.size), -1)
    idx = np.maximum.accumulate(idx)
    d = np.where(idx >= 0, step_dir[np.maximum(idx, 0)], step_dir[nz[0]])
    starts = np.concatenate(([0], np.flatnonzero(np.diff(d)) + 1))
    ends = np.concatenate((starts[1:], [d.size]))
    sig_b, Fc_b, al_b = sigma[..., None], Fc[..., None], alpha[..., None]
    for a, b in zip(starts, ends):
        travel = x[a + 1:b + 1] - x[a]
        F[..., a + 1:b + 1] = dahl_increment(F[..., a, None], travel, sig_b, Fc_b, al_b)
    return F


# --------------------------------------------------------------------------
# loops
# --------------------------------------------------------------------------
def steady_loop_peak(sigma, Fc, amplitude):
    """Peak force of the steady alpha = 1 loop between ``-A`` and ``+A``.

    Returns ``Fc tanh(sigma A / Fc)``: the fixed point of the exact update over
    one branch, ``F = Fc + (-F - Fc) exp(-2 sigma A / Fc)``.
    """
    return Fc * np.tanh(sigma * amplitude / Fc)


def steady_loop_energy(sigma, Fc, amplitude):
    """Energy dissipated per steady alpha = 1 cycle between ``-A`` and ``+A``.

    Integrating the exact ascending branch and using the loop's odd symmetry:
    ``W = 4 Fc (A - tanh(k A) / k)``, ``k = sigma / Fc``; ``W ~ 4 Fc A`` (Coulomb
    rectangle) for ``k A >> 1`` and ``4 sigma^2 A^3 / (3 Fc)`` for small loops.
    """
    k = sigma / Fc
    return 4.0 * Fc * (amplitude - np.tanh(k * amplitude) / k)


def loop_work(x, F):
    """Work ``integral F dx`` along a sampled path (trapezoid rule).

    Over a closed cycle this is the loop area, the energy dissipated per cycle.
    """
    x = np.asarray(x, dtype=float)
    F = np.asarray(F, dtype=float)
    return float(np.sum(0.5 * (F[1:] + F[:-1]) * np.diff(x)))


def kes_loop_path(amplitude, cycles=3, points_per_quarter=100):
    """Curvature path of a KES pure-bending test: 0 -> +K -> -K -> ... -> 0.

    Parameters
    ----------
    amplitude : float
        Largest |x| (KES: 2.5 1/cm = 0.25 1/mm).
    cycles : int
        Number of full +K -> -K swings (each starts at +K and returns to -K).
    points_per_quarter : int
        Samples per quarter cycle (a travel of ``amplitude``).

    Returns
    -------
    ndarray
        Piecewise-linear path that hits every turning point exactly.
    """
    if not (amplitude > 0 and math.isfinite(amplitude)):
        raise KnitsimInputError(f"amplitude = {amplitude!r}: must be a finite number > 0")
    if int(cycles) < 1:
        raise KnitsimInputError(f"cycles = {cycles!r}: must be >= 1")
    if int(points_per_quarter) < 2:
        raise KnitsimInputError(f"points_per_quarter = {points_per_quarter!r}: must be >= 2")
    n = int(points_per_quarter)
    # a quarter of n samples, (2 cycles - 1) half swings of 2 n and a last quarter: 1 + 4 n cycles samples, as
    # long as a load program may be (a probe's `dahl simulate --points 1000000000` was killed for memory)
    from ..cell.load_program import MAX_INCREMENTS
    samples = 1 + 4 * n * int(cycles)
    if samples > MAX_INCREMENTS + 1:
        raise KnitsimInputError(f"cycles = {cycles!r} and points_per_quarter = {points_per_quarter!r} make a path of "
                                f"{samples} samples (more than {MAX_INCREMENTS + 1}): give fewer cycles or points")
    vertices = [0.0] + [amplitude, -amplitude] * int(cycles) + [0.0]
    parts = [np.array([0.0])]
    for a, b in zip(vertices[:-1], vertices[1:]):
        m = max(1, int(round(n * abs(b - a) / amplitude)))
        parts.append(np.linspace(a, b, m + 1)[1:])
    return np.concatenate(parts)


def kes_loop(params: DahlParams, amplitude, cycles=3, points_per_quarter=100, B=0.0, F0=0.0,
             noise=0.0, seed=None):
    """Synthetic KES-like loop ``F = B x + F_dahl(x) + noise`` for tests and demos.

    Parameters
    ----------
    params : DahlParams
        Dahl parameters.
    amplitude, cycles, points_per_quarter
        See :func:`kes_loop_path`.
    B : float
        Elastic stiffness in parallel [force / displacement].
    F0 : float
        Initial Dahl force.
    noise : float
        Standard deviation of Gaussian noise added to F [force].
    seed : int, optional
        Seed of the noise generator.

    Returns
    -------
    x, F : ndarray
    """
    x = kes_loop_path(amplitude, cycles, points_per_quarter)
    F = B * x + params.response(x, F0)
    if noise:
        F = F + np.random.default_rng(seed).normal(0.0, noise, size=x.size)
    return x, F


def turning_points(x, fraction=REVERSAL_FRACTION):
    """Indices of the significant reversals of ``x``.

    A reversal counts when ``x`` travels back by more than ``fraction`` of its
    range from a running extreme, so noise does not create reversals.
    """
    x = np.asarray(x, dtype=float)
    rng = float(np.ptp(x)) if x.size else 0.0
    if rng == 0.0:
        return []
    h = fraction * rng
    turns: list[int] = []
    direction = 0  # +1 rising, -1 falling, 0 not yet known
    ext_i = 0      # index of the running extreme of the current run
    for i in range(1, x.size):
        if direction == 0:
            if x[i] - x[0] > h:
                direction, ext_i = 1, int(np.argmax(x[: i + 1]))
            elif x[0] - x[i] > h:
                direction, ext_i = -1, int(np.argmin(x[: i + 1]))
        elif direction > 0:
            if x[i] >= x[ext_i]:
                ext_i = i
            elif x[ext_i] - x[i] > h:
                turns.append(ext_i)
                direction, ext_i = -1, i
        else:
            if x[i] <= x[ext_i]:
                ext_i = i
            elif x[i] - x[ext_i] > h:
                turns.append(ext_i)
                direction, ext_i = 1, i
    return turns


# --------------------------------------------------------------------------
# identification
# --------------------------------------------------------------------------
@dataclass
class DahlFit:
    """Result of :func:`fit_dahl_loop` (fields in the units of the data).

    Attributes
    ----------
    sigma, Fc, alpha : float
        Dahl parameters (eq 1).
    B : float
        Elastic stiffness in parallel (0 when not fitted).
    F0 : float
        Dahl force at the first sample (the initial friction state).
    stderr : dict of str to float
        Standard errors of the fitted parameters (fixed ones are absent).
    names : tuple of str
        Fitted parameters, in the order of ``cov``.
    cov : ndarray
        Covariance of the fitted parameters, ``s^2 (J^T J)^-1``.
    rms : float
        Root-mean-square residual.
    n_points : int
        Number of samples.
    reversals : int
        Significant reversals found in x.
    success : bool
    status : int
    message : str
        As reported by :func:`scipy.optimize.least_squares`.
    nfev : int
    param_status : dict of str to str
        Per parameter ``"identified"``, ``"fixed"``, ``"at_lower_bound"``,
        ``"at_upper_bound"``, ``"not_identified"`` or ``"lower_bound_only"`` (sigma, where an
        instantaneous transition fits as well: :func:`_sigma_lower_bound`).
    lower_bounds : dict of str to float
        The one-sided 95 % lower bound of each ``"lower_bound_only"`` parameter.
    warnings : list of str
        What makes the result less than believable (shown to the user).
    """

    sigma: float
    Fc: float
    alpha: float
    B: float
    F0: float
    stderr: dict
    names: tuple
    cov: np.ndarray
    rms: float
    n_points: int
    reversals: int
    success: bool
    status: int
    message: str
    nfev: int
    fixed: dict = field(default_factory=dict)
    #: per parameter: ``"identified"``, ``"fixed"``, ``"at_lower_bound"``,
    #: ``"at_upper_bound"``, ``"not_identified"`` (non-finite or zero stderr) or ``"lower_bound_only"``
    param_status: dict = field(default_factory=dict)
    #: sentences for the user: parameters not identified, implausible loops
    warnings: list = field(default_factory=list)
    #: one-sided 95 % lower bounds of the parameters the data bound from one side only (status
    #: ``"lower_bound_only"``: sigma where the transitions are shorter than the row spacing)
    lower_bounds: dict = field(default_factory=dict)
    #: the loop's noise sd read off its rows without the fit (:func:`loop_noise`), and whether it was read
    #: (False: assumed, the rows being smoother than a measurement's)
    noise_sd: float = float("nan")
    noise_estimated: bool = False
    #: the loop's offset and drift against the fit (:func:`loop_closure`)
    closure: dict = field(default_factory=dict)
    #: why the fit is not a law to use beyond its parameters' status (short; the warnings say more): residuals
    #: beyond the noise, an offset, a loop that does not close, rows out of order, a loop that gains energy, an
    #: optimiser that did not converge
    loop_flags: list = field(default_factory=list)

    @property
    def identified(self) -> bool:
        """True when every fitted parameter is identified."""
        return all(v in ("identified", "fixed") for v in self.param_status.values())

    @property
    def params(self) -> DahlParams:
        """The Dahl parameters as a :class:`DahlParams`."""
        return DahlParams(self.sigma, self.Fc, self.alpha)

    def predict(self, x) -> np.ndarray:
        """Fitted force ``B x + F_dahl(x)`` along ``x`` starting from ``F0``."""
        x = np.asarray(x, dtype=float)
        return self.B * x + dahl_response(x, self.sigma, self.Fc, self.alpha, self.F0)


def _validate_loop(x, F, labels=("x", "F")):
    x = np.asarray(x, dtype=float)
    F = np.asarray(F, dtype=float)
    xl, fl = labels
    if x.ndim != 1 or F.ndim != 1 or x.size != F.size:
        raise KnitsimInputError(f"loop data: {xl} and {fl} must be 1-D of equal length (got {x.shape} and {F.shape})")
    if x.size < MIN_FIT_POINTS:
        raise KnitsimInputError(f"loop data: {x.size} points, need at least {MIN_FIT_POINTS}")
    for name, a in ((xl, x), (fl, F)):
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise KnitsimInputError(f"loop data: {name}[{bad[0]}] = {a[bad[0]]!r} is not finite")
    turns = turning_points(x)
    if not turns:
        raise KnitsimInputError(f"loop data: {xl} has no reversal (a hysteresis loop must go and come back)")
    if np.ptp(F) == 0.0:
        what = "never leaves zero" if F[0] == 0.0 else f"is {F[0]:g} on every row"
        raise KnitsimInputError(f"loop data: column {fl} {what}: the loop carries no friction force, so sigma and "
                                "Fc cannot be identified (is it the right column?)")
    return x, F, turns


def energy_gain_warning(x, F, labels=("x", "F")) -> str | None:
    """A warning when the rows, in their order, circulate the loop the way that gains energy, else None.

    A Dahl loop (sigma, Fc > 0) dissipates: ``oint F dx > 0`` over the rows in their order of acquisition
    (the force lags behind on each reversal).  Below -:data:`ENERGY_GAIN_REL` of the loop's bounding box
    the rows run in reverse order, or the sign of x or of F is flipped (each changes the circulation's
    sign); the fit then finds no Dahl loop and says "not identified" without the cause."""
    x, F = np.asarray(x, float), np.asarray(F, float)
    work = float(np.sum(0.5 * (F[1:] + F[:-1]) * np.diff(x)))
    box = float(np.ptp(x) * np.ptp(F))
    if box > 0 and work < -ENERGY_GAIN_REL * box:
        return (f"the loop gains energy: oint {labels[1]} d{labels[0]} = {work:.4g} < 0 over the rows in their "
                f"order, where a Dahl loop dissipates (> 0): the rows run in reverse order, or the sign of "
                f"{labels[0]} or {labels[1]} is flipped")
    return None


def reversal_warning(n_points: int, reversals: int, label: str = "x") -> str | None:
    """A warning when ``x`` reverses too often for a hysteresis loop, else None.

    A measured loop reverses a few times (a KES test: 6 times in about 1200
    samples); more than :data:`REVERSAL_WARN_FRACTION` of the samples (and
    more than :data:`REVERSAL_WARN_MIN`) means rows out of order.
    """
    if reversals > max(REVERSAL_WARN_FRACTION * n_points, REVERSAL_WARN_MIN):
        return (f"{label} reverses {reversals} times in {n_points} points ({100.0 * reversals / n_points:.0f} %): "
                "a loop reverses a few times; the rows may be out of order (give them in order of acquisition)")
    return None


def _local_slope(x, F, idx):
    """Least-squares slope dF/dx over the samples ``idx``."""
    xs, Fs = x[idx], F[idx]
    if xs.size < 2 or np.ptp(xs) == 0:
        return 0.0
    return float(np.polyfit(xs, Fs, 1)[0])


def initial_guess(x, F, elastic=False, turns=None):
    """Starting values (sigma, Fc, B, F0) read off a loop.

    * Fc: half the loop width at mid-range (both branches there; the elastic
      part cancels).  For a steady alpha = 1 loop the width is
      ``2 Fc (1 - sech(k A))``, close to ``2 Fc`` once ``k A >> 1``.
    * B: slope just before the last reversal (the Dahl part has saturated).
    * sigma: slope just after the last reversal is ``B + sigma (1 + F_r/Fc)``
      (eq 1 with ``s`` flipped at ``F = F_r``), about ``B + 2 sigma`` on a saturated
      loop.
    * F0: first sample minus the elastic part, clipped to ``[-Fc, Fc]``.
    """
    x = np.asarray(x, dtype=float)
    F = np.asarray(F, dtype=float)
    if turns is None:
        turns = turning_points(x)
    rng = float(np.ptp(x))
    mid = 0.5 * (x.max() + x.min())
    # branch values at mid-range, from the last ascending and descending branches
    bounds = [0] + list(turns) + [x.size - 1]
    asc, desc = [], []
    for a, b in zip(bounds[:-1], bounds[1:]):
        seg_x, seg_F = x[a:b + 1], F[a:b + 1]
        if seg_x.min() <= mid <= seg_x.max() and np.ptp(seg_x) > 0:
            order = np.argsort(seg_x, kind="stable")
            val = float(np.interp(mid, seg_x[order], seg_F[order]))
            (asc if seg_x[-1] > seg_x[0] else desc).append(val)
    if asc and desc:
        Fc0 = 0.5 * abs(desc[-1] - asc[-1])
    else:
        Fc0 = 0.25 * float(np.ptp(F))
    Fc0 = max(Fc0, 1e-6 * max(float(np.ptp(F)), 1e-300))
    r = turns[-1]
    window_after = [i for i in range(r, min(x.size, r + 50)) if abs(x[i] - x[r]) <= 0.03 * rng]
    window_before = [i for i in range(max(0, r - 50), r + 1) if abs(x[i] - x[r]) <= 0.1 * rng]
    slope_after = abs(_local_slope(x, F, window_after))
    B0 = max(_local_slope(x, F, window_before), 0.0) if elastic else 0.0
    ratio = min(abs(F[r] - B0 * x[r]) / Fc0, 1.0)
    sigma0 = max(slope_after - B0, 0.0) / (1.0 + ratio)
    if sigma0 <= 0.0:
        sigma0 = 4.0 * Fc0 / max(rng, 1e-300)
    F0 = float(np.clip(F[0] - B0 * x[0], -Fc0, Fc0))
    return sigma0, Fc0, B0, F0


#: chi^2 rise (in noise variances) of the one-sided 95 % bound of one parameter (the chi^2_1 quantile at 0.90)
SIGMA_BOUND_CHI2 = 2.706
#: the sharp limit of a transition: its length Fc / sigma this fraction of the shortest step between rows
SHARP_STEP_SHARE = 1.0e-3
#: rows per branch (between reversals) on which a transition must show above the noise to be measured
MIN_TRANSITION_ROWS = 2
#: ... unless the sharp limit costs at least this chi^2 (5 noise sd): the first row after each reversal
#: then measures the decay (sigma = 1 in that probe: one row a branch at 3.8 sd, chi^2 +70, sigma within 1 SE)
SIGMA_RESOLVED_CHI2 = 25.0


def _sigma_lower_bound(residual, theta, names, lower, upper, s2, xn, branches):
    """Whether the loop bounds sigma from below only: ``(bound, d_chi2, shown)`` (the bound, the rise of
    chi^2 at the sharp limit, the rows the fitted transition shows on) or None.

    After a reversal the Dahl force relaxes over a travel Fc / sigma (alpha = 1).  Where that travel is
    shorter than the step between rows, the transition is over by the next row and the data cannot tell
    sigma from infinity: the standard error of the fit (the curvature of chi^2 at its minimum) then
    describes where the fit stopped, not what the data know (a blind probe: sigma = 50 and 5, rows every
    0.05 with Fc = 0.014, both fitted at 1.9 +- 0.23, "identified").  Two tests, either of which says
    that the data bound sigma from below only:

    - the profile of chi^2: the other parameters refitted with sigma at the sharp limit
      (:data:`SHARP_STEP_SHARE`) raise chi^2 by less than :data:`SIGMA_BOUND_CHI2` noise variances
      (``s2``, from the best fit);
    - the fitted transition shows on fewer than :data:`MIN_TRANSITION_ROWS` rows per branch
      (``branches``: its force differs from the sharp limit's by more than the noise sd on fewer rows)
      and the sharp limit costs less than :data:`SIGMA_RESOLVED_CHI2`.
      The profile alone is not enough there: in that probe the sharp limit cost chi^2 +6.0, a rise made
      by the noise of the four rows after the reversals, with the truth 26 times the fit.

    The bound is the sigma below the fit where the profile rises by :data:`SIGMA_BOUND_CHI2` (bisection
    in log sigma).  ``theta`` is the best fit in the scaled units of ``residual``, sigma first.
    """
    rest = [i for i, nm in enumerate(names) if nm != "sigma"]
    r0 = residual(theta)
    best = float(r0 @ r0)

    def profile(sg, start):
        def r(th):
            full = theta.copy()
            full[rest] = th
            full[0] = sg
            return residual(full)
        fit = least_squares(r, np.clip(start, lower[rest] + 1e-9, upper[rest] - 1e-9), jac="3-point",
                            bounds=(lower[rest], upper[rest]), method="trf", x_scale="jac", ftol=1e-12,
                            xtol=1e-12, gtol=1e-12, max_nfev=500)
        return (2.0 * fit.cost - best) / s2, fit.x

    steps = np.abs(np.diff(xn))
    steps = steps[steps > 0]
    if not steps.size or not s2 > 0:
        return None
    Fc = theta[names.index("Fc")]
    sharp = max(theta[0], Fc / (SHARP_STEP_SHARE * float(np.min(steps))))
    d_sharp, _ = profile(sharp, theta[rest])
    # the rows on which the fitted transition shows: its force differs from the instantaneous transition's
    # (the same other parameters) by more than the noise sd
    at_sharp = theta.copy()
    at_sharp[0] = sharp
    shown = int(np.count_nonzero(np.abs(residual(theta) - residual(at_sharp)) > math.sqrt(s2)))
    if d_sharp >= SIGMA_BOUND_CHI2 and (shown >= MIN_TRANSITION_ROWS * branches or d_sharp >= SIGMA_RESOLVED_CHI2):
        return None
    # the bracket: halve sigma until chi^2 rises past the bound (the data do set a lower bound: the
    # loop's rounding after a reversal, at most over a row)
    hi, lo, start = float(theta[0]), None, theta[rest]
    for _ in range(60):
        trial = hi * 0.5
        d, x = profile(trial, start)
        if d >= SIGMA_BOUND_CHI2:
            lo = trial
            break
        hi, start = trial, x
    if lo is None:
        return None
    for _ in range(30):
        mid = math.sqrt(lo * hi)
        d, x = profile(mid, start)
        if d >= SIGMA_BOUND_CHI2:
            lo = mid
        else:
            hi, start = mid, x
        if hi / lo < 1.0 + 1e-3:
            break
    return hi, max(d_sharp, 0.0), shown


#: a fit whose rms residual exceeds this many times the loop's own noise (:func:`loop_noise`) misses the loop:
#: its residuals are systematic.  (rms / sd)^2 = 4 is chi^2 / dof = 4, which the estimate's scatter does not
#: reach by chance: its relative sd is about 1 / sqrt(rows), 0.2 at the fewest rows a fit accepts
RESIDUAL_NOISE_MAX = 2.0
#: an offset or a drift of the loop (:func:`loop_closure`) is flagged beyond this many standard errors ...
CLOSURE_Z = 5.0
#: ... larger than the noise sd of a row, and where it makes at least this share of the residuals' mean square
#: (an offset c makes c^2 of it, a linear drift d over the rows d^2 / 12): a misfit of the law's shape leaves
#: small offsets and trends in the branch means (an elastic part fitted without --elastic: a drift of 0.85
#: times the rms, 0.06 of the mean square); an offset or a drift that is the misfit makes most of it
CLOSURE_SHARE = 0.1


def loop_noise(x, F, turns=None) -> tuple[float, int, bool]:
    """The loop's noise sd read off its rows, independent of any fit.

    Each row is compared with the cubic through its two neighbours on each side along one branch (x strictly
    monotone over the five rows, :func:`knitsim.diagnosis.noise.cubic_deviations`): white noise of sd s gives
    deviations of sd s whatever the loop's slope, and the smooth loop leaves only ``O(h^4)`` of its fourth
    derivative; the few rows by a reversal where a transition curves sharply are clipped
    (:func:`knitsim.diagnosis.noise.clipped_sd`: the RMS within 3.5 robust sd).  The estimate
    ``knitsim diagnose`` makes of a curve's noise.

    Parameters
    ----------
    x, F : array_like, shape (n,)
        The loop, rows in order of acquisition.
    turns : list of int, optional
        Its reversals (:func:`turning_points`).

    Returns
    -------
    sd : float
        The noise sd, in the units of F.  Where it cannot be read (fewer than
        :data:`knitsim.diagnosis.noise.MIN_SAMPLES` stencils, or below
        :data:`knitsim.diagnosis.noise.SMOOTH_REL` of the force range: a loop made by a program, or smoothed)
        :data:`knitsim.diagnosis.noise.ASSUMED_REL` of the force range, as ``diagnose`` assumes for a curve
        read off a figure.
    samples : int
        Rows the estimate rests on.
    estimated : bool
        False where ``sd`` is assumed.
    """
    from ..diagnosis.noise import ASSUMED_REL, MIN_SAMPLES, SMOOTH_REL, clipped_sd, cubic_deviations

    x, F = np.asarray(x, float), np.asarray(F, float)
    if turns is None:
        turns = turning_points(x)
    branch = np.zeros(x.size, int)
    for t in turns:
        branch[t + 1:] += 1
    z, _ = cubic_deviations(x, F, branch, np.zeros(x.size))
    span = float(np.ptp(F))
    sd = clipped_sd(z) if len(z) >= MIN_SAMPLES else 0.0
    if sd > SMOOTH_REL * span:
        return sd, len(z), True
    return ASSUMED_REL * span, len(z), False


#: x jittering by more than this share of its step between rows is named as a cause of a misfit
X_JITTER_SHARE = 0.05


def _x_jitter(x, turns) -> tuple[float, float] | None:
    """``(sd, share of the median step)`` of x's own scatter between rows where it exceeds
    :data:`X_JITTER_SHARE` of a step (:func:`knitsim.diagnosis.noise.strain_jitter`: second differences,
    which a steady ramp cancels), else None.  The fit integrates the law along x as read: a jittering reading
    reverses x by a little, again and again, and moves the Dahl state where the specimen's did not move."""
    from ..diagnosis.noise import strain_jitter

    step = float(np.median(np.abs(np.diff(np.asarray(x, float)))))
    j = strain_jitter(x)
    return (j, j / step) if step > 0 and j > X_JITTER_SHARE * step else None


def loop_closure(x, residual, turns, sd) -> dict:
    """The offset and the drift of a loop against its fit, from the mean residual of each full branch.

    A Dahl loop, with or without an elastic part, is odd in (x, F), and it repeats itself cycle after cycle
    once its start is forgotten (the fit carries that transient).  The mean residuals ``r_b`` of its full
    branches (the rows strictly between two reversals) are fitted by ``c + e s_b + d t_b``: ``s_b`` the
    branch's direction (+-1: what a misfit of the law's shape leaves, opposite on the two directions),
    ``t_b`` its middle row over the rows, less 1/2.  ``c`` is the loop's offset (its centre off zero: a force
    column not tared), ``d`` the change of F at one x from the first row to the last (a loop that does not
    close: a load cell drifting, a specimen creeping or wearing).  Each branch is weighted by its rows, the
    standard errors from ``max(sd, rms of the residuals)`` a row (the residuals of a misfit are not white).

    Parameters
    ----------
    x, residual : array_like, shape (n,)
        The loop's input and the data less the fit, rows in order.
    turns : list of int
        The reversals (:func:`turning_points`).
    sd : float
        The noise sd of a row (:func:`loop_noise`).

    Returns
    -------
    dict
        ``offset``, ``offset_se``, ``drift``, ``drift_se`` (None where the branches do not tell: fewer than
        2 full branches of both directions for the offset, 3 for the drift) and ``branches``.
    """
    x, r = np.asarray(x, float), np.asarray(residual, float)
    bounds = [0] + list(turns) + [x.size - 1]
    rows, means, t, s = [], [], [], []
    for a, b in zip(bounds[1:-2], bounds[2:-1]):   # between two reversals: not the first run, not the last
        if b - a < 2:
            continue
        rows.append(b - a - 1)
        means.append(float(np.mean(r[a + 1:b])))
        t.append(0.5 * (a + b) / x.size - 0.5)
        s.append(1.0 if x[b] > x[a] else -1.0)
    out = {"offset": None, "offset_se": None, "drift": None, "drift_se": None, "branches": len(rows)}
    if len(rows) < 2 or len(set(s)) < 2:
        return out
    per_row = max(float(sd), float(np.sqrt(np.mean(r * r))))
    w = np.asarray(rows, float) / per_row ** 2
    with_drift = len(rows) >= 3
    A = np.column_stack([np.ones(len(rows)), np.asarray(s)] + ([np.asarray(t)] if with_drift else []))
    cov = np.linalg.pinv(A.T @ (A * w[:, None]))
    coef = cov @ (A.T @ (w * np.asarray(means)))
    out["offset"], out["offset_se"] = float(coef[0]), float(math.sqrt(max(cov[0, 0], 0.0)))
    if with_drift:
        out["drift"], out["drift_se"] = float(coef[2]), float(math.sqrt(max(cov[2, 2], 0.0)))
    return out


#: a fitted Fc more than this many times the largest |force| the Dahl part reaches over the loop is not
#: identified: the state never nears its saturation (fit_dahl_loop)
FC_BEYOND = 3.0


def fit_dahl_loop(x, F, *, elastic=False, alpha=1.0, initial=None, labels=("x", "F")):
    """Identify Dahl parameters from a measured hysteresis loop.

    Model: ``F = B x + F_dahl(x history; sigma, Fc, alpha, F0)`` (B = 0 unless
    ``elastic``), fitted by nonlinear least squares as in the paper
    (:func:`scipy.optimize.least_squares`, trust-region reflective with
    sigma, Fc, alpha > 0), from :func:`initial_guess` and two restarts with
    sigma scaled by 1/3 and 3 (the best one is kept).

    Parameters
    ----------
    x, F : array_like, shape (n,)
        The loop: displacement-like input (e.g. curvature) and the measured
        force-like output (e.g. moment per width), in order of acquisition.
    elastic : bool
        Fit an elastic part ``B x`` in parallel.
    alpha : float or None
        Fixed shape exponent in [:data:`ALPHA_MIN`, :data:`ALPHA_MAX`]
        (default 1, as in the paper); ``None`` fits it in that range.
    initial : dict, optional
        Starting values overriding the guesses (keys sigma, Fc, alpha, B, F0).
    labels : (str, str)
        Names of x and F in error messages and warnings (e.g. CSV columns).

    Returns
    -------
    DahlFit
        Parameters, standard errors ``sqrt(diag(s^2 (J^T J)^-1))`` with
        ``s^2 = SSR / (n - p)``, fit statistics, and ``param_status`` / ``warnings``:
        a parameter at a bound of the fit (sigma, Fc -> 0; alpha at
        ALPHA_MIN or ALPHA_MAX), with a non-finite or zero standard error, or
        (sigma, Fc, alpha, all > 0) with a standard error above its value is
        not identified; implausibly many reversals (rows out of order) warn.

    Raises
    ------
    KnitsimInputError
        Fewer than :data:`MIN_FIT_POINTS` samples, non-finite values, a force
        that never changes, no reversal in ``x``, or alpha out of range.
    """
    if alpha is not None:
        try:
            ok = math.isfinite(float(alpha)) and ALPHA_MIN <= float(alpha) <= ALPHA_MAX
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise KnitsimInputError(f"alpha = {alpha!r}: must be a number in [{ALPHA_MIN:g}, {ALPHA_MAX:g}] "
                                    "(or None to fit it)")
    x, F, turns = _validate_loop(x, F, labels)
    # work in scaled units so that every parameter is of order one
    xs = max(float(np.max(np.abs(x))), 1e-300)
    Fs = max(float(np.max(np.abs(F - np.mean(F)))), 1e-300)
    xn, Fn = x / xs, F / Fs
    sigma0, Fc0, B0, F00 = initial_guess(xn, Fn, elastic, turns)
    scale = {"sigma": Fs / xs, "Fc": Fs, "alpha": 1.0, "B": Fs / xs, "F0": Fs}
    start = {"sigma": sigma0, "Fc": Fc0, "alpha": 1.0 if alpha is None else alpha, "B": B0, "F0": F00}
    if initial:
        for key, value in initial.items():
            if key not in start:
                raise KnitsimInputError(f"initial: unknown parameter {key!r}")
            start[key] = float(value) / scale[key]
    names = ["sigma", "Fc"] + (["alpha"] if alpha is None else []) + (["B"] if elastic else []) + ["F0"]
    fixed = {}
    if alpha is not None:
        fixed["alpha"] = float(alpha)
    if not elastic:
        fixed["B"] = 0.0
    lower = np.array([_POSITIVE_FLOOR if n in ("sigma", "Fc") else (ALPHA_MIN if n == "alpha" else -np.inf)
                      for n in names])
    upper = np.array([ALPHA_MAX if n == "alpha" else np.inf for n in names])

    def unpack(theta):
        v = dict(zip(names, theta))
        a = v.get("alpha", start["alpha"])
        b = v.get("B", 0.0)
        return v["sigma"], v["Fc"], a, b, v["F0"]

    def residual(theta):
        sg, fc, a, b, f0 = unpack(theta)
        return b * xn + dahl_response(xn, sg, fc, a, f0) - Fn

    best = None
    for factor in (1.0, 1.0 / 3.0, 3.0):
        th0 = np.array([start[n] * (factor if n == "sigma" else 1.0) for n in names])
        th0 = np.clip(th0, lower + 1e-9, upper - 1e-9)
        res = least_squares(residual, th0, jac="3-point", bounds=(lower, upper), method="trf",
                            x_scale="jac", ftol=1e-12, xtol=1e-12, gtol=1e-12, max_nfev=2000)
        if best is None or res.cost < best.cost:
            best = res
    res = best
    n, p = x.size, len(names)
    J = res.jac
    dof = max(n - p, 1)
    s2 = 2.0 * res.cost / dof
    sc = np.array([scale[nm] for nm in names])
    sg, fc, a, b, f0 = unpack(res.x)
    values = {"sigma": sg * scale["sigma"], "Fc": fc * scale["Fc"], "alpha": a, "B": b * scale["B"], "F0": f0 * scale["F0"]}
    floor = [n in ("sigma", "Fc") for n in names]

    def errors(cols: list[int]) -> np.ndarray:
        """The covariance of the parameters ``cols`` (the others held), in the reported units, p x p (inf
        outside ``cols``); their standard errors go into ``stderr``."""
        cov = np.full((p, p), np.inf)
        cov[np.ix_(cols, cols)] = covariance(J[:, cols], s2) * np.outer(sc[cols], sc[cols])
        for i in cols:
            stderr[names[i]] = float(math.sqrt(cov[i, i])) if math.isfinite(cov[i, i]) and cov[i, i] >= 0 else math.inf
        return cov

    def classify(cols: list[int], positive: tuple[str, ...]) -> tuple[dict, list]:
        """Believable or say why not: parameters at a bound or with a degenerate stderr (the bounds are in the
        fit's scaled units; sigma and Fc have the floor _POSITIVE_FLOOR, written 0)."""
        st, w = parameter_status([names[i] for i in cols], [float(res.x[i]) for i in cols],
                                 [stderr[names[i]] for i in cols], lower[cols], upper[cols],
                                 exact_fit=res.cost == 0.0, positive=positive,
                                 shown=[values[names[i]] for i in cols], atol=[1e-9 if floor[i] else 0.0 for i in cols],
                                 bound_text=["0" if floor[i] else None for i in cols])
        st.update({nm: "fixed" for nm in fixed})
        return st, w

    stderr: dict[str, float] = {}
    every = list(range(p))
    cov = errors(every)
    status, warns = classify(every, ("sigma", "Fc", "alpha"))
    lower_bounds = {}
    # (also where sigma came out not identified: on a loop whose transitions are over within a row the fit
    # ends where chi^2 no longer depends on sigma, its Jacobian column vanishes and every standard error
    # is infinite; a blind probe's sharp loops, sigma 1000 at Fc 0.8, had Fc and F0 "not identified")
    if status.get("sigma") in ("identified", "not_identified") and res.cost > 0.0:
        lb = _sigma_lower_bound(residual, res.x, names, lower, upper, s2, xn, len(turns) + 1)
        if lb is not None and status["sigma"] == "not_identified":
            # the other parameters at sigma's sharp limit: their covariance without sigma's column
            rest = [i for i, nm in enumerate(names) if nm != "sigma"]
            cov = errors(rest)
            status, warns = classify(rest, ("Fc", "alpha"))
        if lb is not None:
            bound, d_chi2, shown = lb
            lower_bounds["sigma"] = bound * scale["sigma"]
            status["sigma"] = "lower_bound_only"
            if d_chi2 < SIGMA_BOUND_CHI2:
                why = (f"an instantaneous transition (sigma -> infinity) fits as well (chi2 +{d_chi2:.2g} in noise "
                       f"variances, below {SIGMA_BOUND_CHI2:g})")
            else:
                why = (f"the fitted transition shows above the noise on {shown} row(s) of {len(turns) + 1} branches "
                       f"(fewer than {MIN_TRANSITION_ROWS} a branch), and an instantaneous transition (sigma -> "
                       f"infinity) fits only {d_chi2:.2g} noise variances worse: a difference the noise of a few rows makes")
            warns.append(
                f"sigma: the loop's transitions after its reversals are not resolved by its rows: {why}; the data "
                f"set only a lower bound, sigma >= {lower_bounds['sigma']:.3g} (one-sided 95 %); its value "
                f"{values['sigma']:.4g} and standard error mean nothing (record the loop with more rows after each "
                "reversal)")
    # Fc from above: a loop whose forces stay far below saturation is a straight spring, the Dahl limit
    # Fc -> infinity (F = F0 + sigma (x - x_0)); where that line fits as well (chi^2 within the one-sided
    # bound, or exactly as the fit does), the data bound Fc from below only (a blind probe's loop of
    # F = 0.3 x read Fc = 1.9e5 N +- 1.1e3, "identified")
    if status.get("Fc") == "identified":
        cols = [xn - xn[0], np.ones_like(xn)] + ([xn] if elastic else [])
        A = np.column_stack(cols)
        line = Fn - A @ np.linalg.lstsq(A, Fn, rcond=None)[0]
        ssr_line, ssr_fit = float(line @ line), 2.0 * float(res.cost)
        tiny = 1e-20 * float(Fn @ Fn)
        if ssr_line <= max(ssr_fit + SIGMA_BOUND_CHI2 * s2, tiny):
            status["Fc"] = "not_identified"
            warns.append(
                f"Fc: the loop shows no saturation above the noise: a straight spring (Fc -> infinity) fits as well "
                f"(residual sum {ssr_line * Fs * Fs:.3g} against the fit's {ssr_fit * Fs * Fs:.3g} {labels[1]}^2); "
                f"the data bound Fc from below only, its value {values['Fc']:.4g} means nothing (a loop with "
                "hysteresis, its forces reaching the saturation, identifies it)")
    # Fc beyond the loop: the Dahl state never nears its saturation over the rows (its largest |state| a small
    # share of Fc), so Fc is an extrapolation of the transitions' curvature.  A blind probe's loop of a Dahl
    # yarn with an elastic part, fitted without --elastic: Fc = 0.0194, 141 times the truth and 7 times the
    # largest moment of the file, "identified"; with --elastic the truth came back
    if status.get("Fc") == "identified":
        state = F - values["B"] * x
        reach = float(np.max(np.abs(state)))
        if values["Fc"] > FC_BEYOND * reach:
            status["Fc"] = "not_identified"
            warns.append(
                f"Fc: {values['Fc']:.4g} is {values['Fc'] / reach:.3g} times the largest {labels[1]} the Dahl part "
                f"reaches over the loop ({reach:.4g}): the loop never nears its saturation, so Fc is an "
                "extrapolation, not a measurement" + ("" if elastic else
                                                      "; a loop with an elastic part in parallel reads so: try --elastic"))
    # the Dahl state at the first row can never exceed Fc (eq. of the Dahl model: |z| <= Fc from any start
    # within it): a fitted F0 beyond Fc is an offset of the force column or a loop not centred
    if abs(values["F0"]) > values["Fc"] and status.get("Fc") not in ("not_identified", "lower_bound_only"):
        status["F0"] = "not_identified"
        warns.append(
            f"F0: the Dahl state at the first row, {values['F0']:.4g}, exceeds Fc = {values['Fc']:.4g}, which no Dahl "
            f"state does: {labels[1]} carries an offset (a zero not tared) or the loop is not centred on zero; tare "
            "the column and fit again")
    # Does the law describe the loop?  The rms residual against the loop's own noise, read off its rows
    # without the fit (loop_noise); then what the misfit is made of (loop_closure).  A blind probe: a Dahl yarn
    # with an elastic part fitted without --elastic left an rms 6 times its noise, "identified", exit 0; the
    # bundled loop with an offset of 22 % of Fc, rms 21 times its noise, and with a drift of 30 noise sd over
    # the file (sigma moved 5 %), rms 17 times, were said nothing of
    pred = values["B"] * x + dahl_response(x, values["sigma"], values["Fc"], values["alpha"], values["F0"])
    resid = F - pred
    rms = float(math.sqrt(2.0 * res.cost / n)) * Fs
    sd, sd_rows, sd_estimated = loop_noise(x, F, turns)
    closure = loop_closure(x, resid, turns, sd)
    noise_words = (f"the loop's noise, sd {sd:.3g} (each row against the cubic through its neighbours, {sd_rows} rows; "
                   "no fit)" if sd_estimated else
                   f"{100 * sd / max(float(np.ptp(F)), 1e-300):.2g} % of the force range, the noise assumed of a loop "
                   "whose rows are smoother than a measurement's (made by a program, or smoothed)")
    loop_flags: list[str] = []
    mean_square = rms * rms
    causes = []
    for key, se_key, share, what in (("offset", "offset_se", 1.0, "offset"), ("drift", "drift_se", 1.0 / 12.0, "drift")):
        v, se = closure[key], closure[se_key]
        # a linear drift d over the rows makes d^2/12 of the mean square, an offset c makes c^2
        if (v is not None and se and abs(v) > CLOSURE_Z * se and abs(v) > sd
                and share * v * v >= CLOSURE_SHARE * mean_square):
            causes.append(what)
            if what == "offset":
                loop_flags.append(f"the loop is off centre by {v:.3g} (an offset in {labels[1]}?)")
                warns.append(
                    f"the loop is not centred on zero: its full branches sit {v:.4g} {labels[1]} off the fit on average "
                    f"(+- {se:.2g}; a Dahl loop, with or without an elastic part, is odd, and over an up and a down "
                    f"branch its fit's misfit cancels): {labels[1]} carries an offset (a zero not tared; or, with a "
                    "drift, the drift's mean at mid-file); tare the column and fit again")
            else:
                loop_flags.append(f"the loop does not close: {labels[1]} drifts by {v:.3g} over the file")
                warns.append(
                    f"the loop does not close: at one {labels[0]}, {labels[1]} moves by {v:.4g} (+- {se:.2g}) from the "
                    f"first row to the last, against the fit, which repeats each cycle (compared on the full branches, "
                    f"{closure['branches']}): a load cell drifting, a specimen creeping or wearing; the law fitted to "
                    "it is an average, not the specimen's")
    ratio = rms / sd
    if ratio > RESIDUAL_NOISE_MAX:
        jitter = _x_jitter(x, turns)
        gains = energy_gain_warning(x, F, labels) is not None
        hint = "; ".join(
            (["the offset or drift above"] if causes else [])
            + (["rows reversed or a sign flipped (the warning below)"] if gains else [])
            + ([f"{labels[0]} itself scatters between rows (sd {jitter[0]:.2g}, {100 * jitter[1]:.0f} % of a step), and "
                f"the Dahl state the fit integrates follows every wiggle of {labels[0]} as read"] if jitter else [])
            + ([] if causes or gains else
               (["an elastic part in parallel? try --elastic"] if not elastic else [])
               + ([f"a shape exponent other than {values['alpha']:g}? try --alpha free"] if alpha is not None else []))
        ) or "a loop the Dahl law does not describe"
        loop_flags.append(f"residuals {ratio:.3g} times the noise")
        warns.append(
            f"the fit misses the loop: its rms residual, {rms:.3g}, is {ratio:.3g} times {noise_words} (more than "
            f"{RESIDUAL_NOISE_MAX:g}): the residuals are systematic, the parameters those of the nearest Dahl loop, "
            f"not the specimen's; {hint}")
    rev = reversal_warning(n, len(turns), labels[0])
    if rev:
        warns.append(rev)
        loop_flags.append("rows out of order")
    gain = energy_gain_warning(x, F, labels)
    if gain:
        warns.append(gain)
        loop_flags.append("the loop gains energy (reversed rows or a flipped sign?)")
    if not res.success:
        warns.append(f"the optimiser did not converge: {res.message}")
        loop_flags.append("the optimiser did not converge")
    return DahlFit(sigma=float(values["sigma"]), Fc=float(values["Fc"]), alpha=float(values["alpha"]),
                   B=float(values["B"]), F0=float(values["F0"]), stderr=stderr, names=tuple(names), cov=cov,
                   rms=rms, n_points=n, reversals=len(turns),
                   success=bool(res.success), status=int(res.status), message=str(res.message),
                   nfev=int(res.nfev), fixed=fixed, param_status=status, warnings=warns,
                   lower_bounds=lower_bounds, noise_sd=float(sd), noise_estimated=bool(sd_estimated),
                   closure=closure, loop_flags=loop_flags)
