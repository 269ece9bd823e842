"""Diagnosis scenes: the specimen of measured curves, and what the diagnosis may calibrate.

A diagnosis scene is a cell scene (:mod:`knitsim.scene.cell_scene`: tables
``[yarn]``, ``[knit]``, ``[friction]``, ``[rules]``) without ``[load]`` (each
measured curve drives its own simulation), plus::

    [diagnosis]
    free = ["m", "phi0"]            # baseline parameters to calibrate: m, phi0, B, d, in_plane_width, L, W0, C0
    bounds = { d = [0.5, 0.7] }     # optional, model units (phi0 as a fraction of phimax)
    effects = ["yarn_compaction"]   # optional, default all seven (knitsim.cell.effects)
    max_increment = 0.01            # optional: largest replay increment (events are located exactly)
    noise_N = 0.01                  # optional: known noise sd of every curve [N per wale]
    offsets = true                  # optional: fit a force offset per curve (a load cell's zero)
    pair = true                     # optional: also fit the best pair
    max_nfev = 20                   # optional: evaluations per calibration

    [[diagnosis.noise]]             # optional: the noise sd of one file (else estimated from it)
    file = "pull_5N.csv"            # matched by path, or by file name
    sigma_N = 0.05

    [diagnosis.fixed]               # optional: effect parameters not fitted
    load_ref_N = 0.1                # normal load at which the ratio is m
    rate_ref_mm_s = 1.0             # test rate at which the ratio is m
    compaction_min = 0.5
    bend_sigma = 20.0

Every key is checked before any solve by the shared scene schema
(:mod:`knitsim.scene.schema`, :data:`DIAGNOSIS_TABLE`); errors name the key and the value.
"""
from __future__ import annotations

import copy
from pathlib import Path

from ..cell.effects import EFFECT_NAMES, EffectSet
from ..diagnosis.calibrate import default_bounds
from ..diagnosis.diagnose import DiagnosisSetup
from ..diagnosis.effects import BASELINE_VARIABLES, EFFECT_SPECS, check_effects
from ..errors import KnitsimInputError
from .cell_scene import load_cell_scene
from .schema import OPTIONAL, REQUIRED, Field, Table, TableArray, load_toml, validate

_FIXED = ("load_ref_N", "rate_ref_mm_s", "compaction_min", "bend_sigma")


def _bounds_check(v) -> str | None:
    if len(v) != 2:
        return "expected [low, high]"
    if not v[0] < v[1]:
        return "expected low < high"
    return None


def _variables() -> dict:
    known = dict(BASELINE_VARIABLES)
    for spec in EFFECT_SPECS.values():
        known.update({v.name: v for v in spec.variables})
    return known


#: the ``[diagnosis]`` table
DIAGNOSIS_TABLE = Table({
    "free": Field(("str_list",), ["m", "phi0"], "baseline parameters to calibrate", choices=tuple(BASELINE_VARIABLES)),
    "bounds": Table({name: Field(("float_list",), OPTIONAL, f"[low, high] of {v.doc}", v.unit, check=_bounds_check)
                     for name, v in _variables().items()}, "bounds of fitted variables (phi0 as a fraction of phimax)"),
    "effects": Field(("str_list",), list(EFFECT_NAMES), "effects to try", choices=EFFECT_NAMES),
    "max_increment": Field(("float",), 0.01, "largest replay increment", min=0.0, min_inclusive=False, max=0.05),
    "noise_N": Field(("float",), OPTIONAL, "noise sd of every curve", "N", min=0.0, min_inclusive=False),
    "noise": TableArray(Table({
        "file": Field(("str",), REQUIRED, "the measured file (path, or file name)"),
        "sigma_N": Field(("float",), REQUIRED, "its noise sd", "N", min=0.0, min_inclusive=False),
    }), "noise sd of single files"),
    "offsets": Field(("bool",), True, "fit a force offset per curve"),
    "pair": Field(("bool",), True, "also fit the best pair of effects"),
    "max_nfev": Field(("int",), 20, "evaluations per calibration", min=2),
    "fixed": Table({k: Field(("float",), OPTIONAL, "effect parameter held fixed") for k in _FIXED},
                   "effect parameters not fitted"),
}, "what the diagnosis calibrates", required=True)


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
        ``noise_N`` holds the scene's ``noise_N``, or ``{file: sd}`` from ``[[diagnosis.noise]]``
        (the command matches those files to the curves it is given).

    Raises
    ------
    KnitsimInputError
        The first problem found, naming the key path and the value.
    """
    if isinstance(source, dict):
        data, name = copy.deepcopy(source), "<dict>"
    else:
        data, name = load_toml(source), str(source)
    if "diagnosis" not in data:
        raise KnitsimInputError(f"{name}: missing table [diagnosis] (what to calibrate; see knitsim.scene.diagnosis_scene)")
    diag = validate(DIAGNOSIS_TABLE, data.pop("diagnosis"), "diagnosis")
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
    effects = check_effects(diag["effects"])
    known = dict(BASELINE_VARIABLES)
    for e in effects:
        known.update({v.name: v for v in EFFECT_SPECS[e].variables})
    bounds = {}
    for k, v in diag["bounds"].items():
        if k not in known:
            raise KnitsimInputError(f"diagnosis.bounds.{k}: not a variable of the effects tried "
                                    f"({', '.join(known)})")
        if k in ("B", "d", "in_plane_width", "L", "W0", "C0") and v[0] <= 0:
            raise KnitsimInputError(f"diagnosis.bounds.{k} = {v!r}: {k} must stay > 0")
        if k == "phi0" and not (-1.0 <= v[0] and v[1] <= 1.0):
            raise KnitsimInputError(f"diagnosis.bounds.phi0 = {v!r}: phi0 is fitted as a fraction of phimax "
                                    "(|phi0| <= phimax), so its bounds lie within [-1, 1]")
        bounds[k] = tuple(v)
    # the specimen must stay a knit at every corner of the bounds: W0 >= 4 d, as the cell scene checks it
    if "d" in bounds:
        W0_low = base.W0
        if "W0" in diag["free"]:
            W0_low = bounds.get("W0", default_bounds(base, BASELINE_VARIABLES["W0"]))[0]
        if bounds["d"][1] > W0_low / 4.0:
            raise KnitsimInputError(f"diagnosis.bounds.d = {list(bounds['d'])!r}: the upper bound must keep "
                                    f"W0 >= 4 d (W0 = {W0_low:.4g} mm: d <= {W0_low / 4.0:.4g} mm)")
    fixed = dict(diag["fixed"])
    EffectSet(**fixed).validated(where="diagnosis.fixed")
    noise = diag.get("noise_N")
    if diag.get("noise"):
        if noise is not None:
            raise KnitsimInputError("diagnosis.noise_N and [[diagnosis.noise]]: give one sd for every curve or "
                                    "one per file, not both")
        noise = {e["file"]: e["sigma_N"] for e in diag["noise"]}
    title = data.get("title", "") or name
    return DiagnosisSetup(base=base, free=tuple(diag["free"]), bounds=bounds, effects=effects, fixed=fixed,
                          max_increment=diag["max_increment"], noise_N=noise, offsets=diag["offsets"],
                          device=scene.device, max_nfev=diag["max_nfev"], pair=diag["pair"],
                          title=str(title)).validated()
