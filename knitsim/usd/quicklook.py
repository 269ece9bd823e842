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

The title says what is drawn: the scene's title (from the file's ``scene``), the
patch (courses x wales of single stitches) or specimen (bands x strips of blocks)
and what the colours are; the legend names each colour (a material by where it
lies and how it differs, ``customLayerData["knitsim"]["materials"]``) and the
colour bar its quantity with units (``field_docs``).
"""
from __future__ import annotations

import os
import textwrap

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


#: at most this many entries in a categorical legend (a random field has a material per cell)
MAX_LEGEND_ENTRIES = 12


def _field_label(info: dict, legend: dict) -> str:
    """What the coloured quantity is, with its units: the file's ``field_docs`` entry up to its units
    (``force per wale of the cell [N]``), else the field's name and the legend's units."""
    field = str(legend.get("field", ""))
    doc = str(dict(info.get("field_docs", {})).get(field, ""))
    if "]" in doc:
        return doc[:doc.index("]") + 1]
    units = legend.get("units", "")
    return field + (f" [{units}]" if units else "")


def _what_is_drawn(info: dict, lay: dict) -> str:
    """The patch or specimen the file holds, in words."""
    if lay.get("kind") == "instanced specimen":
        cc, wc = (np.asarray(lay.get(k, []), float) for k in ("course_count", "wale_count"))
        if cc.size and wc.size and np.all(cc == 1.0) and np.all(wc == 1.0):
            # a [patch] of single stitches, drawn instanced (few distinct cells): not a specimen of blocks
            return (f"patch of {lay.get('bands')} courses x {lay.get('strips')} wales (single stitches, drawn "
                    "instanced)")
        return (f"specimen of {lay.get('bands')} x {lay.get('strips')} blocks (bands x strips), "
                f"{int(lay.get('stitches_drawn', 0)):,} whole stitches drawn for "
                f"{float(lay.get('stitches_represented', 0.0)):,.1f}")
    if lay.get("courses") is not None:
        return f"patch of {lay.get('courses')} courses x {lay.get('wales')} wales"
    return ""


def _scene_title(info: dict) -> str:
    """The ``title`` of the scene the file carries, or ''."""
    import tomllib
    try:
        return str(tomllib.loads(str(info.get("scene", "") or "")).get("title", ""))
    except tomllib.TOMLDecodeError:
        return ""


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
        Figure title; default the scene's title, what is drawn (patch or specimen, its size), the file
        name and what the colours are.
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
    # room beside the panels for a categorical legend (a material's entry is two lines of 56 characters)
    extra = (0.0 if legend.get("kind") != "categorical" else
             4.0 if legend.get("field") == "material_id" else 1.5)
    fig, axes = plt.subplots(1, 2, figsize=(12 + extra, 6.5), sharex=True, sharey=True, constrained_layout=True)
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
    colour = ""
    if kind == "categorical":
        labels = [str(lab) for lab in legend["labels"]]
        field = str(legend.get("field", ""))
        if field == "material_id":
            # each material by where it lies and how it differs (a bare id says nothing)
            mats = dict(info.get("materials", {}))
            said = dict(zip((int(c) for c in mats.get("codes", [])), (str(t) for t in mats.get("labels", []))))
            labels = [f"{lab}: {said[int(lab)]}" if lab.lstrip("-").isdigit() and int(lab) in said else lab
                      for lab in labels]
            colour, heading = "material", "material (material_id)"
        else:
            colour = heading = field
        # (wrapped: a material's label runs to a hundred characters)
        handles = [Patch(color=c, label=textwrap.fill(lab, 56, subsequent_indent="    "))
                   for lab, c in zip(labels, legend["colors_hex"])]
        if len(handles) > MAX_LEGEND_ENTRIES:
            # a legend taller than the figure collapsed the panels (60 materials of a random phi0 field)
            rest = len(handles) - MAX_LEGEND_ENTRIES + 1
            handles = handles[:MAX_LEGEND_ENTRIES - 1] + [Patch(color="none", label=(
                f"... and {rest} more (customLayerData knitsim.materials)" if field == "material_id" else
                f"... and {rest} more"))]
        # beside the panels, not over the drawing nor the title ("outside": the constrained layout makes room)
        fig.legend(handles=handles, title=heading, loc="outside right center", fontsize=8, title_fontsize=8)
    elif kind == "continuous":
        sm = plt.cm.ScalarMappable(cmap=legend.get("colormap", "viridis"),
                                   norm=matplotlib.colors.Normalize(legend["vmin"], legend["vmax"]))
        colour = _field_label(info, legend)
        fig.colorbar(sm, ax=list(axes), shrink=0.7, label=colour)
    note = f" (every {step}th vertex)" if step > 1 else ""
    lay = dict(info.get("layout", {}))
    if title is None:
        # what an engineer reads first: the scene, what is drawn, the file, what the colours are
        what = _what_is_drawn(info, lay)
        scene_title = _scene_title(info)
        second = "; ".join(p for p in (what, os.path.basename(usd_path),
                                       f"colour: {colour}" if colour else "") if p)
        title = f"{scene_title}\n{second}" if scene_title else second
    fig.suptitle(title + note, fontsize=11)
    # missing folders are created, as the USD file's are (its path was checked before the export: a folder
    # missing below a writable one passed, and the PNG then failed as a traceback after the USD was written)
    os.makedirs(os.path.dirname(os.path.abspath(png_path)), exist_ok=True)
    fig.savefig(png_path, dpi=dpi)
    plt.close(fig)
    return png_path
