"""The calibration scene: specimens of one yarn, and what to fit (TOML; ``knitsim calibrate``).

Example (``scenes/calibration/do2020/calibrate.toml``)::

    title = "Do 2020 single jersey: one yarn, two knits"
    device = "cpu"

    [yarn]                      # the yarn's start values (and its name in the library written)
    name = "do2020_yarn"
    d = 0.2                     # [mm]
    B = 0.003                   # [N mm^2]
    in_plane_width = 0.3        # [mm]

    [friction]                  # the friction law, as in a cell scene
    model = "coulomb"
    m = 0.5

    [rules]                     # rules where Table 4 is silent, as in a cell scene
    unloading_rule = "dusserre"

    [effects]                   # effects switched on and their fixed parameters, as in a cell scene
    on = ["yarn_compaction"]
    compaction_k = 5.0

    [calibration]
    shared = ["B", "d", "in_plane_width", "m", "compaction_k"]   # one yarn
    per_specimen = ["phi0", "L", "W0", "C0"]                     # each knit's own
    bounds = { B = [0.0003, 0.03], m = [0.0, 1.5] }
    max_increment = 0.005       # of the simulation
    row_step = 0.005            # strain step of the rows fitted
    starts = 48                 # Latin-hypercube starts screened (seed below)
    refine = 3                  # best starts refined
    seed = 1

    [[specimens]]
    name = "jersey_4p5"         # the knit's name in the library written
    width = 50.0                # [mm] across the wales
    gauge_length = 100.0        # [mm] between the grips
    band = ["low.tsv", "high.tsv"]        # envelopes of the experimental scatter (relative to the scene)
    knit = { L = 4.5, W0 = 1.154, C0 = 0.90 }
    uncertainty = { L = 0.02, W0 = 0.10, C0 = 0.10 }      # relative sd of each stated value

``zero`` says what the files' 0 N is (:mod:`knitsim.calibration.joint`, "The files' zero"):
``"absolute"`` (the default) the model's 0 N; ``"tared"`` the model's force at grip strain 0 (a load cell
zeroed with the knit mounted: each row is fitted as the model's force less that); ``"fitted"`` a force
offset per specimen, fitted (it costs the rest level that identifies phi0 and m).  With ``"absolute"``, a
file that reads at rest well below the fitted knit's force at grip strain 0 is flagged.

A specimen may give ``curve = "FILE"`` (a measured curve; with ``noise_N``,
else its noise is estimated) instead of, or with, the band.  With
``"pretension"`` in ``per_specimen`` each specimen's strain at grip strain 0
is fitted (``pretension_sd``: the sd of its prior around 0, required;
``pretension``: its start; :func:`knitsim.calibration.specimen.pretension_strain`).  Everything is
checked here, before any solve or output (the fit's own checks included:
:func:`knitsim.calibration.joint.check_setup`, e.g. a variable that is not the yarn's, or a strain the
knit cannot reach, such as a column in per cent); errors name the key path and the value, or the file,
row and column.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path

from ..errors import KnitsimInputError
from ..patch.model import MAX_STITCHES_PER_AXIS, cm_hint, specimen_size_notes
from ..scene.cell_scene import _device_check, _effects_table, _friction_table, _rules_table, load_cell_scene
from ..scene.schema import OPTIONAL, REQUIRED, Field, Table, TableArray, error, load_toml, set_value, validate
from .joint import ZERO_MODES, JointSetup, check_setup, check_zero
from .specimen import GEOMETRY, SpecimenData, specimen_from_files

_GEOMETRY_TABLE = Table({k: Field(("float",), REQUIRED, f"stated {k}", "mm", min=0.0, min_inclusive=False)
                         for k in GEOMETRY}, "the knit as stated (L, W0, C0 [mm])", required=True)
_UNCERTAINTY_TABLE = Table({k: Field(("float",), 0.0, f"relative sd of the stated {k}", min=0.0, max=0.5)
                            for k in GEOMETRY}, "relative sd of each stated value (0: known)")

#: the longest a file's name may be (bytes: Linux and macOS; NTFS counts 255 UTF-16 units)
NAME_MAX = 255
#: what a specimen's name is joined with to name the files written (knitsim.calibration.outputs)
_SPECIMEN_FILES = ("fit_{}.png", "{}.cell.toml", "{}.patch.toml")


def _specimen_name_check(name) -> str | None:
    """A specimen's name names the files written for it (``fit_NAME.png``, ``NAME.cell.toml``,
    ``NAME.patch.toml``): refused where it cannot (a folder separator, no name, beyond :data:`NAME_MAX`)
    before the fit, which would otherwise run to a traceback when the files are written (a probe's
    ``"mid/2"``: FileNotFoundError; 250 characters: "File name too long")."""
    if not isinstance(name, str):
        return None
    files = ", ".join(f.format("NAME") for f in _SPECIMEN_FILES)
    if not name.strip():
        return f"empty: it names the files written for the specimen ({files})"
    sep = next((c for c in ("/", "\\", "\0") if c in name), None)
    if sep is not None:
        return f"holds {sep!r}, which no file name may hold: it names the files written for the specimen ({files})"
    longest = max(len(f.format(name).encode()) for f in _SPECIMEN_FILES)
    if longest > NAME_MAX:
        return (f"too long: it names the files written for the specimen ({files}), the longest of them "
                f"{longest} bytes, more than a file name may have ({NAME_MAX})")
    return None


#: the schema of a calibration scene
CALIBRATION_SCENE = Table({
    "title": Field(("str",), OPTIONAL, "free text"),
    "engine": Field(("str",), "warp", "the calibration runs on the warp engine", choices=("warp",)),
    "device": Field(("str",), "cpu", "Warp device", check=_device_check),
    "yarn": Table({
        "name": Field(("str",), "yarn", "name of the calibrated yarn in the library written"),
        "d": Field(("float",), REQUIRED, "compact diameter (start)", "mm", min=0.0, min_inclusive=False),
        "B": Field(("float",), REQUIRED, "bending stiffness (start)", "N mm^2", min=0.0, min_inclusive=False),
        "in_plane_width": Field(("float",), OPTIONAL, "in-plane width (start; default d)", "mm", min=0.0,
                                min_inclusive=False),
    }, "the yarn: start values", required=True),
    "friction": _friction_table(True),
    "rules": _rules_table(True),
    "effects": _effects_table(),
    "calibration": Table({
        "shared": Field(("str_list",), REQUIRED, "yarn variables fitted, shared by every specimen"),
        "per_specimen": Field(("str_list",), ["phi0"], "variables fitted per specimen (phi0, L, W0, C0)"),
        "bounds": Table({n: Field(("float_list",), OPTIONAL, f"[low, high] of {n}") for n in
                         ("B", "d", "in_plane_width", "m", "phi0", "L", "W0", "C0", "pretension", "log10_dahl_sigma", "coil_mu_k",
                          "load_n", "rate_p", "compaction_k", "bend_h", "ext_c")},
                        "ranges: B [N mm^2], d and in_plane_width [mm], phi0 as a fraction of phimax, L/W0/C0 as "
                        "factors on the stated values"),
        "fixed": Table({n: Field(("float",), OPTIONAL, f"effect parameter {n} held fixed") for n in
                        ("load_ref_N", "rate_ref_mm_s", "compaction_min", "bend_sigma")},
                       "effect parameters held fixed (besides [effects])"),
        "max_increment": Field(("float",), 0.005, "largest strain increment of the simulation", min=0.0,
                               min_inclusive=False, max=0.1),
        "row_step": Field(("float",), 0.005, "strain step of the rows fitted", min=0.0, min_inclusive=False, max=0.1),
        "force_accuracy": Field(("float",), 0.005, "relative accuracy of the force reading: the least sd of a band's "
                                "row, times the force (0.005: ISO 7500-1 class 0.5)", min=0.0, max=0.5),
        "objective": Field(("str",), "midline", "what banded rows are fitted to: the band's mid-line with sd = "
                           "half-width (midline), or the band likelihood: anywhere inside at no cost, just outside a "
                           "Gaussian of the force accuracy, far outside a Cauchy tail (band; refined from the "
                           "mid-line fits)", choices=("midline", "band")),
        "zero": Field(("str",), "absolute", "what the files' 0 N is: the model's 0 N (absolute), the model's force at "
                      "grip strain 0 (tared: a load cell zeroed with the knit mounted), or a force offset per "
                      "specimen, fitted (fitted)", choices=ZERO_MODES),
        "offsets": Field(("bool",), OPTIONAL, "replaced by zero (refused)"),
        "starts": Field(("int",), 48, "Latin-hypercube starts screened", min=0, max=10_000),
        "refine": Field(("int",), 3, "best starts refined by least squares", min=1, max=100),
        "max_nfev": Field(("int",), 100, "least-squares evaluations per refined start", min=1),
        "seed": Field(("int",), 0, "seed of the starts", min=0),
    }, "what is fitted", required=True),
    "specimens": TableArray(Table({
        "name": Field(("str",), REQUIRED, "the knit's name in the library written (and in the files written for "
                      "the specimen: fit_NAME.png, NAME.cell.toml, NAME.patch.toml)", check=_specimen_name_check),
        "width": Field(("float",), REQUIRED, "specimen width across the wales", "mm", min=0.0, min_inclusive=False),
        "gauge_length": Field(("float",), REQUIRED, "distance between the grips", "mm", min=0.0,
                              min_inclusive=False),
        "curve": Field(("str",), OPTIONAL, "measured curve (CSV: strain, load_N or force_per_wale_N)"),
        "band": Field(("str_list",), OPTIONAL, "the two envelope files of the experimental scatter"),
        "noise_N": Field(("float",), OPTIONAL, "sd of the curve's force (default: estimated)", "N", min=0.0,
                         min_inclusive=False),
        "end_strain": Field(("float",), OPTIONAL, "last strain fitted (default: the end of the data)", min=0.0,
                            min_inclusive=False),
        "knit": _GEOMETRY_TABLE,
        "uncertainty": _UNCERTAINTY_TABLE,
        "phi0": Field(("float",), OPTIONAL, "start of phi0 [rad] (default: friction.phi0)", "rad"),
        "pretension": Field(("float",), 0.0, "strain of the knit at grip strain 0 (the tester's pretension "
                            "before the strain origin): the start of a fitted one", min=0.0, max=0.5),
        "pretension_sd": Field(("float",), 0.0, "sd of the pretension's prior, a Gaussian centred on 0 (strain; "
                               "> 0 to fit it per specimen)", min=0.0, max=0.5),
    }), "the specimens of the one yarn", min_items=1),
})


@dataclass
class CalibrationScene:
    """A validated calibration scene.

    Attributes
    ----------
    specimens : list of SpecimenData
    setup : JointSetup
    yarn_name : str
    resolved : dict
        The scene with defaults filled (paths as given).
    source : str
    base_dir : Path
        Directory of the scene (paths are relative to it).
    """

    specimens: list
    setup: JointSetup
    yarn_name: str
    resolved: dict
    source: str
    base_dir: Path


def load_calibration_scene(source: str | Path | dict, overrides: list[str] = (),
                           device: str | None = None) -> CalibrationScene:
    """Read, override (``--set``), validate a calibration scene and read its specimens' files.

    Raises
    ------
    KnitsimInputError
        The first problem (key path and value, or file, row and column); nothing is solved.
    """
    if isinstance(source, dict):
        data, name, base_dir = copy.deepcopy(source), "<dict>", Path(".")
    else:
        data, name, base_dir = load_toml(source), str(source), Path(source).resolve().parent
    for a in overrides:
        set_value(data, CALIBRATION_SCENE, a)
    if device is not None:
        data["device"] = device
    doc = validate(CALIBRATION_SCENE, data, fill_defaults=True)
    if "specimens" not in doc:
        raise KnitsimInputError("specimens: missing (one [[specimens]] table per specimen)")
    cal = doc["calibration"]
    names = [s["name"] for s in doc["specimens"]]
    for i, n in enumerate(names):
        if names.index(n) != i:
            raise error(f"specimens[{i}].name", n, "two specimens share this name")
    # the start cell: a cell scene of the yarn on the first specimen's knit (its checks, its effects)
    y = {k: v for k, v in doc["yarn"].items() if k != "name"}
    first = doc["specimens"][0]["knit"]
    on = list(doc.get("effects", {}).get("on", []))
    effects = [e for e in on]
    eff_table = dict(data.get("effects", {}))
    fit_dahl = "log10_dahl_sigma" in cal["shared"]
    if "dahl_transition" in on and not fit_dahl:
        effects.remove("dahl_transition")            # then the friction law itself: friction.model = "dahl"
    friction = dict(data.get("friction", {}))
    if fit_dahl:
        if "dahl_transition" not in on:
            raise error("calibration.shared", cal["shared"], "log10_dahl_sigma is the Dahl stiffness: switch the "
                        "effect on (effects.on = [\"dahl_transition\"])")
        eff_table["on"] = [e for e in on if e != "dahl_transition"]
        friction.pop("model", None)
        # the start of the fitted stiffness: given to the start cell after its scene is read (a Coulomb cell's
        # scene refuses a Dahl stiffness it would not use)
        dahl_start = friction.pop("dahl_sigma", None)
    cell_doc = {"device": doc["device"], "yarn": y, "knit": dict(first), "friction": friction,
                "rules": dict(data.get("rules", {})), "load": {"type": "monotonic", "target_strain": 0.01}}
    if eff_table:
        cell_doc["effects"] = eff_table
    try:
        base = load_cell_scene(cell_doc).params[0]
    except KnitsimInputError as exc:
        raise KnitsimInputError(f"the start yarn on specimens[0]'s knit: {exc}") from None
    if fit_dahl and dahl_start is not None:
        base = base.replace(dahl_sigma=float(dahl_start))
    for n in cal["shared"]:
        if n in ("phi0",) + GEOMETRY:
            raise error("calibration.shared", cal["shared"], f"{n} is the knit's, not the yarn's: list it in "
                        "calibration.per_specimen")
    bounds = {}
    for n, v in cal.get("bounds", {}).items():
        if len(v) != 2 or not v[0] < v[1]:
            raise error(f"calibration.bounds.{n}", v, "expected [low, high] with low < high")
        bounds[n] = (float(v[0]), float(v[1]))
    specimens = []
    for i, s in enumerate(doc["specimens"]):
        where = f"specimens[{i}]"

        def path(p, key):
            f = Path(p)
            f = f if f.is_absolute() else base_dir / f
            if not f.is_file():
                raise error(f"{where}.{key}", p, f"no such file ({f})")
            return f
        band = s.get("band")
        if band is not None and len(band) != 2:
            raise error(f"{where}.band", band, "expected the two envelope files [lower, upper]")
        if band is None and "curve" not in s:
            raise KnitsimInputError(f"{where}: give curve = FILE, band = [LOWER, UPPER], or both")
        # the specimen holds at least one course between its grips and one wale across its width, and no more than
        # a patch may hold (knitsim.patch.model.specimen_size_notes: a size in cm or in um typed as mm)
        wales, courses = s["width"] / s["knit"]["W0"], s["gauge_length"] / s["knit"]["C0"]
        cm = cm_hint(s["width"], s["gauge_length"], wales, courses)
        if s["gauge_length"] < s["knit"]["C0"]:
            raise error(f"{where}.gauge_length", s["gauge_length"], f"shorter than one course (knit.C0 = "
                        f"{s['knit']['C0']:g} mm)" + cm)
        if s["width"] < s["knit"]["W0"]:
            raise error(f"{where}.width", s["width"], f"narrower than one wale (knit.W0 = {s['knit']['W0']:g} mm)"
                        + cm)
        refusal, _ = specimen_size_notes(s["width"], s["gauge_length"], wales, courses)
        if refusal is not None:
            key = "width" if wales > MAX_STITCHES_PER_AXIS else "gauge_length"
            raise error(f"{where}.{key}", s[key], refusal)
        if "noise_N" in s and "curve" not in s:
            raise error(f"{where}.noise_N", s["noise_N"], "the noise of a measured curve: give curve = FILE")
        specimens.append(specimen_from_files(
            s["name"], width_mm=s["width"], gauge_length_mm=s["gauge_length"], knit=s["knit"],
            uncertainty=s["uncertainty"], curve=path(s["curve"], "curve") if "curve" in s else None,
            band=(path(band[0], "band"), path(band[1], "band")) if band else None, row_step=cal["row_step"],
            noise_N=s.get("noise_N"), end_strain=s.get("end_strain"), accuracy_rel=cal["force_accuracy"],
            where=where, pretension=s["pretension"], pretension_sd=s["pretension_sd"]))
    fixed = dict(cal.get("fixed", {}))
    if "offsets" in cal:
        raise error("calibration.offsets", cal["offsets"], 'replaced by calibration.zero = "absolute" | "tared" | '
                    '"fitted" (offsets = true was zero = "fitted"; false was "absolute")')
    setup = JointSetup(base=base, shared=tuple(cal["shared"]), per_specimen=tuple(cal["per_specimen"]),
                       effects=tuple(effects) if fit_dahl else tuple(e for e in effects if e != "dahl_transition"),
                       bounds=bounds, fixed=fixed, max_increment=cal["max_increment"], starts=cal["starts"],
                       refine=cal["refine"], seed=cal["seed"], max_nfev=cal["max_nfev"], device=doc["device"],
                       phi0_starts=tuple(s.get("phi0") for s in doc["specimens"]), objective=cal["objective"],
                       zero=check_zero(cal["zero"]))
    if cal["row_step"] < cal["max_increment"] * (1 - 1e-12):
        raise error("calibration.row_step", cal["row_step"], f"must be >= calibration.max_increment = "
                    f"{cal['max_increment']!r}")
    # the fit's own checks (variable names, bounds, priors, strains the knits cannot reach), without a solve
    check_setup(specimens, setup)
    return CalibrationScene(specimens, setup, doc["yarn"]["name"], doc, name, base_dir)


__all__ = ["CALIBRATION_SCENE", "CalibrationScene", "load_calibration_scene"]
