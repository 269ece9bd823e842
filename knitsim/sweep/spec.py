"""The description of a parameter sweep: a ``[sweep]`` table, and its samples.

A sweep is written as a ``[sweep]`` table, either inside the cell scene itself
or in a separate TOML file given with ``knitsim sweep SCENE.toml --sweep
SWEEP.toml`` (which then replaces any ``[sweep]`` table of the scene; the
separate file holds only the ``[sweep]`` table)::

    [sweep]
    method = "grid"            # "grid" (cartesian product) or "lhs" (Latin hypercube)
    samples = 64               # lhs only: number of samples
    seed = 1                   # lhs only: seed of the Latin hypercube
    chunk_size = 256           # samples per chunk (one batched engine call per chunk)
    curves = false             # also keep force per wale vs increment of every cell

    [sweep.parameters]         # key paths of the scene, as for --set, quoted (unquoted, TOML reads friction.m as a
                               # table friction holding m: refused, saying so); order = dimension order
    "friction.m" = { values = [0.0, 0.1, 0.2, 0.3] }     # grid axis: explicit values
    "knit.L" = { min = 13.0, max = 15.0, count = 5 }      # grid axis: linspace(min, max, count)
    "friction.phi0" = { min = -0.2, max = 0.2 }           # lhs: uniform range

Any scalar key of the cell scene can be swept (``yarn.B``, ``knit.W0``,
``rules.force_cap_N``, ``load.upper_strain``, ``cells[1].friction.m`` ...);
grid ``values`` may also be strings or booleans (``"friction.model" = {
values = ["coulomb", "dahl"] }``).  The key path, the types, the ranges and
every sample's scene (by the scene schema and its cross-field checks, e.g.
``W0 >= 4 d``) are validated before anything is solved
(:func:`knitsim.sweep.runner.plan_sweep`).

Grid: the cartesian product of the axes, the first axis varying slowest (C
order), so that the sample table reshapes to one array dimension per
parameter.  LHS: :class:`scipy.stats.qmc.LatinHypercube` with the seed (one
sample in each of ``samples`` equal strata of every parameter), scaled
linearly to ``[min, max)``; reproducible for a given seed and SciPy version.
"""
from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import KnitsimInputError
from ..scene.schema import fmt, load_toml

METHODS = ("grid", "lhs")
#: most samples of a sweep (a grid's product of axis lengths, or an LHS's ``samples``): more is split by the user
MAX_SAMPLES = 10_000_000
SWEEP_KEYS = ("method", "samples", "seed", "chunk_size", "curves", "parameters")
DEFAULT_CHUNK_SIZE = 256


@dataclass(frozen=True)
class SweepParameter:
    """One swept key path.

    Attributes
    ----------
    key : str
        Key path in the scene (``"friction.m"``, ``"cells[1].knit.L"``).
    values : tuple, optional
        Grid values (explicit, or ``linspace(min, max, count)``).
    low, high : float, optional
        Range of an LHS parameter (or of a linspace axis).
    """

    key: str
    values: tuple | None = None
    low: float | None = None
    high: float | None = None


@dataclass(frozen=True)
class SweepSpec:
    """A validated ``[sweep]`` table.

    Attributes
    ----------
    method : {"grid", "lhs"}
    parameters : tuple of SweepParameter
        In the given order (grid: dimension order).
    samples : int
        Number of samples (grid: the product of the axis lengths).
    seed : int
        LHS seed (0 for a grid, unused).
    chunk_size : int
        Samples per chunk.
    curves : bool
        Keep the force-per-wale curve of every cell.
    table : dict
        The normalised ``[sweep]`` table (what is hashed and stored).
    """

    method: str
    parameters: tuple
    samples: int
    seed: int
    chunk_size: int
    curves: bool
    table: dict = field(default_factory=dict)

    @property
    def keys(self) -> list[str]:
        """The swept key paths, in order."""
        return [p.key for p in self.parameters]

    @property
    def shape(self) -> tuple[int, ...]:
        """Grid: one length per parameter; LHS: ``(samples,)``."""
        if self.method == "grid":
            return tuple(len(p.values) for p in self.parameters)
        return (self.samples,)

    def sample_table(self) -> list[tuple]:
        """The value of every parameter for every sample, in sample order.

        Returns
        -------
        list of tuple
            ``samples`` rows of ``len(parameters)`` values (Python scalars).
        """
        if self.method == "grid":
            return [tuple(row) for row in itertools.product(*(p.values for p in self.parameters))]
        u = lhs_unit(len(self.parameters), self.samples, self.seed)
        lo = np.array([p.low for p in self.parameters])
        hi = np.array([p.high for p in self.parameters])
        x = lo + u * (hi - lo)
        return [tuple(float(v) for v in row) for row in x]

    def hash(self) -> str:
        """SHA-256 of the normalised table (what ``--resume`` compares)."""
        return hashlib.sha256(canonical_json(self.table).encode()).hexdigest()


def canonical_json(value: Any) -> str:
    """JSON with sorted keys and no whitespace (for hashing)."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=False)


def lhs_unit(d: int, n: int, seed: int) -> np.ndarray:
    """``n`` Latin-hypercube points in ``[0, 1)^d`` from ``seed``.

    Each column has exactly one point in each of the ``n`` strata
    ``[k/n, (k+1)/n)`` (the defining property of a Latin hypercube, McKay
    et al. 1979); positions inside a stratum are random (scrambled).
    """
    from scipy.stats import qmc

    try:
        engine = qmc.LatinHypercube(d, rng=np.random.default_rng(seed))
    except TypeError:  # SciPy < 1.15 names it seed
        engine = qmc.LatinHypercube(d, seed=np.random.default_rng(seed))
    return engine.random(n)


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _param(key: str, raw: Any, method: str) -> tuple[SweepParameter, dict]:
    """Validate one ``[sweep.parameters]`` entry; returns it and its normalised table."""
    where = f"sweep.parameters.{json.dumps(key)}"
    if not isinstance(raw, dict):
        raise KnitsimInputError(f"{where} = {fmt(raw)}: expected a table, e.g. {{ values = [0.1, 0.2] }} "
                                "or { min = 0.1, max = 0.3 }")
    entry = ("values", "min", "max", "count")
    if raw and not any(k in raw for k in entry) and all(isinstance(v, dict) for v in raw.values()):
        # an unquoted key path: TOML reads friction.m = {...} as a table friction holding m (a blind probe was told
        # 'sweep.parameters."friction".m = {...}: unknown key')
        def paths(prefix, t):
            return [q for k, v in t.items() for q in (paths(f"{prefix}.{k}", v) if isinstance(v, dict) and v and
                                                      not any(e in v for e in entry) else [f"{prefix}.{k}"])]
        found = paths(key, raw)
        raise KnitsimInputError(f"{where} = {fmt(raw)}: a table of {', '.join(found)}, not a sweep entry: TOML reads "
                                f"an unquoted key path as nested tables; quote it: {json.dumps(found[0])} = {{ ... }}")
    allowed = ("values",) if "values" in raw else ("min", "max", "count")
    unknown = [k for k in raw if k not in entry]
    if unknown:
        raise KnitsimInputError(f"{where}.{unknown[0]} = {fmt(raw[unknown[0]])}: unknown key "
                                "(expected values, or min, max and count)")
    extra = [k for k in raw if k not in allowed]
    if extra:
        raise KnitsimInputError(f"{where}.{extra[0]} = {fmt(raw[extra[0]])}: give either values or min/max, not both")
    if "values" in raw:
        vals = raw["values"]
        if method == "lhs":
            raise KnitsimInputError(f"{where}.values: a Latin hypercube needs a range {{ min = ..., max = ... }}")
        if not isinstance(vals, list):
            raise KnitsimInputError(f"{where}.values = {fmt(vals)}: expected a list")
        if not vals:
            raise KnitsimInputError(f"{where}.values = []: needs at least one value")
        for i, v in enumerate(vals):
            if isinstance(v, (dict, list)):
                raise KnitsimInputError(f"{where}.values[{i}] = {fmt(v)}: expected a number, string or boolean")
            if isinstance(v, float) and not math.isfinite(v):
                raise KnitsimInputError(f"{where}.values[{i}] = {fmt(v)}: must be finite")
        # a number by its value: 0 and 0.0 are one grid value (a blind probe's [0, 0.0] made two samples of m = 0 and
        # a coordinate that repeats, which xarray cannot select by)
        if len({float(v) if _number(v) else canonical_json(v) for v in vals}) != len(vals):
            raise KnitsimInputError(f"{where}.values = {fmt(vals)}: values repeat (each grid value once)")
        # ints stay ints (an int field such as load.cycles takes them; a float field converts them)
        return SweepParameter(key, values=tuple(vals)), {"values": vals}
    for k in ("min", "max"):
        if k not in raw:
            raise KnitsimInputError(f"{where}.{k}: missing (give values = [...], or min and max)")
        if not _number(raw[k]) or not math.isfinite(raw[k]):
            raise KnitsimInputError(f"{where}.{k} = {fmt(raw[k])}: expected a finite number")
    lo, hi = float(raw["min"]), float(raw["max"])
    if lo >= hi:
        raise KnitsimInputError(f"{where}.min = {fmt(raw['min'])}: must be < max = {fmt(raw['max'])}")
    if method == "lhs":
        if "count" in raw:
            raise KnitsimInputError(f"{where}.count = {fmt(raw['count'])}: not used by a Latin hypercube "
                                    "(sweep.samples sets the number of samples)")
        return SweepParameter(key, low=lo, high=hi), {"min": lo, "max": hi}
    if "count" not in raw:
        raise KnitsimInputError(f"{where}.count: missing (a grid axis from min/max needs count)")
    n = raw["count"]
    if not isinstance(n, int) or isinstance(n, bool) or n < 2:
        raise KnitsimInputError(f"{where}.count = {fmt(n)}: expected a whole number >= 2")
    vals = tuple(float(v) for v in np.linspace(lo, hi, n))
    return SweepParameter(key, values=vals, low=lo, high=hi), {"min": lo, "max": hi, "count": n}


def _check_grid_size(params_raw: dict) -> None:
    """Refuse a grid whose product of axis lengths exceeds :data:`MAX_SAMPLES`, naming each axis's count.

    Read from the raw entries, before any axis is built: ``count = 1000000000`` would otherwise allocate
    its linspace (8 GB) and the product of the axes before the cap is met.  Malformed entries are left to
    :func:`_param` (they are not counted)."""
    sizes = []
    for key, raw in params_raw.items():
        if not isinstance(raw, dict):
            continue
        if isinstance(raw.get("values"), list):
            sizes.append((key, len(raw["values"]), "values"))
        elif isinstance(raw.get("count"), int) and not isinstance(raw.get("count"), bool) and raw["count"] >= 1:
            sizes.append((key, raw["count"], "count"))
    total = math.prod(n for _, n, _ in sizes)
    if total > MAX_SAMPLES:
        axes = " x ".join(f"{json.dumps(k)} {'count = ' if how == 'count' else ''}{n}"
                          f"{' values' if how == 'values' else ''}" for k, n, how in sizes)
        raise KnitsimInputError(f"sweep.parameters: a grid of {total} samples ({axes}): more than 10^7 samples; "
                                "split the sweep")


def parse_sweep(table: Any, source: str = "sweep") -> SweepSpec:
    """Validate a ``[sweep]`` table (the key paths are checked against the scene later).

    Parameters
    ----------
    table : dict
        The parsed ``[sweep]`` table.
    source : str
        Where it came from (for messages).

    Returns
    -------
    SweepSpec

    Raises
    ------
    KnitsimInputError
        Naming ``sweep.<key>`` and the value.
    """
    if not isinstance(table, dict):
        raise KnitsimInputError(f"sweep = {fmt(table)}: expected a table [sweep] ({source})")
    unknown = [k for k in table if k not in SWEEP_KEYS]
    if unknown:
        raise KnitsimInputError(f"sweep.{unknown[0]} = {fmt(table[unknown[0]])}: unknown key "
                                f"(expected one of {', '.join(SWEEP_KEYS)})")
    method = table.get("method", "grid")
    if method not in METHODS:
        raise KnitsimInputError(f"sweep.method = {fmt(method)}: expected one of {', '.join(METHODS)}")

    def whole(name, default, low):
        v = table.get(name, default)
        if not isinstance(v, int) or isinstance(v, bool) or v < low:
            raise KnitsimInputError(f"sweep.{name} = {fmt(v)}: expected a whole number >= {low}")
        return v

    chunk_size = whole("chunk_size", DEFAULT_CHUNK_SIZE, 1)
    curves = table.get("curves", False)
    if not isinstance(curves, bool):
        raise KnitsimInputError(f"sweep.curves = {fmt(curves)}: expected true or false")
    params_raw = table.get("parameters")
    if not isinstance(params_raw, dict) or not params_raw:
        raise KnitsimInputError(f"sweep.parameters = {fmt(params_raw) if params_raw is not None else 'missing'}: "
                                'needs at least one swept key path, e.g. "friction.m" = { values = [0.1, 0.2] }')
    if method == "grid":
        _check_grid_size(params_raw)       # before any axis is built (linspace of a huge count)
    params, norm = [], {}
    for key, raw in params_raw.items():
        p, n = _param(key, raw, method)
        params.append(p)
        norm[key] = n
    if method == "grid":
        for k in ("samples", "seed"):
            if k in table:
                raise KnitsimInputError(f"sweep.{k} = {fmt(table[k])}: only used with method = \"lhs\"")
        samples = math.prod(len(p.values) for p in params)     # Python ints: no int64 wrap-around
        seed = 0
    else:
        if "samples" not in table:
            raise KnitsimInputError("sweep.samples: missing (method = \"lhs\" needs the number of samples)")
        samples = whole("samples", None, 1)
        seed = whole("seed", 0, 0)
    if samples > MAX_SAMPLES:
        raise KnitsimInputError(f"sweep.samples = {samples}: more than 10^7 samples; split the sweep")
    norm_table = {"method": method, "chunk_size": chunk_size, "curves": curves,
                  "parameters": [{"key": k, **v} for k, v in norm.items()]}
    if method == "lhs":
        norm_table.update(samples=samples, seed=seed)
    return SweepSpec(method, tuple(params), samples, seed, chunk_size, curves, norm_table)


def split_scene(doc: dict, sweep_file: str | None = None) -> tuple[dict, dict, str]:
    """Separate a parsed scene into its scene part and the ``[sweep]`` table.

    Parameters
    ----------
    doc : dict
        The parsed scene TOML.
    sweep_file : str, optional
        A separate sweep TOML (holding only ``[sweep]``); it replaces the
        scene's ``[sweep]`` table.

    Returns
    -------
    (scene, sweep_table, source)
    """
    scene = {k: v for k, v in doc.items() if k != "sweep"}
    if sweep_file is not None:
        other = load_toml(sweep_file)
        extra = [k for k in other if k != "sweep"]
        if extra:
            raise KnitsimInputError(f"{sweep_file}: {extra[0]}: unknown key (a sweep file holds only a [sweep] table)")
        if "sweep" not in other:
            raise KnitsimInputError(f"{sweep_file}: no [sweep] table")
        return scene, other["sweep"], str(sweep_file)
    if "sweep" not in doc:
        raise KnitsimInputError("sweep: the scene has no [sweep] table (add one, or give --sweep SWEEP.toml)")
    return scene, doc["sweep"], "scene"


__all__ = ["METHODS", "SweepParameter", "SweepSpec", "parse_sweep", "split_scene", "lhs_unit", "canonical_json"]
