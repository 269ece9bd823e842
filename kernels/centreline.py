"""Quarter-stitch centrelines of many cells at once (Dusserre 2015 eqs 8-9), float64 Warp.

Warp twin of :func:`knitsim.cell.quarter_loop.centreline` (the float64 NumPy
reference, its test oracle): the same substitution variables, the same
Gauss-Legendre rules and the same sample points, so the two agree to rounding.

For each cell, from the state (alpha, beta, gamma, phi, P) and the bending
stiffness B, with ``lam = sqrt(B/P)``, ``a = alpha - gamma``, ``u_B = beta - gamma``,
``k = cos(a/2)``, ``k' = sin(a/2)`` (see :mod:`knitsim.cell.elastica`):

- AB (eq 8) is sampled in ``chi = pi/2 - psi``.  Below ``chi_1 = min(chi_B, pi/4)``
  through ``tan(chi) = k' sinh(t)``, ``t`` uniform on ``[0, asinh(tan(chi_1)/k')]``
  (graded toward A at high load), above it uniform in chi up to chi_B.  At each
  sample the partial integrals ``f = int dpsi/Delta`` and ``e = int Delta dpsi``
  from A are Gauss-Legendre rules on ``[0, t]`` (resp. ``[chi_1, chi]``), and
  ``s = lam f``, ``x0 = lam (f - 2 e)``, ``y0 = 2 lam k sin(chi)`` in the frame
  turned by gamma; ``(X, Y) = (X_A + x0 cos g - y0 sin g, x0 sin g + y0 cos g)``.
- BC (eq 9) is sampled in ``eta`` uniform on ``(0, pi/2]``, ``v = v_B cos(eta)``,
  ``v_B = pi - beta``; the partial integrals of ``w = v_B sin(eta) / sqrt(2 D)``,
  ``w cos v`` and ``w sin v`` give ``s - s_B``, ``X_B - X`` and ``Y - Y_B``.
- ``X_B`` is the full BC integral of ``w cos v`` (the apex C lies on X = 0) and
  ``X_A = X_B - (X_B - X_A)`` from AB.

Points: ``n_ab`` on AB (A first, B last) and ``n_bc`` after B on BC (C last).
The sample counts follow the reference: ``n_ab = max(2, n // 2)``,
``n_bc = n - n_ab``, and when AB has a plain-chi piece the graded piece gets
``round(n_ab / 2)`` (Python rounding) of the AB points; the host passes both
counts.  An inadmissible state (theta not monotone A -> C) gives NaN points and
``ok = 0``.
"""
from __future__ import annotations

import warp as wp

wp.set_module_options({"max_unroll": 1})

_PI = wp.constant(wp.float64(3.141592653589793))


@wp.func
def _asinh_pos(x: wp.float64):
    # asinh(x) for x >= 0; log(x + sqrt(1 + x^2)) loses nothing for the x used here
    return wp.log(x + wp.sqrt(wp.float64(1.0) + x * x))


@wp.func
def _bc_dv(e: wp.float64, v_b: wp.float64, delta: wp.float64, k1p: wp.float64):
    # D(v) at v = v_B cos(eta), with v_B - v = 2 v_B sin^2(eta/2) (exact near B), elastica.bc_D
    s2 = wp.sin(wp.float64(0.5) * e)
    return delta + wp.float64(2.0) * k1p * wp.sin(wp.float64(0.5) * v_b * (wp.float64(1.0) + wp.cos(e))) \
        * wp.sin(v_b * s2 * s2)


@wp.kernel
def centreline_kernel(x: wp.array2d(dtype=wp.float64), B: wp.array(dtype=wp.float64),
                      d: wp.array(dtype=wp.float64),
                      xg_ab: wp.array(dtype=wp.float64), wg_ab: wp.array(dtype=wp.float64),
                      xg_bc: wp.array(dtype=wp.float64), wg_bc: wp.array(dtype=wp.float64),
                      n_ab: int, n1_split: int, n_bc: int,
                      s_out: wp.array2d(dtype=wp.float64), xy_out: wp.array3d(dtype=wp.float64),
                      cell_out: wp.array2d(dtype=wp.float64), ok_out: wp.array(dtype=wp.int32)):
    """Centreline of cell i: ``s_out[i, :]`` [mm], ``xy_out[i, :, 0:2]`` = (X, Y) [mm],
    ``cell_out[i] = (W, C, s_AB, Y_C)`` [mm] from the same integrals (eq 6), ``ok_out[i]``."""
    i = wp.tid()
    one = wp.float64(1.0)
    half = wp.float64(0.5)
    two = wp.float64(2.0)
    alpha = x[i, 0]
    beta = x[i, 1]
    gamma = x[i, 2]
    phi = x[i, 3]
    P = x[i, 4]
    a = alpha - gamma
    u_b = beta - gamma
    n_pts = n_ab + n_bc
    nan = wp.float64(wp.nan)

    ok = wp.isfinite(alpha) and wp.isfinite(beta) and wp.isfinite(gamma) and wp.isfinite(phi) \
        and wp.isfinite(P) and wp.isfinite(B[i]) and P > wp.float64(0.0) and B[i] > wp.float64(0.0)
    k1p = wp.cos(gamma) + wp.sin(gamma) * wp.tan(beta + phi)       # eq 7
    delta = two * wp.sin(half * (u_b - a)) * wp.sin(half * (u_b + a))   # elastica.bc_delta
    v_b = _PI - beta
    if ok:
        d0 = delta + two * k1p * wp.sin(half * v_b) * wp.sin(half * v_b)   # D(0), elastica.bc_D
        # quarter_loop._admissible: theta increases monotonically A -> B -> C
        ok = a > wp.float64(0.0) and a < _PI and u_b < two * _PI - a and delta > wp.float64(0.0) \
            and beta < _PI and d0 > wp.float64(0.0) and wp.isfinite(k1p)
    if not ok:
        for j in range(n_pts):
            s_out[i, j] = nan
            xy_out[i, j, 0] = nan
            xy_out[i, j, 1] = nan
        for j in range(4):
            cell_out[i, j] = nan
        ok_out[i] = 0
        return

    lam = wp.sqrt(B[i] / P)

    # ---- BC (eq 9): partial integrals from B, stored relative for now
    nbc_nodes = xg_bc.shape[0]
    x_bc_full = wp.float64(0.0)
    for j in range(1, n_bc + 1):
        eta = half * _PI * wp.float64(j) / wp.float64(n_bc)
        fs = wp.float64(0.0)
        fx = wp.float64(0.0)
        fy = wp.float64(0.0)
        for m in range(nbc_nodes):
            e = eta * xg_bc[m]
            w = v_b * wp.sin(e) / wp.sqrt(two * _bc_dv(e, v_b, delta, k1p))
            v = v_b * wp.cos(e)
            fs = fs + wg_bc[m] * w
            fx = fx + wg_bc[m] * w * wp.cos(v)
            fy = fy + wg_bc[m] * w * wp.sin(v)
        k = n_ab - 1 + j
        s_out[i, k] = lam * fs * eta
        xy_out[i, k, 0] = lam * fx * eta
        xy_out[i, k, 1] = lam * fy * eta
        x_bc_full = lam * fx * eta
    X_B = x_bc_full                                   # X_C = 0: the apex is on the axis

    # ---- AB (eq 8): chi = pi/2 - psi, cos(u/2) = k sin(psi) (elastica._psi_b)
    kk = wp.cos(half * a)
    kp = wp.sin(half * a)
    sin_psi_b = wp.cos(half * u_b) / kk
    cos_psi_b = wp.sqrt(wp.max(wp.sin(half * (u_b - a)) * wp.sin(half * (u_b + a)), wp.float64(0.0))) / kk
    chi_b = wp.atan2(cos_psi_b, sin_psi_b)
    chi_1 = wp.min(chi_b, wp.float64(0.25) * _PI)
    t1 = _asinh_pos(wp.tan(chi_1) / kp)
    n1 = n_ab
    if chi_b > chi_1:
        n1 = n1_split
    cg = wp.cos(gamma)
    sg = wp.sin(gamma)
    nab_nodes = xg_ab.shape[0]
    f_last = wp.float64(0.0)
    e_last = wp.float64(0.0)
    for j in range(n1):
        t = t1 * wp.float64(j) / wp.float64(n1 - 1)
        f = wp.float64(0.0)
        ee = wp.float64(0.0)
        for m in range(nab_nodes):
            tt = t * xg_ab[m]
            sh = kp * wp.sinh(tt)
            ch = kp * wp.cosh(tt)
            q = one + sh * sh
            f = f + wg_ab[m] / wp.sqrt(q)
            ee = ee + wg_ab[m] * ch * ch / (q * wp.sqrt(q))
        f = f * t
        ee = ee * t
        chi = wp.atan(kp * wp.sinh(t))
        x0 = lam * (f - two * ee)
        y0 = lam * two * kk * wp.sin(chi)
        s_out[i, j] = lam * f
        xy_out[i, j, 0] = x0 * cg - y0 * sg
        xy_out[i, j, 1] = x0 * sg + y0 * cg
        f_last = f
        e_last = ee
    n2 = n_ab - n1
    for j in range(1, n2 + 1):
        chi = chi_1 + (chi_b - chi_1) * wp.float64(j) / wp.float64(n2)
        span = chi - chi_1
        f = wp.float64(0.0)
        ee = wp.float64(0.0)
        for m in range(nab_nodes):
            c = chi_1 + span * xg_ab[m]
            sc = kk * wp.sin(c)
            dl = wp.sqrt(kp * kp + sc * sc)
            f = f + wg_ab[m] / dl
            ee = ee + wg_ab[m] * dl
        f = f_last + f * span
        ee = e_last + ee * span
        x0 = lam * (f - two * ee)
        y0 = lam * two * kk * wp.sin(chi)
        k = n1 - 1 + j
        s_out[i, k] = lam * f
        xy_out[i, k, 0] = x0 * cg - y0 * sg
        xy_out[i, k, 1] = x0 * sg + y0 * cg

    # ---- place: X_A = X_B - (X_B - X_A), BC from B
    iB = n_ab - 1
    dx_ab = xy_out[i, iB, 0]
    Y_B = xy_out[i, iB, 1]
    s_B = s_out[i, iB]
    X_A = X_B - dx_ab
    for j in range(n_ab):
        xy_out[i, j, 0] = X_A + xy_out[i, j, 0]
    for j in range(n_ab, n_pts):
        s_out[i, j] = s_B + s_out[i, j]
        xy_out[i, j, 0] = X_B - xy_out[i, j, 0]
        xy_out[i, j, 1] = Y_B + xy_out[i, j, 1]
    hd = half * d[i]
    cell_out[i, 0] = wp.float64(4.0) * (X_B - hd * wp.sin(beta))     # W, eq 6
    cell_out[i, 1] = two * (Y_B + hd * wp.cos(beta))                  # C, eq 6
    cell_out[i, 2] = s_B                                              # s_AB
    cell_out[i, 3] = xy_out[i, n_pts - 1, 1]                          # Y_C
    ok_out[i] = 1
