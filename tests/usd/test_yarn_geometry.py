"""Full stitches and course yarns from quarter-stitch centrelines.

Expected values come from the construction's defining identities (module
docstring of knitsim.usd.yarn_geometry; model.md "Frame and signs", eq 6:
X_A = W/4, Y_A = 0, apex on X = 0) and from an analytic stand-in quarter (a
straight leg plus a circular arc), whose geometry is known in closed form.
"""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.errors import KnitsimInputError
from knitsim.usd import yarn_geometry as yg


def standin_quarter(W: float, Y_C: float, alpha: float, n: int) -> tuple[np.ndarray, dict]:
    """Test stand-in quarter loop: straight leg from A at angle alpha, then a
    circular arc turning the tangent from alpha to pi, ending at (0, Y_C).

    Leg length l and radius r solve  l cos(a) - r sin(a) = -W/4  (X_C = 0) and
    l sin(a) + r (1 + cos(a)) = Y_C.  Points are uniform in arc length.
    Returns the points (n, 2) and {"l", "r", "h"} (h = arc-length step).
    """
    a = alpha
    l, r = np.linalg.solve([[np.cos(a), -np.sin(a)], [np.sin(a), 1 + np.cos(a)]], [-W / 4, Y_C])
    assert l > 0 and r > 0
    total = l + r * (np.pi - a)
    s = np.linspace(0.0, total, n)
    A = np.array([W / 4, 0.0])
    P_l = A + l * np.array([np.cos(a), np.sin(a)])
    centre = P_l + r * np.array([-np.sin(a), np.cos(a)])
    th = a + np.clip(s - l, 0.0, None) / r
    pts = np.where((s <= l)[:, None], A + s[:, None] * np.array([np.cos(a), np.sin(a)]),
                   centre + r * np.stack([np.sin(th), -np.cos(th)], axis=1))
    return pts, {"l": l, "r": r, "h": total / (n - 1)}


W0, YC0, ALPHA0, D0 = 4.0, 3.1, 1.3, 0.4


def _turn(p: np.ndarray, k: int) -> float:
    """Turning angle of the xy polyline at vertex k (0 = no kink)."""
    u, v = p[k, :2] - p[k - 1, :2], p[k + 1, :2] - p[k, :2]
    return float(np.arctan2(abs(u[0] * v[1] - u[1] * v[0]), u @ v))


def test_standin_is_a_valid_quarter():
    q, g = standin_quarter(W0, YC0, ALPHA0, 33)
    # eq 6 (X_A = W/4, Y_A = 0) and apex on X = 0 at height Y_C, horizontal tangent (theta_C = pi)
    np.testing.assert_allclose(q[0], [W0 / 4, 0.0], atol=1e-12)
    np.testing.assert_allclose(q[-1], [0.0, YC0], atol=1e-12)
    t = q[-1] - q[-2]
    assert abs(np.arctan2(t[1], t[0]) - (np.pi - 0.5 * g["h"] / g["r"])) < 1e-12  # chord of an arc ending at theta = pi


def test_landmarks_of_one_stitch():
    n = 17
    q, _ = standin_quarter(W0, YC0, ALPHA0, n)
    p = yg.stitch_polyline(q, W0, d=D0, origin=(10.0, 20.0))
    assert p.shape == (4 * (n - 1) + 1, 3)
    k = n - 1
    # A' = origin, head apex at W/4 (mirror about the apex vertical), A at W/2,
    # sinker apex at 2A - C = (3W/4, -Y_C) (point reflection about A), A'' = A' + W
    np.testing.assert_allclose(p[0], [10.0, 20.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(p[k], [10.0 + W0 / 4, 20.0 + YC0, -D0 / 2], atol=1e-12)
    np.testing.assert_allclose(p[2 * k], [10.0 + W0 / 2, 20.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(p[3 * k], [10.0 + 3 * W0 / 4, 20.0 - YC0, D0 / 2], atol=1e-12)
    np.testing.assert_allclose(p[4 * k], [10.0 + W0, 20.0, 0.0], atol=1e-12)
    for name, off in yg.LANDMARKS.items():
        assert yg.landmark_index(name, n, 0) == off * k


def test_symmetries_of_one_stitch():
    n = 21
    q, _ = standin_quarter(W0, YC0, ALPHA0, n)
    p = yg.stitch_polyline(q, W0, d=D0)
    k = n - 1
    head, sinker = p[:2 * k + 1], p[2 * k:]
    # head: mirror about x = W/4 maps the curve onto itself reversed (z unchanged)
    np.testing.assert_allclose(head[::-1] * [-1, 1, 1] + [W0 / 2, 0, 0], head, atol=1e-12)
    # sinker = point reflection of the head about A = (W/2, 0, 0): (x, y, z) -> (W - x, -y, -z), reversed
    reflected = np.array([W0, 0.0, 0.0]) + head * [-1, -1, -1]
    np.testing.assert_allclose(reflected[::-1], sinker, atol=1e-12)


def test_c1_at_the_joins():
    """Tangent directions match across A, C, the sinker apex and A'' (identity).

    With the stand-in, the leg is straight (no turning at A, A', A'') and the arc
    turns by h/r per step; the mirror about the apex vertical continues the
    circle, so the turn at C and at the sinker apex is h/r as well.
    """
    n = 33
    q, g = standin_quarter(W0, YC0, ALPHA0, n)
    k = n - 1
    p = yg.stitch_polyline(q, W0, d=D0)
    two = np.vstack([p[:-1], p + [W0, 0, 0]])     # two stitches, to see A'' -> A' of the next
    assert _turn(p, 2 * k) < 1e-12                 # A
    assert _turn(two, 4 * k) < 1e-12               # A'' = next A'
    assert abs(_turn(p, k) - g["h"] / g["r"]) < 1e-9      # C
    assert abs(_turn(p, 3 * k) - g["h"] / g["r"]) < 1e-9  # sinker apex
    # one-sided tangents of z: z is odd about A, flat at the apexes
    z = p[:, 2]
    assert abs((z[2 * k + 1] - z[2 * k]) - (z[2 * k] - z[2 * k - 1])) < 1e-12
    assert abs(z[k + 1] - z[k]) < 1e-12 and abs(z[k] - z[k - 1]) < 1e-12


def test_c1_for_a_generic_quarter_converges():
    """Without a circle, the kink left at C by a sampled quarter is the chord
    error, O(h): it must shrink with refinement like the interior turning."""
    def quarter(n):
        # a smooth quarter with theta(A) = 1.2, theta(C) = pi: cubic Bezier
        P0, P3 = np.array([W0 / 4, 0.0]), np.array([0.0, YC0])
        P1 = P0 + 1.5 * np.array([np.cos(1.2), np.sin(1.2)])
        P2 = P3 + 1.2 * np.array([1.0, 0.0])
        t = np.linspace(0, 1, n)[:, None]
        return (1 - t) ** 3 * P0 + 3 * (1 - t) ** 2 * t * P1 + 3 * (1 - t) * t ** 2 * P2 + t ** 3 * P3

    kinks = []
    for n in (17, 65):
        p = yg.stitch_polyline(quarter(n), W0)
        k = n - 1
        interior = max(_turn(p, i) for i in range(1, k))
        assert _turn(p, k) <= 1.5 * interior
        assert _turn(p, 2 * k) < 1e-12     # A: exact identity (point reflection)
        kinks.append(_turn(p, k))
    assert kinks[1] < kinks[0] / 3.0       # O(h): 4x finer -> about 4x smaller


def test_uniform_patch_is_periodic():
    courses, wales, n = 3, 5, 9
    q, _ = standin_quarter(W0, YC0, ALPHA0, n)
    Q = np.broadcast_to(q, (courses, wales, n, 2))
    Cc = 2.7
    W = np.full((courses, wales), W0)
    C = np.full((courses, wales), Cc)
    curves = yg.course_curves(Q, W, C, D0)
    assert len(curves) == courses
    k = yg.vertices_per_cell(n)
    for pts, widths in curves:
        assert pts.shape == (wales * k + 1, 3) and widths.shape == (wales * k + 1,)
        np.testing.assert_allclose(widths, D0)
        for j in range(wales - 1):
            np.testing.assert_allclose(pts[(j + 1) * k:(j + 2) * k], pts[j * k:(j + 1) * k] + [W0, 0, 0], atol=1e-12)
    # courses stacked along y with spacing C
    for i in range(courses - 1):
        np.testing.assert_allclose(curves[i + 1][0], curves[i][0] + [0, Cc, 0], atol=1e-12)


def test_nonuniform_lattice_is_cumulative():
    n = 9
    Ws = np.array([[3.0, 4.0, 5.0], [3.5, 4.5, 5.5]])
    Cs = np.array([[2.0, 2.5, 3.0], [2.2, 2.7, 3.2]])
    Q = np.empty((2, 3, n, 2))
    for i in range(2):
        for j in range(3):
            Q[i, j] = standin_quarter(Ws[i, j], YC0, ALPHA0, n)[0]
    pts = yg.patch_points(Q, Ws, Cs, D0)
    apex = pts[:, yg.landmark_index("head_apex", n, np.arange(3))]
    # hand sums: x = W of the cells to the left + W/4; y = C of the cells below + Y_C
    np.testing.assert_allclose(apex[0, :, 0], [0.75, 3.0 + 1.0, 7.0 + 1.25])
    np.testing.assert_allclose(apex[1, :, 0], [0.875, 3.5 + 1.125, 8.0 + 1.375])
    np.testing.assert_allclose(apex[0, :, 1], [YC0] * 3)
    np.testing.assert_allclose(apex[1, :, 1], [2.0 + YC0, 2.5 + YC0, 3.0 + YC0])
    assert pts[0, -1, 0] == pytest.approx(12.0)   # A'' of the last cell at the course width


def test_crossings_are_d_apart_in_z():
    """At B the head quarter of course i (z = -d/2) meets a sinker quarter of
    course i+1 (z = +d/2): d apart (module docstring, out-of-plane offset)."""
    n = 25
    q, g = standin_quarter(W0, YC0, ALPHA0, n)
    # B at vertex 10 of the quarter; s is measured along the sampled polyline
    s_ab = np.linalg.norm(np.diff(q[:11], axis=0), axis=1).sum()
    Q = np.broadcast_to(q, (2, 2, n, 2))
    pts = yg.patch_points(Q, np.full((2, 2), W0), np.full((2, 2), 2.7), D0, np.full((2, 2), s_ab))
    k = n - 1
    b_head = pts[0, 2 * k - 10]        # H2 runs s downward from C
    b_sinker = pts[1, 2 * k + 10]      # S1 runs s upward from A
    assert b_head[2] - b_sinker[2] == pytest.approx(-D0, abs=1e-12)
    assert pts[0, 2 * k, 2] == 0.0 and pts[0, 0, 2] == 0.0   # in the plane at A and A'


def test_resample_follows_the_curve():
    """Resampling a finely sampled quarter to 7 points reproduces the stand-in
    sampled directly at 7 points (uniform in arc length), to the chord error of
    the fine polyline, O(h^2) ~ 1e-5 mm here; A and C exactly."""
    fine, _ = standin_quarter(W0, YC0, ALPHA0, 401)
    coarse, _ = standin_quarter(W0, YC0, ALPHA0, 7)
    r = yg.resample_quarters(np.stack([fine, fine]), 7)
    assert r.shape == (2, 7, 2)
    np.testing.assert_allclose(r[0], coarse, atol=1e-4)
    np.testing.assert_array_equal(r[1, [0, -1]], fine[[0, -1]])
    with pytest.raises(KnitsimInputError, match="points_per_quarter"):
        yg.resample_quarters(fine, 1)


def test_bad_quarters_raise():
    q, _ = standin_quarter(W0, YC0, ALPHA0, 9)
    with pytest.raises(KnitsimInputError, match="quarter_xy"):
        yg.stitch_polyline(q + [0.3, 0.0], W0)            # A not at W/4
    qn = q.copy()
    qn[3, 1] = np.nan
    with pytest.raises(KnitsimInputError, match="quarter_xy.*non-finite"):
        yg.stitch_polyline(qn, W0)
    Q = np.broadcast_to(q, (2, 3, 9, 2))
    with pytest.raises(KnitsimInputError, match="W must have shape"):
        yg.course_curves(Q, np.full((3, 2), W0), np.full((2, 3), 2.7), D0)
