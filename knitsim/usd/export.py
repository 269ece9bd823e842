"""USD export of simulated knit patches, for visual checks.

A patch (courses x wales quarter-stitch cells) becomes one
``UsdGeom.BasisCurves`` prim per course, ``/Patch/Yarns/course_0000``, ...,
each holding one continuous yarn (geometry in :mod:`knitsim.usd.yarn_geometry`).
Saved simulation frames become time samples; the time code of a frame is its
index in the input sequence (with ``stride`` s: 0, s, 2s, ..., and always the
last frame).

What is written
---------------
Stage metadata: ``metersPerUnit = 0.001`` (mm), ``upAxis = Z`` (the knit lies
in the x-y plane, x along the course, y along the wale), start/end time codes,
``defaultPrim = /Patch``.  ``customLayerData["knitsim"]`` holds the scene text,
the colour legend, the vertex layout, the frame indices (= the time codes) and
times, ``timeline`` (``time_samples`` written, ``frames_passed`` to the writer,
its ``stride``, and what a caller adds: what a time code is), the caller's
``layer_info`` and metadata.

Per course prim (a ``BasisCurves`` with one curve):

- ``points`` (point3f[], per vertex, sampled per frame): centreline [mm];
- ``extent`` (sampled per frame): points +- d/2, as UsdGeom computes it;
- ``widths`` (per vertex, static): yarn diameter d [mm];
- ``primvars:displayColor`` (per vertex, indexed): a static palette, indices
  sampled per frame; the legend in customLayerData says what the colours mean;
- ``primvars:knitsim:<field>`` (uniform, elementSize = wales, sampled per
  frame): one value per cell, element j = wale j; ``stage`` is int
  (0 adherence, 1 sliding, 2 jamming, 3 slack);
- ``primvars:knitsim:material_id`` (same layout, static).

Per wale column, on ``/Patch`` (where the frames carry them): ``knitsim:column_slack_mm``
(float[], one per column, sampled per frame): the length by which the column's
cells, stacked at their course lengths, exceed the grip span [mm]; such a slack
column is drawn compressed between the grips, its stitches overlapping
(:mod:`knitsim.usd.yarn_geometry`, "Slack columns"); other per-column values
(``column_values``) likewise.

The file is checked to be writable before any work (:func:`check_usd_path`); a
file that cannot be written raises :class:`~knitsim.errors.KnitsimInputError`
naming the path, never a raw ``pxr`` error.

Per-cell fields are stored once per cell, not per vertex: a 10^5-cell patch
has a few million vertices.  ``displayColor`` is an *indexed* primvar (a static
palette and one int per vertex per frame) for the same reason.

The input ``stage`` field holds the label codes of
``knitsim.cell.stages.LABEL_CODES`` (0 adherence, 1 sliding, 2 jamming,
3 slack; ``stage_label(stage, jammed)`` gives them from a Stage code and the
jammed flag).  Other integer fields (a raw Stage code, the jammed flag) are
written like any field.
"""
from __future__ import annotations

import os
import time as _time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field as _field

import numpy as np

from ..cell.stages import LABEL_CODES
from ..errors import KnitsimInputError
from . import yarn_geometry as yg

#: stage labels in the order of their codes (knitsim.cell.stages.LABEL_CODES)
STAGE_LABELS: tuple[str, ...] = tuple(sorted(LABEL_CODES, key=LABEL_CODES.get))
_STAGE_HEX = {"adherence": "#1f77b4", "sliding": "#ff7f0e", "jamming": "#d62728", "slack": "#9a9a9a"}
STAGE_COLORS_HEX: tuple[str, ...] = tuple(_STAGE_HEX[s] for s in STAGE_LABELS)

#: categorical palette for material ids (matplotlib's tab10, by rank of the id)
_MATERIAL_HEX = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                 "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf")
CONTINUOUS_COLORMAP = "viridis"
CONTINUOUS_BINS = 256
MISSING_COLOR_HEX = "#ff00ff"  # NaN in a continuous field: loud on purpose

CURVE_BASES = ("catmullRom", "bspline", "linear")
ROOT_PATH = "/Patch"
YARNS_PATH = "/Patch/Yarns"
COURSE_PRIM_FORMAT = "course_{:04d}"
FIELD_PREFIX = "knitsim:"


def _hex_to_rgb(h: str) -> tuple[float, float, float]:
    h = h.lstrip("#")
    return tuple(int(h[i:i + 2], 16) / 255.0 for i in (0, 2, 4))


def _rgb_to_hex(c) -> str:
    return "#" + "".join(f"{int(round(255 * float(v))):02x}" for v in c[:3])


@dataclass
class UsdExportResult:
    """What :func:`write_patch_usd` wrote."""

    path: str
    time_codes: np.ndarray
    courses: int
    wales: int
    points_per_quarter: int
    vertices_per_course: int
    file_bytes: int
    seconds: float
    #: an instanced specimen (knitsim.usd.instanced): stitches drawn and their distinct shapes (0: a patch)
    stitches: int = 0
    prototypes: int = 0


# --------------------------------------------------------------------------- input

def _normalise_frames(frames) -> list[Mapping]:
    """A sequence of per-frame mappings; a mapping of stacked arrays is split."""
    if isinstance(frames, Mapping):
        if "quarter_xy" not in frames:
            raise KnitsimInputError("frames has no 'quarter_xy'")
        q = np.asarray(frames["quarter_xy"])
        if q.ndim != 5:
            raise KnitsimInputError(
                f"frames['quarter_xy'] stacked over frames must have shape (frames, courses, wales, n, 2), got {q.shape}")
        nf = q.shape[0]
        out = []
        for k in range(nf):
            fr = {key: (np.asarray(v)[k] if key != "fields" else {n: np.asarray(a)[k] for n, a in v.items()})
                  for key, v in frames.items() if key != "time"}
            if frames.get("time") is not None:
                fr["time"] = float(np.asarray(frames["time"])[k])
            out.append(fr)
        return out
    if isinstance(frames, (str, bytes)) or not isinstance(frames, Sequence):
        raise KnitsimInputError(f"frames must be a sequence of per-frame mappings or a mapping of stacked arrays, "
                                f"got {type(frames).__name__}")
    if len(frames) == 0:
        raise KnitsimInputError("frames is empty")
    for k, fr in enumerate(frames):
        if not isinstance(fr, Mapping):
            raise KnitsimInputError(f"frames[{k}] must be a mapping, got {type(fr).__name__}")
    return list(frames)


def _check_frame(k: int, fr: Mapping, shape: tuple | None):
    """Validated float arrays of one frame; ``shape`` = (courses, wales, n) of frame 0."""
    for key in ("quarter_xy", "W", "C"):
        if key not in fr:
            raise KnitsimInputError(f"frames[{k}] has no '{key}'")
    q = np.asarray(fr["quarter_xy"], dtype=float)
    if q.ndim != 4 or q.shape[-1] != 2 or q.shape[2] < 2:
        raise KnitsimInputError(
            f"frames[{k}]['quarter_xy'] must have shape (courses, wales, n >= 2, 2), got {q.shape}")
    if shape is not None and q.shape[:3] != shape:
        raise KnitsimInputError(
            f"frames[{k}]['quarter_xy'] has shape {q.shape}, frame 0 has {shape + (2,)}")
    cw = q.shape[:2]
    out = {"quarter_xy": q}
    for key in ("W", "C", "s_AB"):
        if key not in fr or fr[key] is None:
            continue
        a = np.asarray(fr[key], dtype=float)
        if a.shape != cw:
            raise KnitsimInputError(f"frames[{k}]['{key}'] must have shape {cw}, got {a.shape}")
        if not np.all(np.isfinite(a) & (a > 0)):
            i = tuple(int(b) for b in np.argwhere(~(np.isfinite(a) & (a > 0)))[0])
            raise KnitsimInputError(f"frames[{k}]['{key}'] must be finite and > 0, got {a[i]} at cell {i}")
        out[key] = a
    yg.check_quarters(q, out["W"], field=f"frames[{k}]['quarter_xy']")
    fields = fr.get("fields") or {}
    if not isinstance(fields, Mapping):
        raise KnitsimInputError(f"frames[{k}]['fields'] must be a mapping name -> (courses, wales) array")
    out_fields = {}
    for name, a in fields.items():
        a = np.asarray(a)
        if a.shape != cw:
            raise KnitsimInputError(f"frames[{k}]['fields']['{name}'] must have shape {cw}, got {a.shape}")
        if name == "stage":
            ok = np.isfinite(a) & (a == np.round(a)) & (a >= 0) & (a < len(STAGE_LABELS))
            if not np.all(ok):
                i = tuple(int(b) for b in np.argwhere(~ok)[0])
                raise KnitsimInputError(
                    f"frames[{k}]['fields']['stage'] = {a[i]} at cell {i} is not a stage label code "
                    f"(0..{len(STAGE_LABELS) - 1}: {', '.join(STAGE_LABELS)})")
            a = a.astype(np.int32)
        elif not np.issubdtype(a.dtype, np.number):
            raise KnitsimInputError(f"frames[{k}]['fields']['{name}'] must be numeric, got dtype {a.dtype}")
        out_fields[str(name)] = a
    out["fields"] = out_fields
    if fr.get("time") is not None:
        out["time"] = float(fr["time"])
    if fr.get("column_slack_mm") is not None:
        sl = np.asarray(fr["column_slack_mm"], dtype=float)
        if sl.shape != cw[1:] or not np.all(np.isfinite(sl) & (sl >= 0)):
            raise KnitsimInputError(f"frames[{k}]['column_slack_mm'] must be {cw[1]} finite lengths >= 0 (one per "
                                    f"wale column) [mm], got {fr['column_slack_mm']!r}")
        out["column_slack_mm"] = sl
    return out


def _selected(n_frames: int, stride) -> list[int]:
    if isinstance(stride, bool) or not isinstance(stride, (int, np.integer)) or stride < 1:
        raise KnitsimInputError(f"stride must be an integer >= 1, got {stride!r}")
    from ..arrays import stride_select
    # frames 0, stride, 2 stride, ... and the last: the rule of every strided output (knitsim.arrays)
    return [int(i) for i in stride_select(np.arange(n_frames), stride)]


# --------------------------------------------------------------------------- colours

@dataclass
class _Coloring:
    palette: np.ndarray                  # (k, 3) float
    legend: dict
    code: callable = _field(repr=False)  # per-frame fields -> (courses, wales) palette index


def _coloring(color_by, frames: list[dict], material_id, color_range, field_units) -> _Coloring:
    names = set(frames[0]["fields"])
    if material_id is not None:
        names.add("material_id")
    if color_by is None:
        pal = np.array([_hex_to_rgb("#b0b0b0")])
        legend = {"kind": "uniform", "field": "", "colors_hex": _vt_strings(["#b0b0b0"])}
        return _Coloring(pal, legend, lambda fr: np.zeros(frames[0]["W"].shape, np.int32))
    if color_by not in names:
        raise KnitsimInputError(
            f"color_by={color_by!r} is not a field of the frames; available: {sorted(names) or 'none'}")
    from pxr import Vt
    if color_by == "stage":
        pal = np.array([_hex_to_rgb(h) for h in STAGE_COLORS_HEX])
        legend = {"kind": "categorical", "field": "stage", "labels": _vt_strings(STAGE_LABELS),
                  "codes": Vt.IntArray(list(range(len(STAGE_LABELS)))), "colors_hex": _vt_strings(STAGE_COLORS_HEX)}
        return _Coloring(pal, legend, lambda fr: fr["fields"]["stage"])
    if color_by == "material_id":
        ids = np.unique(material_id)
        hexes = [_MATERIAL_HEX[r % len(_MATERIAL_HEX)] for r in range(len(ids))]
        rank = np.searchsorted(ids, material_id).astype(np.int32)
        legend = {"kind": "categorical", "field": "material_id", "labels": _vt_strings([str(i) for i in ids]),
                  "codes": Vt.IntArray([int(i) for i in ids]), "colors_hex": _vt_strings(hexes)}
        return _Coloring(np.array([_hex_to_rgb(h) for h in hexes]), legend, lambda fr: rank)
    # continuous field: fixed range over all written frames, so colours compare across time
    if color_range is None:
        vals = np.concatenate([np.asarray(fr["fields"][color_by], float).ravel() for fr in frames])
        vals = vals[np.isfinite(vals)]
        vmin, vmax = (float(vals.min()), float(vals.max())) if vals.size else (0.0, 1.0)
    else:
        vmin, vmax = (float(v) for v in color_range)
        if not (np.isfinite(vmin) and np.isfinite(vmax) and vmax >= vmin):
            raise KnitsimInputError(f"color_range must be finite (vmin, vmax) with vmax >= vmin, got {color_range!r}")
    if vmax <= vmin:
        vmax = vmin + max(abs(vmin), 1.0) * 1e-9
    import matplotlib
    cmap = matplotlib.colormaps[CONTINUOUS_COLORMAP]
    pal = np.vstack([cmap(np.linspace(0.0, 1.0, CONTINUOUS_BINS))[:, :3], [_hex_to_rgb(MISSING_COLOR_HEX)]])

    def code(fr):
        v = np.asarray(fr["fields"][color_by], float)
        t = np.clip((v - vmin) / (vmax - vmin), 0.0, 1.0)
        out = np.minimum((np.nan_to_num(t) * CONTINUOUS_BINS).astype(np.int32), CONTINUOUS_BINS - 1)
        out[~np.isfinite(v)] = CONTINUOUS_BINS
        return out

    legend = {"kind": "continuous", "field": color_by, "colormap": CONTINUOUS_COLORMAP, "vmin": vmin, "vmax": vmax,
              "bins": CONTINUOUS_BINS, "missing_color_hex": MISSING_COLOR_HEX,
              "units": str((field_units or {}).get(color_by, ""))}
    return _Coloring(pal, legend, code)


def _vt_strings(seq):
    from pxr import Vt
    return Vt.StringArray([str(s) for s in seq])


def _user_metadata(metadata) -> dict:
    """Caller's metadata as a dictionary USD can store (:func:`_layer_value`: scalars, strings, lists as
    arrays, mappings recursively; anything else as its str())."""
    if metadata is None:
        return {}
    if not isinstance(metadata, Mapping):
        raise KnitsimInputError(f"metadata must be a mapping, got {type(metadata).__name__}")
    return _layer_value(metadata)


def _layer_value(v):
    """``v`` as a value a USD dictionary holds: mappings recursively, scalars, strings, and lists of
    strings / ints / floats as Vt arrays; None where USD has no value for it (the key is left out)."""
    from pxr import Vt
    if isinstance(v, Mapping):
        out = {}
        for k, x in v.items():
            x = _layer_value(x)
            if x is not None:
                out[str(k)] = x
        return out
    if v is None:
        return None
    if isinstance(v, (Vt.IntArray, Vt.DoubleArray, Vt.StringArray)):
        return v                          # converted already (the timeline passes through here twice)
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v)
    if isinstance(v, str):
        return v
    if isinstance(v, (list, tuple, np.ndarray)):
        a = list(np.asarray(v).ravel()) if isinstance(v, np.ndarray) else list(v)
        if all(isinstance(x, (bool, np.bool_, int, np.integer)) for x in a) and a:
            return Vt.IntArray([int(x) for x in a])
        if all(isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))
               for x in a) and a:
            return Vt.DoubleArray([float(x) for x in a])
        return _vt_strings(a)
    return str(v)


#: what ``knitsim:column_slack_mm`` is (its attribute's documentation)
COLUMN_SLACK_DOC = ("length [mm] by which the wale column's cells, stacked at their own course lengths, exceed the "
                    "grip span: the column is slack (no force) and drawn compressed between the grips")
#: what a file with slack columns says of them (customLayerData["knitsim"]["drawing"]["slack_columns"])
SLACK_COLUMNS_NOTE = (
    "slack columns are drawn compressed: a column whose cells, stacked at their own course lengths, are longer "
    "than the grip span by knitsim:column_slack_mm (the run does not say where that length goes) has its course "
    "pitch scaled so that its drawn length (last course origin + its course length) is the grip span; each stitch "
    "keeps its own shape, so the stitches overlap (the knit piles up between the grips); loaded columns "
    "(column_slack_mm = 0) are drawn at their cells' course lengths")


def _column_values(values: Mapping | None, n_frames: int, columns: int) -> dict:
    """``values`` (name -> (frames, columns) array) validated, as arrays."""
    out = {}
    for name, v in (values or {}).items():
        a = np.asarray(v)
        if a.shape != (n_frames, columns) or not (np.issubdtype(a.dtype, np.number) or a.dtype == bool):
            raise KnitsimInputError(f"column_values[{name!r}] must be numbers of shape {(n_frames, columns)} (frames, "
                                    f"columns), got {a.dtype} {a.shape}")
        out[str(name)] = a
    return out


def _add_layer_info(info: dict, layer_info: Mapping | None, timeline: dict) -> None:
    """``info["timeline"]`` (the writer's ``timeline`` updated by ``layer_info["timeline"]``) and the other keys
    of ``layer_info``; ``drawing`` notes are merged with the writer's own."""
    extra = _layer_value(dict(layer_info or {}))
    timeline.update(extra.pop("timeline", {}) or {})
    info["timeline"] = _layer_value(timeline)
    drawing = {**info.get("drawing", {}), **(extra.pop("drawing", {}) or {})}
    if drawing:
        info["drawing"] = drawing
    info.update(extra)


# --------------------------------------------------------------------------- writer

USD_EXTENSIONS = (".usda", ".usdc", ".usd")


def check_usd_path(path, flag: str | None = None) -> str:
    """Check, before any work, that a USD file can be written at ``path``; returns it as a str.

    The extension must be ``.usda``, ``.usdc`` or ``.usd``; ``path`` must not be a folder; its
    nearest existing parent must be a folder (the missing ones are created when the file is
    written), and a file must be creatable in it: a probe file is created there and removed (the
    permission bits do not tell: root passes ``os.access`` in ``/proc``, where nothing can be
    created).  An existing file at ``path`` is not touched.

    Parameters
    ----------
    path : str or os.PathLike
    flag : str, optional
        The command-line option that gave the path (``"--usd"``); messages then read
        ``--usd = 'x.usda': ...``, else ``path='x.usda': ...``.

    Raises
    ------
    KnitsimInputError
        One line naming the path and why it cannot be written.
    """
    from ..io.output_dir import check_file_can_be_created

    p = os.fspath(path)
    where = f"{flag} = {p!r}" if flag else f"path={p!r}"
    if os.path.splitext(p)[1].lower() not in USD_EXTENSIONS:
        raise KnitsimInputError(f"{where}: must end in .usda, .usdc or .usd")
    if os.path.isdir(p):
        raise KnitsimInputError(f"{where}: is a folder")
    check_file_can_be_created(p, where)
    return p


def _check_rate(time_codes_per_second) -> float:
    """The playback rate, a finite number > 0 (USD stores it; 0, a negative or a NaN rate plays nothing)."""
    ok = (not isinstance(time_codes_per_second, (bool, np.bool_))
          and isinstance(time_codes_per_second, (int, float, np.integer, np.floating))
          and np.isfinite(time_codes_per_second) and time_codes_per_second > 0)
    if not ok:
        raise KnitsimInputError(f"time_codes_per_second={time_codes_per_second!r}: must be a finite number > 0")
    return float(time_codes_per_second)


def _usd_write_error(path: str, exc) -> KnitsimInputError:
    """A failed write (a ``pxr`` error, an OSError) as knitsim's error, naming the path: one line."""
    msg = " ".join(str(exc).split())
    # pxr's message starts with the C++ function and source line: keep the reason it quotes
    if "'" in msg and "Error in" in msg:
        parts = msg.split(" : ", 1)
        msg = parts[1] if len(parts) == 2 else msg
    return KnitsimInputError(f"path={path!r}: the USD file cannot be written ({msg[:300]})")


def _new_stage(path: str, time_codes, time_codes_per_second: float):
    """A new stage at ``path`` (replacing a file there), in mm with z up, spanning ``time_codes``; returns
    ``(stage, root Xform)``, the root the default prim."""
    from pxr import Tf, Usd, UsdGeom
    try:
        if os.path.exists(path):
            os.remove(path)  # CreateNew refuses an existing layer
        stage = Usd.Stage.CreateNew(path)
    except (Tf.ErrorException, OSError) as exc:
        raise _usd_write_error(path, exc) from None
    UsdGeom.SetStageMetersPerUnit(stage, 0.001)   # lengths in mm
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    stage.SetStartTimeCode(time_codes[0])
    stage.SetEndTimeCode(time_codes[-1])
    stage.SetTimeCodesPerSecond(float(time_codes_per_second))
    root = UsdGeom.Xform.Define(stage, ROOT_PATH)
    stage.SetDefaultPrim(root.GetPrim())
    return stage, root


def _write_frame_scalars(root, scalars: Mapping, time_codes) -> None:
    """One time-sampled double attribute ``knitsim:<name>`` on ``root`` per scalar (one value per time code)."""
    from pxr import Sdf
    for name, v in scalars.items():
        sa = root.GetPrim().CreateAttribute(FIELD_PREFIX + name, Sdf.ValueTypeNames.Double)
        for tc, val in zip(time_codes, v):
            sa.Set(float(val), tc)


def _write_column_values(root, values: Mapping, time_codes, docs: Mapping | None = None) -> None:
    """One time-sampled array attribute ``knitsim:<name>`` on ``root`` per per-column value (one array of
    one value per wale column per time code: float[], or int[] for integer values)."""
    from pxr import Sdf, Vt
    for name, v in values.items():
        a = np.asarray(v)
        is_int = np.issubdtype(a.dtype, np.integer) or a.dtype == bool
        attr = root.GetPrim().CreateAttribute(FIELD_PREFIX + name, Sdf.ValueTypeNames.IntArray if is_int
                                              else Sdf.ValueTypeNames.FloatArray)
        if docs and name in docs:
            attr.SetDocumentation(str(docs[name]))
        for tc, row in zip(time_codes, a):
            attr.Set(Vt.IntArray.FromNumpy(np.asarray(row, np.int32)) if is_int
                     else Vt.FloatArray.FromNumpy(np.asarray(row, np.float32)), tc)


def _save(stage, path: str) -> None:
    """Save the stage's root layer; a failure as knitsim's error naming the path."""
    from pxr import Tf
    try:
        ok = stage.GetRootLayer().Save()
    except (Tf.ErrorException, OSError) as exc:
        raise _usd_write_error(path, exc) from None
    if not ok:
        raise KnitsimInputError(f"path={path!r}: the USD file cannot be written (the layer did not save)")


def _define_curve(stage, path: str, curve_basis: str):
    """A BasisCurves prim at ``path``: linear, or cubic of ``curve_basis`` pinned at its ends."""
    from pxr import UsdGeom
    c = UsdGeom.BasisCurves.Define(stage, path)
    if curve_basis == "linear":
        c.CreateTypeAttr(UsdGeom.Tokens.linear)
    else:
        c.CreateTypeAttr(UsdGeom.Tokens.cubic)
        c.CreateBasisAttr(getattr(UsdGeom.Tokens, curve_basis))
        c.CreateWrapAttr(UsdGeom.Tokens.pinned)
    return c


def write_patch_usd(path, frames, d, *, material_id=None, color_by: str | None = "stage", stride: int = 1,
                    scene_text: str | None = None, metadata: Mapping | None = None,
                    color_range: tuple[float, float] | None = None, field_units: Mapping[str, str] | None = None,
                    curve_basis: str = "catmullRom", points_per_quarter: int | None = None,
                    time_codes_per_second: float = 24.0, frame_indices=None,
                    frame_scalars: Mapping | None = None, column_values: Mapping | None = None,
                    docs: Mapping[str, str] | None = None, layer_info: Mapping | None = None) -> UsdExportResult:
    """Write a knit patch over time as a USD stage.

    Parameters
    ----------
    path : str or os.PathLike
        ``.usda`` writes text, ``.usdc`` and ``.usd`` write the binary crate
        format (use it for large patches).
    frames : sequence of mappings, or a mapping of arrays stacked over frames
        Each frame: ``quarter_xy`` (courses, wales, n, 2) quarter centrelines in
        the cell frame [mm] (A = (W/4, 0) first, apex on X = 0 last); ``W``,
        ``C`` (courses, wales) [mm]; optional ``s_AB`` (courses, wales) [mm]
        (places the out-of-plane crossing, see :mod:`~knitsim.usd.yarn_geometry`);
        optional ``time`` [s]; optional ``fields``: name -> (courses, wales)
        array, e.g. ``stage`` (Stage codes), ``phi`` [rad], ``F`` [N per wale];
        optional ``column_slack_mm`` (wales,) [mm]: the length by which each wale
        column's cells, stacked, exceed the grip span (a slack column: drawn
        compressed between the grips, :func:`~knitsim.usd.yarn_geometry.slack_pitch_scale`;
        written as ``knitsim:column_slack_mm`` of ``/Patch``), in every frame or none.
        Shapes must not change between frames.
    d : float or array (courses, wales)
        Yarn diameter [mm]: curve widths and the out-of-plane offset.
    material_id : int or int array (courses, wales), optional
        Material of each cell (static).
    color_by : str or None
        Field that sets ``displayColor``: ``"stage"``, ``"material_id"`` or any
        field name (continuous: viridis over ``color_range``); None: grey.
    stride : int
        Write frames 0, stride, 2 stride, ... and the last one.
    scene_text : str, optional
        The scene file's text, embedded verbatim in ``customLayerData``.
    metadata : mapping, optional
        Extra key/values for ``customLayerData["knitsim"]["metadata"]``.
    color_range : (float, float), optional
        Range of a continuous colour field; default min/max over written frames.
    field_units : mapping, optional
        Units of fields, recorded in the legend (e.g. ``{"F": "N"}``).
    curve_basis : {"catmullRom", "bspline", "linear"}
        ``catmullRom`` (cubic, pinned: passes through every vertex), ``bspline``
        (cubic, pinned, smoothing) or ``linear``.
    points_per_quarter : int, optional
        Resample every quarter to this many points (uniform in chord length,
        A and the apex kept) to keep large files small; default: as given.
        6 to 9 look smooth with the Catmull-Rom basis.
    time_codes_per_second : float
        Playback rate of the frame index, finite and > 0.
    frame_indices : sequence of int, optional
        Time code of each input frame (increasing), when the frames are a
        selection of a longer run (e.g. increment numbers); default 0, 1, ...
    frame_scalars : mapping, optional
        name -> one number per input frame (e.g. ``grip_strain``), written as
        the time-sampled double attribute ``knitsim:<name>`` of ``/Patch`` and
        listed in ``customLayerData["knitsim"]["frame_scalars"]``.
    column_values : mapping, optional
        name -> array (frames, wales): one value per wale column per input
        frame (e.g. ``column_held``), written as the time-sampled array
        attribute ``knitsim:<name>`` of ``/Patch`` (int[] for integers, else float[]).
    docs : mapping, optional
        name -> text: the documentation of the field primvar, frame scalar or
        per-column attribute of that name (what it is, its units).
    layer_info : mapping, optional
        Keys added to ``customLayerData["knitsim"]`` (strings, numbers, lists,
        mappings); a ``timeline`` mapping is merged into the writer's own.

    Returns
    -------
    UsdExportResult

    Raises
    ------
    KnitsimInputError
        Bad input, or a path that cannot be written (checked first, :func:`check_usd_path`;
        a failure while writing names the path too).
    """
    from pxr import Gf, Sdf, UsdGeom, Vt

    t_start = _time.perf_counter()
    path = check_usd_path(path)
    time_codes_per_second = _check_rate(time_codes_per_second)
    if curve_basis not in CURVE_BASES:
        raise KnitsimInputError(f"curve_basis={curve_basis!r} is not one of {CURVE_BASES}")
    raw = _normalise_frames(frames)
    sel = _selected(len(raw), stride)
    if points_per_quarter is not None and (isinstance(points_per_quarter, bool) or not isinstance(
            points_per_quarter, (int, np.integer)) or points_per_quarter < 2):
        raise KnitsimInputError(f"points_per_quarter must be an integer >= 2, got {points_per_quarter!r}")
    checked, shape = [], None
    for k in sel:
        fr = _check_frame(k, raw[k], shape)
        shape = fr["quarter_xy"].shape[:3]
        if points_per_quarter is not None:
            fr["quarter_xy"] = yg.resample_quarters(fr["quarter_xy"], points_per_quarter)
        if checked and set(fr["fields"]) != set(checked[0]["fields"]):
            raise KnitsimInputError(
                f"frames[{k}]['fields'] has {sorted(fr['fields'])}, frame {sel[0]} has {sorted(checked[0]['fields'])}")
        if checked and ("column_slack_mm" in fr) != ("column_slack_mm" in checked[0]):
            raise KnitsimInputError(f"frames[{k}]: 'column_slack_mm' must be given in every frame or in none")
        checked.append(fr)
    courses, wales, n = checked[0]["quarter_xy"].shape[:3]
    if courses < 1 or wales < 1:
        raise KnitsimInputError(f"frames['quarter_xy'] has no cells: shape {shape}")
    dd = np.asarray(d, dtype=float)
    if dd.shape not in ((), (courses, wales)) or not np.all(np.isfinite(dd) & (dd > 0)):
        raise KnitsimInputError(f"d must be > 0, a scalar or shape {(courses, wales)}, got {d!r}")
    dd = np.broadcast_to(dd, (courses, wales))
    mat = None
    if material_id is not None:
        m = np.asarray(material_id)
        if m.shape not in ((), (courses, wales)) or not np.issubdtype(m.dtype, np.integer):
            raise KnitsimInputError(
                f"material_id must be an int or an int array of shape {(courses, wales)}, got {material_id!r}")
        mat = np.broadcast_to(m, (courses, wales)).astype(np.int32)
    coloring = _coloring(color_by, checked, mat, color_range, field_units)

    m_verts = yg.course_vertex_count(n, wales)
    vcell = yg.vertex_cells(n, wales)
    if frame_indices is None:
        time_codes = [float(k) for k in sel]
    else:
        fi = np.asarray(frame_indices)
        if fi.shape != (len(raw),) or not np.issubdtype(fi.dtype, np.integer) or np.any(np.diff(fi) <= 0):
            raise KnitsimInputError(f"frame_indices must be {len(raw)} increasing integers, got {frame_indices!r}")
        time_codes = [float(fi[k]) for k in sel]
    scalars = {}
    for name, vals in (frame_scalars or {}).items():
        v = np.asarray(vals, dtype=float)
        if v.shape != (len(raw),):
            raise KnitsimInputError(f"frame_scalars[{name!r}] must have one value per frame ({len(raw)}), "
                                    f"got shape {v.shape}")
        scalars[str(name)] = v[sel]
    columns = _column_values(column_values, len(raw), wales)
    columns = {name: v[sel] for name, v in columns.items()}
    slack = None
    if "column_slack_mm" in checked[0]:
        slack = np.array([fr["column_slack_mm"] for fr in checked])
        columns = {"column_slack_mm": slack, **columns}

    stage, root = _new_stage(path, time_codes, time_codes_per_second)
    UsdGeom.Scope.Define(stage, YARNS_PATH)
    times = [fr.get("time") for fr in checked]
    if all(t is not None for t in times):
        ta = root.GetPrim().CreateAttribute("knitsim:time_s", Sdf.ValueTypeNames.Double)
        for tc, t in zip(time_codes, times):
            ta.Set(t, tc)

    _write_frame_scalars(root, scalars, time_codes)
    docs = {**({"column_slack_mm": COLUMN_SLACK_DOC} if slack is not None else {}), **(docs or {})}
    _write_column_values(root, columns, time_codes, docs)
    for name in scalars:
        if name in docs:
            root.GetPrim().GetAttribute(FIELD_PREFIX + name).SetDocumentation(str(docs[name]))

    palette = Vt.Vec3fArray.FromNumpy(coloring.palette.astype(np.float32))
    field_names = sorted(checked[0]["fields"])
    curves, field_pvs, color_pvs, stage_pvs = [], [], [], []
    for i in range(courses):
        c = _define_curve(stage, f"{YARNS_PATH}/{COURSE_PRIM_FORMAT.format(i)}", curve_basis)
        c.CreateCurveVertexCountsAttr(Vt.IntArray([m_verts]))
        c.CreateWidthsAttr(Vt.FloatArray.FromNumpy(dd[i, vcell].astype(np.float32)))
        c.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
        c.GetPrim().SetCustomDataByKey("knitsim:course", i)
        pv_api = UsdGeom.PrimvarsAPI(c)
        col = c.CreateDisplayColorPrimvar(UsdGeom.Tokens.vertex)
        col.Set(palette)
        fpv = {}
        for name in field_names:
            is_int = np.issubdtype(checked[0]["fields"][name].dtype, np.integer)
            fpv[name] = pv_api.CreatePrimvar(FIELD_PREFIX + name, Sdf.ValueTypeNames.IntArray if is_int
                                             else Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.uniform, wales)
            if name in docs:
                fpv[name].GetAttr().SetDocumentation(str(docs[name]))
        if mat is not None:
            pv_api.CreatePrimvar(FIELD_PREFIX + "material_id", Sdf.ValueTypeNames.IntArray,
                                 UsdGeom.Tokens.uniform, wales).Set(Vt.IntArray.FromNumpy(mat[i]))
        curves.append(c)
        field_pvs.append(fpv)
        color_pvs.append(col)

    half_w = 0.5 * dd.max(axis=1)
    for f, (tc, fr) in enumerate(zip(time_codes, checked)):
        # a slack column is drawn between the grips (yarn_geometry, "Slack columns"); 1 where loaded
        scale = None if slack is None else yg.slack_pitch_scale(fr["C"], slack[f])
        pts = yg.patch_points(fr["quarter_xy"], fr["W"], fr["C"], dd, fr.get("s_AB"),
                              pitch_scale=scale).astype(np.float32)
        ci = coloring.code(fr)                                  # (courses, wales)
        vi = ci[:, vcell].astype(np.int32)                      # (courses, m)
        lo = pts.min(axis=1) - half_w[:, None]
        hi = pts.max(axis=1) + half_w[:, None]
        flds = fr["fields"]
        for i in range(courses):
            c = curves[i]
            c.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(pts[i]), tc)
            c.GetExtentAttr().Set(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo[i])), Gf.Vec3f(*map(float, hi[i]))]), tc)
            color_pvs[i].SetIndices(Vt.IntArray.FromNumpy(vi[i]), tc)
            for name, pv in field_pvs[i].items():
                a = flds[name][i]
                if np.issubdtype(a.dtype, np.integer):
                    pv.Set(Vt.IntArray.FromNumpy(a.astype(np.int32)), tc)
                else:
                    pv.Set(Vt.FloatArray.FromNumpy(a.astype(np.float32)), tc)

    from .. import __version__
    info = {
        "generator": f"knitsim {__version__} (knitsim.usd.export)",
        "units": "mm, N, s, rad",
        "scene": scene_text if scene_text is not None else "",
        "color_by": color_by or "",
        "legend": coloring.legend,
        "stage_labels": _vt_strings(STAGE_LABELS),
        "layout": {"courses": courses, "wales": wales, "points_per_quarter": n,
                   "vertices_per_cell": yg.vertices_per_cell(n), "vertices_per_course": m_verts,
                   "curve_basis": curve_basis, "yarns": YARNS_PATH,
                   "prim_name_format": COURSE_PRIM_FORMAT},
        "frame_indices": Vt.IntArray([int(t) for t in time_codes]),
        "frame_scalars": {name: Vt.DoubleArray([float(x) for x in v]) for name, v in scalars.items()},
        "metadata": _user_metadata(metadata),
    }
    if slack is not None:
        info["drawing"] = {"slack_columns": SLACK_COLUMNS_NOTE}
    _add_layer_info(info, layer_info, {"time_samples": len(sel), "frames_passed": len(raw), "stride": int(stride)})
    if all(t is not None for t in times):
        info["time_s"] = Vt.DoubleArray(times)
    layer = stage.GetRootLayer()
    layer.customLayerData = {"knitsim": info}
    _save(stage, path)
    return UsdExportResult(path=path, time_codes=np.array(time_codes), courses=courses, wales=wales,
                           points_per_quarter=n, vertices_per_course=m_verts, file_bytes=os.path.getsize(path),
                           seconds=_time.perf_counter() - t_start)


# --------------------------------------------------------------------------- reader

@dataclass
class PatchUsd:
    """A patch read back from USD (float32 values as float64 arrays).

    Attributes
    ----------
    time_codes : (T,)
    points : (T, courses, m, 3) course curve vertices [mm]
    extents : (T, courses, 2, 3) [mm]
    widths : (courses, m) [mm]
    head_apex, sinker_apex, A : (T, courses, wales, 3) landmark points [mm]
    fields : name -> (T, courses, wales) per-cell primvars (``stage`` is the label code)
    material_id : (courses, wales) or None
    info : dict, ``customLayerData["knitsim"]``
    meters_per_unit, up_axis : stage metadata
    """

    time_codes: np.ndarray
    points: np.ndarray
    extents: np.ndarray
    widths: np.ndarray
    head_apex: np.ndarray
    sinker_apex: np.ndarray
    A: np.ndarray
    fields: dict
    material_id: np.ndarray | None
    info: dict
    meters_per_unit: float
    up_axis: str


def open_knitsim_stage(path):
    """Open a USD file written by knitsim: its stage and the ``customLayerData['knitsim']`` it carries."""
    from pxr import Usd

    path = os.fspath(path)
    if not os.path.exists(path):
        raise KnitsimInputError(f"path={path!r} does not exist")
    stage = Usd.Stage.Open(path)
    return stage, dict(stage.GetRootLayer().customLayerData.get("knitsim", {}))


def read_patch_usd(path) -> PatchUsd:
    """Read a patch written by :func:`write_patch_usd`, at every time code."""
    from pxr import UsdGeom

    path = os.fspath(path)
    stage, info = open_knitsim_stage(path)
    if "layout" not in info:
        raise KnitsimInputError(f"path={path!r} was not written by knitsim.usd (no customLayerData['knitsim'])")
    lay = info["layout"]
    if lay.get("kind") == "instanced specimen":
        raise KnitsimInputError(f"path={path!r} is an instanced specimen: read it with "
                                "knitsim.usd.instanced.read_specimen_usd")
    courses, wales, n = int(lay["courses"]), int(lay["wales"]), int(lay["points_per_quarter"])
    curves = [UsdGeom.BasisCurves(stage.GetPrimAtPath(f"{lay['yarns']}/{lay['prim_name_format'].format(i)}"))
              for i in range(courses)]
    tcs = np.array(curves[0].GetPointsAttr().GetTimeSamples(), dtype=float)
    pts = np.array([[np.asarray(c.GetPointsAttr().Get(t)) for c in curves] for t in tcs], dtype=float)
    ext = np.array([[np.asarray(c.GetExtentAttr().Get(t)) for c in curves] for t in tcs], dtype=float)
    widths = np.array([np.asarray(c.GetWidthsAttr().Get()) for c in curves], dtype=float)
    fields, mat = {}, None
    for pv in UsdGeom.PrimvarsAPI(curves[0]).GetPrimvarsWithValues():
        name = pv.GetPrimvarName()
        if not name.startswith(FIELD_PREFIX):
            continue
        short = name[len(FIELD_PREFIX):]
        pvs = [UsdGeom.PrimvarsAPI(c).GetPrimvar(name) for c in curves]
        if short == "material_id":
            mat = np.array([np.asarray(p.Get()) for p in pvs])
        else:
            fields[short] = np.array([[np.asarray(p.Get(t)) for p in pvs] for t in tcs])
    j = np.arange(wales)
    marks = {k: pts[:, :, yg.landmark_index(k, n, j), :] for k in ("head_apex", "sinker_apex", "A")}
    return PatchUsd(time_codes=tcs, points=pts, extents=ext, widths=widths, fields=fields, material_id=mat,
                    info=info, meters_per_unit=UsdGeom.GetStageMetersPerUnit(stage),
                    up_axis=str(UsdGeom.GetStageUpAxis(stage)), **marks)
