"""Result writers for patch runs (atomic): curve.csv, columns.csv, cells.nc, summary.json, plots, resolved scene.

- ``curve.csv``: ``increment, cycle, direction, grip_strain, force_N, force_per_wale_N``
  (grip force = sum of the column forces; per wale = their mean);
- ``columns.csv``: ``increment, wale, force_per_wale_N, status, iterations, slack_mm``;
- ``cells.nc``: netCDF-3 (xarray, SciPy engine), dimensions ``increment, course, wale``:
  ``strain`` ((C - C0)/C0), ``phi`` [rad], ``force_per_wale_N``, ``stage`` (label codes with
  ``flag_values`` / ``flag_meanings``), ``status``; per column ``column_force_N``,
  ``column_status``; per cell the parameters (``d, B, m, dahl_sigma, L, W0, C0, phi0``);
  coordinates ``grip_strain, cycle, direction``; units in attributes; and, for the yarn
  geometry (:mod:`knitsim.usd.from_results`), per group of identical cells (dimension
  ``group``, ``group_of_cell [course, wale]``): ``state_x [increment, group, unknown]``
  (alpha, beta, gamma, phi [rad], P [N]), ``state_W``, ``state_C``, ``state_s_AB`` [mm];
- ``summary.json``: see :func:`patch_summary`;
- ``force_strain.png``, ``strain_map.png``, ``stage_map.png``; ``scene.resolved.toml``.

Files are built in a hidden sibling directory and renamed in, ``summary.json`` last.
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ..cell.history import STATUS_NAMES, STATUS_OK
from ..cell.stages import LABEL_CODES
from ..patch.coupling import COL_NOT_CONVERGED, COL_OK, COLUMN_STATUS_NAMES
from ..patch.model import PARAM_NAMES
from ..patch.runner import PatchHistory
from .checks import cycle_work, interpenetration, zero_force_cycles
from .results import _num, summary_json, write_result_set

CURVE_COLUMNS = ("increment", "cycle", "direction", "grip_strain", "force_N", "force_per_wale_N")
PATCH_OUTPUT_FILES = ("curve.csv", "columns.csv", "cells.nc", "scene.resolved.toml", "force_strain.png",
                      "strain_map.png", "stage_map.png", "summary.json")
_LABELS = {v: k for k, v in LABEL_CODES.items()}


def curve_csv(h: PatchHistory) -> str:
    """The text of ``curve.csv``."""
    lines = [",".join(CURVE_COLUMNS)]
    # increment 0 is the rest state (grip strain 0); the program's increments are 1 .. n
    cyc0 = str(int(h.cycle[0])) if h.n_increments else "1"
    rest_grip = float(h.info.get("rest_grip_strain", 0.0))     # < 0: a pretensioned specimen at rest
    lines.append(",".join(["0", cyc0, "load", _num(rest_grip), _num(h.rest_force_N), _num(h.rest_force_per_wale_N)]))
    for i in range(h.n_increments):
        lines.append(",".join([str(i + 1), str(int(h.cycle[i])), "load" if h.direction[i] > 0 else "unload",
                               _num(h.grip_strain[i]), _num(h.force_N[i]), _num(h.force_per_wale_N[i])]))
    return "\n".join(lines) + "\n"


def columns_csv(h: PatchHistory) -> str:
    """The text of ``columns.csv`` (one row per increment and wale column)."""
    lines = ["increment,wale,force_per_wale_N,status,iterations,slack_mm"]
    for i in range(h.n_increments):
        for j in range(h.shape[1]):
            lines.append(f"{i},{j},{_num(h.column_force_N[i, j])},{COLUMN_STATUS_NAMES[int(h.column_status[i, j])]},"
                         f"{int(h.column_iterations[i, j])},{_num(h.column_slack_mm[i, j])}")
    return "\n".join(lines) + "\n"


def cells_dataset(h: PatchHistory, fields: dict | None = None):
    """The per-cell fields as an :class:`xarray.Dataset` (see the module docstring)."""
    import xarray as xr
    dims = ("increment", "course", "wale")
    meanings = " ".join(_LABELS[k] for k in sorted(_LABELS))
    n, (courses, wales) = h.n_increments, h.shape
    ds = xr.Dataset(
        {"strain": (dims, h.cell_field("strain"), {"long_name": "strain of the course length (C - C0)/C0",
                                                   "units": "1"}),
         "phi": (dims, h.cell_field("phi"), {"long_name": "friction angle at the crossing", "units": "rad"}),
         "force_per_wale_N": (dims, h.cell_field("F"), {"long_name": "force per wale of the cell", "units": "N"}),
         "stage": (dims, h.cell_field("label").astype(np.int8),
                   {"long_name": "stage label", "flag_values": np.array(sorted(_LABELS), np.int8),
                    "flag_meanings": meanings}),
         "status": (dims, h.cell_field("status").astype(np.int8),
                    {"long_name": "cell status", "flag_values": np.array(sorted(STATUS_NAMES), np.int8),
                     "flag_meanings": " ".join(STATUS_NAMES[k] for k in sorted(STATUS_NAMES))}),
         "column_force_N": (("increment", "wale"), h.column_force_N, {"units": "N"}),
         "column_status": (("increment", "wale"), h.column_status.astype(np.int8),
                           {"flag_values": np.array(sorted(COLUMN_STATUS_NAMES), np.int8),
                            "flag_meanings": " ".join(COLUMN_STATUS_NAMES[k] for k in sorted(COLUMN_STATUS_NAMES))}),
         "force_N": (("increment",), h.force_N, {"units": "N", "long_name": "grip force"})},
        # increment numbers as in curve.csv (0 is the rest state, not stored here), so ds.sel(increment=k,
        # course=i, wale=j) reads one cell at one row; direction as in the CSV files
        coords={"increment": np.arange(1, n + 1, dtype=np.int32), "course": np.arange(courses, dtype=np.int32),
                "wale": np.arange(wales, dtype=np.int32),
                "grip_strain": (("increment",), h.grip_strain), "cycle": (("increment",), h.cycle.astype(np.int32)),
                "direction": (("increment",), np.where(h.direction > 0, "load", "unload"))},
        attrs={"title": "knitsim patch: per-cell fields", "layout": "cell [course, wale]; course 0 at the lower grip",
               "conventions": "units N, mm, rad"})
    for n, arr in (fields or {}).items():
        ds[n] = (("course", "wale"), np.asarray(arr, dtype=np.float64), {"long_name": f"cell parameter {n}"})
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
    if "head_gap" in h.groups:
        ds["head_gap"] = (dims, h.cell_field("head_gap"),
                          {"long_name": "centreline gap between the heads of neighbouring loops", "units": "mm"})
        ds["interpenetrating"] = (dims, h.cell_field("interpenetrating").astype(np.int8),
                                  {"long_name": "1 where the heads overlap (gap below the in-plane width)"})
    return ds


def _encoding(ds) -> dict:
    """gzip level 4, chunked along the increment (a frame is read without the whole file)."""
    enc = {}
    for name, var in ds.data_vars.items():
        if var.dtype.kind in "fiu" and var.ndim:
            chunks = tuple(min(64, s) if d == "increment" else s for d, s in zip(var.dims, var.shape))
            if all(c > 0 for c in chunks):
                enc[name] = {"zlib": True, "complevel": 4, "chunksizes": chunks}
    return enc


def cells_nc(h: PatchHistory, fields: dict | None = None) -> bytes:
    """``cells.nc`` as bytes: netCDF-4 (HDF5) through h5netcdf, compressed and chunked by increment."""
    ds = cells_dataset(h, fields)
    return bytes(ds.to_netcdf(engine="h5netcdf", encoding=_encoding(ds)))


def patch_summary(h: PatchHistory, ref_length: float, **info) -> dict:
    """The ``summary.json`` document.

    Per cycle: peak grip force (and per wale) and the grip strain there;
    residual grip strain, where the force per wale reaches 0 on the cycle's
    unloading branch (linear interpolation between rows; null if it never
    does); ``oint F_grip du`` over the cycle's rows [N mm] (u = grip strain x
    rest length, from the last row of the previous cycle; the first from rest),
    named by :func:`knitsim.io.checks.cycle_work`: ``hysteresis_energy_N_mm`` of a
    closed cycle, ``work_N_mm`` of an open one, ``loading_work_N_mm`` of a loading.  Also the grip
    strain at the first jamming of any cell, non-converged column increments,
    cells whose status is not ok, and rows with a non-finite force.
    """
    F, e = h.force_N, h.grip_strain
    cycles = []
    for k in np.unique(h.cycle):
        rows = np.nonzero(h.cycle == k)[0]
        j = rows[np.argmax(F[rows])]
        entry = {"cycle": int(k), "peak_force_N": float(F[j]), "peak_force_per_wale_N": float(h.force_per_wale_N[j]),
                 "grip_strain_at_peak": float(e[j])}
        unload = rows[h.direction[rows] < 0]
        res = None
        if len(unload):
            prev = np.concatenate([[unload[0] - 1], unload]) if unload[0] > 0 else unload
            for a, b in zip(prev[:-1], prev[1:]):
                if F[a] > 0 >= F[b]:
                    t = F[a] / (F[a] - F[b])
                    res = float(e[a] + t * (e[b] - e[a]))
                    break
        entry["residual_grip_strain"] = res
        path = np.concatenate([[rows[0] - 1], rows]) if rows[0] > 0 else rows
        s_path, f_path = e[path], F[path]
        if rows[0] == 0:                           # the first cycle starts from the rest state
            s_path = np.concatenate([[0.0], s_path])
            f_path = np.concatenate([[h.rest_force_N], f_path])
        work = cycle_work(s_path, f_path, bool(len(unload)))
        entry["closed"] = work["closed"]
        entry[f"{'hysteresis_energy' if work['kind'] == 'hysteresis' else work['kind']}_N_mm"] = \
            work["value"] * ref_length
        cycles.append(entry)
    jam_rows = np.nonzero(np.any(h.groups["label"] == LABEL_CODES["jamming"], axis=1))[0]
    nc = np.argwhere(h.column_status == COL_NOT_CONVERGED)
    bad_cells = np.argwhere(h.cell_field("status")[-1] != STATUS_OK) if h.n_increments else np.zeros((0, 2))
    nonfinite = np.nonzero(~np.isfinite(F))[0]
    warnings = zero_force_cycles([(c["cycle"], c["peak_force_per_wale_N"]) for c in cycles])
    if "interpenetrating" in h.groups:
        warnings += interpenetration(e, h.groups["interpenetrating"], h.groups["head_gap"], h.group_d_jam,
                                     what="distinct cell")
    out = dict(info)
    cells = int(h.shape[0] * h.shape[1])
    solved = int(h.info.get("n_groups", cells))
    out.update(
        cells=cells, courses=int(h.shape[0]), wales=int(h.shape[1]), solved_cells=solved,
        n_increments=int(h.n_increments), solve_s=float(h.wall_s),
        # identical cells are solved once (dedup): the cells represented, and those actually solved
        represented_cell_increments_per_s=float(cells * h.n_increments / h.wall_s) if h.wall_s > 0 else None,
        solved_cell_increments_per_s=float(solved * h.n_increments / h.wall_s) if h.wall_s > 0 else None,
        solver=h.info, cycles=cycles,
        grip_strain_at_first_jamming=float(e[jam_rows[0]]) if len(jam_rows) else None,
        non_converged_column_increments=int(len(nc)),
        non_converged_first=[{"increment": int(i), "wale": int(j)} for i, j in nc[:20]],
        columns_stopped_at_end=int(np.sum(h.column_status[-1] != COL_OK)) if h.n_increments else 0,
        non_ok_cells_at_end=int(len(bad_cells)),
        non_ok_cells_first=[{"course": int(i), "wale": int(j)} for i, j in bad_cells[:20]],
        nonfinite_force_rows=[int(i) for i in nonfinite[:20]],
        all_converged=bool(len(nc) == 0 and len(bad_cells) == 0 and len(nonfinite) == 0),
        warnings=[w.as_dict() for w in warnings],
    )
    return out


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def plot_force_strain(h: PatchHistory, title: str = "") -> bytes:
    """PNG: force per wale vs grip strain (cycles coloured), non-converged increments marked."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(7.5, 5), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    for k in np.unique(h.cycle):
        r = np.nonzero(h.cycle == k)[0]
        if r[0] > 0:
            r = np.concatenate([[r[0] - 1], r])
        ax.plot(h.grip_strain[r], h.force_per_wale_N[r], lw=1.2, label=f"cycle {int(k)}")
    bad = np.any(h.column_status != COL_OK, axis=1)
    if bad.any():
        ax.scatter(h.grip_strain[bad], h.force_per_wale_N[bad], marker="x", color="red", zorder=3,
                   label="column not converged / stopped")
    ax.set_xlabel("grip strain (grip displacement / column rest length)")
    ax.set_ylabel("force per wale [N]")
    ax.set_title(title or f"knitsim patch {h.shape[1]} wales x {h.shape[0]} courses", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _png(fig)


def plot_map(h: PatchHistory, which: str, title: str = "") -> bytes:
    """PNG of the final per-cell ``strain`` or ``stage`` map (courses upward, wales across)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.figure import Figure
    fig = Figure(figsize=(6, 6.5), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    data = h.cell_field(which if which == "strain" else "label")[-1]
    if which == "strain":
        im = ax.imshow(data, origin="lower", aspect="auto", cmap="viridis", interpolation="nearest")
        fig.colorbar(im, ax=ax, label="strain of the course length (C - C0)/C0")
    else:
        names = [_LABELS[k] for k in sorted(_LABELS)]
        cmap = ListedColormap(["#1f77b4", "#2ca02c", "#d62728", "#7f7f7f"])
        im = ax.imshow(data, origin="lower", aspect="auto", cmap=cmap, interpolation="nearest",
                       norm=BoundaryNorm(np.arange(-0.5, 4.5), 4))
        cb = fig.colorbar(im, ax=ax, ticks=range(4))
        cb.ax.set_yticklabels(names)
    ax.set_xlabel("wale")
    ax.set_ylabel("course")
    ax.set_title(title or f"final {which} (grip strain {h.grip_strain[-1]:.3g})", fontsize=10)
    return _png(fig)


def write_patch_results(out_dir: str | Path, h: PatchHistory, summary: dict, resolved_toml: str,
                        fields: dict | None = None, plot: bool = True, cell_fields: bool = True,
                        title: str = "") -> dict[str, Path]:
    """Write the result set into ``out_dir`` atomically (``summary.json`` last); returns the files by name."""
    files = {"curve.csv": curve_csv(h).encode(), "columns.csv": columns_csv(h).encode(),
             "scene.resolved.toml": resolved_toml.encode()}
    if cell_fields:
        files["cells.nc"] = cells_nc(h, fields)
    if plot:
        files["force_strain.png"] = plot_force_strain(h, title)
        files["strain_map.png"] = plot_map(h, "strain")
        files["stage_map.png"] = plot_map(h, "stage")
    files["summary.json"] = summary_json(summary).encode()
    return write_result_set(out_dir, files, PATCH_OUTPUT_FILES)


__all__ = ["CURVE_COLUMNS", "PATCH_OUTPUT_FILES", "curve_csv", "columns_csv", "cells_dataset", "cells_nc",
           "patch_summary", "plot_force_strain", "plot_map", "write_patch_results", "PARAM_NAMES"]
