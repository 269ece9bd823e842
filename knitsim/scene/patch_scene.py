"""Patch scenes: a ``courses x wales`` patch of cells between rigid grips, in one TOML file.

Example (``scenes/two_zone_basalt_e_glass.toml``)::

    title = "two zones"
    engine = "warp"                 # or "reference"
    device = "cpu"                  # cpu, cuda, cuda:N, auto
    seed = 1                        # default seed of random maps

    [patch]
    wales = 23                      # columns in parallel
    courses = 110                   # cells in series along a column
    dedup = true                    # solve identical cells once (exact)

    [yarn]                          # the base cell, as in a cell scene
    material = "e_glass"
    [knit]
    material = "e_glass_plain"
    [friction]
    model = "coulomb"
    m = 0.20
    phi0 = 0.0                      # initial friction angle [rad]
    [rules]
    force_cap_N = 10.0

    [[zones]]                       # rectangular material zones, [start, stop) 0-based
    label = "basalt half"
    courses = [55, 110]
    wales = [0, 23]
    yarn = { material = "basalt" }
    knit = { material = "basalt_plain" }

    [maps.phi0]                     # per-cell maps, applied after the zones
    type = "random"                 # uniform / regions / gradient / file / random
    low = -1.0
    high = 1.0
    scale = "phimax"

    [load]                          # grip strain = grip displacement / column rest length
    type = "cycles"
    lower_strain = 0.10
    upper_strain = 0.60
    cycles = 3
    max_increment = 0.005

    [output]
    plot = true
    checkpoint_every = 50
    cells_stride = 1                # cells.nc at increments k s, the turning points and the last

**A specimen as a tester describes it** (instead of ``[patch]``)::

    materials = "materials.toml"    # a material library (knitsim calibrate writes one)

    [specimen]
    width = 50.0                    # [mm] across the wales
    gauge_length = 100.0            # [mm] between the grips
    strips = 2                      # columns across the width (equal widths)
    bands = 1                       # rows along the gauge length (equal lengths)

    [knit]
    material = "jersey_4p5"         # its yarn comes with it
    [[zones]]                       # zones index bands (courses) and strips (wales)
    wales = [1, 2]
    knit = { material = "jersey_6p5" }

    [[grades]]                      # a blend of two knits of one yarn, graded along an axis
    from = "jersey_4p5"             # at the first band (strip)
    to = "jersey_6p5"               # at the last
    axis = "courses"                # "courses": along the wale (bands); "wales": across (strips)
    profile = "linear"              # or "step" (with steps)
    fractions = [0.0, 1.0]          # share of "to" at the start and the end of the axis (optional)

Each element of the ``bands x strips`` grid is a block of identical
stitches: ``band length / C0`` courses in series and ``strip width / W0``
wales in parallel (so a strip of shorter loops has more courses between the
same grips, and a band of narrower loops more wales across the same width);
every strip's rest length is the gauge length, and the grip strain is the
grip displacement over it, the same for every strip (:mod:`knitsim.patch.model`).
A blend at fraction t (the element's centre, (k + 1/2)/n along the axis, or
its step, scaled onto ``fractions``; each in [0, 1]) is the knit of the same yarn whose L, W0, C0 and phi0 are
``(1 - t) a + t b``: a graded knit is a blend of knits, its yarn (B, d, the
in-plane width, friction, rules, effects) the one yarn of both.  Order:
base, grades, zones, maps.

Everything is validated before any solve: unknown keys, types, missing
fields, ranges, zone and map index ranges, map shapes (files), and every
cell's parameters (W0 >= 4 d, L long enough to close a loop, |phi0| <=
phimax); messages name the key path that set the offending value and the
cell, e.g. ``zones[0].knit.W0 = 2.0: must be >= 4 d = 2.32 mm at cell
[course 55, wale 0]``.
"""
from __future__ import annotations

import copy
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..cell.load_program import LoadProgram, pretensioned
from ..cell.stages import DAHL_SIGMA_MAX, DAHL_SIGMA_TOO_STIFF, DAHL_SIGMA_UNUSED, M_MAX, M_TOO_LARGE
from ..errors import KnitsimInputError
from ..patch.maps import AXES, MAP_TYPES, PROFILES, SCALES, build_map, index_range
from ..patch.model import (MAX_STITCHES_PER_AXIS, PARAM_NAMES, RULE_NAMES, PatchModel, cell_name, cm_hint,
                           specimen_size_notes)
from .cell_scene import (ENGINES, PHI0_KEYS, degrees_hint, _CELL_TABLES, _cell_table, _device_check, _effects_table, _friction_table,
                         _knit_table, _load_table, _materials_field, _merge, _Origins, _program, _resolve_cell,
                         _provenance_table, _rules_table, _yarn_table, library_of)
from .schema import OPTIONAL, REQUIRED, Field, Table, TableArray, dumps, error, fmt, load_toml, set_value, validate


def _map_table(name: str) -> Table:
    return Table({
        "type": Field(("str",), OPTIONAL, "uniform, regions, gradient, file or random (required)",
                      choices=MAP_TYPES),
        "value": Field(("float",), OPTIONAL, "uniform: the value"),
        "default": Field(("float",), OPTIONAL, "regions: value outside the regions (default: the base value)"),
        "regions": TableArray(Table({
            "courses": Field(("float_list",), OPTIONAL, "[start, stop) of courses, 0-based (default: all)"),
            "wales": Field(("float_list",), OPTIONAL, "[start, stop) of wales, 0-based (default: all)"),
            "value": Field(("float",), REQUIRED, "value in the region"),
        }), "regions: rectangles, later ones on top", min_items=1),
        "axis": Field(("str",), OPTIONAL, "gradient: along courses or wales", choices=AXES),
        "start": Field(("float",), OPTIONAL, "gradient: value on the first course / wale"),
        "end": Field(("float",), OPTIONAL, "gradient: value on the last course / wale"),
        "profile": Field(("str",), OPTIONAL, "gradient: linear or step", choices=PROFILES),
        "steps": Field(("int",), OPTIONAL, "step gradient: number of bands", min=2),
        "path": Field(("str",), OPTIONAL, "file: .npy or .csv of shape (courses, wales), relative to the scene"),
        "low": Field(("float",), OPTIONAL, "random: lower bound"),
        "high": Field(("float",), OPTIONAL, "random: upper bound"),
        "seed": Field(("int",), OPTIONAL, "random: seed (default: the scene's seed)", min=0),
        "scale": Field(("str",), OPTIONAL, "random: absolute, or phimax (phi0 only)", choices=SCALES),
    }, f"per-cell map of {name}")


#: the effect each effect parameter belongs to (knitsim.cell.effects): maps of these set it per cell
_EFFECT_OF = {"coil_mu_k": "coiling_angle_friction", "load_n": "normal_load_friction",
              "load_ref_N": "normal_load_friction", "rate_p": "velocity_friction", "rate_ref_mm_s": "velocity_friction",
              "compaction_k": "yarn_compaction", "compaction_min": "yarn_compaction", "bend_h": "bending_hysteresis",
              "bend_sigma": "bending_hysteresis", "ext_c": "yarn_extension"}

_UNITS = {"d": "mm", "B": "N mm^2", "m": "-", "dahl_sigma": "1/mm", "L": "mm", "W0": "mm", "C0": "mm", "phi0": "rad",
          "in_plane_width": "mm"}

#: the schema of a patch scene file
PATCH_SCENE = Table({
    "title": Field(("str",), OPTIONAL, "free text"),
    "provenance": _provenance_table(),
    "materials": _materials_field(),
    "engine": Field(("str",), "warp", "warp (batched kernels) or reference (NumPy)", choices=ENGINES),
    "device": Field(("str",), "cpu", "Warp device", check=_device_check),
    "seed": Field(("int",), 0, "default seed of random maps", min=0),
    "patch": Table({
        "wales": Field(("int",), OPTIONAL, "wale columns (in parallel); required without [specimen]",
                       min=1, max=MAX_STITCHES_PER_AXIS),
        "courses": Field(("int",), OPTIONAL, "cells along a column (in series); required without [specimen]",
                         min=1, max=MAX_STITCHES_PER_AXIS),
        "dedup": Field(("bool",), True, "solve identical cells once (exact)"),
    }, "patch size (a patch of single stitches), or only dedup with [specimen]"),
    "specimen": Table({
        "width": Field(("float",), OPTIONAL, "specimen width across the wales (required)", "mm", min=0.0,
                       min_inclusive=False),
        "gauge_length": Field(("float",), OPTIONAL, "distance between the grips (required)", "mm", min=0.0,
                              min_inclusive=False),
        "strips": Field(("int",), 1, "columns across the width, of equal widths (each width/strips / W0 wales)",
                        min=1, max=10_000),
        "pretension": Field(("float",), 0.0, "strain of the knit at grip strain 0 (pretensioned before the strain "
                            "origin: the knit rests at gauge_length / (1 + pretension), and the run starts by "
                            "stretching it to the gauge length, at negative grip strains)", min=0.0, max=0.5),
        "bands": Field(("int",), 1, "rows along the gauge length, of equal lengths (each length/bands / C0 courses)",
                       min=1, max=10_000),
    }, "a specimen between grips: the grid is bands x strips blocks of stitches"),
    "grades": TableArray(Table({
        "label": Field(("str",), OPTIONAL, "name of the grade"),
        "from": Field(("str",), REQUIRED, "knit at the start of the axis (library or built-in knit)"),
        "to": Field(("str",), REQUIRED, "knit at the end of the axis (the same yarn)"),
        "axis": Field(("str",), REQUIRED, "courses (along the wale) or wales (across)", choices=AXES),
        "profile": Field(("str",), "linear", "linear or step", choices=PROFILES),
        "steps": Field(("int",), OPTIONAL, "step profile: number of bands", min=2),
        "fractions": Field(("float_list",), OPTIONAL, "[at the start, at the end] of the axis: blend fractions "
                           "of the second knit (default [0, 1]; equal: a uniform blend)"),
        "courses": Field(("float_list",), OPTIONAL, "[start, stop) of courses, 0-based (default: all)"),
        "wales": Field(("float_list",), OPTIONAL, "[start, stop) of wales, 0-based (default: all)"),
    }), "blends of two knits of one yarn graded along an axis (applied after the base, before the zones)"),
    "yarn": _yarn_table(),
    "knit": _knit_table(),
    "friction": _friction_table(True),
    "rules": _rules_table(True),
    "effects": _effects_table(),
    "zones": TableArray(Table({
        "label": Field(("str",), OPTIONAL, "name of the zone"),
        "courses": Field(("float_list",), OPTIONAL, "[start, stop) of courses, 0-based (default: all)"),
        "wales": Field(("float_list",), OPTIONAL, "[start, stop) of wales, 0-based (default: all)"),
        "yarn": _yarn_table(), "knit": _knit_table(), "friction": _friction_table(False),
        "rules": _rules_table(False), "effects": _effects_table(),
    }), "rectangular material zones over the base cell (each its friction model, rules and effects), later "
        "ones on top"),
    "maps": Table({**{n: Table(_map_table(n).fields, f"per-cell map of {n} [{_UNITS[n]}]") for n in PARAM_NAMES},
                   **{n: Table(_map_table(n).fields, f"per-cell map of the effect parameter {n} (cells whose effect "
                                                     f"{_EFFECT_OF[n]} is on)") for n in _EFFECT_OF}},
                  "per-cell maps, applied after the zones"),
    "load": replace(_load_table(), doc="grip strain program (grip displacement / column rest length)"),
    "output": Table({
        "plot": Field(("bool",), True, "write PNG plots"),
        "cell_fields": Field(("bool",), True, "write per-cell fields over time (cells.nc)"),
        "cells_stride": Field(("int",), 1, "cells.nc holds the increments at multiples of this, the program's "
                              "turning points and the last (1: every increment; curve.csv and columns.csv always "
                              "hold every increment)", min=1),
        "checkpoint_every": Field(("int",), 50, "increments between checkpoints (0: none)", min=0),
    }, "what to write"),
    "solver": Table({
        "force_rtol": Field(("float",), 1e-8, "relative agreement of the forces along a column", min=0.0,
                            min_inclusive=False, max=1e-2),
        # at most 1000: the coupling's trials converge in 2-4 an increment on the paper's specimen, the slowest
        # column of its 14,380 column-increments in 61 (benchmarks/README.md); 10^8 was taken, a hang where a
        # column does not converge (a blind probe)
        "max_iterations": Field(("int",), 40, "trial steps per increment before a column is flagged", min=1,
                                max=1000),
    }, "series/parallel coupling"),
})


class _ZoneOrigins(_Origins):
    def __init__(self, index: int, over: dict):
        super().__init__(index, over)

    def path(self, table: str, key: str) -> str:
        if key in self.over.get(table, {}):
            return f"zones[{self.index}].{table}.{key}"
        return f"{table}.{key}" + self.from_library(table, key)

    def where(self) -> str:
        return f" (in zones[{self.index}])"


class _GradeOrigins(_Origins):
    def __init__(self, index: int):
        super().__init__(index, {})

    def path(self, table: str, key: str) -> str:
        return f"grades[{self.index}]"

    def where(self) -> str:
        return f" (in grades[{self.index}])"


@dataclass
class PatchScene:
    """A validated patch scene, ready to run.

    Attributes
    ----------
    model : PatchModel
    program : LoadProgram
        Grip strains.
    engine, device : str
    dedup : bool
    resolved : dict
        The scene with every default filled (a valid scene itself, :meth:`to_toml`).
    origins : dict of str to ndarray of str
        Key path that set each cell's parameter, and its ``force_cap_N`` (for messages).
    source : str
    """

    model: PatchModel
    program: LoadProgram
    engine: str
    device: str
    dedup: bool
    resolved: dict
    origins: dict
    source: str = "<dict>"
    #: what the scene's values come from that a flagged calibration wrote, and its flags (as CellScene's)
    calibration_flags: list = field(default_factory=list)
    #: warnings of the scene itself, said before the run (``{"code", "message"}``: a specimen of few stitches)
    warnings: list = field(default_factory=list)

    @property
    def output(self) -> dict:
        """The resolved ``[output]`` table."""
        return self.resolved["output"]

    @property
    def solver_options(self) -> dict:
        """A copy of the resolved ``[solver]`` table (the coupling's options)."""
        return dict(self.resolved["solver"])

    def to_toml(self) -> str:
        """The resolved scene as TOML (every default filled in)."""
        return dumps(self.resolved, header=f"knitsim patch scene, resolved from {self.source}\n"
                                           "every default filled in; units N, mm, rad (degrees only in *_deg)")


def _cell_values(tables: dict) -> dict:
    return {"d": tables["yarn"]["d"], "B": tables["yarn"]["B"], "L": tables["knit"]["L"],
            "W0": tables["knit"]["W0"], "C0": tables["knit"]["C0"], "m": tables["friction"]["m"],
            "phi0": tables["friction"]["phi0"], "dahl_sigma": tables["friction"]["dahl_sigma"],
            "in_plane_width": tables["yarn"].get("in_plane_width", float("nan"))}


def _check_cells(fields: dict, origins: dict, friction, blocks: bool = False) -> None:
    """Per-cell conditions of section 3.1 / 3.3 (as CellParams.validated), naming the key that set the value and
    the cell (a specimen's block by band and strip: ``blocks``)."""
    def fail(name, mask, why):
        i, j = (int(v) for v in np.argwhere(mask)[0])
        v = float(fields[name][i, j])
        raise KnitsimInputError(f"{origins[name][i, j]} = {fmt(v)}: {why(i, j)} at {cell_name(i, j, blocks, True)}")

    for name in ("d", "B", "L", "W0", "C0"):
        bad = ~(fields[name] > 0)
        if bad.any():
            fail(name, bad, lambda i, j: "must be > 0")
    for name in ("m", "dahl_sigma"):
        bad = ~(fields[name] >= 0)
        if bad.any():
            fail(name, bad, lambda i, j: "must be >= 0")
    bad = fields["m"] > M_MAX
    if bad.any():
        fail("m", bad, lambda i, j: M_TOO_LARGE)
    dahl = np.asarray(friction == "dahl") if isinstance(friction, np.ndarray) else (friction == "dahl")
    bad = np.asarray((friction == "coulomb") & (fields["dahl_sigma"] != 0))
    if bad.any():
        fail("dahl_sigma", bad, lambda i, j: DAHL_SIGMA_UNUSED)
    if np.any(dahl):
        bad = dahl & ~(fields["dahl_sigma"] > 0)
        if bad.any():
            fail("dahl_sigma", bad, lambda i, j: "friction.model = \"dahl\" needs a stiffness > 0 [1/mm]")
        bad = dahl & (fields["dahl_sigma"] > DAHL_SIGMA_MAX)
        if bad.any():
            fail("dahl_sigma", bad, lambda i, j: DAHL_SIGMA_TOO_STIFF)
        bad = dahl & ~(fields["m"] > 0)
        if bad.any():
            fail("m", bad, lambda i, j: "Dahl friction needs m > 0")
    d, W0, L, C0 = fields["d"], fields["W0"], fields["L"], fields["C0"]
    bad = W0 < 4.0 * d
    if bad.any():
        fail("W0", bad, lambda i, j: f"must be >= 4 d = {4 * d[i, j]:.4g} mm (d from {origins['d'][i, j]}; "
                                     "loops jammed already)")
    lmin = 2.0 * C0 + W0 - 4.0 * d
    bad = L <= lmin
    if bad.any():
        fail("L", bad, lambda i, j: f"too short to close a loop: needs > 2 C0 + W0 - 4 d = {lmin[i, j]:.4g} mm")
    w = fields["in_plane_width"]
    given = np.isfinite(w)
    bad = given & ~(w >= d)
    if bad.any():
        fail("in_plane_width", bad, lambda i, j: f"the in-plane width cannot be below the compact diameter "
                                                 f"d = {d[i, j]:.4g} mm")
    bad = given & (W0 < 4.0 * w)
    if bad.any():
        fail("in_plane_width", bad, lambda i, j: f"loops jammed at rest: needs 4 in_plane_width <= W0 = "
                                                 f"{W0[i, j]:.4g} mm")
    phimax = np.arctan(fields["m"])
    bad = np.abs(fields["phi0"]) > phimax + 1e-12
    if bad.any():
        fail("phi0", bad, lambda i, j: f"must lie in [-phimax, phimax] = [{-phimax[i, j]:.4g}, {phimax[i, j]:.4g}] "
                                       f"rad (= +/-{np.degrees(phimax[i, j]):.4g} deg, m = {fields['m'][i, j]:.4g} "
                                       f"from {origins['m'][i, j]})" + degrees_hint(float(fields["phi0"][i, j])))


def _knit_of(name: str, lib, key: str) -> tuple:
    """(L, W0, C0, phi0 or None, yarn name, from the library?) of a library or built-in knit."""
    from .. import materials
    if lib is not None and name in lib.knits:
        k = lib.knits[name]
        return k.L, k.W0, k.C0, k.phi0, k.yarn, True
    if name in materials.knit_names():
        k = materials.knit(name, key)
        return k.L, k.W0, k.C0, None, k.yarn, False
    known = sorted(set(materials.knit_names()) | (set(lib.knits) if lib is not None else set()))
    raise error(key, name, f"unknown knit (known: {', '.join(known)})")


def _blend_fractions(n: int, profile: str, steps: int) -> np.ndarray:
    """Blend fraction of each of ``n`` elements along a grade: the element's centre (k + 1/2)/n (linear),
    or its band of ``steps`` equal bands, valued b/(steps - 1) (step)."""
    k = np.arange(n, dtype=np.float64)
    if profile == "linear":
        return (k + 0.5) / n
    band = np.minimum((k * steps // n).astype(np.int64), steps - 1)
    return band / (steps - 1)


def grade_element_label(grade: str, t: float, a: str, b: str) -> str:
    """The label of a grade's element in the resolved scene (a zone there): the grade's name (its label, or
    ``grades[k]``) and its blend, ``(1 - t)`` of knit ``a`` and ``t`` of knit ``b``."""
    return f"{grade}: {1 - t:.4g} {a} + {t:.4g} {b}"


#: a label of :func:`grade_element_label` (library names hold no space; fractions as ``:.4g`` writes them)
_GRADE_ELEMENT = re.compile(r"^(?P<grade>.+): [0-9.e+-]+ \S+ \+ [0-9.e+-]+ \S+$")


def grade_of_zone(zone: dict) -> str | None:
    """The grade (its label, or ``grades[k]``) that a zone of the resolved scene is an element of, or None for
    a zone of the scene's own ``[[zones]]``.  Read from the element's label, so that the resolved scene (a
    valid scene itself, rerun as it is written) says it too."""
    m = _GRADE_ELEMENT.match(str(zone.get("label", "")))
    return m.group("grade") if m else None


def load_patch_scene(source: str | Path | dict, overrides: list[str] = (), engine: str | None = None,
                     device: str | None = None) -> PatchScene:
    """Read, override (``--set``), validate and resolve a patch scene; nothing is solved.

    Raises
    ------
    KnitsimInputError
        The first problem, naming the key path and the value.
    """
    from ..material_library import expand
    if isinstance(source, dict):
        data, name, base_dir = copy.deepcopy(source), "<dict>", Path(".")
    else:
        data, name, base_dir = load_toml(source), str(source), Path(source).resolve().parent
    for a in overrides:
        set_value(data, PATCH_SCENE, a)
    if engine is not None:
        data["engine"] = engine
    if device is not None:
        data["device"] = device
    doc = validate(PATCH_SCENE, data, fill_defaults=True)
    lib = library_of(data, base_dir)
    specimen = "specimen" in data
    if specimen:
        sp = doc["specimen"]
        for key in ("width", "gauge_length"):
            if key not in sp:
                raise KnitsimInputError(f"specimen.{key}: missing (a specimen states its width and the gauge length "
                                        "between the grips, in mm)")
        for key in ("wales", "courses"):
            if key in data.get("patch", {}):
                raise error(f"patch.{key}", data["patch"][key], "give either [patch] wales and courses (a patch of "
                            "single stitches) or [specimen] (width, gauge length: the counts follow from W0 and C0), "
                            "not both")
        courses, wales = sp["bands"], sp["strips"]
    else:
        for key in ("wales", "courses"):
            if key not in doc["patch"]:
                raise KnitsimInputError(f"patch.{key}: missing required key (or describe a [specimen] by its width "
                                        "and gauge length)")
        courses, wales = doc["patch"]["courses"], doc["patch"]["wales"]
    shape = (courses, wales)
    # the key that set the count across (a specimen's strips, not a [patch] it does not have)
    count_key = "specimen.strips" if specimen else "patch.wales"
    if courses * wales > 50_000_000:
        raise error(count_key, wales, f"{courses} x {wales} cells is more than 50 million")
    # the scene's own per-cell arrays against the machine's memory, before they are allocated (a 7000 x 7000 patch
    # was killed part-way through loading, at 24 GB, without a word); the run's records are checked before the
    # solve (knitsim.cli.run.check_record_memory)
    from ..patch import runner as _runner
    need, free = _runner.scene_memory_bytes(courses * wales), _runner.available_memory_bytes()
    if free is not None and need > free:
        gib = 2.0 ** 30
        raise error(count_key, wales, f"{courses:,} x {wales:,} = {courses * wales:,} cells need about "
                    f"{need / gib:.3g} GiB for the patch's per-cell parameters alone "
                    f"({_runner.SCENE_BYTES_PER_CELL} bytes a cell), more than the {free / gib:.3g} GiB free on this "
                    "machine: it would be killed part-way; run a smaller patch"
                    + (" (fewer strips or bands: each is a block of identical stitches)" if specimen else ""))

    # base cell (the yarn / knit / friction / rules tables, as a cell scene)
    raw_base = {t: validate(PATCH_SCENE.fields[t], data.get(t, {}), t, fill_defaults=False) for t in _CELL_TABLES}
    filled: dict = {}
    merged = validate(_cell_table(True), expand(_merge(raw_base, {}), lib, "", filled), "", fill_defaults=True)
    base_tables, _ = _resolve_cell(merged, _Origins(None, {}, filled))
    rules = dict(base_tables["rules"])
    rules["friction"] = base_tables["friction"]["model"]
    # rules and effects per cell (a patch mixes materials: Coulomb and Dahl regions, rule sets, effects)
    rule_arr = {r: np.full(shape, rules.get(r), dtype=object) for r in RULE_NAMES}   # cap None: the default
    effects_arr = np.empty(shape, dtype=object)
    for idx in np.ndindex(shape):
        effects_arr[idx] = base_tables["_effects"]
    base = _cell_values(base_tables)
    fields = {n: np.full(shape, float(base[n])) for n in PARAM_NAMES}
    _BASE_PATHS = {"d": "yarn.d", "B": "yarn.B", "L": "knit.L", "W0": "knit.W0", "C0": "knit.C0",
                   "m": "friction.m", "phi0": "friction.phi0", "dahl_sigma": "friction.dahl_sigma",
                   "in_plane_width": "yarn.in_plane_width"}
    origins = {n: np.full(shape, _BASE_PATHS[n], dtype=object) for n in PARAM_NAMES}
    # and the force cap's (a zone's rules.force_cap_N below a cell's rest force is refused naming it)
    origins["force_cap_N"] = np.full(shape, _Origins(None, {}, filled).path("rules", "force_cap_N"), dtype=object)

    def zone_tables(raw_over: dict, where: str, org) -> dict:
        merged = _merge(raw_base, raw_over)
        zm = validate(_cell_table(True), expand(merged, lib, where, org.library), where, fill_defaults=True)
        return _resolve_cell(zm, org)[0]

    def put(ztables: dict, ci, wi, origin_of) -> dict:
        """Set the cells [ci, wi] from resolved tables; returns the zone as the resolved scene spells it."""
        zrules = dict(ztables["rules"], friction=ztables["friction"]["model"])
        for r in RULE_NAMES:
            rule_arr[r][ci, wi] = zrules.get(r)
        for idx in np.ndindex(effects_arr[ci, wi].shape):
            effects_arr[ci, wi][idx] = ztables["_effects"]
        vals = _cell_values(ztables)
        for n in PARAM_NAMES:
            fields[n][ci, wi] = vals[n]
            o = origin_of(n)
            if o is not None:
                origins[n][ci, wi] = o
        zres = {"courses": [ci.start, ci.stop], "wales": [wi.start, wi.stop],
                "yarn": ztables["yarn"], "knit": ztables["knit"],
                "friction": {"model": ztables["friction"]["model"], "m": ztables["friction"]["m"],
                             "phi0": ztables["friction"]["phi0"], "dahl_sigma": ztables["friction"]["dahl_sigma"]},
                "rules": dict(ztables["rules"])}
        if "effects" in ztables:
            zres["effects"] = ztables["effects"]
        return zres

    zones_out = []
    # a specimen's zones index its bands (courses) and strips (wales): said so in a range error
    counted_courses, counted_wales = ("bands", "strips") if specimen else (None, None)
    counted = ("bands", "strips") if specimen else None
    # grades: blends of two knits of one yarn along an axis (each element a zone of the resolved scene)
    for g, grade in enumerate(doc.get("grades", [])):
        gp = f"grades[{g}]"
        La, Wa, Ca, pa, ya, _ = _knit_of(grade["from"], lib, f"{gp}.from")
        Lb, Wb, Cb, pb, yb, _ = _knit_of(grade["to"], lib, f"{gp}.to")
        if ya != yb:
            raise error(f"{gp}.to", grade["to"], f"a grade blends knits of one yarn: {grade['from']!r} is of yarn "
                        f"{ya!r}, {grade['to']!r} of yarn {yb!r}")
        if (pa is None) != (pb is None):
            raise error(f"{gp}.to", grade["to"], "both knits of a grade must state phi0, or neither")
        ci = index_range(grade.get("courses", [0, courses]), courses, f"{gp}.courses", "courses", counted_courses)
        wi = index_range(grade.get("wales", [0, wales]), wales, f"{gp}.wales", "wales", counted_wales)
        along = ci if grade["axis"] == "courses" else wi
        n = along.stop - along.start
        steps = grade.get("steps", 2)
        if grade["profile"] == "step" and not (2 <= steps <= n):
            raise error(f"{gp}.steps", steps, f"a step grade needs 2 <= steps <= {n} (the {grade['axis']} it spans)")
        if grade["profile"] == "linear" and "steps" in grade:
            raise error(f"{gp}.steps", steps, "not used by a linear grade")
        ends = grade.get("fractions", [0.0, 1.0])
        if len(ends) != 2:
            raise error(f"{gp}.fractions", ends, "expected [at the start, at the end] of the axis")
        for e_i, t_end in enumerate(ends):
            if not 0.0 <= t_end <= 1.0:
                raise error(f"{gp}.fractions[{e_i}]", t_end, f"a blend fraction is in [0, 1] (the share of "
                            f"{grade['to']!r}; outside it the blend would extrapolate the two knits)")
        t_all = ends[0] + (ends[1] - ends[0]) * _blend_fractions(n, grade["profile"], steps)
        for k, t in enumerate(t_all):
            # the blend: the knit geometry (and phi0) between the two, the one yarn of both; the scene's
            # own keys win as for any library material
            knit = {key: v for key, v in raw_base["knit"].items() if key != "material"}
            knit.update(L=(1 - t) * La + t * Lb, W0=(1 - t) * Wa + t * Wb, C0=(1 - t) * Ca + t * Cb)
            friction = dict(raw_base["friction"])
            if pa is not None and not any(key in friction for key in PHI0_KEYS):
                friction["phi0"] = (1 - t) * pa + t * pb
            yarn = dict(raw_base["yarn"])
            if not any(key in yarn for key in ("material", "d", "B")):
                yarn = {"material": ya}
            where = f"{gp} (fraction {t:.4g})"
            merged = {"yarn": yarn, "knit": knit, "friction": friction, "rules": dict(raw_base["rules"]),
                      "effects": dict(raw_base["effects"])}
            zm = validate(_cell_table(True), expand(merged, lib, where), where, fill_defaults=True)
            gt, _ = _resolve_cell(zm, _GradeOrigins(g))
            sl = slice(along.start + k, along.start + k + 1)
            eci, ewi = (sl, wi) if grade["axis"] == "courses" else (ci, sl)
            zres = put(gt, eci, ewi, lambda n_: gp)
            zres["label"] = grade_element_label(grade.get("label", gp), t, grade["from"], grade["to"])
            zones_out.append(zres)

    # zones: the base tables overridden per rectangle (library materials resolved as for a cell)
    for z, zone in enumerate(doc.get("zones", [])):
        zone_names = ("yarn", "knit", "friction", "rules", "effects")
        if not any(data["zones"][z].get(t) for t in zone_names):
            # a zone that changes nothing is a mistake (a table name mistyped or left out), not a zone
            # (a blind probe's [[zones]] with courses only ran as the base knit, silently)
            raise KnitsimInputError(f"zones[{z}]: changes nothing: give it a yarn, knit, friction, rules or "
                                    "effects table (zones[k].knit = { W0 = ... }), or leave it out")
        raw_over = {t: validate(PATCH_SCENE.fields["zones"].item.fields[t], data["zones"][z].get(t, {}),
                                f"zones[{z}].{t}", fill_defaults=False) for t in zone_names}
        zorg = _ZoneOrigins(z, raw_over)
        ztables = zone_tables(raw_over, f"zones[{z}]", zorg)
        ci = index_range(zone.get("courses", [0, courses]), courses, f"zones[{z}].courses", "courses", counted_courses)
        wi = index_range(zone.get("wales", [0, wales]), wales, f"zones[{z}].wales", "wales", counted_wales)

        def origin_of(n, raw_over=raw_over, z=z):
            tbl = {"d": "yarn", "B": "yarn", "in_plane_width": "yarn", "L": "knit", "W0": "knit",
                   "C0": "knit"}.get(n, "friction")
            if (n in raw_over.get(tbl, {}) or "material" in raw_over.get(tbl, {})
                    or (n == "m" and raw_over.get("friction"))
                    or (tbl == "yarn" and "material" in raw_over.get("knit", {}))):
                return f"zones[{z}].{tbl}.{n}"
            return None
        zres = put(ztables, ci, wi, origin_of)
        origins["force_cap_N"][ci, wi] = zorg.path("rules", "force_cap_N")
        if "label" in zone:
            zres = {"label": zone["label"], **zres}
        zones_out.append(zres)

    # maps, m first (a phi0 map may be scaled by phimax = atan(m))
    maps_in = {k: v for k, v in data.get("maps", {}).items()} if isinstance(data.get("maps"), dict) else {}
    maps_out = {}
    for n in sorted((k for k in maps_in if k in PARAM_NAMES), key=lambda k: (k != "m", PARAM_NAMES.index(k))):
        spec = doc["maps"][n]
        spec = {k: v for k, v in spec.items() if not (isinstance(v, dict) and not v)}
        if spec.get("type") == "random":
            spec.setdefault("seed", doc["seed"])
        if "regions" in spec:
            spec["regions"] = [{k: v for k, v in r.items()} for r in spec["regions"]]
        fields[n] = build_map(spec, shape, fields[n], f"maps.{n}", doc["seed"], base_dir,
                              phimax=np.arctan(fields["m"]), name=n, counted=counted)
        origins[n][:] = f"maps.{n}"
        maps_out[n] = spec
    # maps of effect parameters: each cell's EffectSet with the mapped value (where its effect is on)
    from dataclasses import replace as _replace
    for n in (k for k in maps_in if k in _EFFECT_OF):
        spec = {k: v for k, v in doc["maps"][n].items() if not (isinstance(v, dict) and not v)}
        if "regions" in spec:
            spec["regions"] = [dict(r) for r in spec["regions"]]
        on = np.array([[_EFFECT_OF[n] in effects_arr[i, j].on for j in range(wales)] for i in range(courses)])
        if not on.any():
            raise error(f"maps.{n}.type", spec.get("type"), f"no cell has the effect {_EFFECT_OF[n]} on "
                        "(switch it on in [effects] or a zone's effects)")
        current = np.array([[float(getattr(effects_arr[i, j], n)) for j in range(wales)] for i in range(courses)])
        values = build_map(spec, shape, current, f"maps.{n}", doc["seed"], base_dir, name=n, counted=counted)
        for i, j in zip(*np.nonzero(on)):
            effects_arr[i, j] = _replace(effects_arr[i, j], **{n: float(values[i, j])}).validated(
                where=f"maps.{n} at {cell_name(i, j, specimen, True)}")
        maps_out[n] = spec
    _check_cells(fields, origins, rule_arr["friction"], blocks=specimen)
    if doc["engine"] == "reference" and any(e.on for e in effects_arr.ravel()):
        raise error("engine", doc["engine"], "the model extensions ([effects]) run on the warp engine only")

    scene_warnings: list[dict] = []
    if specimen:
        # a tester's specimen: each element holds band length / C0 courses and strip width / W0 wales
        G, width, pre = sp["gauge_length"], sp["width"], sp["pretension"]
        course_count = (G / (1.0 + pre) / courses) / fields["C0"]      # the knit at rest between the grips
        wale_count = (width / wales) / fields["W0"]
        # between the grips, every strip holds at least one course; across the width, every band one wale
        along, across = course_count.sum(axis=0), wale_count.sum(axis=1)
        cm = cm_hint(width, G, float(across.min()), float(along.min()))
        for total, axis, key, value, what, spacing in (
                (along, 0, "gauge_length", G, "shorter than one course", "C0"),
                (across, 1, "width", width, "narrower than one wale", "W0")):
            if np.any(total < 1.0):
                k = int(np.argmin(total))
                line = "strip" if axis == 0 else "band"
                raise error(f"specimen.{key}", value, f"{what} ({spacing} = {fmt(float(fields[spacing].max()))} mm): "
                            f"{line} {k} holds {total[k]:.4g} {'courses' if axis == 0 else 'wales'}" + cm)
        # a specimen no grips hold (refused), or one all edges and grips (warned of, before the run)
        refusal, size_warning = specimen_size_notes(width, G, across, along)
        if refusal is not None:
            key = "width" if across.max() > MAX_STITCHES_PER_AXIS else "gauge_length"
            raise error(f"specimen.{key}", sp[key], refusal)
        if size_warning is not None:
            scene_warnings.append({"code": "specimen_few_stitches", "message": size_warning})
        # and every block at least one stitch: a band shorter than a course (a strip narrower than a wale)
        # is a cell standing for a fraction of a stitch
        for counts, key, across, what in ((course_count, "bands", 0, "courses"), (wale_count, "strips", 1, "wales")):
            if np.any(counts < 1.0 - 1e-9):
                i, j = (int(v) for v in np.unravel_index(int(np.argmin(counts)), counts.shape))
                most = int(np.floor(counts.sum(axis=across).min() * (1.0 + 1e-9)))
                raise error(f"specimen.{key}", sp[key], f"the block at band {i}, strip {j} holds {counts[i, j]:.4g} "
                            f"{what}, less than one stitch: at most {most} {key}")
        model = PatchModel(courses, wales, fields, rule_arr, effects_arr, course_count=course_count,
                           wale_count=wale_count, gauge_length=G, pretension=pre)
        ref = G
        # grip displacement the strips can take from the strain origin (past their pretension)
        reach = (course_count * (fields["L"] / 2.0 - fields["C0"])).sum(axis=0) - (G - G / (1.0 + pre))
        what = "strip"
    else:
        model = PatchModel(courses, wales, fields, rule_arr, effects_arr)
        rest = fields["C0"].sum(axis=0)
        ref = float(rest[0]) if np.all(rest == rest[0]) else float(rest.mean())
        reach = (fields["L"] / 2.0 - fields["C0"]).sum(axis=0)   # straight yarn: C < L/2 in every cell
        what = "column"

    # the grip program; every column must be able to take the largest grip displacement (checked on the
    # load table's numbers, before the program is built)
    j = int(np.argmin(reach))
    program, load_resolved = _program(doc["load"], [], limit_of=(
        float(reach[j] / ref), f"{what} {j} can stretch by at most {reach[j]:.4g} mm (C < L/2 in every cell), "
                               f"i.e. grip strain < {reach[j] / ref:.4g}"))
    if specimen and model.pretension > 0:
        program = pretensioned(program, model.grip_offset, doc["load"]["max_increment"])

    resolved: dict[str, Any] = {}
    if "title" in doc:
        resolved["title"] = doc["title"]
    patch_res = dict(doc["patch"]) if not specimen else {"dedup": doc["patch"]["dedup"]}
    resolved.update(engine=doc["engine"], device=doc["device"], seed=doc["seed"], patch=patch_res)
    if specimen:
        resolved["specimen"] = dict(sp)
    resolved.update(yarn=base_tables["yarn"], knit=base_tables["knit"], friction=base_tables["friction"],
                    rules=base_tables["rules"], load=load_resolved, output=doc["output"], solver=doc["solver"])
    if "effects" in base_tables:
        resolved["effects"] = base_tables["effects"]
    if maps_out:
        resolved["maps"] = maps_out
    if zones_out:
        resolved["zones"] = zones_out
    from ..material_library import flagged_materials
    return PatchScene(model, program, doc["engine"], doc["device"], bool(doc["patch"]["dedup"]), resolved,
                      origins, name, flagged_materials(data, lib), scene_warnings)
