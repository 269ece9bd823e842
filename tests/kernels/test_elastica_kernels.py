"""Elastica integrals (eqs 8-9) and the forward map on the Warp device.

Expected numbers come from independent methods, never from this code:
- scipy.integrate.quad of the original, singular integrands of eqs 8-9
  (with model.md's sign in eq 9, which makes theta' continuous at B);
- Carlson's symmetric elliptic integrals (scipy.special.elliprf/elliprd), the
  closed forms of eq 8 in Legendre's form;
- direct integration of the elastica ODE (x' = cos theta, y' = sin theta,
  B theta'' = moment) with scipy.integrate.solve_ivp (model.md, "Elastica").
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest
import warp as wp
from scipy.integrate import IntegrationWarning, quad, solve_ivp
from scipy.special import elliprd, elliprf

from knitsim import warp_runtime
from knitsim.cell import warp_solve
from knitsim.kernels import elastica

warp_runtime.init()


def _ab(a, b, device):
    out = wp.empty((len(a), 3), dtype=wp.float64, device=device)
    wp.launch(elastica.ab_integrals_kernel, dim=len(a), device=device,
              inputs=[wp.array(a, dtype=wp.float64, device=device), wp.array(b, dtype=wp.float64, device=device)],
              outputs=[out])
    return out.numpy()


def _bc(D, k1, beta, device):
    out = wp.empty((len(D), 4), dtype=wp.float64, device=device)
    arrs = [wp.array(v, dtype=wp.float64, device=device) for v in (D, k1, beta)]
    wp.launch(elastica.bc_integrals_kernel, dim=len(D), device=device, inputs=arrs, outputs=[out])
    return out.numpy()


def _quad_ab(a, b):
    """Eq 8 in units of sqrt(B/P): int_a^b {cos, sin, 1}(q) dq / (2 sqrt(cos^2(a/2) - cos^2(q/2))).

    cos^2(a/2) - cos^2(q/2) = sin((q+a)/2) sin((q-a)/2) (exact identity, no
    cancellation); the 1/sqrt(q - a) factor goes to quad's algebraic weight.
    """
    def reg(q):  # integrand times sqrt(q - a)
        return 0.5 / np.sqrt(np.sin(0.5 * (q + a)) * np.sinc(0.5 * (q - a) / np.pi) * 0.5)

    mid = min(a + 50.0 * a, 0.5 * (a + b))  # the A end varies on the scale a at high load
    res = []
    for f in (lambda q: 1.0, np.cos, np.sin):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IntegrationWarning)
            v1 = quad(lambda q: reg(q) * f(q), a, mid, weight="alg", wvar=(-0.5, 0.0), epsabs=0, epsrel=1e-13, limit=400)[0]
            v2 = quad(lambda q: reg(q) * f(q) / np.sqrt(q - a), mid, b, epsabs=0, epsrel=1e-13, limit=400,
                      points=[min(b, mid + 10 * (mid - a))])[0]
        res.append(v1 + v2)
    return np.array(res)  # s, x0, y0


def _carlson_ab(a, b):
    """Eq 8 as incomplete elliptic integrals F, E of modulus k = cos(a/2) (Carlson forms)."""
    k2 = np.cos(a / 2) ** 2
    kp2 = np.sin(a / 2) ** 2
    sp = np.cos(b / 2) / np.cos(a / 2)  # sin psi_B
    cp = np.sqrt(np.sin((b + a) / 2) * np.sin((b - a) / 2)) / np.cos(a / 2)
    d2 = cp**2 + kp2 * sp**2
    F = sp * elliprf(cp**2, d2, 1.0)
    E = F - k2 * sp**3 * elliprd(cp**2, d2, 1.0) / 3
    K = elliprf(0.0, kp2, 1.0)
    Ec = K - k2 * elliprd(0.0, kp2, 1.0) / 3
    s = K - F
    return np.array([s, s - 2 * (Ec - E), 2 * np.sqrt(np.sin((b + a) / 2) * np.sin((b - a) / 2))])


def _ab_cases():
    rng = np.random.default_rng(20150801)
    # down to a = 1e-10: the graded range ln(2 tan t1 / k') ~ 23 needs the most panels
    a = np.concatenate([rng.uniform(0.05, 1.4, 12), [1e-3, 1e-5, 1e-5, 1e-7, 1e-10]])
    b = a + rng.uniform(0.05, 1.0, a.size)
    b = np.minimum(b, np.pi - 0.05)
    return a, b


def test_ab_integrals_vs_quad_of_singular_eq8(device):
    a, b = _ab_cases()
    got = _ab(a, b, device)
    for i in range(a.size):
        if a[i] < 1e-6:
            continue  # quad's own accuracy degrades below; covered by the Carlson test
        ref = _quad_ab(a[i], b[i])
        np.testing.assert_allclose(got[i], ref, rtol=0, atol=1e-10 * abs(ref[0]), err_msg=f"a={a[i]}, b={b[i]}")


def test_ab_integrals_vs_carlson_closed_forms(device):
    a, b = _ab_cases()
    got = _ab(a, b, device)
    ref = np.array([_carlson_ab(ai, bi) for ai, bi in zip(a, b)])
    # relative to the arc length (x0 can pass through zero)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * np.abs(ref[:, :1]).max())


def _G(D, k1, beta):
    return lambda u: D + k1 * (np.cos(beta) + np.cos(u))


def test_bc_integrals_vs_quad_of_eq9(device):
    # k1' > 0 (graded at B) incl. small D (theta'_B -> 0), k1' ~ 0 (plain), k1' < 0 (graded at C)
    # and k1' < 0 with G(0) = 1e-4 (theta'_C -> 0, high load)
    D = np.array([0.43, 0.2, 1e-2, 1e-3, 0.3, 0.5, 0.8, 0.31])
    k1 = np.array([1.0, 2.5, 0.8, 1.5, 1e-9, -0.3, -0.2, -(0.31 - 1e-4) / (1 + np.cos(2.2266))])
    beta = np.array([1.66, 1.2, 1.9, 1.7, 1.5, 1.8, 2.2, 2.2266])
    got = _bc(D, k1, beta, device)
    for i in range(D.size):
        G = _G(D[i], k1[i], beta[i])
        uB = np.pi - beta[i]
        s = quad(lambda u: 1 / np.sqrt(2 * G(u)), 0, uB, epsabs=0, epsrel=1e-13, limit=400)[0]
        x = quad(lambda u: np.cos(u) / np.sqrt(2 * G(u)), 0, uB, epsabs=0, epsrel=1e-13, limit=400)[0]
        y = quad(lambda u: np.sin(u) / np.sqrt(2 * G(u)), 0, uB, epsabs=0, epsrel=1e-13, limit=400)[0]
        np.testing.assert_allclose(got[i, :3], [s, x, y], rtol=0, atol=1e-10 * s, err_msg=f"case {i}")
        assert got[i, 3] == pytest.approx(np.sqrt(2 * G(0.0)), rel=1e-14)


def _shoot(x, B, d):
    """Quantities from the elastica ODE, integrated A -> B -> C (independent of eqs 8-9)."""
    alpha, beta, gamma, phi, P = x
    k1 = np.cos(gamma) + np.sin(gamma) * np.tan(beta + phi)
    opts = dict(method="DOP853", rtol=1e-12, atol=1e-14, dense_output=False)

    def ab(s, y):  # y = (X - X_A, Y, theta, theta')
        return [np.cos(y[2]), np.sin(y[2]), y[3], P / B * np.sin(y[2] - gamma)]

    ev = lambda s, y: y[2] - beta
    ev.terminal = True
    r1 = solve_ivp(ab, [0, 50], [0, 0, alpha, 0], events=ev, **opts)
    s_ab = r1.t_events[0][0]
    yB = r1.y_events[0][0]

    def bc(s, y):
        return [np.cos(y[2]), np.sin(y[2]), y[3], P * k1 / B * np.sin(y[2])]

    ev2 = lambda s, y: y[2] - np.pi
    ev2.terminal = True
    r2 = solve_ivp(bc, [0, 50], yB, events=ev2, **opts)
    s_bc = r2.t_events[0][0]
    yC = r2.y_events[0][0]
    X_B_minus_X_A = yB[0]
    X_B = yB[0] - yC[0]  # X_C = 0
    return dict(s_AB=s_ab, s_BC=s_bc, X_B=X_B, X_A=X_B - X_B_minus_X_A,
                Y_B=yB[1], Y_C=yC[1], M=B * yC[3],
                W=4 * (X_B - d / 2 * np.sin(beta)), C=2 * (yB[1] + d / 2 * np.cos(beta)), L=4 * (s_ab + s_bc),
                g=X_B_minus_X_A - d / 2 * np.sin(beta))


@pytest.mark.parametrize("x, B, d", [
    ((1.218147, 1.660135, 0.074085, 0.0, 0.145839), 0.31, 0.58),   # E-glass initial state (model.md)
    ((1.173696, 1.818129, 0.348877, 0.0, 0.150118), 0.20, 0.56),   # basalt initial state (model.md)
    # states on a wale-wise stretch path of the E-glass knit (phi = 0.156), found with solve_batch:
    ((1.21817291, 2.14473517, 1.07444096, 0.156, 0.38293985), 0.31, 0.58),  # k1' < 0 (T > 0)
    ((1.36398464, 2.20365475, 1.36255918, 0.156, 2.25359421), 0.31, 0.58),  # alpha - gamma ~ 1e-3
    ((1.4195912, 2.22655131, 1.41958463, 0.156, 6.73507988), 0.31, 0.58),   # alpha - gamma ~ 7e-6
])
def test_forward_map_vs_ode_shooting(device, x, B, d):
    got = warp_solve.forward_batch(np.array(x), B, d, device=device)
    ref = _shoot(np.array(x), B, d)
    for name, v in ref.items():
        scale = 1.0 if name != "M" else B / d
        assert got[name][0] == pytest.approx(v, abs=1e-9 * scale), name
