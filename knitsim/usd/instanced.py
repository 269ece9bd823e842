"""USD export of a specimen whose cells stand for blocks of stitches: one stitch shape per
distinct cell, instanced over every stitch of its blocks (``UsdGeom.PointInstancer``).

Why instancing.  In a specimen (``[specimen]``, :mod:`knitsim.patch.model`) a cell of the
``bands x strips`` grid stands for ``course_count x wale_count`` identical stitches: they carry
the same force and have the same state, so they have the same shape; only their positions
differ.  Drawing every stitch as its own curve vertices (the ``[patch]`` layout of
:mod:`knitsim.usd.export`) writes ``4 (n - 1)`` points per stitch and frame: a 50 mm x 100 mm
jersey (37 x 111 = 4,100 stitches) is 131,000 points per frame.  Here each distinct cell
(group of identical cells solved once) is written once per frame as a prototype curve of
``4 (n - 1) + 1`` points, and each stitch is one instance: its prototype index (static) and
its position (one point per frame), 32 times less per frame at n = 9, and the geometry work
is per distinct cell, not per stitch.  Renderers (Hydra, usdview, Omniverse) draw
instancers natively; :func:`knitsim.usd.quicklook.render_quicklook` expands them.

Layout of the stage::

    /Patch                          Xform, default prim; knitsim:grip_strain etc. time-sampled
    /Patch/Stitches                 PointInstancer: protoIndices (static), positions (per frame),
                                    extent (per frame), primvars knitsim:band, knitsim:strip (static,
                                    per instance)
    /Patch/Stitches/Prototypes      over (not drawn by itself)
        group_0000 ...              BasisCurves, one stitch A' -> head -> A -> sinker -> A''
                                    (:func:`knitsim.usd.yarn_geometry.stitch_points`, A' at the
                                    origin), points per frame, width d, displayColor and the
                                    cell's fields (stage, phi, force, strain, status) as constant
                                    primvars per frame, material_id static

Stitches drawn.  A block stands for a real, not necessarily whole, number of stitches
(band length / C0 courses, strip width / W0 wales).  Whole stitches are drawn: along each
strip the courses by cumulative rounding of the course counts (block k of a strip draws
``round(c_0 + ... + c_k) - round(c_0 + ... + c_{k-1})`` courses, so the strip draws
``round(its courses)`` in all and no band gap opens), across each band the wales likewise.
The stitches of a block sit on its lattice, ``(a W, b C)`` from the block's origin, the
blocks stacked as the stitches of a ``[patch]`` (x cumulative along a band, y cumulative
along a strip).  The drawn specimen is within half a stitch of the real one in each
direction; the counts drawn and represented are in ``customLayerData``.  A slack strip
(``column_slack_mm`` > 0 in a frame: its blocks, stacked, are longer than the grip span) is drawn
compressed between the grips, every stitch keeping its shape (positions along y scaled by
:func:`knitsim.usd.yarn_geometry.slack_pitch_scale`); ``knitsim:column_slack_mm`` of ``/Patch``
gives that length per strip and time.
"""
from __future__ import annotations

import os
import time as _time
from dataclasses import dataclass

import numpy as np

from ..errors import KnitsimInputError
from . import yarn_geometry as yg

INSTANCER_PATH = "/Patch/Stitches"
PROTOTYPES_PATH = "/Patch/Stitches/Prototypes"
PROTOTYPE_FORMAT = "group_{:04d}"
LAYOUT_KIND = "instanced specimen"


def drawn_counts(count: np.ndarray, axis: int) -> np.ndarray:
    """Whole stitches drawn for each block by cumulative rounding of ``count`` along ``axis``.

    ``round(S_k) - round(S_{k-1})`` with ``S_k`` the cumulative count (round half up): the
    counts drawn sum to the rounded total along the axis, and a block of at least one
    stitch draws at least one.
    """
    c = np.asarray(count, dtype=float)
    cum = np.cumsum(c, axis=axis)
    r = np.floor(cum + 0.5).astype(np.int64)
    first = np.take(r, [0], axis=axis)
    return np.concatenate([first, np.diff(r, axis=axis)], axis=axis)


@dataclass(frozen=True)
class StitchLattice:
    """Every drawn stitch of a specimen: its block and its place in the block (static).

    Attributes
    ----------
    band, strip : ndarray of int, shape [N]
        Block of each stitch.
    a, b : ndarray of int, shape [N]
        Wale and course of the stitch within its block.
    wales_drawn, courses_drawn : ndarray of int, shape [bands, strips]
    """

    band: np.ndarray
    strip: np.ndarray
    a: np.ndarray
    b: np.ndarray
    wales_drawn: np.ndarray
    courses_drawn: np.ndarray

    @property
    def n(self) -> int:
        """Stitches drawn (N)."""
        return int(len(self.band))

    @classmethod
    def of(cls, course_count, wale_count) -> "StitchLattice":
        """The stitches drawn for blocks standing for ``course_count`` x ``wale_count`` stitches
        (shape [bands, strips]), rounded to whole stitches by :func:`drawn_counts`."""
        nc = drawn_counts(course_count, axis=0)      # along each strip
        nw = drawn_counts(wale_count, axis=1)        # across each band
        band, strip, a, b = [], [], [], []
        for i in range(nc.shape[0]):
            for j in range(nc.shape[1]):
                k = int(nc[i, j]) * int(nw[i, j])
                if k == 0:
                    continue
                bb, aa = np.divmod(np.arange(k), int(nw[i, j]))
                band.append(np.full(k, i))
                strip.append(np.full(k, j))
                a.append(aa)
                b.append(bb)
        cat = (lambda xs: np.concatenate(xs).astype(np.int64) if xs else np.zeros(0, np.int64))
        return cls(cat(band), cat(strip), cat(a), cat(b), nw, nc)

    def positions(self, W: np.ndarray, C: np.ndarray) -> np.ndarray:
        """Position of each stitch's A' point [mm], shape [N, 3], from each block's current W and C."""
        x0 = np.zeros_like(W)
        y0 = np.zeros_like(C)
        np.cumsum((self.wales_drawn * W)[:, :-1], axis=1, out=x0[:, 1:])
        np.cumsum((self.courses_drawn * C)[:-1, :], axis=0, out=y0[1:, :])
        i, j = self.band, self.strip
        out = np.zeros((self.n, 3))
        out[:, 0] = x0[i, j] + self.a * W[i, j]
        out[:, 1] = y0[i, j] + self.b * C[i, j]
        return out


def write_specimen_usd(path, frames: list, d_group: np.ndarray, group_of_cell: np.ndarray, course_count,
                       wale_count, *, material_id_group=None, color_by: str | None = "stage",
                       scene_text: str = "", metadata: dict | None = None, field_units: dict | None = None,
                       curve_basis: str = "catmullRom", frame_indices=None, frame_scalars: dict | None = None,
                       time_codes_per_second: float = 24.0, column_values: dict | None = None,
                       docs: dict | None = None, layer_info: dict | None = None):
    """Write a specimen over time as an instanced USD stage (module docstring).

    Parameters
    ----------
    path : path
        ``.usda`` text, ``.usdc`` / ``.usd`` binary crate.
    frames : list of dict
        Per frame and per group of identical cells: ``quarter_xy`` (G, n, 2) [mm], ``W``, ``C``,
        ``s_AB`` (G,) [mm], ``fields`` name -> (G,) values (``stage`` label codes, ...); optional
        ``column_slack_mm`` (strips,) [mm] (a slack strip is drawn compressed between the grips).
    d_group : ndarray, shape [G]
        Yarn diameter of each group [mm].
    group_of_cell : ndarray of int, shape [bands, strips]
    course_count, wale_count : ndarray, shape [bands, strips]
        Stitches each block stands for.
    material_id_group : ndarray of int, shape [G], optional
    color_by, scene_text, metadata, field_units, curve_basis, frame_indices, frame_scalars
        As :func:`knitsim.usd.export.write_patch_usd`.
    time_codes_per_second : float
        Playback rate of the stage's time samples (one per exported increment), finite and > 0.
    column_values, docs, layer_info
        As :func:`knitsim.usd.export.write_patch_usd` (a column is a strip).

    Returns
    -------
    UsdExportResult
        With ``stitches`` and ``prototypes`` set.

    Raises
    ------
    KnitsimInputError
        Bad input, or a path that cannot be written (:func:`knitsim.usd.export.check_usd_path`).
    """
    from pxr import Gf, Sdf, UsdGeom, Vt

    from .export import (COLUMN_SLACK_DOC, CURVE_BASES, FIELD_PREFIX, SLACK_COLUMNS_NOTE, STAGE_LABELS,
                         UsdExportResult, _add_layer_info, _check_rate, _coloring, _column_values, _define_curve,
                         _new_stage, _save, _user_metadata, _vt_strings, _write_column_values, _write_frame_scalars,
                         check_usd_path)
    t_start = _time.perf_counter()
    path = check_usd_path(path)
    time_codes_per_second = _check_rate(time_codes_per_second)
    if curve_basis not in CURVE_BASES:
        raise KnitsimInputError(f"curve_basis={curve_basis!r} is not one of {CURVE_BASES}")
    if not frames:
        raise KnitsimInputError("frames is empty")
    goc = np.asarray(group_of_cell, dtype=np.int64)
    G = int(goc.max()) + 1
    n = int(frames[0]["quarter_xy"].shape[1])
    lattice = StitchLattice.of(course_count, wale_count)
    if lattice.n == 0:
        raise KnitsimInputError("the specimen draws no stitch (every block stands for less than half a stitch)")
    proto_of_stitch = goc[lattice.band, lattice.strip].astype(np.int32)
    d_group = np.asarray(d_group, dtype=float)
    # colours per group: the frame fields as (G, 1) "cells" for the shared colouring
    col_frames = [{"W": np.ones((G, 1)), "fields": {k: np.asarray(v)[:, None] for k, v in fr["fields"].items()}}
                  for fr in frames]
    mat = None if material_id_group is None else np.asarray(material_id_group, np.int32)[:, None]
    coloring = _coloring(color_by, col_frames, mat, None, field_units)
    time_codes = ([float(k) for k in range(len(frames))] if frame_indices is None
                  else [float(k) for k in frame_indices])
    if len(time_codes) != len(frames) or np.any(np.diff(time_codes) <= 0):
        raise KnitsimInputError(f"frame_indices must be {len(frames)} increasing integers, got {frame_indices!r}")

    scalars = {str(name): np.asarray(vals, float) for name, vals in (frame_scalars or {}).items()}
    for name, v in scalars.items():
        if v.shape != (len(frames),):
            raise KnitsimInputError(f"frame_scalars[{name!r}] must have one value per frame ({len(frames)})")

    strips = int(goc.shape[1])
    columns = _column_values(column_values, len(frames), strips)
    has_slack = [fr.get("column_slack_mm") is not None for fr in frames]
    if any(has_slack) and not all(has_slack):
        raise KnitsimInputError("frames: 'column_slack_mm' must be given in every frame or in none")
    slack = None
    if all(has_slack):
        slack = np.array([np.asarray(fr["column_slack_mm"], float) for fr in frames])
        if slack.shape != (len(frames), strips) or not np.all(np.isfinite(slack) & (slack >= 0)):
            raise KnitsimInputError(f"frames: 'column_slack_mm' must be {strips} finite lengths >= 0 per frame [mm]")
        columns = {"column_slack_mm": slack, **columns}
    docs = {**({"column_slack_mm": COLUMN_SLACK_DOC} if slack is not None else {}), **(docs or {})}

    stage, root = _new_stage(path, time_codes, time_codes_per_second)
    _write_frame_scalars(root, scalars, time_codes)
    _write_column_values(root, columns, time_codes, docs)
    for name in scalars:
        if name in docs:
            root.GetPrim().GetAttribute(FIELD_PREFIX + name).SetDocumentation(str(docs[name]))

    inst = UsdGeom.PointInstancer.Define(stage, INSTANCER_PATH)
    field_names = sorted(frames[0]["fields"])
    protos, field_pvs, color_pvs = [], [], []
    for g in range(G):
        c = _define_curve(stage, f"{PROTOTYPES_PATH}/{PROTOTYPE_FORMAT.format(g)}", curve_basis)
        c.CreateCurveVertexCountsAttr(Vt.IntArray([yg.vertices_per_cell(n) + 1]))
        c.CreateWidthsAttr(Vt.FloatArray([float(d_group[g])]))
        c.SetWidthsInterpolation(UsdGeom.Tokens.constant)
        pv_api = UsdGeom.PrimvarsAPI(c)
        color_pvs.append(c.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant))
        fpv = {}
        for name in field_names:
            is_int = np.issubdtype(np.asarray(frames[0]["fields"][name]).dtype, np.integer)
            fpv[name] = pv_api.CreatePrimvar(FIELD_PREFIX + name, Sdf.ValueTypeNames.Int if is_int
                                             else Sdf.ValueTypeNames.Float, UsdGeom.Tokens.constant)
            if name in docs:
                fpv[name].GetAttr().SetDocumentation(str(docs[name]))
        if mat is not None:
            pv_api.CreatePrimvar(FIELD_PREFIX + "material_id", Sdf.ValueTypeNames.Int,
                                 UsdGeom.Tokens.constant).Set(int(mat[g, 0]))
        protos.append(c)
        field_pvs.append(fpv)
    # defining the prototypes made their parent a def: make it an over again, so that a traversal (a renderer,
    # the quick-look) meets them only through the instancer
    stage.GetPrimAtPath(PROTOTYPES_PATH).SetSpecifier(Sdf.SpecifierOver)
    inst.CreatePrototypesRel().SetTargets([p.GetPath() for p in protos])
    inst.CreateProtoIndicesAttr(Vt.IntArray.FromNumpy(proto_of_stitch))
    ipv = UsdGeom.PrimvarsAPI(inst)
    for name, arr in (("band", lattice.band), ("strip", lattice.strip)):
        ipv.CreatePrimvar(FIELD_PREFIX + name, Sdf.ValueTypeNames.IntArray, UsdGeom.Tokens.vertex).Set(
            Vt.IntArray.FromNumpy(arr.astype(np.int32)))
    pos_attr = inst.CreatePositionsAttr()
    ext_attr = inst.CreateExtentAttr()
    palette = coloring.palette
    cc_rep = np.asarray(course_count, float)
    for f, (tc, fr, cf) in enumerate(zip(time_codes, frames, col_frames)):
        q = np.asarray(fr["quarter_xy"], float)
        Wg, Cg = np.asarray(fr["W"], float), np.asarray(fr["C"], float)
        pts = yg.stitch_points(q, Wg, d_group, fr.get("s_AB")).astype(np.float32)     # (G, m, 3)
        codes = np.asarray(coloring.code(cf)).reshape(-1)
        for g in range(G):
            protos[g].GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(pts[g]), tc)
            lo = pts[g].min(axis=0) - 0.5 * d_group[g]
            hi = pts[g].max(axis=0) + 0.5 * d_group[g]
            protos[g].GetExtentAttr().Set(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]), tc)
            color_pvs[g].Set(Vt.Vec3fArray([Gf.Vec3f(*map(float, palette[int(codes[g])]))]), tc)
            for name, pv in field_pvs[g].items():
                v = np.asarray(fr["fields"][name])[g]
                pv.Set(int(v) if np.issubdtype(np.asarray(v).dtype, np.integer) else float(v), tc)
        pos = lattice.positions(Wg[goc], Cg[goc])
        if slack is not None:
            # a slack strip between the grips: its stitches' y scaled (yarn_geometry, "Slack columns"),
            # its length stood for by the blocks' represented courses, drawn by the courses drawn
            scale = yg.slack_pitch_scale(Cg[goc], slack[f], drawn=lattice.courses_drawn, represented=cc_rep)
            pos[:, 1] *= scale[lattice.strip]
        pos_attr.Set(Vt.Vec3fArray.FromNumpy(pos.astype(np.float32)), tc)
        plo = pts.min(axis=1) - 0.5 * d_group[:, None]
        phi = pts.max(axis=1) + 0.5 * d_group[:, None]
        lo = (pos + plo[proto_of_stitch]).min(axis=0)
        hi = (pos + phi[proto_of_stitch]).max(axis=0)
        ext_attr.Set(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]), tc)

    from .. import __version__
    cc, wc = np.asarray(course_count, float), np.asarray(wale_count, float)
    info = {
        "generator": f"knitsim {__version__} (knitsim.usd.instanced)",
        "units": "mm, N, s, rad",
        "scene": scene_text or "",
        "color_by": color_by or "",
        "legend": coloring.legend,
        "stage_labels": _vt_strings(STAGE_LABELS),
        "layout": {"kind": LAYOUT_KIND, "bands": int(goc.shape[0]), "strips": int(goc.shape[1]),
                   "points_per_quarter": n, "vertices_per_stitch": yg.vertices_per_cell(n) + 1,
                   "prototypes": G, "stitches_drawn": lattice.n, "stitches_represented": float(np.sum(cc * wc)),
                   "instancer": INSTANCER_PATH, "prototypes_path": PROTOTYPES_PATH,
                   "prim_name_format": PROTOTYPE_FORMAT, "curve_basis": curve_basis,
                   "group_of_cell": Vt.IntArray([int(v) for v in goc.ravel()]),
                   "course_count": Vt.DoubleArray([float(v) for v in cc.ravel()]),
                   "wale_count": Vt.DoubleArray([float(v) for v in wc.ravel()]),
                   "courses_drawn": Vt.IntArray([int(v) for v in lattice.courses_drawn.ravel()]),
                   "wales_drawn": Vt.IntArray([int(v) for v in lattice.wales_drawn.ravel()]),
                   "drawing": "each block stands for course_count x wale_count stitches (row-major over bands x "
                              "strips); whole stitches drawn by cumulative rounding along each strip (courses) "
                              "and across each band (wales), each an instance of its group's stitch"},
        "frame_indices": Vt.IntArray([int(t) for t in time_codes]),
        "frame_scalars": {name: Vt.DoubleArray([float(x) for x in np.asarray(v, float)])
                          for name, v in (frame_scalars or {}).items()},
        "metadata": _user_metadata(metadata),
    }
    if slack is not None:
        info["drawing"] = {"slack_columns": SLACK_COLUMNS_NOTE + " (here a column is a strip of blocks)"}
    _add_layer_info(info, layer_info, {"time_samples": len(frames), "frames_passed": len(frames), "stride": 1})
    layer = stage.GetRootLayer()
    layer.customLayerData = {"knitsim": info}
    _save(stage, path)
    return UsdExportResult(path=path, time_codes=np.array(time_codes), courses=int(lattice.courses_drawn.sum(axis=0)
                                                                                     .max()),
                           wales=int(lattice.wales_drawn.sum(axis=1).max()), points_per_quarter=n,
                           vertices_per_course=0, file_bytes=os.path.getsize(path),
                           seconds=_time.perf_counter() - t_start, stitches=lattice.n, prototypes=G)


@dataclass
class SpecimenUsd:
    """An instanced specimen read back from USD (float32 values as float64 arrays).

    Attributes
    ----------
    time_codes : (T,)
    positions : (T, N, 3) A' point of every drawn stitch [mm]
    proto_indices : (N,) prototype (group) of every stitch
    band, strip : (N,) block of every stitch
    prototype_points : (T, G, m, 3) stitch curve of every prototype, A' at the origin [mm]
    widths : (G,) [mm]
    fields : name -> (T, G) per-prototype values (``stage`` is the label code)
    material_id : (G,) or None
    info : dict, ``customLayerData["knitsim"]``
    """

    time_codes: np.ndarray
    positions: np.ndarray
    proto_indices: np.ndarray
    band: np.ndarray
    strip: np.ndarray
    prototype_points: np.ndarray
    widths: np.ndarray
    fields: dict
    material_id: np.ndarray | None
    info: dict

    def stitch_points(self, k: int) -> np.ndarray:
        """Every drawn stitch's curve at time sample ``k`` [mm], shape (N, m, 3)."""
        return self.prototype_points[k][self.proto_indices] + self.positions[k][:, None, :]


def read_specimen_usd(path) -> SpecimenUsd:
    """Read a specimen written by :func:`write_specimen_usd`, at every time code."""
    from pxr import UsdGeom

    from .export import FIELD_PREFIX, open_knitsim_stage
    path = os.fspath(path)
    stage, info = open_knitsim_stage(path)
    lay = info.get("layout", {})
    if lay.get("kind") != LAYOUT_KIND:
        raise KnitsimInputError(f"path={path!r} is not an instanced specimen written by knitsim.usd")
    inst = UsdGeom.PointInstancer(stage.GetPrimAtPath(lay["instancer"]))
    targets = inst.GetPrototypesRel().GetTargets()
    protos = [UsdGeom.BasisCurves(stage.GetPrimAtPath(t)) for t in targets]
    tcs = np.array(inst.GetPositionsAttr().GetTimeSamples(), dtype=float)
    pos = np.array([np.asarray(inst.GetPositionsAttr().Get(t)) for t in tcs], dtype=float)
    pp = np.array([[np.asarray(p.GetPointsAttr().Get(t)) for p in protos] for t in tcs], dtype=float)
    widths = np.array([float(p.GetWidthsAttr().Get()[0]) for p in protos])
    ipv = UsdGeom.PrimvarsAPI(inst)
    band = np.asarray(ipv.GetPrimvar(FIELD_PREFIX + "band").Get(), dtype=np.int64)
    strip = np.asarray(ipv.GetPrimvar(FIELD_PREFIX + "strip").Get(), dtype=np.int64)
    fields, mat = {}, None
    for pv in UsdGeom.PrimvarsAPI(protos[0]).GetPrimvarsWithValues():
        name = pv.GetPrimvarName()
        if not name.startswith(FIELD_PREFIX):
            continue
        short = name[len(FIELD_PREFIX):]
        pvs = [UsdGeom.PrimvarsAPI(p).GetPrimvar(name) for p in protos]
        if short == "material_id":
            mat = np.array([p.Get() for p in pvs])
        else:
            fields[short] = np.array([[p.Get(t) for p in pvs] for t in tcs])
    return SpecimenUsd(tcs, pos, np.asarray(inst.GetProtoIndicesAttr().Get(), dtype=np.int64), band, strip, pp,
                       widths, fields, mat, info)


__all__ = ["write_specimen_usd", "read_specimen_usd", "SpecimenUsd", "StitchLattice", "drawn_counts",
           "INSTANCER_PATH", "PROTOTYPES_PATH", "LAYOUT_KIND"]
