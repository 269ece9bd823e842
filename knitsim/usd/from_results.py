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
  ``phi`` [rad], ``force`` (force per wale of the cell [N]), ``strain``
  ((C - C0)/C0), ``status``; ``material_id`` (static) numbers the distinct
  parameter sets (``d, B, m, dahl_sigma, L, W0, C0, phi0``) in sorted order;
- per frame, ``grip_strain``, ``cycle`` and ``direction`` as time-sampled
  attributes of ``/Patch``.

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

from ..errors import KnitsimInputError
from . import yarn_geometry as yg

#: points per quarter centreline (A .. C) by default; Catmull-Rom looks smooth from about 7
DEFAULT_POINTS = 9
MIN_POINTS = 6
#: --color-by names and the frame field each one colours by
COLOR_FIELDS = {"stage": "stage", "phi": "phi", "force": "force", "material": "material_id", "strain": "strain"}
FIELD_UNITS = {"phi": "rad", "force": "N", "strain": "1"}
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
    if isinstance(n_points, bool) or not isinstance(n_points, (int, np.integer)) or n_points < MIN_POINTS:
        raise KnitsimInputError(f"n_points = {n_points!r}: must be an integer >= {MIN_POINTS}")
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

    @property
    def blocks(self) -> bool:
        """Cells stand for blocks of stitches (a specimen): exported instanced (:mod:`knitsim.usd.instanced`)."""
        return any(c is not None and not np.all(np.asarray(c) == 1.0) for c in (self.course_count, self.wale_count))

    @property
    def n_frames(self) -> int:
        return int(self.x.shape[0])

    @property
    def shape(self) -> tuple[int, int]:
        return tuple(self.group_of_cell.shape)


def material_ids(params: dict) -> np.ndarray:
    """Material of each cell: rank of its parameter set among the distinct ones, (courses, wales) int32."""
    # an absent in-plane width (NaN: the cell jams with its d) is one value; older results lack the field
    stack = np.stack([np.nan_to_num(np.asarray(params[n], dtype=np.float64), nan=-1.0)
                      for n in _MATERIAL_PARAMS if n in params], axis=-1)
    _, inv = np.unique(stack.reshape(-1, stack.shape[-1]), axis=0, return_inverse=True)
    return inv.reshape(stack.shape[:2]).astype(np.int32)


def record_from_history(h, params: dict, scene_text: str = "", course_count=None, wale_count=None) -> PatchRecord:
    """A :class:`PatchRecord` from a :class:`~knitsim.patch.runner.PatchHistory` and the model's fields (and,
    for a specimen, the stitches each cell stands for: the model's ``course_count`` and ``wale_count``)."""
    wales = float(h.info.get("wales_represented", h.shape[1]))
    if course_count is None and wale_count is None and not np.isclose(wales, h.shape[1], rtol=1e-12):
        raise KnitsimInputError("the history is a specimen's (cells stand for blocks of stitches): give its "
                                "course_count and wale_count")
    for k in ("x", "W", "s_AB"):
        if k not in h.groups:
            raise KnitsimInputError(f"history has no per-cell states ('{k}' not recorded: the run resumed from a "
                                    "checkpoint that predates them); rerun the scene to export USD")
    cf = {"stage": h.cell_field("label"), "phi": h.cell_field("phi"), "force": h.cell_field("F"),
          "strain": h.cell_field("strain"), "status": h.cell_field("status")}
    fs = {"grip_strain": np.asarray(h.grip_strain, float), "cycle": np.asarray(h.cycle, float),
          "direction": np.asarray(h.direction, float)}
    return PatchRecord(np.asarray(h.group_of_cell), np.asarray(h.groups["x"], float), np.asarray(h.groups["W"], float),
                       np.asarray(h.groups["C"], float), np.asarray(h.groups["s_AB"], float), cf,
                       {k: np.asarray(v, float) for k, v in params.items()}, fs, scene_text, "history",
                       None if course_count is None else np.asarray(course_count, float),
                       None if wale_count is None else np.asarray(wale_count, float))


def record_from_results(results_dir) -> PatchRecord:
    """A :class:`PatchRecord` from a ``knitsim run`` results folder (``cells.nc``, ``scene.resolved.toml``)."""
    d = Path(os.fspath(results_dir))
    if not d.is_dir():
        raise KnitsimInputError(f"RESULTS_DIR = {str(d)!r}: not a directory")
    nc = d / "cells.nc"
    if not nc.is_file():
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
    cf = {"stage": ds["stage"].values.astype(np.int64), "phi": ds["phi"].values, "force": ds["force_per_wale_N"].values,
          "strain": ds["strain"].values, "status": ds["status"].values.astype(np.int64)}
    params = {k: ds[k].values for k in _MATERIAL_PARAMS if k in ds}
    fs = {k: np.asarray(ds[k].values, float) for k in ("grip_strain", "cycle")}
    dvals = ds["direction"].values
    # direction as the CSV files write it ("load" / "unload"), or +1 / -1 (older results)
    fs["direction"] = (np.where(dvals.astype(str) == "load", 1.0, -1.0) if dvals.dtype.kind in "USO"
                       else np.asarray(dvals, float))
    scene = d / "scene.resolved.toml"
    counts = [np.asarray(ds[k].values, float) if k in ds else None for k in ("course_count", "wale_count")]
    return PatchRecord(ds["group_of_cell"].values.astype(np.int64), ds["state_x"].values, ds["state_W"].values,
                       ds["state_C"].values, ds["state_s_AB"].values, cf, params, fs,
                       scene.read_text() if scene.is_file() else "", str(d), *counts)


@dataclass
class PatchFrames:
    """Frames ready for :func:`~knitsim.usd.write_patch_usd` (only the selected ones are built)."""

    frames: list
    d: np.ndarray
    material_id: np.ndarray
    frame_indices: list
    frame_scalars: dict
    fallback_cells: list = field(default_factory=list)
    seconds_geometry: float = 0.0


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


def build_frames(rec: PatchRecord, stride: int = 1, n_points: int = DEFAULT_POINTS, device: str = "cpu",
                 frames: list | None = None, per_group: bool | None = None) -> PatchFrames:
    """The frames of a record: frames 0, stride, 2 stride, ... and the last (or the indices ``frames``).

    The unselected frames are not built (the exporter is then called with
    ``stride=1``); their indices are kept as the time codes.  ``per_group``: one entry per
    distinct cell (the instanced layout) instead of one per cell; default: a specimen's record.
    """
    per_group = rec.blocks if per_group is None else bool(per_group)
    import time
    if isinstance(stride, bool) or not isinstance(stride, (int, np.integer)) or stride < 1:
        raise KnitsimInputError(f"stride = {stride!r}: must be an integer >= 1")
    T = rec.n_frames
    if T == 0:
        raise KnitsimInputError(f"{rec.source or 'record'}: no saved increments")
    sel = list(range(0, T, int(stride))) if frames is None else [int(k) for k in frames]
    if sel[-1] != T - 1 and frames is None:
        sel.append(T - 1)
    goc = rec.group_of_cell
    G = rec.x.shape[1]
    # B and d of each group from a cell of it (identical cells share every parameter)
    flat = goc.ravel()
    _, rep = np.unique(flat, return_index=True)
    Bg = rec.params["B"].ravel()[rep]
    dg = rec.params["d"].ravel()[rep]
    t0 = time.perf_counter()
    xs = rec.x[sel].reshape(-1, 5)
    cl = quarter_centrelines(xs, np.tile(Bg, len(sel)), np.tile(dg, len(sel)), n_points, device)
    secs = time.perf_counter() - t0
    q_all = cl["xy"].reshape(len(sel), G, -1, 2)
    ok_all = cl["ok"].reshape(len(sel), G)
    mat = material_ids(rec.params)
    out, fallback = [], []
    for f, k in enumerate(sel):
        Wg, Cg = rec.W[k], rec.C[k]
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
        s_ab = np.where(good & np.isfinite(rec.s_AB[k]) & (rec.s_AB[k] > 0), rec.s_AB[k], np.nan)
        s_ab = np.where(np.isfinite(s_ab), s_ab, 0.25 * np.hypot(Wg / 4, Cg / 2))
        fallback.append(int(np.sum(~good[goc])))
        if per_group:
            # one stitch shape per group, instanced (knitsim.usd.instanced)
            out.append({"quarter_xy": q, "W": Wg, "C": Cg, "s_AB": s_ab,
                        "fields": {n: a[k].ravel()[rep] for n, a in rec.cell_fields.items()}})
        else:
            out.append({"quarter_xy": q[goc], "W": Wg[goc], "C": Cg[goc], "s_AB": s_ab[goc],
                        "fields": {n: a[k] for n, a in rec.cell_fields.items()}})
    scalars = {n: np.asarray(a, float)[sel] for n, a in rec.frame_scalars.items()}
    return PatchFrames(out, np.asarray(rec.params["d"], float), mat, sel, scalars, fallback, secs)


def export_record(rec: PatchRecord, out_path, *, color_by: str = "stage", stride: int = 1,
                  n_points: int = DEFAULT_POINTS, device: str = "cpu", quicklook=None, curve_basis: str = "catmullRom",
                  metadata: dict | None = None, layout: str = "auto"):
    """Write a record as USD (``.usda`` text, ``.usdc``/``.usd`` binary crate); optionally a quick-look PNG.

    Parameters
    ----------
    rec : PatchRecord
    out_path : path
    color_by : {"stage", "phi", "force", "material", "strain"}
    stride : int, >= 1
        Frames 0, stride, 2 stride, ... and the last one; time code = increment index.
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

    Returns
    -------
    UsdExportResult
        With ``geometry_seconds`` (kernel) and ``fallback_cells`` added as attributes.
    """
    from .export import write_patch_usd
    from .quicklook import render_quicklook
    if color_by not in COLOR_FIELDS:
        raise KnitsimInputError(f"color_by = {color_by!r}: expected one of {', '.join(COLOR_FIELDS)}")
    out_path = os.fspath(out_path)
    ext = os.path.splitext(out_path)[1].lower()
    if ext not in (".usda", ".usdc", ".usd"):
        raise KnitsimInputError(f"--out = {out_path!r}: must end in .usda, .usdc or .usd")
    if quicklook is not None and not os.fspath(quicklook).lower().endswith(".png"):
        raise KnitsimInputError(f"--quicklook = {os.fspath(quicklook)!r}: must end in .png")
    instanced = resolve_layout(rec, layout) == "instanced"
    pf = build_frames(rec, stride, n_points, device, per_group=instanced)
    courses, wales = rec.shape
    geometry = "quarter centreline from the elastica state (kernels/centreline.py, eqs 8-9)"
    md = {"source": rec.source, **({"bands": courses, "strips": wales} if instanced else
                                   {"courses": courses, "wales": wales}),
          "points_per_quarter": int(n_points), "stride": int(stride), "frames_in_run": rec.n_frames,
          "fallback_cells": ",".join(str(c) for c in pf.fallback_cells),
          "geometry": geometry + (", one stitch shape per distinct cell, instanced over the stitches of its "
                                  "blocks" if instanced else "")}
    md.update(metadata or {})
    common = dict(color_by=COLOR_FIELDS[color_by], scene_text=rec.scene_text, metadata=md, field_units=FIELD_UNITS,
                  curve_basis=curve_basis, frame_indices=pf.frame_indices, frame_scalars=pf.frame_scalars)
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
    if quicklook is not None:
        render_quicklook(out_path, quicklook)
    return res


def export_history(h, params: dict, out_path, *, scene_text: str = "", course_count=None, wale_count=None, **kw):
    """Write a :class:`~knitsim.patch.runner.PatchHistory` as USD (keywords of :func:`export_record`); a
    specimen's history with its model's ``course_count`` and ``wale_count`` (drawn instanced)."""
    return export_record(record_from_history(h, params, scene_text, course_count, wale_count), out_path, **kw)


def export_results(results_dir, out_path, **kw):
    """Write a saved results folder as USD (keywords of :func:`export_record`)."""
    return export_record(record_from_results(results_dir), out_path, **kw)
