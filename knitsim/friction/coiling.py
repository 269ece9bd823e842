"""Apparent friction ratio at a loop crossing: Dusserre (2015) eqs 10 and 11.

Eq 10: the ratio ``m = Rt/Rn`` of the contact load at the crossing point B
when one yarn is coiled by ``theta`` around the other and slides on it with
the drive-belt law (eq 1).  Eq 11: the coiling angle of the jammed knit from
the stitch length ``L``, the course length ``C`` and the yarn diameter ``d``.

Functions take radians; ``*_deg`` helpers convert at the edge.

Eq 10, derivation
-----------------
Let the sliding yarn wrap an arc of angle ``theta`` around the other one.
Along the arc ``dT/dphi = mu_k T`` (drive belt), so the strand tensions are
``T0`` and ``T1 = T0 exp(mu_k theta)``.  Equilibrium of the coiled arc gives
the contact load on the other yarn as the sum of the two strand pulls; in the
frame of the arc's bisector (normal) and the chord (tangent):

    R_chord    = (T1 - T0) cos(theta/2),
    R_bisector = (T1 + T0) sin(theta/2),

(:func:`drive_belt_resultant` integrates the distributed load numerically as
an independent check).  The drive-belt factor of eq 10 is therefore exact:

    (T1 - T0)/(T1 + T0) = (e^{mu theta} - 1)/(e^{mu theta} + 1) = tanh(mu theta/2).

The geometric factor printed in eq 10 is ``tan(theta/2)``, which is what the
resultant gives if ``theta`` in that factor is the angle between the two
strand directions (turning angle ``pi - theta``); the bisector
decomposition with turning angle ``theta`` gives ``cot(theta/2)``
(:func:`m_bisector`).  Both agree at ``theta = pi/2``.  We keep the printed
eq 10 (:func:`m_eq10`): it is the law the paper used (m grows from rest to
jamming), and its basalt value 0.17 is reproduced.  Its E-glass value at
110 deg is 0.212, not the paper's 0.20 (a deviation; 0.20 would need about
108 deg).

Eq 11, derivation
-----------------
Fig. 6c: in the jammed knit a quarter stitch is a straight piece ``d/2``
at the loop apex, an arc of centreline radius ``d`` (two touching yarns of
diameter ``d``) turning by ``theta`` around the interlocking yarn, and a
straight leg inclined at ``theta - pi/2`` to the wale direction that climbs
the rest of half a course, ``C/2 - d sin(theta - pi/2)``:

    L/4 = d/2 + theta d + (C/2 - d sin(theta - pi/2)) / cos(theta - pi/2).

The right side increases from ``d/2 + pi d/2 + C/2`` at ``theta = pi/2`` to
infinity at ``theta = pi`` (where the leg is horizontal), so the root in
``(pi/2, pi)`` is unique when ``L/4`` exceeds the left end; it is found with
``brentq``.  ``C`` is the course length of the jammed knit, which the paper
does not give; the knit's measured ``C0`` (2.7 mm) is the default reading.
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import quad, solve_ivp
from scipy.optimize import brentq

from ..errors import KnitsimInputError


def m_eq10(theta, mu_k):
    """Apparent tangential-to-normal ratio at the crossing (eq 10).

    Parameters
    ----------
    theta : float or array_like
        Coiling angle [rad].
    mu_k : float or array_like
        Coefficient of kinetic friction.

    Returns
    -------
    float or ndarray
        ``m = (e^{mu theta} - 1)/(e^{mu theta} + 1) * tan(theta/2)``.
    """
    theta = np.asarray(theta, dtype=float)
    _check_coiling(theta, mu_k, "m_eq10")
    e = np.exp(np.asarray(mu_k, dtype=float) * theta)
    # (e - 1)/(e + 1) = tanh(mu theta/2): the drive-belt factor (eq 1 on the arc)
    return (e - 1.0) / (e + 1.0) * np.tan(0.5 * theta)


def _check_coiling(theta, mu_k, where: str) -> None:
    """Refuse a coiling angle outside (0, pi) [rad] or a friction coefficient that is not >= 0: an angle in
    degrees by mistake (110) gave m = -45.2, a NaN hung the belt's integration (a blind probe)."""
    th = np.asarray(theta, dtype=float)
    mu = np.asarray(mu_k, dtype=float)
    if not np.all(np.isfinite(th) & (th > 0.0) & (th < np.pi)):
        bad = float(th[~(np.isfinite(th) & (th > 0.0) & (th < np.pi))].ravel()[0])
        hint = " (in degrees? use m_eq10_deg, or radians)" if np.isfinite(bad) and bad >= np.pi else ""
        raise KnitsimInputError(f"{where}: coiling angle theta = {bad!r} rad: expected 0 < theta < pi{hint}")
    if not np.all(np.isfinite(mu) & (mu >= 0.0)):
        bad = float(mu[~(np.isfinite(mu) & (mu >= 0.0))].ravel()[0])
        raise KnitsimInputError(f"{where}: mu_k = {bad!r}: expected a friction coefficient >= 0")


def m_eq10_deg(theta_deg, mu_k):
    """:func:`m_eq10` with the coiling angle in degrees (edge helper)."""
    return m_eq10(np.deg2rad(theta_deg), mu_k)


def m_bisector(theta, mu_k):
    """Alternative reading: ``Rt/Rn`` of the drive-belt resultant on the bisector frame.

    ``tanh(mu theta/2) cot(theta/2)`` (see the module docstring); equal to
    :func:`m_eq10` at ``theta = pi/2``.
    """
    theta = np.asarray(theta, dtype=float)
    return np.tanh(0.5 * np.asarray(mu_k, dtype=float) * theta) / np.tan(0.5 * theta)


def drive_belt_resultant(theta: float, mu_k: float, T0: float = 1.0) -> tuple[float, float, float]:
    """Contact load of a belt coiled by ``theta`` with friction ``mu_k``, by numerical integration.

    The tension along the arc is integrated from ``dT/dphi = mu_k T`` with
    ``solve_ivp``; the load per unit angle on the core, ``T (n + mu t)``, is
    then integrated with ``quad`` in the frame (chord, bisector).  Independent
    of the closed forms used in :func:`m_eq10`.

    Returns
    -------
    (R_chord, R_bisector, T1) : tuple of float
        Chord and bisector components of the contact load [N], end tension [N].
    """
    _check_coiling(theta, mu_k, "drive_belt_resultant")
    if not (np.isfinite(T0) and T0 > 0):
        raise KnitsimInputError(f"drive_belt_resultant: T0 = {T0!r}: expected a tension > 0 [N]")
    sol = solve_ivp(lambda phi, T: mu_k * T, (0.0, theta), [T0], dense_output=True, rtol=1e-12, atol=1e-14)

    def T(phi):
        return float(sol.sol(phi)[0])

    # polar angle alpha = phi - theta/2 from the bisector (+y); the yarn travels
    # along t = (cos a, -sin a).  Per unit angle the core receives the normal
    # pressure T toward its centre, -T (sin a, cos a), and the friction that
    # the yarn drags along, mu T t (the yarn's element balance T' = mu T).
    def fx(phi):
        a = phi - 0.5 * theta
        return T(phi) * (-np.sin(a) + mu_k * np.cos(a))

    def fy(phi):
        a = phi - 0.5 * theta
        return T(phi) * (-np.cos(a) - mu_k * np.sin(a))

    R_chord = quad(fx, 0.0, theta, epsabs=1e-13, epsrel=1e-13)[0]
    R_bis = -quad(fy, 0.0, theta, epsabs=1e-13, epsrel=1e-13)[0]
    return R_chord, R_bis, T(theta)


# --------------------------------------------------------------------------
# eq 11: coiling angle of the jammed knit
# --------------------------------------------------------------------------
def eq11_length(theta: float, C: float, d: float) -> float:
    """Right side of eq 11: quarter-stitch yarn length [mm] at coiling angle ``theta`` [rad]."""
    psi = theta - 0.5 * np.pi
    return 0.5 * d + theta * d + (0.5 * C - d * np.sin(psi)) / np.cos(psi)


def coiling_angle_jammed(L: float, C: float, d: float) -> float:
    """Coiling angle [rad] of the jammed knit: root of eq 11 in ``(pi/2, pi)``.

    Parameters
    ----------
    L : float
        Yarn length per stitch [mm].
    C : float
        Course length [mm] (the knit's ``C0`` unless the jammed value is known).
    d : float
        Yarn diameter [mm].
    """
    for name, v in (("L", L), ("C", C), ("d", d)):
        if not np.isfinite(v) or v <= 0.0:
            raise KnitsimInputError(f"{name} = {v!r}: must be a positive length in mm")
    if 0.5 * C <= d:
        raise KnitsimInputError(f"C = {C:g} mm: eq 11 needs C/2 > d = {d:g} mm")
    lo, hi = 0.5 * np.pi, np.pi - 1e-9
    f = lambda th: eq11_length(th, C, d) - 0.25 * L
    if f(lo) >= 0.0:
        raise KnitsimInputError(f"L = {L:g} mm: too short for eq 11 (L/4 must exceed {eq11_length(lo, C, d):.4g} mm)")
    while f(hi) <= 0.0:  # pragma: no cover - only for absurd inputs
        hi = 0.5 * (hi + np.pi)
    return brentq(f, lo, hi, xtol=1e-14)


def coiling_angle_jammed_deg(L: float, C: float, d: float) -> float:
    """:func:`coiling_angle_jammed` in degrees (edge helper)."""
    return float(np.rad2deg(coiling_angle_jammed(L, C, d)))
