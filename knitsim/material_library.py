"""Material library files: calibrated yarns and the knits made of them, by name (TOML).

``knitsim calibrate`` writes one (:mod:`knitsim.calibration`); a cell or patch
scene reads it with a top-level ``materials = "FILE.toml"`` (relative to the
scene) and then names its yarns and knits like the built-in ones of
:mod:`knitsim.materials`::

    [yarns.do2020_yarn]                 # a yarn: everything that is the yarn's own
    d = 0.25                            # [mm] compact diameter (bending, crossing geometry)
    B = 0.0031                          # [N mm^2]
    in_plane_width = 0.28               # [mm] jamming width (optional: d)
    source = "knitsim calibrate scenes/calibration/do2020/calibrate.toml"
    [yarns.do2020_yarn.friction]        # the friction law at the crossing
    model = "coulomb"                   # or "dahl" (with dahl_sigma [1/mm])
    m = 0.31
    [yarns.do2020_yarn.rules]           # rules where Table 4 is silent (optional)
    unloading_rule = "dusserre"
    [yarns.do2020_yarn.effects]         # model extensions (optional), as a scene's [effects]
    on = ["yarn_compaction"]
    compaction_k = 12.0
    [yarns.do2020_yarn.std_errors]      # informative: not read by the simulation
    B = 0.0002

    [knits.jersey_4p5]                  # a knit: the yarn it is made of and its geometry at rest
    yarn = "do2020_yarn"
    L = 4.5                             # [mm]
    W0 = 1.20                           # [mm]
    C0 = 0.88                           # [mm]
    phi0 = 0.05                         # [rad] initial friction angle of the knit as made

A scene's ``knit.material = "jersey_4p5"`` gives the cell its L, W0, C0 and
phi0 and, unless the scene names or spells out a yarn, the knit's yarn; a
``yarn.material`` from the file gives d, B, the in-plane width, the friction
law, the rules and the effects.  Keys the scene states itself win.  Units N,
mm, rad (degrees only in ``*_deg`` keys).  Every error names the file and the
key path.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from .errors import KnitsimInputError

#: keys of a yarn entry and of a knit entry (besides its sub-tables)
YARN_KEYS = ("d", "B", "in_plane_width", "source", "flags")
YARN_TABLES = ("friction", "rules", "effects", "std_errors")
KNIT_KEYS = ("yarn", "L", "W0", "C0", "phi0", "source", "flags")
KNIT_OPTIONAL = ("phi0", "source", "flags")


@dataclass(frozen=True)
class LibraryYarn:
    """A yarn of a library file.

    Attributes
    ----------
    name : str
    d, B : float
        Compact diameter [mm] and bending stiffness [N mm^2].
    in_plane_width : float or None
        Jamming width in the plane of the knit [mm] (None: d).
    friction : dict
        ``model``, ``m`` and ``dahl_sigma`` [1/mm] (a scene's ``[friction]`` keys).
    rules : dict
        A scene's ``[rules]`` keys.
    effects : dict
        A scene's ``[effects]`` keys (empty: none).
    std_errors : dict
        Standard errors of the calibrated values (informative).
    source : str
    """

    name: str
    d: float
    B: float
    in_plane_width: float | None = None
    friction: dict = field(default_factory=dict)
    rules: dict = field(default_factory=dict)
    effects: dict = field(default_factory=dict)
    std_errors: dict = field(default_factory=dict)
    source: str = ""
    #: why the calibration that wrote it is not one to use (empty: usable, or not a calibration)
    flags: tuple = ()


@dataclass(frozen=True)
class LibraryKnit:
    """A knit of a library file: its yarn and geometry at rest (L, W0, C0 [mm], phi0 [rad] or None)."""

    name: str
    yarn: str
    L: float
    W0: float
    C0: float
    phi0: float | None = None
    source: str = ""
    #: why the calibration that wrote it is not one to use (empty: usable, or not a calibration)
    flags: tuple = ()


@dataclass(frozen=True)
class MaterialLibrary:
    """The yarns and knits of one library file."""

    path: str
    yarns: dict
    knits: dict

    def yarn(self, name: str, key: str) -> LibraryYarn:
        """The yarn ``name``; an unknown name raises :class:`KnitsimInputError` naming ``key``."""
        if name not in self.yarns:
            raise KnitsimInputError(f"{key} = {name!r}: not a yarn of {self.path} (its yarns: "
                                    f"{', '.join(sorted(self.yarns)) or 'none'})")
        return self.yarns[name]

    def knit(self, name: str, key: str) -> LibraryKnit:
        """The knit ``name``; an unknown name raises :class:`KnitsimInputError` naming ``key``."""
        if name not in self.knits:
            raise KnitsimInputError(f"{key} = {name!r}: not a knit of {self.path} (its knits: "
                                    f"{', '.join(sorted(self.knits)) or 'none'})")
        return self.knits[name]


def _number(path: str, key: str, v, positive: bool = True) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
        raise KnitsimInputError(f"{path}: {key} = {v!r}: expected a finite number")
    if positive and not float(v) > 0:
        raise KnitsimInputError(f"{path}: {key} = {v!r}: must be > 0")
    return float(v)


def _check_yarn_law(path: str, where: str, y: dict) -> None:
    """The values of a yarn's friction and rules that need no scene to judge: the law and rule names, m,
    dahl_sigma and the force cap (a blind probe's ``model = "coloumb"`` in a library yarn was reported as the
    scene's ``zones[0].friction.model``, in no file the user wrote it in).  What combines with the scene
    (a missing m the scene may give, the knit's phi0 within atan m) stays the scene's check."""
    from .cell.stages import (DAHL_SIGMA_MAX, DAHL_SIGMA_TOO_STIFF, FRICTION_MODELS, JAMMING_CRITERIA, M_MAX,
                              M_TOO_LARGE, RELOAD_RULES, UNLOADING_RULES)
    f, r = y.get("friction", {}), y.get("rules", {})
    for table, key, choices in (("friction", "model", FRICTION_MODELS), ("rules", "unloading_rule", UNLOADING_RULES),
                                ("rules", "reload_rule", RELOAD_RULES), ("rules", "jamming_criterion", JAMMING_CRITERIA)):
        v = y.get(table, {}).get(key)
        if v is not None and v not in choices:
            raise KnitsimInputError(f"{path}: {where}.{table}.{key} = {v!r}: expected one of {', '.join(choices)}")
    if "m" in f and _number(path, f"{where}.friction.m", f["m"], positive=False) < 0:
        raise KnitsimInputError(f"{path}: {where}.friction.m = {f['m']!r}: the friction ratio must be >= 0")
    if "m" in f and f["m"] > M_MAX:
        raise KnitsimInputError(f"{path}: {where}.friction.m = {f['m']!r}: {M_TOO_LARGE}")
    if f.get("model") == "dahl":
        sigma = _number(path, f"{where}.friction.dahl_sigma", f.get("dahl_sigma", 0.0), positive=False)
        if not sigma > 0:
            raise KnitsimInputError(f"{path}: {where}.friction.dahl_sigma = {f.get('dahl_sigma', 0.0)!r}: "
                                    "friction.model = \"dahl\" needs a stiffness > 0 [1/mm]")
        if sigma > DAHL_SIGMA_MAX:
            raise KnitsimInputError(f"{path}: {where}.friction.dahl_sigma = {sigma!r}: {DAHL_SIGMA_TOO_STIFF}")
    if "force_cap_N" in r:
        _number(path, f"{where}.rules.force_cap_N", r["force_cap_N"])


def _check_yarn_tables(path: str, where: str, y: dict) -> None:
    """A yarn's ``friction``, ``rules`` and ``effects`` tables against the scene's tables of those names (the
    keys they may hold and their types): the library fills a scene's tables from them, whose checks then named
    the scene's key (a blind probe's ``mu = 0.2`` in a library yarn's friction was refused as the scene's
    ``friction.mu``, in no file the user wrote it in)."""
    from .scene.cell_scene import _effects_table, _friction_table, _rules_table
    from .scene.schema import validate
    for t, table in (("friction", _friction_table(False)), ("rules", _rules_table(False)),
                     ("effects", _effects_table())):
        if t in y:
            validate(table, y[t], f"{path}: {where}.{t}", fill_defaults=False)


def _flags(path: str, key: str, v) -> tuple:
    if not (isinstance(v, list) and all(isinstance(x, str) for x in v)):
        raise KnitsimInputError(f"{path}: {key} = {v!r}: expected a list of strings (a calibration's flags)")
    return tuple(v)


def flagged_materials(doc: dict, lib: "MaterialLibrary | None") -> list[tuple[str, tuple]]:
    """``(what, flags)`` of every library material a scene document names (``yarn.material`` /
    ``knit.material`` at the top, in ``[[cells]]`` and in ``[[zones]]``) that a flagged calibration wrote, and
    of the scene's own ``provenance.flags`` (a scene ``knitsim calibrate`` wrote): a result built on them is
    not believable as the yarn's (a blind probe ran the bundled calibration's scenes, NOT A CALIBRATION YOU
    CAN USE, and read "completed the load program", with nothing in the summary)."""
    out = []
    prov = doc.get("provenance")
    if isinstance(prov, dict) and prov.get("flags"):
        out.append((f"this scene (written by {prov.get('source', 'a calibration')})", tuple(prov["flags"])))
    if lib is None:
        return out
    tables = [doc] + [t for k in ("cells", "zones") for t in (doc.get(k) or []) if isinstance(t, dict)]
    seen = set()
    for t in tables:
        for kind, pool in (("yarn", lib.yarns), ("knit", lib.knits)):
            name = (t.get(kind) or {}).get("material") if isinstance(t.get(kind), dict) else None
            entry = pool.get(name) if isinstance(name, str) else None
            if entry is None and kind == "yarn":
                k = (t.get("knit") or {}).get("material") if isinstance(t.get("knit"), dict) else None
                entry = lib.yarns.get(lib.knits[k].yarn) if k in lib.knits else None
            if entry is not None and entry.flags and (kind, entry.name) not in seen:
                seen.add((kind, entry.name))
                out.append((f"{kind} {entry.name!r} of {lib.path}", entry.flags))
    # one calibration's materials (the same flags) said once
    merged: dict = {}
    for what, flags in out:
        merged.setdefault(flags, []).append(what)
    return [(" and ".join(whats), flags) for flags, whats in merged.items()]


def parse_library(doc: dict, path: str) -> MaterialLibrary:
    """Check a parsed library document (the scene-level checks of friction, rules and effects that combine
    with a scene are the scene's, when a scene uses the material; the law's own values here,
    :func:`_check_yarn_law`); errors name ``path`` and the key."""
    for k in doc:
        if k not in ("yarns", "knits", "title", "source"):
            raise KnitsimInputError(f"{path}: unknown key {k!r} (expected yarns, knits, title, source)")
    yarns, knits = {}, {}
    for name, y in (doc.get("yarns") or {}).items():
        where = f"yarns.{name}"
        if not isinstance(y, dict):
            raise KnitsimInputError(f"{path}: {where}: expected a table")
        for k in y:
            if k not in YARN_KEYS + YARN_TABLES:
                raise KnitsimInputError(f"{path}: {where}.{k}: unknown key (expected one of "
                                        f"{', '.join(YARN_KEYS + YARN_TABLES)})")
        for k in ("d", "B"):
            if k not in y:
                raise KnitsimInputError(f"{path}: {where}.{k}: missing")
        for t in YARN_TABLES:
            if t in y and not isinstance(y[t], dict):
                raise KnitsimInputError(f"{path}: {where}.{t}: expected a table")
        _check_yarn_law(path, where, y)
        _check_yarn_tables(path, where, y)
        w = y.get("in_plane_width")
        yarns[name] = LibraryYarn(name, _number(path, f"{where}.d", y["d"]), _number(path, f"{where}.B", y["B"]),
                                  None if w is None else _number(path, f"{where}.in_plane_width", w),
                                  dict(y.get("friction", {})), dict(y.get("rules", {})), dict(y.get("effects", {})),
                                  dict(y.get("std_errors", {})), str(y.get("source", "")),
                                  _flags(path, f"{where}.flags", y.get("flags", [])))
    for name, k in (doc.get("knits") or {}).items():
        where = f"knits.{name}"
        if not isinstance(k, dict):
            raise KnitsimInputError(f"{path}: {where}: expected a table")
        for key in k:
            if key not in KNIT_KEYS:
                raise KnitsimInputError(f"{path}: {where}.{key}: unknown key (expected one of {', '.join(KNIT_KEYS)})")
        for key in KNIT_KEYS:
            if key not in KNIT_OPTIONAL and key not in k:
                raise KnitsimInputError(f"{path}: {where}.{key}: missing")
        if k["yarn"] not in yarns:
            raise KnitsimInputError(f"{path}: {where}.yarn = {k['yarn']!r}: not a yarn of this file "
                                    f"(its yarns: {', '.join(sorted(yarns)) or 'none'})")
        phi0 = k.get("phi0")
        knits[name] = LibraryKnit(name, str(k["yarn"]), _number(path, f"{where}.L", k["L"]),
                                  _number(path, f"{where}.W0", k["W0"]), _number(path, f"{where}.C0", k["C0"]),
                                  None if phi0 is None else _number(path, f"{where}.phi0", phi0, positive=False),
                                  str(k.get("source", "")), _flags(path, f"{where}.flags", k.get("flags", [])))
    return MaterialLibrary(path, yarns, knits)


def load_library(path: str | Path) -> MaterialLibrary:
    """Read and check a library file (:func:`parse_library`)."""
    from .scene.schema import load_toml
    return parse_library(load_toml(path), str(path))


def library_document(yarns: list[LibraryYarn], knits: list[LibraryKnit], title: str = "") -> dict:
    """The TOML document of a library (what :func:`knitsim.scene.schema.dumps` writes)."""
    doc: dict = {}
    if title:
        doc["title"] = title
    doc["yarns"] = {}
    for y in yarns:
        e: dict = {"d": y.d, "B": y.B}
        if y.in_plane_width is not None:
            e["in_plane_width"] = y.in_plane_width
        if y.source:
            e["source"] = y.source
        if y.flags:
            e["flags"] = list(y.flags)
        for t in YARN_TABLES:
            v = getattr(y, t)
            if v:
                e[t] = dict(v)
        doc["yarns"][y.name] = e
    doc["knits"] = {}
    for k in knits:
        e = {"yarn": k.yarn, "L": k.L, "W0": k.W0, "C0": k.C0}
        if k.phi0 is not None:
            e["phi0"] = k.phi0
        if k.source:
            e["source"] = k.source
        if k.flags:
            e["flags"] = list(k.flags)
        doc["knits"][k.name] = e
    return doc


def expand(cell: dict, lib: MaterialLibrary | None, where: str = "", filled: dict | None = None) -> dict:
    """Fill a raw (not yet defaulted) cell's tables from the library materials it names.

    ``cell`` holds the scene's ``yarn``, ``knit``, ``friction``, ``rules`` and ``effects`` tables as
    given (merged with any override).  A ``knit.material`` of the library gives L, W0, C0 (and
    ``friction.phi0``) where the scene does not, and its yarn when the scene names no yarn and gives
    neither d nor B; a ``yarn.material`` of the library gives d, B, the in-plane width, the friction
    law, the rules and the effects likewise.  The library names are removed (the result is explicit);
    built-in names are left to :mod:`knitsim.materials`.  Returns a new dict.

    ``filled``, where given, receives ``(table, key) -> "knits.NAME of FILE"`` (or the yarn's) for every value
    the library gave: a check of the scene then names where the value came from (a blind probe's W0 of a
    library knit was refused as the scene's ``knit.W0``, which the scene does not state).
    """
    import copy
    out = copy.deepcopy(cell)
    if lib is None:
        return out
    for t in ("yarn", "knit", "friction", "rules", "effects"):
        out.setdefault(t, {})
    pre = f"{where}." if where else ""
    y, k, f = out["yarn"], out["knit"], out["friction"]
    filled = {} if filled is None else filled

    from .scene.cell_scene import CELL_SCENE
    alternatives = CELL_SCENE.fields["friction"]

    def give(table: str, key: str, value, source: str) -> None:
        # not where the scene states the quantity, in any of its ways (m or mu_k; phi0, phi0_deg or phi0_fraction)
        others = alternatives.others_than(key) if table == "friction" else ()
        if key not in out[table] and not any(o in out[table] for o in others):
            out[table][key] = value
            filled[(table, key)] = f"{source} of {lib.path}"

    kname = k.get("material")
    if kname is not None and kname in lib.knits:
        knit = lib.knits[kname]
        del k["material"]
        for key in ("L", "W0", "C0"):
            give("knit", key, getattr(knit, key), f"knits.{kname}")
        if knit.phi0 is not None:
            give("friction", "phi0", knit.phi0, f"knits.{kname}")
        if "material" not in y and "d" not in y and "B" not in y:
            y["material"] = knit.yarn
    yname = y.get("material")
    if yname is not None and yname in lib.yarns:
        yarn = lib.yarns[yname]
        del y["material"]
        source = f"yarns.{yname}"
        give("yarn", "d", yarn.d, source)
        give("yarn", "B", yarn.B, source)
        if yarn.in_plane_width is not None:
            give("yarn", "in_plane_width", yarn.in_plane_width, source)
        for key, v in yarn.friction.items():
            give("friction", key, v, source)
        for key, v in yarn.rules.items():
            give("rules", key, v, source)
        if yarn.effects and not out["effects"]:
            out["effects"] = dict(yarn.effects)
    elif yname is not None and yname not in _builtin_yarns():
        known = sorted(set(lib.yarns) | set(_builtin_yarns()))
        raise KnitsimInputError(f"{pre}yarn.material = {yname!r}: unknown yarn (known: {', '.join(known)}; "
                                f"library {lib.path})")
    if kname is not None and kname not in lib.knits and kname not in _builtin_knits():
        known = sorted(set(lib.knits) | set(_builtin_knits()))
        raise KnitsimInputError(f"{pre}knit.material = {kname!r}: unknown knit (known: {', '.join(known)}; "
                                f"library {lib.path})")
    return out


def _builtin_yarns() -> list[str]:
    from . import materials
    return materials.yarn_names()


def _builtin_knits() -> list[str]:
    from . import materials
    return materials.knit_names()


__all__ = ["LibraryYarn", "LibraryKnit", "MaterialLibrary", "parse_library", "load_library", "library_document",
           "expand"]
