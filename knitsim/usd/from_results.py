"""USD frames of a simulated patch: yarn geometry from the cells' elastica states.

A patch run (:func:`knitsim.patch.runner.run_patch`) records, per saved
increment and per group of identical cells, the state x = (alpha, beta, gamma,
phi, P) with W, C and s_AB (``cells.nc``: ``state_x``, ``state_W``,
``state_C``, ``state_s_AB``, ``group_of_cell``).  From them this module
rebuilds the frames that :func:`knitsim.usd.write_patch_usd` takes:

- the quarter centreline A -> B -> C of each group from its state, computed for
  every group and frame in one launch of the Warp kernel
  :func:`knitsim.kernels.centreline.centreline_kernel` (the twin of
  :func:`knitsim.cell.quarter_loop.centreline`, eqs 8-9);
- placed on the patch lattice from the cells' current W (eq 6) and C
  (:mod:`knitsim.usd.yarn_geometry` completes the full stitch by the model's
  symmetries and stacks the stitches);
- per-cell fields ``stage`` (label codes of :data:`knitsim.cell.stages.LABEL_CODES`),
  ``phi`` [rad], ``force_per_wale_N`` (force per wale of the cell [N], as
  cells.nc's variable of that name), ``strain`` ((C - C0)/C0), ``status`` (codes of
  :data:`knitsim.cell.history.STATUS_NAMES`; the legend is in
  ``customLayerData["knitsim"]["field_legends"]``); ``material_id`` (static) numbers the
  distinct parameter sets (``d, B, m, dahl_sigma, L, W0, C0, phi0``) in sorted order
  (``customLayerData["knitsim"]["materials"]`` says what each is: :func:`material_labels`);
- per frame, ``grip_strain``, ``cycle``, ``direction`` and ``columns_held`` as
  time-sampled attributes of ``/Patch``; per wale column (strip) and frame,
  ``knitsim:column_slack_mm`` (a slack column is drawn compressed between the grips,
  :mod:`knitsim.usd.yarn_geometry`) and ``knitsim:column_held`` (1: the column's
  state is held, not the knit's: it did not converge, or holds a stopped cell).

Time codes.  Time code k is increment k of the run, as numbered in curve.csv:
0 is the rest state (grip strain 0, or a pretensioned specimen's rest grip
strain), drawn from the per-group rest state that the run records
(:attr:`knitsim.patch.runner.PatchHistory.group_rest`; in a results folder,
cells.nc's :data:`REST_VARIABLES`).  ``stride`` s writes increments 0, s, 2s, ...
and always the last one written.  A results folder whose cells.nc holds no rest
state (written by a knitsim that did not save it) is exported as before: time
code k is increment k + 1, and ``customLayerData["knitsim"]["timeline"]`` says so
(``time_code_0_is_increment``).

A results folder whose cells.nc was written at a stride (``output.cells_stride``)
holds some increments only (the multiples of its stride, the program's turning
points and the last: :func:`knitsim.io.patch_results.cells_increments`); the
record keeps the increment number of each saved row (:attr:`PatchRecord.increments`,
cells.nc's ``increment`` coordinate), the time codes are still those increment
numbers, ``stride`` s writes those of them that are multiples of s (and the
last), and the file lists the saved increments (``timeline``:
``saved_increments``, ``saved_increments_are``).

Increments the knit did not reach.  Where, from some increment to the end of the
run, every column is held (stopped at its cells' force cap, failed cells, columns
that no longer converge: the run goes on moving the grip while the knit keeps its
last state), only the increments up to the first of them are written; the file
says which were left out and why (``timeline``), carries the run's warnings and
flags (``customLayerData["knitsim"]["run"]``, from its summary) and the legend of
the status codes.  A column held while others move is drawn, marked by
``knitsim:column_held``.

A cell whose state is not admissible (theta not monotone A -> C, e.g. a failed
cell) or whose quarter does not close on X_A = W/4 within
:data:`knitsim.usd.yarn_geometry.ENDPOINT_RTOL` (an unconverged state) is drawn
as a straight quarter from (W/4, 0) to (0, C/2); the count per frame is in
``customLayerData["knitsim"]["metadata"]["fallback_cells"]``.  This is a display
device, not a model result.
"""
from __future__ import annotations

import functools
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..arrays import stride_select
from ..errors import KnitsimInputError
from . import yarn_geometry as yg

#: points per quarter centreline (A .. C) by default; Catmull-Rom looks smooth from about 7
DEFAULT_POINTS = 9
MIN_POINTS = 6
#: most points per quarter centreline: the polyline of 200 points already lies within 1e-4 mm of the elastica
#: (measured against 4001 points on the E-glass cell at rest, C = 3.4 and 4.0 mm: 9.1e-5, 6.6e-5, 4.5e-5 mm; 9
#: points: 0.025-0.037 mm), 1/6000 of the yarn's 0.58 mm, so more draw nothing new while the file and the export
#: grow with them (a blind probe's 10^6 points wrote 8.6 GB in 462 s for a 12-cell patch)
MAX_POINTS = 1000
#: --color-by names and the frame field each one colours by
COLOR_FIELDS = {"stage": "stage", "phi": "phi", "force": "force_per_wale_N", "material": "material_id",
                "strain": "strain"}
FIELD_UNITS = {"phi": "rad", "force_per_wale_N": "N", "strain": "1"}
#: what each per-cell primvar and per-frame / per-column attribute is (their USD documentation)
FIELD_DOCS = {
    "stage": "stage label code of the cell (0 adherence, 1 sliding, 2 jamming, 3 slack)",
    "phi": "friction angle at the crossing [rad]",
    "force_per_wale_N": "force per wale of the cell [N] (cells.nc force_per_wale_N; a specimen's block carries "
                        "wale_count times it)",
    "strain": "strain of the cell's course length, (C - C0)/C0 [1]",
    "status": "cell status code (customLayerData knitsim.field_legends.status: 0 ok, 1 no_convergence, 2 force_cap, "
              "3 event_not_located, 4 no_rest_state)",
    "grip_strain": "grip strain of the increment (grip displacement / the columns' rest length, or a specimen's "
                   "gauge length) [1]",
    "cycle": "cycle of the load program (from 1)",
    "direction": "+1 loading, -1 unloading",
    "columns_held": "wale columns (strips) whose state is held, not the knit's (curve.csv columns_held)",
    "column_held": "per wale column (strip): 1 where its state is held, not the knit's (it did not converge, or "
                   "holds a cell stopped at its force cap or failed: it keeps its last state while the grip moves)",
}
#: cells.nc variables of the rest state (per group) read where present: time code 0 is then the rest state
REST_VARIABLES = {"x": "rest_state_x", "C": "rest_state_C", "F": "rest_force_per_wale_N",
                  "W": "rest_state_W", "s_AB": "rest_state_s_AB", "label": "rest_stage"}
#: of them, those needed: every one (knitsim.io.patch_results writes them together, from the run's group_rest)
REST_REQUIRED = tuple(REST_VARIABLES)
#: USD layouts: one BasisCurves yarn per course, or one stitch shape per distinct cell instanced
#: (knitsim.usd.instanced); "auto" instances where it writes at least INSTANCE_GAIN times fewer shapes
LAYOUTS = ("auto", "courses", "instanced")
INSTANCE_GAIN = 4
#: parameters that identify a material (as knitsim.patch.model.PARAM_NAMES)
_MATERIAL_PARAMS = ("d", "B", "m", "dahl_sigma", "L", "W0", "C0", "phi0", "in_plane_width")


# --------------------------------------------------------------------------- kernel driver

@functools.lru_cache(maxsize=None)
def _gl_arrays(device: str):
    import warp as wp

    from ..cell import elastica
    out = []
    for n in (elastica.N_AB, elastica.N_BC):
        xg, wg = elastica.gauss_legendre_01(n)
        out += [wp.array(np.ascontiguousarray(xg), dtype=wp.float64, device=device),
                wp.array(np.ascontiguousarray(wg), dtype=wp.float64, device=device)]
    return tuple(out)


def point_counts(n_points: int) -> tuple[int, int, int]:
    """``(n_ab, n1_split, n_bc)`` as :func:`knitsim.cell.quarter_loop.centreline` splits ``n_points``."""
    n_ab = max(2, n_points // 2)
    return n_ab, max(2, int(round(n_ab * 0.5))), max(2, n_points - n_ab)


def quarter_centrelines(x, B, d, n_points: int = DEFAULT_POINTS, device: str = "cpu") -> dict:
    """Quarter-stitch centrelines of N cells at once (Warp, float64).

    Parameters
    ----------
    x : array, shape (N, 5)
        States (alpha, beta, gamma, phi [rad], P [N]).
    B, d : float or array, shape (N,)
        Bending stiffness [N mm^2] and yarn diameter [mm].
    n_points : int, >= 6
        Points per quarter, A first, apex C last (sampled as the reference:
        graded toward A at high load, B at index ``n_points // 2 - 1``).
    device : str
        Warp device.

    Returns
    -------
    dict
        ``s`` (N, n) [mm], ``xy`` (N, n, 2) [mm] in the cell frame,
        ``W``, ``C``, ``s_AB``, ``Y_C`` (N,) [mm] from the same integrals (eq 6),
        ``ok`` (N,) bool (admissible state; NaN points where False), ``i_B``.
    """
    from .. import warp_runtime
    warp_runtime.init()
    import warp as wp

    from ..kernels.centreline import centreline_kernel
    if (isinstance(n_points, bool) or not isinstance(n_points, (int, np.integer))
            or not MIN_POINTS <= n_points <= MAX_POINTS):
        raise KnitsimInputError(f"n_points = {n_points!r}: must be an integer in [{MIN_POINTS}, {MAX_POINTS}]")
    x = np.ascontiguousarray(np.asarray(x, dtype=np.float64).reshape(-1, 5))
    n = len(x)
    Bv = np.ascontiguousarray(np.broadcast_to(np.asarray(B, dtype=np.float64), (n,)))
    dv = np.ascontiguousarray(np.broadcast_to(np.asarray(d, dtype=np.float64), (n,)))
    n_ab, n1, n_bc = point_counts(int(n_points))
    m = n_ab + n_bc
    if n == 0:
        z = np.zeros((0,))
        return {"s": np.zeros((0, m)), "xy": np.zeros((0, m, 2)), "W": z, "C": z, "s_AB": z, "Y_C": z,
                "ok": np.zeros(0, bool), "i_B": n_ab - 1}
    s_out = wp.empty((n, m), dtype=wp.float64, device=device)
    xy_out = wp.empty((n, m, 2), dtype=wp.float64, device=device)
    cell_out = wp.empty((n, 4), dtype=wp.float64, device=device)
    ok_out = wp.empty(n, dtype=wp.int32, device=device)
    wp.launch(centreline_kernel, dim=n,
              inputs=[wp.array(x, dtype=wp.float64, device=device), wp.array(Bv, dtype=wp.float64, device=device),
                      wp.array(dv, dtype=wp.float64, device=device), *_gl_arrays(device), n_ab, n1, n_bc],
              outputs=[s_out, xy_out, cell_out, ok_out], device=device)
    cell = cell_out.numpy()
    return {"s": s_out.numpy(), "xy": xy_out.numpy(), "W": cell[:, 0], "C": cell[:, 1], "s_AB": cell[:, 2],
            "Y_C": cell[:, 3], "ok": ok_out.numpy() != 0, "i_B": n_ab - 1}


# --------------------------------------------------------------------------- frames

@dataclass
class PatchRecord:
    """What a patch run saved, as needed for the geometry (all float64 / int arrays).

    Attributes
    ----------
    group_of_cell : (courses, wales) int
    x : (T, G, 5) group states; W, C, s_AB : (T, G) [mm]
    cell_fields : name -> (T, courses, wales): ``stage``, ``phi``, ``force``, ``strain``, ``status``
    params : name -> (courses, wales) cell parameters (``d``, ``B``, ...)
    frame_scalars : name -> (T,): ``grip_strain``, ``cycle``, ``direction``
    scene_text : str
    course_count, wale_count : (courses, wales) or None
        Stitches each cell stands for (a specimen's blocks; None: single stitches).
    rest : dict or None
        The rest state before increment 1, per group: ``x`` (G, 5), ``C``, ``F`` (G,),
        ``W``, ``s_AB`` [mm] and ``label`` (G,); ``grip_strain`` and ``cycle`` of curve.csv's row 0.
        None: not recorded (time code 0 is then increment 1).
    column_slack_mm, column_status : (T, wales) or None
        Each column's slack length [mm] (columns.csv ``slack_mm``) and status code
        (:data:`knitsim.patch.coupling.COLUMN_STATUS_NAMES`).
    run_summary : dict or None
        The run's summary (``summary.json``): its warnings and flags go into the file.
    increments : (T,) int or None
        The increment number (curve.csv's) of each saved row; None: 1 .. T (every increment, a history or
        an unstrided results folder).  A results folder written at ``output.cells_stride`` holds some only.
    increments_written : str
        What the results say of the increments they hold (cells.nc's ``increments_written``), or "".
    """

    group_of_cell: np.ndarray
    x: np.ndarray
    W: np.ndarray
    C: np.ndarray
    s_AB: np.ndarray
    cell_fields: dict
    params: dict
    frame_scalars: dict
    scene_text: str = ""
    source: str = ""
    course_count: np.ndarray | None = None
    wale_count: np.ndarray | None = None
    rest: dict | None = None
    column_slack_mm: np.ndarray | None = None
    column_status: np.ndarray | None = None
    run_summary: dict | None = None
    increments: np.ndarray | None = None
    increments_written: str = ""

    @property
    def saved_increments(self) -> np.ndarray:
        """The increment number of each saved row, (T,) int64: :attr:`increments`, or 1 .. T."""
        if self.increments is None:
            return np.arange(1, self.n_frames + 1, dtype=np.int64)
        inc = np.asarray(self.increments, dtype=np.int64).ravel()
        if inc.shape != (self.n_frames,) or np.any(inc < 1) or np.any(np.diff(inc) <= 0):
            raise KnitsimInputError(f"{self.source or 'record'}: increments must be {self.n_frames} increasing "
                                    "increment numbers >= 1 (one per saved row)")
        return inc

    @property
    def blocks(self) -> bool:
        """Cells stand for blocks of stitches (a specimen): exported instanced (:mod:`knitsim.usd.instanced`)."""
        return any(c is not None and not np.all(np.asarray(c) == 1.0) for c in (self.course_count, self.wale_count))

    @property
    def n_frames(self) -> int:
        """Frames saved (T)."""
        return int(self.x.shape[0])

    @property
    def shape(self) -> tuple[int, int]:
        """(courses, wales)."""
        return tuple(self.group_of_cell.shape)


def material_ids(params: dict) -> np.ndarray:
    """Material of each cell: rank of its parameter set among the distinct ones, (courses, wales) int32."""
    # an absent in-plane width (NaN: the cell jams with its d) is one value; older results lack the field
    stack = np.stack([np.nan_to_num(np.asarray(params[n], dtype=np.float64), nan=-1.0)
                      for n in _MATERIAL_PARAMS if n in params], axis=-1)
    _, inv = np.unique(stack.reshape(-1, stack.shape[-1]), axis=0, return_inverse=True)
    return inv.reshape(stack.shape[:2]).astype(np.int32)


#: units of the material parameters, as a legend writes them
_MATERIAL_UNITS = {"d": "mm", "B": "N mm^2", "m": "", "dahl_sigma": "1/mm", "L": "mm", "W0": "mm", "C0": "mm",
                   "phi0": "rad", "in_plane_width": "mm"}


def material_labels(params: dict, material_id: np.ndarray, scene_text: str = "", blocks: bool = False) -> list[str]:
    """What each material id is, in words, in the order of the ids (``customLayerData["knitsim"]["materials"]``):
    where its cells are (the resolved scene's zones, grade elements included, or the base knit), its yarn and
    knit by name where the scene names them, the parameters by which the materials differ, with units, and
    how many cells (``blocks``: a specimen's blocks) it holds.

    A bare id (``0``, ``1``) told an engineer nothing (a blind probe's quicklook of a basalt zone on E-glass
    read ``material_id 0, 1``, and its first was the basalt: ids follow the sorted parameters)."""
    import tomllib
    try:
        doc = tomllib.loads(scene_text) if scene_text else {}
    except tomllib.TOMLDecodeError:
        doc = {}
    zones = [z for z in doc.get("zones", []) if isinstance(z, dict)]
    shape = material_id.shape
    zone_of = np.full(shape, -1)                        # later zones win, as the scene applies them
    for k, z in enumerate(zones):
        ci, wi = z.get("courses", [0, shape[0]]), z.get("wales", [0, shape[1]])
        zone_of[ci[0]:ci[1], wi[0]:wi[1]] = k

    def zone_name(k: int) -> str:
        if k < 0:
            return "base knit"
        z = zones[k]
        return (f"zone {z['label']!r}" if z.get("label") else
                f"zone on courses {z['courses'][0]}-{z['courses'][1] - 1}, wales {z['wales'][0]}-{z['wales'][1] - 1}")

    def names(k: int) -> str:
        t = doc if k < 0 else zones[k]
        got = [str(t.get(tbl, {}).get("material")) for tbl in ("yarn", "knit")
               if isinstance(t.get(tbl), dict) and t[tbl].get("material")]
        return f" ({' / '.join(got)})" if got else ""

    ids = np.unique(material_id)
    # a parameter is named where it tells the materials apart (where every material has it alike, it says nothing)
    values = {n: np.asarray(params[n], float) for n in _MATERIAL_PARAMS if n in params}
    first = {int(i): tuple(int(v) for v in np.argwhere(material_id == i)[0]) for i in ids}
    differ = [n for n, a in values.items()
              if len({(float(a[first[int(i)]]) if np.isfinite(a[first[int(i)]]) else None) for i in ids}) > 1]
    what = "block" if blocks else "cell"
    out = []
    for i in ids:
        at = material_id == i
        where = list(dict.fromkeys(int(k) for k in zone_of[at]))
        place = zone_name(where[0]) + names(where[0]) + (f" and {len(where) - 1} more zone(s)" if len(where) > 1
                                                         else "")
        cell = first[int(i)]
        diffs = []
        for n in differ:
            v = float(values[n][cell])
            unit = _MATERIAL_UNITS.get(n, "")
            diffs.append(f"{n} {v:.4g}{' ' + unit if unit else ''}" if np.isfinite(v) else f"{n} as d")
        n_at = int(at.sum())
        out.append(f"{place}{': ' + ', '.join(diffs) if diffs else ''}; {n_at} {what}{'s' if n_at != 1 else ''}")
    return out


def record_from_history(h, params: dict, scene_text: str = "", course_count=None, wale_count=None,
                        summary: dict | None = None) -> PatchRecord:
    """A :class:`PatchRecord` from a :class:`~knitsim.patch.runner.PatchHistory` and the model's fields (and,
    for a specimen, the stitches each cell stands for: the model's ``course_count`` and ``wale_count``).

    ``summary``: the run's summary (:func:`knitsim.io.patch_results.patch_summary`), whose warnings and
    flags the file carries.  The rest state is the history's ``group_rest`` (time code 0)."""
    wales = float(h.info.get("wales_represented", h.shape[1]))
    if course_count is None and wale_count is None and not np.isclose(wales, h.shape[1], rtol=1e-12):
        raise KnitsimInputError("the history is a specimen's (cells stand for blocks of stitches): give its "
                                "course_count and wale_count")
    for k in ("x", "W", "s_AB"):
        if k not in h.groups:
            raise KnitsimInputError(f"history has no per-cell states ('{k}' not recorded: the run resumed from a "
                                    "checkpoint that predates them); rerun the scene to export USD")
    cf = {"stage": h.cell_field("label"), "phi": h.cell_field("phi"), "force_per_wale_N": h.cell_field("F"),
          "strain": h.cell_field("strain"), "status": h.cell_field("status")}
    fs = {"grip_strain": np.asarray(h.grip_strain, float), "cycle": np.asarray(h.cycle, float),
          "direction": np.asarray(h.direction, float)}
    rest = None
    gr = getattr(h, "group_rest", None)
    if gr is not None and all(k in gr for k in REST_REQUIRED):
        rest = {k: np.asarray(gr[k], np.int64 if k == "label" else float) for k in REST_REQUIRED}
        # curve.csv's row 0: the rest grip strain (< 0 for a pretensioned specimen), the first cycle
        rest["grip_strain"] = float(h.info.get("rest_grip_strain", 0.0))
        rest["cycle"] = float(h.cycle[0]) if h.n_increments else 1.0
    return PatchRecord(np.asarray(h.group_of_cell), np.asarray(h.groups["x"], float), np.asarray(h.groups["W"], float),
                       np.asarray(h.groups["C"], float), np.asarray(h.groups["s_AB"], float), cf,
                       {k: np.asarray(v, float) for k, v in params.items()}, fs, scene_text, "history",
                       None if course_count is None else np.asarray(course_count, float),
                       None if wale_count is None else np.asarray(wale_count, float),
                       rest, np.asarray(h.column_slack_mm, float), np.asarray(h.column_status, np.int64),
                       summary)


def record_from_results(results_dir) -> PatchRecord:
    """A :class:`PatchRecord` from a ``knitsim run`` results folder (``cells.nc``, ``scene.resolved.toml``)."""
    d = Path(os.fspath(results_dir))
    if not d.is_dir():
        raise KnitsimInputError(f"RESULTS_DIR = {str(d)!r}: not a directory")
    nc = d / "cells.nc"
    if not nc.is_file():
        if (d / "events.csv").is_file() and not (d / "columns.csv").is_file():
            # a `knitsim cell` folder (curve.csv, events.csv): cells without a patch to lay out
            raise KnitsimInputError(f"RESULTS_DIR = {str(d)!r}: holds the results of `knitsim cell` (single cells, "
                                    "no patch to lay out); `knitsim usd` draws a `knitsim run` folder: run the "
                                    "scene as a patch (`knitsim run` with [patch] wales = 1, courses = 1 for one cell)")
        if (d / "sweep.json").is_file():
            # a sweep's folder (results.nc, sweep.json): samples of cells, no patch (a blind probe read "was the
            # run made with output.cell_fields = false?", of a run it never was)
            raise KnitsimInputError(f"RESULTS_DIR = {str(d)!r}: holds the results of `knitsim sweep` (samples of "
                                    "single cells, no patch to lay out); `knitsim usd` draws a `knitsim run` folder: "
                                    "run a sample's scene as a patch (`knitsim run` with [patch] wales and courses)")
        if not (d / "columns.csv").is_file():
            # no run wrote here: not a patch's results (a folder of other files, or of another command)
            raise KnitsimInputError(f"RESULTS_DIR = {str(d)!r}: not a results folder of `knitsim run` (no cells.nc, "
                                    "no columns.csv); give the --out folder of a `knitsim run`")
        raise KnitsimInputError(f"RESULTS_DIR = {str(d)!r}: no cells.nc (was the run made with output.cell_fields "
                                "= false?)")
    import xarray as xr
    try:
        ds = xr.load_dataset(nc, engine="h5netcdf")
    except Exception as exc:  # noqa: BLE001 - a damaged file is a user-level problem
        raise KnitsimInputError(f"RESULTS_DIR = {str(d)!r}: cells.nc is not readable ({exc})") from None
    need = ("state_x", "state_W", "state_C", "state_s_AB", "group_of_cell", "d", "B")
    missing = [k for k in need if k not in ds]
    if missing:
        raise KnitsimInputError(f"RESULTS_DIR = {str(d)!r}: cells.nc has no per-cell states ({', '.join(missing)} "
                                "missing); rerun the scene with this knitsim to export USD")
    cf = {"stage": ds["stage"].values.astype(np.int64), "phi": ds["phi"].values,
          "force_per_wale_N": ds["force_per_wale_N"].values,
          "strain": ds["strain"].values, "status": ds["status"].values.astype(np.int64)}
    params = {k: ds[k].values for k in _MATERIAL_PARAMS if k in ds}
    fs = {k: np.asarray(ds[k].values, float) for k in ("grip_strain", "cycle")}
    dvals = ds["direction"].values
    # direction as the CSV files write it ("load" / "unload"), or +1 / -1 (older results)
    fs["direction"] = (np.where(dvals.astype(str) == "load", 1.0, -1.0) if dvals.dtype.kind in "USO"
                       else np.asarray(dvals, float))
    scene = d / "scene.resolved.toml"
    counts = [np.asarray(ds[k].values, float) if k in ds else None for k in ("course_count", "wale_count")]
    T, wales = ds["state_x"].shape[0], ds["group_of_cell"].shape[1]
    status = ds["column_status"].values.astype(np.int64) if "column_status" in ds else None
    increments = _increments_of_results(d, ds, T)
    return PatchRecord(ds["group_of_cell"].values.astype(np.int64), ds["state_x"].values, ds["state_W"].values,
                       ds["state_C"].values, ds["state_s_AB"].values, cf, params, fs,
                       scene.read_text() if scene.is_file() else "", str(d), *counts,
                       _rest_of_results(d, ds), _column_slack_of_results(d, increments, wales), status,
                       _summary_of(d), increments, str(ds.attrs.get("increments_written", "")))


def _increments_of_results(d: Path, ds, T: int) -> np.ndarray:
    """The increment number of each of cells.nc's T saved rows: its ``increment`` coordinate (curve.csv's
    numbers: every increment, or those of ``output.cells_stride``), or 1 .. T where the file has no such
    coordinate (cells.nc of a knitsim before it was numbered)."""
    if "increment" in ds.coords:
        inc = np.asarray(ds["increment"].values)
        if inc.dtype.kind in "iu" and inc.shape == (T,) and (T == 0 or (inc[0] >= 1 and np.all(np.diff(inc) > 0))):
            return inc.astype(np.int64)
        if "cells_stride" in ds.attrs:
            # a strided file must say which increments it holds: without them its rows cannot be placed
            raise KnitsimInputError(f"RESULTS_DIR = {str(d)!r}: cells.nc's increment coordinate is not {T} "
                                    "increasing increment numbers >= 1; the file is damaged: rerun the scene")
    return np.arange(1, T + 1, dtype=np.int64)


def _csv_rows(path: Path) -> list[dict] | None:
    """The rows of a CSV file as dicts, or None where it is absent or unreadable."""
    import csv
    try:
        with open(path, newline="") as fh:
            return list(csv.DictReader(fh))
    except (OSError, csv.Error, UnicodeDecodeError):
        return None


def _rest_of_results(d: Path, ds) -> dict | None:
    """The rest state of a results folder: cells.nc's :data:`REST_VARIABLES` (per group) and curve.csv's row 0
    (grip strain, cycle); None where cells.nc does not hold it (a results folder of an older knitsim)."""
    if not all(REST_VARIABLES[k] in ds for k in REST_REQUIRED):
        return None
    rest = {k: np.asarray(ds[v].values, np.int64 if k == "label" else float) for k, v in REST_VARIABLES.items()}
    rows = _csv_rows(d / "curve.csv") or []
    row0 = next((r for r in rows if str(r.get("increment", "")).strip() == "0"), None)
    try:
        rest["grip_strain"] = float(row0["grip_strain"]) if row0 else float(ds.attrs.get("rest_grip_strain", 0.0))
        rest["cycle"] = float(row0["cycle"]) if row0 else float(ds["cycle"].values[0])
    except (KeyError, TypeError, ValueError):
        return None
    return rest


def _column_slack_of_results(d: Path, increments: np.ndarray, columns: int) -> np.ndarray | None:
    """Each column's slack length at each saved increment, (len(increments), columns) [mm], from columns.csv
    ``slack_mm``; None where the file or the column is missing or does not cover every saved increment and
    column.

    ``increments``: the increment numbers (curve.csv's) of cells.nc's rows; columns.csv holds every
    increment, so a strided cells.nc's rows are picked from it."""
    inc = np.asarray(increments, dtype=np.int64).ravel()
    row_of = {int(k): i for i, k in enumerate(inc)}
    rows = _csv_rows(d / "columns.csv")
    if not rows or "slack_mm" not in rows[0]:
        return None
    out = np.full((len(inc), columns), np.nan)
    try:
        for r in rows:
            i, j = row_of.get(int(r["increment"]), -1), int(r["column"])
            if i >= 0 and 0 <= j < columns:
                out[i, j] = float(r["slack_mm"])
    except (KeyError, TypeError, ValueError):
        return None
    return out if np.all(np.isfinite(out)) else None


def _summary_of(d: Path) -> dict | None:
    """The run's summary.json, or None."""
    import json
    try:
        doc = json.loads((d / "summary.json").read_text())
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) else None


@dataclass
class PatchFrames:
    """Frames ready for :func:`~knitsim.usd.write_patch_usd` (only the selected ones are built).

    ``frame_indices`` are the time codes (:class:`Timeline`); ``column_values`` name -> (frames,
    columns) per-column values (``column_held``); ``timeline`` what the time codes are.
    """

    frames: list
    d: np.ndarray
    material_id: np.ndarray
    frame_indices: list
    frame_scalars: dict
    fallback_cells: list = field(default_factory=list)
    seconds_geometry: float = 0.0
    column_values: dict = field(default_factory=dict)
    timeline: "Timeline | None" = None


def _fallback_quarter(W, C, n):
    t = np.linspace(0.0, 1.0, n)
    return np.stack([(W / 4)[..., None] * (1 - t), np.maximum(C / 2, 1e-6 * W)[..., None] * t], axis=-1)


def resolve_layout(rec: PatchRecord, layout: str = "auto") -> str:
    """``"courses"`` or ``"instanced"``: the USD layout of a record.

    A specimen (cells standing for blocks of stitches) is always instanced.  ``"auto"`` instances a
    patch whose distinct cells are at most 1/:data:`INSTANCE_GAIN` of its cells (a uniform or
    zoned patch solved with ``dedup``): every stitch of a group has the same shape, so writing the
    shape once per group and a position per stitch is exact and about ``4 (n - 1)`` times smaller
    per stitch (the 23 x 110 uniform specimen of the README: 104 MiB as courses at stride 5).
    """
    if layout not in LAYOUTS:
        raise KnitsimInputError(f"layout = {layout!r}: expected one of {', '.join(LAYOUTS)}")
    if rec.blocks:
        if layout == "courses":
            raise KnitsimInputError("layout = 'courses': a specimen's cells stand for blocks of stitches, which "
                                    "are drawn instanced only; use layout 'auto' or 'instanced'")
        return "instanced"
    if layout == "auto":
        groups = int(np.unique(rec.group_of_cell).size)
        return "instanced" if groups * INSTANCE_GAIN <= rec.group_of_cell.size else "courses"
    return layout


def column_held(rec: PatchRecord) -> np.ndarray:
    """Per saved increment and wale column (strip): whether its state is held rather than the knit's,
    shape (T, wales) bool: the column did not converge or is stopped (``column_status`` != ok), or it
    holds a cell whose status is not ok (failed, or stopped at its force cap), whose last state it
    keeps (as :func:`knitsim.io.patch_results.columns_held`, curve.csv's ``columns_held``)."""
    status = rec.cell_fields.get("status")
    held = (np.asarray(status) != 0).any(axis=1) if status is not None else np.zeros((rec.n_frames, rec.shape[1]), bool)
    if rec.column_status is not None:
        held = held | (np.asarray(rec.column_status) != 0)
    return held


@dataclass(frozen=True)
class Timeline:
    """Which increments of a record a USD file shows, and what its time codes are.

    Attributes
    ----------
    rest : bool
        The rest state is known: time code k is increment k (0 the rest state); else time code k is
        increment k + 1 (a results folder of an older knitsim).
    last_row : int
        The last saved row written (0-based): the run's last, or the first row of a tail in which every
        column is held (:func:`column_held`).
    n_rows : int
        Saved rows of the run.
    increments : tuple of int
        The increment number (curve.csv's) of each saved row; empty: 1 .. ``n_rows`` (every increment).
        A results folder written at ``output.cells_stride`` holds some increments only: its time codes
        are still increment numbers, with gaps between them.
    increments_written : str
        What the results say of the increments they hold (cells.nc's ``increments_written``), or "".
    """

    rest: bool
    last_row: int
    n_rows: int
    increments: tuple = ()
    increments_written: str = ""

    def increment(self, row: int) -> int:
        """The increment number of saved row ``row`` (0-based)."""
        return int(self.increments[row]) if self.increments else int(row) + 1

    @property
    def n_increments(self) -> int:
        """Increments of the run: the last saved row's number (a strided record always keeps the last)."""
        return self.increment(self.n_rows - 1) if self.n_rows else 0

    @property
    def sparse(self) -> bool:
        """The saved rows are not every increment 1 .. n (a results folder written at a stride)."""
        return bool(self.increments) and tuple(self.increments) != tuple(range(1, self.n_rows + 1))

    @property
    def time_codes(self) -> list[int]:
        """The time codes available, increasing: 0 for the rest state where known, then each saved increment
        up to :attr:`last_row` (increment k at time code k, or k - 1 without the rest state)."""
        off = 0 if self.rest else 1
        return ([0] if self.rest else []) + [self.increment(r) - off for r in range(self.last_row + 1)]

    @property
    def length(self) -> int:
        """One past the last time code (time codes 0 .. length - 1; with gaps where :attr:`sparse`)."""
        return self.time_codes[-1] + 1

    def row(self, tc: int) -> int:
        """The saved row of time code ``tc`` (-1: the rest state)."""
        if self.rest and tc == 0:
            return -1
        inc = int(tc) + (0 if self.rest else 1)
        if not self.increments:
            return inc - 1
        i = int(np.searchsorted(np.asarray(self.increments), inc))
        if i >= len(self.increments) or int(self.increments[i]) != inc:
            raise KnitsimInputError(f"time code {tc}: increment {inc} is not among the saved increments")
        return i

    def select(self, stride: int) -> list[int]:
        """Of the time codes, those that are multiples of ``stride`` and the last one
        (:func:`knitsim.arrays.stride_select`: 0, stride, 2 stride, ... where every increment is saved)."""
        return [int(t) for t in stride_select(self.time_codes, stride)]

    def info(self, stride: int, written: int) -> dict:
        """The file's ``customLayerData["knitsim"]["timeline"]``."""
        n_run, last = self.n_increments, self.increment(self.last_row)
        out = {"time_code_is": ("the increment number of the run (curve.csv's increment; 0 is the rest state)"
                                if self.rest else
                                "the saved increment's number less 1: time code k is increment k + 1 (curve.csv's "
                                "numbering); this results folder holds no rest state (cells.nc has no "
                                f"{REST_VARIABLES['x']}), so increment 0 is not drawn"),
               "time_code_0_is_increment": 0 if self.rest else 1, "rest_state": self.rest,
               "increments_in_run": n_run, "last_increment_written": last,
               "stride": int(stride), "time_samples": int(written)}
        if self.sparse:
            # a results folder written at output.cells_stride: the increments between these are not in it
            saved = [self.increment(r) for r in range(self.n_rows)]
            out["saved_increments"] = saved
            out["saved_increments_are"] = (
                f"sparse: the results hold {len(saved)} of the run's {n_run} increments"
                + (f" (cells.nc's increments_written: {self.increments_written})" if self.increments_written else "")
                + "; the time codes are their increment numbers, and the increments between them are not drawn"
                + (f"; of them, those at multiples of the stride {int(stride)} and the last are written"
                   if int(stride) != 1 else ""))
        if self.last_row + 1 < self.n_rows:
            out["increments_not_written"] = f"{last + 1}-{n_run}"
            why = ("stopped at its cells' force cap, failed cells, or not converging: see run.warning_codes")
            if self.sparse:
                # the increment where the hold began may lie between two saved ones: its state is the one drawn at
                # `last`, but which increment it is only curve.csv (every increment) says
                prev = self.increment(self.last_row - 1) if self.last_row > 0 else 0
                out["why_not_written"] = (
                    f"every column is held ({why}) from an increment in {prev + 1}-{last} on (the results hold some "
                    f"increments only; curve.csv's columns_held gives which): the run moves the grip on while the "
                    f"knit keeps the state it had there, drawn at increment {last}, the last written")
            else:
                out["why_not_written"] = (
                    f"from increment {last + 1} on every column is held ({why}): the run moves the grip on while "
                    f"the knit keeps the state of increment {last}, which is the last written")
        return out


def timeline(rec: PatchRecord) -> Timeline:
    """The :class:`Timeline` of a record: its rest state if recorded, and the rows the knit reached (every row,
    up to the first of a tail of rows in which every column is held: there the knit no longer moves), with the
    increment number of each row (:attr:`PatchRecord.saved_increments`)."""
    T = rec.n_frames
    held = column_held(rec).all(axis=1)
    free = np.nonzero(~held)[0]
    last = T - 1 if not held[-1] else (min(int(free[-1]) + 1, T - 1) if len(free) else 0)
    inc = () if rec.increments is None else tuple(int(k) for k in rec.saved_increments)
    return Timeline(rec.rest is not None, last, T, inc, rec.increments_written)


def build_frames(rec: PatchRecord, stride: int = 1, n_points: int = DEFAULT_POINTS, device: str = "cpu",
                 frames: list | None = None, per_group: bool | None = None) -> PatchFrames:
    """The frames of a record at time codes 0, stride, 2 stride, ... and the last (or the time codes ``frames``).

    The time codes are those of :func:`timeline`: increment numbers, 0 the rest state where the record has
    it, up to the last increment the knit reached; of a record saved at a stride (``output.cells_stride``),
    its saved increments only, of which ``stride`` takes those that are multiples of it
    (:meth:`Timeline.select`).  The unselected frames are not built (the exporter is then called with
    ``stride=1``).  ``per_group``: one entry per distinct cell (the instanced layout) instead of
    one per cell; default: a specimen's record.
    """
    per_group = rec.blocks if per_group is None else bool(per_group)
    import time
    if isinstance(stride, bool) or not isinstance(stride, (int, np.integer)) or stride < 1:
        raise KnitsimInputError(f"stride = {stride!r}: must be an integer >= 1")
    T = rec.n_frames
    if T == 0:
        raise KnitsimInputError(f"{rec.source or 'record'}: no saved increments")
    tl = timeline(rec)
    if frames is None:
        sel = tl.select(stride)
    else:
        sel = [int(k) for k in frames]
        codes = tl.time_codes
        if not sel or np.any(np.diff(sel) <= 0) or not set(sel) <= set(codes):
            have = (f"in 0..{tl.length - 1}" if not tl.sparse else
                    f"among the saved ones ({', '.join(map(str, codes[:12]))}{' ...' if len(codes) > 12 else ''})")
            raise KnitsimInputError(f"frames = {frames!r}: must be increasing time codes {have}")
    rows = [tl.row(tc) for tc in sel]                   # -1: the rest state
    goc = rec.group_of_cell
    G = rec.x.shape[1]
    # B and d of each group from a cell of it (identical cells share every parameter)
    flat = goc.ravel()
    _, rep = np.unique(flat, return_index=True)
    Bg = rec.params["B"].ravel()[rep]
    dg = rec.params["d"].ravel()[rep]
    rest = rec.rest
    xs = np.stack([rest["x"] if k < 0 else rec.x[k] for k in rows]).reshape(-1, 5)
    t0 = time.perf_counter()
    cl = quarter_centrelines(xs, np.tile(Bg, len(sel)), np.tile(dg, len(sel)), n_points, device)
    secs = time.perf_counter() - t0
    q_all = cl["xy"].reshape(len(sel), G, -1, 2)
    ok_all = cl["ok"].reshape(len(sel), G)
    mat = material_ids(rec.params)
    held = column_held(rec)
    rest_fields = None
    if rest is not None:
        C0 = rec.params["C0"] if "C0" in rec.params else None
        label = rest["label"][goc]
        rest_fields = {"stage": label, "phi": rest["x"][:, 3][goc], "force_per_wale_N": rest["F"][goc],
                       "strain": (rest["C"][goc] / C0 - 1.0) if C0 is not None else np.full(rec.shape, np.nan),
                       "status": np.zeros(rec.shape, np.int64)}
        rest_fields = {n: np.asarray(a).astype(np.asarray(rec.cell_fields[n]).dtype) for n, a in rest_fields.items()
                       if n in rec.cell_fields}
    out, fallback, col_held, slack = [], [], [], []
    for f, k in enumerate(rows):
        if k < 0:
            Wg, Cg, sg = rest["W"], rest["C"], rest["s_AB"]          # the rest state, as recorded
            cell_fields = rest_fields
            col_held.append(np.zeros(rec.shape[1], np.int32))
            slack.append(np.zeros(rec.shape[1]))           # at rest every column spans its rest length
        else:
            Wg, Cg, sg = rec.W[k], rec.C[k], rec.s_AB[k]
            cell_fields = {n: a[k] for n, a in rec.cell_fields.items()}
            col_held.append(held[k].astype(np.int32))
            if rec.column_slack_mm is not None:
                slack.append(np.asarray(rec.column_slack_mm[k], float))
        q = q_all[f]
        good = ok_all[f] & np.isfinite(Wg) & (Wg > 0) & np.isfinite(Cg) & (Cg > 0)
        with np.errstate(invalid="ignore"):
            closes = ((np.abs(q[:, 0, 0] - Wg / 4) <= 0.5 * yg.ENDPOINT_RTOL * Wg)
                      & (np.abs(q[:, 0, 1]) <= 0.5 * yg.ENDPOINT_RTOL * Wg)
                      & (np.abs(q[:, -1, 0]) <= 0.5 * yg.ENDPOINT_RTOL * Wg))
        good &= closes
        if not np.all(good):
            bad = ~good
            W0g = rec.params["W0"].ravel()[rep] if "W0" in rec.params else np.full(G, 1.0)
            C0g = rec.params["C0"].ravel()[rep] if "C0" in rec.params else np.full(G, 1.0)
            Wg = np.where(np.isfinite(Wg) & (Wg > 0), Wg, W0g)
            Cg = np.where(np.isfinite(Cg) & (Cg > 0), Cg, C0g)
            q = q.copy()
            q[bad] = _fallback_quarter(Wg[bad], Cg[bad], q.shape[1])
        s_ab = np.where(good & np.isfinite(sg) & (sg > 0), sg, np.nan)
        s_ab = np.where(np.isfinite(s_ab), s_ab, 0.25 * np.hypot(Wg / 4, Cg / 2))
        fallback.append(int(np.sum(~good[goc])))
        if per_group:
            # one stitch shape per group, instanced (knitsim.usd.instanced)
            fr = {"quarter_xy": q, "W": Wg, "C": Cg, "s_AB": s_ab,
                  "fields": {n: a.ravel()[rep] for n, a in cell_fields.items()}}
        else:
            fr = {"quarter_xy": q[goc], "W": Wg[goc], "C": Cg[goc], "s_AB": s_ab[goc], "fields": cell_fields}
        if len(slack) == f + 1:
            # an unknown (non-finite) slack length is drawn as no slack: the cells at their own lengths
            fr["column_slack_mm"] = np.where(np.isfinite(slack[f]), np.maximum(slack[f], 0.0), 0.0)
        out.append(fr)
    scalars = {}
    for n, a in rec.frame_scalars.items():
        at_rest = {"grip_strain": rest["grip_strain"], "cycle": rest["cycle"], "direction": 1.0}.get(n, np.nan) \
            if rest is not None else np.nan
        scalars[n] = np.array([at_rest if k < 0 else float(np.asarray(a, float)[k]) for k in rows])
    scalars["columns_held"] = np.array([float(np.sum(h)) for h in col_held])
    return PatchFrames(out, np.asarray(rec.params["d"], float), mat, sel, scalars, fallback, secs,
                       {"column_held": np.array(col_held)}, tl)


def run_flags(summary: dict | None) -> dict:
    """What a file says of the run it shows (``customLayerData["knitsim"]["run"]``): the summary's warnings
    (``warning_codes``, ``warning_messages``) and its flags (``all_expected_end``, ``all_converged``, the force
    cap, failed and stopped cells, non-converged columns); ``{}`` without a summary."""
    if not summary:
        return {}
    ws = [w for w in summary.get("warnings", []) if isinstance(w, dict)]
    out = {"warning_codes": [str(w.get("code", "")) for w in ws],
           "warning_messages": [str(w.get("message", "")) for w in ws]}
    for k in ("all_expected_end", "all_converged", "grip_strain_at_force_cap", "cells_stopped_at_force_cap_at_end",
              "failed_cells_at_end", "non_converged_column_increments",
              "non_converged_column_increments_at_force_cap", "columns_stopped_at_end", "n_increments"):
        if summary.get(k) is not None:
            out[k] = summary[k]
    cut = [c.get("cut_at_grip_strain") for c in summary.get("cycles", []) if isinstance(c, dict)]
    if any(c is not None for c in cut):
        out["cycles_cut_at_grip_strain"] = [float("nan") if c is None else float(c) for c in cut]
    return out


def field_legends() -> dict:
    """Legends of the integer codes the file holds: ``status`` (cell status, primvars:knitsim:status),
    ``stage`` (label codes) and ``column_held``."""
    from ..cell.history import STATUS_NAMES
    from ..cell.stages import LABEL_CODES
    return {"status": {"codes": sorted(STATUS_NAMES), "labels": [STATUS_NAMES[k] for k in sorted(STATUS_NAMES)]},
            "stage": {"codes": sorted(LABEL_CODES.values()), "labels": sorted(LABEL_CODES, key=LABEL_CODES.get)},
            "column_held": {"codes": [0, 1], "labels": ["the knit's state", "held: not the knit's (the column keeps "
                                                        "its last state while the grip moves)"]}}


def export_record(rec: PatchRecord, out_path, *, color_by: str = "stage", stride: int = 1,
                  n_points: int = DEFAULT_POINTS, device: str = "cpu", quicklook=None, curve_basis: str = "catmullRom",
                  metadata: dict | None = None, layout: str = "auto", time_codes_per_second: float = 24.0):
    """Write a record as USD (``.usda`` text, ``.usdc``/``.usd`` binary crate); optionally a quick-look PNG.

    Parameters
    ----------
    rec : PatchRecord
    out_path : path
        Checked writable before any work (:func:`knitsim.usd.export.check_usd_path`).
    color_by : {"stage", "phi", "force", "material", "strain"}
        ``force`` colours by the force per wale of each cell [N] (field ``force_per_wale_N``).
    stride : int, >= 1
        Increments 0, stride, 2 stride, ... and the last one written; time code = increment number
        (module docstring, "Time codes"; of a record saved at a stride, its saved increments that are
        multiples of ``stride``).
    n_points : int, >= 6
        Points per quarter centreline.
    device : str
        Warp device of the centreline kernel.
    quicklook : path, optional
        PNG of the first and last frame rendered from the written file.
    curve_basis : str
        USD BasisCurves basis of the yarn centrelines (``"catmullRom"``: through every point).
    metadata : dict, optional
        Added to the file's ``customLayerData["knitsim"]["metadata"]``.
    layout : {"auto", "courses", "instanced"}
        One BasisCurves yarn per course (read back with :func:`knitsim.usd.read_patch_usd`), or
        one stitch shape per distinct cell instanced over its stitches (read back with
        :func:`knitsim.usd.instanced.read_specimen_usd`); ``"auto"``: :func:`resolve_layout`.
    time_codes_per_second : float
        Playback rate, finite and > 0.

    Returns
    -------
    UsdExportResult
        With ``geometry_seconds`` (kernel), ``fallback_cells`` and ``timeline`` (what was written, the
        file's ``customLayerData["knitsim"]["timeline"]``) added as attributes.
    """
    from .export import _check_rate, check_usd_path, write_patch_usd
    from .quicklook import render_quicklook
    if color_by not in COLOR_FIELDS:
        raise KnitsimInputError(f"color_by = {color_by!r}: expected one of {', '.join(COLOR_FIELDS)}")
    out_path = check_usd_path(out_path)
    _check_rate(time_codes_per_second)
    if quicklook is not None and not os.fspath(quicklook).lower().endswith(".png"):
        raise KnitsimInputError(f"--quicklook = {os.fspath(quicklook)!r}: must end in .png")
    instanced = resolve_layout(rec, layout) == "instanced"
    pf = build_frames(rec, stride, n_points, device, per_group=instanced)
    courses, wales = rec.shape
    geometry = "quarter centreline from the elastica state (kernels/centreline.py, eqs 8-9)"
    md = {"source": rec.source, **({"bands": courses, "strips": wales} if instanced else
                                   {"courses": courses, "wales": wales}),
          "points_per_quarter": int(n_points),
          "fallback_cells": ",".join(str(c) for c in pf.fallback_cells),
          "geometry": geometry + (", one stitch shape per distinct cell, instanced over the stitches of its "
                                  "blocks" if instanced else "")}
    md.update(metadata or {})
    tl_info = pf.timeline.info(stride, len(pf.frame_indices))
    drawing = {}
    if rec.column_slack_mm is None:
        drawing["slack_columns"] = ("the results hold no column slack lengths (columns.csv slack_mm): slack "
                                    "columns are drawn at their cells' course lengths, longer than the grip span")
    if len(np.unique(pf.material_id)) > 1:
        drawing["non_uniform"] = yg.NON_UNIFORM_NOTE
    layer_info = {"timeline": tl_info, "field_legends": field_legends(), "field_docs": dict(FIELD_DOCS),
                  # what each material id is (the quick-look's legend of --color-by material)
                  "materials": {"codes": [int(i) for i in np.unique(pf.material_id)],
                                "labels": material_labels(rec.params, pf.material_id, rec.scene_text, rec.blocks)},
                  **({"run": run_flags(rec.run_summary)} if rec.run_summary else {}),
                  **({"drawing": drawing} if drawing else {})}
    common = dict(color_by=COLOR_FIELDS[color_by], scene_text=rec.scene_text, metadata=md, field_units=FIELD_UNITS,
                  curve_basis=curve_basis, frame_indices=pf.frame_indices, frame_scalars=pf.frame_scalars,
                  column_values=pf.column_values, docs=FIELD_DOCS, layer_info=layer_info,
                  time_codes_per_second=time_codes_per_second)
    if instanced:
        from .instanced import write_specimen_usd
        _, rep = np.unique(rec.group_of_cell.ravel(), return_index=True)
        ones = np.ones(rec.shape)
        res = write_specimen_usd(out_path, pf.frames, np.asarray(rec.params["d"], float).ravel()[rep],
                                 rec.group_of_cell, ones if rec.course_count is None else rec.course_count,
                                 ones if rec.wale_count is None else rec.wale_count,
                                 material_id_group=pf.material_id.ravel()[rep], **common)
    else:
        res = write_patch_usd(out_path, pf.frames, pf.d, material_id=pf.material_id, stride=1, **common)
    res.geometry_seconds = pf.seconds_geometry
    res.fallback_cells = pf.fallback_cells
    res.timeline = tl_info
    if quicklook is not None:
        render_quicklook(out_path, quicklook)
    return res


def export_history(h, params: dict, out_path, *, scene_text: str = "", course_count=None, wale_count=None,
                   summary: dict | None = None, **kw):
    """Write a :class:`~knitsim.patch.runner.PatchHistory` as USD (keywords of :func:`export_record`); a
    specimen's history with its model's ``course_count`` and ``wale_count`` (drawn instanced); ``summary``:
    the run's summary, whose warnings and flags the file carries."""
    return export_record(record_from_history(h, params, scene_text, course_count, wale_count, summary),
                         out_path, **kw)


def export_results(results_dir, out_path, **kw):
    """Write a saved results folder as USD (keywords of :func:`export_record`)."""
    return export_record(record_from_results(results_dir), out_path, **kw)
