"""Result writers for patch runs (atomic): curve.csv, columns.csv, cells.nc, summary.json, plots, resolved scene.

A patch is a grid of cells, ``courses x wales``.  In a patch of single stitches
(``[patch]``) every cell is one stitch; in a specimen (``[specimen]``,
:mod:`knitsim.patch.model`) every cell is a block of identical stitches,
``course_count`` courses in series times ``wale_count`` wales in parallel, the
grid is ``bands x strips`` and a column is a strip carrying one total force.
Every file says which (:class:`SpecimenLayout`):

- ``curve.csv``: ``increment, cycle, direction, grip_strain, force_N, force_per_wale_N``
  (increment 0 is the rest state; grip force = sum of the columns' total forces; per wale = over
  the wales across the width: the columns' count of single stitches, or the sum of the strips'
  wale counts, each the mean along its rest length);
- ``columns.csv``: ``increment, column, wales, force_N, force_per_wale_N, status, iterations,
  slack_mm``, one row per increment (numbered as in curve.csv) and column (a wale of single
  stitches, or a strip): its total force [N], the wales it holds (1, or the strip's wale count,
  the mean along its rest length where its bands differ), and force_N / wales;
- ``cells.nc``: netCDF-4 (h5netcdf), dimensions ``increment, course, wale`` (course = band and
  wale = strip in a specimen): ``strain`` ((C - C0)/C0), ``phi`` [rad], ``force_per_wale_N``
  (of each of the cell's wales), ``stage`` (label codes with ``flag_values`` /
  ``flag_meanings``), ``status``; per column ``column_force_N`` (its total force),
  ``column_force_per_wale_N``, ``column_status``, ``column_wales``; per cell the parameters
  (``d, B, m, dahl_sigma, L, W0, C0, phi0, in_plane_width``), the rules (``friction``,
  ``unloading_rule``, ``reload_rule``, ``jamming_criterion`` as flag codes with their meanings,
  ``force_cap_N``) and the stitches it stands for,
  ``course_count`` and ``wale_count`` (1 and 1 for single stitches); coordinates ``grip_strain,
  cycle, direction``; units in attributes, with ``cell_is`` (``stitch`` / ``block of stitches``),
  ``stitches`` and, for a specimen, ``width_mm`` and ``gauge_length_mm``; and, for the yarn
  geometry (:mod:`knitsim.usd.from_results`), per group of identical cells (dimension
  ``group``, ``group_of_cell [course, wale]``): ``state_x [increment, group, unknown]``
  (alpha, beta, gamma, phi [rad], P [N]), ``state_W``, ``state_C``, ``state_s_AB`` [mm].
  Every increment by default; with ``output.cells_stride`` s > 1 only those of
  :func:`cells_increments` (the multiples of s, the program's turning points and the last), the
  ``increment`` coordinate holding their numbers, the attributes ``cells_stride`` and
  ``increments_written`` saying so;
- ``summary.json``: see :func:`patch_summary`;
- ``force_strain.png``, ``strain_map.png``, ``stage_map.png``; ``scene.resolved.toml``.

Files are built in a hidden sibling directory and renamed in, ``summary.json`` last.
"""
from __future__ import annotations

import io
import warnings as _warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..arrays import stride_select, turning_rows
from ..cell.history import STATUS_FORCE_CAP, STATUS_NAMES, STATUS_OK
from ..cell.material import DEFAULT_FORCE_CAP_TEXT
from ..cell.stages import FRICTION_MODELS, JAMMING_CRITERIA, LABEL_CODES, RELOAD_RULES, UNLOADING_RULES
from ..errors import KnitsimInputError
from ..patch.coupling import COL_NOT_CONVERGED, COL_OK, COLUMN_STATUS_NAMES, HELD_RETRIES
from ..patch.model import PARAM_NAMES, PatchModel
from ..patch.runner import PatchHistory
from .checks import (ENERGY_ERROR_SHARE, FORCE_CAP_RTOL, HEAD_OVERLAP_RTOL, ResultWarning, jam_width_floor, wale_spacing_below_jamming, compressive_rest_state, cut_by_force_cap,
                     cycle_warnings, cycle_work, energy_creating_loops, energy_loop_candidates, force_cap_reached, held_at_force_cap,
                     interpenetration, reloads_below_first_loading)
from .results import _num, rule_meaning, summary_json, warning_lines, write_result_set

CURVE_COLUMNS = ("increment", "cycle", "direction", "grip_strain", "force_N", "force_per_wale_N", "columns_held")
PATCH_OUTPUT_FILES = ("curve.csv", "columns.csv", "cells.nc", "scene.resolved.toml", "force_strain.png",
                      "strain_map.png", "stage_map.png", "summary.json")
_LABELS = {v: k for k, v in LABEL_CODES.items()}


@dataclass(frozen=True)
class SpecimenLayout:
    """What the cells of a patch stand for: single stitches, or blocks of a specimen.

    Attributes
    ----------
    blocks : bool
        True for a specimen (cells are blocks of stitches; ``bands x strips``), False for a patch
        of single stitches (``courses x wales``).
    course_count, wale_count : ndarray, shape [rows, columns]
        Stitches in series along the wale and wales in parallel that each cell stands for.
    width_mm, gauge_length_mm : float or None
        The specimen's width (sum of its strips' widths, wale count x W0) and the distance
        between its grips (None for a patch of single stitches without a gauge length).
    strip_width_mm : ndarray, shape [columns]
        Width of each column at rest (wale count x W0, mean over its rows) [mm].
    band_length_mm : ndarray, shape [rows]
        Rest length of each row (course count x C0, mean over the columns) [mm].
    column_wales : ndarray, shape [columns]
        Wales of each column: the mean of its cells' wale counts along its rest length (the
        divisor of its force per wale).
    column_courses : ndarray, shape [columns]
        Courses between the grips in each column (sum of its course counts).
    stitches : float
        Stitches the patch stands for (sum of course count x wale count).
    """

    blocks: bool
    course_count: np.ndarray
    wale_count: np.ndarray
    width_mm: float | None
    gauge_length_mm: float | None
    strip_width_mm: np.ndarray
    band_length_mm: np.ndarray
    column_wales: np.ndarray
    column_courses: np.ndarray
    stitches: float

    @property
    def rows(self) -> int:
        """Rows of cells (bands of a specimen, courses of a patch)."""
        return int(self.course_count.shape[0])

    @property
    def columns(self) -> int:
        """Columns of cells (strips of a specimen, wales of a patch)."""
        return int(self.course_count.shape[1])

    @property
    def wales_across(self) -> float:
        """Wales across the width: the sum of the columns' wale counts (the divisor of the grip force
        per wale)."""
        return float(np.sum(self.column_wales))

    def describe(self, max_items: int = 4) -> str:
        """One line: the grid and what it stands for (the header of ``knitsim run``)."""
        if not self.blocks:
            return (f"{self.columns} wales x {self.rows} courses = {self.rows * self.columns} cells (single "
                    "stitches)")
        wmin, wmax = self.wale_count.min(axis=0), self.wale_count.max(axis=0)

        def wales(j):
            return f"{wmin[j]:.4g}" if np.isclose(wmin[j], wmax[j], rtol=1e-9) else f"{wmin[j]:.4g}-{wmax[j]:.4g}"

        if self.columns <= max_items:
            strips = "; ".join(f"strip {j}: {wales(j)} wales x {self.column_courses[j]:.4g} courses"
                               for j in range(self.columns))
        else:
            strips = (f"strips of {self.wale_count.min():.4g}-{self.wale_count.max():.4g} wales x "
                      f"{self.column_courses.min():.4g}-{self.column_courses.max():.4g} courses")
        n = self.rows * self.columns
        return (f"specimen {self.width_mm:.4g} mm wide, {self.gauge_length_mm:.4g} mm between the grips (grip "
                f"strain = grip displacement / {self.gauge_length_mm:.4g} mm): {self.columns} strip{'s' * (self.columns != 1)} x {self.rows} band{'s' * (self.rows != 1)} = "
                f"{n} block{'s' * (n != 1)} standing for {self.stitches:,.0f} stitches ({strips})")

    def as_dict(self) -> dict:
        """The ``specimen`` entry of ``summary.json`` (per strip and per band)."""
        cc, wc = self.course_count, self.wale_count
        return {
            "width_mm": self.width_mm, "gauge_length_mm": self.gauge_length_mm, "bands": self.rows,
            "strips": self.columns, "blocks": self.rows * self.columns, "stitches": self.stitches,
            "wales_across": self.wales_across,
            "strip": [{"strip": j, "width_mm": float(self.strip_width_mm[j]), "wales": float(self.column_wales[j]),
                       "wales_min": float(wc[:, j].min()), "wales_max": float(wc[:, j].max()),
                       "courses": float(self.column_courses[j]), "stitches": float(np.sum(cc[:, j] * wc[:, j]))}
                      for j in range(self.columns)],
            "band": [{"band": i, "length_mm": float(self.band_length_mm[i]), "wales": float(np.sum(wc[i])),
                      "courses_min": float(cc[i].min()), "courses_max": float(cc[i].max())}
                     for i in range(self.rows)],
            "note": "each block of the bands x strips grid stands for course_count courses in series and "
                    "wale_count wales in parallel (cells.nc); a strip's force per wale is its total force over "
                    "its wale count (the mean along its rest length where its bands differ)"}


def specimen_layout(model: PatchModel | None, shape: tuple[int, int] | None = None) -> SpecimenLayout:
    """The :class:`SpecimenLayout` of a model (None: ``shape`` cells of single stitches)."""
    if model is None:
        if shape is None:
            raise ValueError("specimen_layout: give the model or the shape")
        ones = np.ones(shape)
        return SpecimenLayout(False, ones, ones, None, None, np.full(shape[1], np.nan), np.full(shape[0], np.nan),
                              np.ones(shape[1]), np.full(shape[1], float(shape[0])), float(shape[0] * shape[1]))
    cc, wc = np.asarray(model.course_count, float), np.asarray(model.wale_count, float)
    blocks = model.blocks
    W0, C0 = model.fields["W0"], model.fields["C0"]
    strip_w = (wc * W0).mean(axis=0)
    band_l = (cc * C0).mean(axis=1)
    return SpecimenLayout(blocks, cc, wc, float(strip_w.sum()) if blocks else None, model.gauge_length,
                          strip_w, band_l, np.asarray(model.column_wales(), float), cc.sum(axis=0),
                          float(np.sum(cc * wc)))


def _layout_of(h: PatchHistory, model: PatchModel | None) -> SpecimenLayout:
    """The layout of a history's model; a specimen's history needs its model (its counts are not in it)."""
    if model is None:
        wales = float(h.info.get("wales_represented", h.shape[1]))
        if not np.isclose(wales, h.shape[1], rtol=1e-12):
            raise ValueError("the history is a specimen's (cells stand for blocks of stitches): pass its model")
        return specimen_layout(None, h.shape)
    if tuple(model.shape) != tuple(h.shape):
        raise ValueError(f"model shape {model.shape} is not the history's {h.shape}")
    return specimen_layout(model)


#: a column whose cells' rest forces differ by more than this share of the largest is not balanced at rest
#: (identical cells give equal forces to rounding; :func:`_unbalanced_rest_columns`)
UNBALANCED_REST_RTOL = 1e-6


def columns_held(h: PatchHistory) -> np.ndarray:
    """Per increment, the columns (strips) whose force is held rather than the knit's: the column did not
    converge on it, or holds a cell stopped (failed, or at its force cap), whose last state it keeps."""
    if not h.n_increments:
        return np.zeros(0, dtype=np.int64)
    stopped = (np.asarray(h.groups["status"]) != STATUS_OK)[:, np.asarray(h.group_of_cell)].any(axis=1)
    return ((np.asarray(h.column_status) != COL_OK) | stopped).sum(axis=1)


def curve_csv(h: PatchHistory) -> str:
    """The text of ``curve.csv``; ``columns_held``: :func:`columns_held` (0: every column is the knit's)."""
    lines = [",".join(CURVE_COLUMNS)]
    # increment 0 is the rest state (grip strain 0); the program's increments are 1 .. n
    cyc0 = str(int(h.cycle[0])) if h.n_increments else "1"
    rest_grip = float(h.info.get("rest_grip_strain", 0.0))     # < 0: a pretensioned specimen at rest
    lines.append(",".join(["0", cyc0, "load", _num(rest_grip), _num(h.rest_force_N), _num(h.rest_force_per_wale_N),
                           "0"]))
    held = columns_held(h)
    for i in range(h.n_increments):
        lines.append(",".join([str(i + 1), str(int(h.cycle[i])), "load" if h.direction[i] > 0 else "unload",
                               _num(h.grip_strain[i]), _num(h.force_N[i]), _num(h.force_per_wale_N[i]),
                               str(int(held[i]))]))
    return "\n".join(lines) + "\n"


COLUMNS_COLUMNS = ("increment", "column", "wales", "force_N", "force_per_wale_N", "status", "iterations", "slack_mm")


def column_forces(h: PatchHistory, layout: SpecimenLayout) -> tuple[np.ndarray, np.ndarray]:
    """Total force [N] and force per wale [N] of each column, shape [n, columns] each.

    The history holds each column's force per wale (a strip's total over its wale count); its
    total force is that times the wale count (the solver's total to rounding; exactly it for
    single stitches)."""
    per_wale = np.asarray(h.column_force_N, float)
    if not layout.blocks:
        return per_wale, per_wale
    return per_wale * layout.column_wales[None, :], per_wale


def columns_csv(h: PatchHistory, layout: SpecimenLayout | None = None) -> str:
    """The text of ``columns.csv`` (one row per increment and column; module docstring)."""
    layout = layout or _layout_of(h, None)
    total, per_wale = column_forces(h, layout)
    wales = [_num(w) if layout.blocks else "1" for w in layout.column_wales]
    lines = [",".join(COLUMNS_COLUMNS)]
    for i in range(h.n_increments):
        for j in range(h.shape[1]):
            lines.append(f"{i + 1},{j},{wales[j]},{_num(total[i, j])},{_num(per_wale[i, j])},"
                         f"{COLUMN_STATUS_NAMES[int(h.column_status[i, j])]},{int(h.column_iterations[i, j])},"
                         f"{_num(h.column_slack_mm[i, j])}")
    return "\n".join(lines) + "\n"


#: the rule choices of a patch's cells, by name (cells.nc writes each as a flag variable)
RULE_CHOICES = {"friction": FRICTION_MODELS, "unloading_rule": UNLOADING_RULES, "reload_rule": RELOAD_RULES,
                "jamming_criterion": JAMMING_CRITERIA}


def rule_sets(model: PatchModel | None) -> list[dict] | None:
    """The rule sets the patch's cells ran with (``summary.json``: ``rules``), each with its meaning and the
    cells that ran it, in order of first appearance (course by course); None without a model.  A blind
    probe found a patch's summary naming no friction law or rule (``knitsim cell``'s names them)."""
    if model is None or not model.rules:
        return None
    names = [n for n in ("friction", "unloading_rule", "reload_rule", "jamming_criterion", "force_cap_N")
             if n in model.rules]
    shape = (model.courses, model.wales)
    cols = [np.broadcast_to(np.asarray(model.rules[n], dtype=object), shape).ravel() for n in names]
    # whether each cell's cap is the default, 50 B / d^2 of its yarn (PatchModel.cap_is_default)
    default = np.broadcast_to(np.asarray(getattr(model, "cap_is_default", False), dtype=bool), shape).ravel()
    seen: dict[tuple, int] = {}
    for key in zip(*cols, default):
        seen[key] = seen.get(key, 0) + 1
    out = []
    for key, count in seen.items():
        entry = {}
        key, is_default = key[:-1], bool(key[-1])
        friction = str(dict(zip(names, key)).get("friction", ""))
        for n, v in zip(names, key):
            if n == "force_cap_N":
                entry[n] = {"value": float(v), "meaning": "a cell stops when its force per wale reaches this value"
                            + (f" ({DEFAULT_FORCE_CAP_TEXT} of its yarn; rules.force_cap_N sets another)"
                               if is_default else "")}
            else:
                entry[n] = {"value": str(v), "meaning": rule_meaning(n, v, friction)}
        entry["cells"] = int(count)
        out.append(entry)
    return out


def _check_stride(stride) -> int:
    """``stride`` as an int, or a one-line error (the scene's ``output.cells_stride`` is checked when the scene
    is read; this is for a caller of the Python API)."""
    if isinstance(stride, (bool, np.bool_)) or not isinstance(stride, (int, np.integer)) or stride < 1:
        raise KnitsimInputError(f"cells_stride = {stride!r}: must be an integer >= 1")
    return int(stride)


def cells_increments(h: PatchHistory, stride: int = 1) -> np.ndarray:
    """The increment numbers (as in curve.csv, 1 .. n) that ``cells.nc`` holds at ``output.cells_stride``
    ``stride``: the multiples of ``stride``, every turning point of the grip program (the last increment
    before the direction changes: the peaks and valleys of the cycles) and the last increment.

    Parameters
    ----------
    h : PatchHistory
        The run (its ``direction`` per increment is the program's).
    stride : int, >= 1
        1: every increment.

    Returns
    -------
    ndarray of int64
        Increasing increment numbers; empty for a run of no increments.

    The turning points are kept so that a strided file still holds each cycle's peak and valley (the states
    a reader looks at first), the last so that it ends where the run ends."""
    return strided_increments(h.direction, stride)


def strided_increments(direction, stride: int = 1) -> np.ndarray:
    """:func:`cells_increments` of a program whose increments go in ``direction`` (+1 / -1 each, the
    :class:`~knitsim.cell.load_program.LoadProgram`'s or the run's): known before the run (its memory check)."""
    stride = _check_stride(stride)
    n = len(np.asarray(direction).ravel())
    # turning_rows are 0-based rows; increment k is row k - 1
    return stride_select(np.arange(1, n + 1), stride, keep=turning_rows(direction) + 1)


def cells_written(h: PatchHistory, stride: int = 1) -> dict:
    """What ``cells.nc`` holds at ``stride`` (summary.json's ``cells_nc`` where the stride is not 1):
    ``cells_stride``, ``increments_written`` (in words) and how many of the run's increments it holds (their
    numbers are cells.nc's ``increment`` coordinate)."""
    inc = cells_increments(h, stride)
    return {"cells_stride": int(stride), "increments_written": _written_sentence(stride),
            "increments_in_file": int(len(inc)), "increments_in_run": int(h.n_increments)}


def _written_sentence(stride: int) -> str:
    return (f"increments at multiples of {int(stride)}, the program's turning points (the last increment before "
            "the grip turns) and the last; curve.csv and columns.csv hold every increment")


def _history_rows(h: PatchHistory, rows: np.ndarray) -> PatchHistory:
    """A copy of ``h`` holding the rows ``rows`` (0-based) of every per-increment record only: what a strided
    cells.nc is built from (the run's own history, which the checks read, is left whole)."""
    from dataclasses import replace
    rows = np.asarray(rows, dtype=np.int64)
    per_row = ("grip_strain", "cycle", "direction", "force_N", "force_per_wale_N", "column_force_N",
               "column_status", "column_iterations", "column_slack_mm")
    return replace(h, groups={k: np.asarray(v)[rows] for k, v in h.groups.items()},
                   **{k: np.asarray(getattr(h, k))[rows] for k in per_row})


def cells_dataset(h: PatchHistory, fields: dict | None = None, layout: SpecimenLayout | None = None,
                  rules: dict | None = None, stride: int = 1):
    """The per-cell fields as an :class:`xarray.Dataset` (see the module docstring); ``rules``: the model's
    rules of every cell (``PatchModel.rules``), written as flag variables (``friction``: which cells are
    Coulomb, which Dahl) and ``force_cap_N``.

    ``stride`` (``output.cells_stride``): every variable with an ``increment`` dimension holds the
    increments of :func:`cells_increments` only, numbered as in curve.csv (``ds.sel(increment=k)`` reads
    increment k), and the attributes ``cells_stride`` and ``increments_written`` say so; 1 (the default)
    writes every increment, as before the option existed (no such attributes)."""
    import xarray as xr
    layout = layout or _layout_of(h, None)
    increments = cells_increments(h, stride)
    n_run = h.n_increments
    strided = int(stride) != 1
    if strided:
        # only the written rows are expanded to cells (a 300 x 300 patch's per-cell fields are 0.2 GB a field)
        h = _history_rows(h, increments - 1)
    dims = ("increment", "course", "wale")
    meanings = " ".join(_LABELS[k] for k in sorted(_LABELS))
    n, (courses, wales) = h.n_increments, h.shape
    total, per_wale = column_forces(h, layout)
    block = layout.blocks
    ds = xr.Dataset(
        {"strain": (dims, h.cell_field("strain"), {"long_name": "strain of the course length (C - C0)/C0",
                                                   "units": "1"}),
         "phi": (dims, h.cell_field("phi"), {"long_name": "friction angle at the crossing", "units": "rad"}),
         "force_per_wale_N": (dims, h.cell_field("F"), {
             "long_name": "force per wale of the cell" + (" (each of the block's wale_count wales; the block "
                                                          "carries wale_count x it)" if block else ""),
             "units": "N"}),
         "stage": (dims, h.cell_field("label").astype(np.int8),
                   {"long_name": "stage label", "flag_values": np.array(sorted(_LABELS), np.int8),
                    "flag_meanings": meanings}),
         "status": (dims, h.cell_field("status").astype(np.int8),
                    {"long_name": "cell status", "flag_values": np.array(sorted(STATUS_NAMES), np.int8),
                     "flag_meanings": " ".join(STATUS_NAMES[k] for k in sorted(STATUS_NAMES))}),
         "column_force_N": (("increment", "wale"), total, {
             "units": "N", "long_name": "total force of the column" + (" (strip)" if block else "")}),
         "column_force_per_wale_N": (("increment", "wale"), per_wale, {
             "units": "N", "long_name": "force per wale of the column (its total force / column_wales)"}),
         "column_wales": (("wale",), np.asarray(layout.column_wales, float), {
             "units": "1", "long_name": "wales of the column (1, or a strip's wale count, the mean along its rest "
                                        "length)"}),
         "column_status": (("increment", "wale"), h.column_status.astype(np.int8),
                           {"flag_values": np.array(sorted(COLUMN_STATUS_NAMES), np.int8),
                            "flag_meanings": " ".join(COLUMN_STATUS_NAMES[k] for k in sorted(COLUMN_STATUS_NAMES))}),
         "force_N": (("increment",), h.force_N, {"units": "N", "long_name": "grip force"}),
         "course_count": (("course", "wale"), np.asarray(layout.course_count, float), {
             "units": "1", "long_name": "courses in series that the cell stands for (band length / C0)"}),
         "wale_count": (("course", "wale"), np.asarray(layout.wale_count, float), {
             "units": "1", "long_name": "wales in parallel that the cell stands for (strip width / W0)"})},
        # increment numbers as in curve.csv (0 is the rest state, not stored here; at a stride only those
        # written), so ds.sel(increment=k, course=i, wale=j) reads one cell at one row; direction as in the CSV
        # files
        coords={"increment": increments.astype(np.int32), "course": np.arange(courses, dtype=np.int32),
                "wale": np.arange(wales, dtype=np.int32),
                "grip_strain": (("increment",), h.grip_strain), "cycle": (("increment",), h.cycle.astype(np.int32)),
                "direction": (("increment",), np.where(h.direction > 0, "load", "unload"))},
        attrs={"title": "knitsim patch: per-cell fields",
               "layout": ("cell [course, wale] = block [band, strip] of a specimen; band 0 at the lower grip"
                          if block else "cell [course, wale]; course 0 at the lower grip"),
               "cell_is": "block of stitches" if block else "stitch",
               "stitches": layout.stitches, "conventions": "units N, mm, rad"})
    if strided:
        # what the file holds (a stride-1 file carries neither: every increment, as files always did)
        ds.attrs["cells_stride"] = np.int32(stride)
        ds.attrs["increments_written"] = f"{_written_sentence(stride)}: {n} of the run's {n_run} increments"
    if block:
        ds.attrs["width_mm"] = float(layout.width_mm)
    if layout.gauge_length_mm is not None:
        ds.attrs["gauge_length_mm"] = float(layout.gauge_length_mm)
    for n, choices in RULE_CHOICES.items():
        if rules and n in rules:
            v = np.broadcast_to(np.asarray(rules[n], dtype=object), (courses, wales))
            code = np.vectorize(lambda x: choices.index(str(x)), otypes=[np.int8])(v)
            ds[n] = (("course", "wale"), code, {"long_name": f"cell rule {n}",
                                                "flag_values": np.arange(len(choices), dtype=np.int8),
                                                "flag_meanings": " ".join(choices)})
    if rules and "force_cap_N" in rules:
        ds["force_cap_N"] = (("course", "wale"), np.broadcast_to(np.asarray(rules["force_cap_N"], dtype=float),
                                                                 (courses, wales)).copy(),
                             {"long_name": "cell rule force_cap_N: a cell stops at this force per wale", "units": "N"})
    for n, arr in (fields or {}).items():
        attrs = {"long_name": f"cell parameter {n}"}
        if n == "in_plane_width":
            attrs["comment"] = "NaN where not given: the cell jams with its d"
        ds[n] = (("course", "wale"), np.asarray(arr, dtype=np.float64), attrs)
    if all(k in h.groups for k in ("x", "W", "s_AB")):
        # the geometry is stored per group (identical cells share it), expanded by group_of_cell
        ds["group_of_cell"] = (("course", "wale"), np.asarray(h.group_of_cell, dtype=np.int32),
                               {"long_name": "group of identical cells solved once"})
        ds = ds.assign_coords(group=np.arange(len(h.groups["W"][0]), dtype=np.int32),
                              state=np.array(["alpha", "beta", "gamma", "phi", "P"]))
        ds["state_x"] = (("increment", "group", "state"), np.asarray(h.groups["x"], dtype=np.float64),
                         {"long_name": "cell state (alpha, beta, gamma, phi, P)", "units": "rad rad rad rad N"})
        for k, long_name in (("W", "wale width (eq 6)"), ("C", "course length of the cell"),
                             ("s_AB", "arc length A -> B (eq 8)")):
            ds[f"state_{k}"] = (("increment", "group"), np.asarray(h.groups[k], dtype=np.float64),
                                {"long_name": long_name, "units": "mm"})
        rest = h.group_rest or {}
        if all(k in rest for k in ("x", "C", "F")):
            # increment 0, the rest state (not on the increment axis: the per-cell fields start at 1); the
            # USD export draws it as time code 0 (knitsim.usd.from_results.REST_VARIABLES)
            ds["rest_state_x"] = (("group", "state"), np.asarray(rest["x"], dtype=np.float64),
                                  {"long_name": "cell state at rest, increment 0 (alpha, beta, gamma, phi, P)",
                                   "units": "rad rad rad rad N"})
            ds["rest_state_C"] = (("group",), np.asarray(rest["C"], dtype=np.float64),
                                  {"long_name": "course length of the cell at rest", "units": "mm"})
            ds["rest_force_per_wale_N"] = (("group",), np.asarray(rest["F"], dtype=np.float64),
                                           {"long_name": "force per wale of the cell at rest", "units": "N"})
            for k, long_name in (("W", "wale width at rest (eq 6)"), ("s_AB", "arc length A -> B at rest (eq 8)")):
                if k in rest:
                    ds[f"rest_state_{k}"] = (("group",), np.asarray(rest[k], dtype=np.float64),
                                             {"long_name": long_name, "units": "mm"})
            if "label" in rest:
                ds["rest_stage"] = (("group",), np.asarray(rest["label"]).astype(np.int8),
                                    {"long_name": "stage label at rest", "flag_values": np.array(sorted(_LABELS), np.int8),
                                     "flag_meanings": meanings})
    if "head_gap" in h.groups:
        ds["head_gap"] = (dims, h.cell_field("head_gap"),
                          {"long_name": "centreline gap between the heads of neighbouring loops", "units": "mm"})
        ds["interpenetrating"] = (dims, h.cell_field("interpenetrating").astype(np.int8),
                                  {"long_name": "1 where the heads overlap (gap below the in-plane width)"})
    return ds


def _encoding(ds) -> dict:
    """gzip level 1 after HDF5's byte shuffle, chunked along the increment (a frame is read without the whole
    file).  The write is most of a large patch's output time (a 300 x 300 random patch through 3 cycles: 83 s of
    171 s on a GPU host, 1.5 GB at level 4 without the shuffle); on a 100 x 100 one (10,000 cells x 310
    increments) level 4 took 5.0 s for 171.5 MB, level 1 after the shuffle 3.4 s for 151.8 MB (the shuffle
    groups the doubles' like bytes, which compress better at the faster level).  The values are the same
    (read back identical); a small uniform patch's file grows a little (the bundled specimen: 336 to 517 kB)."""
    enc = {}
    for name, var in ds.data_vars.items():
        if var.dtype.kind in "fiu" and var.ndim:
            chunks = tuple(min(64, s) if d == "increment" else s for d, s in zip(var.dims, var.shape))
            if all(c > 0 for c in chunks):
                enc[name] = {"zlib": True, "complevel": 1, "shuffle": True, "chunksizes": chunks}
    return enc


def cells_nc(h: PatchHistory, fields: dict | None = None, layout: SpecimenLayout | None = None,
             rules: dict | None = None, stride: int = 1) -> bytes:
    """``cells.nc`` as bytes: netCDF-4 (HDF5) through h5netcdf, compressed and chunked by increment; ``stride``:
    ``output.cells_stride`` (:func:`cells_dataset`)."""
    ds = cells_dataset(h, fields, layout, rules, stride)
    return bytes(ds.to_netcdf(engine="h5netcdf", encoding=_encoding(ds)))


@dataclass(frozen=True)
class ForceCapRows:
    """Where a patch's force is its cells' force cap (:func:`force_cap_rows`).

    Attributes
    ----------
    rows : ndarray of bool, shape [n]
        Increments where some cell stopped at its cap or is held at it.
    group_at_cap : ndarray of bool, shape [n_groups]
        Groups at the cap at some increment; ``group_stopped`` those stopped (status force_cap).
    first_stop : int or None
        The first increment where a cell stopped at its cap (status force_cap).
    caps : ndarray or None
        The caps of the groups at the cap (None: the model was not given).
    column_rows : ndarray of bool, shape [n, columns]
        Increments where a column holds a cell at its cap (None where built without it).
    """

    rows: np.ndarray
    group_at_cap: np.ndarray
    group_stopped: np.ndarray
    first_stop: int | None
    caps: np.ndarray | None
    column_rows: np.ndarray | None = None


def force_cap_rows(h: PatchHistory, model: PatchModel | None = None) -> ForceCapRows:
    """Increments and cells at the force cap (:func:`knitsim.io.checks.held_at_force_cap`, per group).

    Without ``model`` the caps are unknown and only cells stopped at the cap (status force_cap) count."""
    from ..cell.history import STATUS_FORCE_CAP

    n_groups = int(h.group_of_cell.max()) + 1 if h.group_of_cell.size else 0
    empty = np.zeros(n_groups, bool)
    if not h.n_increments or not n_groups:
        return ForceCapRows(np.zeros(h.n_increments, bool), empty, empty, None, None,
                            np.zeros((h.n_increments, h.shape[1]), bool))
    goc = np.asarray(h.group_of_cell)
    caps = None
    if model is not None and "force_cap_N" in model.rules:
        cap_cell = np.asarray(model.rules["force_cap_N"], dtype=float)
        caps = np.zeros(n_groups)
        caps[goc.ravel()] = np.broadcast_to(cap_cell, goc.shape).ravel()   # identical cells share their rules
    # the columns holding each group: a group is held where one of them did not converge or stopped.  By the
    # distinct (group, column) pairs of the cells, not a columns x groups matrix: that matrix's products took
    # 24 s on a 300 x 300 random patch through 310 increments (90,000 groups, 300 columns)
    pair_g, pair_c = _group_column_pairs(goc)
    col_bad = _any_by(np.asarray(h.column_status)[:, pair_c] != COL_OK, pair_g, n_groups)
    status = np.asarray(h.groups["status"])
    at = held_at_force_cap(h.groups["F"], status, caps, col_bad)
    stopped = status == STATUS_FORCE_CAP
    first = np.nonzero(stopped.any(axis=1))[0]
    return ForceCapRows(at.any(axis=1), at.any(axis=0), stopped.any(axis=0),
                        int(first[0]) if len(first) else None,
                        None if caps is None else caps[at.any(axis=0)],
                        _any_by(at[:, pair_g], pair_c, h.shape[1]))


def _group_column_pairs(goc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct (group, column) pairs of a patch's cells (``goc``: group of each cell, [courses, wales]),
    as two arrays sorted by group then column."""
    wales = goc.shape[1]
    key = np.unique(goc.astype(np.int64) * wales + np.arange(wales)[None, :])
    return key // wales, key % wales


def _any_by(flags: np.ndarray, owner: np.ndarray, n_owners: int) -> np.ndarray:
    """``out[:, o]`` = any of ``flags[:, k]`` over the k with ``owner[k] == o`` (False where o owns none);
    ``flags`` shape [n, k]."""
    out = np.zeros((flags.shape[0], n_owners), bool)
    if flags.shape[1] == 0:
        return out
    order = np.argsort(owner, kind="stable")
    o = owner[order]
    starts = np.flatnonzero(np.r_[True, o[1:] != o[:-1]])
    out[:, o[starts]] = np.logical_or.reduceat(flags[:, order], starts, axis=1)
    return out


def _force_cap_warnings(h: PatchHistory, fc: ForceCapRows, layout: SpecimenLayout, peak: float) -> list[ResultWarning]:
    """``force_cap_reached`` (cells stopped at or held at their cap) and, where a stop at the cap left
    unloadings of the program to the stopped columns, ``program_cut_by_force_cap``."""
    if not fc.rows.any():
        return []
    cells_of = np.bincount(np.asarray(h.group_of_cell).ravel(), minlength=len(fc.group_at_cap))
    at_cell = fc.group_at_cap[h.group_of_cell]
    what, column = ("block", "strip") if layout.blocks else ("cell", "wale column")
    cap_text, strip_caps = _specimen_cap(h, fc, layout, at_cell)
    out = force_cap_reached(h.grip_strain, fc.rows, fc.caps, cells=int(h.group_of_cell.size),
                            cells_at_cap=int(cells_of[fc.group_at_cap].sum()),
                            cells_stopped=int(cells_of[fc.group_stopped].sum()),
                            columns=int(h.shape[1]), columns_at_cap=int(at_cell.any(axis=0).sum()), peak=peak,
                            what=what, column=column, remedy=(
                                f", or a smaller specimen.pretension ({pre:g}: the knit starts stretched)"
                                if (pre := float(h.info.get("pretension") or 0.0)) > 0 else ""), cap_text=cap_text)
    if fc.first_stop is not None:
        caps = strip_caps if strip_caps is not None else fc.caps
        cap = float(np.max(caps)) if caps is not None and len(caps) else float("nan")
        # cut_by_force_cap decides whether unloadings were left (its wording is a cell's: rewritten for a patch)
        cut = cut_by_force_cap(h.grip_strain, h.direction, h.cycle, fc.first_stop, cap)
        k = fc.first_stop
        from ..cell.history import STATUS_FORCE_CAP
        # the columns stopped at that grip strain (a blind probe read "3 of 3 stopped at 0.33" where two went on
        # to 0.71: the count was the run's end), and those that stop later
        stopped_cols = (np.asarray(h.groups["status"])[k] == STATUS_FORCE_CAP)[h.group_of_cell].any(axis=0)
        later_cols = fc.group_stopped[h.group_of_cell].any(axis=0) & ~stopped_cols
        n_stop, n_cols = int(stopped_cols.sum()), int(h.shape[1])
        c_stop, c_last = int(h.cycle[k]), int(h.cycle.max())
        rest = (f"the rest of cycle {c_stop}" + (f" and cycles {c_stop + 1}-{c_last}" if c_last > c_stop + 1 else
                                                 f" and cycle {c_last}" if c_last > c_stop else ""))
        # the rows after the stop are in curve.csv: the stopped columns keep their last state (curve.csv's
        # columns_held) while the grip moves on (and the other columns follow it), so the grip force there is
        # not the knit's, and the cycle figures stop at the stop (before, the message said "not run")
        others = (f"; the other {n_cols - n_stop} {column}(s) follow the grip" if n_stop < n_cols else "")
        if later_cols.any():
            grp_stop = np.asarray(h.groups["status"]) == STATUS_FORCE_CAP
            col_first = [int(np.flatnonzero(grp_stop[:, np.unique(np.asarray(h.group_of_cell)[:, j])].any(axis=1))[0])
                         for j in np.flatnonzero(later_cols)]
            others += (f" ({int(later_cols.sum())} of them stop at the cap later, the first at grip strain "
                       f"{float(h.grip_strain[min(col_first)]):.4g})")
        out += [ResultWarning(w.code, (
            f"{n_stop} of {n_cols} {column}(s) stopped at the force cap"
            + ((f" ({cap:.4g} N per wale of the strip)" if strip_caps is not None else f" ({cap:g} N per wale)")
               if np.isfinite(cap) else "")
            + f" at grip strain {float(h.grip_strain[k]):.4g} in cycle {c_stop} of {c_last}: from there the stopped "
            f"{column}(s) keep their last state while the grip moves on (curve.csv's columns_held){others}, so the "
            f"grip force is not the knit's and the figures of {rest} are not given; raise force_cap_N to run "
            f"{'them' if c_last > c_stop else 'it'}")) for w in cut[:1]]
    return out


def _specimen_cap(h: PatchHistory, fc: ForceCapRows, layout: SpecimenLayout,
                  at_cell: np.ndarray) -> tuple[str | None, np.ndarray | None]:
    """A specimen's force cap as its force per wale says it, where a capped block's wales are not its strip's mean:
    the message's cap and the caps per wale of the strip of the blocks at the cap; ``(None, None)`` elsewhere.

    A block's cap is per wale of the block (``force_cap_N`` of its cell); its strip carries one total force, cap x
    the block's wales, and the specimen's force per wale is that total over the strip's mean wales.  A probe's
    specimen of two bands, 6.82 and 5.45 wales, capped at 0.5 N per wale, read "the force is the force cap (0.5 N
    per wale) ... the peak 0.4426 N per wale is the cap": the narrow band's blocks at 0.5 N per wale of their 5.45
    wales, 2.727 N, are 0.4444 N per wale of the strip's 6.136."""
    if not layout.blocks or fc.caps is None or not at_cell.any():
        return None, None
    caps_g = np.zeros(len(fc.group_at_cap))
    caps_g[fc.group_at_cap] = fc.caps
    wales = np.broadcast_to(np.asarray(layout.wale_count, float), at_cell.shape)
    strip_wales = np.broadcast_to(np.asarray(layout.column_wales, float)[None, :], at_cell.shape)
    block_cap = caps_g[np.asarray(h.group_of_cell)]
    per_strip = block_cap * wales / strip_wales
    if np.allclose(per_strip[at_cell], block_cap[at_cell], rtol=1e-9, atol=0.0):
        return None, None
    i, j = (int(v) for v in np.argwhere(at_cell)[0])
    vals = np.unique(np.round(per_strip[at_cell], 12))
    head = f"{vals[0]:.4g}" if len(vals) == 1 else f"{vals.min():.4g}-{vals.max():.4g}"
    return (f"{head} N per wale of the strip: e.g. the block at band {i}, strip {j} capped at {block_cap[i, j]:g} N "
            f"per wale of its {wales[i, j]:.4g} wales, {block_cap[i, j] * wales[i, j]:.4g} N in all, over the strip's "
            f"{strip_wales[i, j]:.4g} wales"), per_strip[at_cell]


def _unbalanced_rest_columns(h: PatchHistory, row_key: str, col_key: str) -> list[ResultWarning]:
    """``rest_state_unbalanced``: columns whose cells carry different forces at rest.

    Each cell's rest state is its own (C = C0, its phi0); cells in series carry one force, so a column of
    unequal rest forces (zones in series, a phi0 field) is not in equilibrium at rest.  The first increment
    balances it with every cell moving in the grip's direction: a cell that shortens there moves back along its
    loading branch instead of reversing (Table 4's SF-), and curve.csv's row 0 is the mean of the unequal rest
    forces.  (A blind probe's E-glass/basalt column, by its own solver with each cell's own direction: 0.6 % of
    the force at grip strain 0.01, the basalt cell shortening 15 times too far.)"""
    rest = h.group_rest or {}
    if "F" not in rest or not h.group_of_cell.size:
        return []
    F = np.asarray(rest["F"], float)[np.asarray(h.group_of_cell)]
    if not np.all(np.isfinite(F)):
        return []
    lo, hi = F.min(axis=0), F.max(axis=0)
    scale = np.maximum(np.abs(F).max(axis=0), 1e-12)
    bad = np.flatnonzero(hi - lo > UNBALANCED_REST_RTOL * scale)
    if not bad.size:
        return []
    j = int(bad[np.argmax((hi - lo)[bad])])
    # where in the column (a blind probe's tight stitch at 10.4 N between loose ones: the warning named the column
    # alone, and the column, held from its first increment, nothing else)
    at = f"lowest at {row_key} {int(np.argmin(F[:, j]))}, highest at {row_key} {int(np.argmax(F[:, j]))}"
    return [ResultWarning("rest_state_unbalanced", (
        f"{bad.size} of {F.shape[1]} {col_key} column(s) carry unequal forces at rest (their cells' own rest states; "
        f"the widest, {col_key} {j}: {lo[j]:.4g} to {hi[j]:.4g} N per wale, {at}): not an equilibrium of cells in "
        "series. "
        "The first increment balances them with every cell moving in the grip's direction (a cell that shortens "
        "there moves back along its loading branch rather than reversing), so the first rows are approximate, and "
        "curve.csv's row 0 is the mean of the unequal rest forces"))]


def _run_stop(h: PatchHistory, model: PatchModel | None, layout: SpecimenLayout, row_key: str,
              col_key: str, fc: ForceCapRows) -> tuple[int | None, float | None, list[ResultWarning]]:
    """The first row from which the grip force is no longer the knit's, the grip strain the cycle figures
    are cut at, and the warnings saying so; (None, None, []) where there is none.  Three cases, the earliest
    one counts:

    - ``run_stopped_by_failed_cells``: a cell failed (no_convergence, event_not_located); its column
      holds the cell's last converged state from there.  Where, the first failed cell and why
      (:func:`knitsim.cell.history.solver_stop_reason`);
    - ``run_held_by_unconverged_columns``: a column stops converging and holds its last converged state
      (its force constant) to the end of the run, the grip moving (the coupling finds no balance of its
      cells' forces), below its cells' force cap (held at the cap, ``force_cap_reached`` says so).  A column that fails to converge on an increment and moves again later is not this:
      those increments are counted in ``non_converged_column_increments`` and marked;
    - cells stopped at their force cap with unloadings of the program left: the row reaching the cap is
      the last of the knit's, their columns hold the cap after it (cut at that row's grip strain; the
      warnings ``force_cap_reached`` and ``program_cut_by_force_cap`` say so, none is added here).  A stop
      at the cap on the last loading is an expected end, and cuts nothing."""
    from ..cell.history import STATUS_EVENT_NOT_LOCATED, STATUS_NO_CONVERGENCE, solver_stop_reason

    n = h.n_increments
    if not n:
        return None, None, []
    goc = np.asarray(h.group_of_cell)
    caps = np.full(goc.shape, np.inf)
    if model is not None and "force_cap_N" in model.rules:
        caps = np.broadcast_to(np.asarray(model.rules["force_cap_N"], float), goc.shape)
    what, column = ("block", "strip") if layout.blocks else ("cell", "column")

    def not_run(stop: int) -> str:
        cut = [int(k) for k in np.unique(h.cycle) if np.nonzero(h.cycle == k)[0][0] >= stop]
        return f" (cycle(s) {', '.join(map(str, cut))} not run)" if cut else ""

    out = []
    status = np.asarray(h.groups["status"])
    failed = np.isin(status, (STATUS_NO_CONVERGENCE, STATUS_EVENT_NOT_LOCATED))
    rows = np.nonzero(failed.any(axis=1))[0]
    if len(rows):
        stop = int(rows[0])
        g = int(np.nonzero(failed[stop])[0][0])
        i, j = (int(v) for v in np.argwhere(goc == g)[0])
        why = solver_stop_reason(int(status[stop, g]), float(h.groups["C"][stop, g]) / float(h.C0[i, j]) - 1.0, None,
                                 _LABELS.get(int(h.groups["label"][stop, g]), "unknown stage"),
                                 float(h.groups["F"][stop, g]), float(caps[i, j]), int(h.direction[stop]) > 0)
        cells = int(failed.any(axis=0)[goc].sum())
        out.append((stop, float(h.grip_strain[stop]), ResultWarning("run_stopped_by_failed_cells", (
            f"{cells} {what}(s) failed from grip strain {h.grip_strain[stop]:.4g} (increment {stop + 1}); the first, "
            f"{row_key} {i} {col_key} {j}: {why}. Their {column}s hold the last converged state, so from there the "
            f"grip force is not the knit's: the cycle figures stop there" + not_run(stop)))))
    # a column held to the end: its force is constant from its last converged state on, and the hold begins
    # with an increment it did not converge on (a slack column's zero force is constant too, but converged)
    unconverged = np.asarray(h.column_status) == COL_NOT_CONVERGED
    Fcol = np.asarray(h.column_force_N)
    held_from = {}
    for j in np.nonzero(unconverged.any(axis=0))[0]:
        moved = np.nonzero(Fcol[:, j] != Fcol[-1, j])[0]
        c0 = int(moved[-1]) + 1 if len(moved) else 0
        if Fcol[-1, j] >= (1.0 - FORCE_CAP_RTOL) * float(np.min(caps[:, j])):
            continue                    # held at its cells' force cap: force_cap_reached says so
        for r in (c0, c0 + 1):
            if r < n and unconverged[r, j] and np.ptp(h.grip_strain[r:]) > 0:
                held_from[int(j)] = r
                break
    if held_from:
        held = min(held_from.values())
        cols = sorted(held_from)
        j = min(cols, key=lambda c: (held_from[c], c))
        F = float(Fcol[held, j])
        jammed = bool(np.any(h.groups["label"][held, goc[:, j]] == LABEL_CODES["jamming"]))
        cap = float(np.min(caps[:, j]))
        advice = (f"; its {what}s are jammed and the jammed branch's force diverges: a force_cap_N below {F:.3g} N "
                  "ends the run there as expected" if jammed and int(h.direction[held]) > 0 and F < cap else "")
        out.append((held, float(h.grip_strain[held]), ResultWarning("run_held_by_unconverged_columns", (
            f"from grip strain {h.grip_strain[held]:.4g} (increment {held + 1}), {len(cols)} of {h.shape[1]} "
            f"{column}(s) no longer converge: the coupling finds no balance of their {what}s' forces, and they hold "
            f"their last converged state to the end of the run, so the grip force there is not the knit's: the "
            f"cycle figures stop there (a column that failed in {HELD_RETRIES} loading increments in a row is not "
            f"tried again until the grip turns: its iterations read 0)" + not_run(held) + f"; the first, {col_key} {j}, held at {F:.4g} N per "
            f"wale{' (jamming)' if jammed else ''}" + advice))))
    if fc.first_stop is not None and np.any(h.direction[fc.first_stop:] < 0):
        out.append((fc.first_stop + 1, float(h.grip_strain[fc.first_stop]), None))
    if not out:
        return None, None, []
    stop, cut_at, _ = min(out, key=lambda o: o[0])
    return stop, cut_at, [w for _, _, w in out if w is not None]


#: how a cycle's residual grip strain is obtained (summary.json: ``residual_grip_strain_from``)
RESIDUAL_FROM = {
    "slack_lengths": "located: the grip strain at which the last column went slack (F = 0), from the columns' "
                     "slack lengths on the first row without grip force (each cell keeps the length at which it "
                     "located its own F = 0)",
    "linear": "linear interpolation of the grip force between the last row with force and the first without",
    "secant": "the last two rows with grip force extrapolated linearly to F = 0 (no slack lengths to read; "
              "error at most h^2 |F''/F'|, h the increment)",
}
#: how the first jamming is obtained (summary.json: ``grip_strain_at_first_jamming_from``)
FIRST_JAMMING_FROM = {
    "located": "located between rows: each cell jamming on the first row with a jammed cell has its jamming "
               "quantity (W - 4 w, or the head gap - w, from cells.nc's state) extrapolated linearly from its two "
               "unjammed rows before to zero; the earliest counts (error at most h^2 |q''/q'|, h the increment: "
               "2e-5 at h = 0.01 on the calibrated E-glass knit, against 0.0075 for the row)",
    "row": "the first row with a jammed cell, not located between rows (the rows before do not allow it)",
}


def _residual_grip_strain(h: PatchHistory, a: int, b: int, ref_length: float) -> tuple[float, str]:
    """Where the grip force reaches 0 between rows ``a`` (F > 0) and ``b`` (F <= 0) of an unloading.

    A slack column keeps the length at which its cells located F = 0 (:class:`~knitsim.patch.coupling.PatchSolver`:
    its cells' elongations exceed the grip displacement by ``column_slack_mm``), so the grip strain at which
    column j went slack is ``e[b] + slack_j / ref_length``, and the grip force is 0 from the last of them,
    the smallest.  Where row ``b`` carries a negative force (no slack), or the slack lengths do not fall
    between the rows, the rows are interpolated (:data:`RESIDUAL_FROM`)."""
    F, e = np.asarray(h.force_N, float), np.asarray(h.grip_strain, float)
    lo, hi = min(e[a], e[b]), max(e[a], e[b])
    tol = 1e-9 * max(abs(hi), abs(lo), 1.0)
    if F[b] == 0.0 and a != b:
        colF = np.asarray(h.column_force_N, float)[b]
        slack = np.asarray(h.column_slack_mm, float)[b]
        if np.all(colF == 0.0) and np.all(np.isfinite(slack)) and ref_length > 0:
            at = float(np.min(e[b] + slack / ref_length))
            if lo - tol <= at <= hi + tol:
                return float(np.clip(at, lo, hi)), "slack_lengths"
        a0 = a - 1
        if a0 >= 0 and h.direction[a0] == h.direction[a] and F[a0] > F[a] > 0 and e[a0] != e[a]:
            at = float(e[a] - F[a] * (e[a0] - e[a]) / (F[a0] - F[a]))
            return float(np.clip(at, lo, hi)), "secant"
    t = F[a] / (F[a] - F[b])
    return float(e[a] + t * (e[b] - e[a])), "linear"


def _first_jamming(h: PatchHistory) -> tuple[float | None, str | None]:
    """The grip strain of the first jamming, located between rows where the cells' states allow it
    (:data:`FIRST_JAMMING_FROM`), and how it was obtained; (None, None) where no cell jams.

    A jammed cell holds its criterion (W = 4 w, or the head gap = w, w the in-plane width); on its two rows
    before, unjammed on the same branch, the quantity q = W - 4 w (or gap - w) falls towards 0.  The secant
    through them reaches 0 at the located jamming to O(h^2) (the 1 x 1 patch of the E-glass knit at increment
    0.01: 0.47253 against the cell's 0.47251)."""
    label = np.asarray(h.groups["label"])
    jam = label == LABEL_CODES["jamming"]
    rows = np.nonzero(jam.any(axis=1))[0]
    if not len(rows):
        return None, None
    b = int(rows[0])
    e, d = np.asarray(h.grip_strain, float), np.asarray(h.direction)
    row = float(e[b])
    if (b < 2 or "W" not in h.groups or h.group_d_jam is None or not (d[b - 2] == d[b - 1] == d[b])
            or e[b - 2] == e[b - 1]):
        return row, "row"
    w = np.asarray(h.group_d_jam, float)
    W = np.asarray(h.groups["W"], float)
    gap = np.asarray(h.groups["head_gap"], float) if "head_gap" in h.groups else None
    found = []
    for g in np.nonzero(jam[b])[0]:
        # the criterion the jammed state holds: W = 4 w, or the head gap = w
        qs = [W[:, g] - 4.0 * w[g]] + ([gap[:, g] - w[g]] if gap is not None else [])
        q = min(qs, key=lambda v: abs(v[b]) if np.isfinite(v[b]) else np.inf)
        if not (np.isfinite(q[b]) and abs(q[b]) <= 1e-6 * max(w[g], 1e-12)):
            continue
        q1, q2 = q[b - 2], q[b - 1]
        if not (np.isfinite(q1) and np.isfinite(q2) and q1 > q2 > 0):
            continue
        at = e[b - 1] + q2 * (e[b - 1] - e[b - 2]) / (q1 - q2)
        found.append(float(np.clip(at, min(e[b - 1], e[b]), max(e[b - 1], e[b]))))
    if not found:
        return row, "row"
    # the earliest on this branch: the smallest grip strain while loading, the largest while unloading
    return (min(found) if d[b] > 0 else max(found)), "located"


def _group_C0(h: PatchHistory) -> tuple[np.ndarray, np.ndarray]:
    """Per group: its rest course length C0 [mm] (identical cells share it), and how many cells it stands for."""
    goc = np.asarray(h.group_of_cell)
    n_groups = int(goc.max()) + 1 if goc.size else 0
    C0 = np.zeros(n_groups)
    C0[goc.ravel()] = np.asarray(h.C0, float).ravel()
    return C0, np.bincount(goc.ravel(), minlength=n_groups)


def _zone_of(zones: list | None, i: int, j: int) -> str:
    """The zone of the resolved scene a cell lies in (the last that covers it: later zones win), or the base."""
    name = "base knit"
    for k, z in enumerate(zones or []):
        ci, wi = z.get("courses", [0, 0]), z.get("wales", [0, 0])
        if ci[0] <= i < ci[1] and wi[0] <= j < wi[1]:
            name = (f"zone {z['label']!r}" if z.get("label") else
                    f"the zone of courses {ci[0]}-{ci[1] - 1}, wales {wi[0]}-{wi[1] - 1}")
    return name


def _cells_beyond_domain(h: PatchHistory, layout: SpecimenLayout, row_key: str, col_key: str,
                         zones: list | None = None) -> list[ResultWarning]:
    """``cells_outside_domain``: cells whose strain (C - C0)/C0 went past the model's domain
    (:data:`knitsim.cell.domain.DOMAIN`'s strains), judged on the strains they reached, not on the grip's.

    The grip strain is not a cell's: cells of another material in series stretch more or less than the
    grip, and a specimen's pretension stretches the knit before the grip strain's origin; the pre-run check
    (``knitsim run``'s ``check_patch_domain``) sees only the grip program.  Only the upper end is judged:
    the lower end, 0, is the rest state, which a cell of a mixed column passes by a little when the
    column balances its cells' rest forces (a few 1e-3)."""
    from ..cell.domain import DOMAIN

    if not h.n_increments:
        return []
    hi = float(DOMAIN.strain[1])
    C0, cells_of = _group_C0(h)
    C = np.asarray(h.groups["C"], float)
    # the largest strain of each group (C0 > 0: the strain grows with C), without a copy of the rows
    with _warnings.catch_warnings(), np.errstate(invalid="ignore", divide="ignore"):
        _warnings.simplefilter("ignore", RuntimeWarning)            # a group of NaN lengths only (failed): NaN
        smax_g = np.nanmax(C, axis=0) / C0 - 1.0
    out_g = np.nonzero(np.isfinite(smax_g) & (smax_g > hi * (1.0 + 1e-9)))[0]
    if not len(out_g):
        return []
    n_out = int(cells_of[out_g].sum())
    g = int(out_g[np.argmax(smax_g[out_g])])
    with np.errstate(invalid="ignore"):
        sg = C[:, g] / C0[g] - 1.0
        r = int(np.nanargmax(sg))
        first = int(np.nonzero((C[:, out_g] / C0[out_g] - 1.0 > hi * (1.0 + 1e-9)).any(axis=1))[0][0])
    goc = np.asarray(h.group_of_cell)
    i, j = (int(v) for v in np.argwhere(goc == g)[0])
    e = np.asarray(h.grip_strain, float)
    what = "block" if layout.blocks else "cell"
    zone_txt = ""
    if zones:
        # each cell's zone (-1: the base knit; later zones win, as they are applied) and its largest strain
        zid = np.full(goc.shape, -1)
        for k, z in enumerate(zones):
            ci, wi = z.get("courses", [0, 0]), z.get("wales", [0, 0])
            zid[ci[0]:ci[1], wi[0]:wi[1]] = k
        out_cell = np.isin(goc, out_g)
        parts = []
        for k in np.unique(zid[out_cell]):
            at = out_cell & (zid == k)
            i0, j0 = (int(v) for v in np.argwhere(at)[0])
            parts.append(f"{_zone_of(zones, i0, j0)}: {int(at.sum())} {what}(s) up to "
                         f"{float(smax_g[goc[at]].max()):.4g}")
        zone_txt = "; by zone: " + ", ".join(parts)
    emax = float(np.nanmax(e))
    grip = (f", while the grip strain stays within it (at most {emax:.4g})" if emax <= hi else
            f" (the grip strain too reaches {emax:.4g})")
    pre = float(h.info.get("pretension") or 0.0)
    why = (f"; specimen.pretension = {pre:g} stretches the knit before the grip strain's origin" if pre > 0 else
           "; cells in series with stiffer ones stretch more than the grip" if zones or len(cells_of) > 1 else "")
    return [ResultWarning("cells_outside_domain", (
        f"extrapolation: {n_out} of {goc.size} {what}(s) stretched beyond the model's domain (strain of the "
        f"course length (C - C0)/C0 up to {hi:g}, knitsim.cell.domain){grip}: up to {float(sg[r]):.4g} "
        f"at {row_key} {i} {col_key} {j}{f' ({_zone_of(zones, i, j)})' if zones else ''} at grip strain "
        f"{e[r]:.4g} (increment {r + 1}), past {hi:g} from grip strain {e[first]:.4g} (increment {first + 1})"
        f"{why}{zone_txt}"))]


def _overlap_cell_strains(h: PatchHistory) -> str:
    """`` (cell strains a to b)`` where the heads overlap: the interpenetration warning's rows are grip strains."""
    rows, cols = np.nonzero(np.asarray(h.groups["interpenetrating"]) > 0)
    if not len(rows):
        return ""
    C0, _ = _group_C0(h)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.asarray(h.groups["C"], float)[rows, cols] / C0[cols] - 1.0
    s = s[np.isfinite(s)]
    return f" (cell strains {float(s.min()):.4g} to {float(s.max()):.4g})" if s.size else ""


def patch_summary(h: PatchHistory, ref_length: float, model: PatchModel | None = None,
                  zones: list | None = None, reference: PatchHistory | None = None,
                  force_cap: ForceCapRows | None = None, **info) -> dict:
    """The ``summary.json`` document (``model``: the run's, needed for a specimen; ``info`` is copied in).

    What a cell is: ``cell_is`` (``stitch`` or ``block of stitches``), ``cells`` (grid cells),
    ``stitches`` (what they stand for); a patch of single stitches has ``courses`` and ``wales``, a
    specimen ``bands``, ``strips`` and ``specimen`` (:meth:`SpecimenLayout.as_dict`: width, gauge
    length, wales and courses of every strip, wales of every band).  Forces: ``peak_force_N`` is the
    grip force (the total on a specimen), ``peak_force_per_wale_N`` it over the wales across the
    width (``wales_across``).

    Per cycle: peak grip force (and per wale) and the grip strain there;
    residual grip strain, where the grip force reaches 0 on the cycle's
    unloading branch (null if it never does), located from the columns' slack
    lengths where they allow it, else interpolated between rows
    (:func:`_residual_grip_strain`; ``residual_grip_strain_from`` says which, the
    top-level ``residual_grip_strain_from`` what each means); ``oint F_grip du``
    over the cycle's rows [N mm] (u = grip strain x
    rest length, from the last row of the previous cycle; the first from rest),
    named by :func:`knitsim.io.checks.cycle_work`: ``hysteresis_energy_N_mm`` of a
    closed cycle, ``work_N_mm`` of an open one, ``loading_work_N_mm`` of a loading, ``unloading_work_N_mm`` of an
    unloading (a program that starts by unloading: warning ``cycle_without_loading``).  Also the grip
    strain at the first jamming of any cell, located between rows where the cells' states allow it
    (:func:`_first_jamming`; ``grip_strain_at_first_jamming_from`` says how), non-converged column
    increments (and of them those held at their cells' force cap), cells whose status is not ok (by
    status: failed, or stopped at the force cap), and rows with a non-finite force.  ``all_converged``:
    every column converged on every increment and no cell failed; ``all_expected_end``: no failure, a stop
    at the force cap (a cell's status, or a column held at the cap) being an expected end (``knitsim run``
    exits 0 on it).

    Cells whose strain (C - C0)/C0 went past the model's domain are a ``cells_outside_domain`` warning (the
    pre-run check's are ``outside_domain``), judged on
    the strains they reached (:func:`_cells_beyond_domain`; ``zones``: the resolved scene's, to name them).

    Force cap: ``grip_strain_at_force_cap`` is where the force first is the cells' force cap
    (:func:`force_cap_rows`: a cell stopped at it, or held within
    :data:`~knitsim.io.checks.FORCE_CAP_RTOL` of it), null if never; each cycle's
    ``peak_is_force_cap`` says whether its peak is the cap; and the warning ``force_cap_reached``
    (with ``program_cut_by_force_cap`` where a stop left unloadings of the program unrun) says so.

    Failed cells (no_convergence, event_not_located), or columns that no longer converge to the end of the
    run: from the first such row, a column holds its last converged state, so the cycle figures use the
    rows before only; the cycle cut there has ``cut_at_grip_strain`` and no work, later cycles are left
    out, and the warning ``run_stopped_by_failed_cells`` or ``run_held_by_unconverged_columns`` says
    where and why (:func:`_run_stop`).  Likewise after cells stopped at their force cap where unloadings
    of the program were left (``program_cut_by_force_cap``): the figures stop at the row reaching the cap.
    """
    F, e = h.force_N, h.grip_strain
    # (force_cap: the run's force_cap_rows(h, model), found once for the summary and the force plot: 0.7 s
    # each on a 300 x 300 patch)
    fc = force_cap_rows(h, model) if force_cap is None else force_cap
    layout = _layout_of(h, model)
    row_key, col_key = ("band", "strip") if layout.blocks else ("course", "wale")
    # from the first row with a failed cell on (its column holds the cell's last converged state), from
    # where columns stop converging for good, or after cells stopped at their cap with unloadings left, the
    # grip force is not the knit's: the cycle figures stop there (_run_stop)
    stop, cut_at, stop_warnings = _run_stop(h, model, layout, row_key, col_key, fc)
    # a stop where cells failed: the grips hold their last converged state on that row (at a grip strain the
    # row does not record), which knitsim cell's peak counts (its row of the failed increment) and this
    # peak does not: said in the cut cycle's entry, with that force, so that the two can be compared
    from ..cell.history import STATUS_EVENT_NOT_LOCATED, STATUS_NO_CONVERGENCE
    failed_stop = stop is not None and bool(np.isin(np.asarray(h.groups["status"])[stop],
                                                     (STATUS_NO_CONVERGENCE, STATUS_EVENT_NOT_LOCATED)).any())
    # rows whose grip force holds columns that are not the knit's (not converged, or a stopped cell's last
    # state), other than at the force cap (its own warning): a cycle figure over them is not the knit's
    # (a column held at its cells' force cap too: its force is the cap, constant while the grip moves, and a
    # cycle's work over such rows counts it; force_cap_reached says where the force is the cap)
    held = (columns_held(h) > 0) if h.n_increments else np.zeros(0, bool)
    held_in = []
    cycles = []
    under_resolved = []
    for k in np.unique(h.cycle):
        rows = cycle_rows = np.nonzero(h.cycle == k)[0]
        if stop is not None:
            rows = cycle_rows[cycle_rows < stop]
            if not len(rows):
                continue                           # not run: the warning names it
        j = rows[np.argmax(F[rows])]
        entry = {"cycle": int(k), "peak_force_N": float(F[j]), "peak_force_per_wale_N": float(h.force_per_wale_N[j]),
                 "grip_strain_at_peak": float(e[j]), "grip_displacement_at_peak_mm": float(e[j] * ref_length),
                 # the peak is the cells' force cap, not the knit's response (warning force_cap_reached)
                 "peak_is_force_cap": bool(fc.rows[j]),
                 # of how many columns: all (the peak per wale is the cap) or some (the peak mixes them)
                 "columns_at_force_cap_at_peak": int(fc.column_rows[j].sum()) if fc.column_rows is not None else 0}
        if rows[0] == 0 and h.rest_force_N > F[j]:
            # a first cycle that unloads from rest peaks at the rest state (a blind probe read 0 N at -0.005)
            rest_e = float(h.info.get("rest_grip_strain", 0.0))
            entry.update(peak_force_N=float(h.rest_force_N), peak_force_per_wale_N=float(h.rest_force_per_wale_N),
                         grip_strain_at_peak=rest_e, grip_displacement_at_peak_mm=rest_e * ref_length,
                         peak_is_force_cap=False, columns_at_force_cap_at_peak=0)
        n_held = int(np.count_nonzero(held[rows]))
        if n_held:
            entry["held_rows"] = n_held
            held_in.append((int(k), rows[held[rows]]))
        unload = rows[h.direction[rows] < 0]
        res = res_from = None
        if len(unload):
            prev = np.concatenate([[unload[0] - 1], unload]) if unload[0] > 0 else unload
            for a, b in zip(prev[:-1], prev[1:]):
                if F[a] > 0 >= F[b]:
                    res, res_from = _residual_grip_strain(h, int(a), int(b), ref_length)
                    break
        entry["residual_grip_strain"] = res
        # how it was obtained (RESIDUAL_FROM): located from the slack lengths, or interpolated between rows
        entry["residual_grip_strain_from"] = res_from
        if len(rows) < len(cycle_rows):
            # cut where the force stops being the knit's: no work over a part of a cycle (_run_stop's warning)
            entry["cut_at_grip_strain"] = cut_at
            if failed_stop:
                entry["peak_before_failed_increment"] = True
                entry["force_per_wale_N_held_on_failed_increment"] = float(h.force_per_wale_N[stop])
            cycles.append(entry)
            continue
        path = np.concatenate([[rows[0] - 1], rows]) if rows[0] > 0 else rows
        s_path, f_path = e[path], F[path]
        if rows[0] == 0:                           # the first cycle starts from the rest state
            # at grip strain 0, or below it for a pretensioned specimen (its rest state, curve.csv's row 0)
            s_path = np.concatenate([[float(h.info.get("rest_grip_strain", 0.0))], s_path])
            f_path = np.concatenate([[h.rest_force_N], f_path])
        work = cycle_work(s_path, f_path, bool(len(unload)), loads=bool(np.any(h.direction[rows] > 0)))
        entry["closed"] = work["closed"]
        entry[f"{'hysteresis_energy' if work['kind'] == 'hysteresis' else work['kind']}_N_mm"] = \
            work["value"] * ref_length
        # the rows' trapezoids cut the kinks between rows (slide onsets, a reversal's steep drop): the estimated
        # error of this energy, every row against every other row (dissipated_energy_error)
        from ..cell.cycle import dissipated_energy_error
        err = dissipated_energy_error(s_path, f_path) * ref_length
        entry["energy_error_estimate_N_mm"] = err
        value = abs(work["value"]) * ref_length
        # a cycle of next to no work (a cycle that carries no force, warned of itself) is not judged by its share
        scale = max(value, 0.01 * float(np.max(np.abs(f_path))) * float(np.ptp(s_path)) * ref_length)
        if err > ENERGY_ERROR_SHARE * scale:
            under_resolved.append((int(k), "hysteresis energy" if work["kind"] == "hysteresis" else work["kind"].replace("_", " "),
                                   work["value"] * ref_length, err))
        cycles.append(entry)
    first_jam, first_jam_from = _first_jamming(h)
    nc = np.argwhere(h.column_status == COL_NOT_CONVERGED)
    # a column that cannot pass its cells' force cap does not converge and holds the cap: the cap's stop
    nc_at_cap = np.array([bool(fc.column_rows[i, j]) for i, j in nc], bool) if len(nc) else np.zeros(0, bool)
    end_status = h.cell_field("status")[-1] if h.n_increments else np.zeros((0, 0), np.int8)
    bad_cells = np.argwhere(end_status != STATUS_OK) if h.n_increments else np.zeros((0, 2))
    failed = np.argwhere((end_status != STATUS_OK) & (end_status != STATUS_FORCE_CAP)) if h.n_increments \
        else np.zeros((0, 2))
    nonfinite = np.nonzero(~np.isfinite(F))[0]
    peaks = [(c["cycle"], c["peak_force_per_wale_N"]) for c in cycles]
    # the rows the figures use: the grip strains up to a stop
    end = len(F) if stop is None else stop
    warnings = stop_warnings + cycle_warnings(peaks, e[:end], h.force_per_wale_N[:end], h.cycle[:end],
                                              h.direction[:end], strain_name="grip strain",
                                              residuals={c["cycle"]: c["residual_grip_strain"] for c in cycles})
    if reference is not None and reference.n_increments:
        # the same patch pulled monotonically (knitsim run's first-loading reference, where the program reloads
        # past an earlier maximum): a reload past the earlier maximum that stays below it; the reference's rows
        # up to its first held row (a column at its cap or not converged is not the knit's)
        ref_held = columns_held(reference) > 0
        n_ref = int(np.argmax(ref_held)) if ref_held.any() else reference.n_increments
        below = {int(w.cycle) for w in warnings if w.code in ("reload_below_earlier_loading", "zero_force_cycle")
                 and w.cycle is not None}
        warnings += reloads_below_first_loading(e[:end], h.force_per_wale_N[:end], h.cycle[:end], h.direction[:end],
                                                reference.grip_strain[:n_ref], reference.force_per_wale_N[:n_ref],
                                                strain_name="grip strain", flagged=below)
    if under_resolved:
        warnings.append(ResultWarning("energy_under_resolved", (
            # (a share only of an energy larger than its error: a cycle whose rows retrace each other, its hysteresis
            # -7.7e-19 N mm of rounding, read "+/-0.00056 N mm (73477348050127616 %)")
            "; ".join(f"cycle {k}'s {kind} {v:.4g} N mm is resolved to about +/-{err:.2g} N mm ({100 * err / abs(v):.0f} %)"
                      if abs(v) > err else f"cycle {k}'s {kind} {v:.4g} N mm is resolved to about +/-{err:.2g} N mm "
                      "(more than the value: not told from 0)"
                      for k, kind, v, err in under_resolved)
            + f" (energy_error_estimate_N_mm: the trapezoids over every row against every other row): the rows cut the "
            "kinks between them (slide onsets, the steep drop after a reversal); a smaller load.max_increment resolves "
            "it (the error goes with the increment)")))
    if held_in:
        warnings.append(ResultWarning("cycle_figures_include_held_rows", (
            "the figures of cycle(s) " + ", ".join(
                f"{k} ({len(r)} row(s), grip strains {e[r].min():.4g} to {e[r].max():.4g})" for k, r in held_in)
            + " include rows whose force is held, not the knit's (a column that did not converge, or is held at its "
            "cells' force cap, keeps its last state; curve.csv's columns_held): their peak, work and hysteresis count "
            "a force the knit did not carry there")))
    warnings += _cells_beyond_domain(h, layout, row_key, col_key, zones)
    if "interpenetrating" in h.groups:
        # the rows are grip strains; the cells where the heads overlap are at their own strains
        warnings += interpenetration(e, h.groups["interpenetrating"], h.groups["head_gap"], h.group_d_jam,
                                     what="distinct cell", direction=h.direction, strain_is="grip strain",
                                     note=_overlap_cell_strains(h))
    if "W" in h.groups and h.group_d_jam is not None:
        # W below 4 w, past the model's jamming limit (the head-gap criterion allows it once the heads touch)
        width = np.asarray(h.group_d_jam, float)
        if model is not None and len(np.ravel(h.group_of_cell)) == model.cell_count:
            # with yarn_compaction on, a cell jams at its compacted width, down to compaction_min of it
            codes, sets = model.effect_codes()
            floor_of_set = jam_width_floor(np.ones(len(sets)), np.array(sets + [None], dtype=object)[:-1])
            floor = np.ones(len(width))
            np.minimum.at(floor, np.ravel(h.group_of_cell), floor_of_set[np.ravel(codes)])
            width = width * floor
        warnings += wale_spacing_below_jamming(e, h.groups["W"], width, what="distinct cell",
                                               direction=h.direction, strain_is="grip strain")
    # a peak per wale is the cap where every column is at it (else it mixes capped and free columns)
    capped_peaks = [c["peak_force_per_wale_N"] for c in cycles
                    if c["peak_is_force_cap"] and c["columns_at_force_cap_at_peak"] >= h.shape[1]]
    warnings += _force_cap_warnings(h, fc, layout, max(capped_peaks) if capped_peaks else None)
    warnings += _compressive_rest_cells(h, row_key, col_key)
    warnings += _unbalanced_rest_columns(h, row_key, col_key)
    warnings += _energy_creating_cells(h, row_key, col_key)
    out = dict(info)
    cells = int(h.shape[0] * h.shape[1])
    solved = int(h.info.get("n_groups", cells))
    out.update(cell_is="block of stitches" if layout.blocks else "stitch", cells=cells,
               grip_strain_is=(f"grip displacement / gauge length ({ref_length:.6g} mm), the same for every strip"
                               if layout.blocks else
                               f"grip displacement / the columns' rest length ({ref_length:.6g} mm"
                               f"{'' if np.allclose(h.C0.sum(axis=0), ref_length, rtol=1e-12) else ', their mean'})"))
    if layout.blocks:
        out.update(bands=int(h.shape[0]), strips=int(h.shape[1]), stitches=layout.stitches,
                   wales_across=layout.wales_across, specimen=layout.as_dict())
    else:
        out.update(courses=int(h.shape[0]), wales=int(h.shape[1]), stitches=cells,
                   wales_across=float(h.shape[1]))
    out.update(
        solved_cells=solved, n_increments=int(h.n_increments), solve_s=float(h.wall_s),
        # identical cells are solved once (dedup): the cells represented, and those actually solved
        represented_cell_increments_per_s=float(cells * h.n_increments / h.wall_s) if h.wall_s > 0 else None,
        solved_cell_increments_per_s=float(solved * h.n_increments / h.wall_s) if h.wall_s > 0 else None,
        represented_stitch_increments_per_s=(float(layout.stitches * h.n_increments / h.wall_s) if h.wall_s > 0
                                             else None),
        solver=h.info, rules=rule_sets(model), cycles=cycles,
        grip_strain_at_first_jamming=first_jam,
        grip_strain_at_first_jamming_from=FIRST_JAMMING_FROM.get(first_jam_from),
        residual_grip_strain_from=RESIDUAL_FROM,
        # (row, column) pairs that did not converge, and of them those held at their cells' force cap
        non_converged_column_increments=int(len(nc)),
        non_converged_column_increments_at_force_cap=int(nc_at_cap.sum()),
        # where: a wale and a course of single stitches, a strip and a band of a specimen
        non_converged_first=[{"increment": int(i) + 1, col_key: int(j)} for i, j in nc[:20]],
        columns_stopped_at_end=int(np.sum(h.column_status[-1] != COL_OK)) if h.n_increments else 0,
        # cells whose status is not ok at the end: failed (no_convergence, event_not_located) or stopped at
        # their force cap (an expected end, README "Rules where Table 4 is silent")
        non_ok_cells_at_end=int(len(bad_cells)),
        non_ok_cells_first=[{row_key: int(i), col_key: int(j)} for i, j in bad_cells[:20]],
        cells_at_end_by_status={STATUS_NAMES[int(k)]: int(v) for k, v in
                                zip(*np.unique(end_status, return_counts=True))},
        failed_cells_at_end=int(len(failed)),
        failed_cells_first=[{row_key: int(i), col_key: int(j)} for i, j in failed[:20]],
        cells_stopped_at_force_cap_at_end=int(np.sum(end_status == STATUS_FORCE_CAP)),
        nonfinite_force_rows=[int(i) for i in nonfinite[:20]],
        # from which grip strain the force is the cells' force cap (warning force_cap_reached), or null
        grip_strain_at_force_cap=float(e[np.argmax(fc.rows)]) if fc.rows.any() else None,
        # every column converged on every increment, no cell failed, every force finite; cells stopped at
        # their force cap converged (their stop is all_expected_end's business)
        all_converged=bool(len(nc) == 0 and len(failed) == 0 and len(nonfinite) == 0),
        # the run ended as a run may: no failed cell, no column that failed to converge other than one
        # held at its cells' force cap, every force finite; a stop at the force cap is expected (as in
        # knitsim cell's summary); knitsim run exits 0 on it, 1 otherwise
        all_expected_end=bool(len(nc) == int(nc_at_cap.sum()) and len(failed) == 0 and len(nonfinite) == 0),
        warnings=[w.as_dict() for w in warnings],
    )
    return out


#: a cell of a patch comes back to the strain it started from only to within the column coupling's solution
#: (force_tol + force_rtol |F|, over a tangent): a loop of a cell is closed within this strain
PATCH_LOOP_ATOL = 1e-6


def _compressive_rest_cells(h: PatchHistory, row_key: str, col_key: str) -> list[ResultWarning]:
    """One warning naming the distinct cells whose rest state is compressive
    (:func:`knitsim.io.checks.compressive_rest_state`; their loops from rest are not judged)."""
    if h.group_rest is None:
        return []
    F = np.asarray(h.group_rest["F"], float)
    bad = np.flatnonzero(np.isfinite(F) & (F < 0.0))
    if not bad.size:
        return []
    where = []
    for g in bad[:10]:
        i, j = np.argwhere(h.group_of_cell == g)[0]
        where.append(f"{row_key} {int(i)} {col_key} {int(j)}")
    first = compressive_rest_state(F[bad[0]])[0].message.replace("the cell: ", "")
    return [ResultWarning(
        "rest_state_compressive",
        f"{bad.size} of {F.size} distinct cell(s) have a compressive rest state, e.g. at {', '.join(where)}"
        f"{' ...' if bad.size > 10 else ''}; the first: {first}")]


def _group_stitch_energy(h: PatchHistory, g: int):
    """``k ->`` the bending energy stored in one stitch of group ``g`` at row k of its path, row 0 its rest
    state (:func:`knitsim.cell.quarter_loop.stored_energy`); None where the history keeps no angles."""
    rest = h.group_rest or {}
    if "x" not in h.groups or "x" not in rest or "B" not in rest:
        return None
    from ..cell.quarter_loop import stitch_energy_along
    return stitch_energy_along(rest["x"][g], h.groups["x"][:, g], rest["B"][g])


def _energy_creating_cells(h: PatchHistory, row_key: str, col_key: str) -> list[ResultWarning]:
    """One warning naming the distinct cells with a closed loop that returns energy (oint F dC < 0).

    Each distinct cell (group) is checked on its own path, rest state first, by
    :func:`knitsim.io.checks.energy_creating_loops` (closure within :data:`PATCH_LOOP_ATOL`, the open end's
    work added to the tolerance).  Only where a cell's path has closed loops can the flag fire.  Loops that
    start on a loading and unload-reload loops from a peak are judged with the stitch's stored bending energy
    (``stored_at``: the group's angles and P of each row, ``groups["x"]``, and of its rest state), where the
    history keeps them.
    """
    if h.group_rest is None or not h.n_increments:
        return []
    g_C, g_F = h.groups["C"], h.groups["F"]
    n_groups = g_C.shape[1]
    C0 = np.zeros(n_groups)
    C0[h.group_of_cell.ravel()] = h.C0.ravel()
    ok = np.all(h.groups["status"] == STATUS_OK, axis=0)
    # the groups whose whole path could hold such a loop, found at once (energy_loop_candidates: a superset);
    # a group that failed is judged on its rows before the failure, one by one
    judged = ~ok
    if ok.any():
        S = np.vstack([h.group_rest["C"][None, ok], g_C[:, ok]]) / C0[ok] - 1.0
        Fv = np.vstack([h.group_rest["F"][None, ok], g_F[:, ok]])
        judged[np.flatnonzero(ok)] = energy_loop_candidates(S, Fv, atol=PATCH_LOOP_ATOL,
                                                            judge_open=_group_stitch_energy(h, 0) is not None)
    flagged = {}
    for g in np.flatnonzero(judged):
        n = int(np.argmin(h.groups["status"][:, g] == STATUS_OK)) if not ok[g] else h.n_increments
        s = np.concatenate([[h.group_rest["C"][g]], g_C[:n, g]]) / C0[g] - 1.0
        f = np.concatenate([[h.group_rest["F"][g]], g_F[:n, g]])
        w = energy_creating_loops(s, f, C0[g], atol=PATCH_LOOP_ATOL, stored_at=_group_stitch_energy(h, g))
        if w:
            flagged[int(g)] = w[0].message
    if not flagged:
        return []
    where = []
    for g in flagged:
        i, j = np.argwhere(h.group_of_cell == g)[0]
        where.append(f"{row_key} {int(i)} {col_key} {int(j)}")
    first = next(iter(flagged.values())).replace("the cell: ", "")
    return [ResultWarning(
        "loop_creates_energy",
        f"{len(flagged)} of {n_groups} distinct cell(s) have a closed loop that returns energy (oint F dC < 0), "
        f"e.g. at {', '.join(where[:10])}{' ...' if len(where) > 10 else ''}; the first: {first}")]


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def plot_force_strain(h: PatchHistory, title: str = "", layout: SpecimenLayout | None = None,
                      warnings: list | None = None, force_cap: np.ndarray | None = None) -> bytes:
    """PNG: force vs grip strain (cycles coloured), non-converged increments, increments where the
    heads of neighbouring loops overlap and increments whose force is the cells' force cap
    (``force_cap``, shape [n] bool: :attr:`ForceCapRows.rows`) marked: the force per wale of a patch of
    single stitches, the total force on a specimen (what a tester reports).  ``warnings`` (the
    summary's, dicts with a ``message``) are printed under the axes, so that the figure never looks
    cleaner than the run."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    layout = layout or _layout_of(h, None)
    F = h.force_N if layout.blocks else h.force_per_wale_N
    lines = warning_lines(warnings, 120)
    fig = Figure(figsize=(7.5, 5 + 0.16 * len(lines)), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    if lines:
        bottom = (0.55 + 0.16 * len(lines)) / (5 + 0.16 * len(lines))
        fig.subplots_adjust(bottom=bottom)
        fig.text(0.02, 0.01, "\n".join(lines), fontsize=6.5, color="#b22222", va="bottom", ha="left")
    for i, k in enumerate(np.unique(h.cycle)):
        r = np.nonzero(h.cycle == k)[0]
        if r[0] > 0:
            r = np.concatenate([[r[0] - 1], r])
        e_k, F_k = h.grip_strain[r], F[r]
        if r[0] == 0:
            # the first cycle starts from the rest state (curve.csv's row 0), as a tensile test's curve does
            e_k = np.concatenate([[float(h.info.get("rest_grip_strain", 0.0))], e_k])
            F_k = np.concatenate([[h.rest_force_N if layout.blocks else h.rest_force_per_wale_N], F_k])
        # later cycles thinner and dashed: a cycle that retraces the one before stays visible under it
        ax.plot(e_k, F_k, lw=max(2.6 - 0.8 * i, 0.9), ls="-" if i == 0 else (0, (4, 2 + i)),
                label=f"cycle {int(k)}")
    bad = np.any(h.column_status != COL_OK, axis=1)
    if bad.any():
        ax.scatter(h.grip_strain[bad], F[bad], marker="x", color="red", zorder=3,
                   label="column not converged / stopped")
    if "interpenetrating" in h.groups:
        over = np.asarray(h.groups["interpenetrating"]) > 0
        if "head_gap" in h.groups and h.group_d_jam is not None:
            # the warning's tolerance (io.checks.HEAD_OVERLAP_RTOL): a micrometre of overlap is rounding
            w = np.asarray(h.group_d_jam, float)[None, :]
            with np.errstate(invalid="ignore"):
                over &= ~(w - np.asarray(h.groups["head_gap"], float) <= HEAD_OVERLAP_RTOL * w)
        over = np.any(over, axis=1)
        if over.any():
            ax.scatter(h.grip_strain[over], F[over], marker="o", s=9, color="darkorange", zorder=3,
                       label="heads of neighbouring loops overlap")
    if force_cap is not None and np.any(force_cap):
        at = np.asarray(force_cap, bool)
        ax.scatter(h.grip_strain[at], F[at], marker="s", s=22, facecolors="none", edgecolors="purple", zorder=3,
                   label="force = force cap, not the knit's response")
    if layout.blocks:
        ax.set_xlabel("grip strain (grip displacement / gauge length)")
        ax.set_ylabel(f"total force on the {layout.width_mm:.4g} mm wide specimen [N]")
        default = (f"knitsim specimen {layout.width_mm:.4g} x {layout.gauge_length_mm:.4g} mm "
                   f"({layout.stitches:,.0f} stitches in {h.shape[0]} x {h.shape[1]} blocks)")
    else:
        ax.set_xlabel("grip strain (grip displacement / column rest length)")
        ax.set_ylabel("force per wale [N]")
        default = f"knitsim patch {h.shape[1]} wales x {h.shape[0]} courses"
    ax.set_title(title or default, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _png(fig)


def map_rows(h: PatchHistory) -> list[int]:
    """Increments a map shows: the last cycle's largest grip strain (where a tensile test jams) and the
    end of the run, or the end alone where they coincide."""
    if h.n_increments == 0:
        return []
    last = np.nonzero(h.cycle == h.cycle[-1])[0]
    peak = int(last[np.argmax(h.grip_strain[last])])
    end = h.n_increments - 1
    return [end] if peak == end else [peak, end]


def plot_map(h: PatchHistory, which: str, title: str = "", layout: SpecimenLayout | None = None) -> bytes:
    """PNG of :func:`map_figure`."""
    return _png(map_figure(h, which, title, layout))


def _hatched_runs(xe: np.ndarray, ye: np.ndarray, mask: np.ndarray):
    """A hatched collection over the cells of ``mask`` ([courses, wales], cell edges ``xe``, ``ye``): one
    rectangle per run of neighbouring cells along a course.  (One square per cell, as ``pcolor`` draws them,
    took 21 s for the two panels of a 300 x 300 patch whose cells were all past the domain.)"""
    from matplotlib.collections import PolyCollection

    edge = np.diff(np.pad(mask.astype(np.int8), ((0, 0), (1, 1))), axis=1)
    ri, a = np.nonzero(edge == 1)                  # run starts (row-major: paired with the stops below)
    _, b = np.nonzero(edge == -1)                  # one past each run's last cell
    x0, x1 = np.asarray(xe, float)[a], np.asarray(xe, float)[b]
    y0, y1 = np.asarray(ye, float)[ri], np.asarray(ye, float)[ri + 1]
    verts = np.stack([np.stack([x0, y0], 1), np.stack([x1, y0], 1), np.stack([x1, y1], 1),
                      np.stack([x0, y1], 1)], axis=1)
    return PolyCollection(verts, hatch="///", facecolor="none", edgecolor="black", linewidth=0.0)


def map_figure(h: PatchHistory, which: str, title: str = "", layout: SpecimenLayout | None = None):
    """The matplotlib figure of the per-cell ``strain`` or ``stage`` map at the last cycle's peak grip strain and
    at the end (:func:`map_rows`; courses upward, wales across; a specimen's blocks drawn at their rest size in mm).

    On the strain map, cells whose strain lies past the model's domain (above
    :data:`knitsim.cell.domain.DOMAIN`'s strain range, as the summary's ``cells_outside_domain`` judges them)
    are hatched, with a legend entry, and the domain's end is marked on the colour bar."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import BoundaryNorm, ListedColormap, Normalize
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    from ..cell.domain import DOMAIN
    layout = layout or _layout_of(h, None)
    rows = map_rows(h)
    field = h.cell_field(which if which == "strain" else "label")
    fig = Figure(figsize=(1.0 + 4.6 * max(len(rows), 1), 6.5), dpi=100)
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, max(len(rows), 1), squeeze=False)[0]
    if which == "strain":
        vals = field[rows] if rows else np.zeros((1,) + tuple(h.shape))
        finite = vals[np.isfinite(vals)]
        lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
        if hi - lo < 1e-9 * max(1.0, abs(hi)):
            lo, hi = lo - 0.01, hi + 0.01
        style = {"cmap": "viridis", "norm": Normalize(lo, hi)}
    else:
        style = {"cmap": ListedColormap(["#1f77b4", "#2ca02c", "#d62728", "#7f7f7f"]),
                 "norm": BoundaryNorm(np.arange(-0.5, 4.5), 4)}
    im = None
    beyond_at = float(DOMAIN.strain[1])
    panels_beyond = 0
    for ax, r in zip(axes, rows):
        data = field[r]
        if layout.blocks:
            xe = np.concatenate([[0.0], np.cumsum(layout.strip_width_mm)])
            ye = np.concatenate([[0.0], np.cumsum(layout.band_length_mm)])
            im = ax.pcolormesh(xe, ye, data, shading="flat", **style)
            ax.set_xlabel(f"across the width [mm] ({h.shape[1]} strip{'s' * (h.shape[1] != 1)})")
            if ax is axes[0]:   # the panels share their axes; a second y label ran into the first panel
                ax.set_ylabel(f"from the lower grip, at rest [mm] ({h.shape[0]} band{'s' * (h.shape[0] != 1)})")
        else:
            im = ax.imshow(data, origin="lower", aspect="auto", interpolation="nearest", **style)
            ax.set_xlabel("wale")
            if ax is axes[0]:
                ax.set_ylabel("course")
            xe, ye = np.arange(h.shape[1] + 1) - 0.5, np.arange(h.shape[0] + 1) - 0.5
        if which == "strain":
            # the cells past the domain's strain (an extrapolation, which the summary warns of): hatched over their
            # colour, judged as the summary judges them (cells_outside_domain)
            with np.errstate(invalid="ignore"):
                beyond = np.isfinite(data) & (data > beyond_at * (1.0 + 1e-9))
            if beyond.any():
                panels_beyond += 1
                ax.add_collection(_hatched_runs(xe, ye, beyond))
        when = "end" if r == h.n_increments - 1 else f"cycle {int(h.cycle[r])} peak"
        ax.set_title(f"{which} at the {when} (grip strain {h.grip_strain[r]:.3g})", fontsize=10)
    if im is not None:
        if which == "strain":
            on_bar = style["norm"].vmin < beyond_at < style["norm"].vmax
            if panels_beyond:
                fig.subplots_adjust(bottom=0.17)          # room for the legend below the axes (before the bar)
            cb = fig.colorbar(im, ax=list(axes), label="strain of the course length (C - C0)/C0")
            if on_bar:
                cb.ax.axhline(beyond_at, color="black", linewidth=1.5)
            if panels_beyond:
                fig.legend(handles=[Patch(facecolor="none", edgecolor="black", hatch="///",
                                          label=f"past the model's domain: strain above {beyond_at:g}"
                                                + (" (line on the colour bar)" if on_bar else "")
                                                + "\nan extrapolation (summary.json: cells_outside_domain)")],
                           loc="lower center", fontsize=8, frameon=False)
        else:
            cb = fig.colorbar(im, ax=list(axes), ticks=range(4))
            cb.ax.set_yticklabels([_LABELS[k] for k in sorted(_LABELS)])
    if title:
        fig.suptitle(title, fontsize=10)
    return fig


def write_patch_results(out_dir: str | Path, h: PatchHistory, summary: dict, resolved_toml: str,
                        fields: dict | None = None, plot: bool = True, cell_fields: bool = True,
                        title: str = "", model: PatchModel | None = None, cells_stride: int = 1,
                        force_cap: ForceCapRows | None = None) -> dict[str, Path]:
    """Write the result set into ``out_dir`` atomically (``summary.json`` last); returns the files by name.

    ``model``: the run's (its parameters go into cells.nc unless ``fields`` is given; a specimen's
    history needs it for the stitches each block stands for).  ``cells_stride``: ``output.cells_stride``,
    the increments cells.nc holds (:func:`cells_increments`; curve.csv, columns.csv and the plots keep every
    increment); where it is not 1, summary.json gets a ``cells_nc`` entry saying so (:func:`cells_written`)
    unless ``summary`` has one.  ``force_cap``: :func:`force_cap_rows` of the run where already found (the
    summary's), else found here."""
    cells_stride = _check_stride(cells_stride)
    layout = _layout_of(h, model)
    if fields is None and model is not None:
        fields = model.fields
    files = {"curve.csv": curve_csv(h).encode(), "columns.csv": columns_csv(h, layout).encode(),
             "scene.resolved.toml": resolved_toml.encode()}
    if cell_fields:
        files["cells.nc"] = cells_nc(h, fields, layout, model.rules if model is not None else None, cells_stride)
        if cells_stride != 1 and "cells_nc" not in summary:
            summary = {**summary, "cells_nc": cells_written(h, cells_stride)}
    if plot:
        fc = force_cap_rows(h, model) if force_cap is None else force_cap
        files["force_strain.png"] = plot_force_strain(h, title, layout, summary.get("warnings"), fc.rows)
        files["strain_map.png"] = plot_map(h, "strain", layout=layout)
        files["stage_map.png"] = plot_map(h, "stage", layout=layout)
    files["summary.json"] = summary_json(summary).encode()
    return write_result_set(out_dir, files, PATCH_OUTPUT_FILES)


__all__ = ["CURVE_COLUMNS", "COLUMNS_COLUMNS", "PATCH_OUTPUT_FILES", "SpecimenLayout", "specimen_layout",
           "column_forces", "curve_csv", "columns_csv", "cells_dataset", "cells_nc", "cells_increments",
           "cells_written", "ForceCapRows", "force_cap_rows",
           "patch_summary", "plot_force_strain", "plot_map", "map_figure", "write_patch_results", "PARAM_NAMES"]
