"""Quick-look PNG of a patch, rendered from the USD file itself.

The file is re-opened with ``Usd.Stage.Open``; every ``BasisCurves`` prim is
read at the first and the last time code (points and flattened
``displayColor``), and drawn with matplotlib as two panels seen from +z (the
knit's normal; ``upAxis = Z``).  Segments are drawn back to front (by z), so
the interlocking shows; line widths are the curve widths in data units.  The
legend comes from ``customLayerData["knitsim"]["legend"]``.  What is drawn is
the control polygon; with the default pinned Catmull-Rom basis the curve
passes through every vertex, so at the usual 8+ points per quarter the two
agree to the eye.  A check needs no GUI.
"""
from __future__ import annotations

import os

import numpy as np

from ..errors import KnitsimInputError


def _curves(stage, prims, t):
    from pxr import UsdGeom
    for prim in prims:
        c = UsdGeom.BasisCurves(prim)
        p = np.asarray(c.GetPointsAttr().Get(t), dtype=float)
        if p.size == 0:
            continue
        pv = UsdGeom.PrimvarsAPI(c).GetPrimvar("displayColor")
        col = pv.ComputeFlattened(t) if pv and pv.HasValue() else None
        col = np.full((len(p), 3), 0.6) if col is None or len(col) != len(p) else np.asarray(col, dtype=float)
        w = c.GetWidthsAttr().Get(t)
        w = np.full(len(p), 0.0) if w is None or len(w) == 0 else np.broadcast_to(np.asarray(w, float), (len(p),))
        yield p, col, w


def _read_frame(stage, prims, t, step, instanced=()):
    segs, cols, zs, wids = [], [], [], []
    for p, col, w in [*_curves(stage, prims, t), *instanced]:
        if step > 1:   # decimate: keep every step-th vertex and the last one
            keep = np.unique(np.r_[np.arange(0, len(p), step), len(p) - 1])
            p, col, w = p[keep], col[keep], w[keep]
        segs.append(np.stack([p[:-1, :2], p[1:, :2]], axis=1))
        cols.append(0.5 * (col[:-1] + col[1:]))
        zs.append(0.5 * (p[:-1, 2] + p[1:, 2]))
        wids.append(0.5 * (w[:-1] + w[1:]))
    if not segs:
        return None
    return np.concatenate(segs), np.concatenate(cols), np.concatenate(zs), np.concatenate(wids)


def _instanced_curves(stage, t):
    """Every instance of every PointInstancer at ``t`` as (points (m, 3), colour (m, 3), widths (m,)) per instance:
    its prototype's curve moved to its position (knitsim.usd.instanced writes no orientations or scales)."""
    from pxr import UsdGeom
    out = []
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.PointInstancer):
            continue
        inst = UsdGeom.PointInstancer(prim)
        pos = np.asarray(inst.GetPositionsAttr().Get(t), dtype=float)
        idx = np.asarray(inst.GetProtoIndicesAttr().Get(t), dtype=np.int64)
        protos = []
        for target in inst.GetPrototypesRel().GetTargets():
            c = UsdGeom.BasisCurves(stage.GetPrimAtPath(target))
            p = np.asarray(c.GetPointsAttr().Get(t), dtype=float)
            pv = UsdGeom.PrimvarsAPI(c).GetPrimvar("displayColor")
            col = pv.ComputeFlattened(t) if pv and pv.HasValue() else None
            col = np.full(3, 0.6) if col is None or len(col) == 0 else np.asarray(col, dtype=float)[0]
            w = c.GetWidthsAttr().Get(t)
            w = 0.0 if w is None or len(w) == 0 else float(np.asarray(w, float)[0])
            protos.append((p, col, w))
        for k in range(len(idx)):
            p, col, w = protos[int(idx[k])]
            out.append((p + pos[k], np.broadcast_to(col, p.shape), np.full(len(p), w)))
    return out


def render_quicklook(usd_path, png_path, *, dpi: int = 150, title: str | None = None,
                     max_vertices: int = 500_000) -> str:
    """Draw the first and last time code of a USD patch into a PNG.

    Parameters
    ----------
    usd_path : str or os.PathLike
        A file written by :func:`knitsim.usd.write_patch_usd` (any stage with
        ``BasisCurves`` works; the legend needs knitsim's layer data).
    png_path : str or os.PathLike
        Output image.
    dpi : int
    title : str, optional
        Figure title; default the file name.
    max_vertices : int
        Above this many vertices per frame, every k-th vertex is drawn (a
        10^5-cell patch has millions; at screen resolution they merge anyway).

    Returns
    -------
    str
        ``png_path``.
    """
    import matplotlib
    if "MPLBACKEND" not in os.environ:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Patch
    from pxr import Usd, UsdGeom

    usd_path, png_path = os.fspath(usd_path), os.fspath(png_path)
    if not os.path.exists(usd_path):
        raise KnitsimInputError(f"usd_path={usd_path!r} does not exist")
    stage = Usd.Stage.Open(usd_path)
    prims = [p for p in stage.Traverse() if p.IsA(UsdGeom.BasisCurves)]     # (prototypes under an over: not here)
    has_instancer = any(p.IsA(UsdGeom.PointInstancer) for p in stage.Traverse())
    if not prims and not has_instancer:
        raise KnitsimInputError(f"usd_path={usd_path!r} holds no BasisCurves prim")
    t0, t1 = stage.GetStartTimeCode(), stage.GetEndTimeCode()
    info = dict(stage.GetRootLayer().customLayerData.get("knitsim", {}))
    legend = dict(info.get("legend", {}))

    inst0 = _instanced_curves(stage, t0) if has_instancer else []
    n_vert = (sum(len(UsdGeom.BasisCurves(p).GetPointsAttr().Get(t0) or []) for p in prims)
              + sum(len(c[0]) for c in inst0))
    step = max(1, int(np.ceil(n_vert / max(int(max_vertices), 2))))
    frames = [(t, _read_frame(stage, prims, t, step, inst0 if t == t0 else
                              (_instanced_curves(stage, t) if has_instancer else []))) for t in (t0, t1)]
    all_xy = np.concatenate([f[0].reshape(-1, 2) for _, f in frames if f is not None])
    lo, hi = all_xy.min(axis=0), all_xy.max(axis=0)
    pad = 0.03 * max(hi - lo) + 1e-9
    fig, axes = plt.subplots(1, 2, figsize=(12, 6.5), sharex=True, sharey=True, constrained_layout=True)
    for ax, (t, fr) in zip(axes, frames):
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal")
        ax.set_xlabel("x (course) [mm]")
        ax.set_title(f"time code {t:g}")
        if fr is None:
            continue
        segs, cols, zs, wids = fr
        order = np.argsort(zs, kind="stable")     # back (z < 0) first, front last
        # data-unit width -> points, from the axes' size after the equal aspect
        fig.canvas.draw()
        bbox = ax.get_window_extent()
        pts_per_mm = bbox.width / fig.dpi * 72.0 / (ax.get_xlim()[1] - ax.get_xlim()[0])
        lw = np.maximum(wids[order] * pts_per_mm, 0.3)
        # darken with depth a little, so crossings read
        shade = np.clip(0.75 + 0.25 * (zs[order] - zs.min()) / (np.ptp(zs) + 1e-12), 0, 1)[:, None]
        ax.add_collection(LineCollection(segs[order], colors=cols[order] * shade, linewidths=lw,
                                         capstyle="round"))
    axes[0].set_ylabel("y (wale) [mm]")
    kind = legend.get("kind")
    if kind == "categorical":
        handles = [Patch(color=c, label=str(lab)) for lab, c in zip(legend["labels"], legend["colors_hex"])]
        axes[1].legend(handles=handles, title=str(legend.get("field", "")), loc="upper right", fontsize=8)
    elif kind == "continuous":
        sm = plt.cm.ScalarMappable(cmap=legend.get("colormap", "viridis"),
                                   norm=matplotlib.colors.Normalize(legend["vmin"], legend["vmax"]))
        units = legend.get("units", "")
        fig.colorbar(sm, ax=list(axes), shrink=0.7,
                     label=f"{legend.get('field', '')}" + (f" [{units}]" if units else ""))
    note = f" (every {step}th vertex)" if step > 1 else ""
    lay = dict(info.get("layout", {}))
    if title is None and lay.get("kind") == "instanced specimen":
        # a specimen: its blocks stand for a real number of stitches, the whole ones are drawn
        title = (f"{os.path.basename(usd_path)}: specimen of {lay.get('bands')} x {lay.get('strips')} blocks (bands x "
                 f"strips), {int(lay.get('stitches_drawn', 0)):,} whole stitches drawn for "
                 f"{float(lay.get('stitches_represented', 0.0)):,.1f}")
    fig.suptitle((title if title is not None else os.path.basename(usd_path)) + note)
    fig.savefig(png_path, dpi=dpi)
    plt.close(fig)
    return png_path
