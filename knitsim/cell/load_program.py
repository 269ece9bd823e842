"""Strain-controlled load programs.

A load program is a piecewise-linear history of the imposed strain
(change in length of the course length, (C - C0) / C0, or the grip strain of a
patch), sampled into increments no larger than ``max_increment``.  Every sample
carries its cycle number (1-based; a cycle is one loading branch followed by one
unloading branch) and its direction (+1 loading, -1 unloading).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import KnitsimInputError


#: largest step of a program's strain against its direction (LoadProgram)
OPPOSITE_STEP_MAX = 1e-3


@dataclass(frozen=True)
class LoadProgram:
    """Sampled strain history.

    Attributes
    ----------
    strain : ndarray, shape [n]
        Imposed strain after each increment (the start, strain 0 at rest, is
        not included).
    cycle : ndarray of int, shape [n]
        Cycle number of each increment, from 1.
    direction : ndarray of int, shape [n]
        +1 while the strain increases (loading), -1 while it decreases.
    waypoints : tuple of float
        The piecewise-linear corners, starting at 0.
    rate : ndarray or None, shape [n]
        Test (crosshead) rate of each increment [mm/s], where known (a measured
        curve's ``rate_mm_s``); read by the ``velocity_friction`` effect only.
    """

    strain: np.ndarray
    cycle: np.ndarray
    direction: np.ndarray
    waypoints: tuple[float, ...]
    rate: np.ndarray | None = None

    def __post_init__(self):
        # a hand-built program is checked as the built ones are made: before, one whose direction said
        # unloading while its strain rose ran "ok" to 92.8 N past a 50 N cap, and arrays of other lengths
        # were read past their end (a blind probe of the Python API)
        strain = np.asarray(self.strain, dtype=np.float64)
        if strain.ndim != 1:
            raise KnitsimInputError(f"LoadProgram.strain: expected a 1-D array, got shape {strain.shape}")
        n = len(strain)
        bad = np.nonzero(~np.isfinite(strain) | (strain <= -1.0))[0]
        if len(bad):
            raise KnitsimInputError(f"LoadProgram.strain[{bad[0]}] = {float(strain[bad[0]])!r}: expected a finite strain > -1 "
                                    "(C = C0 (1 + strain) > 0)")
        arrays = {"cycle": self.cycle, "direction": self.direction}
        if self.rate is not None:
            arrays["rate"] = self.rate
        out = {}
        for name, v in arrays.items():
            a = np.asarray(v)
            if a.ndim != 1 or len(a) != n:
                raise KnitsimInputError(f"LoadProgram.{name}: expected one value per increment ({n}, as strain), "
                                        f"got shape {a.shape}")
            out[name] = a
        d = out["direction"]
        bad = np.nonzero(~np.isin(d, (-1, 1)))[0]
        if len(bad):
            raise KnitsimInputError(f"LoadProgram.direction[{bad[0]}] = {d[bad[0]].item()!r}: expected +1 (loading) or -1")
        # a step against its direction beyond OPPOSITE_STEP_MAX: the cell would be driven back along its branch
        # without a reversal (a patch's cells may move a little against the grips at the rest state, where
        # the column balances their rest forces: a few 1e-4; replayed, such a path is a program too)
        step = np.diff(np.concatenate([[0.0], strain]))
        bad = np.nonzero(-step * d > OPPOSITE_STEP_MAX)[0]
        if len(bad):
            i = bad[0]
            raise KnitsimInputError(f"LoadProgram.direction[{i}] = {int(d[i])} but the strain goes from "
                                    f"{0.0 if i == 0 else float(strain[i - 1])!r} to {float(strain[i])!r}: the direction "
                                    "is the sign of the strain's change (a held strain may carry either)")
        c = out["cycle"]
        if not (np.issubdtype(c.dtype, np.number) and np.all(np.isfinite(c)) and np.all(c == np.round(c))
                and np.all(c >= 1) and np.all(np.diff(c) >= 0)):
            raise KnitsimInputError(f"LoadProgram.cycle: expected whole numbers >= 1 that never decrease, got "
                                    f"{np.asarray(c)[:8].tolist()}{' ...' if n > 8 else ''}")
        if self.rate is not None:
            r = np.asarray(out["rate"], dtype=np.float64)
            bad = np.nonzero(~(np.isfinite(r) & (r > 0)))[0]
            if len(bad):
                raise KnitsimInputError(f"LoadProgram.rate[{bad[0]}] = {float(r[bad[0]])!r}: expected a rate > 0 [mm/s]")
            object.__setattr__(self, "rate", r)
        object.__setattr__(self, "strain", strain)
        object.__setattr__(self, "cycle", c.astype(np.int32) if c.dtype != np.int32 else c)
        object.__setattr__(self, "direction", d.astype(np.int32) if d.dtype != np.int32 else d)

    def __len__(self) -> int:
        return len(self.strain)


#: the most increments a load program may have (each is a row of every output)
MAX_INCREMENTS = 1_000_000


def _check_length(n: int, max_increment: float, field: str) -> None:
    """Refuse a program of more than :data:`MAX_INCREMENTS` increments before it is built (through the Python
    API a blind probe's ``monotonic(0.6, 1e-9)`` grew to 24 GB; the scene checks the same with its keys)."""
    if n > MAX_INCREMENTS:
        raise KnitsimInputError(f"load.max_increment = {max_increment:g}: {field} gives {n} increments (more than "
                                f"{MAX_INCREMENTS}); use a larger increment or a shorter program")


def piecewise_linear(waypoints, max_increment: float = 0.005, field: str = "load.waypoints") -> LoadProgram:
    """Sample a piecewise-linear strain history.

    Parameters
    ----------
    waypoints : sequence of float
        Strains to pass through, in order, starting from the rest state
        (strain 0 is prepended if the first waypoint is not 0).
    max_increment : float
        Largest strain increment between samples (> 0).
    field : str
        Name used in error messages.

    Returns
    -------
    LoadProgram
    """
    try:
        pts = [float(w) for w in waypoints]
    except (TypeError, ValueError):
        # (a bare number or text raised TypeError / ValueError without the field: a blind probe)
        raise KnitsimInputError(f"{field} = {waypoints!r}: expected a sequence of strains (numbers)") from None
    if not pts:
        raise KnitsimInputError(f"{field}: empty strain history")
    for i, w in enumerate(pts):
        if not math.isfinite(w):
            raise KnitsimInputError(f"{field}[{i}] = {w}: not a finite number")
        if w <= -1.0:
            raise KnitsimInputError(f"{field}[{i}] = {w}: a strain of -1 or less means a non-positive course length")
    if not (math.isfinite(max_increment) and max_increment > 0):
        raise KnitsimInputError(f"load.max_increment = {max_increment}: must be a positive number")
    if pts[0] != 0.0:
        pts = [0.0] + pts
    n_total = sum(max(1, math.ceil(abs(b - a) / max_increment - 1e-12)) for a, b in zip(pts[:-1], pts[1:]) if b != a)
    _check_length(n_total, max_increment, field)
    strain, cycle, direction = [], [], []
    cyc, last_dir = 1, +1
    for a, b in zip(pts[:-1], pts[1:]):
        if b == a:
            continue
        d = 1 if b > a else -1
        if d == 1 and last_dir == -1:
            cyc += 1  # a new loading branch starts a new cycle
        last_dir = d
        n = max(1, math.ceil(abs(b - a) / max_increment - 1e-12))
        seg = a + (b - a) * np.arange(1, n + 1) / n
        strain.extend(seg.tolist())
        cycle.extend([cyc] * n)
        direction.extend([d] * n)
    if not strain:
        raise KnitsimInputError(f"{field} = {list(waypoints)}: the history never moves away from strain 0")
    return LoadProgram(np.asarray(strain), np.asarray(cycle, dtype=np.int32),
                       np.asarray(direction, dtype=np.int32), tuple(pts))


def monotonic(target: float, max_increment: float = 0.005) -> LoadProgram:
    """Monotonic loading from rest to ``target`` strain (> 0)."""
    if not (math.isfinite(target) and target > 0):
        raise KnitsimInputError(f"load.target_strain = {target}: must be a positive number")
    if math.isfinite(max_increment) and max_increment > 0:
        _check_length(math.ceil(target / max_increment - 1e-12), max_increment, f"load.target_strain = {target:g}")
    return piecewise_linear([0.0, target], max_increment, field="load.target_strain")


def pretensioned(program: LoadProgram, offset: float, max_increment: float = 0.005) -> LoadProgram:
    """A grip program of a pretensioned specimen, as its solver runs it from the knit at rest.

    The first increments load from rest to ``offset`` (the grip strain, over the gauge length, of
    the pretension: pretension / (1 + pretension)); then ``program`` follows, shifted by ``offset``.
    A run reports its grip strains less ``offset`` (negative while the specimen is pretensioned).
    """
    if not (math.isfinite(offset) and offset > 0):
        raise KnitsimInputError(f"pretension offset = {offset!r}: must be a positive grip strain")
    pre = monotonic(offset, max_increment)
    first = int(program.cycle[0]) if len(program) else 1
    return LoadProgram(np.concatenate([pre.strain, np.asarray(program.strain) + offset]),
                       np.concatenate([np.full(len(pre), first, np.int32), np.asarray(program.cycle, np.int32)]),
                       np.concatenate([np.ones(len(pre), np.int32), np.asarray(program.direction, np.int32)]),
                       tuple([0.0] + [w + offset for w in program.waypoints]))


def cycles_travel(lower: float, upper: float, n_cycles: int) -> float:
    """The strain :func:`cycles` travels: from rest up to ``upper``, then ``2 n - 1`` half cycles of ``upper -
    lower`` (what sets its length at a given increment)."""
    return upper + (2 * n_cycles - 1) * (upper - lower)


def cycles(lower: float, upper: float, n_cycles: int, max_increment: float = 0.005) -> LoadProgram:
    """``n_cycles`` cycles: load to ``upper``, unload to ``lower``, repeat.

    The first loading starts at rest (strain 0); the paper's program is
    ``cycles(0.10, 0.60, 3)`` (Dusserre 2015, section 2.3).
    """
    if isinstance(n_cycles, (bool, np.bool_)) or not (isinstance(n_cycles, (int, np.integer)) and n_cycles >= 1):
        raise KnitsimInputError(f"load.cycles = {n_cycles}: must be a whole number >= 1")
    if not (math.isfinite(upper) and upper > 0):
        raise KnitsimInputError(f"load.upper_strain = {upper}: must be a positive number")
    if not (math.isfinite(lower) and 0 <= lower < upper):
        raise KnitsimInputError(f"load.lower_strain = {lower}: must satisfy 0 <= lower_strain < upper_strain = {upper}")
    if math.isfinite(max_increment) and max_increment > 0:
        # (before the waypoints are listed: load.cycles = 10^9 would list 2 x 10^9 of them)
        per_cycle = 2 * max(1, math.ceil((upper - lower) / max_increment - 1e-12))
        _check_length(int(n_cycles) * per_cycle, max_increment, f"load.cycles = {n_cycles}")
    pts = [0.0]
    for _ in range(int(n_cycles)):
        pts += [upper, lower]
    return piecewise_linear(pts, max_increment, field="load")
