"""Forward map of the quarter stitch: angles and force -> every quantity (Dusserre 2015 eqs 6-9).

Given the four angles (alpha, beta, gamma, phi), the force P at A, the bending
stiffness B and the yarn diameter d, the shape of the quarter stitch A -> B -> C
is fixed (eqs 8-9, :mod:`knitsim.cell.elastica`) and so is every quantity of
:mod:`knitsim.cell.quantities`.  Frame and signs as in ``docs/model.md``.

Equilibrium of the quarter stitch (eq 7, derived here): the loads are
``-P (cos gamma, sin gamma)`` at A, ``R (sin(beta + phi), -cos(beta + phi))`` at B
(the contact force makes the angle phi with -n, n = (-sin beta, cos beta) the
normal toward the interlocking yarn) and ``(P k1', 0)`` at C (symmetry: no
vertical force on the cut through the apex).  Force balance gives::

    R_Y = -R cos(beta + phi) = P sin(gamma)
    R_X =  R sin(beta + phi) = -P sin(gamma) tan(beta + phi)
    k1' = cos(gamma) + sin(gamma) tan(beta + phi),   T = -P k1'

and the moment about C gives ``M = P (y0_AB + k1' (Y_C - Y_B))``, which equals
``B theta'(C)`` of the elastica (checked in the tests).  Geometry (eq 6)::

    W / 4 = X_B - (d/2) sin(beta)
    C / 2 = Y_B + (d/2) cos(beta)
    g     = X_B - X_A - (d/2) sin(beta)       (intrinsic condition, = 0 at equilibrium)
    L / 4 = s_AB + s_BC

X_A is computed from the shape, X_A = X_B - (x0 cos gamma - y0 sin gamma), so
``g = 0`` is the statement X_A = W/4.  Since every length is ``sqrt(B/P)`` times a
function of the angles, ``g = 0`` fixes P once the angles are given
(:func:`closing_force`).
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from knitsim.cell import elastica
from knitsim.cell.quantities import QUANTITY_NAMES


@dataclass(frozen=True)
class QuarterLoop:
    """Every quantity of one (or an array of) quarter-stitch states.

    Fields named as in :data:`knitsim.cell.quantities.QUANTITY_NAMES`, plus
    ``k1p`` (k1', eq 7), ``g`` (the intrinsic residual of eq 6, mm) and
    ``admissible`` (theta increases monotonically from A to C; where False all
    derived quantities are NaN).  Units: N, mm, rad.
    """

    alpha: np.ndarray
    beta: np.ndarray
    gamma: np.ndarray
    phi: np.ndarray
    P: np.ndarray
    W: np.ndarray
    C: np.ndarray
    L: np.ndarray
    s_AB: np.ndarray
    s_BC: np.ndarray
    X_A: np.ndarray
    X_B: np.ndarray
    Y_B: np.ndarray
    Y_C: np.ndarray
    T: np.ndarray
    M: np.ndarray
    R: np.ndarray
    Rn: np.ndarray
    Rt: np.ndarray
    F: np.ndarray
    k1p: np.ndarray
    g: np.ndarray
    admissible: np.ndarray

    def as_dict(self) -> dict[str, np.ndarray]:
        """The quantities of :data:`QUANTITY_NAMES`, by name."""
        return {name: getattr(self, name) for name in QUANTITY_NAMES}

    def quantity(self, name: str) -> np.ndarray:
        """One quantity by its name in :data:`QUANTITY_NAMES`."""
        if name not in QUANTITY_NAMES:
            raise KeyError(f"unknown quantity {name!r}; known: {', '.join(QUANTITY_NAMES)}")
        return getattr(self, name)


def k1_prime(beta, gamma, phi):
    """``k1' = cos(gamma) + sin(gamma) tan(beta + phi)`` (eq 7); k1 when phi = 0."""
    return np.cos(gamma) + np.sin(gamma) * np.tan(beta + phi)


def _admissible(a, beta, u_b, delta, d0):
    """theta increases monotonically A -> B -> C (see :mod:`elastica`)."""
    return ((a > 0.0) & (a < np.pi) & (u_b < 2.0 * np.pi - a) & (delta > 0.0)
            & (beta < np.pi) & (d0 > 0.0))


def _shape(alpha, beta, gamma, phi, a, rho=None):
    """Dimensionless shape (units sqrt(B/P)) and admissibility."""
    alpha, beta, gamma, phi = np.broadcast_arrays(
        *(np.asarray(z, dtype=np.float64) for z in (alpha, beta, gamma, phi)))
    a = (alpha - gamma) if a is None else np.broadcast_to(np.asarray(a, dtype=np.float64),
                                                          alpha.shape)
    u_b = beta - gamma
    if rho is None:
        k1p = k1_prime(beta, gamma, phi)
    else:
        # R / P given: k1' = cos(gamma) - (R/P) sin(beta + phi), no 0/0 at beta + phi = pi/2
        k1p = np.cos(gamma) - rho * np.sin(beta + phi)
    delta = elastica.bc_delta(a, u_b)
    d0 = elastica.bc_D(0.0, np.pi - beta, delta, k1p)
    ok = _admissible(a, beta, u_b, delta, d0)
    # evaluate on a harmless state where inadmissible, then mask with NaN
    a_s = np.where(ok, a, 0.5)
    ub_s = np.where(ok, u_b, 1.0)
    s_ab, x0, y0 = elastica.ab_integrals(a_s, ub_s)
    s_bc, x_bc, y_bc = elastica.bc_integrals(np.where(ok, beta, 2.0), np.where(ok, delta, 1.0),
                                             np.where(ok, k1p, 1.0))
    nan = np.nan
    return dict(alpha=alpha, beta=beta, gamma=gamma, phi=phi, a=a, k1p=k1p, d0=d0, ok=ok,
                s_ab=np.where(ok, s_ab, nan), x0=np.where(ok, x0, nan),
                y0=np.where(ok, y0, nan), s_bc=np.where(ok, s_bc, nan),
                x_bc=np.where(ok, x_bc, nan), y_bc=np.where(ok, y_bc, nan))


def closing_force(alpha, beta, gamma, phi, B, d, *, a=None):
    """The force P that satisfies the intrinsic condition g = 0 (eq 6, third line).

    ``X_B - X_A = sqrt(B/P) (x0 cos gamma - y0 sin gamma)/sqrt(B/P)`` must equal
    ``(d/2) sin(beta)``, so ``P = B (2 xhat / (d sin beta))^2``; NaN where
    inadmissible or where ``xhat <= 0`` (B would lie left of A).
    """
    sh = _shape(alpha, beta, gamma, phi, a)
    xhat = sh["x0"] * np.cos(sh["gamma"]) - sh["y0"] * np.sin(sh["gamma"])
    target = 0.5 * d * np.sin(sh["beta"])
    p = B * (xhat / target) ** 2
    return np.where((xhat > 0.0) & (target > 0.0), p, np.nan)


def stored_energy(alpha, beta, gamma, phi, P, B, *, a=None, rho=None):
    """Bending energy ``U = (B/2) int_A^C theta'^2 ds`` of the quarter stitch [N mm] (NaN where inadmissible).

    From the first integrals of eqs 8-9 (:mod:`knitsim.cell.elastica`), ``(B/2) theta'^2 = P (cos a - cos u)``
    on AB and ``P D(v)`` on BC, the integrals of the shape give it in closed form::

        U / (P sqrt(B/P)) = s_AB cos(a) - x0_AB + (delta - k1' cos v_B) s_BC + k1' x_BC

    (``x0_AB = int cos u ds``, ``x_BC = int cos v ds``, in units sqrt(B/P)).  A stitch holds four quarter
    stitches.  What it is for: the work put into a stitch, ``int F dC`` per wale, is its stored energy
    ``4 U`` plus what friction dissipated; on a path without slip the work must equal ``4 dU``
    (virtual work), and over any path the dissipation ``int F dC - 4 dU`` cannot fall
    (:func:`knitsim.io.checks.energy_balance`).  ``a`` and ``rho`` as for :func:`quarter_loop`.
    """
    sh = _shape(alpha, beta, gamma, phi, a, rho)
    P = np.asarray(P, dtype=np.float64)
    u_b = sh["beta"] - sh["gamma"]
    delta = elastica.bc_delta(sh["a"], u_b)
    v_b = np.pi - sh["beta"]
    dimless = (sh["s_ab"] * np.cos(sh["a"]) - sh["x0"] + (delta - sh["k1p"] * np.cos(v_b)) * sh["s_bc"]
               + sh["k1p"] * sh["x_bc"])
    return P * np.sqrt(np.asarray(B, dtype=np.float64) / P) * dimless


def stitch_energy(alpha, beta, gamma, phi, P, B):
    """Bending energy stored in one stitch [N mm]: its four quarter stitches (:func:`stored_energy`)."""
    return 4.0 * stored_energy(alpha, beta, gamma, phi, P, B)


def stitch_energy_along(x_rest, x_rows, B: float):
    """``k ->`` :func:`stitch_energy` at row k of a path whose row 0 is the rest state ``x_rest`` and row
    k > 0 is ``x_rows[k - 1]`` (each (alpha, beta, gamma, phi, P)): what
    :func:`knitsim.io.checks.energy_creating_loops` asks for (``stored_at``), evaluated only where asked."""
    def at(k: int) -> float:
        return float(stitch_energy(*(x_rest if k == 0 else x_rows[k - 1]), B))
    return at


def quarter_loop(alpha, beta, gamma, phi, P, B, d, *, a=None, rho=None) -> QuarterLoop:
    """Forward map: angles and force -> :class:`QuarterLoop` (eqs 6-9).

    Parameters
    ----------
    alpha, beta, gamma, phi : array_like
        Angles [rad] (see :mod:`knitsim.cell.quantities`); broadcast together.
    P : array_like
        Force at A [N], > 0.
    B : float
        Bending stiffness [N mm^2].
    d : float
        Yarn diameter [mm].
    a : array_like, optional
        ``alpha - gamma`` given directly, at full relative precision (high load);
        ``alpha`` is then only used for output.
    rho : array_like, optional
        ``R / P`` given directly (with ``sin(gamma) = -rho cos(beta + phi)``), so
        that R and k1' stay defined where ``beta + phi = pi/2`` and gamma = 0
        (horizontal contact force at zero force per wale).

    Returns
    -------
    QuarterLoop
        The state; ``g`` is the residual of the intrinsic condition (0 at equilibrium).
    """
    sh = _shape(alpha, beta, gamma, phi, a, rho)
    alpha, beta, gamma, phi = sh["alpha"], sh["beta"], sh["gamma"], sh["phi"]
    P = np.asarray(P, dtype=np.float64)
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        # (a trial point of a solver at P -> 0 gives inf lengths, which it rejects: no warning on the console,
        # where a blind probe's d = 1e-4 cell printed NumPy's before its refusal)
        lam = np.sqrt(B / P)                               # lengths scale with sqrt(B/P)
    s_ab = lam * sh["s_ab"]
    x0 = lam * sh["x0"]
    y0 = lam * sh["y0"]
    s_bc = lam * sh["s_bc"]
    x_b = lam * sh["x_bc"]                                 # X_C = 0: apex on the axis
    y_bc = lam * sh["y_bc"]
    cg, sg = np.cos(gamma), np.sin(gamma)
    x_ab = x0 * cg - y0 * sg                               # eq 8: rotate by gamma
    y_b = x0 * sg + y0 * cg
    x_a = x_b - x_ab
    y_c = y_b + y_bc
    k1p = sh["k1p"]
    half_d = 0.5 * d
    # eq 7, R_Y = -R cos(beta + phi) = P sin gamma
    r = -P * sg / np.cos(beta + phi) if rho is None else P * np.asarray(rho, dtype=np.float64)
    return QuarterLoop(
        alpha=alpha, beta=beta, gamma=gamma, phi=phi, P=P * np.ones_like(alpha),
        W=4.0 * (x_b - half_d * np.sin(beta)),             # eq 6
        C=2.0 * (y_b + half_d * np.cos(beta)),
        L=4.0 * (s_ab + s_bc),
        s_AB=s_ab, s_BC=s_bc, X_A=x_a, X_B=x_b, Y_B=y_b, Y_C=y_c,
        T=-P * k1p,
        M=P * (y0 + k1p * y_bc),
        R=r, Rn=r * np.cos(phi), Rt=r * np.sin(phi),
        F=2.0 * P * sg,                                    # two legs per wale cut
        k1p=k1p,
        g=x_ab - half_d * np.sin(beta),
        admissible=sh["ok"],
    )


def intrinsic_residual(alpha, beta, gamma, phi, P, B, d, *, a=None):
    """``g = X_B - X_A - (d/2) sin(beta)`` [mm] (eq 6, third line)."""
    return quarter_loop(alpha, beta, gamma, phi, P, B, d, a=a).g


def _partial_gl(f, upper, n):
    """``int_0^upper f`` for each entry of the 1-D array ``upper`` (Gauss-Legendre)."""
    xg, wg = elastica.gauss_legendre_01(n)
    nodes = upper[:, None] * xg
    return np.sum(wg * f(nodes), axis=-1) * upper


def centreline(alpha, beta, gamma, phi, P, B, d, n_points: int = 201, *, a=None):
    """Points of the yarn axis from A through B to C (scalar state).

    The elastica is integrated along s with the substitution variables of
    :mod:`elastica` (graded toward A at high load), so points are denser where
    the curvature changes fast.

    Returns
    -------
    dict
        ``s``, ``X``, ``Y``, ``theta`` (1-D arrays, A first, C last) and ``i_B``,
        the index of B.
    """
    state = quarter_loop(alpha, beta, gamma, phi, P, B, d, a=a)
    if not bool(np.all(state.admissible)):
        raise ValueError("centreline: inadmissible state (theta not monotone from A to C)")
    alpha, beta, gamma, phi, P = (float(np.asarray(z)) for z in (alpha, beta, gamma, phi, P))
    a = alpha - gamma if a is None else float(a)
    lam = np.sqrt(B / P)
    u_b = beta - gamma
    n_ab = max(2, n_points // 2)
    n_bc = max(2, n_points - n_ab)
    n = elastica.N_AB

    # --- AB, parametrised by chi = pi/2 - psi (see elastica.ab_integrals)
    sin_psi_b, cos_psi_b, k, kp = elastica._psi_b(np.float64(a), np.float64(u_b))
    chi_b = float(np.arctan2(cos_psi_b, sin_psi_b))
    chi_1 = min(chi_b, 0.25 * np.pi)
    t1 = float(np.arcsinh(np.tan(chi_1) / kp))
    n1 = max(2, int(round(n_ab * (0.5 if chi_b > chi_1 else 1.0))))
    t = np.linspace(0.0, t1, n1)
    ff = lambda tt: 1.0 / np.sqrt(1.0 + (kp * np.sinh(tt)) ** 2)
    fe = lambda tt: (kp * np.cosh(tt)) ** 2 / (1.0 + (kp * np.sinh(tt)) ** 2) ** 1.5
    f_part = _partial_gl(ff, t, n)
    e_part = _partial_gl(fe, t, n)
    chi = np.arctan(kp * np.sinh(t))
    if chi_b > chi_1:
        chi2 = np.linspace(chi_1, chi_b, n_ab - n1 + 1)[1:]
        dl = lambda c: np.sqrt(kp * kp + (k * np.sin(c)) ** 2)
        span = chi2 - chi_1
        f2 = _partial_gl(lambda z: 1.0 / dl(chi_1 + z), span, n)
        e2 = _partial_gl(lambda z: dl(chi_1 + z), span, n)
        f_part = np.concatenate([f_part, f_part[-1] + f2])
        e_part = np.concatenate([e_part, e_part[-1] + e2])
        chi = np.concatenate([chi, chi2])
    s_ab = lam * f_part
    x0 = lam * (f_part - 2.0 * e_part)
    y0 = lam * 2.0 * k * np.sin(chi)                       # cos(psi) = sin(chi)
    u = 2.0 * np.arccos(np.clip(k * np.cos(chi), -1.0, 1.0))
    u[0] = a
    cg, sg = np.cos(gamma), np.sin(gamma)
    x_ab = state.X_A + x0 * cg - y0 * sg
    y_ab = x0 * sg + y0 * cg
    th_ab = gamma + u

    # --- BC, parametrised by eta, v = v_B cos(eta)
    v_b = np.pi - beta
    delta = float(elastica.bc_delta(a, u_b))
    k1p = float(state.k1p)

    def w(e):
        dv = delta + 2.0 * k1p * np.sin(0.5 * v_b * (1.0 + np.cos(e))) \
            * np.sin(v_b * np.sin(0.5 * e) ** 2)
        return v_b * np.sin(e) / np.sqrt(2.0 * dv)

    eta = np.linspace(0.0, 0.5 * np.pi, n_bc + 1)[1:]
    s_bc = lam * _partial_gl(w, eta, elastica.N_BC)
    x_bc = lam * _partial_gl(lambda e: w(e) * np.cos(v_b * np.cos(e)), eta, elastica.N_BC)
    y_bc = lam * _partial_gl(lambda e: w(e) * np.sin(v_b * np.cos(e)), eta, elastica.N_BC)
    x_b, y_b = float(state.X_B), float(state.Y_B)
    s_b = s_ab[-1]
    return dict(
        s=np.concatenate([s_ab, s_b + s_bc]),
        X=np.concatenate([x_ab, x_b - x_bc]),              # dX/ds = cos(theta) = -cos(v)
        Y=np.concatenate([y_ab, y_b + y_bc]),
        theta=np.concatenate([th_ab, np.pi - v_b * np.cos(eta)]),
        i_B=len(s_ab) - 1,
    )
