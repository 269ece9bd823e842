"""Measured force-strain curves of a knit and the load program that replays them.

A measured curve is a CSV file with columns

``strain``
    strain of the course length, (C - C0) / C0 [-] (the imposed strain of
    :mod:`knitsim.cell.load_program`);
``force_per_wale_N``
    force per wale [N], >= 0;
``cycle`` (optional)
    cycle number from 1 (a new loading branch starts a new cycle);
``direction`` (optional)
    ``load`` or ``unload``;
``rate_mm_s`` (optional)
    crosshead rate [mm/s], > 0 (carried along; the cell model is rate independent).

Missing ``direction`` / ``cycle`` are inferred from the strain turning points
with the convention of :func:`~knitsim.cell.load_program.piecewise_linear`:
the test starts at rest (strain 0), a row belongs to the branch that reaches
it (the turning point ends its branch), and each loading branch after an
unloading starts a new cycle.

:func:`program_for_curve` turns the curve's own strain history into a
:class:`~knitsim.cell.load_program.LoadProgram` whose corners are every
measured strain, so that each measured row is an increment of the program
(to rounding of ``a + (b - a) * n / n``); :func:`force_at_rows` reads the
simulated force (and stage labels) at the measured rows.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..cell.history import BatchHistory
from ..cell.load_program import LoadProgram, piecewise_linear
from ..cli.common import read_csv_columns
from ..errors import KnitsimInputError

REQUIRED = ("strain", "force_per_wale_N")
OPTIONAL = ("cycle", "direction", "rate_mm_s")
_DIRECTIONS = {"load": 1, "unload": -1}


@dataclass(frozen=True)
class MeasuredCurve:
    """A validated measured curve, one entry per row.

    Attributes
    ----------
    strain : ndarray of float
        Strain of the course length [-].
    force : ndarray of float
        Force per wale [N].
    cycle : ndarray of int
        Cycle number from 1.
    direction : ndarray of int
        +1 loading, -1 unloading.
    rate_mm_s : ndarray of float or None
        Crosshead rate [mm/s] where given.
    source : str
        File name (or label) used in messages.
    """

    strain: np.ndarray
    force: np.ndarray
    cycle: np.ndarray
    direction: np.ndarray
    rate_mm_s: np.ndarray | None = None
    source: str = "curve"

    def __len__(self) -> int:
        return len(self.strain)


def infer_branches(strain) -> tuple[np.ndarray, np.ndarray]:
    """Cycle and direction of each row from the strain turning points.

    The test starts at rest (strain 0).  A row's direction is the sign of its
    strain step from the previous row (from 0 for the first row); a row with no
    step keeps the direction of the previous one (loading at the start).  Each
    change from unloading to loading starts a new cycle, as in
    :func:`~knitsim.cell.load_program.piecewise_linear`.

    Returns
    -------
    cycle, direction : ndarray of int
    """
    s = np.asarray(strain, float)
    step = np.diff(np.concatenate([[0.0], s]))
    direction = np.empty(len(s), np.int32)
    cycle = np.empty(len(s), np.int32)
    d, cyc = 1, 1
    for i, ds in enumerate(step):
        nd = d if ds == 0 else (1 if ds > 0 else -1)
        if nd == 1 and d == -1:
            cyc += 1
        d = nd
        direction[i], cycle[i] = d, cyc
    return cycle, direction


def _cycles_from_direction(direction: np.ndarray) -> np.ndarray:
    cyc, out = 1, np.empty(len(direction), np.int32)
    for i, d in enumerate(direction):
        if i > 0 and d == 1 and direction[i - 1] == -1:
            cyc += 1
        out[i] = cyc
    return out


def curve_from_arrays(strain, force, cycle=None, direction=None, rate_mm_s=None,
                      source: str = "curve") -> MeasuredCurve:
    """Validate arrays into a :class:`MeasuredCurve` (rows numbered as in a CSV file, header = row 1).

    ``direction`` may hold ``"load"`` / ``"unload"`` or +1 / -1.  Raises
    :class:`~knitsim.errors.KnitsimInputError` naming the row and column of a
    NaN, a negative force, a strain that goes back within a branch, a bad
    direction or cycle.
    """
    s = np.asarray(strain, float)
    f = np.asarray(force, float)
    n = len(s)
    if n == 0:
        raise KnitsimInputError(f"{source}: no data rows")
    if len(f) != n:
        raise KnitsimInputError(f"{source}: column force_per_wale_N has {len(f)} rows, strain has {n}")

    def row(i):
        return i + 2  # header is row 1

    for name, arr in (("strain", s), ("force_per_wale_N", f)):
        bad = np.nonzero(~np.isfinite(arr))[0]
        if len(bad):
            raise KnitsimInputError(f"{source}: row {row(bad[0])}, column {name}: {arr[bad[0]]!r} is not finite")
    bad = np.nonzero(s <= -1.0)[0]
    if len(bad):
        raise KnitsimInputError(f"{source}: row {row(bad[0])}, column strain: {s[bad[0]]!r} <= -1 "
                                "means a non-positive course length")
    bad = np.nonzero(f < 0)[0]
    if len(bad):
        raise KnitsimInputError(f"{source}: row {row(bad[0])}, column force_per_wale_N: {f[bad[0]]!r} is negative "
                                "(a knit carries no compression)")
    if direction is None:
        inf_cycle, d = infer_branches(s)
    else:
        d = np.empty(n, np.int32)
        for i, v in enumerate(direction):
            key = v.strip().lower() if isinstance(v, str) else v
            if key in _DIRECTIONS:
                d[i] = _DIRECTIONS[key]
            elif not isinstance(key, str) and key in (1, -1):
                d[i] = int(key)
            else:
                raise KnitsimInputError(f"{source}: row {row(i)}, column direction: {v!r} "
                                        "is not 'load' or 'unload'")
        inf_cycle = _cycles_from_direction(d)
    # monotonic within a direction: a loading row may not go below the previous row, an
    # unloading row not above it (a repeated strain is allowed: it maps to the same increment)
    prev = np.concatenate([[0.0], s[:-1]])
    back = np.nonzero(d * (s - prev) < 0)[0]
    if len(back):
        i = back[0]
        what = "decreases within a load branch" if d[i] > 0 else "increases within an unload branch"
        raise KnitsimInputError(f"{source}: row {row(i)}, column strain: {s[i]!r} {what} "
                                f"(previous strain {prev[i]!r}); check the direction column or the row order")
    if cycle is None:
        c = inf_cycle
    else:
        craw = np.asarray(cycle, float)
        for i, v in enumerate(craw):
            if not (np.isfinite(v) and v == round(v) and v >= 1):
                raise KnitsimInputError(f"{source}: row {row(i)}, column cycle: {v!r} is not a whole number >= 1")
        c = craw.astype(np.int32)
        # the cycle must follow the branches: it changes exactly where a new loading branch starts
        bad = np.nonzero(c != inf_cycle - inf_cycle[0] + c[0])[0]
        if len(bad):
            i = bad[0]
            raise KnitsimInputError(f"{source}: row {row(i)}, column cycle: {c[i]} does not match the branches "
                                    "(a cycle starts with each new loading branch)")
    r = None
    if rate_mm_s is not None:
        r = np.asarray(rate_mm_s, float)
        bad = np.nonzero(~(np.isfinite(r) & (r > 0)))[0]
        if len(bad):
            raise KnitsimInputError(f"{source}: row {row(bad[0])}, column rate_mm_s: {r[bad[0]]!r} must be > 0")
    return MeasuredCurve(s, f, np.asarray(c, np.int32), d, r, source)


def read_measured_curve(path: str | Path) -> MeasuredCurve:
    """Read and validate a measured curve CSV (see the module docstring).

    Raises
    ------
    KnitsimInputError
        Missing column, NaN or text, negative force, strain going back within
        a branch, bad direction / cycle / rate; the message names the row and column.
    """
    cols = read_csv_columns(path, REQUIRED, OPTIONAL, numeric=("strain", "force_per_wale_N", "cycle", "rate_mm_s"))
    return curve_from_arrays(cols["strain"], cols["force_per_wale_N"], cols.get("cycle"), cols.get("direction"),
                             cols.get("rate_mm_s"), source=str(path))


def program_for_curve(curve: MeasuredCurve, max_increment: float = 0.005) -> tuple[LoadProgram, np.ndarray]:
    """The load program that replays a measured strain history.

    Every measured strain is a corner of a :func:`piecewise_linear` program
    (the turning points among them), refined to steps of at most
    ``max_increment``, so every measured row is an increment of the program.

    Returns
    -------
    program : LoadProgram
    rows : ndarray of int, shape [len(curve)]
        The program increment of each measured row; -1 for rows at rest
        (strain 0 before the first move), whose simulated force is 0.
    """
    s = curve.strain
    program = piecewise_linear(s, max_increment, field=f"{curve.source}: strain")
    # walk the corners as piecewise_linear does: each non-zero segment adds its increments,
    # the last of which is the segment's end (the measured row)
    pts = [0.0] + list(s) if s[0] != 0.0 else list(s)
    offset = 1 if s[0] != 0.0 else 0
    rows = np.empty(len(s), np.int64)
    rate = np.zeros(len(program)) if curve.rate_mm_s is not None else None
    count = 0
    if offset == 0:
        rows[0] = -1
    for j, (a, b) in enumerate(zip(pts[:-1], pts[1:])):
        start = count
        if b != a:
            count += max(1, int(np.ceil(abs(b - a) / max_increment - 1e-12)))
        rows[j + 1 - offset] = count - 1
        if rate is not None:
            rate[start:count] = curve.rate_mm_s[j + 1 - offset]  # the rate of the row the segment reaches
    if count != len(program):  # pragma: no cover - guards against a change of piecewise_linear
        raise RuntimeError(f"program_for_curve: counted {count} increments, the program has {len(program)}")
    if rate is not None:
        program = replace(program, rate=rate)
    return program, rows


def force_at_rows(history: BatchHistory, rows: np.ndarray, cell: int = 0) -> tuple[np.ndarray, list[str]]:
    """Simulated force per wale [N] and stage label at the measured rows.

    ``rows`` from :func:`program_for_curve`; a row at rest (-1) has force 0 and
    the label ``adherence`` (the rest state sticks until the first move).
    """
    F = history.force_per_wale[:, cell]
    labels = history.labels(cell)
    rows = np.asarray(rows)
    force = np.where(rows >= 0, F[np.maximum(rows, 0)], 0.0)
    lab = [labels[r] if r >= 0 else "adherence" for r in rows]
    return force, lab
