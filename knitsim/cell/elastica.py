"""Elastica integrals of the quarter stitch (Hong et al. 2002; Dusserre 2015 eqs 8-9).

Every length of the quarter stitch is ``lam = sqrt(B / P)`` times a dimensionless
integral that depends on the angles only; this module computes those
dimensionless integrals.  Notation (see :mod:`knitsim.cell.quantities`):

``a = alpha - gamma`` and ``u_B = beta - gamma``
    tangent angle relative to the line of action of P, at A and at B;
``k = cos(a / 2)``, ``k' = sin(a / 2)``
    elliptic modulus of segment AB and its complement;
``v = pi - theta``
    on BC, ``v`` runs from ``v_B = pi - beta`` at B to 0 at C;
``c = k1'``
    the horizontal resultant at C divided by P (eq 7).

Segment AB (eq 8).  The moment of the load at A about the section gives
``B theta'' = P sin(theta - gamma)`` with ``theta'(A) = 0`` (A is an inflection),
whose first integral is ``theta'^2 = (4 P / B) [cos^2(a/2) - cos^2(u/2)]``,
``u = theta - gamma``.  theta increases monotonically from alpha while
``a < u < 2 pi - a``; ``u`` may pass pi (the rod passes the direction of -P),
the substitution below covers that.  With ``cos(u/2) = k sin(psi)``
(psi from pi/2 at A down to ``psi_B``, negative when ``u_B > pi``)::

    s_AB / lam = int_{psi_B}^{pi/2} dpsi / Delta,      Delta = sqrt(1 - k^2 sin^2 psi)
    x0_AB / lam = s_AB / lam - 2 int Delta dpsi          (cos u = 1 - 2 Delta^2)
    y0_AB / lam = 2 k cos(psi_B)                         (sin u ds = (B/P) dtheta')

(x0, y0) are the components of AB along and across the line of action of P;
the 1/sqrt singularity of eq 8 at A is gone.  When ``a -> 0`` (high load) the
integrand ``1/Delta`` peaks near A with height ``1/k'``; with
``chi = pi/2 - psi`` and ``tan(chi) = k' sinh(t)`` the AB integrands become
``1 / sqrt(1 + k'^2 sinh^2 t)`` and ``k'^2 cosh^2 t / (1 + k'^2 sinh^2 t)^(3/2)``,
smooth on ``t`` in ``[0, asinh(tan(chi_1)/k')]``, only logarithmically long.  The
AB interval is split at ``chi_1 = min(chi_B, pi/4)``: t-variable below, plain chi
above (where Delta >= sqrt(1/2)).

Segment BC (eq 9).  Beyond B the resultant of P and R is horizontal,
``(-P k1', 0)`` on the part A..s, so ``B theta'' = P k1' sin(theta)``; theta' is
continuous at B (a point force carries no moment), which gives::

    theta'^2 = (2 P / B) D(v),   D(v) = delta + k1' (cos v - cos v_B),
    delta = cos(a) - cos(u_B) = D(v_B)   (curvature at B from eq 8).

The extracted eq 9 prints ``-k1 cos(beta)`` where this reading has
``+k1' cos(beta)`` (= ``-k1' cos(v_B)``): with the printed sign the curvature
jumps at B.  theta increases monotonically on BC iff D > 0 on ``[0, v_B]``; since
D is monotone in v there, it suffices that ``D(0) > 0`` (a positive moment at C)
and ``delta > 0`` (beta > alpha).  The substitution ``v = v_B cos(eta)``,
eta from 0 at B to pi/2 at C, removes the 1/sqrt singularity that appears at B
when ``delta -> 0``::

    s_BC / lam = int_0^{pi/2} v_B sin(eta) / sqrt(2 D) deta
    X_B / lam  = int cos(v) ...,   (Y_C - Y_B) / lam = 2 (1 - cos v_B) / (sqrt(2 D(0)) + sqrt(2 delta))

(the last in closed form from ``B theta'' = P k1' sin(v)``, written without a
division by k1').  The other end, C, becomes nearly singular only when the moment
at the apex vanishes (``D(0) -> 0``); this is not graded, and the accuracy there
is given with :data:`N_BC`.

All quadratures are Gauss-Legendre with a fixed node count (module constants
below, chosen by the convergence study in ``tests/cell/test_elastica.py``).
Inputs broadcast as NumPy arrays; nodes run along a trailing axis.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.special import elliprd, elliprf

#: Gauss-Legendre nodes on each of the two AB pieces.  Convergence study (max
#: error relative to s_AB vs the Carlson closed forms, 2000 random states,
#: a = alpha - gamma log-uniform in [1e-8, 2], beta - alpha in [0.01, 3.5]):
#: 16 nodes 1.5e-6, 24 2.7e-9, 32 4.9e-12, 40 1.0e-14, 48 2.9e-15.
N_AB = 40
#: Gauss-Legendre nodes on BC (eta variable).  Convergence study (max error
#: relative to s_BC vs Carlson, random beta, k1' in [-0.3, 3]): with delta and
#: D(0) both > 0.05: 24 nodes 5e-11, 32 5e-14, 40 3e-15; both > 0.01: 40 1e-12,
#: 48 3e-14; both > 1e-3: 48 4e-9, 64 1e-11, 96 1e-14.  The end C (D(0) -> 0,
#: vanishing moment at the apex) is not graded: see the module docstring.
N_BC = 48


@lru_cache(maxsize=None)
def gauss_legendre_01(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on [0, 1] (``n`` points)."""
    x, w = np.polynomial.legendre.leggauss(int(n))
    x = 0.5 * (x + 1.0)
    w = 0.5 * w
    x.setflags(write=False)
    w.setflags(write=False)
    return x, w


def _psi_b(a, u_b):
    """``(sin psi_B, cos psi_B, k, k')`` for ``cos(u_B/2) = k sin(psi_B)``, accurately."""
    k = np.cos(0.5 * a)
    kp = np.sin(0.5 * a)
    sin_psi_b = np.cos(0.5 * u_b) / k
    # k^2 - cos^2(u_B/2) = sin((u_B - a)/2) sin((u_B + a)/2): no cancellation when beta ~ alpha
    cos_psi_b = np.sqrt(np.maximum(np.sin(0.5 * (u_b - a)) * np.sin(0.5 * (u_b + a)), 0.0)) / k
    return sin_psi_b, cos_psi_b, k, kp


def ab_integrals(a, u_b, n: int = N_AB):
    """Dimensionless integrals of segment AB (eq 8), in units of ``sqrt(B/P)``.

    Parameters
    ----------
    a : array_like
        ``alpha - gamma`` [rad], in (0, pi); passed separately so that it keeps
        full relative precision at high load, where it falls toward 1e-7.
    u_b : array_like
        ``beta - gamma`` [rad], with ``a < u_b < 2 pi - a``.
    n : int
        Gauss-Legendre nodes on each of the two pieces.

    Returns
    -------
    s, x0, y0 : ndarray
        ``s_AB``, and the components of vector AB along (cos gamma, sin gamma)
        and across (-sin gamma, cos gamma), all divided by ``sqrt(B/P)``.
    """
    a = np.asarray(a, dtype=np.float64)
    u_b = np.asarray(u_b, dtype=np.float64)
    a, u_b = np.broadcast_arrays(a, u_b)
    sin_psi_b, cos_psi_b, k, kp = _psi_b(a, u_b)
    chi_b = np.arctan2(cos_psi_b, sin_psi_b)          # pi/2 - psi_B, in [0, pi)
    chi_1 = np.minimum(chi_b, 0.25 * np.pi)
    xg, wg = gauss_legendre_01(n)

    # piece 1: chi in [0, chi_1] through tan(chi) = k' sinh(t)
    t1 = np.arcsinh(np.tan(chi_1) / kp)[..., None]
    t = t1 * xg
    kp_ = kp[..., None]
    sh = kp_ * np.sinh(t)
    ch = kp_ * np.cosh(t)
    q = 1.0 + sh * sh
    f1 = np.sum(wg / np.sqrt(q), axis=-1) * t1[..., 0]
    e1 = np.sum(wg * ch * ch / (q * np.sqrt(q)), axis=-1) * t1[..., 0]

    # piece 2: chi in [chi_1, chi_B], Delta = sqrt(k'^2 + k^2 sin^2 chi) >= sqrt(1/2) here
    span = (chi_b - chi_1)[..., None]
    chi = chi_1[..., None] + span * xg
    delta = np.sqrt(kp_ * kp_ + (k[..., None] * np.sin(chi)) ** 2)
    f2 = np.sum(wg / delta, axis=-1) * span[..., 0]
    e2 = np.sum(wg * delta, axis=-1) * span[..., 0]

    s = f1 + f2
    x0 = s - 2.0 * (e1 + e2)
    y0 = 2.0 * k * cos_psi_b
    return s, x0, y0


def bc_delta(a, u_b):
    """``delta = cos(a) - cos(u_B)``: (B / 2P) theta'(B)^2, written without cancellation."""
    return 2.0 * np.sin(0.5 * (np.asarray(u_b) - a)) * np.sin(0.5 * (np.asarray(u_b) + a))


def bc_D(v, v_b, delta, k1p):
    """``D(v) = delta + k1' (cos v - cos v_B)`` = (B / 2P) theta'^2 on BC (eq 9)."""
    return delta + 2.0 * k1p * np.sin(0.5 * (v_b + v)) * np.sin(0.5 * (v_b - v))


def bc_integrals(beta, delta, k1p, n: int = N_BC):
    """Dimensionless integrals of segment BC (eq 9), in units of ``sqrt(B/P)``.

    Parameters
    ----------
    beta : array_like
        tangent angle at B [rad], in (0, pi).
    delta : array_like
        ``cos(alpha - gamma) - cos(beta - gamma)`` (see :func:`bc_delta`), > 0.
    k1p : array_like
        ``k1' = cos gamma + sin gamma tan(beta + phi)`` (eq 7).
    n : int
        Gauss-Legendre nodes.

    Returns
    -------
    s, x, y : ndarray
        ``s_BC``, ``X_B - X_C = X_B`` and ``Y_C - Y_B``, divided by ``sqrt(B/P)``.
    """
    beta, delta, k1p = np.broadcast_arrays(*(np.asarray(z, dtype=np.float64)
                                             for z in (beta, delta, k1p)))
    v_b = np.pi - beta
    xg, wg = gauss_legendre_01(n)
    eta = 0.5 * np.pi * xg
    vb_ = v_b[..., None]
    half = 0.5 * vb_
    v = vb_ * np.cos(eta)
    # D written with v_B - v = 2 v_B sin^2(eta/2), exact near B
    d_v = delta[..., None] + 2.0 * k1p[..., None] * np.sin(half * (1.0 + np.cos(eta))) \
        * np.sin(vb_ * np.sin(0.5 * eta) ** 2)
    w = (0.5 * np.pi) * wg * vb_ * np.sin(eta) / np.sqrt(2.0 * d_v)
    s = np.sum(w, axis=-1)
    x = np.sum(w * np.cos(v), axis=-1)
    d0 = bc_D(0.0, v_b, delta, k1p)
    y = 2.0 * (1.0 - np.cos(v_b)) / (np.sqrt(2.0 * d0) + np.sqrt(2.0 * delta))
    return s, x, y


# --------------------------------------------------------------------------
# Closed forms in Carlson's symmetric integrals: an independent check.
# F(phi|m) = sin(phi) R_F(cos^2 phi, 1 - m sin^2 phi, 1)
# int_0^phi sin^2 / sqrt(1 - m sin^2) = sin^3(phi) / 3 R_D(cos^2 phi, 1 - m sin^2 phi, 1)
# --------------------------------------------------------------------------

def _carlson_f_and_d(sin_phi, cos_phi, m, mc=None):
    """``F(phi|m)`` and ``D(phi|m)`` from sin and cos of phi (exact at phi = pi/2);
    ``mc = 1 - m`` given exactly where m ~ 1."""
    s = sin_phi
    c2 = cos_phi * cos_phi
    dd = 1.0 - m * s * s if mc is None else c2 + mc * s * s
    return s * elliprf(c2, dd, 1.0), s ** 3 / 3.0 * elliprd(c2, dd, 1.0)


def ab_integrals_carlson(a, u_b):
    """Same as :func:`ab_integrals` through Legendre's F and E in Carlson form.

    ``int_{psi_B}^{pi/2} dpsi/Delta = K(k) - F(psi_B|k^2)`` and
    ``int Delta = (K - F) - k^2 (D_K - D(psi_B))`` with ``D(phi) = int sin^2/Delta``.
    """
    a = np.asarray(a, dtype=np.float64)
    u_b = np.asarray(u_b, dtype=np.float64)
    sin_psi_b, cos_psi_b, k, kp = _psi_b(a, u_b)
    m = k * k
    # cos(pi/2) must be exactly 0 here: R_F(x, k'^2, 1) moves by O(sqrt(x)/k')
    f_k, d_k = _carlson_f_and_d(1.0, 0.0, m, kp * kp)
    f_b, d_b = _carlson_f_and_d(sin_psi_b, cos_psi_b, m, kp * kp)
    f = f_k - f_b
    e = f - m * (d_k - d_b)
    return f, f - 2.0 * e, 2.0 * k * cos_psi_b


def bc_integrals_carlson(beta, delta, k1p):
    """Same as :func:`bc_integrals` through Carlson's R_F and R_D.

    With ``w = v/2``: ``2 D = 2 D(0) (1 - m sin^2 w)``, ``m = 2 k1' / D(0)``, so
    ``s_BC = sqrt(2 / D(0)) F(v_B/2 | m)`` and ``X_B = sqrt(2/D(0)) (F - 2 D(v_B/2|m))``.
    """
    beta = np.asarray(beta, dtype=np.float64)
    v_b = np.pi - beta
    d0 = bc_D(0.0, v_b, delta, k1p)
    m = 2.0 * k1p / d0
    f, dd = _carlson_f_and_d(np.sin(0.5 * v_b), np.cos(0.5 * v_b), m)
    scale = np.sqrt(2.0 / d0)
    y = 2.0 * (1.0 - np.cos(v_b)) / (np.sqrt(2.0 * d0) + np.sqrt(2.0 * delta))
    return scale * f, scale * (f - 2.0 * dd), y
