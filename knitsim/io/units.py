"""Units a lab writes a column in, and the factor to knitsim's own (mm, N): the one table of ``knitsim dahl fit``
and ``knitsim capstan fit`` (a probe's capstan records in cN were refused where ``dahl fit`` converted a force in cN).

A unit is read as a header writes it, in brackets after the column's name or in a units row (``1/cm``, ``gf cm/cm``,
``mN``); :func:`parse_unit` gives the quantity it measures and the factor to the internal unit, :func:`identities`
the identities that make the factor (said to the user on a ``read:`` line).
"""
from __future__ import annotations

import re

#: gram-force [N] and centimetre [mm]: the KES units of the paper's table
GF_N = 9.80665e-3
CM_MM = 10.0
#: lengths a column's unit may be written in, in mm (casefold): 1 cm = 10 mm, 1 m = 1000 mm, 1 um = 1e-3 mm
LENGTH_MM = {"mm": 1.0, "cm": CM_MM, "m": 1000.0, "um": 1e-3, "\u00b5m": 1e-3, "\u03bcm": 1e-3}
#: forces, in N (casefold): 1 gf = 1 g x 9.80665 m/s^2 (standard gravity) = 9.80665e-3 N; 1 mN = 1e-3 N,
#: 1 cN = 1e-2 N, 1 kN = 1e3 N
FORCE_N = {"n": 1.0, "mn": 1e-3, "cn": 1e-2, "kn": 1e3, "gf": GF_N}
_L = "(" + "|".join(sorted(LENGTH_MM, key=len, reverse=True)) + ")"
_F = "(" + "|".join(sorted(FORCE_N, key=len, reverse=True)) + ")"
#: the quantities a column may hold, with the unit it is read in inside (KES: curvature, moment per width)
INTERNAL_UNIT = {"curvature": "1/mm", "moment per width": "N.mm/mm", "displacement": "mm", "force": "N"}


def parse_unit(unit: str) -> tuple[str, float] | None:
    """The quantity a column's unit says and the factor that converts it to the internal unit.

    Parameters
    ----------
    unit : str
        As a header writes it: ``1/cm``, ``cm^-1``, ``gf cm/cm``, ``gf.cm/cm``, ``N mm/mm``, ``mm``, ``gf``.

    Returns
    -------
    (str, float) or None
        A key of :data:`INTERNAL_UNIT` and the factor (value in the internal unit = factor x value as
        written), ``("moment", factor to N.mm)`` for a moment not per unit width (refused by the caller: it
        needs the specimen's width), or None for a unit not known.

    Notes
    -----
    The factors follow from 1 gf = 9.80665e-3 N and 1 cm = 10 mm: a curvature in 1/cm is 1/(10 mm), so
    x 0.1 to 1/mm; a moment per width in gf.cm/cm is 9.80665e-3 N x 10 mm / 10 mm, so x 9.80665e-3 to
    N.mm/mm (the widths' cm cancel the lever arm's; the same number as gf -> N).
    """
    parts = unit_parts(unit)
    if parts is None:
        return None
    quantity, force, lengths = parts
    if quantity == "curvature":
        return quantity, 1.0 / LENGTH_MM[lengths[0]]
    if quantity == "displacement":
        return quantity, LENGTH_MM[lengths[0]]
    if quantity == "force":
        return quantity, FORCE_N[force]
    if quantity == "moment per width":
        return quantity, FORCE_N[force] * LENGTH_MM[lengths[0]] / LENGTH_MM[lengths[1]]
    return quantity, FORCE_N[force] * LENGTH_MM[lengths[0]]


def unit_parts(unit: str) -> tuple[str, str | None, tuple[str, ...]] | None:
    """:func:`parse_unit`'s reading of a unit: the quantity, its force unit (None for a length or a curvature) and
    its length units, as keys of :data:`FORCE_N` and :data:`LENGTH_MM`; None for a unit not known."""
    u = unit.casefold().strip()
    for sep in ("\u00b7", "\u22c5", "*", "\u00d7", " "):    # a middle dot, a star, a space: one product, gf.cm
        u = u.replace(sep, ".")
    u = re.sub(r"\.+", ".", u).strip(".").replace("./", "/").replace("/.", "/")
    u = u.replace("\u207b\u00b9", "^-1").replace("**-1", "^-1")
    if m := re.fullmatch(rf"1/{_L}|{_L}\^?-1", u):
        return "curvature", None, (m.group(1) or m.group(2),)
    if m := re.fullmatch(_L, u):
        return "displacement", None, (m.group(1),)
    if m := re.fullmatch(_F, u):
        return "force", m.group(1), ()
    if m := re.fullmatch(rf"{_F}\.?{_L}/{_L}", u):
        return "moment per width", m.group(1), (m.group(2), m.group(3))
    if m := re.fullmatch(rf"{_F}\.?{_L}", u):
        return "moment", m.group(1), (m.group(2),)
    return None


def identities(unit: str) -> str:
    """The identities that make a unit's factor to the internal unit: ``1 gf = 0.00980665 N; cm/cm = mm/mm``,
    ``1 m = 1000 mm``, ``1 cN = 0.01 N`` (a probe's 'K [1/m]' was said converted by "1 cm = 10 mm", 'F [cN]' by
    "1 gf = 9.80665e-3 N")."""
    _, force, lengths = unit_parts(unit)
    out = []
    if force is not None and force != "n":
        out.append(f"1 {force[:-1] + 'N' if force.endswith('n') else force} = {FORCE_N[force]:g} N")
    if len(lengths) == 2:            # per width: the lever arm's length over the width's
        out.append(f"{lengths[0]}/{lengths[1]} = {LENGTH_MM[lengths[0]] / LENGTH_MM[lengths[1]]:g} mm/mm")
    elif lengths and LENGTH_MM[lengths[0]] != 1.0:
        out.append(f"1 {lengths[0]} = {LENGTH_MM[lengths[0]]:g} mm")
    return "; ".join(out)


#: speeds a column's unit may be written in: the factor to mm/s as written (casefold, no spaces): 1 mm/min = 1/60
#: mm/s (a tensile tester's crosshead rate, Dusserre's 50 mm/min), 1 m/min = 1000/60 mm/s, 1 cm/s = 10 mm/s.
#: Apart from :func:`parse_unit`'s quantities: ``knitsim dahl fit`` reads no speed column
_SPEED_TEXT = {"mm/s": "1", "mm/min": "1/60", "cm/s": "10", "cm/min": "10/60", "m/s": "1000", "m/min": "1000/60"}
SPEED_MM_S = {u: (float(t.split("/")[0]) / float(t.split("/")[1]) if "/" in t else float(t)) for u, t in _SPEED_TEXT.items()}


def _speed_key(unit: str) -> str:
    return unit.casefold().replace(" ", "").replace("sec", "s")


def speed_factor(unit: str) -> float | None:
    """The factor that converts a speed written in ``unit`` (``mm/min``, ``m / min``, ``mm/sec``) to mm/s, or None for
    a unit not in :data:`SPEED_MM_S`."""
    return SPEED_MM_S.get(_speed_key(unit))


def speed_identity(unit: str) -> str:
    """The identity that makes a speed unit's factor (``1 mm/min = 1/60 mm/s``; "" for mm/s or a unit not known)."""
    t = _SPEED_TEXT.get(_speed_key(unit))
    return "" if t in (None, "1") else f"1 {unit.strip()} = {t} mm/s"
