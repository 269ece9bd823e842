"""Per-cell parameter maps of a patch: arrays of shape ``(courses, wales)``.

A map is a small table (a scene's ``[maps.<param>]``, see
:mod:`knitsim.scene.patch_scene`)::

    type = "uniform"   value = 0.58
    type = "regions"   regions = [{courses = [0, 55], wales = [0, 23], value = 0.56}], default = 0.58
    type = "gradient"  axis = "courses" | "wales", start = 13.5, end = 14.7,
                       profile = "linear" | "step", steps = 4
    type = "file"      path = "phi0.npy" | "phi0.csv"      (shape (courses, wales))
    type = "random"    low = -1.0, high = 1.0, seed = 7, scale = "absolute" | "phimax"

Index ranges are 0-based and half-open, ``[start, stop)``; course 0 is at the
lower grip, wale 0 at the left edge.  A linear gradient puts ``start`` on the
first course (wale) and ``end`` on the last; a step gradient cuts the axis into
``steps`` equal bands (the last band takes the remainder) valued
``start + (end - start) b / (steps - 1)``.  Random fields are uniform in
``[low, high)``, drawn from ``numpy.random.default_rng([seed, k])`` with ``k``
the parameter's index in :data:`~knitsim.patch.model.PARAM_NAMES` (so two maps
with one seed are independent, and a seed reproduces the field on every
platform NumPy supports); ``scale = "phimax"`` multiplies by each cell's
phimax = atan(m) (phi0 uniform in ``[-phimax, phimax]``: ``low = -1, high = 1``).

A ``.csv`` map is read as a spreadsheet writes it (:func:`_read_map_csv`): ``,``, ``;`` or tab between
the cells (decimal commas with ``;`` and tab, and in quoted cells), a byte-order mark or UTF-16, one row of
labels at the top.

Every error names the key path and the value (a map file's, the row and column).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import KnitsimInputError
from .model import PARAM_NAMES

MAP_TYPES = ("uniform", "regions", "gradient", "file", "random")
AXES = ("courses", "wales")
PROFILES = ("linear", "step")
SCALES = ("absolute", "phimax")


def _err(path: str, value, why: str) -> KnitsimInputError:
    from ..scene.schema import fmt
    return KnitsimInputError(f"{path} = {fmt(value)}: {why}")


def index_range(rng, n: int, path: str, axis: str, counted: str | None = None) -> slice:
    """``[start, stop)`` as a slice, checked against ``n`` cells along ``axis``; ``counted``: what a
    specimen's ``axis`` counts there (``"bands"`` of courses, ``"strips"`` of wales), named in the message
    (a blind probe's specimen of 10 wales in 2 strips was told "the patch has 2 wales")."""
    if (not isinstance(rng, (list, tuple)) or len(rng) != 2
            or any(isinstance(v, bool) or not isinstance(v, (int, float)) or float(v) != int(v) for v in rng)):
        raise _err(path, list(rng) if isinstance(rng, (list, tuple)) else rng,
                   f"expected [start, stop], two whole numbers (0-based, stop excluded) of {axis}")
    a, b = int(rng[0]), int(rng[1])
    if not (0 <= a < b <= n):
        has = f"the specimen has {n} {counted}" if counted else f"the patch has {n} {axis}"
        raise _err(path, [a, b], f"expected 0 <= start < stop <= {n} ({has})")
    return slice(a, b)


def gradient(n: int, start: float, end: float, profile: str = "linear", steps: int = 2) -> np.ndarray:
    """Values along one axis of ``n`` cells (see the module docstring)."""
    k = np.arange(n, dtype=np.float64)
    if profile == "linear":
        t = k / (n - 1) if n > 1 else np.zeros(n)
    else:
        band = np.minimum((k * steps // n).astype(np.int64), steps - 1)
        t = band / (steps - 1)
    return start + (end - start) * t


def _read_map_csv(f: Path, path: str) -> tuple[np.ndarray, tuple[int, list[str]] | None]:
    """A map CSV as a lab's spreadsheet writes it: a byte-order mark, UTF-16, Windows line ends, ``;`` or tab
    between the cells with decimal commas (Excel in a decimal-comma locale), quoted cells (``"0,05"``: a
    script's QUOTE_ALL, LibreOffice's or Google Sheets' decimal-comma export with ``,`` between the cells, read
    as the measured-curve reader reads them), one row of labels at the top (skipped where no cell of it is a
    number), blank lines.  An empty or non-numeric cell below is refused, named by row and column (a probe's
    Excel map was refused as "row 1 is not a list of numbers"), and so is a row of another length than the first,
    named with both (a probe's quoted first row was skipped as labels, and a ragged row was "not rectangular",
    no row named).

    Returns the array and the row of labels skipped, as (its row number, its cells), or None: a map of the
    wrong shape then says that row was not read as numbers (a blind probe's first row, skipped silently, left
    a map one course short and an error that did not say why)."""
    from ..io.table_input import _comma_file_decimal_comma, _number, _split, _text
    lines = _text(f).splitlines()
    first = next((ln for ln in lines if ln.strip()), "")
    # a ';' or a tab is the separator wherever one is written: their cells may hold decimal commas, which
    # outnumber them (0,1;0,0;-0,1)
    delim = max(("\t", ";"), key=first.count) if ("\t" in first or ";" in first) else ","
    table = []
    for r, line in enumerate(lines, start=1):
        cells = [c.strip() for c in _split(line, delim)]
        if not any(cells):
            continue
        while len(cells) > 1 and cells[-1] == "":          # a spreadsheet's trailing separators
            cells.pop()
        table.append((r, cells))
    width = max((len(c) for _, c in table), default=0)
    # a ',' file's quoted cells may hold decimal commas (refused where every one reads as a thousands separator too)
    decimal_comma = delim != "," or _comma_file_decimal_comma(
        f, [c for _, c in table], [r for r, _ in table], list(range(width)), [str(k + 1) for k in range(width)])
    rows, rows_at, shown, labels = [], [], 0, None
    sep = ("the sheet's columns" if f.suffix.lower() in (".xlsx", ".xlsm") else "a tab" if delim == "\t"
           else repr(delim))
    for r, cells in table:
        shown += 1
        vals = []
        for c in cells:
            try:
                vals.append(_number(c, decimal_comma) if c else None)
            except ValueError:
                vals.append("text")
        if shown == 1 and all(v == "text" for v in vals):
            labels = (r, cells)
            continue                                        # a row of labels
        for k, (c, v) in enumerate(zip(cells, vals), start=1):
            if v is None or v == "text" or not np.isfinite(v):
                # (a NaN or inf cell, e.g. a spreadsheet's #NUM! written as NaN, named as an empty one is: a probe's
                # map was refused as "the array must hold finite numbers only", no cell named)
                what = ("empty" if v is None else f"{c!r} is not a number" if v == "text"
                        else f"{c!r} is not a finite number")
                raise _err(path, str(f), f"row {r}, column {k}: {what} (a map holds one number per cell, one row "
                                         f"per course, separated by {sep})")
        if rows and len(vals) != len(rows[0]):
            raise _err(path, str(f), f"row {r} holds {len(vals)} number(s), row {rows_at[0]} {len(rows[0])}: expected a "
                                     f"rectangular table of numbers, one row per course, separated by {sep}")
        rows.append(vals)
        rows_at.append(r)
    if not rows:
        raise _err(path, str(f), "expected a rectangular table of numbers, one row per course")
    return np.asarray(rows, dtype=np.float64), labels


def read_array_file(file: str | Path, shape: tuple[int, int], path: str,
                    counted: tuple[str, str] | None = None) -> np.ndarray:
    """A ``.npy``, ``.csv`` or ``.xlsx`` (its sheet, as a CSV) array of shape ``(courses, wales)``, finite float64; ``counted``: what a specimen's
    axes count (``("bands", "strips")``), named in the message (a probe's 3 bands x 2 strips was told
    "expected (courses, wales) = (3, 2)")."""
    f = Path(file)
    labels = None
    if not f.is_file():
        raise _err(path, str(file), "no such file")
    if f.suffix == ".npy":
        try:
            a = np.load(f, allow_pickle=False)
        except ValueError as exc:
            raise _err(path, str(file), f"not a readable .npy array ({exc})") from None
    elif f.suffix.lower() in (".csv", ".xlsx", ".xlsm"):
        # (a workbook's sheet is read as its CSV: knitsim.io.table_input)
        a, labels = _read_map_csv(f, path)
    else:
        raise _err(path, str(file), "expected a .npy, .csv or .xlsx file")
    if a.ndim != 2 or a.shape != tuple(shape):
        axes = "(bands, strips)" if counted else "(courses, wales)"
        hint = (f" (the file may hold the map transposed: one row per {'band' if counted else 'course'} is expected)"
                if a.ndim == 2 and a.shape == tuple(shape)[::-1] else "")
        skipped = ""
        if labels is not None:
            r, cells = labels
            shown = ", ".join(repr(c) for c in cells[:4]) + (", ..." if len(cells) > 4 else "")
            skipped = (f"; row {r} ({shown}) was read as a row of labels and skipped (no cell of it is a number): "
                       "if it is a row of the map, write its cells as numbers")
        raise _err(path, str(file), f"array of shape {tuple(a.shape)}, expected {axes} = {tuple(shape)}{hint}"
                                    f"{skipped}")
    if not np.issubdtype(a.dtype, np.number) or np.iscomplexobj(a):
        raise _err(path, str(file), f"an array of {a.dtype}: the map must hold real numbers")
    bad = ~np.isfinite(a)
    if bad.any():
        # the first cell that is not finite, and how many are not (a probe's NaN was refused as "the array must hold
        # finite numbers only", the cell not named among 10^4)
        from .model import cell_name
        i, j = (int(v) for v in np.argwhere(bad)[0])
        more = f" ({int(bad.sum())} cells in all)" if bad.sum() > 1 else ""
        raise _err(path, str(file), f"{a[i, j]} at {cell_name(i, j, counted is not None, True)} (index [{i}, {j}])"
                                    f"{more}: the map must hold finite numbers only")
    return a.astype(np.float64)


def build_map(spec: dict, shape: tuple[int, int], base, path: str, seed: int = 0,
              base_dir: str | Path = ".", phimax: np.ndarray | None = None, name: str = "",
              counted: tuple[str, str] | None = None) -> np.ndarray:
    """Evaluate one map.

    Parameters
    ----------
    spec : dict
        The map table (``type`` and its keys; already type-checked by the scene schema).
    shape : (courses, wales)
    base : float or ndarray
        The value under the map (from the yarn/knit/friction tables and zones):
        the background of ``regions`` without ``default``.
    path : str
        Key path of the map, for messages (``"maps.phi0"``).
    seed : int
        Default seed of random maps (the scene's ``seed``).
    base_dir : path
        Directory against which a relative ``file`` path is resolved.
    phimax : ndarray, optional
        Per-cell atan(m), for ``scale = "phimax"``.
    name : str
        The parameter (one of :data:`~knitsim.patch.model.PARAM_NAMES`).
    counted : (str, str), optional
        What a specimen's axes count, ``("bands", "strips")``, named in the messages.

    Returns
    -------
    ndarray, shape ``shape``, float64
    """
    courses, wales = shape
    kind = spec.get("type")
    if kind is None:
        raise KnitsimInputError(f"{path}.type: missing (one of {', '.join(MAP_TYPES)})")
    allowed = {"uniform": {"value"}, "regions": {"regions", "default"},
               "gradient": {"axis", "start", "end", "profile", "steps"}, "file": {"path"},
               "random": {"low", "high", "seed", "scale"}}
    if kind not in allowed:
        raise _err(f"{path}.type", kind, f"expected one of {', '.join(MAP_TYPES)}")
    for key in spec:
        if key != "type" and key not in allowed[kind]:
            raise _err(f"{path}.{key}", spec[key], f"not used by {path}.type = \"{kind}\" "
                       f"(it takes {', '.join(sorted(allowed[kind]))})")

    def need(key):
        if key not in spec:
            raise KnitsimInputError(f"{path}.{key}: missing ({path}.type = \"{kind}\" needs it)")
        return spec[key]

    out = np.broadcast_to(np.asarray(base, dtype=np.float64), shape).copy()
    if kind == "uniform":
        out[:] = float(need("value"))
    elif kind == "regions":
        regions = need("regions")
        if "default" in spec:
            out[:] = float(spec["default"])
        for r, reg in enumerate(regions):
            rp = f"{path}.regions[{r}]"
            for key in reg:
                if key not in ("courses", "wales", "value"):
                    raise _err(f"{rp}.{key}", reg[key], "unknown key (expected one of courses, wales, value)")
            if "value" not in reg:
                raise KnitsimInputError(f"{rp}.value: missing")
            ci = index_range(reg.get("courses", [0, courses]), courses, f"{rp}.courses", "courses",
                             counted[0] if counted else None)
            wi = index_range(reg.get("wales", [0, wales]), wales, f"{rp}.wales", "wales", counted[1] if counted else None)
            out[ci, wi] = float(reg["value"])
    elif kind == "gradient":
        axis = need("axis")
        if axis not in AXES:
            raise _err(f"{path}.axis", axis, f"expected one of {', '.join(AXES)}")
        profile = spec.get("profile", "linear")
        if profile not in PROFILES:
            raise _err(f"{path}.profile", profile, f"expected one of {', '.join(PROFILES)}")
        steps = spec.get("steps", 2)
        n = courses if axis == "courses" else wales
        if n < 2:
            # start on the first cell and end on the last cannot both hold (a blind probe's end = -3 was dropped
            # without a word, where 3 wales refused it)
            raise _err(f"{path}.axis", axis, f"a gradient needs at least 2 {axis} (start on the first, end on the "
                       f"last); the patch has 1: give the value as a uniform map")
        if profile == "step" and not (2 <= steps <= n):
            raise _err(f"{path}.steps", steps, f"a step gradient needs 2 <= steps <= {n} (the {axis} of the patch)")
        g = gradient(n, float(need("start")), float(need("end")), profile, int(steps))
        out[:] = g[:, None] if axis == "courses" else g[None, :]
    elif kind == "file":
        f = Path(need("path"))
        if not f.is_absolute():
            f = Path(base_dir) / f
        out[:] = read_array_file(f, shape, f"{path}.path", counted)
    else:
        low, high = float(need("low")), float(need("high"))
        if not low < high:
            raise _err(f"{path}.low", low, f"must be < {path}.high = {high!r}")
        s = spec.get("seed", seed)
        from ..cell.effects import PARAM_COLUMNS
        # one stream per parameter: the cell parameters, then the effect parameters
        k = (PARAM_NAMES.index(name) if name in PARAM_NAMES
             else len(PARAM_NAMES) + PARAM_COLUMNS.index(name) if name in PARAM_COLUMNS else 0)
        rng = np.random.default_rng([int(s), k])
        out[:] = rng.uniform(low, high, size=shape)
        scale = spec.get("scale", "absolute")
        if scale not in SCALES:
            raise _err(f"{path}.scale", scale, f"expected one of {', '.join(SCALES)}")
        if scale == "phimax":
            if name != "phi0":
                raise _err(f"{path}.scale", scale, "\"phimax\" scales the initial friction angle phi0 only")
            if phimax is None:
                raise _err(f"{path}.scale", scale, "needs the cells' phimax (friction ratio m)")
            # low and high are fractions of phimax: beyond 1 every such cell leaves the friction cone, and the
            # cell check then named a drawn value as if given in degrees (a blind probe's low = -30, high = 30)
            for key, v in (("low", low), ("high", high)):
                if abs(v) > 1.0:
                    raise _err(f"{path}.{key}", v, "with scale = \"phimax\", low and high are fractions of each "
                               "cell's phimax = atan m, within [-1, 1] (phi0 in the friction cone); for an angle in "
                               "radians use scale = \"absolute\"")
            out *= np.broadcast_to(np.asarray(phimax, dtype=np.float64), shape)
    return out
