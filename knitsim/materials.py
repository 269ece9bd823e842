"""Material library: the yarns and knits of Dusserre (2015), by name.

Every number is read from the bundled transcription of the paper,
:func:`knitsim.data.dusserre2015` (one place for the paper's numbers):

- yarn diameter ``d`` and bending stiffness ``B``: Table 1;
- capstan friction law ``mu_k = b V^p Fn^(n-1)`` (eq 5): Table 3;
- kinetic friction coefficient ``mu_k`` at the crossing conditions
  (0.5 mm/s, 1 N), mean coiling angle and apparent ratio ``m``: section 3.4;
- stitch length ``L``, wale width ``W0`` and course length ``C0`` at rest:
  section 2.2.

Units: mm, N (``B`` in N mm^2); angles in degrees only in ``*_deg`` fields.

Examples
--------
>>> from knitsim import materials
>>> materials.yarn("e_glass").B
0.31
>>> materials.knit("basalt_plain").L
13.1
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from functools import lru_cache

from .data import dusserre2015
from .errors import KnitsimInputError

SOURCE = "Dusserre (2015), Eur. J. Mech. A/Solids 51, 160-171"


@dataclass(frozen=True)
class Yarn:
    """A yarn of the library.

    Attributes
    ----------
    name : str
        Library name, e.g. ``"e_glass"``.
    d : float
        Yarn diameter [mm] (Table 1, compact hexagonal packing).
    B : float
        Bending stiffness [N mm^2] (Table 1).
    friction_b, friction_p, friction_n : float
        Capstan friction law of eq 5, ``mu_k = b V^p Fn^(n-1)`` (Table 3);
        ``b`` in s^p mm^-p N^(1-n).
    mu_k : float
        Kinetic friction coefficient at the loop crossing's conditions (section 3.4).
    coiling_angle_deg : float
        Mean coiling angle at the crossing [deg] (section 3.4).
    m : float
        Apparent tangent-to-normal ratio at the crossing used by the paper (eq 10, section 3.4).
    source : str
        Where the numbers come from.
    """

    name: str
    d: float
    B: float
    friction_b: float
    friction_p: float
    friction_n: float
    mu_k: float
    coiling_angle_deg: float
    m: float
    source: str

    def as_dict(self) -> dict:
        """Fields by name."""
        return asdict(self)


@dataclass(frozen=True)
class Knit:
    """A knit of the library.

    Attributes
    ----------
    name : str
        Library name, e.g. ``"e_glass_plain"``.
    yarn : str
        Name of the library yarn it is knitted from.
    L : float
        Yarn length per stitch [mm] (section 2.2).
    W0, C0 : float
        Wale width and course length at rest [mm] (section 2.2).
    source : str
        Where the numbers come from.
    """

    name: str
    yarn: str
    L: float
    W0: float
    C0: float
    source: str

    def as_dict(self) -> dict:
        """Fields by name."""
        return asdict(self)


@lru_cache(maxsize=None)
def _library() -> tuple[dict, dict]:
    paper = dusserre2015()
    app = paper["apparent_friction"]
    yarns, knits = {}, {}
    for name, y in paper["yarn"].items():
        law = paper["friction_law"][name]
        yarns[name] = Yarn(
            name=name, d=float(y["yarn_diameter_mm"]), B=float(y["bending_stiffness_N_mm2"]),
            friction_b=float(law["b"]), friction_p=float(law["p"]), friction_n=float(law["n"]),
            mu_k=float(app["mu_k"][name]), coiling_angle_deg=float(app["mean_coiling_angle_deg"][name]),
            m=float(app["m"][name]),
            source=f"{SOURCE}: Table 1 (d, B), Table 3 (b, p, n), section 3.4 (mu_k, coiling angle, m)")
    k = paper["knit"]
    for name, L in k["stitch_length_mm"].items():
        knits[f"{name}_plain"] = Knit(
            name=f"{name}_plain", yarn=name, L=float(L), W0=float(k["wale_width_mm"]),
            C0=float(k["course_length_mm"]), source=f"{SOURCE}: section 2.2 (L, W0, C0)")
    return yarns, knits


def yarn_names() -> list[str]:
    """Names of the library yarns."""
    return sorted(_library()[0])


def knit_names() -> list[str]:
    """Names of the library knits."""
    return sorted(_library()[1])


def yarn(name: str, field: str = "yarn.material") -> Yarn:
    """The library yarn ``name``.

    Raises
    ------
    KnitsimInputError
        Unknown name; the message names ``field`` and lists the known yarns.
    """
    lib = _library()[0]
    if name not in lib:
        raise KnitsimInputError(f"{field} = {name!r}: unknown yarn (known: {', '.join(sorted(lib))})")
    return lib[name]


def knit(name: str, field: str = "knit.material") -> Knit:
    """The library knit ``name``.

    Raises
    ------
    KnitsimInputError
        Unknown name; the message names ``field`` and lists the known knits.
    """
    lib = _library()[1]
    if name not in lib:
        raise KnitsimInputError(f"{field} = {name!r}: unknown knit (known: {', '.join(sorted(lib))})")
    return lib[name]
