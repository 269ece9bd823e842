"""Yarn centrelines of a knit patch, built from quarter-stitch cells.

Pure NumPy; no USD here.  :mod:`knitsim.usd.export` writes what this module
builds.

Geometry
--------
Quarter stitch (Dusserre 2015 section 3, Hong et al. 2002; ``docs/model.md``).
In the *cell frame* X is measured from the vertical through the loop apex C,
Y upward from the inflection point A.  The quarter centreline runs, by
increasing arc length s, from A = (W/4, 0) (eq 6: X_A = W/4) through the
crossing point B to the apex C = (0, Y_C), where the tangent is horizontal
(theta_C = pi).  It is an *input* here, sampled at ``n`` points
``q_0 = A, ..., q_{n-1} = C``.

Full stitch.  The model's symmetries give the other three quarters:

- mirror about X = 0 (the vertical through the apex) gives the other half of
  the loop head, C -> A' = (-W/4, 0);
- point reflection about A gives the sinker loop: the leg continues below A with
  opposite curvature (A is an inflection point), its apex at
  2A - C = (W/2, -Y_C); mirroring that about X = W/2 closes the period at
  A'' = A' + (W, 0).

In the *stitch frame* used below, x = X + W/4 (so that A' sits at x = 0) and
y = Y.  One period W of the course yarn, in the direction of increasing x, is
the concatenation of four copies of the quarter (each quarter's end point is
shared with the next copy, hence ``4 (n - 1) + 1`` points)::

    H1  head, left half    (W/4 - X(s),   Y(s))   s increasing   A' -> C
    H2  head, right half   (W/4 + X(s),   Y(s))   s decreasing   C  -> A
    S1  sinker, left half  (3W/4 - X(s), -Y(s))   s increasing   A  -> sinker apex
    S2  sinker, right half (3W/4 + X(s), -Y(s))   s decreasing   sinker apex -> A''

Tangent continuity (C1) at the joins is an identity of this construction:
at A the S1 tangent is the H2 tangent (a point reflection maps a direction d to
-d and S1 runs s the other way); at C and at the sinker apex a mirror about a
vertical keeps a horizontal tangent horizontal; at A'' the S2 end tangent is
(-cos alpha, sin alpha), the H1 start tangent of the next stitch.

Out-of-plane offset.  The model is planar: at B the two interlocking
centrelines touch in the plane at distance d.  For display, the yarn leaves the
plane::

    z = -(d/2) f(s)   on the head quarters H1, H2
    z = +(d/2) f(s)   on the sinker quarters S1, S2
    f(s) = sin((pi/2) min(s / s_AB, 1))

f rises from 0 at A to 1 at B and stays 1 up to the apex, so z is odd about A
(continuous, with continuous slope: A is the centre of the point reflection)
and flat across C and the sinker apex (continuous slope across the mirrors).
The yarn interlocking at B is a sinker quarter of the next course (the point
reflection about S = (W/4, C/2) of eq 6 maps A to an A point one course up and
C to a sinker apex), so at B one yarn is at -d/2, the other at +d/2: d apart
in z.  The loop heads of a course lie behind (z < 0) the legs of the next course,
as on the technical face of a plain knit seen from +z (the next loop is drawn
through the previous one from the back).  Unlike a real knit, the head and
sinker apexes are not sent further back: z is a display device, the model is
planar.
When s_AB is not given, B is taken at the widest point of the quarter (largest
X; B lies just past it, where theta = beta is a little above pi/2), with a floor
of a quarter of the quarter's length; this moves only the display offset.

Patch lattice.  Cell (i, j) is course i, wale j.  Cells can have different W
and C.  The stitch of cell (i, j) is placed with its A' point at::

    x0[i, j] = sum_{k < j} W[i, k]      (cumulative along the course)
    y0[i, j] = sum_{m < i} C[m, j]      (cumulative along the wale column)

so a course yarn is periodic with period W along x when the cells are equal,
and courses are stacked along y with spacing C: each course's heads
(up to y0 + Y_C) interlock with the sinker loops of the next course (down to
y0 + C - Y_C).  One continuous polyline per course: the last point of each cell
(its A'') is dropped and the next cell's A' follows; when neighbouring cells of
a course have the same y0 these points coincide.  When they differ (C varying
across a course) the yarn steps between them: the lattice rule above does not
make the cells of a non-uniform patch fit, and the picture shows it.  So in a
non-uniform patch (random phi0, gradients, zones) the yarn is stretched (one
course curve: a segment jumps between the two end points) or broken (an
instanced stitch per cell: a gap) where neighbouring stitches of a course meet;
this is a display artefact of the lattice rule, not a result of the model
(:data:`NON_UNIFORM_NOTE`).

Slack columns.  A column whose cells, stacked at their own course lengths, are
longer than the grip span (a slack column after an unloading: its extra length
``slack`` [mm] is the run's ``column_slack_mm``, the knit does not say where
it goes) is drawn between the grips: its course pitch is scaled by
:func:`slack_pitch_scale` so that its drawn length, the last course's origin
plus that course's C, is ``sum C - slack``, the grip span.  Each stitch keeps
its own shape, so neighbouring courses overlap (the knit piles up)::

    y0[i, j] = s_j * sum_{m < i} C[m, j]
    s_j = (sum_m C[m, j] - slack_j - C[-1, j]) / (sum_m C[m, j] - C[-1, j])

clipped to [0, 1]; s_j = 1 exactly in a column without slack (a loaded
column is drawn as before).

Vertex layout of a course curve with ``w`` wales and ``n`` points per quarter:
cell j owns vertices ``j*4(n-1) ... (j+1)*4(n-1) - 1``; within it the offsets of
A', head apex, A and sinker apex are ``0, n-1, 2(n-1), 3(n-1)``; the course
ends with one extra vertex (A'' of the last cell).
"""
from __future__ import annotations

import numpy as np

from ..errors import KnitsimInputError

#: offsets of the landmark points within a cell's block of ``4 (n - 1)`` vertices,
#: in units of ``n - 1`` (see the module docstring)
LANDMARKS: dict[str, int] = {"A_prime": 0, "head_apex": 1, "A": 2, "sinker_apex": 3}

#: tolerance on the closure checks X_A = W/4, Y_A = 0, X_C = 0, relative to W
ENDPOINT_RTOL = 1e-4

#: what a file of a non-uniform patch says of the joins between stitches (module docstring, "Patch lattice")
NON_UNIFORM_NOTE = (
    "non-uniform patch: neighbouring stitches of a course differ in course length (and wale width), and each "
    "wale column is stacked at its own course lengths, so where two stitches of a course meet the yarn is "
    "stretched (course yarns: a segment jumps between their end points) or broken (instanced stitches: a gap); "
    "this is a display artefact of the lattice (knitsim.usd.yarn_geometry), not a result of the model, which "
    "does not resolve the yarn between cells")


def vertices_per_cell(n: int) -> int:
    """Vertices a cell contributes to its course curve, ``4 (n - 1)``."""
    return 4 * (int(n) - 1)


def course_vertex_count(n: int, wales: int) -> int:
    """Vertices of one course curve: ``wales * 4 (n - 1) + 1``."""
    return int(wales) * vertices_per_cell(n) + 1


def landmark_index(name: str, n: int, wale: int | np.ndarray) -> int | np.ndarray:
    """Index in the course curve of a landmark point of the cell of ``wale``.

    Parameters
    ----------
    name : {"A_prime", "head_apex", "A", "sinker_apex"}
    n : int
        Points per quarter.
    wale : int or array of int
    """
    if name not in LANDMARKS:
        raise KnitsimInputError(f"landmark name={name!r} is not one of {sorted(LANDMARKS)}")
    return np.asarray(wale) * vertices_per_cell(n) + LANDMARKS[name] * (int(n) - 1)


def _arc_length(q: np.ndarray) -> np.ndarray:
    """Cumulative chord length along the last-but-one axis, shape q.shape[:-1]."""
    seg = np.linalg.norm(np.diff(q, axis=-2), axis=-1)
    s = np.zeros(q.shape[:-1])
    np.cumsum(seg, axis=-1, out=s[..., 1:])
    return s


def _default_s_ab(q: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Arc length to the widest point of each quarter (largest X), floored."""
    i = np.argmax(q[..., 0], axis=-1)
    s_widest = np.take_along_axis(s, i[..., None], axis=-1)[..., 0]
    return np.maximum(s_widest, 0.25 * s[..., -1])


def resample_quarters(quarter_xy, points: int) -> np.ndarray:
    """Resample quarters to ``points`` points, uniform in chord length.

    A and the apex C are kept exactly; in between, points are interpolated
    linearly on the input polyline (a display decimation, not a refit).

    Parameters
    ----------
    quarter_xy : array, shape (..., n, 2)
    points : int, >= 2

    Returns
    -------
    array, shape (..., points, 2)
    """
    q = np.asarray(quarter_xy, dtype=float)
    if isinstance(points, bool) or not isinstance(points, (int, np.integer)) or points < 2:
        raise KnitsimInputError(f"points_per_quarter must be an integer >= 2, got {points!r}")
    s = _arc_length(q)
    total = s[..., -1:]
    t = np.linspace(0.0, 1.0, int(points)) * total            # (..., points)
    # segment of each target point: last node with s <= t (clipped to the last segment)
    i = np.clip((s[..., None, :] <= t[..., :, None]).sum(axis=-1) - 1, 0, q.shape[-2] - 2)
    s0 = np.take_along_axis(s, i, axis=-1)
    s1 = np.take_along_axis(s, i + 1, axis=-1)
    w = np.where(s1 > s0, (t - s0) / np.where(s1 > s0, s1 - s0, 1.0), 0.0)[..., None]
    q0 = np.take_along_axis(q, i[..., None], axis=-2)
    q1 = np.take_along_axis(q, i[..., None] + 1, axis=-2)
    out = q0 + w * (q1 - q0)
    out[..., 0, :] = q[..., 0, :]
    out[..., -1, :] = q[..., -1, :]
    return out


def check_quarters(quarter_xy: np.ndarray, W: np.ndarray, field: str = "quarter_xy") -> None:
    """Check that quarters are finite and close on the cell frame.

    Raises :class:`KnitsimInputError` naming ``field`` and the first bad cell
    unless every quarter starts at A = (W/4, 0) and ends on X = 0 (eq 6 and the
    symmetry at the apex), within ``ENDPOINT_RTOL * W``.
    """
    q = np.asarray(quarter_xy, dtype=float)
    if not np.all(np.isfinite(q)):
        bad = np.argwhere(~np.isfinite(q))[0]
        raise KnitsimInputError(f"{field} has a non-finite value at index {tuple(int(b) for b in bad)}")
    Wb = np.broadcast_to(np.asarray(W, dtype=float), q.shape[:-2])
    tol = ENDPOINT_RTOL * np.abs(Wb)
    for what, err in (("X_A - W/4", q[..., 0, 0] - Wb / 4), ("Y_A", q[..., 0, 1]), ("X_C", q[..., -1, 0])):
        bad = np.abs(err) > tol
        if np.any(bad):
            k = tuple(int(b) for b in np.argwhere(bad)[0])
            raise KnitsimInputError(
                f"{field} at cell {k}: {what} = {err[k]:.6g} mm, expected 0 (quarter must run from "
                f"A = (W/4, 0) to the apex on X = 0)")


def stitch_points(quarter_xy, W, d=0.0, s_ab=None) -> np.ndarray:
    """Full-stitch points of many cells at once, each in its stitch frame.

    Parameters
    ----------
    quarter_xy : array, shape (..., n, 2)
        Quarter centrelines in the cell frame [mm], A first, apex C last.
    W : array, shape (...)
        Wale width [mm].
    d : float or array, shape (...)
        Yarn diameter [mm]; sets the out-of-plane offset +-(d/2).
    s_ab : array, shape (...), optional
        Arc length A -> B [mm]; default the widest point of the quarter.

    Returns
    -------
    array, shape (..., 4 (n - 1) + 1, 3)
        From A' = (0, 0, 0) to A'' = (W, 0, 0) [mm] (module docstring).
    """
    q = np.asarray(quarter_xy, dtype=float)
    lead = q.shape[:-2]
    Wq = np.broadcast_to(np.asarray(W, dtype=float), lead)[..., None] / 4.0
    half_d = np.broadcast_to(np.asarray(d, dtype=float), lead)[..., None] / 2.0
    X, Y = q[..., 0], q[..., 1]
    s = _arc_length(q)
    sb = _default_s_ab(q, s) if s_ab is None else np.broadcast_to(np.asarray(s_ab, dtype=float), lead)
    # f(s): 0 at A, 1 from B on; sin keeps the slope continuous at B
    f = np.sin(0.5 * np.pi * np.clip(s / np.maximum(sb, 1e-300)[..., None], 0.0, 1.0))
    z = half_d * f
    h1 = np.stack([Wq - X, Y, -z], axis=-1)
    h2 = np.stack([Wq + X, Y, -z], axis=-1)[..., ::-1, :]
    s1 = np.stack([3 * Wq - X, -Y, z], axis=-1)
    s2 = np.stack([3 * Wq + X, -Y, z], axis=-1)[..., ::-1, :]
    return np.concatenate([h1, h2[..., 1:, :], s1[..., 1:, :], s2[..., 1:, :]], axis=-2)


def stitch_polyline(quarter_xy, W: float, d: float = 0.0, s_ab: float | None = None,
                    origin=(0.0, 0.0)) -> np.ndarray:
    """Full-stitch centreline of one cell.

    Parameters
    ----------
    quarter_xy : array, shape (n, 2)
        Quarter centreline in the cell frame [mm]: A = (W/4, 0) first, apex
        (0, Y_C) last.
    W : float
        Wale width [mm].
    d : float
        Yarn diameter [mm] (out-of-plane offset +-(d/2); 0 gives a planar stitch).
    s_ab : float, optional
        Arc length A -> B [mm]; default the widest point of the quarter.
    origin : (float, float)
        Where A' goes [mm].

    Returns
    -------
    array, shape (4 (n - 1) + 1, 3)
        A' -> head apex -> A -> sinker apex -> A'' [mm].
    """
    q = np.asarray(quarter_xy, dtype=float)
    if q.ndim != 2 or q.shape[1] != 2 or q.shape[0] < 2:
        raise KnitsimInputError(f"quarter_xy must have shape (n >= 2, 2), got {q.shape}")
    check_quarters(q, W)
    p = stitch_points(q, W, d, s_ab)
    p[:, 0] += origin[0]
    p[:, 1] += origin[1]
    return p


def slack_pitch_scale(C, slack, drawn=None, represented=None) -> np.ndarray:
    """Scale of the course pitch of each wale column that puts a slack column between the grips.

    Parameters
    ----------
    C : array, shape (courses, wales)
        Course length of each cell [mm].
    slack : array, shape (wales,)
        Length by which each column's cells, stacked, exceed the grip span [mm] (the run's
        ``column_slack_mm``; 0 for a loaded column).
    drawn, represented : array, shape (courses, wales), optional
        Courses drawn and courses stood for by each cell (a specimen's blocks,
        :mod:`knitsim.usd.instanced`); default 1 and 1.  The grip span is then the drawn column's
        length times ``1 - slack / (its represented length)``.

    Returns
    -------
    array, shape (wales,)
        ``s`` in [0, 1] (module docstring, "Slack columns"): origins ``y0 = s * sum C`` put the top
        of the column's last stitch at the grip span; exactly 1 where ``slack`` is 0.
    """
    C = np.asarray(C, dtype=float)
    slack = np.broadcast_to(np.asarray(slack, dtype=float), C.shape[1:])
    n_d = np.ones_like(C) if drawn is None else np.asarray(drawn, dtype=float)
    n_r = n_d if represented is None else np.asarray(represented, dtype=float)
    length = (n_d * C).sum(axis=0)                       # drawn length of each column [mm]
    rep = (n_r * C).sum(axis=0)
    # the top stitch of each column: the last course that draws one
    top_row = np.where(n_d > 0, np.arange(C.shape[0])[:, None], -1).max(axis=0)
    top = C[np.maximum(top_row, 0), np.arange(C.shape[1])]
    with np.errstate(divide="ignore", invalid="ignore"):
        span = length * (1.0 - slack / rep)
        s = np.clip((span - top) / (length - top), 0.0, 1.0)
    # a loaded column (no slack), or one of a single course (nothing to compress), is drawn as it is
    return np.where((slack > 0) & np.isfinite(slack) & (length - top > 0) & np.isfinite(s), s, 1.0)


def cell_origins(W, C, pitch_scale=None) -> tuple[np.ndarray, np.ndarray]:
    """Lattice position of each cell's A' point [mm], shapes (courses, wales).

    x0 is cumulative W along the course (over wales), y0 cumulative C along
    the wale column (over courses), both starting at 0; ``pitch_scale``
    (wales,): y0 of each column times it (a slack column, :func:`slack_pitch_scale`).
    """
    W = np.asarray(W, dtype=float)
    C = np.asarray(C, dtype=float)
    x0 = np.zeros_like(W)
    y0 = np.zeros_like(C)
    np.cumsum(W[:, :-1], axis=1, out=x0[:, 1:])
    np.cumsum(C[:-1, :], axis=0, out=y0[1:, :])
    if pitch_scale is not None:
        y0 *= np.asarray(pitch_scale, dtype=float)[None, :]
    return x0, y0


def patch_points(quarter_xy, W, C, d, s_ab=None, pitch_scale=None) -> np.ndarray:
    """Course curves of a patch as one array.

    Parameters
    ----------
    quarter_xy : array, shape (courses, wales, n, 2)
        Quarter centrelines in each cell's frame [mm].
    W, C : array, shape (courses, wales)
        Wale width and course length of each cell [mm].
    d : float or array, shape (courses, wales)
        Yarn diameter [mm].
    s_ab : array, shape (courses, wales), optional
        Arc length A -> B [mm].
    pitch_scale : array, shape (wales,), optional
        Scale of each column's course pitch (a slack column drawn between the grips,
        :func:`slack_pitch_scale`); default 1.

    Returns
    -------
    array, shape (courses, wales * 4 (n - 1) + 1, 3)
        Vertices of each course yarn [mm] (layout in the module docstring).
    """
    q = np.asarray(quarter_xy, dtype=float)
    courses, wales, n, _ = q.shape
    cells = stitch_points(q, W, d, s_ab)                 # (courses, wales, 4(n-1)+1, 3)
    x0, y0 = cell_origins(W, C, pitch_scale)
    cells[..., 0] += x0[..., None]
    cells[..., 1] += y0[..., None]
    k = vertices_per_cell(n)
    out = np.empty((courses, wales * k + 1, 3))
    out[:, :-1] = cells[:, :, :-1, :].reshape(courses, wales * k, 3)
    out[:, -1] = cells[:, -1, -1, :]
    return out


def vertex_cells(n: int, wales: int) -> np.ndarray:
    """Wale index of each vertex of a course curve, shape (wales * 4 (n - 1) + 1,)."""
    k = vertices_per_cell(n)
    return np.minimum(np.arange(wales * k + 1) // k, wales - 1)


def course_curves(quarter_xy, W, C, d, s_ab=None) -> list[tuple[np.ndarray, np.ndarray]]:
    """One continuous yarn per course: ``[(points (m, 3), widths (m,)), ...]``.

    Parameters as :func:`patch_points`; ``widths`` is the yarn diameter d of
    the cell that owns each vertex [mm], ``m = wales * 4 (n - 1) + 1``.
    """
    q = np.asarray(quarter_xy, dtype=float)
    if q.ndim != 4 or q.shape[-1] != 2 or q.shape[2] < 2:
        raise KnitsimInputError(f"quarter_xy must have shape (courses, wales, n >= 2, 2), got {q.shape}")
    courses, wales, n, _ = q.shape
    for name, a in (("W", W), ("C", C)):
        if np.shape(a) != (courses, wales):
            raise KnitsimInputError(f"{name} must have shape {(courses, wales)}, got {np.shape(a)}")
    check_quarters(q, W)
    dd = np.broadcast_to(np.asarray(d, dtype=float), (courses, wales))
    pts = patch_points(q, W, C, dd, s_ab)
    vc = vertex_cells(n, wales)
    return [(pts[i], dd[i, vc].copy()) for i in range(courses)]
