"""Specimens of a calibration: a knit between grips, and what was measured on it.

A tester reports, per specimen, the force on the whole specimen against the
grip strain (grip displacement / gauge length), often only as the upper and
lower envelopes of the scatter of several tests; the knit is known by its
loop length L and, with less certainty, its wale and course spacings W0, C0
(measured or estimated, e.g. from Munden's constants).  :class:`SpecimenData`
holds that, on the rows the fit uses:

- the rows are a uniform grid of grip strains from one step to the end of the
  data (the smaller of the envelopes' last strains), so that a share of rows
  is a share of the strain range; a file that starts above the first row is
  refused (its rows there would be made up);
- the target is the measured curve there (linear interpolation) when one is
  given, else the mid-line of the envelopes;
- each row's weight is 1 / its sd: the half-width of the envelope band (the
  band is the tolerance a fit must meet), but not below the accuracy of the
  testing machine's force, ``accuracy_rel`` of the reading (0.5 %: ISO 7500-1
  class 0.5; two envelopes that cross leave no width there, though the
  specimens scatter and the machine reads no better); for a curve without a
  band, its noise (given, or estimated from the curve,
  :mod:`knitsim.diagnosis.noise`).

Files: CSV (``,`` ``;`` or tab, :mod:`knitsim.io.table_input`) with a strain
column (``strain`` or ``strain_mm_per_mm``) and a force column, the total
force (``load_N`` or ``force_N``) or the force per wale
(``force_per_wale_N``).  Units N and mm; strain dimensionless.  A ``cycle`` column, where there is one, is
checked as the diagnosis checks it: a loading curve is one cycle
(:func:`knitsim.diagnosis.measured.read_cycle_column`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import KnitsimInputError
from ..diagnosis.measured import (
    HOLD_TRAVEL_TOLS, PER_CENT_HINT, STRAIN_TOL_REL, TEST_LABELS, TIME_LABELS, compression_limit, drop_copied_rows,
    flat_top_note, flat_tops, force_holds, hold_note, pasted_block, pasted_note, refuse_few_rows, refuse_negative_force,
    read_cycle_column, refuse_no_response, refuse_reversed_rows, refuse_several_tests, strain_tolerance,
    zero_offset_below,
)
from ..diagnosis.noise import CurveNoise, curve_noise, reading_jitter, steeper_slopes
from ..io.table_input import LAB_ALIASES, notes_of, read_csv_columns

STRAIN_COLUMNS = ("strain", "strain_mm_per_mm")
TOTAL_COLUMNS = ("load_N", "force_N")
PER_WALE_COLUMNS = ("force_per_wale_N",)
#: knit geometry a specimen states (mm), and may let the fit move within its uncertainty
GEOMETRY = ("L", "W0", "C0")
#: relative accuracy of a tensile tester's force reading (ISO 7500-1 class 0.5): the least sd of a band's row
FORCE_ACCURACY_REL = 0.005


@dataclass(frozen=True)
class MeasuredTable:
    """One file: strain [-] and force [N], total or per wale, with its spreadsheet rows."""

    strain: np.ndarray
    force: np.ndarray
    total: bool
    source: str
    rows: np.ndarray
    strain_column: str = "strain"
    #: the force's noise, from the curve (knitsim.diagnosis.noise)
    noise: CurveNoise | None = None
    #: a load cell's zero below zero read off the force (knitsim.diagnosis.measured.zero_offset_below) and
    #: subtracted from it [N] (0: none seen)
    zero_offset_N: float = 0.0
    #: the sd of the strain column's own jitter (knitsim.diagnosis.noise.reading_jitter; 0: none seen, or steps
    #: that vary while read exactly)
    strain_jitter: float = 0.0
    #: what the reader did that the user must be told (a strain column read in per cent, divided by 100:
    #: knitsim.io.table_input.Columns.notes); () for most files
    notes: tuple = ()


def read_table(path: str | Path) -> MeasuredTable:
    """Read a strain-force file (module docstring); refuses what is wrong, naming file, row and column."""
    path = Path(path)
    cols = read_csv_columns(path, (), STRAIN_COLUMNS + TOTAL_COLUMNS + PER_WALE_COLUMNS, aliases=LAB_ALIASES,
                            labels=TEST_LABELS + ("cycle",) + TIME_LABELS)
    cols = drop_copied_rows(refuse_several_tests(path, cols))
    for group in (STRAIN_COLUMNS, TOTAL_COLUMNS):
        both = [c for c in group if c in cols]
        if len(both) > 1:
            # which one the fit is to follow is not said (a blind probe's Load (N) and Standard force (N) of
            # different sizes: the first was read without a word)
            raise KnitsimInputError(f"{path}: both {both[0]} and {both[1]} are present "
                                    f"({'; '.join(notes_of(cols)) or 'the file names both'}): keep one column")
    s_name = next((c for c in STRAIN_COLUMNS if c in cols), None)
    f_total = next((c for c in TOTAL_COLUMNS if c in cols), None)
    f_wale = next((c for c in PER_WALE_COLUMNS if c in cols), None)
    why = "".join(f"; {w}" for w in cols.not_read)
    if s_name is None:
        raise KnitsimInputError(f"{path}: no strain column (expected one of {', '.join(STRAIN_COLUMNS)}, or a "
                                f"machine's 'Tensile strain' with its unit: 'Tensile strain (%)'){why}")
    if f_total is None and f_wale is None:
        raise KnitsimInputError(f"{path}: no force column (expected the total force {' or '.join(TOTAL_COLUMNS)}, "
                                f"or {PER_WALE_COLUMNS[0]}, or a machine's 'Load', 'Force' or 'Standard force' with "
                                f"its unit: 'Load (N)'){why}")
    if f_total is not None and f_wale is not None:
        raise KnitsimInputError(f"{path}: both a total force ({f_total}) and a force per wale ({f_wale}): "
                                "keep one column")
    strain, rows = cols[s_name], cols["_row"]
    force = cols[f_total or f_wale]
    refuse_few_rows(path, rows)
    # a lab's zero offset and jitter are kept, as the diagnosis keeps them (knitsim.diagnosis.measured): a
    # strain down to -max(0.005, 5 % of the largest) is an extensometer's zero, a step back by at most 1e-3
    # of the strain range is jitter (the running maximum is used, the force is kept); beyond, it is wrong
    limit = compression_limit(strain)
    bad = np.nonzero(strain < limit)[0]
    if len(bad):
        i = int(bad[0])
        raise KnitsimInputError(f"{path}: row {rows[i]}, column {s_name}: {float(strain[i])!r} is negative beyond a "
                                f"zero offset ({limit:.3g}): a tensile test starts at strain 0")
    tol = strain_tolerance(strain)
    # rows in reverse order (or a log from the peak) are said as such, as the diagnosis says them
    refuse_reversed_rows(str(path), strain, tol, lambda i: int(rows[i]), s_name)
    # rows pasted again after later ones, refused as the diagnosis refuses them
    block = pasted_block(strain, force, tol)
    if block is not None:
        raise KnitsimInputError(f"{path}: {pasted_note(block, lambda k: int(rows[k]))} (a test never retraces its "
                                "readings to the last digit of both columns)")
    # a strain back by at most HOLD_TRAVEL_TOLS tolerances below the rows before is a hold's, kept in the loading at
    # the running maximum as the diagnosis keeps it (infer_branches): a clamp or extensometer settling while the force
    # relaxes, a tracked strain wandering at rest (Singal 2024's raw video frames, 21 stockinette runs, were every one
    # refused at a step back of 4 to 7 tolerances, most at rest near strain 0); beyond, an unloading
    clean = np.maximum.accumulate(strain)
    back = np.nonzero(clean - strain > HOLD_TRAVEL_TOLS * tol)[0]
    if len(back):
        i = int(back[0])
        raise KnitsimInputError(f"{path}: row {rows[i]}, column {s_name}: {float(strain[i])!r} is below the rows before "
                                f"(up to {float(clean[i])!r}) by more than a hold's creep ({HOLD_TRAVEL_TOLS:g} times "
                                f"the jitter tolerance {tol:.3g}): an unloading? A calibration reads loading curves "
                                "(strain non-decreasing)")
    if len(clean) < 2 or clean[-1] <= clean[0]:
        raise KnitsimInputError(f"{path}: the strain does not increase (needs a loading curve)")
    cycle = _cycle_numbers(cols.get("cycle"))
    if cycle is not None:
        # a loading curve is one branch, one cycle: a cycle column that changes in it (a step counter, two logs
        # pasted one after the other) is refused as the diagnosis refuses it (before, it was not read)
        read_cycle_column(str(path), cycle, np.ones(len(strain), int), lambda i: int(rows[i]))
    # the force as the diagnosis reads it: a reading around zero is kept, a wrong sign or zero and a
    # force that never rises above the noise (all zero, not connected) are refused
    one = np.ones(len(clean), int)
    noise = curve_noise(clean, force, one, one, source=str(path))
    column = f_total or f_wale
    # a hold whose force relaxes (force_holds): its rows but its first are left out, as the diagnosis leaves them
    # out, and said (the model keeps one force at one strain; fitted, the relaxed rows pull the knit down)
    held = force_holds(strain, force, one, one, noise)
    held_note = ()
    if held:
        held_note = (hold_note(held, clean, lambda i: int(rows[i]), "N" if f_total else "N per wale"),)
        kept = np.ones(len(clean), bool)
        for i, j, _ in held:
            kept[i + 1:j] = False
        strain, clean, force, rows, one = strain[kept], clean[kept], force[kept], rows[kept], one[kept]
        noise = curve_noise(clean, force, one, one, source=str(path))

    def row(i):
        return int(rows[i])
    refuse_negative_force(str(path), force, noise, row, column, offset_use="tared (subtracted)")
    refuse_no_response(str(path), force, noise.sigma_N, row, column)
    # a zero offset below zero is the load cell's (a knit carries no compression): tared, since the model's
    # force has no offset term (left in, a -10 mN zero on a 55 N curve moved phi0 by 3 to 7 sd in a blind
    # probe).  A zero above zero is not told from the knit's own force at rest or a pretension: left in
    zero = _rest_level(force, noise.sigma_N, zero_offset_below(force, noise.sigma_N))
    notes = notes_of(cols) + held_note
    # a force flat at its largest reading while the strain moves on: a saturated load cell, said (a probe's pull
    # clipped at 80 % of its peak read only as a misfit)
    tops = flat_tops(strain, force, tol)
    if tops:
        i = tops[0][0]
        notes += (flat_top_note(tops, strain, force, row, column, "N" if f_total else "N per wale")
                  + f"; a fit reads them as the knit's unless the specimen's end_strain stops below them "
                  f"({float(clean[i - 1]):.4g}, its last row below the limit)",)
    return MeasuredTable(np.asarray(clean, float), np.asarray(force, float) - zero, f_total is not None, str(path),
                         rows, s_name, noise, zero, reading_jitter(strain, one), notes)


def _cycle_numbers(cells) -> np.ndarray | None:
    """A calibration file's ``cycle`` column (its cells as text) as numbers, a blank cell the cycle of the row above
    (a logger that writes the count where a cycle starts); None without the column, or where a cell is no number
    (a column of words counts no cycle the reader knows: it is not read, as before)."""
    if cells is None:
        return None
    out, last = [], float("nan")
    for c in cells:
        c = str(c).strip()
        if c:
            try:
                last = float(c.replace(",", "."))
            except ValueError:
                return None
        out.append(last)
    return np.asarray(out, float) if out and np.isfinite(out[0]) else None


def pretension_strain(grip_strain, pretension: float):
    """The knit's strain at a grip strain when the specimen was pretensioned before the strain origin.

    A tensile tester clamps the specimen and applies a pretension before it sets the gauge length
    ``G`` and the strain origin (textile strip tests, e.g. ISO 13934-1): the knit between the grips, of
    rest length ``G / (1 + e_p)``, is then already at strain ``e_p`` at grip strain 0.  At grip strain
    ``e`` (displacement / G) its length is ``G (1 + e)``, so its strain is

        e_knit = (1 + e_p)(1 + e) - 1 = e_p + e (1 + e_p).

    Parameters
    ----------
    grip_strain : float or ndarray
        Grip strain(s) from the test's origin.
    pretension : float
        ``e_p``: the knit's strain at grip strain 0 (>= 0).

    Returns
    -------
    float or ndarray
    """
    return (1.0 + pretension) * (1.0 + np.asarray(grip_strain, float)) - 1.0


def check_reach(sp: "SpecimenData", limit: float, why: str, where: str | None = None) -> None:
    """Refuse a specimen whose data reach grip strain ``limit``, naming the file, row, column and value.

    ``limit`` is the largest grip strain the specimen's knit can reach, in the loosest case the fit allows
    (:func:`knitsim.diagnosis.measured.reachable_strain` at the largest L and smallest C0, through the largest
    pretension: :func:`pretension_strain`); ``why`` says how it was obtained.  The rows of each file up to the
    end of the fit are checked, and the first that reaches the limit is named: a tail cut off with
    ``end_strain`` (a test run on past what the model can reach) is not refused.  (A band whose files end
    ten times apart, one in per cent, is refused when it is read: :func:`specimen_from_files`.)  Nothing is
    solved.

    Raises
    ------
    KnitsimInputError
    """
    where = where or f"specimens.{sp.name}"
    top = float(sp.strain[-1])
    for src in sp.sources:
        try:
            t = read_table(src)
        except (KnitsimInputError, OSError):       # pragma: no cover - it was read before
            continue
        fitted = t.strain <= top * (1.0 + 1e-12) + 1e-12
        if np.any(fitted & (t.strain >= limit)):
            i = int(np.argmax(np.where(fitted, t.strain, -np.inf)))     # the largest strain fitted
            _unreachable(where, f"{t.source}: row {int(t.rows[i])}, column {t.strain_column}:", float(t.strain[i]),
                         limit, why)
    if top >= limit:                                # rows without a file (a SpecimenData made in code)
        _unreachable(where, "the last row fitted, grip strain", top, limit, why)


def _unreachable(where: str, place: str, value: float, limit: float, why: str):
    pct = " " + PER_CENT_HINT if value >= 1.0 else ""
    raise KnitsimInputError(f"{where}: {place} {value:g} is a strain the specimen's knit cannot reach "
                            f"({why}: grip strain < {limit:.4g}).{pct}")


def band_residuals(force, low, high, accuracy) -> np.ndarray:
    """Signed residuals of the likelihood of a force reading against an experimental band.

    The band ``[low, high]`` is the scatter of the specimens: the true curve of a specimen is anywhere
    inside it, none more likely than another (a uniform density on the band), and the testing machine
    reads it with a Gaussian error of sd ``accuracy`` (ISO 7500-1).  The density of a model force ``f``
    is then the box convolved with the Gaussian,

        p(f) = [Phi((high - f) / s) - Phi((low - f) / s)] / (high - low),

    flat inside the band (well inside, where the band is wide against ``s``), falling off as a Gaussian of
    sd ``s`` outside it, and the Gaussian ``N(f; low, s)`` itself where the band has no width.  The
    residual is ``r = sign(f - mid) sqrt(2 [ln p(mid) - ln p(f)])``: ``sum r^2`` is ``-2 ln`` of the
    likelihood up to a constant, so least squares on ``r`` is maximum likelihood, and ``r = (f - mid) / s``
    exactly for a band of no width.  A fit to this likelihood puts the model anywhere inside the band at
    no cost instead of pulling it to the mid-line (the target of a Gaussian of sd = half-width).

    Parameters
    ----------
    force, low, high, accuracy : ndarray, shape [n]
        Model force, band and sd of the reading [N] (``accuracy > 0``, ``low <= high``).

    Returns
    -------
    ndarray, shape [n]
    """
    from scipy.special import log_ndtr
    f, lo, hi, s = (np.asarray(a, float) for a in (force, low, high, accuracy))
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)

    def log_mass(x):
        # ln[Phi(half - x) - Phi(-half - x)] in units of s, x = |f - mid| / s >= 0: the difference written
        # with the smaller tail first (log_ndtr keeps far tails exact)
        a, b = (half / s) - x, -(half / s) - x
        la, lb = log_ndtr(a), log_ndtr(b)
        return la + np.log1p(-np.exp(np.minimum(lb - la, 0.0)))

    x = np.abs(f - mid) / s
    narrow = half < 1e-6 * s           # no width to resolve: the Gaussian of the reading itself
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.where(narrow, 0.5 * x * x, log_mass(np.zeros_like(x)) - log_mass(x))
    return np.sign(f - mid) * np.sqrt(2.0 * np.maximum(d, 0.0))


def cauchy_tail(r) -> np.ndarray:
    """Residuals of a heavy-tailed (Cauchy) likelihood from Gaussian ones: ``sign(r) sqrt(2 ln(1 + r^2 / 2))``.

    The density ``p ~ 1 / (1 + r^2 / 2)`` (a Cauchy of scale sqrt 2 in ``r``) is ``exp(-r^2 / 2)`` to
    second order, the Gaussian itself near the band, and falls as ``r^-2`` far from it: a row the model
    cannot reach (a feature of one test that the model does not make, a mechanism it lacks) costs
    ``2 ln(1 + r^2 / 2)``, not ``r^2``, so a few such rows do not pull the fit out of the band everywhere
    else (robust regression; least squares on these residuals is scipy's ``loss="cauchy"`` with
    ``f_scale = sqrt 2``).  ``sum`` of their squares is ``-2 ln`` of that likelihood up to a constant.
    """
    r = np.asarray(r, float)
    return np.sign(r) * np.sqrt(2.0 * np.log1p(0.5 * r * r))


def _readings(t: MeasuredTable) -> tuple[np.ndarray, np.ndarray]:
    """The file's (strain, force) readings with repeated strains (a logger writing a row twice) averaged,
    so that the interpolation between them is defined."""
    s, inv = np.unique(t.strain, return_inverse=True)
    return s, np.bincount(inv, weights=t.force) / np.bincount(inv)


def _interp(t: MeasuredTable, x: np.ndarray) -> np.ndarray:
    return np.interp(x, *_readings(t))


def _rest_level(force, sigma_N: float, floor: float) -> float:
    """The load cell's zero where :func:`~knitsim.diagnosis.measured.zero_offset_below` saw one below zero
    (``floor`` < 0; else 0): the median of every reading within 3 noise sd above that floor (the readings at
    rest, both sides of their noise).  The floor itself, the median of the lowest 5 % of all readings, lies
    1 to 2 sd below the zero (the low tail of the noise at rest): a re-probe found it tared a -1 sd zero to
    +1.1 .. +1.7 sd.  Never above 0 (a zero above zero is not told from the knit's force)."""
    if floor >= 0.0:
        return 0.0
    f = np.asarray(force, float)
    rest = f[f <= floor + 3.0 * sigma_N]
    return min(float(np.median(rest)), 0.0) if len(rest) else floor


def rest_reading(t: MeasuredTable) -> tuple[float, float]:
    """A file's force at rest and its sd [its force column's units]: the median of its first readings, those
    at strain within 1e-3 of its strain range of its first (:data:`~knitsim.diagnosis.measured.STRAIN_TOL_REL`;
    at least the first reading; not the jitter tolerance, which irregular steps inflate: a probe's steps of
    0.005 +- 50 % read as a jitter of 0.001, and its tolerance took in a reading at strain 0.0049, 0.53 N up
    the curve), after the tare of a zero below zero (:func:`_rest_level`); the sd of one reading there (its
    noise, :class:`~knitsim.diagnosis.noise.CurveNoise`).  What the joint calibration's zero check
    (:mod:`knitsim.calibration.joint`, "The files' zero") compares with the model's force at grip strain 0."""
    s, f = np.asarray(t.strain, float), np.asarray(t.force, float)
    at = f[s <= s[0] + STRAIN_TOL_REL * float(np.max(s) - min(float(np.min(s)), 0.0))]
    level = float(np.median(at if len(at) else f[:1]))
    sd = float(t.noise.sd_at(np.array([level]))[0]) if t.noise is not None else float("nan")
    return level, sd


def _interpolation_sd(t: MeasuredTable, x: np.ndarray) -> np.ndarray:
    """An sd of :func:`_interp`'s error at the rows ``x``: where a row falls between two of the file's
    readings, the curve between them is not known to be straight (a knee, a stick-slip onset, may lie
    there); the change of slope from the segment before to the segment after, times (x - a)(b - x)/(b - a)
    for the readings a, b around the row: the chord's miss were the knee at the row (a bound; half of it
    left one yarn flagged as two on a curve read every 0.02).  0 at a reading.
    A blind probe's exact model curves read at steps of 0.003 and 0.01 with rows at 0.005 were 27 sd off at
    the row just past the stick-slip knee, and one yarn read as two (p = 1e-80)."""
    s, f = _readings(t)
    if len(s) < 3:
        return np.zeros(len(x))
    seg = np.diff(f) / np.diff(s)
    a = np.clip(np.searchsorted(s, x, side="right") - 1, 0, len(s) - 2)
    left = seg[np.maximum(a - 1, 0)]
    right = seg[np.minimum(a + 1, len(seg) - 1)]
    lo, hi = s[a], s[a + 1]
    w = np.clip((x - lo) * (hi - x) / (hi - lo), 0.0, None)
    return np.abs(right - left) * w


def _row_slopes(t: MeasuredTable, x: np.ndarray) -> np.ndarray:
    """|dF/dstrain| at the rows ``x`` of a curve: the larger of the two slopes to the neighbouring rows (to the
    curve at strain 0 for the first), so that a row at a knee takes the steep side."""
    ext = np.concatenate([[0.0], x])
    return steeper_slopes(ext, _interp(t, ext))[1:]


@dataclass(frozen=True)
class SpecimenData:
    """One specimen on the rows of the fit.

    Attributes
    ----------
    name : str
    strain : ndarray, shape [n]
        Grip strains of the rows (uniform grid).
    target_N : ndarray, shape [n]
        Force to fit [N]: total on the specimen (``total``), or per wale.
    sigma_N : ndarray, shape [n]
        sd of each row [N] (module docstring).
    band_low_N, band_high_N : ndarray, shape [n], or None
        The experimental band at the rows, where given.
    total : bool
        Forces are on the whole specimen (the model's force per wale times width / W0).
    width_mm, gauge_length_mm : float
        Specimen width across the wales and distance between the grips.
    knit : dict
        Stated L, W0, C0 [mm].
    uncertainty : dict
        Relative sd of each stated L, W0, C0 (the prior of a fitted one; 0: known).
    sources : list of str
        The files read.
    sigma_rule : str
        How the sds were obtained (for the report).
    zero_offsets_N : tuple of (str, float)
        The files whose load cell read below zero at rest, and the zero offset tared from each [N].
    pretension : float
        Strain of the knit at grip strain 0 (:func:`pretension_strain`): the start of a fitted
        pretension, else the value used (0: the knit is at rest at the strain origin).
    pretension_sd : float
        sd of the prior of a fitted pretension, a Gaussian centred on 0 (the tester's strain origin
        at face value), cut at 0 by its range; 0: not fitted.
    accuracy_rel : float
        Relative accuracy of the force reading (the least sd of a band's row, times the force).
    """

    name: str
    strain: np.ndarray
    target_N: np.ndarray
    sigma_N: np.ndarray
    band_low_N: np.ndarray | None
    band_high_N: np.ndarray | None
    total: bool
    width_mm: float
    gauge_length_mm: float
    knit: dict
    uncertainty: dict = field(default_factory=dict)
    sources: tuple = ()
    sigma_rule: str = ""
    pretension: float = 0.0
    pretension_sd: float = 0.0
    accuracy_rel: float = FORCE_ACCURACY_REL
    zero_offsets_N: tuple = ()
    #: the files' force at rest (first readings, :func:`rest_reading`) and its sd [N, total or per wale];
    #: NaN: not known (a specimen made by hand)
    rest_N: float = float("nan")
    rest_sd_N: float = float("nan")
    #: (file, note) of what reading its files did that the user must be told (MeasuredTable.notes)
    read_notes: tuple = ()
    #: (key path, file, digest of its rows) of each file read: the same test given to two specimens, or a copy of
    #: it, is refused (:func:`refuse_repeated_tests`); () for a specimen made by hand
    file_rows: tuple = ()

    @property
    def has_band(self) -> bool:
        return self.band_low_N is not None

    def wales(self, W0: float) -> float:
        """Wales across the specimen at wale spacing ``W0`` [mm] (width / W0)."""
        return self.width_mm / W0

    def in_band(self, force_N: np.ndarray) -> np.ndarray:
        """Whether each row's force lies inside the experimental band (all True without a band)."""
        if not self.has_band:
            return np.ones(len(self.strain), bool)
        return (force_N >= self.band_low_N) & (force_N <= self.band_high_N)

    @property
    def accuracy_N(self) -> np.ndarray:
        """sd of the force reading at each row [N]: ``accuracy_rel`` x the target (at least 1e-6 of the
        largest target, so that a row at zero force keeps a finite sd)."""
        scale = max(float(np.max(np.abs(self.target_N))), 1e-300)
        return np.maximum(self.accuracy_rel * np.abs(self.target_N), 1e-6 * scale)

    def band_residuals(self, force_N: np.ndarray) -> np.ndarray:
        """Signed residuals of the band likelihood with a heavy tail at the rows
        (:func:`band_residuals`, then :func:`cauchy_tail`); without a band, the curve's
        ``(force - target) / sd`` (with the same tail)."""
        if not self.has_band:
            return cauchy_tail((force_N - self.target_N) / self.sigma_N)
        return cauchy_tail(band_residuals(force_N, self.band_low_N, self.band_high_N, self.accuracy_N))

    def in_band_tolerant(self, force_N: np.ndarray) -> np.ndarray:
        """Inside the band widened on each side by the force reading's accuracy (``accuracy_rel`` x the
        target): where the envelopes meet or cross, the band has no width though the specimens scatter."""
        if not self.has_band:
            return np.ones(len(self.strain), bool)
        tol = self.accuracy_rel * np.abs(self.target_N)
        return (force_N >= self.band_low_N - tol) & (force_N <= self.band_high_N + tol)


def specimen_from_files(name: str, *, width_mm: float, gauge_length_mm: float, knit: dict,
                        uncertainty: dict | None = None, curve: str | Path | None = None,
                        band: tuple | None = None, row_step: float = 0.005, noise_N: float | None = None,
                        end_strain: float | None = None, accuracy_rel: float = FORCE_ACCURACY_REL,
                        where: str | None = None, pretension: float = 0.0,
                        pretension_sd: float = 0.0) -> SpecimenData:
    """Read a specimen's files and put them on the fit rows (module docstring).

    Parameters
    ----------
    name : str
    width_mm, gauge_length_mm : float
    knit : dict
        L, W0, C0 [mm].
    uncertainty : dict, optional
        Relative sd of L, W0, C0 (default 0: known).
    curve : path, optional
        A measured curve.
    band : (path, path), optional
        The lower and upper envelopes of the experimental scatter (either order: each row's band is their
        min and max; a pair given upper first on most rows is said in ``read_notes``).
    row_step : float
        Strain step of the rows.
    noise_N : float, optional
        sd of the curve's force [N] (a curve without a band); default: estimated from the curve.
    end_strain : float, optional
        Last strain of the rows (default: the end of the data).
    accuracy_rel : float
        Relative accuracy of the force reading: the least sd of a band's row, times the force.
    where : str, optional
        Key path of the specimen in its scene, for messages (default ``specimens.<name>``).
    pretension, pretension_sd : float
        Strain of the knit at grip strain 0 (start), and the sd of its prior (:class:`SpecimenData`).
    """
    where = where or f"specimens.{name}"
    if curve is None and band is None:
        raise KnitsimInputError(f"{where}: give a measured curve, an experimental band, or both")
    for key in GEOMETRY:
        if key not in knit:
            raise KnitsimInputError(f"{where}.knit.{key}: missing (the knit's {key} in mm)")

    def read(path, key):
        try:
            return read_table(path)
        except KnitsimInputError as exc:         # the file's problem, and the key that named the file
            raise KnitsimInputError(f"{where}.{key}: {exc}") from None
    tables = []
    cur = read(curve, "curve") if curve is not None else None
    lo_t = hi_t = None
    if band is not None:
        lo_t, hi_t = read(band[0], "band[0]"), read(band[1], "band[1]")
        if _rows_digest(lo_t) == _rows_digest(hi_t):
            # one test as both envelopes (a copy, or the same file under another path): a band of no width, each row
            # weighed by the machine's accuracy as if tests did not scatter (a probe's copy was fitted without a word)
            raise KnitsimInputError(f"{where}.band: {lo_t.source} and {hi_t.source} hold the same rows: one test as "
                                    "both envelopes, a band of no width; give the two envelopes of the tests' "
                                    "scatter, or the one test as curve = FILE")
        tables += [lo_t, hi_t]
    if cur is not None:
        tables.append(cur)
    totals = {t.total for t in tables}
    if len(totals) > 1:
        raise KnitsimInputError(f"{where}: the files mix total forces and forces per wale "
                                f"({', '.join(t.source for t in tables)})")
    end = min(t.strain[-1] for t in tables)
    far = max(t.strain[-1] for t in tables)
    if far > 10.0 * max(end, 1e-12):
        # the two envelopes of one specimen's scatter span the same test: one ten times longer is in
        # other units (per cent)
        raise KnitsimInputError(f"{where}: the files' strains end at "
                                f"{', '.join(f'{t.source}: {float(t.strain[-1]):g}' for t in tables)}, ten times apart "
                                f"or more. {PER_CENT_HINT}")
    if end_strain is not None:
        if end_strain > end:
            raise KnitsimInputError(f"{where}.end_strain = {end_strain!r}: beyond the data (ends at {end:g})")
        end = end_strain
    # every row lies where every file measured: a file that starts above the first row (its lab dropped
    # the pre-load part) would have its first force held constant down to that row, made-up data
    late = [t for t in tables if t.strain[0] > row_step + 1e-9]
    if late:
        t = late[0]
        raise KnitsimInputError(f"{where}: {t.source} starts at strain {float(t.strain[0]):g} (row {int(t.rows[0])}), "
                                f"above the first row of the fit ({row_step:g}, row_step): the rows below it would "
                                "be made up. Give the curve from the start of its test (strain 0), or a calibration.row_step of at least "
                                "that strain")
    n = int(np.floor(end / row_step + 1e-9))
    if n < 4:
        # a column read in per cent says so (its fractions, divided by 100, end a hundred times too early)
        read = "".join(f" ({t.source}: {note})" for t in tables for note in t.notes)
        raise KnitsimInputError(f"{where}: the data end at strain {end:g}, fewer than 4 rows of "
                                f"{row_step:g}{read}")
    strain = row_step * np.arange(1, n + 1)
    low = high = None
    swap_notes: tuple = ()
    if band is not None:
        a, b = _interp(lo_t, strain), _interp(hi_t, strain)
        low, high = np.minimum(a, b), np.maximum(a, b)
        mid = 0.5 * (low + high)
        swap_notes = _swapped_band(lo_t, hi_t, strain, a, b, accuracy_rel)
    target = _interp(cur, strain) if cur is not None else mid
    scale = max(float(np.max(np.abs(target))), 1e-300)
    if band is not None:
        half = 0.5 * (high - low)
        how = "half-width of the band"
        sigma = np.maximum(np.maximum(half, accuracy_rel * np.abs(target)), 1e-6 * scale)
        rule = f"{how}, at least {100 * accuracy_rel:.3g} % of the force (the machine's accuracy)"
        if cur is None:
            # the mid-line is the envelopes interpolated between their readings: its miss at a row is the mean
            # of theirs (:func:`_interpolation_sd`, as a curve's rows take it); without it a knee between two
            # readings of an envelope left one row many sds off and one yarn on +-4 % bands read as two
            e_interp = 0.5 * (_interpolation_sd(lo_t, strain) + _interpolation_sd(hi_t, strain))
            if np.any(e_interp > 0):
                sigma = np.sqrt(sigma ** 2 + e_interp ** 2)
                rule += "; with the interpolation's error where a row falls between an envelope's readings"
    else:
        if noise_N is None:
            # where the curve's scatter grows with the force, each row's own sd (knitsim.diagnosis.noise)
            sigma = np.maximum(cur.noise.sd_at(target), 1e-6 * scale)
            rule = f"noise of the curve, {cur.noise.describe()} ({cur.noise.method} from the curve)"
        else:
            sigma = np.full(len(strain), max(float(noise_N), 1e-6 * scale))
            rule = f"noise of the curve, {noise_N:.3g} N (given)"
        if cur.strain_jitter > 0:
            # errors in the strain: a row read at a strain off by e carries the force of strain - e, so its sd
            # adds slope x e (effective variance; the steeper of the curve's slopes beside the row).  Without it
            # a blind probe's extensometer jitter of 2e-4 (within what the reading keeps) made steep rows weigh
            # 10 x too much: standard errors 4 to 5 times too small, and one yarn read as two in 3 seeds of 8
            sigma = np.sqrt(sigma ** 2 + (_row_slopes(cur, strain) * cur.strain_jitter) ** 2)
            rule += (f"; with the strain column's jitter ({cur.strain_jitter:.2g}, sd) times the curve's slope "
                     "(errors in the strain)")
        # rows between the file's readings: the interpolation's own error (a knee between two readings)
        e_interp = _interpolation_sd(cur, strain)
        if np.any(e_interp > 0):
            sigma = np.sqrt(sigma ** 2 + e_interp ** 2)
            rule += "; with the interpolation's error where a row falls between readings (the change of slope there)"
    unc = {k: float((uncertainty or {}).get(k, 0.0)) for k in GEOMETRY}
    for k, v in unc.items():
        if not (0.0 <= v < 1.0):
            raise KnitsimInputError(f"{where}.uncertainty.{k} = {v!r}: expected a relative sd in [0, 1)")
    return SpecimenData(name, strain, np.asarray(target, float), sigma, low, high, totals.pop(), float(width_mm),
                        float(gauge_length_mm), {k: float(knit[k]) for k in GEOMETRY}, unc,
                        tuple(t.source for t in tables), rule, float(pretension), float(pretension_sd),
                        float(accuracy_rel), tuple((t.source, t.zero_offset_N) for t in tables if t.zero_offset_N),
                        *_rest_of(cur, lo_t, hi_t), tuple((t.source, n) for t in tables for n in t.notes) + swap_notes
                        + tuple(note for t in tables for note in _gap_notes(t, strain)),
                        tuple((key, t.source, _rows_digest(t)) for key, t in
                              (("band[0]", lo_t), ("band[1]", hi_t), ("curve", cur)) if t is not None))


#: a step between two readings of a file wider than this share of its strain range ...
GAP_RANGE_SHARE = 0.1
#: ... and this many times its median step is a gap (:func:`_gap_notes`)
GAP_MEDIAN_STEPS = 10.0


def _gap_notes(t: MeasuredTable, rows: np.ndarray) -> tuple:
    """``((file, note), ...)`` of each gap in a file's strain that holds rows of the fit: a step between two readings
    wider than :data:`GAP_RANGE_SHARE` of its strain range and :data:`GAP_MEDIAN_STEPS` times its median step (rows
    lost from the log, two files pasted with a part missing).  The fit's rows there are the straight line between
    the two readings, weighed as rows between close readings are (the noise, and the chord's miss from the slopes
    just beside the gap: not what the gap hides): said, naming the rows and the strains (a probe's pull with 40 % of
    its range missing was fitted without a word).  The irregular steps of real logs are no gap: Singal 2024's video
    frames (89 runs, clamp and pin strains) step by at most 5.3 % of their range (the widest 50 to 70 times their
    median, between holds), Do 2020's envelopes by 0.15 %, its model curves by 6.7 % at one step (1 times)."""
    s, _ = _readings(t)
    if len(s) < 3:
        return ()
    step = np.diff(s)
    span = float(s[-1] - min(float(s[0]), 0.0))
    wide = np.flatnonzero((step > GAP_RANGE_SHARE * span) & (step > GAP_MEDIAN_STEPS * float(np.median(step))))
    out = []
    for k in wide:
        a, b = float(s[k]), float(s[k + 1])
        inside = int(np.count_nonzero((rows > a) & (rows < b)))
        if not inside:
            continue
        ra = int(t.rows[np.flatnonzero(t.strain == a)[-1]])
        rb = int(t.rows[np.flatnonzero(t.strain == b)[0]])
        out.append((t.source, f"no reading between strain {a:.4g} (row {ra}) and {b:.4g} (row {rb}), "
                              f"{100 * (b - a) / span:.0f} % of its strain range and {(b - a) / np.median(step):.0f} "
                              f"times its median step: the fit's {inside} row(s) there are the straight line between "
                              "the two readings, weighed by the noise and the slopes just beside the gap, not by what "
                              "it hides; if rows are missing from the file, give them, or fit below the gap "
                              "(end_strain)"))
    return tuple(out)


def _rows_digest(t: MeasuredTable) -> str:
    """A digest of a file's rows as read (strain, force): equal for the same file under another path or name,
    or a copy of it, whatever its format."""
    import hashlib
    rows = np.ascontiguousarray(np.column_stack([np.asarray(t.strain, float), np.asarray(t.force, float)]))
    return hashlib.sha1(rows.tobytes()).hexdigest()


def refuse_repeated_tests(specimens) -> None:
    """Refuse two specimens that read the same rows (one test given twice, under another name or path, or a copy
    of it): its rows would count twice, the standard errors shrink by sqrt(2) and the one-yarn check would
    compare a test with itself (a blind probe's copy as a second specimen was fitted without a word; `knitsim
    diagnose` refuses it).  Specimens made by hand (no ``file_rows``) are not checked.

    Raises
    ------
    KnitsimInputError
        Naming both specimens' keys and files.
    """
    seen: dict[str, tuple[int, str, str]] = {}
    for i, s in enumerate(specimens):
        for key, source, digest in getattr(s, "file_rows", ()):
            if digest in seen and seen[digest][0] != i:
                i0, key0, source0 = seen[digest]
                raise KnitsimInputError(
                    f"specimens[{i}].{key}: {source} holds the same rows as specimens[{i0}].{key0} ({source0}): "
                    "the same test given twice, or a copy of it; its rows would count twice (standard errors "
                    "too small, one yarn checked against itself). Give each test once")
            seen.setdefault(digest, (i, key, source))


def _swapped_band(lo_t: MeasuredTable, hi_t: MeasuredTable, strain: np.ndarray, a: np.ndarray, b: np.ndarray,
                  accuracy_rel: float) -> tuple:
    """A band given upper envelope first, said: ``((file, note),)`` where ``band[0]`` (``a`` at the rows
    ``strain``) lies above ``band[1]`` (``b``) by more than the force accuracy on most rows, else ``()``.

    Accepted, not refused: each row's band is the min and max of the two files (envelopes that cross are
    read so), so the fit does not depend on their order (a hand-made pair given high first fitted to the
    same calibration.json); but a lab's low file that holds the higher forces is a mislabelled file, and
    the report's sources would list it as the lower envelope.  Rows where the files cross only locally (two
    tests' curves: Do 2020's 6.5 mm pair, 20 of 62 rows at its start) are not most rows, and say nothing.
    """
    tol = accuracy_rel * 0.5 * np.abs(a + b)
    above = a > b + tol
    if np.count_nonzero(above) * 2 <= len(strain) or np.count_nonzero(above) <= np.count_nonzero(b > a + tol):
        return ()
    # the runs of rows where it lies above, as grip strain ranges (the rows of the fit)
    edges = np.flatnonzero(np.diff(np.r_[0, above.astype(int), 0]))
    runs = [f"{strain[i]:g}" if i == j - 1 else f"{strain[i]:g} .. {strain[j - 1]:g}"
            for i, j in zip(edges[::2], edges[1::2])]
    listed = ", ".join(runs[:4]) + (f" and {len(runs) - 4} more" if len(runs) > 4 else "")
    return ((lo_t.source, f"band[0] lies above band[1] ({hi_t.source}) on {np.count_nonzero(above)} "
                          f"of {len(strain)} rows (grip strain {listed}; by more than the force accuracy, "
                          f"{100 * accuracy_rel:.3g} %): read as the upper envelope, the band being each row's "
                          "lower and higher file (the fit does not depend on their order); if the files are "
                          "named low and high, they are named the wrong way round"),)


def _rest_of(cur, lo_t, hi_t) -> tuple[float, float]:
    """A specimen's force at rest and its sd (:func:`rest_reading`): its curve's; without one, the envelopes'
    mean, with the larger of their noise and half their gap."""
    if cur is not None:
        return rest_reading(cur)
    (a, sa), (b, sb) = rest_reading(lo_t), rest_reading(hi_t)
    return 0.5 * (a + b), max(sa, sb, 0.5 * abs(a - b))


__all__ = ["MeasuredTable", "SpecimenData", "read_table", "specimen_from_files", "refuse_repeated_tests", "pretension_strain", "check_reach",
           "GEOMETRY", "rest_reading",
           "band_residuals", "cauchy_tail"]
