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

Where each sample stands with the model's domain (``domain``, found by the
planner before any solve, :mod:`knitsim.cell.domain`) is shown too: a sample
without an admissible rest state was not solved (outside the model): a grey
hollow square on the axis (lines, scatter) or a grey ``//``-hatched cell (heat
maps), apart from the failed ones; a sample outside the domain's box was
solved (an extrapolation): its points are ringed in black (lines, scatter) or
its heat-map cell is dotted.  A sample whose cell has a closed loop that
returns energy (``loop_creates_energy``: a jammed reversal under Table 4's
frozen T, README "Loops that return energy") keeps its values, drawn with a
red diamond around each point (lines, scatter) or a red ``\\\\``-hatched cell
(heat maps).  A sample whose cell stopped at its force cap before the program's
last cycle (a stop, not a failure) has no values for the later cycles: a grey
triangle at the foot of the axis (lines, scatter) or a grey ``--``-hatched cell
in those cycles' heat maps.  A sample whose cell's rest state is compressive
(``rest_state_compressive``: the knit is not free at rest) is not marked on the axes; the title
counts it.  The title counts each kind.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
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
NO_REST_STYLE = {"marker": "s", "facecolors": "none", "edgecolors": "0.45", "s": 30, "lw": 1.2, "zorder": 5}
OUTSIDE_STYLE = {"marker": "o", "facecolors": "none", "edgecolors": "k", "s": 46, "lw": 0.9, "zorder": 4}
CAPPED_STYLE = {"marker": "^", "facecolors": "none", "edgecolors": "0.45", "s": 30, "lw": 1.2, "zorder": 5}
ENERGY_STYLE = {"marker": "D", "facecolors": "none", "edgecolors": "tab:red", "s": 60, "lw": 1.1, "zorder": 4}


def _domain(ds) -> np.ndarray:
    return np.asarray(ds["domain"].values) if "domain" in ds.data_vars else np.full(ds["final_status"].shape, -1)


def _no_rest(ds) -> np.ndarray:
    """Where a sample has no admissible rest state (not solved: outside the model)."""
    from ..cell.domain import DOMAIN_NO_REST_STATE
    from ..cell.history import STATUS_NO_REST_STATE

    return (_domain(ds) == DOMAIN_NO_REST_STATE) | (np.asarray(ds["final_status"].values) == STATUS_NO_REST_STATE)


def _outside(ds) -> np.ndarray:
    """Where a sample lies outside the domain's box (solved: an extrapolation)."""
    from ..cell.domain import DOMAIN_OUTSIDE_BOX

    return _domain(ds) == DOMAIN_OUTSIDE_BOX


def _energy(ds) -> np.ndarray:
    """Where a sample's cell has a closed loop that returns energy (knitsim.io.checks.energy_creating_loops)."""
    return (np.asarray(ds["loop_creates_energy"].values) == 1 if "loop_creates_energy" in ds.data_vars
            else np.zeros(ds["final_status"].shape, dtype=bool))


def _compressive(ds) -> np.ndarray:
    """Where a sample's cell has a compressive rest state (knitsim.io.checks.compressive_rest_state)."""
    return (np.asarray(ds["rest_state_compressive"].values) == 1 if "rest_state_compressive" in ds.data_vars
            else np.zeros(ds["final_status"].shape, dtype=bool))


def _capped(ds) -> np.ndarray:
    """Where a sample's cell stopped at its force cap (the rest of the program not run: the peak of the cycle it
    stopped in is the cap, later cycles NaN)."""
    from ..cell.history import STATUS_FORCE_CAP

    return np.asarray(ds["final_status"].values) == STATUS_FORCE_CAP


def _failed(ds) -> np.ndarray:
    """Where a sample's cell failed (status not ok nor force cap, it ran, and it has a rest state)."""
    return ((np.asarray(ds["expected_end"].values) == 0) & (np.asarray(ds["final_status"].values) >= 0)
            & ~_no_rest(ds))


@dataclass(frozen=True)
class _Marks:
    """Where each kind of marked sample lies (bool arrays in the dataset's sample shape)."""

    failed: np.ndarray
    no_rest: np.ndarray
    outside: np.ndarray
    energy: np.ndarray
    capped: np.ndarray
    compressive: np.ndarray


def _marks(ds) -> _Marks:
    return _Marks(_failed(ds), _no_rest(ds), _outside(ds), _energy(ds), _capped(ds), _compressive(ds))


#: the title's count of each kind of marked sample, in the order shown
_TITLE_PHRASES = (
    ("failed", "failed sample(s) (grey x / xx-hatched): no results"),
    ("no_rest", "without a rest state (grey square / //-hatched): outside the model, not solved"),
    ("outside", "outside the domain's box (ringed / dotted): extrapolated"),
    ("capped", "stopped at the force cap (grey triangle / --hatched): peak = the cap, the rest not run"),
    ("energy", "with a closed loop that returns energy (red diamond / red-hatched: loop_creates_energy)"),
    ("compressive", "with a compressive rest state (not free at rest: rest_state_compressive; not marked)"),
)


def _title(title: str, marks: _Marks) -> str:
    parts = [f"{n} {phrase}" for name, phrase in _TITLE_PHRASES
             if (n := int(np.count_nonzero(getattr(marks, name))))]
    return title if not parts else title + "\n" + "; ".join(parts) + "; see summary.json"


def _mark_axis(ax, xs, marks: _Marks, lines: bool = False) -> None:
    """Failed, rest-less and capped samples at the foot of the axis (they have no values, or none for some
    cycles, to plot); with ``lines`` a dotted line marks the samples without any value."""
    lo = ax.get_ylim()[0]
    for mask, style, label, gap in ((marks.failed, FAILED_STYLE, "failed", True),
                                    (marks.no_rest, NO_REST_STYLE, "no rest state", True),
                                    (marks.capped, CAPPED_STYLE, "stopped at the force cap", False)):
        if mask.any():
            if lines and gap:
                for xv in xs[mask]:
                    ax.axvline(xv, color="0.6", ls=":", lw=0.8)
            ax.scatter(xs[mask], np.full(int(mask.sum()), lo), label=label, clip_on=False, **style)


def _lines(ds, key: str, title: str) -> bytes:
    fig, axes = _figure(1, 3)
    x = ds[key].values
    numeric = np.issubdtype(x.dtype, np.number)
    xs = x if numeric else np.arange(len(x))
    mk = _marks(ds)
    for ax, (q, ylabel) in zip(axes[0], QUANTITIES):
        for c in ds["cycle"].values:
            y = ds[q].sel(cycle=c).values
            ax.plot(xs, y, marker="o", ms=3, label=f"cycle {int(c)}")
            _ring(ax, xs, y, mk, first=c == ds["cycle"].values[0])
        _mark_axis(ax, xs, mk, lines=True)
        ax.set_xlabel(key)
        ax.set_ylabel(ylabel)
        if not numeric:
            ax.set_xticks(xs, [str(v) for v in x])
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.suptitle(_title(title, mk), fontsize=9)
    fig.tight_layout()
    return _png(fig)


def _heatmaps(ds, keys: list[str], title: str) -> bytes:
    cycles = _cycles_shown(ds)
    fig, axes = _figure(len(cycles), 3, 4.4, 3.4)
    kx, ky = keys[1], keys[0]
    x, y = ds[kx].values, ds[ky].values
    t = ds.transpose(ky, kx, ...)
    mk = _marks(t)                                   # [y, x]
    xe, ye = _edges(x), _edges(y)
    for r, c in enumerate(cycles):
        for ax, (q, label) in zip(axes[r], QUANTITIES):
            z = ds[q].sel(cycle=c).transpose(ky, kx).values
            im = ax.pcolormesh(xe, ye, np.ma.masked_invalid(z), shading="flat", cmap="viridis")
            _hatch(ax, xe, ye, mk.failed, "xx", "0.85")
            _hatch(ax, xe, ye, mk.no_rest, "//", "0.85")
            _hatch(ax, xe, ye, mk.outside, "..", None)
            _hatch(ax, xe, ye, mk.energy, "\\\\", None, edge="tab:red")
            _hatch(ax, xe, ye, mk.capped & np.isnan(z), "--", "0.85")
            fig.colorbar(im, ax=ax, shrink=0.85)
            ax.set_xlabel(kx)
            ax.set_ylabel(ky)
            ax.set_title(f"{label}, cycle {c}", fontsize=8)
    fig.suptitle(_title(title, mk), fontsize=9)
    fig.tight_layout()
    return _png(fig)


def _hatch(ax, xe: np.ndarray, ye: np.ndarray, mask: np.ndarray, hatch: str, face: str | None,
           edge: str = "0.3") -> None:
    """Hatch the heat-map cells of ``mask`` [y, x]: grey filled (no values) or only hatched (values kept)."""
    from matplotlib.patches import Rectangle

    for iy, ix in np.argwhere(mask):
        ax.add_patch(Rectangle((xe[ix], ye[iy]), xe[ix + 1] - xe[ix], ye[iy + 1] - ye[iy], hatch=hatch,
                               fill=face is not None, facecolor=face or "none", edgecolor=edge, lw=0.0))


def _ring(ax, xs: np.ndarray, y: np.ndarray, marks: _Marks, first: bool) -> None:
    """Ring the points of samples outside the domain's box (black circle) or whose loop returns energy
    (red diamond); their values are kept."""
    for mask, style, label in ((marks.outside, OUTSIDE_STYLE, "outside domain"),
                               (marks.energy, ENERGY_STYLE, "loop returns energy")):
        if mask.any():
            ax.scatter(xs[mask], y[mask], label=label if first else None, **style)


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
    # a parameter of text values (a rule) is drawn at positions 0, 1, ... named by its values: matplotlib's own
    # categorical axis failed on the masked points of flagged samples (a blind probe's traceback)
    ticks = {}
    for k in keys:
        if not np.issubdtype(np.asarray(xs[k]).dtype, np.number):
            names, pos = np.unique(np.asarray(xs[k]).astype(str), return_inverse=True)
            xs[k], ticks[k] = pos.astype(float), list(names)
    mk = _marks(flat)
    skip = mk.failed | mk.no_rest
    for r, (q, label) in enumerate(QUANTITIES):
        for j, k in enumerate(keys):
            ax = axes[r][j]
            if k in ticks:
                ax.set_xticks(range(len(ticks[k])), ticks[k])
                ax.set_xlim(-0.5, len(ticks[k]) - 0.5)   # every value shown, also one without a point
            for c in cycles:
                y = flat[q].sel(cycle=c).values
                ax.scatter(xs[k][~skip], y[~skip], s=8, alpha=0.7, label=f"cycle {c}")
                _ring(ax, xs[k], y, mk, first=c == cycles[0])
            _mark_axis(ax, xs[k], mk)
            ax.set_xlabel(k)
            ax.set_ylabel(label, fontsize=8)
            ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.suptitle(_title(title, mk), fontsize=9)
    fig.tight_layout()
    return _png(fig)


__all__ = ["plot_sweep", "QUANTITIES"]
