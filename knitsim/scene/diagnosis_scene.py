"""Diagnosis scenes: the specimen of measured curves, and what the diagnosis may calibrate.

A diagnosis scene is a cell scene (:mod:`knitsim.scene.cell_scene`: tables
``[yarn]``, ``[knit]``, ``[friction]``, ``[rules]``) without ``[load]`` (each
measured curve drives its own simulation), plus::

    [diagnosis]
    free = ["m", "phi0"]            # baseline parameters to calibrate: m, phi0, B, d, L, W0, C0
    bounds = { d = [0.5, 0.7] }     # optional, model units (phi0 as a fraction of phimax)
    effects = ["yarn_compaction"]   # optional, default all seven (knitsim.cell.effects)
    max_increment = 0.01            # optional: largest replay increment (events are located exactly)
    noise_N = 0.01                  # optional: known noise sd [N per wale]
    pair = true                     # optional: also fit the best pair
    max_nfev = 20                   # optional: evaluations per calibration

    [diagnosis.fixed]               # optional: effect parameters not fitted
    load_ref_N = 0.1                # normal load at which the ratio is m
    rate_ref_mm_s = 1.0             # test rate at which the ratio is m
    compaction_min = 0.5
    bend_sigma = 20.0

Every key is checked before any solve; errors name the key and the value.
"""
from __future__ import annotations

import copy
import math
from pathlib import Path

from ..cell.effects import EFFECT_NAMES, EffectSet
from ..diagnosis.diagnose import DiagnosisSetup
from ..diagnosis.effects import BASELINE_VARIABLES, EFFECT_SPECS, check_effects
from ..errors import KnitsimInputError
from .cell_scene import load_cell_scene
from .schema import load_toml

_KEYS = ("free", "bounds", "effects", "max_increment", "noise_N", "pair", "max_nfev", "fixed")
_FIXED = ("load_ref_N", "rate_ref_mm_s", "compaction_min", "bend_sigma")


def _number(path: str, v, positive: bool = False) -> float:
    if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
        raise KnitsimInputError(f"{path} = {v!r}: must be a finite number")
    if positive and v <= 0:
        raise KnitsimInputError(f"{path} = {v!r}: must be > 0")
    return float(v)


def load_diagnosis_scene(source: str | Path | dict, device: str | None = None) -> DiagnosisSetup:
    """Read and validate a diagnosis scene.

    Parameters
    ----------
    source : path or dict
        A TOML file, or an already-parsed document.
    device : str, optional
        Replaces the scene's device.

    Returns
    -------
    DiagnosisSetup

    Raises
    ------
    KnitsimInputError
        The first problem found, naming the key path and the value.
    """
    if isinstance(source, dict):
        data, name = copy.deepcopy(source), "<dict>"
    else:
        data, name = load_toml(source), str(source)
    diag = data.pop("diagnosis", None)
    if diag is None:
        raise KnitsimInputError(f"{name}: missing table [diagnosis] (what to calibrate; see knitsim.scene.diagnosis_scene)")
    if not isinstance(diag, dict):
        raise KnitsimInputError(f"diagnosis = {diag!r}: expected a table")
    for k in diag:
        if k not in _KEYS:
            raise KnitsimInputError(f"diagnosis.{k}: unknown key; expected one of {', '.join(_KEYS)}")
    if "load" in data:
        raise KnitsimInputError("load: a diagnosis scene has no [load] table (each measured curve drives its own "
                                "simulation); remove it")
    if "cells" in data:
        raise KnitsimInputError("cells: a diagnosis scene describes one specimen; remove [[cells]]")
    # the cell scene checks the specimen (W0 >= 4 d, L long enough, |phi0| <= phimax, ...); its load
    # program is not used, a one-increment placeholder satisfies the schema
    data["load"] = {"type": "monotonic", "target_strain": 0.005}
    scene = load_cell_scene(data, device=device)
    base = scene.params[0]
    if scene.engine != "warp":
        raise KnitsimInputError(f"engine = {scene.engine!r}: the diagnosis runs on the Warp batch (engine = 'warp')")

    free = diag.get("free", ["m", "phi0"])
    if not isinstance(free, list) or not all(isinstance(x, str) for x in free):
        raise KnitsimInputError(f"diagnosis.free = {free!r}: expected a list of names ({', '.join(BASELINE_VARIABLES)})")
    effects = diag.get("effects", list(EFFECT_NAMES))
    if not isinstance(effects, list) or not all(isinstance(x, str) for x in effects):
        raise KnitsimInputError(f"diagnosis.effects = {effects!r}: expected a list of effect names")
    check_effects(effects)
    known = dict(BASELINE_VARIABLES)
    for e in effects:
        known.update({v.name: v for v in EFFECT_SPECS[e].variables})
    bounds = {}
    for k, v in (diag.get("bounds") or {}).items():
        if k not in known:
            raise KnitsimInputError(f"diagnosis.bounds.{k}: unknown variable; expected one of {', '.join(known)}")
        if not (isinstance(v, list) and len(v) == 2):
            raise KnitsimInputError(f"diagnosis.bounds.{k} = {v!r}: expected [low, high]")
        lo, hi = (_number(f"diagnosis.bounds.{k}", x) for x in v)
        if not lo < hi:
            raise KnitsimInputError(f"diagnosis.bounds.{k} = {v!r}: expected low < high")
        if k in ("B", "d", "L", "W0", "C0") and lo <= 0:
            raise KnitsimInputError(f"diagnosis.bounds.{k} = {v!r}: {k} must stay > 0")
        bounds[k] = (lo, hi)
    fixed = {}
    for k, v in (diag.get("fixed") or {}).items():
        if k not in _FIXED:
            raise KnitsimInputError(f"diagnosis.fixed.{k}: unknown key; expected one of {', '.join(_FIXED)}")
        fixed[k] = _number(f"diagnosis.fixed.{k}", v)
    try:
        EffectSet(**fixed).validated(where="diagnosis.fixed")
    except TypeError as exc:  # pragma: no cover - keys are checked above
        raise KnitsimInputError(f"diagnosis.fixed: {exc}") from None
    noise = diag.get("noise_N")
    if noise is not None:
        noise = _number("diagnosis.noise_N", noise, positive=True)
    mi = _number("diagnosis.max_increment", diag.get("max_increment", 0.01), positive=True)
    pair = diag.get("pair", True)
    if not isinstance(pair, bool):
        raise KnitsimInputError(f"diagnosis.pair = {pair!r}: expected true or false")
    nfev = diag.get("max_nfev", 20)
    if not isinstance(nfev, int) or isinstance(nfev, bool) or nfev < 2:
        raise KnitsimInputError(f"diagnosis.max_nfev = {nfev!r}: expected a whole number >= 2")
    title = data.get("title", "") or name
    return DiagnosisSetup(base=base, free=tuple(free), bounds=bounds, effects=tuple(effects), fixed=fixed,
                          max_increment=mi, noise_N=noise, device=scene.device, max_nfev=nfev, pair=pair,
                          title=str(title)).validated()
