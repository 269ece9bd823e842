"""PNG plots of a sweep dataset (:func:`knitsim.sweep.runner.assemble`).

- one grid parameter: peak force per wale, residual strain and hysteresis
  energy against the parameter, one line per cycle (``plot_sweep.png``);
- two grid parameters: heat maps of the three quantities over the two
  parameters, one column per cycle shown (first and last);
- a Latin hypercube (or a grid of three or more parameters): scatter plots of
  the three quantities against each parameter, first and last cycle.

A scene with several ``[[cells]]`` is plotted for its first cell (named in
the title).  A sample whose cell failed (it did not finish the program: no
convergence, an event not located) has no results (NaN); it is shown as failed
in every plot: a grey cross on the axis and a dotted line (lines), a grey
hatched cell (heat maps), a grey cross at the foot of the axis (scatter), and
the title counts them.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..io.results import atomic_write_bytes

QUANTITIES = (("peak_force_per_wale_N", "peak force per wale [N]"),
              ("residual_strain", "residual strain C/C0 - 1"),
              ("energy_N_mm", "energy per cycle (hysteresis if closed) [N mm]"))


def _figure(nrows: int, ncols: int, w: float = 4.2, h: float = 3.2):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w * ncols, h * nrows), dpi=100)
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, squeeze=False)
    return fig, axes


def _png(fig) -> bytes:
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def _cycles_shown(ds) -> list[int]:
    cyc = [int(c) for c in ds["cycle"].values]
    return sorted({cyc[0], cyc[-1]})


def plot_sweep(ds, out_dir: str | Path) -> list[Path]:
    """Write the plots of ``ds`` into ``out_dir``; returns the written files."""
    out = Path(out_dir)
    keys = json.loads(ds.attrs["parameters"])
    title = ds.attrs.get("title", "") or "knitsim sweep"
    if "cell" in ds.dims:
        label = str(ds["cell_label"].values[0])
        ds = ds.isel(cell=0)
        title += f" (cell 0: {label})"
    grid = ds.attrs["method"] == "grid"
    numeric = all(np.issubdtype(ds[k].dtype, np.number) for k in keys)
    if grid and len(keys) == 1:
        data = _lines(ds, keys[0], title)
    elif grid and len(keys) == 2 and numeric:
        data = _heatmaps(ds, keys, title)
    else:
        data = _scatter(ds, keys, title, grid)
    path = out / "plot_sweep.png"
    atomic_write_bytes(path, data)
    return [path]


FAILED_STYLE = {"marker": "x", "color": "0.45", "s": 28, "lw": 1.2, "zorder": 5}


def _failed(ds) -> np.ndarray:
    """Where a sample's cell failed (status not ok nor force cap, and it ran)."""
    return (np.asarray(ds["expected_end"].values) == 0) & (np.asarray(ds["final_status"].values) >= 0)


def _title(title: str, failed: np.ndarray) -> str:
    n = int(np.count_nonzero(failed))
    return title if not n else f"{title}\n{n} failed sample(s) (grey x / hatched): no results, see summary"


def _lines(ds, key: str, title: str) -> bytes:
    fig, axes = _figure(1, 3)
    x = ds[key].values
    numeric = np.issubdtype(x.dtype, np.number)
    xs = x if numeric else np.arange(len(x))
    bad = _failed(ds)
    for ax, (q, ylabel) in zip(axes[0], QUANTITIES):
        for c in ds["cycle"].values:
            ax.plot(xs, ds[q].sel(cycle=c).values, marker="o", ms=3, label=f"cycle {int(c)}")
        if bad.any():
            lo = ax.get_ylim()[0]
            for xv in xs[bad]:
                ax.axvline(xv, color="0.6", ls=":", lw=0.8)
            ax.scatter(xs[bad], np.full(int(bad.sum()), lo), label="failed", clip_on=False, **FAILED_STYLE)
        ax.set_xlabel(key)
        ax.set_ylabel(ylabel)
        if not numeric:
            ax.set_xticks(xs, [str(v) for v in x])
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.suptitle(_title(title, bad), fontsize=9)
    fig.tight_layout()
    return _png(fig)


def _heatmaps(ds, keys: list[str], title: str) -> bytes:
    cycles = _cycles_shown(ds)
    fig, axes = _figure(len(cycles), 3, 4.4, 3.4)
    kx, ky = keys[1], keys[0]
    x, y = ds[kx].values, ds[ky].values
    bad = (ds["expected_end"] == 0) & (ds["final_status"] >= 0)
    bad_yx = np.asarray(bad.transpose(ky, kx).values)
    for r, c in enumerate(cycles):
        for ax, (q, label) in zip(axes[r], QUANTITIES):
            z = ds[q].sel(cycle=c).transpose(ky, kx).values
            im = ax.pcolormesh(_edges(x), _edges(y), np.ma.masked_invalid(z), shading="flat", cmap="viridis")
            if bad_yx.any():
                ax.pcolor(_edges(x), _edges(y), np.ma.masked_where(~bad_yx, np.ones_like(z)), hatch="xx",
                          cmap="Greys", vmin=0, vmax=3, edgecolor="0.4", shading="flat")
            fig.colorbar(im, ax=ax, shrink=0.85)
            ax.set_xlabel(kx)
            ax.set_ylabel(ky)
            ax.set_title(f"{label}, cycle {c}", fontsize=8)
    fig.suptitle(_title(title, bad_yx), fontsize=9)
    fig.tight_layout()
    return _png(fig)


def _edges(v: np.ndarray) -> np.ndarray:
    """Cell edges around sorted-or-not grid values (midpoints; unit cells for one value)."""
    v = np.asarray(v, dtype=float)
    if len(v) == 1:
        return np.array([v[0] - 0.5, v[0] + 0.5]) if v[0] == 0 else v[0] * np.array([0.95, 1.05])
    mid = 0.5 * (v[1:] + v[:-1])
    return np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])


def _scatter(ds, keys: list[str], title: str, grid: bool) -> bytes:
    cycles = _cycles_shown(ds)
    fig, axes = _figure(3, len(keys), 3.8, 3.0)
    if grid:  # flatten a grid of >= 3 parameters into samples
        flat = ds.stack(sample=keys)
        xs = {k: np.asarray(flat[k].values) for k in keys}
    else:
        flat = ds
        xs = {k: ds[k].values for k in keys}
    bad = _failed(flat)
    for r, (q, label) in enumerate(QUANTITIES):
        for j, k in enumerate(keys):
            ax = axes[r][j]
            for c in cycles:
                y = flat[q].sel(cycle=c).values
                ax.scatter(xs[k][~bad], y[~bad], s=8, alpha=0.7, label=f"cycle {c}")
            if bad.any():
                lo = ax.get_ylim()[0]
                ax.scatter(xs[k][bad], np.full(int(bad.sum()), lo), label="failed", clip_on=False, **FAILED_STYLE)
            ax.set_xlabel(k)
            ax.set_ylabel(label, fontsize=8)
            ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.suptitle(_title(title, bad), fontsize=9)
    fig.tight_layout()
    return _png(fig)


__all__ = ["plot_sweep", "QUANTITIES"]
