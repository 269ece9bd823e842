"""PNG plots of a sweep dataset (:func:`knitsim.sweep.runner.assemble`).

- one grid parameter: peak force per wale, residual strain and energy per
  cycle against the parameter, one line per cycle, each cycle with its own
  marker and dash (later cycles hollow) so that none hides another
  (``plot_sweep.png``);
- two grid parameters: heat maps of the three quantities over the two
  parameters, one row per cycle shown (first and last);
- a Latin hypercube (or a grid of three or more parameters): scatter plots of
  the three quantities against each parameter, first and last cycle.

A text-valued parameter (a rule's name) is drawn at positions 0, 1, ... in the
sweep's order, named by its values.  The value axes carry no offset notation.
The energy legend says what each cycle's energy is (``energy_kind``: the
hysteresis of a closed cycle, the work of an open one).

A scene with several ``[[cells]]`` is plotted for its first cell; the title
says so, names every cell, and counts the flagged samples of each cell that
is not plotted (every cell's samples are listed in ``summary.json``).  A
sample whose cell failed (it did not finish the program: no convergence, an
event not located) has no results (NaN); it is shown as failed in every plot:
a grey cross on the axis and a dotted line (lines), a grey hatched cell (heat
maps), a grey cross at the foot of the axis (scatter), and the title counts
them.

Where each sample stands with the model's domain (``domain``, found by the
planner before any solve, :mod:`knitsim.cell.domain`) is shown too: a sample
without an admissible rest state was not solved (outside the model): a grey
hollow square on the axis (lines, scatter) or a grey ``//``-hatched cell (heat
maps), apart from the failed ones; a sample outside the domain's box was
solved (an extrapolation): its points are ringed in black (lines, scatter) or
its heat-map cell is dotted.  A sample whose cell has a closed loop that
returns energy (``loop_creates_energy``: a jammed reversal under Table 4's
frozen T, README "Loops that return energy") keeps its values, drawn with a
red diamond around each point (lines, scatter) or a red ``\\``-hatched cell
(heat maps).  A sample whose cell stopped at its force cap (a stop, not a
failure) did not run the rest of its program: the peak of the cycle it stopped
in is the cap (``peak_at_force_cap``) and that cycle's energy, if it never
unloaded, loading work (``energy_kind``); a program that starts by unloading
has a first cycle that never loads, whose peak is its start and whose energy
the unloading's work (``unloading_work``): all drawn apart from the lines
as grey stars (lines, scatter) or grey ``++``-hatched cells kept out of the
colour scale (heat maps); its values that are missing (the residual strain of
a cycle never unloaded, later cycles) are marked by a grey triangle at the
foot of the axis (lines, scatter) or a grey ``--``-hatched cell (heat maps).
A sample whose cell's rest state is compressive (``rest_state_compressive``),
whose loops' heads overlap (``heads_interpenetrate``), whose later cycle
carries nearly no force (``zero_force_cycle``), reloads far below the earlier
loading (``reload_below_earlier_loading``), goes on losing force from cycle to
cycle (``reload_loss_continues``) or reloads above the first loading
(``reload_above_first_loading``) keeps its values, ringed by an orange hexagon
(lines, scatter) or ``oo``-hatched in orange (heat maps): a value the model
gives but a reader should not take as the knit's without reading why (a blind
probe read a title's "not marked" next to a smooth line through such samples).
The title counts each kind.  A parameter whose values are names (a rule, a
material) is drawn as points, not joined by lines: its order is not a scale.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io.results import atomic_write_bytes

QUANTITIES = (("peak_force_per_wale_N", "peak force per wale [N]"),
              ("residual_strain", "residual strain C/C0 - 1"),
              ("energy_N_mm", "energy per cycle [N mm]"))


#: the files :func:`render_sweep` draws (removed by the runner when not drawn: no stale figure)
PLOT_FILES = ("plot_sweep.png",)
#: the title's font size [pt]
TITLE_PT = 9


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


def _finish(fig, text: str) -> None:
    """Put ``text`` above the panels, wrapped to the figure's width, in room added on top of the figure.

    A blind probe found the LHS title cut at the figure's edges and the energy label running into it: the
    lines are wrapped at the width the figure has, and the figure grows by the title's height instead of the
    panels giving it up."""
    import textwrap

    chars = max(40, int(fig.get_figwidth() * 72 / (TITLE_PT * 0.55)))
    lines = [w for line in text.split("\n") for w in (textwrap.wrap(line, chars) or [""])]
    fig.set_figheight(fig.get_figheight() + len(lines) * TITLE_PT * 1.3 / 72)
    fig.suptitle("\n".join(lines), fontsize=TITLE_PT)
    fig.tight_layout()                         # places the panels below the title


def _cycles_shown(ds) -> list[int]:
    cyc = [int(c) for c in ds["cycle"].values]
    return sorted({cyc[0], cyc[-1]})


def _positions(values: np.ndarray) -> tuple[np.ndarray, list[str] | None]:
    """Where the values of a parameter go on an axis: numbers at themselves; text (a rule's name) at 0, 1, ...
    in the order the sweep gives them, with the names for tick labels.  matplotlib's own categorical axis
    failed on the masked points of flagged samples (a blind probe's ConversionError traceback)."""
    v = np.asarray(values)
    if np.issubdtype(v.dtype, np.number) and v.dtype != bool:
        return v.astype(float), None
    names = list(dict.fromkeys(str(x) for x in v.ravel()))
    return np.asarray([names.index(str(x)) for x in v.ravel()], dtype=float).reshape(v.shape), names


def _name_ticks(ax, names: list[str] | None, axis: str = "x") -> None:
    if names is None:
        return
    set_ticks, set_lim = (ax.set_xticks, ax.set_xlim) if axis == "x" else (ax.set_yticks, ax.set_ylim)
    set_ticks(range(len(names)), names)
    set_lim(-0.5, len(names) - 0.5)            # every value shown, also one without a point


def _plain_numbers(ax) -> None:
    """A value axis that reads: no offset notation, and a flat line shown flat.

    A residual strain the same in every sample up to rounding was drawn on a span of 1e-13 with an offset
    ('1e-13 + 3.13e-1', a blind probe): a span below 1e-9 of the values' size is widened to +-5 % of them.
    Call before :func:`_mark_axis`, which puts its markers at the axis' foot."""
    from matplotlib.ticker import ScalarFormatter

    lo, hi = ax.get_ylim()
    mid = 0.5 * (lo + hi)
    if hi - lo <= 1e-9 * abs(mid):
        pad = 0.05 * abs(mid)
        ax.set_ylim(mid - pad, mid + pad)
    fmt = ScalarFormatter(useOffset=False)
    fmt.set_powerlimits((-3, 4))
    ax.yaxis.set_major_formatter(fmt)


def render_sweep(ds) -> dict[str, bytes]:
    """Draw the plots of ``ds`` (:func:`knitsim.sweep.runner.assemble`).

    Returns
    -------
    dict of str to bytes
        File name (:data:`PLOT_FILES`) -> PNG bytes.  Nothing is written: the runner writes the results
        and the plots only once everything is drawn.
    """
    keys = json.loads(ds.attrs["parameters"])
    head = ds.attrs.get("title", "") or "knitsim sweep"
    others = ""
    if "cell" in ds.dims:
        # one cell's values per figure; every cell's flags in the title (a blind probe's failures of cell 1
        # were on the console only)
        labels = [str(v) for v in ds["cell_label"].values]
        head += (f"\ncell 0 ({labels[0]}) plotted, of {len(labels)} cells ("
                 + ", ".join(f"{i} {lab}" for i, lab in enumerate(labels))
                 + "); results.nc and results.csv hold every cell")
        flagged = []
        for c in range(1, len(labels)):
            parts = _counts(_marks(ds.isel(cell=c)))
            if parts:
                flagged.append(f"cell {c} ({labels[c]}): " + ", ".join(parts))
        others = ("cells not plotted: " + "; ".join(flagged)) if flagged else ""
        ds = ds.isel(cell=0)
    grid = ds.attrs["method"] == "grid"
    if grid:
        # lines and heat-map cells in the order of the values, not the order the sweep gives them (a blind probe's
        # "friction.m" = [0.3, 0.1, 0.45, 0.2] drew its lines back and forth, and its heat-map cells over each other,
        # on an axis 13.95-14.7 for knit.L values 13.8-14.4); names keep the sweep's order (_positions)
        for k in keys:
            if _positions(ds[k].values)[1] is None:
                ds = ds.sortby(k)
    if grid and len(keys) == 1:
        data = _lines(ds, keys[0], head, others)
    elif grid and len(keys) == 2:
        data = _heatmaps(ds, keys, head, others)
    else:
        data = _scatter(ds, keys, head, others, grid)
    return {"plot_sweep.png": data}


def plot_sweep(ds, out_dir: str | Path) -> list[Path]:
    """Write the plots of ``ds`` into ``out_dir``; returns the written files."""
    out = Path(out_dir)
    paths = []
    for name, data in render_sweep(ds).items():
        atomic_write_bytes(out / name, data)
        paths.append(out / name)
    return paths


FAILED_STYLE = {"marker": "x", "color": "0.45", "s": 28, "lw": 1.2, "zorder": 5}
NO_REST_STYLE = {"marker": "s", "facecolors": "none", "edgecolors": "0.45", "s": 30, "lw": 1.2, "zorder": 5}
OUTSIDE_STYLE = {"marker": "o", "facecolors": "none", "edgecolors": "k", "s": 46, "lw": 0.9, "zorder": 4}
CAPPED_STYLE = {"marker": "^", "facecolors": "none", "edgecolors": "0.45", "s": 30, "lw": 1.2, "zorder": 5}
ENERGY_STYLE = {"marker": "D", "facecolors": "none", "edgecolors": "tab:red", "s": 60, "lw": 1.1, "zorder": 4}
#: a value the model gives with a warning on its cycles, rest state or heads (kept, ringed)
WARNED_STYLE = {"marker": "H", "facecolors": "none", "edgecolors": "tab:orange", "s": 95, "lw": 1.1, "zorder": 4}
#: a value that is not the knit's: a peak that is the force cap, the loading work of a cycle cut by the cap
AT_CAP_STYLE = {"marker": "*", "facecolors": "none", "edgecolors": "0.3", "s": 90, "lw": 1.0, "zorder": 5}
#: one look per cycle, so that a later cycle's line does not hide an earlier one's
CYCLE_MARKERS = ("o", "s", "^", "v", "D", "P")
CYCLE_LINES = ("-", "--", ":", "-.")


def _cycle_style(n: int) -> dict:
    """Line style of the ``n``-th cycle drawn: its own marker and dash; later cycles hollow, over the first."""
    return {"marker": CYCLE_MARKERS[n % len(CYCLE_MARKERS)], "ls": CYCLE_LINES[n % len(CYCLE_LINES)],
            "ms": 5 if n else 4, "mfc": "none" if n else None, "alpha": 0.85, "lw": 1.3}


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


def _flag(ds, var: str) -> np.ndarray:
    """Where a sample's per-cell flag ``var`` is 1 (False everywhere for a dataset without it)."""
    return (np.asarray(ds[var].values) == 1 if var in ds.data_vars
            else np.zeros(ds["final_status"].shape, dtype=bool))


def _energy(ds) -> np.ndarray:
    """Where a sample's cell has a closed loop that returns energy (knitsim.io.checks.energy_creating_loops)."""
    return _flag(ds, "loop_creates_energy")


def _compressive(ds) -> np.ndarray:
    """Where a sample's cell has a compressive rest state (knitsim.io.checks.compressive_rest_state)."""
    return _flag(ds, "rest_state_compressive")


def _at_rest(ds) -> np.ndarray:
    """Where a sample's cell stopped at rest: its rest state at or above its force cap (``stopped_at_strain`` 0, no
    cycle run; its cycle-1 values are the rest state's, not a cycle's: knitsim.sweep.runner.capped_samples)."""
    from ..cell.history import STATUS_FORCE_CAP

    capped = np.asarray(ds["final_status"].values) == STATUS_FORCE_CAP
    if "stopped_at_strain" not in ds.data_vars:
        return np.zeros(capped.shape, bool)
    return capped & (np.asarray(ds["stopped_at_strain"].values) == 0.0)


def _capped(ds) -> np.ndarray:
    """Where a sample's cell stopped at its force cap while running the program (the rest of the program not run:
    the peak of the cycle it stopped in is the cap, later cycles NaN); one stopped at rest is :func:`_at_rest`."""
    from ..cell.history import STATUS_FORCE_CAP

    return (np.asarray(ds["final_status"].values) == STATUS_FORCE_CAP) & ~_at_rest(ds)


def _failed(ds) -> np.ndarray:
    """Where a sample's cell failed (status not ok nor force cap, it ran, and it has a rest state)."""
    return ((np.asarray(ds["expected_end"].values) == 0) & (np.asarray(ds["final_status"].values) >= 0)
            & ~_no_rest(ds))


def _not_the_knits(ds, q: str, cycle) -> np.ndarray:
    """Where quantity ``q`` of ``cycle`` is not the knit's own value: a peak that is the force cap, the loading
    work of a cycle that never unloaded, the unloading work of one that never loaded (knitsim cell's
    energy_kind loading_work, unloading_work).  Drawn apart from the lines (a blind probe's 10 N cap was drawn
    as a peak, its loading work as a hysteresis 10x the others)."""
    from .runner import ENERGY_KINDS

    def codes(*names):
        return [k for k, v in ENERGY_KINDS.items() if v in names]

    # the peak of a cycle that never loads is its start (warning cycle_without_loading), not a loaded peak
    marks = {"peak_force_per_wale_N": [("peak_at_force_cap", [1]), ("energy_kind", codes("unloading_work"))],
             "energy_N_mm": [("energy_kind", codes("loading_work", "unloading_work"))]}.get(q, [])
    off = np.zeros(ds[q].sel(cycle=cycle).shape, dtype=bool)
    for var, values in marks:
        if var in ds.data_vars:
            off |= np.isin(np.asarray(ds[var].sel(cycle=cycle).values), values)
    return off


def _cycle_values(ds, q: str, cycle) -> np.ndarray:
    """Quantity ``q`` of ``cycle`` as drawn: NaN for a sample stopped at rest (:func:`_at_rest`: it ran no cycle, its
    cycle-1 values are its rest state's; a probe's rest force was drawn as cycle 1's peak), marked at the axis foot."""
    y = np.asarray(ds[q].sel(cycle=cycle).values, dtype=float)
    return np.where(_at_rest(ds).reshape(y.shape), np.nan, y)


def _energy_label(ds, cycle) -> str:
    """What the energy of ``cycle`` is where it is the knit's (hysteresis of a closed cycle, work of an open
    one), for the legend."""
    from .runner import ENERGY_KINDS

    if "energy_kind" not in ds.data_vars:
        return f"cycle {int(cycle)}"
    kinds = np.unique(np.asarray(ds["energy_kind"].sel(cycle=cycle).values))
    names = [{"hysteresis": "hysteresis (closed)", "work": "work (open cycle)"}[ENERGY_KINDS[int(k)]]
             for k in kinds if int(k) >= 0 and ENERGY_KINDS[int(k)] not in ("loading_work", "unloading_work")]
    return f"cycle {int(cycle)}" + (f": {' or '.join(names)}" if names else "")


@dataclass(frozen=True)
class _Marks:
    """Where each kind of marked sample lies (bool arrays in the dataset's sample shape)."""

    failed: np.ndarray
    no_rest: np.ndarray
    outside: np.ndarray
    energy: np.ndarray
    capped: np.ndarray
    at_rest: np.ndarray
    compressive: np.ndarray
    heads: np.ndarray
    zero_force: np.ndarray
    reload_below: np.ndarray
    reload_loss: np.ndarray
    reload_above: np.ndarray

    @property
    def warned(self) -> np.ndarray:
        """Samples whose values stand but carry a model warning (ringed in orange)."""
        return (self.compressive | self.heads | self.zero_force | self.reload_below | self.reload_loss
                | self.reload_above)


def _marks(ds) -> _Marks:
    return _Marks(_failed(ds), _no_rest(ds), _outside(ds), _energy(ds), _capped(ds), _at_rest(ds), _compressive(ds),
                  _flag(ds, "heads_interpenetrate"), _flag(ds, "zero_force_cycle"),
                  _flag(ds, "reload_below_earlier_loading"), _flag(ds, "reload_loss_continues"),
                  _flag(ds, "reload_above_first_loading"))


#: the title's count of each kind of marked sample, in the order shown
_TITLE_PHRASES = (
    ("failed", "failed sample(s) (grey x / xx-hatched): no results"),
    ("no_rest", "without a rest state (grey square / //-hatched): outside the model, not solved"),
    ("outside", "outside the domain's box (ringed / dotted): extrapolated"),
    ("capped", "stopped at the force cap: peak = the cap and energy = loading work (grey star, off the lines / "
               "++-hatched), the rest not run (grey triangle / --hatched)"),
    ("at_rest", "stopped at rest: its rest force at or above the force cap, no cycle run (grey triangle / "
                "--hatched; no value drawn: its cycle-1 values are the rest state's)"),
    ("energy", "with a closed loop that returns energy (red diamond / red-hatched: loop_creates_energy)"),
    ("compressive", "with a compressive rest state (not free at rest: rest_state_compressive; orange)"),
    ("heads", "with overlapping heads of neighbouring loops (heads_interpenetrate; orange)"),
    ("zero_force", "with a later cycle carrying nearly no force (zero_force_cycle; orange)"),
    ("reload_below", "with a reload far below the earlier loading (reload_below_earlier_loading; orange)"),
    ("reload_loss", "losing force cycle after cycle (reload_loss_continues; orange)"),
    ("reload_above", "with a reload above the first loading (reload_above_first_loading; orange)"),
)
#: the same kinds, short (the flags of the cells not plotted)
_SHORT = {"failed": "failed", "no_rest": "no rest state", "outside": "outside the box", "capped": "stopped at the "
          "force cap", "at_rest": "stopped at rest (cap)", "energy": "loop returns energy",
          "compressive": "compressive rest state", "heads": "heads overlap", "zero_force": "zero-force cycle", "reload_below": "reload below earlier loading",
          "reload_loss": "reload loss continues", "reload_above": "reload above first loading"}


def _counts(marks: _Marks) -> list[str]:
    """``"2 failed"``-like counts of each kind of marked sample (short names)."""
    return [f"{n} {_SHORT[name]}" for name, _ in _TITLE_PHRASES if (n := int(np.count_nonzero(getattr(marks, name))))]


def _title(title: str, marks: _Marks, others: str = "") -> str:
    parts = [f"{n} {phrase}" for name, phrase in _TITLE_PHRASES
             if (n := int(np.count_nonzero(getattr(marks, name))))]
    lines = [title] + (["; ".join(parts)] if parts else []) + ([others] if others else [])
    return "\n".join(lines) + ("; see summary.json" if parts or others else "")


def _mark_axis(ax, xs, marks: _Marks, lines: bool = False) -> None:
    """Failed, rest-less and capped samples at the foot of the axis (they have no values, or none for some
    cycles, to plot); with ``lines`` a dotted line marks the samples without any value."""
    lo = ax.get_ylim()[0]
    for mask, style, label, gap in ((marks.failed, FAILED_STYLE, "failed", True),
                                    (marks.no_rest, NO_REST_STYLE, "no rest state", True),
                                    (marks.capped, CAPPED_STYLE, "stopped at the force cap", False),
                                    (marks.at_rest, CAPPED_STYLE, "stopped at rest (cap)", False)):
        if mask.any():
            if lines and gap:
                for xv in xs[mask]:
                    ax.axvline(xv, color="0.6", ls=":", lw=0.8)
            ax.scatter(xs[mask], np.full(int(mask.sum()), lo), label=label, clip_on=False, **style)


_AT_CAP_LABEL = {"peak_force_per_wale_N": "peak = the force cap (not the knit's)",
                 "energy_N_mm": "loading work only (cut by the force cap)"}


def _lines(ds, key: str, title: str, others: str = "") -> bytes:
    fig, axes = _figure(1, 3)
    xs, names = _positions(ds[key].values)
    mk = _marks(ds)
    cycles = ds["cycle"].values
    for ax, (q, ylabel) in zip(axes[0], QUANTITIES):
        labelled = False
        for n, c in enumerate(cycles):
            y = _cycle_values(ds, q, c)
            off = _not_the_knits(ds, q, c) & np.isfinite(y)
            label = _energy_label(ds, c) if q == "energy_N_mm" else f"cycle {int(c)}"
            style = _cycle_style(n)
            if names is not None:                # names have an order, not a scale: points, not a trend line
                style["ls"] = "none"
            ax.plot(xs, np.where(off, np.nan, y), label=label, **style)
            if off.any():
                ax.scatter(xs[off], y[off], label=None if labelled else _AT_CAP_LABEL[q], **AT_CAP_STYLE)
                labelled = True
            _ring(ax, xs, y, mk, first=n == 0)
        _plain_numbers(ax)
        _mark_axis(ax, xs, mk, lines=True)
        ax.set_xlabel(key)
        ax.set_ylabel(ylabel)
        _name_ticks(ax, names)
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7, framealpha=0.6)
    axes[0][2].legend(fontsize=7, framealpha=0.6)
    _finish(fig, _title(title, mk, others))
    return _png(fig)


def _heatmaps(ds, keys: list[str], title: str, others: str = "") -> bytes:
    cycles = _cycles_shown(ds)
    fig, axes = _figure(len(cycles), 3, 4.4, 3.4)
    kx, ky = keys[1], keys[0]
    (x, xnames), (y, ynames) = _positions(ds[kx].values), _positions(ds[ky].values)
    t = ds.transpose(ky, kx, ...)
    mk = _marks(t)                                   # [y, x]
    xe, ye = _edges(x), _edges(y)
    for r, c in enumerate(cycles):
        for ax, (q, label) in zip(axes[r], QUANTITIES):
            z = _cycle_values(t, q, c)
            off = _not_the_knits(t, q, c)
            # a value that is not the knit's stays out of the colour scale (a 10 N cap would set it)
            im = ax.pcolormesh(xe, ye, np.ma.masked_invalid(np.where(off, np.nan, z)), shading="flat",
                               cmap="viridis")
            _hatch(ax, xe, ye, mk.failed, "xx", "0.85")
            _hatch(ax, xe, ye, mk.no_rest, "//", "0.85")
            _hatch(ax, xe, ye, mk.outside, "..", None)
            _hatch(ax, xe, ye, mk.energy, "\\\\", None, edge="tab:red")
            _hatch(ax, xe, ye, mk.warned & ~mk.energy, "oo", None, edge="tab:orange")
            _hatch(ax, xe, ye, (mk.capped & np.isnan(z)) | mk.at_rest, "--", "0.85")
            _hatch(ax, xe, ye, off, "++", "0.85")
            cb = fig.colorbar(im, ax=ax, shrink=0.85)
            cb.formatter.set_useOffset(False)
            ax.set_xlabel(kx)
            ax.set_ylabel(ky)
            _name_ticks(ax, xnames, "x")
            _name_ticks(ax, ynames, "y")
            ax.set_title(f"{label}, cycle {c}", fontsize=8)
    _finish(fig, _title(title, mk, others))
    return _png(fig)


def _hatch(ax, xe: np.ndarray, ye: np.ndarray, mask: np.ndarray, hatch: str, face: str | None,
           edge: str = "0.3") -> None:
    """Hatch the heat-map cells of ``mask`` [y, x]: grey filled (no values) or only hatched (values kept)."""
    from matplotlib.patches import Rectangle

    for iy, ix in np.argwhere(mask):
        ax.add_patch(Rectangle((xe[ix], ye[iy]), xe[ix + 1] - xe[ix], ye[iy + 1] - ye[iy], hatch=hatch,
                               fill=face is not None, facecolor=face or "none", edgecolor=edge, lw=0.0))


def _ring(ax, xs: np.ndarray, y: np.ndarray, marks: _Marks, first: bool) -> None:
    """Ring the points of samples outside the domain's box (black circle), whose loop returns energy
    (red diamond) or that carry a model warning (orange hexagon: the title says which); their values are
    kept."""
    for mask, style, label in ((marks.outside, OUTSIDE_STYLE, "outside domain"),
                               (marks.energy, ENERGY_STYLE, "loop returns energy"),
                               (marks.warned, WARNED_STYLE, "model warning (title)")):
        if mask.any():
            ax.scatter(xs[mask], y[mask], label=label if first else None, **style)


def _edges(v: np.ndarray) -> np.ndarray:
    """Cell edges around sorted-or-not grid values (midpoints; unit cells for one value)."""
    v = np.asarray(v, dtype=float)
    if len(v) == 1:
        return np.array([v[0] - 0.5, v[0] + 0.5]) if v[0] == 0 else v[0] * np.array([0.95, 1.05])
    mid = 0.5 * (v[1:] + v[:-1])
    return np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])


def _scatter(ds, keys: list[str], title: str, others: str, grid: bool) -> bytes:
    cycles = _cycles_shown(ds)
    fig, axes = _figure(3, len(keys), 3.8, 3.0)
    flat = ds.stack(sample=keys) if grid else ds      # a grid of >= 3 parameters flattened into samples
    xs, ticks = {}, {}
    for k in keys:
        xs[k], ticks[k] = _positions(flat[k].values)
    mk = _marks(flat)
    skip = mk.failed | mk.no_rest
    for r, (q, label) in enumerate(QUANTITIES):
        for j, k in enumerate(keys):
            ax = axes[r][j]
            _name_ticks(ax, ticks[k])
            labelled = False
            for n, c in enumerate(cycles):
                y = _cycle_values(flat, q, c)
                off = _not_the_knits(flat, q, c) & np.isfinite(y)
                keep = ~skip & ~off
                name = _energy_label(flat, c) if q == "energy_N_mm" else f"cycle {c}"
                ax.scatter(xs[k][keep], y[keep], s=10 if n else 8, alpha=0.7, label=name,
                           marker=CYCLE_MARKERS[n % len(CYCLE_MARKERS)],
                           **({"facecolors": "none", "edgecolors": f"C{n}"} if n else {}))
                if off.any():
                    ax.scatter(xs[k][off], y[off], label=None if labelled else _AT_CAP_LABEL[q], **AT_CAP_STYLE)
                    labelled = True
                _ring(ax, xs[k], y, mk, first=n == 0)
            _plain_numbers(ax)
            _mark_axis(ax, xs[k], mk)
            ax.set_xlabel(k)
            ax.set_ylabel(label, fontsize=8)
            ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7, framealpha=0.6)
    axes[2][0].legend(fontsize=7, framealpha=0.6)
    _finish(fig, _title(title, mk, others))
    return _png(fig)

__all__ = ["plot_sweep", "render_sweep", "QUANTITIES", "PLOT_FILES"]
