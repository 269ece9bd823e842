"""Cell scenes: one quarter-stitch cell, or a batch of them, through a load program.

A cell scene is a TOML file (see ``scenes/paper/``)::

    title = "E-glass plain knit, monotonic"
    engine = "warp"              # or "reference" (NumPy, one cell at a time)
    device = "cpu"               # cpu, cuda, cuda:N, auto
    materials = "lib.toml"       # optional: a material library file (knitsim.material_library),
                                 # whose yarns and knits the material keys may name

    [yarn]                       # library yarn, explicit keys override it
    material = "e_glass"         # d = 0.58 mm, B = 0.31 N mm^2 (Table 1)

    [knit]
    material = "e_glass_plain"   # L = 14.1, W0 = 4.4, C0 = 2.7 mm (section 2.2)

    [friction]
    model = "coulomb"            # or "dahl" (needs dahl_sigma [1/mm])
    m = 0.20                     # or mu_k + coiling_angle_deg (eq 10)
    phi0 = 0.0                   # [rad], or phi0_deg, or phi0_fraction (of phimax), or "phimax" / "-phimax"

    [rules]
    unloading_rule = "dusserre"  # or "hong_constant_t"
    force_cap_N = 10.0           # absent: 50 B / d^2 (the yarn's force scale)

    [load]
    type = "monotonic"           # or "cycles" / "piecewise"
    target_strain = 1.0
    max_increment = 0.005

    [[cells]]                    # optional: one entry per cell of a batch,
    label = "m = 0.4"            # each a partial override of the tables above
    friction = { m = 0.4 }

Every key is checked by :data:`CELL_SCENE` (:mod:`knitsim.scene.schema`);
cross-field conditions (``W0 >= 4 d``, ``L`` long enough to close a loop,
``|phi0| <= phimax``, a reachable load program) are checked here, before any
solve, with messages naming the key path: ``cells[2].knit.W0 = 2.0: must be
>= 4 d = 2.32 mm``.

Friction ratio ``m``: ``friction.m`` if given; else eq 10
(:func:`knitsim.friction.coiling.m_eq10`) from ``friction.mu_k`` and
``friction.coiling_angle_deg`` (default: the yarn material's mean coiling
angle, section 3.4); else the yarn material's ``m`` (section 3.4).
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .. import materials
from ..cell.load_program import LoadProgram, cycles, monotonic, piecewise_linear
from ..cell.material import CellParams
from ..cell.stages import (DAHL_SIGMA_MAX, DAHL_SIGMA_TOO_STIFF, DAHL_SIGMA_UNUSED, FRICTION_MODELS, JAMMING_CRITERIA,
                           M_MAX, M_TOO_LARGE, RELOAD_RULES, UNLOADING_RULES)
from ..errors import KnitsimInputError
from ..friction.coiling import m_eq10
from .schema import OPTIONAL, REQUIRED, Field, Table, TableArray, dumps, error, fmt, load_toml, set_value, validate

ENGINES = ("warp", "reference")
LOAD_TYPES = ("monotonic", "cycles", "piecewise")


def degrees_hint(phi0: float) -> str:
    """A friction angle beyond pi/2 rad cannot be one (phimax = atan(m) < pi/2): said to look like degrees."""
    if not (isinstance(phi0, (int, float)) and abs(phi0) > math.pi / 2):
        return ""
    return (f"; {phi0:g} looks like degrees: phi0 is in radians ({phi0:g} deg = {math.radians(phi0):.4g} rad; "
            "friction.phi0_deg takes degrees)")


def _device_check(v: str) -> str | None:
    if v in ("cpu", "cuda", "auto") or (v.startswith("cuda:") and v[5:].isdigit()):
        return None
    return "expected cpu, cuda, cuda:N or auto"


def _pos(doc, unit, default=OPTIONAL):
    return Field(("float",), default, doc, unit, min=0.0, min_inclusive=False)


def _yarn_table() -> Table:
    return Table({
        "material": Field(("str",), OPTIONAL, f"library yarn, one of {', '.join(materials.yarn_names())}"),
        "d": _pos("yarn diameter (Table 1); jamming at W = 4 d", "mm"),
        "B": _pos("bending stiffness (Table 1)", "N mm^2"),
        "in_plane_width": _pos("width that jams loops in the plane of the knit (a flattened roving); "
                               "jamming at W = 4 in_plane_width (default: d)", "mm"),
    }, "the yarn: a library material and/or explicit d, B, in_plane_width")


def _knit_table() -> Table:
    return Table({
        "material": Field(("str",), OPTIONAL, f"library knit, one of {', '.join(materials.knit_names())}"),
        "L": _pos("yarn length per stitch (section 2.2)", "mm"),
        "W0": _pos("wale width at rest (section 2.2)", "mm"),
        "C0": _pos("course length at rest (section 2.2)", "mm"),
    }, "the knit geometry at rest: a library knit and/or explicit L, W0, C0")


def _coiling_in_degrees(v) -> str | None:
    """A coiling angle up to 2 pi reads as radians given in degrees (a blind probe's 1.9 ran as 1.9 deg, m
    0.002); a knit's crossing coils 90-180 deg (110 deg in Dusserre 2015, section 3.4)."""
    if isinstance(v, (int, float)) and 0 < v <= 2 * math.pi:
        return (f"a coiling angle of {v:g} deg is no knit crossing's (90-180 deg; 110 deg in section 3.4): the "
                f"field is in degrees ({v:g} rad = {math.degrees(v):.4g} deg)")
    return None


#: keys of the friction table that state one quantity in different ways: a cell or an override (``--set``, a
#: sweep's sample) that sets one drops the others the scene said
FRICTION_ALTERNATIVES = ((("m",), ("mu_k", "coiling_angle_deg")),
                         (("phi0",), ("phi0_deg",), ("phi0_fraction",)))
#: the keys that state a cell's initial friction angle
PHI0_KEYS = tuple(k for g in FRICTION_ALTERNATIVES[1] for k in g)


def _friction_table(defaults: bool) -> Table:
    d = (lambda v: v) if defaults else (lambda v: OPTIONAL)
    return Table({
        "model": Field(("str",), d("coulomb"), "friction at the crossing", choices=FRICTION_MODELS),
        "m": Field(("float",), OPTIONAL, "apparent ratio Rt/Rn = tan(phimax) (eq 10)", min=0.0),
        "mu_k": Field(("float",), OPTIONAL, "kinetic friction coefficient, with coiling_angle_deg gives m by eq 10",
                      min=0.0),
        "coiling_angle_deg": Field(("float",), OPTIONAL, "coiling angle at the crossing for eq 10", "deg",
                                   min=0.0, max=180.0, min_inclusive=False, max_inclusive=False,
                                   check=_coiling_in_degrees),
        "phi0": Field(("float", "str"), OPTIONAL, 'initial friction angle [rad], or "phimax" / "-phimax"', "rad",
                      check=lambda v: None if not isinstance(v, str) or v in ("phimax", "-phimax")
                      else 'expected a number [rad], "phimax" or "-phimax"'),
        "phi0_deg": Field(("float",), OPTIONAL, "initial friction angle in degrees", "deg"),
        "phi0_fraction": Field(("float",), OPTIONAL, "initial friction angle as a fraction of phimax = atan(m)",
                               min=-1.0, max=1.0),
        "dahl_sigma": Field(("float",), d(0.0), "Dahl stiffness of tan(phi) per unit slip (model = dahl)",
                            "1/mm", min=0.0),
    }, "friction at the loop crossing (section 3.3)", alternatives=FRICTION_ALTERNATIVES)


def _rules_table(defaults: bool) -> Table:
    d = (lambda v: v) if defaults else (lambda v: OPTIONAL)
    return Table({
        "unloading_rule": Field(("str",), d("dusserre"), "SF- step: freeze beta (Table 4) or T (Hong)",
                                choices=UNLOADING_RULES),
        "reload_rule": Field(("str",), d("mirror_unloading"), "reloading from zero contact force",
                             choices=RELOAD_RULES),
        "jamming_criterion": Field(("str",), d("w_4d"), "W = 4 d (Hong) or head-to-head distance d",
                                   choices=JAMMING_CRITERIA),
        # absent: the cell's own default, 50 B / d^2 (knitsim.cell.material.default_force_cap_N)
        "force_cap_N": Field(("float",), OPTIONAL, "force per wale at which a cell stops (jammed branch); "
                             "default 50 B / d^2, the yarn's own force scale", "N",
                             min=0.0, min_inclusive=False),
    }, "rules where Table 4 is silent (knitsim.cell.stages)")


def _effects_table() -> Table:
    """The model extensions of a material (knitsim.cell.effects), off unless listed in ``on``."""
    from ..cell.effects import EFFECT_NAMES, PARAM_COLUMNS
    fields = {"on": Field(("str_list",), OPTIONAL, "effects switched on (dahl_transition: friction.model = dahl)",
                          choices=EFFECT_NAMES)}
    for c in PARAM_COLUMNS:
        fields[c] = Field(("float",), OPTIONAL, f"parameter {c} of its effect (knitsim.cell.effects.EffectSet)")
    return Table(fields, "model extensions (knitsim.cell.effects): off by default")


#: the keys each load.type takes (an override of load.type drops the others': Table.variants)
LOAD_KEYS = {"monotonic": ("target_strain",), "cycles": ("lower_strain", "upper_strain", "cycles"),
             "piecewise": ("waypoints",)}


def _load_table() -> Table:
    return Table({
        "type": Field(("str",), REQUIRED, "monotonic, cycles or piecewise", choices=LOAD_TYPES),
        "target_strain": Field(("float",), OPTIONAL, "monotonic: final change in length (C - C0)/C0",
                               min=0.0, min_inclusive=False),
        "lower_strain": Field(("float",), OPTIONAL, "cycles: strain at the end of each unloading", min=0.0),
        "upper_strain": Field(("float",), OPTIONAL, "cycles: strain at the end of each loading",
                              min=0.0, min_inclusive=False),
        "cycles": Field(("int",), OPTIONAL, "cycles: number of load-unload cycles", min=1),
        "waypoints": Field(("float_list",), OPTIONAL, "piecewise: strains to pass through, from rest"),
        "max_increment": Field(("float",), 0.005, "largest strain increment (at most 0.1: a row every 10 % of "
                               "strain cannot show a cycle's stages)", min=0.0, min_inclusive=False, max=0.1),
    }, "strain-controlled load program of the course length", required=True, variants=("type", LOAD_KEYS))


def _cell_table(defaults: bool) -> Table:
    return Table({
        "label": Field(("str",), OPTIONAL, "name of the cell in outputs"),
        "yarn": _yarn_table(),
        "knit": _knit_table(),
        "friction": _friction_table(defaults),
        "rules": _rules_table(defaults),
        "effects": _effects_table(),
    })


def _provenance_table() -> Table:
    return Table({
        "source": Field(("str",), OPTIONAL, "what wrote the scene (knitsim calibrate FILE)"),
        "flags": Field(("str_list",), OPTIONAL, "why that calibration is not one to use: every result says so"),
    }, "where the scene's values come from (knitsim calibrate writes it)")


def _materials_field() -> Field:
    return Field(("str",), OPTIONAL, "material library file (knitsim calibrate writes one), relative to the scene; "
                 "its yarns and knits can be named by yarn.material / knit.material")


def library_of(data: dict, base_dir: Path):
    """The material library a scene names (``materials = FILE``), or None."""
    from ..material_library import load_library
    path = data.get("materials")
    if path is None:
        return None
    if not isinstance(path, str):
        raise error("materials", path, "expected the path of a material library file (a string)")
    f = Path(path)
    if not f.is_absolute():
        f = base_dir / f
    if not f.is_file():
        raise error("materials", path, f"no such material library file ({f})")
    return load_library(f)


#: the schema of a cell scene file
CELL_SCENE = Table({
    "title": Field(("str",), OPTIONAL, "free text"),
    "provenance": _provenance_table(),
    "materials": _materials_field(),
    "engine": Field(("str",), "warp", "warp (batched kernels) or reference (NumPy)", choices=ENGINES),
    "device": Field(("str",), "cpu", "Warp device", check=_device_check),
    "yarn": _yarn_table(),
    "knit": _knit_table(),
    "friction": _friction_table(True),
    "rules": _rules_table(True),
    "effects": _effects_table(),
    "load": _load_table(),
    "output": Table({"plot": Field(("bool",), True, "write plot.png")}, "what to write"),
    "cells": TableArray(_cell_table(False), "cells of a batch, each overriding the tables above", min_items=1),
})

_CELL_TABLES = ("yarn", "knit", "friction", "rules", "effects")


@dataclass
class CellScene:
    """A validated cell scene, ready to run.

    Attributes
    ----------
    params : list of CellParams
        One per cell (validated).
    labels : list of str
        Cell names for outputs.
    program : LoadProgram
        The sampled strain history (shared by every cell).
    engine, device : str
        ``"warp"`` or ``"reference"``; the Warp device name (not yet resolved).
    resolved : dict
        The scene with every default filled and every cell spelled out; a
        valid scene itself (:meth:`to_toml`).
    notes : list of dict
        Per cell, where ``m`` and ``phi0`` came from (for summaries).
    source : str
        The scene file, or ``"<dict>"``.
    calibration_flags : list of (str, tuple)
        What the scene's values come from that a flagged calibration wrote, and its flags
        (:func:`knitsim.material_library.flagged_materials`): said with every result.
    """

    params: list
    labels: list
    program: LoadProgram
    engine: str
    device: str
    resolved: dict
    notes: list
    source: str = "<dict>"
    calibration_flags: list = field(default_factory=list)

    @property
    def plot(self) -> bool:
        """Whether to write plot.png (``[output] plot``)."""
        return bool(self.resolved["output"]["plot"])

    def to_toml(self) -> str:
        """The resolved scene as TOML (loads back to the same cells)."""
        return dumps(self.resolved, header=f"knitsim cell scene, resolved from {self.source}\n"
                                           "every default filled in; units N, mm, rad (degrees only in *_deg)")


def _merge(base: dict, over: dict) -> dict:
    """Merge one cell's partial override into the base tables, key by key."""
    out = copy.deepcopy({t: base.get(t, {}) for t in _CELL_TABLES})
    for t in _CELL_TABLES:
        o = over.get(t, {})
        if t == "friction":
            # a cell that states a quantity one way drops the base's other ways (FRICTION_ALTERNATIVES)
            for key in o:
                for other in CELL_SCENE.fields["friction"].others_than(key):
                    out[t].pop(other, None)
        out[t].update(o)
    return out


def cells_stating(doc: dict, key: str) -> dict[int, str]:
    """The cells of ``doc``'s ``[[cells]]`` that state the base tables' key path ``key`` (``friction.m``)
    themselves, by that key or another way of its quantity (``friction.mu_k``): cell index -> the key.  Their own
    value replaces the base's (:func:`_merge`), so a value given to the base key (``--set friction.m=0.3``, a sweep's
    axis) does not reach them.  Empty for a key of no cell table, or one that indexes a cell (``cells[1]...``)."""
    table, _, name = key.partition(".")
    if table not in _CELL_TABLES or not name or "." in name:
        return {}
    same = (name,) + CELL_SCENE.fields[table].others_than(name)
    own: dict[int, str] = {}
    for i, cell in enumerate(doc.get("cells") or []):
        sub = cell.get(table) if isinstance(cell, dict) else None
        for k in same:
            if isinstance(sub, dict) and k in sub:
                own.setdefault(i, k)
    return own


class _Origins:
    """Key paths of the values of one cell, for messages."""

    def __init__(self, index: int | None, over: dict, library: dict | None = None):
        # library: (table, key) -> the library entry that gave the value (material_library.expand's ``filled``)
        self.index, self.over, self.library = index, over, library or {}

    def path(self, table: str, key: str) -> str:
        if self.index is not None and key in self.over.get(table, {}):
            return f"cells[{self.index}].{table}.{key}"
        return f"{table}.{key}" + self.from_library(table, key)

    def from_library(self, table: str, key: str) -> str:
        """`` (from knits.NAME of FILE)`` where a material library gave the value, else ``""``."""
        src = self.library.get((table, key))
        return f" (from {src})" if src else ""

    def where(self) -> str:
        return f" (in cells[{self.index}])" if self.index is not None else ""


def _resolve_cell(cell: dict, org: _Origins) -> tuple[dict, dict]:
    """Fill a merged cell from the library and check it; returns (resolved tables, notes)."""
    y, k, f, r = cell["yarn"], cell["knit"], cell["friction"], cell["rules"]
    notes: dict = {}
    ylib = materials.yarn(y["material"], org.path("yarn", "material")) if "material" in y else None
    klib = materials.knit(k["material"], org.path("knit", "material")) if "material" in k else None

    def take(table, key, lib, name):
        src = cell[table]
        if key in src:
            return src[key]
        if lib is not None:
            return getattr(lib, key)
        raise KnitsimInputError(f"{org.path(table, key)}: missing{org.where()} (give {table}.{key} or "
                                f"{table}.material = one of {', '.join(name())})")

    d = take("yarn", "d", ylib, materials.yarn_names)
    B = take("yarn", "B", ylib, materials.yarn_names)
    L = take("knit", "L", klib, materials.knit_names)
    W0 = take("knit", "W0", klib, materials.knit_names)
    C0 = take("knit", "C0", klib, materials.knit_names)

    # geometry (section 3.1): W >= 4 d (Hong), and a loop needs L > 2 C0 + W0 - 4 d
    if W0 < 4.0 * d:
        raise error(org.path("knit", "W0"), W0,
                    f"must be >= 4 d = {4.0 * d:.4g} mm ({org.path('yarn', 'd')} = {fmt(d)}; loops jammed already)"
                    + org.where())
    lmin = 2.0 * C0 + W0 - 4.0 * d
    if L <= lmin:
        raise error(org.path("knit", "L"), L,
                    f"too short to close a loop: needs > 2 C0 + W0 - 4 d = {lmin:.4g} mm" + org.where())

    # in-plane width (README "The yarn's in-plane width"): the compact d up to W0/4
    w = y.get("in_plane_width")
    if w is not None:
        if w < d:
            raise error(org.path("yarn", "in_plane_width"), w,
                        f"the in-plane width cannot be below the compact diameter d = {fmt(d)} mm" + org.where())
        if W0 < 4.0 * w:
            raise error(org.path("yarn", "in_plane_width"), w,
                        f"loops jammed at rest: needs 4 in_plane_width <= W0 = {fmt(W0)} mm" + org.where())

    # friction ratio m: explicit, eq 10, or the library yarn's (section 3.4)
    if "m" in f and ("mu_k" in f or "coiling_angle_deg" in f):
        other = "mu_k" if "mu_k" in f else "coiling_angle_deg"
        raise error(org.path("friction", other), f[other], "give either friction.m or friction.mu_k "
                    "(+ coiling_angle_deg), not both" + org.where())
    if "m" in f:
        m = f["m"]
        notes["m_source"] = "friction.m"
    elif "mu_k" in f:
        if "coiling_angle_deg" in f:
            theta_deg = f["coiling_angle_deg"]
        elif ylib is not None:
            theta_deg = ylib.coiling_angle_deg
        else:
            raise KnitsimInputError(f"{org.path('friction', 'coiling_angle_deg')}: missing{org.where()} "
                                    "(eq 10 needs the coiling angle with friction.mu_k)")
        m = float(m_eq10(math.radians(theta_deg), f["mu_k"]))
        notes["m_source"] = f"eq 10: mu_k = {f['mu_k']:g}, coiling angle = {theta_deg:g} deg"
    elif "coiling_angle_deg" in f:
        raise error(org.path("friction", "coiling_angle_deg"), f["coiling_angle_deg"],
                    "needs friction.mu_k (eq 10)" + org.where())
    elif ylib is not None:
        m = ylib.m
        notes["m_source"] = f"yarn {ylib.name}: m = {ylib.m:g} (section 3.4)"
    else:
        raise KnitsimInputError(f"{org.path('friction', 'm')}: missing{org.where()} (give friction.m, "
                                "friction.mu_k with coiling_angle_deg, or yarn.material)")
    if m > M_MAX:
        # named by the key that set it (before, the engines' backstop named "cell.m", in no file: a blind probe)
        if "m" in f:
            raise error(org.path("friction", "m"), m, M_TOO_LARGE + org.where())
        raise error(org.path("friction", "mu_k"), f["mu_k"], f"eq 10 gives m = {m:.4g} ({notes['m_source']}): "
                    + M_TOO_LARGE + org.where())
    phimax = math.atan(m)

    given = [k for k in PHI0_KEYS if k in f]
    if len(given) > 1:
        raise error(org.path("friction", given[1]), f[given[1]],
                    f"give one of friction.phi0, phi0_deg and phi0_fraction, not {' and '.join(given)}"
                    + org.where())
    if "phi0_deg" in f:
        phi0, phi_path, phi_val = math.radians(f["phi0_deg"]), org.path("friction", "phi0_deg"), f["phi0_deg"]
    elif "phi0_fraction" in f:
        # within [-1, 1] by the schema, so within the cone whatever m is (a sweep over m and phi0 together)
        phi_val, phi_path = f["phi0_fraction"], org.path("friction", "phi0_fraction")
        phi0 = phi_val * phimax
    else:
        phi_val = f.get("phi0", 0.0)
        phi_path = org.path("friction", "phi0")
        phi0 = {"phimax": phimax, "-phimax": -phimax}.get(phi_val, phi_val) if isinstance(phi_val, str) else phi_val
    if abs(phi0) > phimax + 1e-12:
        raise error(phi_path, phi_val, f"must lie in [-phimax, phimax] = [{-phimax:.4g}, {phimax:.4g}] rad "
                    f"(= +/-{math.degrees(phimax):.4g} deg, m = {m:.4g})"
                    + (degrees_hint(phi0) if "phi0_deg" not in f else "") + org.where())
    phi0 = max(-phimax, min(phimax, phi0))
    notes["phi0_source"] = f"{phi_path} = {fmt(phi_val)}"

    model = f["model"]
    sigma = f["dahl_sigma"]
    effects, model = _resolve_effects(cell.get("effects", {}), model, org)
    if model == "dahl" and sigma <= 0:
        raise error(org.path("friction", "dahl_sigma"), sigma,
                    "friction.model = \"dahl\" needs a stiffness > 0 [1/mm]" + org.where())
    if model == "dahl" and sigma > DAHL_SIGMA_MAX:
        raise error(org.path("friction", "dahl_sigma"), sigma, DAHL_SIGMA_TOO_STIFF + org.where())
    if model == "coulomb" and sigma != 0:
        raise error(org.path("friction", "dahl_sigma"), sigma, DAHL_SIGMA_UNUSED + org.where())
    if model == "dahl" and not m > 0:
        # named by the key that set it (before, the batch's backstop named "cells[0].m", in no file: a probe's
        # friction.m = 0 with friction.model = "dahl"), as the patch scene names it
        key = "m" if "m" in f else "mu_k" if "mu_k" in f else None
        raise error(org.path("friction", key) if key else org.path("yarn", "material"),
                    f[key] if key else y.get("material"), "Dahl friction needs m > 0 (saturation tan(phi) = m)"
                    + org.where())

    out = {
        "yarn": dict(({"material": y["material"]} if "material" in y else {}), d=d, B=B,
                     **({"in_plane_width": w} if w is not None else {})),
        "knit": dict(({"material": k["material"]} if "material" in k else {}), L=L, W0=W0, C0=C0),
        "friction": {"model": model, "m": m, "phi0": phi0, "dahl_sigma": sigma},
        "rules": dict(r),
    }
    if effects.on:
        out["effects"] = effects.as_dict()
    out["_effects"] = effects
    return out, notes


def _resolve_effects(table: dict, model: str, org) -> tuple:
    """The EffectSet of a cell's ``[effects]`` table; ``dahl_transition`` there is friction.model = "dahl"."""
    from ..cell.effects import EffectSet
    t = dict(table or {})
    on = [e for e in t.pop("on", [])]
    if "dahl_transition" in on:
        on.remove("dahl_transition")
        model = "dahl"
    try:
        eff = EffectSet(on=tuple(on), **t).validated(where=org.path("effects", "").rstrip("."))
    except TypeError as exc:  # pragma: no cover - the schema admits only EffectSet fields
        raise KnitsimInputError(f"effects: {exc}") from None
    return eff, model




def _corners(load: dict) -> tuple[list, str]:
    """The strains a program passes through (from rest; each cycle's two once) and the key of its largest strain."""
    kind = load["type"]
    if kind == "monotonic":
        return [0.0, load["target_strain"]], "load.target_strain"
    if kind == "cycles":
        # (not listed per cycle: load.cycles = 10^9 listed 2 x 10^9 strains here, 22 GB, before the increments' check)
        return [0.0, load["upper_strain"], load["lower_strain"]], "load.upper_strain"
    return [0.0] + list(load["waypoints"]), "load.waypoints"


def _program(load: dict, cells: list[dict], limit_of=None) -> tuple[LoadProgram, dict]:
    """Check the load table, then build its program.

    Every limit is checked on the table's numbers before anything is built (a strain of 1e308 or
    1e6 is refused, not an overflow or an out-of-memory): the strain the cells can reach (C < L/2,
    a straight yarn); the number of increments (:data:`knitsim.cell.load_program.MAX_INCREMENTS`) by the
    program's constructor, before it allocates anything.  ``limit_of`` overrides the reach: ``(largest strain, message suffix)`` (a patch's columns).
    """
    kind = load["type"]
    for key in ("target_strain", "lower_strain", "upper_strain", "cycles", "waypoints"):
        if key in load and key not in LOAD_KEYS[kind]:
            raise error(f"load.{key}", load[key], f"not used by load.type = {fmt(kind)} "
                        f"(it takes {', '.join('load.' + k for k in LOAD_KEYS[kind])})")
    for key in LOAD_KEYS[kind]:
        if key not in load:
            raise KnitsimInputError(f"load.{key}: missing (load.type = {fmt(kind)} needs it)")
    inc = load["max_increment"]
    if kind == "cycles" and load["lower_strain"] >= load["upper_strain"]:
        raise error("load.lower_strain", load["lower_strain"],
                    f"must be < load.upper_strain = {fmt(load['upper_strain'])}")
    if kind == "cycles" and load["upper_strain"] - load["lower_strain"] < 2.0 * inc * (1.0 - 1e-12):
        # a branch of one increment: each cycle two rows, a line there and back, its hysteresis 0 by construction
        raise error("load.max_increment", inc, f"the branches between load.lower_strain = {fmt(load['lower_strain'])} "
                    f"and load.upper_strain = {fmt(load['upper_strain'])} would be one increment each (a cycle of two "
                    f"rows, no loop to measure); use at most {(load['upper_strain'] - load['lower_strain']) / 2:.4g}")
    if kind == "piecewise" and not load["waypoints"]:
        raise error("load.waypoints", load["waypoints"], "needs at least one strain")
    corners, top_key = _corners(load)
    top = float(max(corners))
    # reachability: a quarter stitch of length L/4 spans C/2, so C < L/2 (straight yarn)
    for i, c in enumerate(cells):
        limit = c["knit"]["L"] / (2.0 * c["knit"]["C0"]) - 1.0
        if top >= limit:
            where = f" for cells[{i}]" if len(cells) > 1 else ""
            raise KnitsimInputError(
                f"{top_key} = {fmt(load[top_key.split('.')[1]])}: strain {top:g} cannot be reached{where}: "
                f"C = C0 (1 + strain) must stay below L/2 = {c['knit']['L'] / 2:.4g} mm (straight yarn), "
                f"i.e. strain < {limit:.4g}")
    if limit_of is not None and top >= limit_of[0]:
        raise KnitsimInputError(f"{top_key} = {fmt(load[top_key.split('.')[1]])}: grip strain {top:g} cannot be "
                                f"reached: {limit_of[1]}")
    # (a program longer than MAX_INCREMENTS is refused by its constructor, naming what set its length)
    if kind == "monotonic":
        prog = monotonic(load["target_strain"], inc)
    elif kind == "cycles":
        prog = cycles(load["lower_strain"], load["upper_strain"], load["cycles"], inc)
    else:
        prog = piecewise_linear(load["waypoints"], inc)
    resolved = {"type": kind, **{k: load[k] for k in LOAD_KEYS[kind]}, "max_increment": inc}
    return prog, resolved


def load_cell_scene(source: str | Path | dict, overrides: list[str] = (),
                    engine: str | None = None, device: str | None = None) -> CellScene:
    """Read, override, validate and resolve a cell scene.

    Parameters
    ----------
    source : path or dict
        A TOML file, or an already-parsed document.
    overrides : list of str
        ``key.path=value`` assignments (``--set``), applied before validation
        and type-checked by the schema.
    engine, device : str, optional
        Command-line choices that replace the scene's.

    Returns
    -------
    CellScene

    Raises
    ------
    KnitsimInputError
        The first problem found, naming the key path and the value; nothing
        has been solved or written.
    """
    if isinstance(source, dict):
        data, name, base_dir = copy.deepcopy(source), "<dict>", Path(".")
    else:
        data, name, base_dir = load_toml(source), str(source), Path(source).resolve().parent
    for a in overrides:
        set_value(data, CELL_SCENE, a)
    if engine is not None:
        data["engine"] = engine
    if device is not None:
        data["device"] = device
    # the base tables are merged with each cell's override before defaults are filled
    base = validate(CELL_SCENE, {k: v for k, v in data.items() if k != "cells"}, fill_defaults=True)
    from ..material_library import expand
    lib = library_of(data, base_dir)
    raw_base = {t: validate(CELL_SCENE.fields[t], data.get(t, {}), t, fill_defaults=False) for t in _CELL_TABLES}
    cells_in = data.get("cells")
    if cells_in is not None:
        cells_over = validate(Table({"cells": CELL_SCENE.fields["cells"]}), {"cells": cells_in})["cells"]
    else:
        cells_over = [None]
    cell_defaults = _cell_table(True)
    resolved_cells, params, labels, notes = [], [], [], []
    for i, over in enumerate(cells_over):
        index = None if over is None else i
        where = "" if index is None else f"cells[{i}]"
        filled: dict = {}
        merged = expand(_merge(raw_base, over or {}), lib, where, filled)
        merged = validate(cell_defaults, merged, where, fill_defaults=True)
        org = _Origins(index, over or {}, filled)
        tables, note = _resolve_cell(merged, org)
        label = (over or {}).get("label") or (base.get("title") if over is None else None) or f"cell {i}"
        p = CellParams(B=tables["yarn"]["B"], d=tables["yarn"]["d"], L=tables["knit"]["L"],
                       W0=tables["knit"]["W0"], C0=tables["knit"]["C0"], m=tables["friction"]["m"],
                       phi0=tables["friction"]["phi0"], friction=tables["friction"]["model"],
                       dahl_sigma=tables["friction"]["dahl_sigma"],
                       in_plane_width=tables["yarn"].get("in_plane_width"), effects=tables.pop("_effects"),
                       **tables["rules"])
        p.validated(where or "cell")   # backstop: the same checks as the engines
        params.append(p)
        if label in labels:
            raise error(f"cells[{i}].label", label, f"the label of cells[{labels.index(label)}] too: outputs name "
                        "cells by label, so each needs its own")
        labels.append(label)
        notes.append(note)
        resolved_cells.append({"label": label, **tables})
    program, load_resolved = _program(base["load"], resolved_cells)
    resolved: dict[str, Any] = {}
    if "title" in base:
        resolved["title"] = base["title"]
    resolved.update(engine=base["engine"], device=base["device"], output=base["output"], load=load_resolved,
                    cells=resolved_cells)
    from ..material_library import flagged_materials
    return CellScene(params, labels, program, base["engine"], base["device"], resolved, notes, name,
                     flagged_materials(data, lib))
