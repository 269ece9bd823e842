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

Everything is validated before any solve: unknown keys, types, missing
fields, ranges, zone and map index ranges, map shapes (files), and every
cell's parameters (W0 >= 4 d, L long enough to close a loop, |phi0| <=
phimax); messages name the key path that set the offending value and the
cell, e.g. ``zones[0].knit.W0 = 2.0: must be >= 4 d = 2.32 mm at cell
[course 55, wale 0]``.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..cell.load_program import LoadProgram
from ..errors import KnitsimInputError
from ..patch.maps import AXES, MAP_TYPES, PROFILES, SCALES, build_map, index_range
from ..patch.model import PARAM_NAMES, RULE_NAMES, PatchModel
from .cell_scene import (ENGINES, _CELL_TABLES, _cell_table, _device_check, _effects_table, _friction_table,
                         _knit_table, _load_table, _merge, _Origins, _program, _resolve_cell, _rules_table,
                         _yarn_table)
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


_UNITS = {"d": "mm", "B": "N mm^2", "m": "-", "dahl_sigma": "1/mm", "L": "mm", "W0": "mm", "C0": "mm", "phi0": "rad",
          "in_plane_width": "mm"}

#: the schema of a patch scene file
PATCH_SCENE = Table({
    "title": Field(("str",), OPTIONAL, "free text"),
    "engine": Field(("str",), "warp", "warp (batched kernels) or reference (NumPy)", choices=ENGINES),
    "device": Field(("str",), "cpu", "Warp device", check=_device_check),
    "seed": Field(("int",), 0, "default seed of random maps", min=0),
    "patch": Table({
        "wales": Field(("int",), REQUIRED, "wale columns (in parallel)", min=1, max=100_000),
        "courses": Field(("int",), REQUIRED, "cells along a column (in series)", min=1, max=100_000),
        "dedup": Field(("bool",), True, "solve identical cells once (exact)"),
    }, "patch size", required=True),
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
    "maps": Table({n: Table(_map_table(n).fields, f"per-cell map of {n} [{_UNITS[n]}]") for n in PARAM_NAMES},
                  "per-cell maps, applied after the zones"),
    "load": Table(dict(_load_table().fields), "grip strain program (grip displacement / column rest length)",
                  required=True),
    "output": Table({
        "plot": Field(("bool",), True, "write PNG plots"),
        "cell_fields": Field(("bool",), True, "write per-cell fields over time (cells.nc)"),
        "checkpoint_every": Field(("int",), 50, "increments between checkpoints (0: none)", min=0),
    }, "what to write"),
    "solver": Table({
        "force_rtol": Field(("float",), 1e-8, "relative agreement of the forces along a column", min=0.0,
                            min_inclusive=False, max=1e-2),
        "max_iterations": Field(("int",), 40, "trial steps per increment before a column is flagged", min=1),
    }, "series/parallel coupling"),
})


class _ZoneOrigins(_Origins):
    def __init__(self, index: int, over: dict):
        super().__init__(index, over)

    def path(self, table: str, key: str) -> str:
        if key in self.over.get(table, {}):
            return f"zones[{self.index}].{table}.{key}"
        return f"{table}.{key}"

    def where(self) -> str:
        return f" (in zones[{self.index}])"


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
        Key path that set each cell's parameter (for messages).
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

    @property
    def output(self) -> dict:
        return self.resolved["output"]

    @property
    def solver_options(self) -> dict:
        return dict(self.resolved["solver"])

    def to_toml(self) -> str:
        return dumps(self.resolved, header=f"knitsim patch scene, resolved from {self.source}\n"
                                           "every default filled in; units N, mm, rad (degrees only in *_deg)")


def _cell_values(tables: dict) -> dict:
    return {"d": tables["yarn"]["d"], "B": tables["yarn"]["B"], "L": tables["knit"]["L"],
            "W0": tables["knit"]["W0"], "C0": tables["knit"]["C0"], "m": tables["friction"]["m"],
            "phi0": tables["friction"]["phi0"], "dahl_sigma": tables["friction"]["dahl_sigma"],
            "in_plane_width": tables["yarn"].get("in_plane_width", float("nan"))}


def _check_cells(fields: dict, origins: dict, friction) -> None:
    """Per-cell conditions of section 3.1 / 3.3 (as CellParams.validated), naming the key that set the value."""
    def fail(name, mask, why):
        i, j = (int(v) for v in np.argwhere(mask)[0])
        v = float(fields[name][i, j])
        raise KnitsimInputError(f"{origins[name][i, j]} = {fmt(v)}: {why(i, j)} at cell [course {i}, wale {j}]")

    for name in ("d", "B", "L", "W0", "C0"):
        bad = ~(fields[name] > 0)
        if bad.any():
            fail(name, bad, lambda i, j: "must be > 0")
    for name in ("m", "dahl_sigma"):
        bad = ~(fields[name] >= 0)
        if bad.any():
            fail(name, bad, lambda i, j: "must be >= 0")
    dahl = np.asarray(friction == "dahl") if isinstance(friction, np.ndarray) else (friction == "dahl")
    if np.any(dahl):
        bad = dahl & ~(fields["dahl_sigma"] > 0)
        if bad.any():
            fail("dahl_sigma", bad, lambda i, j: "friction.model = \"dahl\" needs a stiffness > 0 [1/mm]")
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
                                       f"rad (m = {fields['m'][i, j]:.4g} from {origins['m'][i, j]})")


def load_patch_scene(source: str | Path | dict, overrides: list[str] = (), engine: str | None = None,
                     device: str | None = None) -> PatchScene:
    """Read, override (``--set``), validate and resolve a patch scene; nothing is solved.

    Raises
    ------
    KnitsimInputError
        The first problem, naming the key path and the value.
    """
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
    courses, wales = doc["patch"]["courses"], doc["patch"]["wales"]
    shape = (courses, wales)
    if courses * wales > 50_000_000:
        raise error("patch.wales", wales, f"{courses} x {wales} cells is more than 50 million")

    # base cell (the yarn / knit / friction / rules tables, as a cell scene)
    raw_base = {t: validate(PATCH_SCENE.fields[t], data.get(t, {}), t, fill_defaults=False) for t in _CELL_TABLES}
    merged = validate(_cell_table(True), _merge(raw_base, {}), "", fill_defaults=True)
    base_tables, _ = _resolve_cell(merged, _Origins(None, {}))
    rules = dict(base_tables["rules"])
    rules["friction"] = base_tables["friction"]["model"]
    # rules and effects per cell (a patch mixes materials: Coulomb and Dahl regions, rule sets, effects)
    rule_arr = {r: np.full(shape, rules[r], dtype=object) for r in RULE_NAMES}
    effects_arr = np.empty(shape, dtype=object)
    for idx in np.ndindex(shape):
        effects_arr[idx] = base_tables["_effects"]
    base = _cell_values(base_tables)
    fields = {n: np.full(shape, float(base[n])) for n in PARAM_NAMES}
    _BASE_PATHS = {"d": "yarn.d", "B": "yarn.B", "L": "knit.L", "W0": "knit.W0", "C0": "knit.C0",
                   "m": "friction.m", "phi0": "friction.phi0", "dahl_sigma": "friction.dahl_sigma",
                   "in_plane_width": "yarn.in_plane_width"}
    origins = {n: np.full(shape, _BASE_PATHS[n], dtype=object) for n in PARAM_NAMES}

    # zones: the base tables overridden per rectangle (library materials resolved as for a cell)
    zones_out = []
    for z, zone in enumerate(doc.get("zones", [])):
        zone_tables = ("yarn", "knit", "friction", "rules", "effects")
        raw_over = {t: validate(PATCH_SCENE.fields["zones"].item.fields[t], data["zones"][z].get(t, {}),
                                f"zones[{z}].{t}", fill_defaults=False) for t in zone_tables}
        zm = validate(_cell_table(True), _merge(raw_base, raw_over), f"zones[{z}]", fill_defaults=True)
        org = _ZoneOrigins(z, raw_over)
        ztables, _ = _resolve_cell(zm, org)
        ci = index_range(zone.get("courses", [0, courses]), courses, f"zones[{z}].courses", "courses")
        wi = index_range(zone.get("wales", [0, wales]), wales, f"zones[{z}].wales", "wales")
        zrules = dict(ztables["rules"], friction=ztables["friction"]["model"])
        for r in RULE_NAMES:
            rule_arr[r][ci, wi] = zrules[r]
        for idx in np.ndindex(effects_arr[ci, wi].shape):
            effects_arr[ci, wi][idx] = ztables["_effects"]
        vals = _cell_values(ztables)
        for n in PARAM_NAMES:
            fields[n][ci, wi] = vals[n]
            tbl = {"d": "yarn", "B": "yarn", "in_plane_width": "yarn", "L": "knit", "W0": "knit",
                   "C0": "knit"}.get(n, "friction")
            key = n
            origins[n][ci, wi] = (f"zones[{z}].{tbl}.{key}" if (key in raw_over.get(tbl, {}) or
                                                               "material" in raw_over.get(tbl, {}) or
                                                               (n == "m" and raw_over.get("friction")))
                                  else origins[n][ci, wi])
        zres = {k: zone[k] for k in ("label",) if k in zone}
        zres.update(courses=[ci.start, ci.stop], wales=[wi.start, wi.stop],
                    yarn=ztables["yarn"], knit=ztables["knit"],
                    friction={"model": ztables["friction"]["model"], "m": ztables["friction"]["m"],
                              "phi0": ztables["friction"]["phi0"], "dahl_sigma": ztables["friction"]["dahl_sigma"]},
                    rules=dict(ztables["rules"]))
        if "effects" in ztables:
            zres["effects"] = ztables["effects"]
        zones_out.append(zres)

    # maps, m first (a phi0 map may be scaled by phimax = atan(m))
    maps_in = {k: v for k, v in data.get("maps", {}).items()} if isinstance(data.get("maps"), dict) else {}
    maps_out = {}
    for n in sorted(maps_in, key=lambda k: (k != "m", PARAM_NAMES.index(k))):
        spec = doc["maps"][n]
        spec = {k: v for k, v in spec.items() if not (isinstance(v, dict) and not v)}
        if spec.get("type") == "random":
            spec.setdefault("seed", doc["seed"])
        if "regions" in spec:
            spec["regions"] = [{k: v for k, v in r.items()} for r in spec["regions"]]
        fields[n] = build_map(spec, shape, fields[n], f"maps.{n}", doc["seed"], base_dir,
                              phimax=np.arctan(fields["m"]), name=n)
        origins[n][:] = f"maps.{n}"
        maps_out[n] = spec
    _check_cells(fields, origins, rule_arr["friction"])
    if doc["engine"] == "reference" and any(e.on for e in effects_arr.ravel()):
        raise error("engine", doc["engine"], "the model extensions ([effects]) run on the warp engine only")
    model = PatchModel(courses, wales, fields, rule_arr, effects_arr)

    # the grip program; every column must be able to take the largest grip displacement (checked on the
    # load table's numbers, before the program is built)
    rest = fields["C0"].sum(axis=0)
    ref = float(rest[0]) if np.all(rest == rest[0]) else float(rest.mean())
    reach = (fields["L"] / 2.0 - fields["C0"]).sum(axis=0)   # straight yarn: C < L/2 in every cell
    j = int(np.argmin(reach))
    program, load_resolved = _program(doc["load"], [], limit_of=(
        float(reach[j] / ref), f"column {j} can stretch by at most {reach[j]:.4g} mm (C < L/2 in every cell), "
                               f"i.e. grip strain < {reach[j] / ref:.4g}"))

    resolved: dict[str, Any] = {}
    if "title" in doc:
        resolved["title"] = doc["title"]
    resolved.update(engine=doc["engine"], device=doc["device"], seed=doc["seed"], patch=doc["patch"],
                    yarn=base_tables["yarn"], knit=base_tables["knit"], friction=base_tables["friction"],
                    rules=base_tables["rules"], load=load_resolved, output=doc["output"], solver=doc["solver"])
    if "effects" in base_tables:
        resolved["effects"] = base_tables["effects"]
    if maps_out:
        resolved["maps"] = maps_out
    if zones_out:
        resolved["zones"] = zones_out
    return PatchScene(model, program, doc["engine"], doc["device"], bool(doc["patch"]["dedup"]), resolved,
                      origins, name)
