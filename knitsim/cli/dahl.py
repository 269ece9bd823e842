"""``knitsim dahl``: identify Dahl friction from a hysteresis loop, or synthesise one.

``knitsim dahl fit FILE.csv`` fits ``F = B x + F_dahl(x)`` (Dahl 1976, eq 1 of the
Gemtex KES paper) to a loop and prints the parameters with standard errors;
``knitsim dahl simulate ... --out FILE.csv`` writes a synthetic KES-like loop.

CSV columns (first row names them, units in the name):

* ``kappa_1_mm`` and ``M_N_mm_per_mm`` (default): a KES pure-bending loop,
  curvature [1/mm] and bending moment per unit width [N.mm/mm].  Then sigma and
  B are in N.mm^2/mm, Fc and F0 in N.mm/mm, and the paper's KES units
  (sigma, B: gf.cm^2/cm; Fc: gf.cm/cm) are printed too.
* ``x_mm`` and ``F_N``: a displacement [mm] / force [N] loop (sigma, B in N/mm;
  Fc, F0 in N); used when the defaults are absent.
* a lab's own names with their units, in brackets after the name or in a units row
  (``K [1/cm]``, ``M [gf cm/cm]``, ``K (cm^-1)``: KES-FB2's units; ``x [cm]``, ``F [gf]``),
  found by their units (one curvature and one bending moment per width, or one
  displacement and one force) or named by ``--columns``: converted to the units
  above (1/mm and N.mm/mm, or mm and N), said on a ``read:`` line and in --json
  (``read_notes``, ``conversion``).  A unit it does not know is refused naming the
  header and what to write.
* any other pair given by ``--columns X,F`` (no unit stated): parameters in the
  units of the columns.

The bundled ``scenes/dahl/kes_yarn_loop.csv`` was written by::

    knitsim dahl simulate --row yarn --noise 0.01 --seed 1 --out scenes/dahl/kes_yarn_loop.csv
"""
from __future__ import annotations

import csv
import math
import re
from pathlib import Path

import numpy as np

from ..data import dahl_kes
from ..errors import KnitsimInputError
from ..friction.dahl import ALPHA_MAX, ALPHA_MIN, DahlParams, fit_dahl_loop, kes_loop
from ..friction.identification import FLAG_TEXT
from ..io.results import add_output_flags, prepare_output_file
from ..io.table_input import has_columns, header_candidates, notes_of, split_unit, stated_units
from ..io.units import CM_MM, GF_N, INTERNAL_UNIT, parse_unit
from ..io.units import identities as _identities
from .common import add_json_flag, plain_help, print_json, read_csv_columns

KES_COLUMNS = ("kappa_1_mm", "M_N_mm_per_mm")
XF_COLUMNS = ("x_mm", "F_N")
#: KES-FB2 pure-bending range, +-2.5 1/cm, in 1/mm
KES_AMPLITUDE_1_MM = 2.5 / CM_MM
#: a kappa_1_mm column beyond this many times the KES range is warned of as a curvature in 1/cm
KES_UNIT_CHECK = 4.0

#: dimensionless units (a column stated so is read as it is, in the columns' own units)
_NO_UNIT = ("-", "1", "", "mm/mm", "m/m")
#: what to write, for a refusal
_WHAT_TO_WRITE = ("write a KES loop as a curvature in 1/cm or 1/mm ('K [1/cm]') and a bending moment per width "
                  "in gf cm/cm or N mm/mm ('M [gf cm/cm]'), or a loop of a displacement in mm, cm or m and a force "
                  "in N, mN, cN or gf ('x [mm]', 'F [N]')")


def register(subparsers) -> None:
    """Add ``knitsim dahl`` with its ``fit`` and ``simulate`` subcommands."""
    parser = subparsers.add_parser(
        "dahl", help="Dahl friction: fit a hysteresis loop (KES bending) or simulate one",
        description=plain_help(__doc__.split("\n\n")[0]) + "\n\nSee 'knitsim dahl fit --help' and 'knitsim dahl simulate --help'.")
    sub = parser.add_subparsers(dest="dahl_command", metavar="ACTION")
    sub.required = True

    fit = sub.add_parser(
        "fit", help="fit Dahl parameters (sigma, Fc[, alpha][, B], F0) to a loop in a CSV file",
        description="Fit F = B x + F_dahl(x history) by nonlinear least squares; print parameters with "
                    "standard errors and write a PNG of data vs fit. Default columns kappa_1_mm, "
                    "M_N_mm_per_mm (KES bending: curvature 1/mm, moment per width N.mm/mm), else x_mm, F_N, else "
                    "a lab's two columns found by the units stated in the header (KES-FB2's K [1/cm], M [gf cm/cm]; "
                    "x [cm], F [gf]): converted to 1/mm and N.mm/mm (or mm and N), said on 'read:' lines. "
                    "Exit status 0: a usable law; 1: flagged (a parameter not identified, a loop that gains "
                    "energy, rows out of order, no convergence, residuals beyond the loop's own noise, an offset, a loop "
                    "that does not close: NOT A DAHL LAW YOU CAN USE, --json usable/flags); "
                    "2: bad input.")
    fit.add_argument("file", metavar="FILE.csv", help="the loop, samples in order of acquisition")
    fit.add_argument("--columns", metavar="X,F", help="names of the input and output columns "
                     "(default kappa_1_mm,M_N_mm_per_mm, else x_mm,F_N, else found by their units); a unit "
                     "stated in the header or after the name ('K [1/cm],M [gf cm/cm]') is converted, else the "
                     "parameters are in the columns' own units")
    fit.add_argument("--elastic", action="store_true", help="fit an elastic part B x in parallel")
    fit.add_argument("--alpha", default="1", metavar="free|VALUE",
                     help="exponent alpha of the Dahl law dF/dx = sigma (1 - F/Fc sign(dx))^alpha (shape of the "
                          "approach to Fc): 'free' to fit it, or a fixed value in "
                          f"[{ALPHA_MIN:g}, {ALPHA_MAX:g}] (default 1, as in the paper)")
    fit.add_argument("--png", metavar="OUT.png", help="plot file (default FILE_dahl_fit.png next to the CSV)")
    fit.add_argument("--no-png", action="store_true", help="do not write a plot")
    fit.add_argument("--overwrite", action="store_true",
                     help="replace an existing plot file (--png, or the default FILE_dahl_fit.png); "
                          "without it an existing plot file is refused")
    add_json_flag(fit)
    fit.set_defaults(func=run_fit)

    sim = sub.add_parser(
        "simulate", help="write a synthetic KES-like Dahl loop to a CSV file",
        description="Write a loop 0 -> +A -> -A -> ... -> 0 of F = B x + F_dahl(x) (+ noise). Parameters are in "
                    "the units of the columns (defaults: sigma, B in N.mm^2/mm, Fc in N.mm/mm; or as --columns states "
                    "them, 'K [1/cm],M [gf cm/cm]'), or taken from a row of the paper's table (--row, converted from "
                    "gf.cm^2/cm and gf.cm/cm to the columns' units).")
    sim.add_argument("--sigma", type=float, help="Dahl stiffness sigma (dF/dx at F = 0)")
    sim.add_argument("--Fc", type=float, help="Coulomb force Fc")
    sim.add_argument("--alpha", type=float, default=None,
                     help="Dahl shape exponent (default 1, or the --row's; with --row it replaces the row's)")
    sim.add_argument("--row", metavar="SAMPLE",
                     help="take sigma, Fc, alpha from this row of dahl_kes.toml ("
                          + ", ".join(repr(r["sample"]) for r in dahl_kes()["dahl"]) + ")")
    sim.add_argument("--B", type=float, default=0.0, help="elastic stiffness in parallel (default 0)")
    sim.add_argument("--amplitude", type=float, default=None,
                     help=f"largest |x|, in the x column's unit (default {KES_AMPLITUDE_1_MM} 1/mm = KES 2.5 1/cm)")
    sim.add_argument("--cycles", type=int, default=3, help="number of full swings (default 3)")
    sim.add_argument("--points", type=int, default=100, help="samples per quarter cycle (default 100)")
    sim.add_argument("--noise", type=float, default=0.0,
                     help="standard deviation of Gaussian noise on F, as a fraction of Fc (default 0)")
    sim.add_argument("--seed", type=int, default=1, help="seed of the noise (default 1)")
    sim.add_argument("--columns", metavar="X,F", default=",".join(KES_COLUMNS),
                     help="names of the columns written (default kappa_1_mm,M_N_mm_per_mm)")
    sim.add_argument("--out", required=True, metavar="FILE.csv", help="CSV file to write")
    add_output_flags(sim, what="file")
    sim.set_defaults(func=run_simulate)


def _parse_columns(text: str) -> tuple[str, str]:
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 2 or not all(parts) or parts[0] == parts[1]:
        raise KnitsimInputError(f"--columns = {text!r}: expected two different names 'X,F'")
    return parts[0], parts[1]


def _choose_columns(path: Path, columns: str | None) -> tuple[str, str]:
    if columns:
        return _parse_columns(columns)
    # the header as the reader finds it (a preamble, # comments, any case, UTF-16): our own names first, then a
    # lab's found by their units (KES-FB2 writes K [1/cm], M [gf cm/cm]: a blind probe's such file was refused as
    # missing kappa_1_mm), else the KES names (the refusal names them)
    for names in (KES_COLUMNS, XF_COLUMNS):
        if has_columns(path, names):
            # our names as written; a lab's that stand for them (x, F for x_mm, F_N) are read by the units they state,
            # as any lab's columns are (a probe's 'x [cm]', 'F [gf]', the --help's own example, was refused as not
            # x_mm's unit, 'F [mN]' as not F_N's, where 'disp [cm]', 'force [gf]' were converted)
            if len(stated_units(path, names)) < len(names):
                return _columns_by_unit(path) or names
            return names
    return _columns_by_unit(path) or KES_COLUMNS


def _bare(cell: str) -> str:
    """A header cell's name without its unit (``K [1/cm]`` -> ``K``: the reader's split_unit)."""
    return split_unit(cell)[0] or cell


def _unread(cell: str, unit: str, parsed) -> str:
    """Why the unit of header cell ``cell`` is not read (a refusal's clause)."""
    if parsed is not None and parsed[0] == "moment":
        return (f"{cell!r} states a moment ({unit}), not a moment per unit width: divide the column by the "
                "specimen's width and write its unit per width (gf cm/cm)")
    return f"{cell!r}: the unit {unit!r} is not one knitsim dahl fit reads"


#: the pairs of quantities a loop's columns may be (input, output): KES bending, or a displacement and a force
_PAIRS = (("curvature", "moment per width"), ("displacement", "force"))


def _columns_by_unit(path: Path) -> tuple[str, str] | None:
    """The loop's columns found by their units, where they lack our names: on the first line stating two units
    or more of which one is a curvature, a length, a moment or a force, one curvature and one moment per width
    (or one displacement and one force), asked for as ``name [unit]``; None if no line states such units.  A line
    whose units make no loop is refused only where no later line makes one (a preamble ``Sample;yarn A`` over the
    header ``K;M`` reads that header as its units row, ``M`` a metre: a probe's KES file was refused so)."""
    refusal = None
    for line, cells, units in header_candidates(path):
        stated = {j: u for j, u in enumerate(units) if u is not None and u.strip().casefold() not in _NO_UNIT}
        if len(stated) < 2:
            continue
        parsed = {j: parse_unit(u) for j, u in stated.items()}
        by_quantity: dict[str, list[int]] = {}
        for j, p in parsed.items():
            if p is not None:
                by_quantity.setdefault(p[0], []).append(j)
        if not by_quantity:
            continue                     # a preamble's units (time [s], angle [deg]), not the loop's header
        for pair in _PAIRS:
            if all(len(by_quantity.get(q, ())) == 1 for q in pair):
                return tuple(f"{_bare(cells[j])} [{units[j]}]" for j in (by_quantity[q][0] for q in pair))
        why = [_unread(cells[j], stated[j], p) for j, p in parsed.items() if p is None or p[0] == "moment"]
        if "curvature" in by_quantity and "force" in by_quantity:
            # gf.cm/cm is dimensionally gf, but a force column beside a curvature is more likely a moment not
            # per width, or a unit shortened: which one is not said
            why += [f"{cells[j]!r} states a force: write a bending moment per width as gf cm/cm or N mm/mm"
                    for j in by_quantity["force"]]
        refusal = refusal or KnitsimInputError(
            f"{path}: row {line}: the columns {', '.join(repr(cells[j]) for j in stated)} state their units, but not "
            f"one curvature and one bending moment per width, nor one displacement and one force"
            + (f" ({'; '.join(why)})" if why else "") + f": {_WHAT_TO_WRITE}; or name the two columns with --columns X,F")
    if refusal is not None:
        raise refusal
    return None


#: our own column names (casefold) and the quantity each holds, in the internal unit
_OWN = {"kappa_1_mm": "curvature", "m_n_mm_per_mm": "moment per width", "x_mm": "displacement", "f_n": "force"}


def _resolve_columns(path: Path, names: tuple[str, str]) -> tuple[list[dict], tuple[str, str] | None]:
    """How each of the two columns asked for is read: the name to ask the reader, its header cell, its unit, the
    quantity it holds and the factor to the internal unit (1 for our own names, and for a column whose unit is
    not stated: the columns' own units).  Returns the two and the pair of quantities, None when the units are
    the columns' own.

    Raises
    ------
    KnitsimInputError
        A unit not known (naming the header and what to write), a moment not per unit width, two quantities
        that are no loop (a curvature and a force), or one column converted while the other's unit is not stated.
    """
    return _columns_read(stated_units(path, names), names, str(path))


def _columns_read(found: dict, names: tuple[str, str], where: str) -> tuple[list[dict], tuple[str, str] | None]:
    """:func:`_resolve_columns` of the header cells and units ``found`` for the two names (``{name: (cell, unit)}``;
    a name not there is its own cell, its unit not stated); refusals start with ``where``."""
    cols = []
    for name in names:
        cell, unit = found.get(name, (name, None))
        key = _bare(name).casefold()
        if key in _OWN:
            # our names say their unit; one stated beside it is checked by the reader
            cols.append({"name": name, "header": cell, "unit": INTERNAL_UNIT[_OWN[key]], "quantity": _OWN[key],
                         "factor": 1.0, "stated": False})
            continue
        if unit is None or unit.strip().casefold() in _NO_UNIT:
            cols.append({"name": name, "header": cell, "unit": None, "quantity": None, "factor": 1.0,
                         "stated": False})
            continue
        parsed = parse_unit(unit)
        if parsed is None or parsed[0] == "moment":
            raise KnitsimInputError(f"{where}: {_unread(cell, unit, parsed)}: {_WHAT_TO_WRITE}")
        asked = split_unit(name)[1]
        if asked is not None and parse_unit(asked) != parsed:
            # --columns 'M [N mm/mm]' over a file's 'M [gf cm/cm]': which one holds is not said
            raise KnitsimInputError(f"{where}: --columns names {name!r}, but the file states {unit!r} for "
                                    f"{cell!r}: give the column's name as the file has it, or correct its unit")
        cols.append({"name": f"{_bare(cell)} [{unit}]", "header": cell, "unit": unit, "quantity": parsed[0],
                     "factor": parsed[1], "stated": True})
    pair = (cols[0]["quantity"], cols[1]["quantity"])
    if None not in pair:
        if pair not in _PAIRS:
            raise KnitsimInputError(
                f"{where}: the columns {cols[0]['header']!r} ({pair[0]}) and {cols[1]['header']!r} ({pair[1]}) are no "
                f"loop knitsim dahl fit reads (input, then output): {_WHAT_TO_WRITE}")
        return cols, pair
    known = [c for c in cols if c["quantity"] is not None and c["factor"] != 1.0]
    if known:
        # converting one column and not the other would give parameters in a mixture of units
        other = next(c for c in cols if c["quantity"] is None)
        raise KnitsimInputError(
            f"{where}: the column {known[0]['header']!r} states its unit ({known[0]['unit']}) and {other['header']!r} "
            f"does not: state it ({_WHAT_TO_WRITE})")
    return cols, None


def _read_note(col: dict) -> str:
    """The ``read:`` line of a column read in a unit it states (the conversion, and why its factor)."""
    internal = INTERNAL_UNIT[col["quantity"]]
    if col["factor"] == 1.0:
        return f"column {col['header']!r} read as the {col['quantity']} in {internal}"
    why = _identities(col["unit"])
    return (f"column {col['header']!r} read as the {col['quantity']} in {col['unit']}: x {col['factor']:.6g} to "
            f"{internal} ({why})")


def _units(pair: tuple[str, str] | None, xcol: str, fcol: str) -> dict[str, str]:
    if pair == _PAIRS[0]:
        f_unit, s_unit = "N.mm/mm", "N.mm^2/mm"
    elif pair == _PAIRS[1]:
        f_unit, s_unit = "N", "N/mm"
    else:
        f_unit, s_unit = f"[{fcol}]", f"[{fcol}]/[{xcol}]"
    return {"sigma": s_unit, "Fc": f_unit, "alpha": "", "B": s_unit, "F0": f_unit}


def _parse_alpha(text: str) -> float | None:
    if text.strip().lower() == "free":
        return None
    expected = f"expected 'free' or a number in [{ALPHA_MIN:g}, {ALPHA_MAX:g}] (the paper: 1)"
    try:
        value = float(text)
    except ValueError:
        raise KnitsimInputError(f"--alpha = {text!r}: {expected}") from None
    if not (math.isfinite(value) and ALPHA_MIN <= value <= ALPHA_MAX):
        raise KnitsimInputError(f"--alpha = {text!r}: {expected}")
    return value




def _flagged(fit) -> list[str]:
    return [n for n in fit.names if fit.param_status.get(n) in FLAG_TEXT]


def _plot(path: Path, x, F, fit, xcol: str, fcol: str, source: Path | None = None) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.8))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    ax.plot(x, F, ".", ms=2.5, color="0.45", label="data")
    ax.plot(x, fit.predict(x), "-", lw=1.2, color="C3",
            label=f"Dahl fit: sigma={fit.sigma:.4g}, Fc={fit.Fc:.4g}, alpha={fit.alpha:.3g}"
                  + (f", B={fit.B:.4g}" if "B" in fit.names else ""))
    ax.set_xlabel(xcol)
    ax.set_ylabel(fcol)
    ax.grid(alpha=0.3)
    ax.legend(loc="center", fontsize=8)  # a Dahl loop is empty inside
    title = f"Dahl fit of {(source or path).name}"
    bad = _flagged(fit)
    # the loop's flags as fit_dahl_loop sets them (out of order, energy gained, ...): not found again in the text
    notes = ([f"NOT IDENTIFIED: {', '.join(bad)}"] if bad else []) + list(fit.loop_flags)
    if notes:
        ax.set_title(title + "\n" + "; ".join(notes), fontsize=9, color="C3")
    else:
        ax.set_title(title, fontsize=9)
    fig.tight_layout()
    try:
        Path(path).parent.mkdir(parents=True, exist_ok=True)   # missing folders created, as every output's are
        fig.savefig(path, dpi=120)
    except OSError as exc:
        raise KnitsimInputError(f"--png = {str(path)!r}: cannot write ({exc.strerror})") from None


#: what the summary says first when a fit is flagged (as ``knitsim capstan fit`` and ``calibrate`` do)
UNUSABLE = "NOT A DAHL LAW YOU CAN USE"


def fit_flags(fit) -> list[str]:
    """Why a Dahl fit is not a law to use (empty: usable): each fitted parameter not identified (its
    status, FLAG_TEXT), a loop that gains energy, rows out of order, an optimiser that did not converge,
    residuals beyond the loop's noise, an offset, a loop that does not close (``fit.loop_flags``).
    A blind probe's sign-flipped loop printed sigma and Fc NOT IDENTIFIED and a warning, and exited 0 with
    "success": true: a script could not tell."""
    # the loop's own flags are set by fit_dahl_loop where it writes their warnings (a blind probe's offset and
    # drifting loops exited 0 with nothing said)
    return [f"{n} {FLAG_TEXT[fit.param_status[n]]}" for n in _flagged(fit)] + list(fit.loop_flags)


def run_fit(args) -> int:
    """``knitsim dahl fit`` (exit status: 0 usable, 1 flagged; :func:`fit_flags`)."""
    path = Path(args.file)
    alpha = _parse_alpha(args.alpha)
    names = _choose_columns(path, args.columns)
    # each column's unit, from its header (KES-FB2's K [1/cm] and M [gf cm/cm]): read in the internal units (a
    # blind probe's such file was refused, and with --columns fitted unconverted: sigma, Fc in gf units)
    cols, pair = _resolve_columns(path, names)
    png = None
    if not args.no_png:
        png = prepare_output_file(args.png or path.with_name(path.stem + "_dahl_fit.png"), args.overwrite, "--png",
                                  suffix=".png")
    from ..diagnosis.measured import drop_copied_rows
    try:
        raw = read_csv_columns(path, [c["name"] for c in cols])
    except KnitsimInputError as exc:
        if args.columns or names != KES_COLUMNS or "missing column" not in str(exc):
            # (the hint is on finding a lab's columns: a probe's NaN in row 502 was told to state its units)
            raise
        raise KnitsimInputError(f"{exc}; a lab's columns are read with their units stated ('K [1/cm]', "
                                "'M [gf cm/cm]'), or name them with --columns X,F") from None
    # a row copied (pasted twice) is no second measurement: counted twice it would shrink the standard errors
    data = drop_copied_rows(raw)
    x, F = (data[c["name"]] * c["factor"] for c in cols)
    # what the reader did (rows left out as copies, a footer skipped, a workbook's sheet): said, as diagnose and
    # capstan fit say it (a probe's loop pasted twice read "1201 points" and nothing of the 1201 rows left out)
    read_notes = list(notes_of(data)) + [_read_note(c) for c in cols if c["stated"]]
    if pair is None:
        read_notes.append(f"the columns {cols[0]['header']!r}, {cols[1]['header']!r} state no unit: the parameters "
                          "are in the columns' own units (state them, 'K [1/cm]', to have them converted)")
    # the columns as the fit and the plot name them: in the units they are fitted in
    xcol, fcol = (f"{_bare(c['header'])} [{INTERNAL_UNIT[c['quantity']]}]" if c["stated"] else c["header"]
                  for c in cols)
    try:
        fit = fit_dahl_loop(x, F, elastic=args.elastic, alpha=alpha, labels=(xcol, fcol))
    except KnitsimInputError as exc:
        raise KnitsimInputError(f"{path}: {exc}") from None
    if cols[0]["quantity"] == "curvature" and float(np.max(np.abs(x))) > KES_UNIT_CHECK * KES_AMPLITUDE_1_MM:
        # a KES loop's curvature in 1/cm under kappa_1_mm (or 1/mm) reads 10 times too large (a blind probe's
        # file, fitted without a word: sigma and B then 10 and 100 times off)
        fix = (f"check the unit stated in {cols[0]['header']!r}" if cols[0]["stated"] else
               "if the column holds 1/cm, divide it by 10 (kappa_1_mm is per mm)")
        fit.warnings.append(
            f"the curvature reaches {float(np.max(np.abs(x))):.3g} 1/mm, {float(np.max(np.abs(x))) / KES_AMPLITUDE_1_MM:.0f} "
            f"times the KES-FB2 range (+-{KES_AMPLITUDE_1_MM:g} 1/mm = +-2.5 1/cm): {fix}")
    if png is not None:
        _plot(png, x, F, fit, xcol, fcol, source=path)
    flags = fit_flags(fit)
    units = _units(pair, xcol, fcol)
    values = {n: getattr(fit, n) for n in ("sigma", "Fc", "alpha", "B", "F0")}
    conversion = {axis: {"column": c["header"], "unit": c["unit"], "to": INTERNAL_UNIT[c["quantity"]],
                         "factor": c["factor"]} for axis, c in zip(("x", "F"), cols) if c["stated"]} or None
    kes = None
    if pair == _PAIRS[0]:
        # N.mm^2/mm -> gf.cm^2/cm and N.mm/mm -> gf.cm/cm (the paper's table)
        to_kes = {"sigma": 1.0 / (GF_N * CM_MM), "B": 1.0 / (GF_N * CM_MM), "Fc": 1.0 / GF_N, "F0": 1.0 / GF_N}
        kes = {n: {"value": values[n] * f, "stderr": fit.stderr.get(n, 0.0) * f} for n, f in to_kes.items()}
    if args.json:
        print_json({
            "file": str(path), "columns": {"x": cols[0]["header"], "F": cols[1]["header"]},
            "read_notes": read_notes, "conversion": conversion, "n_points": fit.n_points,
            "reversals": fit.reversals, "parameters": values, "stderr": fit.stderr, "fixed": fit.fixed,
            "units": units, "kes_units": kes, "rms": fit.rms, "success": fit.success, "message": fit.message,
            "png": str(png) if png else None, "param_status": fit.param_status, "lower_bounds": fit.lower_bounds,
            "warnings": fit.warnings, "usable": not flags, "flags": flags,
            "noise": {"sd": fit.noise_sd, "estimated": fit.noise_estimated, "rms_over_sd": fit.rms / fit.noise_sd},
            "closure": fit.closure,
        })
        return 1 if flags else 0
    if flags:
        print(f"{UNUSABLE}: " + "; ".join(flags) + " (the warnings below say why)")
    print(f"Dahl fit of {path} ({fit.n_points} points, {fit.reversals} reversals; x = {cols[0]['header']}, "
          f"F = {cols[1]['header']})")
    for note in read_notes:
        print(f"  read: {note}")
    for n in ("sigma", "Fc", "alpha", "B", "F0"):
        if n in fit.stderr:
            line = f"  {n:<6} = {values[n]:.6g} +- {fit.stderr[n]:.2g} {units[n]}".rstrip()
        else:
            line = f"  {n:<6} = {values[n]:.6g} {units[n]}".rstrip() + " (fixed)"
        if kes and n in kes and n in fit.stderr:
            unit = "gf.cm/cm" if n in ("Fc", "F0") else "gf.cm^2/cm"
            line += f"   [{kes[n]['value']:.4g} +- {kes[n]['stderr']:.2g} {unit}]"
        flag = FLAG_TEXT.get(fit.param_status.get(n, ""))
        if flag:
            line += f"   <- {flag}"
        if n in fit.lower_bounds:
            line += f" ({n} >= {fit.lower_bounds[n]:.3g} {units[n]}, one-sided 95 %)".replace(" ,", ",")
        print(line)
    print(f"  rms residual = {fit.rms:.3g} {units['F0']}, {fit.rms / fit.noise_sd:.3g} times the loop's noise "
          f"(sd {fit.noise_sd:.3g}, " + ("read off its rows)" if fit.noise_estimated else
                                        "assumed: the rows are smoother than a measurement's)")
          + ("" if fit.success else f"  (optimizer: {fit.message})"))
    for w in fit.warnings:
        print(f"  warning: {w}")
    if png:
        print(f"  plot: {png}")
    return 1 if flags else 0


def _written_factors(xcol: str, fcol: str) -> tuple[float, float]:
    """The factors from the units the columns to write state to the internal units (1 for our own names and for
    columns stating no unit: the columns' own units), refused as a file with that header would be by `dahl fit`
    (:func:`_columns_read`)."""
    cols, _ = _columns_read({n: (n, split_unit(n)[1]) for n in (xcol, fcol)}, (xcol, fcol), "--columns")
    return cols[0]["factor"], cols[1]["factor"]


def run_simulate(args) -> int:
    """``knitsim dahl simulate``."""
    xcol, fcol = _parse_columns(args.columns)
    # the values are written in the units the columns state ('K [1/cm]', 'M [gf cm/cm]'), which `dahl fit` reads
    # back: a blind probe's --row yarn under those columns wrote 1/mm and N.mm/mm, which the fit read as 1/cm and
    # gf cm/cm (sigma 0.006 and Fc 0.00014 gf units for the row's 0.061 and 0.014)
    fx, fF = _written_factors(xcol, fcol)
    amplitude = KES_AMPLITUDE_1_MM / fx if args.amplitude is None else args.amplitude
    if args.row is not None:
        if args.sigma is not None or args.Fc is not None:
            raise KnitsimInputError("--row: give either --row or --sigma/--Fc, not both")
        rows = {r["sample"]: r for r in dahl_kes()["dahl"]}
        if args.row not in rows:
            raise KnitsimInputError(f"--row = {args.row!r}: expected one of {', '.join(map(repr, rows))}")
        r = rows[args.row]
        # paper units gf.cm^2/cm and gf.cm/cm -> N.mm^2/mm and N.mm/mm; an --alpha given replaces the row's
        # (a blind probe's --row yarn --alpha 3 wrote the row's alpha 1 and said alpha=1, the 3 dropped)
        alpha = float(r["alpha"]) if args.alpha is None else args.alpha
        source = f"; from row {args.row!r}" + ("" if args.alpha is None else
                                              f", alpha {alpha:g} given in place of the row's {float(r['alpha']):g}")
    else:
        if args.sigma is None or args.Fc is None:
            raise KnitsimInputError("--sigma/--Fc: both are required (or use --row SAMPLE)")
        alpha, source = (1.0 if args.alpha is None else args.alpha), ""
    if not (math.isfinite(alpha) and ALPHA_MIN <= alpha <= ALPHA_MAX):
        raise KnitsimInputError(f"--alpha = {alpha!r}: must be in [{ALPHA_MIN:g}, {ALPHA_MAX:g}] (the range "
                                "`dahl fit` identifies)")
    if args.row is not None:
        # N.mm^2/mm and N.mm/mm, then in the columns' units (F = fF F_written, x = fx x_written)
        params = DahlParams(r["sigma"] * GF_N * CM_MM * fx / fF, r["Fc"] * GF_N / fF, alpha)
    else:
        params = DahlParams(args.sigma, args.Fc, alpha)
    if not (math.isfinite(args.noise) and args.noise >= 0):
        raise KnitsimInputError(f"--noise = {args.noise!r}: must be >= 0")
    if not math.isfinite(args.B):
        raise KnitsimInputError(f"--B = {args.B!r}: must be finite")
    x, F = kes_loop(params, amplitude, args.cycles, args.points, B=args.B,
                    noise=args.noise * params.Fc, seed=args.seed)
    out = prepare_output_file(args.out, args.overwrite)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)          # missing folders created, as every output's are
        with out.open("w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh)
            w.writerow([xcol, fcol])
            for xi, Fi in zip(x, F):
                w.writerow([f"{xi:.12g}", f"{Fi:.12g}"])
    except OSError as exc:
        raise KnitsimInputError(f"--out = {str(out)!r}: cannot write ({exc.strerror})") from None
    print(f"wrote {x.size} samples to {out} (sigma={params.sigma:.6g}, Fc={params.Fc:.6g}, "
          f"alpha={params.alpha:g}, B={args.B:g}{source})")
    return 0
