"""Independent check of the quarter-stitch shape: direct integration of the rod equations.

Instead of the elastica integrals of eqs 8-9, integrate Euler-Bernoulli's
``B theta'(s) = m(s)``, where m(s) is the moment about the current point of the
loads on the part A..s of the quarter stitch::

    x' = cos(theta),  y' = sin(theta),
    m(s) = (r - r_A) x F_A + [s > s_B] (r - r_B) x R,
    F_A = -P (cos gamma, sin gamma),  R = R (sin(beta + phi), -cos(beta + phi)),
    R = -P sin(gamma) / cos(beta + phi)                        (eq 7)

from A (``r_A = 0``, ``theta = alpha``, m = 0: an inflection) to theta = beta
(event: point B), then with R added to theta = pi (event: apex C).  No first
integral, no substitution, no quadrature: a check of both.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp


@dataclass(frozen=True)
class OdeShape:
    """Shape from :func:`integrate_quarter_loop` (mm; A at the origin)."""

    s_AB: float
    s_BC: float
    x_B: float      #: X_B - X_A
    y_B: float      #: Y_B - Y_A = Y_B
    x_C: float      #: X_C - X_A
    y_C: float      #: Y_C
    curvature_C: float  #: theta'(C), so that B theta'(C) is the moment at C
    bending_energy: float = float("nan")  #: (B/2) int theta'^2 ds from A to C [N mm], accumulated along the rod

    @property
    def X_A(self) -> float:
        """X_A in the paper's frame (X_C = 0)."""
        return -self.x_C

    @property
    def X_B(self) -> float:
        """X_B in the paper's frame (X_C = 0)."""
        return self.x_B - self.x_C


def integrate_quarter_loop(alpha, beta, gamma, phi, P, B, *, rtol=1e-13, atol_rel=1e-15,
                           method="DOP853") -> OdeShape:
    """Integrate the rod from A to C with :func:`scipy.integrate.solve_ivp`.

    Parameters
    ----------
    alpha, beta, gamma, phi : float
        Angles [rad].
    P : float
        Force at A [N].
    B : float
        Bending stiffness [N mm^2].
    rtol, atol_rel : float
        Relative tolerance, and absolute tolerance in units of ``sqrt(B/P)``.
    method : str
        The :func:`scipy.integrate.solve_ivp` method (an explicit high-order Runge-Kutta by default).
    """
    alpha, beta, gamma, phi, P, B = (float(z) for z in (alpha, beta, gamma, phi, P, B))
    lam = np.sqrt(B / P)
    fa = -P * np.array([np.cos(gamma), np.sin(gamma)])
    r_mag = -P * np.sin(gamma) / np.cos(beta + phi)
    r_vec = r_mag * np.array([np.sin(beta + phi), -np.cos(beta + phi)])
    atol = atol_rel * lam

    def cross(u, f):
        return u[0] * f[1] - u[1] * f[0]

    def rhs_ab(_s, z):
        m = cross(z[:2], fa)
        return [np.cos(z[2]), np.sin(z[2]), m / B, 0.5 * m * m / B]

    def at_beta(_s, z):
        return z[2] - beta
    at_beta.terminal = True
    at_beta.direction = 1.0

    # the AB leg is ~ lam ln(1/(alpha - gamma)) long; give generous room
    s_max = lam * (50.0 + 4.0 * np.log(1.0 / max(alpha - gamma, 1e-300)))
    sol1 = solve_ivp(rhs_ab, (0.0, s_max), [0.0, 0.0, alpha, 0.0], method=method, rtol=rtol,
                     atol=atol, events=at_beta)
    if sol1.status != 1:
        raise RuntimeError("ode_check: theta never reached beta on AB")
    s_b = float(sol1.t_events[0][0])
    z_b = sol1.y_events[0][0]
    r_b = z_b[:2].copy()

    def rhs_bc(_s, z):
        m = cross(z[:2], fa) + cross(z[:2] - r_b, r_vec)
        return [np.cos(z[2]), np.sin(z[2]), m / B, 0.5 * m * m / B]

    def at_pi(_s, z):
        return z[2] - np.pi
    at_pi.terminal = True
    at_pi.direction = 1.0

    sol2 = solve_ivp(rhs_bc, (s_b, s_b + s_max), [z_b[0], z_b[1], beta, z_b[3]], method=method,
                     rtol=rtol, atol=atol, events=at_pi)
    if sol2.status != 1:
        raise RuntimeError("ode_check: theta never reached pi on BC")
    s_c = float(sol2.t_events[0][0])
    z_c = sol2.y_events[0][0]
    m_c = cross(z_c[:2], fa) + cross(z_c[:2] - r_b, r_vec)
    return OdeShape(s_AB=s_b, s_BC=s_c - s_b, x_B=float(r_b[0]), y_B=float(r_b[1]),
                    x_C=float(z_c[0]), y_C=float(z_c[1]), curvature_C=float(m_c / B), bending_energy=float(z_c[3]))
