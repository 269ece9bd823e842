"""Measured force-strain curves of a knit and the load program that replays them.

A measured curve is a CSV file (any delimiter ``,`` ``;`` or tab, a UTF-8 BOM,
CRLF line ends, decimal commas after ``;``: :mod:`knitsim.io.table_input`) with columns

``strain``
    strain of the course length, (C - C0) / C0 [-] (the imposed strain of
    :mod:`knitsim.cell.load_program`);
``force_per_wale_N``
    force per wale [N];
``cycle`` (optional)
    cycle number from 1 (a new loading branch starts a new cycle); a column numbered from 0, as a logger
    may count, is read as numbered from 1 and said so (:attr:`MeasuredCurve.notes`);
``direction`` (optional)
    ``load`` or ``unload``, in any case, or another word for them (:func:`direction_signs`: ``loading`` /
    ``unloading``, ``up`` / ``down``, ``L`` / ``U``, ``+`` / ``-``, ``1`` / ``-1``);
``rate_mm_s`` (optional)
    crosshead rate [mm/s], > 0.

What a laboratory writes is accepted (:func:`curve_from_arrays`):

- **forces slightly below zero**: a load cell reads around zero at rest.  A
  force down to :data:`NEGATIVE_SIGMAS` noise sd below zero is kept as
  measured (the noise of the curve itself, :mod:`knitsim.diagnosis.noise`),
  and so are one or two spikes below that (outliers, which the diagnosis
  leaves out); more rows lower are an error naming the first (a knit carries
  no compression: a wrong zero or sign);
- **strain jitter**: a strain that steps back by at most the tolerance
  (:func:`strain_tolerance`: 1e-3 of the curve's strain range, or 5 sd of
  the strain's own jitter where that is more) inside a
  branch is extensometer jitter or round-off, not a reversal.  The branch
  follows its overall direction and the replayed strain is the running
  extreme (the knit is not unloaded by the jitter); the measured force stays.
  Without a ``direction`` column a reversal starts a new branch only when the
  strain moves back by more than the tolerance and the force follows (does
  not move against it by more than noise); with the column, a step back
  beyond the tolerance is an error naming the row.

Missing ``direction`` / ``cycle`` are inferred from the strain turning points
with the convention of :func:`~knitsim.cell.load_program.piecewise_linear`:
the test starts at rest (strain 0), a row belongs to the branch that reaches
it (the turning point ends its branch), and each loading branch after an
unloading starts a new cycle.

Every rejection names the file, the row (as a spreadsheet shows it, header =
row 1), the column and the value, and says what to do.

:func:`program_for_curve` turns the curve's own strain history into a
:class:`~knitsim.cell.load_program.LoadProgram` whose corners are every
measured strain, so that each measured row is an increment of the program
(to rounding of ``a + (b - a) * n / n``); :func:`force_at_rows` reads the
simulated force (and stage labels) at the measured rows.
"""
from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..cell.history import BatchHistory
from ..cell.load_program import LoadProgram, piecewise_linear
from ..errors import KnitsimInputError
from ..io.table_input import LAB_ALIASES, Columns, notes_of, read_csv_columns
from .noise import (STRAIN_JITTER_MIN_ROWS, CurveNoise, curve_noise, reading_jitter, strain_jitter,  # noqa: F401
                    written_resolution)

REQUIRED = ("strain", "force_per_wale_N")
OPTIONAL = ("cycle", "direction", "rate_mm_s")
#: the words of a direction column (any case, spaces around trimmed): +1 loading, -1 unloading.  A lab writes
#: load / unload, loading / unloading, up / down, + / - or 1 / -1 (a blind probe's up / down and L / U files were
#: refused); a reloading is a loading
_DIRECTIONS = {"load": 1, "loading": 1, "reload": 1, "reloading": 1, "up": 1, "+": 1,
               "unload": -1, "unloading": -1, "down": -1, "-": -1}
#: one-letter codes, read by the column's other letters: ``U`` is an unloading beside ``L`` (load / unload) and a
#: loading beside ``D`` (up / down); alone, or beside both, which one is meant is not said (refused)
_DIRECTION_LETTERS = {"l": 1, "d": -1}
#: a test program's word for a hold (the grip stopped while the force relaxes): the branch it is in goes on
_HOLD_WORDS = ("hold", "holding", "dwell", "pause", "relax", "relaxation")

#: a force this many noise sd below zero is kept as a reading around zero; lower is refused
NEGATIVE_SIGMAS = 5.0
#: a load cell's zero below zero is read off the lowest this share of a curve's readings, and accepted
#: up to this share of its peak force (:func:`zero_offset_below`)
ZERO_OFFSET_ROWS = 0.05
ZERO_OFFSET_SHARE = 0.05
#: rows below that limit tolerated as spikes (outliers): at most this many, or this share of the rows
NEGATIVE_SPIKES = 2
NEGATIVE_SPIKE_SHARE = 0.005
#: strain jitter tolerated inside a branch, as a fraction of the curve's strain range
STRAIN_TOL_REL = 1.0e-3
#: or as this many sd of the strain's own jitter (an extensometer noisier than 1e-3 of the range: a step
#: back of 3 sd is then common, and read as a reversal it cut a pull into cycles; the jitter estimated from
#: STRAIN_JITTER_MIN_ROWS rows, knitsim.diagnosis.noise.strain_jitter)
STRAIN_JITTER_SIGMAS = 5.0
#: an unloading branch whose strain goes back no more than this many jitter tolerances is a hold
#: (:func:`infer_branches`)
HOLD_TRAVEL_TOLS = 10.0
#: the fewest data rows of a measured curve file (a shape, and a noise, need more than a line's points)
MIN_CURVE_ROWS = 4
#: columns that name the specimen or the test of each row (a lab's file of several tests, stacked): a curve file
#: holds one test, so more than one value in one of them is refused (:func:`refuse_several_tests`)
TEST_LABELS = ("specimen", "sample", "specimen_id", "sample_id", "specimen_name", "sample_name", "run", "test",
               "test_id")
#: columns that say when each row was read (a logger's time, a video's frame): read as text where the header holds
#: one, only to tell a second reading from a copy (:func:`drop_copied_rows`), never fitted
TIME_LABELS = ("time", "time_s", "t", "t_s", "test_time", "test time", "elapsed_time", "elapsed time", "total_time",
               "total time", "timestamp", "frame", "zeit", "temps", "tiempo")


@dataclass(frozen=True)
class MeasuredCurve:
    """A validated measured curve, one entry per row.

    Attributes
    ----------
    strain : ndarray of float
        Strain of the course length [-], monotone within each branch (the running
        extreme of the read strain: jitter removed, see the module docstring).
    force : ndarray of float
        Force per wale [N], as measured (may be slightly negative).
    cycle : ndarray of int
        Cycle number from 1.
    direction : ndarray of int
        +1 loading, -1 unloading.
    rate_mm_s : ndarray of float or None
        Crosshead rate [mm/s] where given.
    source : str
        File name (or label) used in messages.
    rows : ndarray of int or None
        Spreadsheet row of each entry (header = row 1), for messages.
    strain_read : ndarray of float or None
        The strain as read, before the jitter was removed.
    noise : CurveNoise or None
        This curve's noise sd and how it was obtained.
    notes : tuple of str
        What the reader did that the user must be told (a strain column read in per cent:
        :attr:`knitsim.io.table_input.Columns.notes`); empty for most files.
    """

    strain: np.ndarray
    force: np.ndarray
    cycle: np.ndarray
    direction: np.ndarray
    rate_mm_s: np.ndarray | None = None
    source: str = "curve"
    rows: np.ndarray | None = None
    strain_read: np.ndarray | None = None
    noise: CurveNoise | None = None
    notes: tuple = ()
    #: rows (spreadsheet numbers) where the strain jumps and the force does not follow (:func:`strain_slips`)
    slips: tuple = ()
    #: rows (spreadsheet numbers) of short blocks whose force leaves the curve and comes back (:func:`force_glitches`):
    #: left out of the fit
    glitches: tuple = ()
    #: rows (spreadsheet numbers) where the force stalls on a steep loading while the strain runs on
    #: (:func:`force_stalls`: a grip slip seen in the force)
    stalls: tuple = ()
    #: rows (spreadsheet numbers) of a hold whose force relaxes at one strain (:func:`force_holds`), but each hold's
    #: first: left out of the fit
    holds: tuple = ()
    #: rows (spreadsheet numbers) that end a branch already on the next one: the turn between them and the row before
    #: was not recorded (:func:`unrecorded_turns`)
    late_turns: tuple = ()
    #: rows (spreadsheet numbers) where the force is flat at its largest reading while the strain moves on
    #: (:func:`flat_tops`: a saturated load cell)
    flat_top: tuple = ()

    def __len__(self) -> int:
        return len(self.strain)

    def row_of(self, i: int) -> int:
        """Spreadsheet row of entry ``i``."""
        return int(self.rows[i]) if self.rows is not None else i + 2


#: a strain below -max(NEGATIVE_STRAIN_ABS, NEGATIVE_STRAIN_REL x the largest strain) is a compression, not an
#: extensometer's zero offset (refused: the knit is modelled in tension)
NEGATIVE_STRAIN_ABS = 5.0e-3
NEGATIVE_STRAIN_REL = 0.05


def compression_limit(strain) -> float:
    """The lowest strain read as an extensometer's zero offset, not a compression:
    -max(NEGATIVE_STRAIN_ABS, NEGATIVE_STRAIN_REL x the largest strain)."""
    return -max(NEGATIVE_STRAIN_ABS, NEGATIVE_STRAIN_REL * max(float(np.max(strain)), 0.0))


#: what an unreachable strain of 1 or more most likely is (the refusals of the diagnosis and the calibration)
PER_CENT_HINT = "Is the column in per cent? A strain of 5 % is 0.05."


def reachable_strain(L: float, C0: float) -> float:
    """The largest strain a quarter-stitch cell reaches: C = C0 (1 + strain) < L/2 (a straight yarn)."""
    return L / (2.0 * C0) - 1.0


def check_reachable(curve: "MeasuredCurve", limit: float, why: str) -> None:
    """Refuse a curve whose strain reaches ``limit`` (:func:`reachable_strain`), naming its row: a strain in
    per cent (or a length) read as a strain is the usual cause."""
    s = curve.strain_read if curve.strain_read is not None else curve.strain
    i = int(np.argmax(s))
    if s[i] >= limit:
        pct = " " + PER_CENT_HINT if s[i] >= 1.0 else ""
        raise KnitsimInputError(f"{curve.source}: row {curve.row_of(i)}, column strain: {float(s[i]):g} cannot be "
                                f"reached by the scene's knit ({why}: strain < {limit:.4g}).{pct}")


def check_response(curve: "MeasuredCurve") -> None:
    """Refuse a measured curve whose force never rises above NEGATIVE_SIGMAS noise sd (a load cell that
    was not connected, the wrong column): there is nothing to compare.  (A strain-only shell, force 0,
    that only carries a replay program is not a measurement and is not checked.)"""
    sigma = curve.noise.sigma_N if curve.noise is not None else 0.0
    refuse_no_response(curve.source, curve.force, sigma, curve.row_of)


def refuse_no_response(source: str, force, sigma_N: float, row, column: str = "force_per_wale_N") -> None:
    """Refuse a force column that never rises above NEGATIVE_SIGMAS noise sd ``sigma_N`` (all zero, not
    connected, or of the wrong sign); ``row(i)`` is the spreadsheet row of entry i."""
    f = np.asarray(force, float)
    top = int(np.argmax(f))
    if not f[top] > NEGATIVE_SIGMAS * sigma_N:
        raise KnitsimInputError(
            f"{source}: column {column}: the force never rises above the noise (largest "
            f"{float(f[top]):g} N at row {row(top)}, noise sd {sigma_N:.3g} N): there is no measured response "
            "to compare; check the column, its sign and the load cell")


def zero_offset_below(force, sigma_N: float) -> float:
    """A load cell's zero offset below zero read off a force column (0.0 where there is none to see).

    A knit carries no compression, so its lowest readings (at rest, slack) are the load cell's zero plus
    noise: the median of the lowest :data:`ZERO_OFFSET_ROWS` share (at least 5 rows), where it lies more
    than 2 noise sd below zero and within :data:`ZERO_OFFSET_SHARE` of the peak force (a zero, not a sign
    or a column gone wrong).  The diagnosis fits each curve's offset; a blind probe found a -12 mN zero
    refused while the same +12 mN was read and fitted."""
    f = np.sort(np.asarray(force, float))
    if len(f) == 0:
        return 0.0
    z = float(np.median(f[:max(5, int(ZERO_OFFSET_ROWS * len(f)))]))
    return z if (z < -2.0 * sigma_N and -z <= ZERO_OFFSET_SHARE * float(f[-1])) else 0.0


def refuse_negative_force(source: str, force, noise: CurveNoise, row, column: str = "force_per_wale_N",
                          offset_use: str = "fitted") -> None:
    """Refuse a force column below zero (or below a load cell's zero offset, :func:`zero_offset_below`) by
    more than NEGATIVE_SIGMAS noise sd, beyond a few spikes (outliers, only where the noise is known): a
    wrong zero or sign.  ``row(i)`` is the spreadsheet row of entry i; ``offset_use`` says (in the message)
    what the caller does with a zero offset it accepts (the diagnosis fits it, the calibration tares it)."""
    f = np.asarray(force, float)
    zero = zero_offset_below(f, noise.sigma_N)
    bad = np.nonzero(f < zero - NEGATIVE_SIGMAS * noise.sigma_N)[0]
    # a spike or two on a curve whose noise is known is an outlier (the diagnosis leaves isolated outliers
    # out); more, or any without a known noise, is a wrong zero or sign
    spikes = max(NEGATIVE_SPIKES, NEGATIVE_SPIKE_SHARE * len(f)) if noise.known else 0
    if len(bad) > spikes:
        i = int(bad[0])
        how = noise.method if noise.known else f"assumed: {noise.note}"
        raise KnitsimInputError(
            f"{source}: row {row(i)}, column {column}: {float(f[i]):g} N is below zero by more than "
            f"{NEGATIVE_SIGMAS:g} noise sd ({noise.sigma_N:.3g} N, {how}): a knit carries no compression; "
            f"check the load cell's zero and the sign of the column (a zero offset below zero by up to "
            f"{ZERO_OFFSET_SHARE:.0%} of the peak force is read as such, and {offset_use})")


def strain_tolerance(strain) -> float:
    """Strain jitter tolerated inside a branch: :data:`STRAIN_TOL_REL` of the strain range, or
    :data:`STRAIN_JITTER_SIGMAS` sd of the strain's own jitter (:func:`strain_jitter`) where that is more
    (>= 1e-9) and the steps scatter as a jittering reading's do (:func:`~knitsim.diagnosis.noise.reading_jitter`,
    on the branches that tolerance reads).  Steps that vary while each strain is read exactly (a log at irregular
    strains, rows picked by hand) have second differences too, and were read as a jitter: steps of 0.01 +- 30 %
    to 0.6 as 9e-4 of it, a tolerance of 4.8e-3, so that a real unloading of 0.03 and its reload (within 10
    tolerances of travel: :data:`HOLD_TRAVEL_TOLS`) were read as a hold and their rows left out as a force glitch."""
    s = np.asarray(strain, float)
    span = float(np.max(s) - min(float(np.min(s)), 0.0)) if len(s) else 0.0
    tol = max(1e-9, STRAIN_TOL_REL * span)
    wide = STRAIN_JITTER_SIGMAS * strain_jitter(s)
    if wide > tol:
        wide = STRAIN_JITTER_SIGMAS * reading_jitter(s, infer_branches(s, None, wide)[1])
    return max(tol, wide)


def _force_scale(force) -> float:
    """A rough noise sd of a force column from its second differences, before branches exist
    (f[i-1] - 2 f[i] + f[i+1] cancels a straight trend and has variance 6 sigma^2 for white noise;
    the median keeps the few rows at turning points out)."""
    f = np.asarray(force, float)
    if len(f) < 3:
        return 0.0
    return float(1.4826 * np.median(np.abs(np.diff(f, 2))) / np.sqrt(6.0))


def infer_branches(strain, force=None, tol: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Cycle and direction of each row from the strain turning points.

    The test starts at rest (strain 0), loading.  A branch continues while the
    strain moves its way or back by at most ``tol`` (jitter: default
    :func:`strain_tolerance`); a move back by more starts the opposite branch,
    provided the force (when given) follows: it does not move against the
    strain by more than three times its noise scale (from second differences).  Each
    change from unloading to loading starts a new cycle, as in
    :func:`~knitsim.cell.load_program.piecewise_linear`.

    Returns
    -------
    cycle, direction : ndarray of int
    """
    s = np.asarray(strain, float)
    tol = strain_tolerance(s) if tol is None else float(tol)
    f = None if force is None else np.asarray(force, float)
    noise = 3.0 * _force_scale(f) if f is not None else 0.0
    direction = np.empty(len(s), np.int32)
    cycle = np.empty(len(s), np.int32)
    d, cyc, ext, ext_i = 1, 1, 0.0, -1
    for i, si in enumerate(s):
        if (si - ext) * d >= 0:
            ext, ext_i = si, i
        elif abs(si - ext) > tol:
            follows = True
            if f is not None and ext_i >= 0:
                # the new direction is -d: unloading, the force must not rise by more than noise;
                # reloading, not fall.  The force at the turn is the median of the turning row and its two
                # neighbours: one bad reading there (a spike at the last row of an unloading) was the reference
                # of every row after it, and a slack reload, ~0 N, read as the unloading going on
                follows = (f[i] - float(np.median(f[max(ext_i - 1, 0):ext_i + 2]))) * -d >= -noise
            if follows:
                d = -d
                if d == 1:
                    cyc += 1
                ext, ext_i = si, i
        direction[i], cycle[i] = d, cyc
    # a "branch back" that travels no more than HOLD_TRAVEL_TOLS tolerances is a hold: the strain held while
    # the force relaxes (a step-and-hold pull), not an unloading (a blind probe's monotonic pull of a
    # Singal 2024 stockinette was read as 19 load cycles, 414 of its 1061 rows unloading)
    i = 0
    while i < len(s):
        if direction[i] != -1:
            i += 1
            continue
        j = i
        while j < len(s) and direction[j] == -1:
            j += 1
        top = float(np.max(s[max(i - 1, 0):i + 1]))
        # (and one whose force stays up while its strain goes back farther: _force_stays)
        if (top - float(np.min(s[i:j])) <= HOLD_TRAVEL_TOLS * tol
                or (f is not None and _force_stays(s, f, direction, i, j, noise))):
            direction[i:j] = 1
        i = j
    return _cycles_from_direction(direction), direction


#: a "branch back" whose force falls by less than this share of what the loading before it rose over the same
#: strains (less the noise) is no unloading (:func:`_force_stays`)
UNLOAD_DROP_SHARE = 0.5


def _force_stays(s, f, direction, i: int, j: int, noise: float) -> bool:
    """Whether the force stays up while the strain goes back over rows ``i .. j-1`` (read as an unloading by
    :func:`infer_branches`): an unloading lies below the loading that reached its turn (friction dissipates: at a
    strain below the turn the unloading's force is at most the loading's), so its force falls from the turn's at least
    by what the loading rose over the strains it went back over.  One that falls by less than
    :data:`UNLOAD_DROP_SHARE` of that, less ``noise`` (three times the force's noise scale), is a strain read going
    back while the knit did not (a clamp or pin tracked on video settling over a hold, as Singal 2024's raw frames
    do by up to 25 tolerances: a monotonic test read as 2 to 6 cycles).  Forces are medians of a row and its
    neighbours (one bad reading is no turn)."""
    a = i
    while a > 0 and direction[a - 1] == 1:         # the loading before: its rows
        a -= 1
    if i - a < 2:
        return False
    t = a + int(np.argmax(s[a:i]))                 # the turn: the loading's largest strain
    low = i + int(np.argmin(s[i:j]))               # how far back the strain went
    below = np.flatnonzero(s[a:t + 1] >= s[low])
    if not len(below):
        return False
    m = a + int(below[0])                           # the loading's first row at that strain

    def at(r, lo, hi):
        return float(np.median(f[max(r - 1, lo):min(r + 2, hi)]))
    rise = at(t, a, i) - at(m, a, i)
    drop = at(t, a, i) - at(low, i, j)
    return drop < UNLOAD_DROP_SHARE * rise - noise


def _cycles_from_direction(direction: np.ndarray) -> np.ndarray:
    cyc, out = 1, np.empty(len(direction), np.int32)
    for i, d in enumerate(direction):
        if i > 0 and d == 1 and direction[i - 1] == -1:
            cyc += 1
        out[i] = cyc
    return out


def _monotone(s: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The running extreme of the strain within each branch (jitter removed); the first loading
    branch starts from rest, strain 0."""
    out = np.empty_like(s)
    ext = 0.0
    for i in range(len(s)):
        if i > 0 and d[i] != d[i - 1]:
            ext = s[i]
        ext = max(ext, s[i]) if d[i] > 0 else min(ext, s[i])
        out[i] = ext
    return out


#: rows of a branch (the turning row with those before it) whose line in the row number gives the turning
#: row's strain where the strain jitters (:func:`settle_turns`)
TURN_FIT_ROWS = 21
#: ... used only where it moves the read strain by at most this many jitter sd (else the ramp is not steady)
TURN_FIT_SIGMAS = 4.0


def settle_turns(strain: np.ndarray, direction: np.ndarray, jitter: float) -> np.ndarray:
    """The strain of each branch's last row (a turning point of the test) from the line through it and the
    rows before it on its branch (up to :data:`TURN_FIT_ROWS`, in the row number: a steady ramp logged at a
    steady rate), where the strain column jitters by ``jitter`` (sd; 0: the strain is returned as is).

    Why: the knit's response depends on where each turn happened (Table 4's frozen quantities are taken
    there: T on S-, beta on SF-), so a turn read off by the jitter shifts the whole branch after it, not a
    row.  A blind probe's model-made cycles with 2e-4 of strain jitter (rows 0.005 apart, 1 mN of force
    noise) were fitted at chi^2/dof 2.08 (1.72 with the rows weighted for the jitter) and read as a confident
    ``unexplained``; the same rows with their five turning strains exact: 1.06, ``none``.  The line's value at its last row has the sd
    ``jitter sqrt(1/n + ((n - 1)/2)^2 / S_xx)`` = 0.42 jitter with n = 21 rows.  Kept within the
    neighbours' strains (a turn stays a turn), and used only where it moves the read strain by at most
    :data:`TURN_FIT_SIGMAS` jitter sd (a ramp that changes speed at the turn keeps its reading)."""
    s = np.array(strain, float)
    d = np.asarray(direction)
    if not jitter > 0 or len(s) < 3:
        return s
    ends = np.nonzero(np.diff(d) != 0)[0]          # each branch's last row, followed by the next branch
    starts = np.concatenate([[0], ends + 1])
    for i in ends:
        a = max(int(starts[starts <= i][-1]), i - TURN_FIT_ROWS + 1)
        n = i - a + 1
        if n < 5:
            continue
        k = np.arange(n, dtype=float)
        slope, icpt = np.polyfit(k, s[a:i + 1], 1)
        at = icpt + slope * (n - 1)
        if abs(at - s[i]) > TURN_FIT_SIGMAS * jitter:
            continue
        lo = max(s[i - 1], s[i + 1]) if d[i] > 0 else -np.inf   # a maximum stays above both neighbours
        hi = min(s[i - 1], s[i + 1]) if d[i] < 0 else np.inf    # a minimum below them
        s[i] = min(max(at, lo), hi)
    return s


def refuse_reversed_rows(source: str, strain, tol: float, row, column: str = "strain") -> None:
    """Refuse a file whose strain only decreases from its first row (by more than ``tol``, never rising by more
    than ``tol`` on the way): rows in reverse order (sorted descending, a log read bottom up) or a log that starts
    at the peak.  A test is replayed from rest in the order of its rows, so such a file was read as a loading to its
    first row that no row records and an unloading: a blind probe's reversed pull got a confident ``unexplained``
    from diagnose (calibrate refused it at its second row, as a strain that decreases).  Both readers of a file
    (:func:`read_measured_curve`, :func:`knitsim.calibration.specimen.read_table`) refuse it so, naming the file, the
    first and the last row (``row(i)``: the spreadsheet row of entry i) and what to do; which of the two it is, the
    rows cannot tell (a loading read backwards also falls steeply from its first row).  :func:`curve_from_arrays`
    keeps the replay's convention for arrays made in code: the first row ends a loading from rest."""
    s = np.asarray(strain, float)
    if len(s) < 2 or not s[0] - s[-1] > tol or np.any(s - np.minimum.accumulate(s) > tol):
        return
    raise KnitsimInputError(
        f"{source}: column {column}: the strain only decreases, from {float(s[0]):g} at row {row(0)} to "
        f"{float(s[-1]):g} at row {row(len(s) - 1)}: the rows look reversed (sorted descending, or a log read from "
        "its end) or the log starts at the peak, without the loading that reached it.  A test is read from rest "
        "(strain 0) in the order its rows were measured: give them in that order (by time or the logger's row "
        "count), from the start of the loading (the knit's unloading depends on the loading that reached it)")


def direction_signs(source: str, direction, row) -> np.ndarray:
    """The sign of each row of a direction column (+1 loading, -1 unloading): the words of :data:`_DIRECTIONS` in
    any case, ``1`` / ``-1`` (numbers, or cells that read as them: ``+1``, ``-1.0``), and the letters ``L`` / ``U``
    or ``U`` / ``D`` (:data:`_DIRECTION_LETTERS`: ``U`` read by the column's other letters).  ``-`` is also a
    missing-value mark: read as an unloading only where the column holds ``+`` too.  A hold (:data:`_HOLD_WORDS`: a
    test program's segment, the grip stopped) is the branch it is in, the row above's (a loading on the first row:
    the test starts at rest); before, ``hold`` was refused as no direction.  Anything else is refused, naming the row
    (``row(i)``), the column and the value."""
    keys = [v.strip().casefold() if isinstance(v, str) else v for v in direction]
    letters = {k for k in keys if isinstance(k, str) and k in ("l", "u", "d")}
    u_sign = -1 if "d" not in letters and "l" in letters else 1 if "l" not in letters and "d" in letters else None
    plus = "+" in keys
    d = np.empty(len(keys), np.int32)
    for i, (v, key) in enumerate(zip(direction, keys)):
        if isinstance(key, str) and key in _DIRECTIONS and (key != "-" or plus):
            d[i] = _DIRECTIONS[key]
            continue
        if isinstance(key, str) and key in _HOLD_WORDS:
            d[i] = d[i - 1] if i else 1
            continue
        if isinstance(key, str) and key in _DIRECTION_LETTERS:
            d[i] = _DIRECTION_LETTERS[key]
            continue
        if key == "u" and u_sign is not None:
            d[i] = u_sign
            continue
        try:
            num = float(key)
        except (TypeError, ValueError):
            num = None
        if num in (1.0, -1.0):
            d[i] = int(num)
            continue
        if key == "u":
            why = ("beside L (load / unload) and D (up / down) alike" if {"l", "d"} <= letters else
                   "without an L or a D beside it in the column")
            raise KnitsimInputError(f"{source}: row {row(i)}, column direction: {v!r} reads as an unloading "
                                    f"(L / U) or a loading (U / D), {why}: which one is meant is not said; write "
                                    "load / unload (or up / down) in full")
        if key == "-":
            raise KnitsimInputError(f"{source}: row {row(i)}, column direction: {v!r} marks an unloading (+ / -) or "
                                    "a missing value, and the column holds no '+' to tell: write load / unload")
        raise KnitsimInputError(f"{source}: row {row(i)}, column direction: {v!r} is not 'load' or 'unload' (nor "
                                "another word for them: loading / unloading, up / down, L / U, + / -, 1 / -1; nor "
                                "'hold')")
    return d


def read_cycle_column(source: str, cycle, branch_cycle, row) -> tuple[np.ndarray, tuple]:
    """A file's ``cycle`` column checked against the cycles of its branches, ``branch_cycle`` (from the strain's
    turning points or the ``direction`` column; all 1 for a calibration's loading curve): returns it numbered from
    1, as ``int32``, and the note to give where the file numbers it from 0 (a logger's count), else ``()``.

    Raises
    ------
    KnitsimInputError
        Naming the file, the row (``row(i)``), the column and the file's own value: a cycle that is not a whole
        number >= 0, one that goes back, and one that does not change where a new loading branch starts or
        changes where none does (a step counter of a ramp program, two tests' logs pasted one after the other:
        before, a calibration read such a column without a word).
    """
    craw = np.asarray(cycle, float)
    for i, v in enumerate(craw):
        if not (np.isfinite(v) and v == round(v) and v >= 0):
            raise KnitsimInputError(f"{source}: row {row(i)}, column cycle: {float(v):g} is not a whole "
                                    "number >= 1 (or >= 0, in a column numbered from 0)")
    c = craw.astype(np.int64)
    # (the refusals name the file's own numbers)
    down = np.nonzero(np.diff(c) < 0)[0]
    if len(down):
        i = int(down[0]) + 1
        raise KnitsimInputError(f"{source}: row {row(i)}, column cycle: {int(c[i])} is below the cycle of row "
                                f"{row(i - 1)} ({int(c[i - 1])}): cycles count up, one more with each new loading "
                                "branch; check the column or the row order")
    # the cycle must follow the branches: it changes exactly where a new loading branch starts
    b = np.asarray(branch_cycle, np.int64)
    bad = np.nonzero(c != b - b[0] + c[0])[0]
    if len(bad):
        i = int(bad[0])
        if b[i] == b[i - 1]:
            where = (f"changes from {int(c[i - 1])} (row {row(i - 1)}) where no new loading branch starts (the strain "
                     "goes on in one direction through it)")
        elif c[i] == c[i - 1]:
            where = f"stays the cycle of row {row(i - 1)} where a new loading branch starts"
        else:
            where = f"follows {int(c[i - 1])} (row {row(i - 1)}) where one new loading branch starts"
        raise KnitsimInputError(f"{source}: row {row(i)}, column cycle: {int(c[i])} does not match the branches: it "
                                f"{where}; a cycle starts with each new loading branch. If the column counts "
                                "something else (a step of the test program), rename it")
    if c[0] == 0:
        # a logger that counts from 0 (0, 0, ..., 1, 1, ...): the same cycles, numbered from 1 as the package
        # numbers them (a blind probe's such file was refused at its first row)
        return (c + 1).astype(np.int32), ("column cycle numbered from 0: read as numbered from 1 (its cycle 0 is "
                                          "cycle 1)",)
    return c.astype(np.int32), ()


#: a run of at least this many rows whose force is the column's largest reading while the strain moves on is a flat
#: top (:func:`flat_tops`)
FLAT_TOP_ROWS = 4
#: ... where the loading that reached it rose, over a strain as long as the run's, by more than this many steps of
#: the column's printed resolution (a curve that rises by less prints one value over several rows)
FLAT_TOP_RISE_STEPS = 3.0


def flat_tops(strain, force, tol: float) -> list[tuple[int, int]]:
    """Runs ``(i, j)`` (rows ``i .. j - 1``) of :data:`FLAT_TOP_ROWS` rows or more whose force is the column's
    largest reading, the same number, while the strain moves by more than ``tol`` over them: a load cell (or its
    amplifier, or a logger's range) that saturated, flat at its limit over the top of the loading (or of every
    cycle's), or a force limit of the test.  A run counts only where the loading that reached it rose, over the
    rows before it spanning as much strain as the run does (or all of that loading where it is shorter), by more
    than :data:`FLAT_TOP_RISE_STEPS` steps of the printed resolution (:func:`~knitsim.diagnosis.noise
    .written_resolution`, the last decimal place, as the noise's rounding reads it): a curve whose rise over the run
    is below the last printed digit prints one value there, rising or not.  A hold at the top (the
    strain within ``tol``: the 30 fps frames of a step-and-hold test, Singal 2024's acrylic stockinette X run 3
    holding 29.38 N over 5 rows) is no flat top.  The rows are what the file measured at the limit, not the knit's
    force: a fit reads them as a knit that stopped stiffening (a probe's pull clipped at 80 % of its peak over its
    last 38 rows read only as a misfit, the clipping never named)."""
    s, f = np.asarray(strain, float), np.asarray(force, float)
    if len(f) < FLAT_TOP_ROWS:
        return []
    top, q = float(np.max(f)), written_resolution(f)
    at = np.r_[False, f == top, False]
    edges = np.flatnonzero(np.diff(at.astype(int)))
    runs = []
    for i, j in zip(edges[::2], edges[1::2]):
        span = float(np.max(s[i:j]) - np.min(s[i:j]))
        if j - i < FLAT_TOP_ROWS or not span > tol or i == 0:
            continue
        k = i - 1                               # back along the loading that reached the run, as far as its span
        while k > 0 and s[k - 1] <= s[k] + tol and s[k] > s[i] - span:
            k -= 1
        if top - f[k] > FLAT_TOP_RISE_STEPS * q:
            runs.append((int(i), int(j)))
    return runs


def flat_top_note(runs, strain, force, row, column: str, unit: str = "N") -> str:
    """The read note of :func:`flat_tops`' runs (the first four named), naming the force, the rows and the strains."""
    s = np.asarray(strain, float)
    i0, _ = runs[0]
    where = ", ".join(f"rows {row(i)}-{row(j - 1)} (strain {float(np.min(s[i:j])):.4g} to {float(np.max(s[i:j])):.4g})"
                      for i, j in runs[:4]) + (", ..." if len(runs) > 4 else "")
    return (f"the force column {column} is flat at {float(force[i0]):.6g} {unit}, its largest reading, over {where} "
            "while the strain moves on: a saturated load cell (or a force limit of the test)? Those rows hold the "
            "limit, not the knit's force")


def curve_from_arrays(strain, force, cycle=None, direction=None, rate_mm_s=None, source: str = "curve",
                      rows=None, noise_N: float | None = None, strain_tol: float | None = None) -> MeasuredCurve:
    """Validate arrays into a :class:`MeasuredCurve` (see the module docstring).

    Parameters
    ----------
    strain, force : array_like
        Strain of the course length [-] and force per wale [N].
    cycle, direction, rate_mm_s : array_like, optional
        ``direction`` holds ``"load"`` / ``"unload"`` (or another word for them: :func:`direction_signs`)
        or +1 / -1.
    source : str
        Name used in messages.
    rows : array_like of int, optional
        Spreadsheet row of each entry (default: header = row 1, then 2, 3, ...).
    noise_N : float, optional
        The curve's noise sd [N] if known (else estimated from the curve).
    strain_tol : float, optional
        Strain jitter tolerated inside a branch (default :func:`strain_tolerance`).

    Raises
    ------
    KnitsimInputError
        Naming the row, the column and the value: a NaN, a force below zero by
        more than :data:`NEGATIVE_SIGMAS` noise sd, a strain that goes back
        beyond the tolerance within a given direction, a bad direction, cycle or rate.
    """
    s = np.asarray(strain, float)
    f = np.asarray(force, float)
    n = len(s)
    if n == 0:
        raise KnitsimInputError(f"{source}: no data rows")
    if len(f) != n:
        raise KnitsimInputError(f"{source}: column force_per_wale_N has {len(f)} rows, strain has {n}")
    # every column one value a row: a shorter one was read past its end (uninitialised memory, a curve
    # accepted with made-up directions one run and refused the next: a blind probe of the Python API)
    for name, v in (("cycle", cycle), ("direction", direction), ("rate_mm_s", rate_mm_s), ("rows", rows)):
        if v is not None and (np.ndim(v) != 1 or len(v) != n):
            raise KnitsimInputError(f"{source}: column {name} has {len(v) if np.ndim(v) == 1 else np.shape(v)} "
                                    f"values, strain has {n} rows")
    row_no = np.arange(2, n + 2) if rows is None else np.asarray(rows, np.int64)

    def row(i):
        return int(row_no[i])

    for name, arr in (("strain", s), ("force_per_wale_N", f)):
        bad = np.nonzero(~np.isfinite(arr))[0]
        if len(bad):
            raise KnitsimInputError(f"{source}: row {row(bad[0])}, column {name}: {float(arr[bad[0]])} is not finite "
                                    "(fix or delete the row)")
    bad = np.nonzero(s <= -1.0)[0]
    if len(bad):
        raise KnitsimInputError(f"{source}: row {row(bad[0])}, column strain: {float(s[bad[0]]):g} <= -1 "
                                "means a non-positive course length (is the column a strain, not a length?)")
    if noise_N is not None and not (np.isfinite(noise_N) and noise_N > 0):
        raise KnitsimInputError(f"{source}: noise sd {noise_N!r} N: must be a number > 0")
    if n > 1 and np.all(s == s[0]):
        raise KnitsimInputError(f"{source}: column strain: every row holds {float(s[0]):g}: the specimen is never "
                                "stretched, so there is no curve to compare (is it the right column?)")
    # a knit is modelled in tension: a strain below zero by more than an extensometer's zero offset is a
    # compression (or a reversed sign), not jitter
    limit = compression_limit(s)
    bad = np.nonzero(s < limit)[0]
    if len(bad):
        raise KnitsimInputError(f"{source}: row {row(bad[0])}, column strain: {float(s[bad[0]]):g} is a compression "
                                f"(below {limit:.3g}, more than a zero offset): the knit model runs in tension, "
                                "strain >= 0; check the sign of the column and the extensometer's zero")
    tol = strain_tolerance(s) if strain_tol is None else float(strain_tol)
    refuse_strain_spikes(source, s, f, tol, row)
    if direction is None:
        inf_cycle, d = infer_branches(s, f, tol)
    else:
        d = direction_signs(source, direction, row)
        inf_cycle = _cycles_from_direction(d)
        # within a direction the strain may step back by a hold's creep (<= HOLD_TRAVEL_TOLS tolerances) only, as
        # infer_branches keeps it in its branch without the column (before, by one tolerance: a hold whose strain
        # crept back by 4 while the force relaxed was refused with the column and read as a hold without it)
        clean = _monotone(s, d)
        back = np.nonzero(np.abs(s - clean) > HOLD_TRAVEL_TOLS * tol)[0]
        if len(back):
            i = back[0]
            what = "decreases within a load branch" if d[i] > 0 else "increases within an unload branch"
            raise KnitsimInputError(
                f"{source}: row {row(i)}, column strain: {float(s[i]):g} {what} by {abs(float(s[i] - clean[i])):.3g} "
                f"(more than a hold's creep, {HOLD_TRAVEL_TOLS:g} times the jitter tolerance {tol:.3g}); check the "
                "direction column or the row order")
    cycle_note = ()
    if cycle is None:
        c = inf_cycle
    else:
        c, cycle_note = read_cycle_column(source, cycle, inf_cycle, row)
    r = None
    if rate_mm_s is not None:
        r = np.asarray(rate_mm_s, float)
        bad = np.nonzero(~(np.isfinite(r) & (r > 0)))[0]
        if len(bad):
            raise KnitsimInputError(f"{source}: row {row(bad[0])}, column rate_mm_s: {float(r[bad[0]]):g} must be > 0")
    # the strain column's jitter from the strain as read (its steps; `clean` has its back-steps levelled), where
    # its steps scatter as a jitter does (reading_jitter), and the turning points where it jitters from their
    # branches (settle_turns)
    jitter = reading_jitter(s, d)
    clean = settle_turns(_monotone(s, d), d, jitter)
    refuse_merged_branches(source, clean, f, c, d, row)
    noise = curve_noise(clean, f, c, d, source, noise_N, strain_sd=jitter)
    # a hold whose force relaxes (force_holds): its rows after the first are left out of the fit, of the noise
    # estimate (their steps are the relaxation, not scatter) and of the glitch and stall checks (not their
    # neighbours: a hold's rows beside the steep rows that reach it made those read as a glitch).  Sought where the
    # noise is assumed too, in its assumed sd: a hold's relaxation is what makes a step-and-hold file's noise read as
    # correlated (the raw frames of Singal 2024's acrylic run 5), and a logger printing 0.01 N has its noise assumed
    # at the rounding's sd; both read their holds as the loading going on, without a word
    held = force_holds(s, f, c, d, noise)
    kept = np.ones(len(f), bool)
    for i, j, _ in held:
        kept[i + 1:j] = False
    if held:
        noise = curve_noise(clean[kept], f[kept], c[kept], d[kept], source, noise_N,
                            strain_sd=reading_jitter(s[kept], d[kept]))
    refuse_negative_force(source, f, noise, row)
    found = strain_slips(clean, f, d, noise)
    notes, slips = cycle_note, ()
    if held:
        notes += (hold_note(held, clean, row) + ", so no verdict on this curve is confident",)
    if found:
        slips = tuple(row(k) for k, *_ in found)
        k, jump, times, tells = found[0]
        what = ("while the force moves as over one step: a grip or extensometer slip?" if tells else
                "where the force is too flat to tell rows missing from the log from a grip or extensometer slip")
        more = (f" (and at {len(found) - 1} more row(s): {', '.join(map(str, slips[1:4]))}"
                + (", ..." if len(found) > 4 else "") + ")") if len(found) > 1 else ""
        notes += (f"the strain jumps by {jump:.3g} ({times:.1f} times its steps around) between rows {row(k)} and "
                  f"{row(k + 1)}, {what}{more}; a slip would be read as the knit's stretch, so no verdict on this "
                  "curve is confident",)
    # a force flat at its largest reading while the strain moves on (flat_tops): a saturated load cell, said
    tops = flat_tops(s, f, tol)
    if tops:
        notes += (flat_top_note(tops, s, f, row, "force_per_wale_N", "N per wale")
                  + "; no verdict on this curve is confident",)
    glitches, stalls = (), ()
    if noise.known:
        # (in noise sd: a curve whose noise is assumed, read off a figure or an envelope, cannot tell)
        at = np.flatnonzero(kept)       # (the rows checked: a relaxing hold's left out, mapped back by `at`)
        blocks = [(int(at[i]), int(at[j - 1]) + 1, z) for i, j, z in force_glitches(clean[kept], f[kept], c[kept],
                                                                                      d[kept], noise)]
        if blocks:
            glitches = tuple(row(k) for i, j, _ in blocks for k in range(i, j))
            notes += (f"{len(blocks)} short block(s) of rows whose force leaves the curve and comes back: "
                      + ", ".join(f"rows {row(i)}-{row(j - 1)} ({z:+.0f} sd)" for i, j, z in blocks[:4])
                      + (", ..." if len(blocks) > 4 else "")
                      + " (a load-cell glitch, a yarn snapping and re-seating?); left out of the fit",)
        inside = np.cumsum(kept) - 1    # (a row's index among the rows checked)
        found = [(int(at[k]), m, short) for k, m, short in
                 force_stalls(clean[kept], f[kept], d[kept], noise,
                              skip=[int(inside[k]) for i, j, _ in blocks for k in range(i, j)])]
        if found:
            stalls = tuple(row(k) for k, *_ in found)
            k, m, short = found[0]
            more = (f" (and at {len(found) - 1} more: row(s) {', '.join(map(str, stalls[1:4]))}"
                    + (", ..." if len(found) > 4 else "") + ")") if len(found) > 1 else ""
            notes += (f"the force stalls from row {row(k)} to row {row(k + m)} ({short:.3g} N short of the rise of the "
                      f"steps around) while the strain runs on, and rises again as steeply as before: a grip slip (or "
                      f"the knit's own stick-slip, which the model lacks)?{more}; the rows after it are read at a strain "
                      "the knit did not take, so no verdict on this curve is confident",)
    late = ()
    if noise.known:
        found = unrecorded_turns(f, d, noise)
        if found:
            late = tuple(row(k) for k in found)
            notes += (f"{len(found)} turn(s) not recorded: row(s) {', '.join(map(str, late[:4]))}"
                      + (", ..." if len(found) > 4 else "")
                      + f" end a branch, a step further along it than the row before, but read the next branch already (row "
                        f"{late[0]}: {float(f[found[0]]):.4g} N against {float(f[found[0] - 1]):.4g} N); the replay turns "
                        "at such a row's strain, short of where the grip turned, and the knit's later branches depend on "
                        "it, so no verdict on this curve is confident (log the turning points)",)
    return MeasuredCurve(clean, f, np.asarray(c, np.int32), d, r, source, row_no, s, noise, notes, slips, glitches,
                         stalls, tuple(row(k) for k in np.flatnonzero(~kept)), late_turns=late,
                         flat_top=tuple(row(k) for i, j in tops for k in range(i, j)))


#: a step of the strain this many times the median step of its branch is a jump (:func:`strain_slips`)
SLIP_STEPS = 3.0
#: the force change a jump should carry (the local slope times the jump, beyond one step's) must exceed this
#: many noise sd for a missing one to be seen
SLIP_SIGMAS = 6.0


def strain_slips(strain, force, direction, noise) -> list[tuple[int, float, float, bool]]:
    """Rows where the strain jumps alone: ``(index, jump, jump / the steps around, force_can_tell)``.

    A grip that slips (or an extensometer knife that slides) adds a step to the recorded strain that the knit
    did not take: the strain jumps by several steps between two rows, its steps regular on both sides (a blind
    probe's slip of 0.015 at strain 0.4, steps of 0.005, was fitted as yarn_compaction, confident, chi2/dof
    6.2 left).  Within each branch (rows of one direction, at least 8), a step above :data:`SLIP_STEPS` times
    the three steps on each side (each within 1.5 times their median) is a jump.  Where the local slope (their
    secant) says the jump should change the force by more than :data:`SLIP_SIGMAS` noise sd beyond one step's,
    the force tells, and a jump where it changes only as over one step is a slip (``force_can_tell`` true).
    On a plateau the force cannot tell rows missing from a slip: reported with ``force_can_tell`` false.  Not
    reported: a jump where the force changes beyond one step's by more than that many sd (the knit moved with
    it: rows missing from the log, a stick-slip of the knit; the measured acrylic stockinette has two), and a
    change of rate (every later step larger: no isolated jump)."""
    s, f, d = np.asarray(strain, float), np.asarray(force, float), np.asarray(direction)
    out = []
    cuts = np.flatnonzero(np.diff(d) != 0) + 1
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(s)]):
        if b - a < 8:
            continue
        ds, dF = np.diff(s[a:b]), np.diff(f[a:b])
        typ = float(np.median(np.abs(ds)))
        if not typ > 0:
            continue
        for k in np.flatnonzero(np.abs(ds) > SLIP_STEPS * typ):
            near = np.r_[np.arange(k - 3, k), np.arange(k + 1, k + 4)]
            if near[0] < 0 or near[-1] >= len(ds):
                continue
            steps = np.abs(ds[near])
            local = float(np.median(steps))
            if not (local > 0 and np.all(steps <= 1.5 * local) and abs(ds[k]) > SLIP_STEPS * local):
                continue
            slope = float(np.sum(dF[near]) / np.sum(ds[near]))
            one, full = slope * np.sign(ds[k]) * local, slope * ds[k]
            sd = float(noise.sd_at(np.array([max(f[a + k], f[a + k + 1])]))[0]) if noise is not None else 0.0
            if abs(dF[k] - one) > SLIP_SIGMAS * max(sd, 1e-12):
                continue          # the force moved with the jump beyond one step's and the noise: the knit's
            tells = bool(abs(full - one) > SLIP_SIGMAS * max(sd, 1e-12))
            out.append((int(a + k), float(ds[k]), float(abs(ds[k]) / local), tells))
    return out


#: a block of at most this many rows (and at least 2: one row alone is the diagnosis' outlier) whose force leaves
#: the curve and comes back is a glitch (:func:`force_glitches`)
GLITCH_MAX_ROWS = 6
#: the rows on each side of a block that say where the curve runs (a polynomial of GLITCH_DEGREE in the strain
#: through them).  A cubic through 4 rows a side: the quadratic through 3 missed the model's own jammed pull (rows
#: 0.005 apart, E-glass) by 17-30 mN, beyond 3 sd of its 3 mN, so a 4-row glitch there, 25 % low, was found only
#: while the glitch itself made the noise read as growing with the force; a cubic through 3 a side bridges a
#: stall's two offset sides (read as a glitch)
GLITCH_NEIGHBOURS = 4
GLITCH_DEGREE = 3
#: every row of a glitch lies beyond GLITCH_ROW_SIGMAS noise sd of that cubic, on one side, one of them beyond
#: GLITCH_SIGMAS (the diagnosis' outlier limit), while the neighbours lie within GLITCH_ROW_SIGMAS of it
GLITCH_SIGMAS = 6.0
GLITCH_ROW_SIGMAS = 3.0
#: ... and the slopes on its two sides within this factor of each other (:func:`force_glitches`)
GLITCH_BEND = 4.0


#: a hold (:func:`force_holds`): at least this many rows of a branch in a row at one strain ...
HOLD_MIN_ROWS = 4
#: ... whose force moves against the branch (falls on a loading, rises on an unloading) by more than this many
#: standard errors of the line through them
HOLD_SIGMAS = 5.0
#: rows "at one strain": within this share of the branch's mean step of the first (its travel over its rows: a
#: logger's steady step is more), or within the curve's jitter tolerance (strain_tolerance)
HOLD_STEP_SHARE = 0.1


#: a branch's last row that moves against its branch from the row before by more than this many sd of their
#: difference is on the next branch already (:func:`unrecorded_turns`)
TURN_SIGMAS = 5.0


def unrecorded_turns(force, direction, noise) -> list[int]:
    """Rows that end a branch but read the next branch already: the turn lies between such a row and the row before
    it, and no row records it.  A logger sampling in time rarely writes the grip's turning point: its last "loading"
    row (the strain still above the row before it) is read after the grip turned, on the unloading, its force below
    the row before by more than :data:`TURN_SIGMAS` sd of their difference (a knit's loading does not lose force as
    its strain grows; nor an unloading gain it), and not below the row after it by as much (that is a spike, an
    outlier).  The replay turns at that row's strain, short of the grip's, and the knit's later branches remember
    where it turned (slack, beta or T frozen there): a probe's model-made cycles 0.1-0.6, 2 mN of noise, sampled at
    irregular steps without the turning rows (peaks read at 0.5989, 0.5947, 0.5979), read as a confident
    `unexplained`, chi2/dof 3.1, the first peak's row 18.6 sd off."""
    f, d = np.asarray(force, float), np.asarray(direction)
    sd = np.maximum(noise.sd_at(f), 1e-300)
    out = []
    for t in range(1, len(f) - 1):
        if d[t] == d[t + 1] or d[t - 1] != d[t]:
            continue
        back = (f[t] - f[t - 1]) * float(d[t])
        ahead = (f[t] - f[t + 1]) * float(d[t])
        if (back < -TURN_SIGMAS * math.hypot(sd[t], sd[t - 1])
                and ahead >= -TURN_SIGMAS * math.hypot(sd[t], sd[t + 1])):
            out.append(t)
    return out


def force_holds(strain, force, cycle, direction, noise) -> list[tuple[int, int, float]]:
    """Holds whose force relaxes: ``(start, end, change)``, rows ``start..end-1`` of one branch at one strain *as
    read* (``strain`` the column as read, not the running extreme: a slack reload read as the unloading going on
    keeps the extreme while its strain runs on), each within :data:`HOLD_STEP_SHARE` of the branch's mean step, or
    the curve's jitter tolerance (:func:`strain_tolerance`), of the first (on a loading, or below it by up to
    :data:`HOLD_TRAVEL_TOLS` jitter tolerances, as far as :func:`infer_branches` keeps a strain that goes back in the
    loading: a clamp or extensometer that settles, creeping back, while the force relaxes); at least
    :data:`HOLD_MIN_ROWS` of them, whose force moves against the branch's direction (falls on a loading, rises on an
    unloading: a relaxation, or the recovery of an unloading held) by more than :data:`HOLD_SIGMAS` standard errors of
    the line through them in the row order (each row weighted by its noise sd); ``change`` the line's change over the
    hold [N].

    A step-and-hold test (a hold at each peak, the force relaxing by a few per cent) holds rows that the model,
    rate-independent, keeps at one force: a probe's hold of 20 rows at the first peak of the model's own cycles,
    relaxing by 6 %, read as a confident ``yarn_extension`` (its jamming rows before the hold taken for a force
    glitch, the hold's rows being their neighbours).  A force that moves *with* the branch at one strain is not a
    hold: a logger faster than its extensometer writes a ramp's rising force at one strain."""
    s, f = np.asarray(strain, float), np.asarray(force, float)
    d = np.asarray(direction)
    sd = np.maximum(noise.sd_at(f), 1e-300)
    jitter_tol = strain_tolerance(s)
    out = []
    for a, b in _branches(cycle, direction):
        if b - a < HOLD_MIN_ROWS:
            continue
        tol = max(HOLD_STEP_SHARE * float(np.mean(np.abs(np.diff(s[a:b])))), jitter_tol)
        # (on a loading, the strain may creep back over a hold, as far as infer_branches keeps in the loading: a
        # clamp or extensometer that settles while the force relaxes; on an unloading not, where a slack reload
        # read as the unloading going on runs back, its force flat at ~0 and then rising)
        back = HOLD_TRAVEL_TOLS * jitter_tol if d[a] > 0 else tol
        lo = a
        while lo < b:
            hi = lo + 1
            while hi < b and -back <= s[hi] - s[lo] <= tol:
                hi += 1
            if hi - lo >= HOLD_MIN_ROWS:      # rows lo..hi-1 at one strain
                t = np.arange(hi - lo, dtype=float)
                ww = 1.0 / sd[lo:hi] ** 2
                tm = float(np.sum(ww * t) / np.sum(ww))
                sxx = float(np.sum(ww * (t - tm) ** 2))
                change = float(np.sum(ww * (t - tm) * f[lo:hi]) / sxx) * (hi - lo - 1)
                if -change * float(d[lo]) > HOLD_SIGMAS * (hi - lo - 1) / math.sqrt(sxx):
                    out.append((lo, hi, change))
            lo = hi
    return out


def hold_note(held, strain, row, unit: str = "N") -> str:
    """What the readers say of the holds :func:`force_holds` found (``row(i)``: the spreadsheet row of entry i)."""
    return (f"{len(held)} hold(s) whose force relaxes at one strain: "
            + ", ".join(f"rows {row(i)}-{row(j - 1)} at strain {float(strain[i]):.4g}, {change:+.3g} {unit}"
                        for i, j, change in held[:4])
            + (", ..." if len(held) > 4 else "")
            + "; the model has no relaxation (it is rate-independent): each hold's rows but its first are left out of "
              "the fit, and the curve after it starts from a relaxed knit the model does not know")


def _row_sd(strain, force, cycle, direction, noise) -> np.ndarray:
    """Each row's noise sd as the diagnosis weighs it (:meth:`~knitsim.diagnosis.noise.CurveNoise.sd_at`)."""
    from .noise import row_slopes
    slope = row_slopes(strain, force, cycle, direction) if noise.strain_sd > 0 else None
    return np.maximum(noise.sd_at(force, slope), 1e-300)


def _branches(*keys) -> list[tuple[int, int]]:
    """(start, end) of the runs of rows where every key stays the same (a branch: one cycle and direction)."""
    cut = np.zeros(len(keys[0]) - 1, bool) if len(keys[0]) > 1 else np.zeros(0, bool)
    for k in keys:
        cut |= np.diff(np.asarray(k)) != 0
    br = np.r_[0, np.flatnonzero(cut) + 1, len(keys[0])]
    return list(zip(br[:-1].tolist(), br[1:].tolist()))


def _poly_through(x, f, w, at, degree: int):
    """The weighted least-squares polynomial of ``degree`` through points ``x``, ``f`` (weights ``w`` = 1 / sd;
    one window per row of the arrays): its values at the points, at ``at``, the variance of those at ``at``,
    and whether the fit was determined."""
    x0 = x[:, :1]
    span = np.maximum(np.ptp(x, axis=1, keepdims=True), 1e-300)
    u, v = (x - x0) / span, (at - x0) / span
    U = np.stack([u ** p for p in range(degree + 1)], axis=2)
    V = np.stack([v ** p for p in range(degree + 1)], axis=2)
    A = U * w[:, :, None]
    M = np.einsum("nij,nik->njk", A, A)
    ok = np.abs(np.linalg.det(M)) > 1e-12 * (np.einsum("nii->n", M) / (degree + 1)) ** (degree + 1)
    M[~ok] = np.eye(degree + 1)
    cov = np.linalg.inv(M)
    coef = np.einsum("njk,nk->nj", cov, np.einsum("nij,ni->nj", A, f * w))
    return (np.einsum("nij,nj->ni", U, coef), np.einsum("nij,nj->ni", V, coef),
            np.einsum("nij,njk,nik->ni", V, cov, V), ok)


def _slopes(x, f, w):
    """The weighted least-squares slope of each window of points ``x``, ``f`` (weights ``w`` = 1 / sd) and its
    standard error."""
    ww = w * w
    xm = np.sum(ww * x, axis=1, keepdims=True) / np.sum(ww, axis=1, keepdims=True)
    sxx = np.maximum(np.sum(ww * (x - xm) ** 2, axis=1), 1e-300)
    return np.sum(ww * (x - xm) * f, axis=1) / sxx, 1.0 / np.sqrt(sxx)


def force_glitches(strain, force, cycle, direction, noise) -> list[tuple[int, int, float]]:
    """Short blocks of rows whose force leaves the curve and comes back: ``(start, end, z)``, rows
    ``start..end-1``, z the largest deviation of the block's rows in noise sd (signed).

    A load cell that glitches for a moment, or a yarn that snaps and re-seats, drops the force for a few rows;
    the force then goes on where the curve was.  One row alone is left to the diagnosis (its outliers, judged
    against the fit); a block of rows was not: a blind probe's four rows 15 % low in the jammed part of an
    effect-free pull (a neighbour off too, so none isolated) moved the whole fit and read as a confident
    ``unexplained``.  Within a branch, a block of 2 to :data:`GLITCH_MAX_ROWS` rows is a glitch where the
    cubic (:data:`GLITCH_DEGREE`) in the strain through the :data:`GLITCH_NEIGHBOURS` rows on each side (weighted by the rows' noise
    sd, ``noise.sd_at``) passes within :data:`GLITCH_ROW_SIGMAS` sd of each of them, every row of the block lies
    beyond it on one side by more than :data:`GLITCH_ROW_SIGMAS` sd (its own with the cubic's at the row),
    one beyond :data:`GLITCH_SIGMAS` and beyond the force the curve gains over one strain step there (its slope,
    the side lines' interpolated, times the median step: a row off by less may be read at a strain, or a time,
    off by less than a step: a 2-row stall of the interpolated Do 2020 6.5 mm curve, 0.5-0.8 of a step, is not
    taken), and the two sides are one smooth stretch of the curve: their slopes (the line through each side's
    rows) either both resolved (beyond :data:`GLITCH_ROW_SIGMAS` standard errors), of one sign and within a
    factor :data:`GLITCH_BEND` of each other (a jamming knit stiffens by about 2 over such a window), or both
    flat within their errors and at one level.  A knee (the end of a stick, jamming setting in, the slack toe
    of a specimen mounted loose: a flat side and a steep one) is no glitch: a cubic bridges it smoothly and
    the corner's rows lie off it.  Nor is a block that goes on along one side's own line (within
    :data:`GLITCH_ROW_SIGMAS` of the line through that side's rows): the curve steps between it and the other
    side (a slack reload taking the force up within a row: the blind study's lab specimen 66, seed 0, rows
    348-352)."""
    s, f = np.asarray(strain, float), np.asarray(force, float)
    sd = _row_sd(s, f, cycle, direction, noise)
    P = GLITCH_NEIGHBOURS
    out = []
    for a, b in _branches(cycle, direction):
        taken, found = np.zeros(b - a, bool), []
        for k in range(2, GLITCH_MAX_ROWS + 1):
            starts = np.arange(a + P, b - P - k + 1)
            if not len(starts):
                break
            before = starts[:, None] + np.arange(-P, 0)
            after = starts[:, None] + k + np.arange(P)
            nb = np.concatenate([before, after], axis=1)
            blk = starts[:, None] + np.arange(k)
            at_nb, pred, var, ok = _poly_through(s[nb], f[nb], 1.0 / sd[nb], s[blk], GLITCH_DEGREE)
            z = (f[blk] - pred) / np.sqrt(sd[blk] ** 2 + var)
            (g1, e1), (g2, e2) = _slopes(s[before], f[before], 1.0 / sd[before]), _slopes(s[after], f[after], 1.0 / sd[after])
            r1, r2 = np.abs(g1) > GLITCH_ROW_SIGMAS * e1, np.abs(g2) > GLITCH_ROW_SIGMAS * e2
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(g1 * g2 > 0, np.maximum(g1 / g2, g2 / g1), np.inf)
            # flat sides: at one level (their lines meet in the block's middle within their errors)
            mid = 0.5 * (s[starts - 1] + s[starts + k])
            (m1, v1), (m2, v2) = (_poly_through(s[x], f[x], 1.0 / sd[x], mid[:, None], 1)[1:3] for x in (before, after))
            level = np.abs(m1 - m2)[:, 0] <= GLITCH_ROW_SIGMAS * np.sqrt(v1 + v2)[:, 0]
            smooth = (r1 & r2 & (ratio <= GLITCH_BEND)) | (~r1 & ~r2 & level)
            # a block that goes on along one side's own line is that side's: the curve steps between the block and
            # the other side (a slack reload taking the force up again within a row), it does not come back
            goes_on = np.zeros(len(starts), bool)
            for x in (before, after):
                _, line, lvar, _ = _poly_through(s[x], f[x], 1.0 / sd[x], s[blk], 1)
                goes_on |= np.all(np.abs(f[blk] - line) <= GLITCH_ROW_SIGMAS * np.sqrt(sd[blk] ** 2 + lvar), axis=1)
            hit = ok & smooth & ~goes_on & np.all(np.abs(f[nb] - at_nb) <= GLITCH_ROW_SIGMAS * sd[nb], axis=1)
            hit &= np.all(z > GLITCH_ROW_SIGMAS, axis=1) | np.all(z < -GLITCH_ROW_SIGMAS, axis=1)
            # one row beyond GLITCH_SIGMAS sd and beyond what the curve's force changes over one strain step there:
            # a row off by less could be read at a strain (a time) off by less than a step
            h = np.median(np.abs(np.diff(s[nb], axis=1)), axis=1)[:, None]
            # (a block whose sides share one strain, a jittering extensometer's: its slope is unbounded there, so no
            # row of it counts as beyond one step's change; the inf and NaN this makes are that, not a fault)
            with np.errstate(over="ignore", invalid="ignore"):
                g = np.abs(g1[:, None] + (g2 - g1)[:, None] * (s[blk] - s[starts - 1][:, None])
                           / np.maximum(s[starts + k] - s[starts - 1], 1e-300)[:, None])
                big = (np.abs(z) > GLITCH_SIGMAS) & (np.abs(f[blk] - pred) > g * h)
            hit &= np.any(big, axis=1)
            for n in np.flatnonzero(hit):
                found.append((float(np.max(np.abs(z[n]))), int(starts[n]), k, float(z[n][np.argmax(np.abs(z[n]))])))
        # the block that stands out most first: rows beside a glitch, with the glitch among their neighbours, can
        # pass for a block of their own
        for _, i, k, zmax in sorted(found, reverse=True):
            if taken[i - a - 1:i - a + k + 1].any():
                continue                # (overlaps, or touches, a block taken)
            taken[i - a:i - a + k] = True
            out.append((i, i + k, zmax))
    return sorted(out)


#: a stall of the force on a loading branch (:func:`force_stalls`): at most this many steps ...
STALL_MAX_STEPS = 6
#: ... between STALL_NEIGHBOURS steps on each side that each raise the force by more than STALL_RISE_SIGMAS noise
#: sd (the force resolves the slope) and by slopes within a factor STALL_STEADY of their median (a steady rise)
STALL_NEIGHBOURS = 3
STALL_RISE_SIGMAS = 3.0
STALL_STEADY = 2.0
#: ... where the force rises by less than STALL_SHARE of what those slopes give, short of it by more than
#: SLIP_SIGMAS noise sd
STALL_SHARE = 0.25


def force_stalls(strain, force, direction, noise, skip=()) -> list[tuple[int, int, float]]:
    """Where the force stalls on a steep loading while the strain runs on: ``(start, steps, shortfall_N)``, the
    force flat (or falling) from row ``start`` to row ``start + steps``.

    A specimen that slips in its grip while the crosshead moves on (the strain read off the crosshead, or an
    extensometer on the grips) keeps its force, or drops it, for a few rows, and then rises again as before from
    where it stalled: every later row is read at a strain the knit did not take (as :func:`strain_slips`, a slip
    seen in the strain).  Not seen on a plateau (the force cannot tell); a knee of the curve (the end of a stick,
    the force rising steeply and then slowly ever after) is not a stall: the force must rise as steeply after it
    as before.  On a loading branch, a run of 1 to :data:`STALL_MAX_STEPS` steps is a stall where the
    :data:`STALL_NEIGHBOURS` steps on each side each raise the force by more than :data:`STALL_RISE_SIGMAS` noise
    sd, at slopes within a factor :data:`STALL_STEADY` of their median, and the run raises it by less than
    :data:`STALL_SHARE` of what that median slope gives over its strain, short by more than :data:`SLIP_SIGMAS`
    noise sd and by more than that slope gives over :data:`SLIP_STEPS` - 1 of the neighbouring strain steps (the
    strain the knit did not take, as much as a jump of SLIP_STEPS steps that :func:`strain_slips` reports adds:
    a one-step flat of the interpolated Do 2020 6.5 mm curve is not taken); the run's first and last steps
    stall themselves.  A force that drops and comes back to the curve is a glitch (:func:`force_glitches`; its rows are
    ``skip``ped): the step back up is no steady step.  The knit's own stick-slip (a yarn that slides at a
    crossing) reads the same; the model has none either."""
    s, f, d = np.asarray(strain, float), np.asarray(force, float), np.asarray(direction)
    sd = _row_sd(s, f, np.zeros(len(s)), d, noise)
    skip = set(int(k) for k in skip)
    P = STALL_NEIGHBOURS
    out = []
    for a, b in _branches(d):
        if d[a] <= 0 or b - a < 2 * P + 2:
            continue
        ds, dF = np.diff(s[a:b]), np.diff(f[a:b])
        step_sd = np.sqrt(sd[a:b - 1] ** 2 + sd[a + 1:b] ** 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            slope = np.where(ds > 0, dF / ds, np.nan)
        # steps that can neighbour a stall (a finite slope, a rise above the noise), counted: a row whose P steps
        # before are not all such is no stall's start, for any run length (the loop below would try each one:
        # 13 s of reading a 10^5-row logger file)
        steady = np.r_[0, np.cumsum(np.isfinite(slope) & (dF > STALL_RISE_SIGMAS * step_sd))]
        k = P
        while k < len(ds) - P:
            if steady[k] - steady[k - P] < P:
                k += 1
                continue
            hit = None
            for m in range(1, STALL_MAX_STEPS + 1):
                if k + m + P > len(ds):
                    break
                near = np.r_[k - P:k, k + m:k + m + P]
                g = slope[near]
                if not np.all(np.isfinite(g)) or not np.all(dF[near] > STALL_RISE_SIGMAS * step_sd[near]):
                    continue
                med = float(np.median(g))
                if not (med > 0 and np.all(g <= STALL_STEADY * med) and np.all(g >= med / STALL_STEADY)):
                    continue
                want = med * float(s[a + k + m] - s[a + k])
                rise = float(f[a + k + m] - f[a + k])
                sd_run = float(np.hypot(sd[a + k], sd[a + k + m]))
                lost = (want - rise) / med          # the strain the knit did not take, as strain_slips' jump
                ends = all(dF[q] < STALL_SHARE * med * ds[q] for q in (k, k + m - 1))   # (the run's own ends stall)
                if (ends and rise < STALL_SHARE * want and want - rise > SLIP_SIGMAS * sd_run
                        and lost > (SLIP_STEPS - 1.0) * float(np.median(ds[near]))):
                    if not skip.intersection(range(a + k - P, a + k + m + P + 1)):
                        hit = (a + k, m, want - rise)
                    break
            if hit is not None:
                out.append(hit)
                k += hit[1] + P
            else:
                k += 1
    return out


#: a row (or a block of rows) whose strain leaves its neighbours and returns by more than this many times the
#: neighbouring steps, while its force stays in line with theirs, is a typo (:func:`refuse_strain_spikes`)
SPIKE_STEPS = 10.0
#: the longest block of rows displaced in strain that :func:`refuse_strain_spikes` looks for
SPIKE_BLOCK_ROWS = 8


def refuse_strain_spikes(source: str, strain, force, tol: float, row) -> None:
    """Refuse a row, or a block of up to :data:`SPIKE_BLOCK_ROWS` rows, whose strain jumps away from its
    neighbours and back while the force runs on in line.

    A mistyped strain (0.843 for 0.343, 0.154 for 0.254; rows with two neighbours on each side) is read without
    cycle / direction columns as a reversal and back: a made-up cycle (a blind probe: one such row gave an
    effect-free specimen a confident ``yarn_extension``).  So is a block of rows shifted in strain (an
    extensometer that slipped and caught again, rows pasted at another strain): a second probe's four rows
    0.046 back, the force rising on through them, were read as an unloading and a second cycle, and the fit
    collapsed to a confident ``unexplained``.  A real turn of the test changes the force with the strain; a
    real excursion recorded by a few rows is as sparse as its neighbouring steps.  Refused where the strain
    jumps by more than :data:`SPIKE_STEPS` times the neighbouring steps (and the jitter tolerance ``tol``) at
    the block's start and back at its end, the block's own steps no larger than the neighbours' scale, the
    strain after the block within half the jump of where it was before, and the block's forces within the
    noise of the chord from the row before it to the row after it."""
    s, f = np.asarray(strain, float), np.asarray(force, float)
    n = len(s)
    if n < 3:
        return
    noise = 3.0 * _force_scale(f)
    ds = np.diff(s)
    # the first row, whose neighbour before it is the rest the test starts from (strain 0): a strain beyond the
    # rows after it by more than SPIKE_STEPS times their steps, while the force does not fall as the strain goes
    # back (0.6 typed for 0.0 at the top of a pull from rest: every row below 0.6 was read as the loading going
    # on at 0.6, the replayed strain being the branch's running extreme, without a word)
    if n >= 3 and s[0] > 0 and ds[0] < 0 and -ds[0] > SPIKE_STEPS * max(abs(ds[1]), tol) and f[1] >= f[0] - noise:
        raise KnitsimInputError(
            f"{source}: row {row(0)}, column strain: {float(s[0]):g} lies beyond the rows after it ({float(s[1]):g} "
            f"at row {row(1)}, {-ds[0] / max(abs(ds[1]), tol):.0f} times their steps), while the force does not fall "
            f"as the strain goes back ({float(f[0]):g}, {float(f[1]):g} N): a typo or a logger glitch, not an "
            "unloading (a knit's force follows its strain back).  Correct or delete the row")
    # (a block with two neighbours on each side: the steps around it say what a jump is; only a step beyond
    # SPIKE_STEPS tolerances can start one, which keeps a 200,000-row file's scan to its few large steps)
    starts = np.flatnonzero(np.abs(ds) > SPIKE_STEPS * tol) + 1
    for i in starts[(starts >= 2) & (starts <= n - 3)]:
        a = ds[i - 1]                                   # the jump into the block (s[i] - s[i - 1])
        for j in range(i + 1, min(i + SPIKE_BLOCK_ROWS, n - 2) + 1):
            b = ds[j - 1]                               # the jump out of it (s[j] - s[j - 1])
            jump = min(abs(a), abs(b))
            if a * b >= 0 or abs(s[j] - s[i - 1]) > 0.5 * jump:
                continue
            inside = np.abs(ds[i:j - 1]).max() if j - 1 > i else 0.0
            local = max(abs(ds[i - 2]), abs(ds[j]), inside, tol)
            if jump <= SPIKE_STEPS * local:
                continue
            # the force of the block against the chord from the row before it to the row after it
            chord = f[i - 1] + (f[j] - f[i - 1]) * (np.arange(i, j) - (i - 1)) / (j - (i - 1))
            if np.max(np.abs(f[i:j] - chord)) > noise + abs(f[j] - f[i - 1]):
                continue   # the force follows the strain: a turn of the test recorded by these rows
            what = (f"row {row(i)}, column strain: {float(s[i]):g} jumps from {float(s[i - 1]):g} (row {row(i - 1)}) "
                    f"and back to {float(s[j]):g} (row {row(j)})" if j == i + 1 else
                    f"rows {row(i)}-{row(j - 1)}, column strain: {float(s[i]):g} .. {float(s[j - 1]):g} jump from "
                    f"{float(s[i - 1]):g} (row {row(i - 1)}) and back to {float(s[j]):g} (row {row(j)})")
            forces = ", ".join(f"{float(v):g}" for v in f[i - 1:j + 1])
            raise KnitsimInputError(
                f"{source}: {what}, {jump / local:.0f} times the neighbouring steps, while the force runs on in line "
                f"({forces} N): a typo, a logger glitch or a slipped extensometer, not a turn of the test (a knit's "
                f"force follows its strain back).  Correct or delete the row{'s' if j > i + 1 else ''}")


#: rows at one strain that differ by more than this many times the curve's scatter between strains are
#: readings of different branches (:func:`refuse_merged_branches`)
MERGED_REPEAT_RATIO = 5.0
#: ... on at least this many strains, and this share of the curve's distinct strains
MERGED_MIN_STRAINS = 10
MERGED_MIN_SHARE = 0.1


def refuse_merged_branches(source: str, strain, force, cycle, direction, row) -> None:
    """Refuse a curve whose rows at one strain are readings of different branches, not one reading twice.

    A logger faster than the extensometer writes the force twice at one strain, and the two differ by the
    noise (:func:`knitsim.diagnosis.noise.repeat_differences`).  A file sorted by strain (a spreadsheet sort,
    its row order lost) puts the loading, the unloading and the reloading at one strain next to each other:
    their forces differ by the hysteresis, many times the scatter between neighbouring strains, and the
    curve as read (one branch, the force jumping up and down) is no measurement; a blind probe's sorted file
    had its noise estimated at 96.5 % of the force and an effect named with confidence.  Refused where the
    robust sd of the differences at one strain exceeds :data:`MERGED_REPEAT_RATIO` times that of the
    chord deviations, on at least :data:`MERGED_MIN_STRAINS` strains and :data:`MERGED_MIN_SHARE` of the
    distinct strains (a relaxation hold at a few strains is not caught: its rows are one branch).  Branches
    read on grids of their own and interleaved by a sort are not caught either: the chords between their
    rows are no scatter, and the ratio does not show."""
    from .noise import MAD_TO_SD, MIN_SAMPLES, _repeats, chord_residuals

    s, f = np.asarray(strain, float), np.asarray(force, float)
    rep, _ = _repeats(s, f, cycle, direction)
    chords = chord_residuals(s, f, cycle, direction)
    n_strains = len(np.unique(s))
    if len(rep) < max(MERGED_MIN_STRAINS, MERGED_MIN_SHARE * n_strains) or len(chords) < MIN_SAMPLES:
        return
    repeated = len(np.unique(s[1:][(s[1:] == s[:-1])]))
    sd_rep = MAD_TO_SD * float(np.median(rep))
    sd_chord = MAD_TO_SD * float(np.median(chords))
    if repeated < max(MERGED_MIN_STRAINS, MERGED_MIN_SHARE * n_strains) or not sd_rep > MERGED_REPEAT_RATIO * sd_chord:
        return
    same = np.nonzero((s[1:] == s[:-1]) & (np.asarray(cycle)[1:] == np.asarray(cycle)[:-1])
                      & (np.asarray(direction)[1:] == np.asarray(direction)[:-1]))[0]
    i = int(same[np.argmax(np.abs(np.diff(f)[same]))])
    raise KnitsimInputError(
        f"{source}: rows {row(i)} and {row(i + 1)} read {float(f[i]):g} and {float(f[i + 1]):g} N at one strain "
        f"{float(s[i]):g}; on {repeated} strains the rows at one strain differ by {sd_rep / max(sd_chord, 1e-300):.3g} "
        f"times the curve's scatter between strains (robust sd {sd_rep:.3g} against {sd_chord:.3g} N): readings of "
        "different branches, not of one state.  Was the file sorted by strain (its row order lost), or are its "
        "cycles written without cycle / direction columns?  Give the rows in the order they were measured")


def drop_copied_rows(cols: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The columns read from a file (:func:`~knitsim.io.table_input.read_csv_columns`, ``_row`` the line
    numbers) without a row that repeats the row above it in every column: a row copied (pasted twice, a
    logger writing one record twice) is not a second measurement, and counted twice it would weigh
    twice and read as zero noise.  A row at the same strain with another force is kept: a second reading.  So is
    one read at another time (a :data:`TIME_LABELS` column, read as a label: a logger's or a video's reading that
    repeats the one before at a later time, as a slow ramp or a hold printed coarsely does; Singal 2024's acrylic
    run 5 has 268 such frames of its 2168, its holds' relaxation among them, which were dropped as copies).  The
    time columns are compared, then left out of the columns returned.  The notes of the columns
    (:class:`knitsim.io.table_input.Columns`) are kept, with one more naming the rows dropped (a blind probe's file
    read "711 rows" and said nothing of the copies it had left out)."""
    names = [k for k in cols if k != "_row"]
    n = len(cols["_row"])
    copy = np.zeros(n, bool)
    if n > 1:
        copy[1:] = np.logical_and.reduce([cols[k][1:] == cols[k][:-1] for k in names])
    kept = [k for k in cols if k not in TIME_LABELS]
    if not copy.any():
        if len(kept) == len(cols):
            return cols
        note = ()
    else:
        rows = [int(r) for r in np.asarray(cols["_row"])[copy]]
        note = (f"{len(rows)} row(s) that repeat the row above in every column left out as copies (row(s) "
                + ", ".join(map(str, rows[:8])) + (", ..." if len(rows) > 8 else "") + ")",)
    out = Columns({k: cols[k][~copy] for k in kept}, notes=tuple(notes_of(cols)) + note)
    out.not_read = getattr(cols, "not_read", ())
    return out


def refuse_several_tests(source, cols):
    """Refuse a file whose rows name more than one specimen or test (a :data:`TEST_LABELS` column, read by
    :func:`~knitsim.io.table_input.read_csv_columns` as ``labels``, holding two values or more): its curves,
    stacked, would be read as one test's cycles (a probe's file of specimens A1 and A2, one under the other, was
    read as two cycles of one curve, the drop from A1's last row to A2's first as an unloading, without a word).
    Only values that each label :data:`MIN_CURVE_ROWS` rows or more count: a logger's row counter named ``Sample``
    (1, 2, 3, ...) names no test.  Returns the columns without the labels (checked, not measured: a row copied
    under the next counter value is still a copy, :func:`drop_copied_rows`)."""
    for name in TEST_LABELS:
        if name not in cols:
            continue
        values = [str(v).strip() for v in cols[name]]
        counts = Counter(values)
        first = {}
        for v, r in zip(values, cols["_row"]):
            if v and v not in first and counts[v] >= MIN_CURVE_ROWS:
                first[v] = int(r)
        if len(first) > 1:
            shown = ", ".join(f"{v!r} from row {r}" for v, r in list(first.items())[:4])
            more = f" and {len(first) - 4} more" if len(first) > 4 else ""
            raise KnitsimInputError(f"{source}: column {name} holds {len(first)} specimens or tests ({shown}{more}): "
                                    "a file is one test's curve; split it into one file per test (tests of one "
                                    "specimen are given together, as several files)")
    if not any(name in cols for name in TEST_LABELS):
        return cols
    out = Columns({k: v for k, v in cols.items() if k not in TEST_LABELS}, notes=notes_of(cols))
    out.not_read = getattr(cols, "not_read", ())
    return out


def pasted_block(strain, force, tol: float) -> tuple[int, int, int] | None:
    """``(i, j, m)``: the first block of rows ``i .. i + m - 1`` that starts where the strain steps back below the
    rows before it by more than ``tol`` and repeats rows ``j .. j + m - 1`` before it exactly, in strain and force,
    while its strain moves on by more than ``tol`` (rows of a loading pasted twice); None where there is none.  A
    reload retraces no earlier readings to the last digit of both columns; a hold may (Singal 2024's video frames:
    0.01 N and 1e-5 of strain, 2 or 3 rows at one reading repeated after the tracked strain jittered back, within
    3e-5 of strain), and is no block.  Only the first row of each step back is looked up (once per cycle of a
    cyclic log)."""
    s, f = np.asarray(strain, float), np.asarray(force, float)
    back = np.maximum.accumulate(s) - s > tol
    for i in np.flatnonzero(back & ~np.r_[False, back[:-1]]):
        for j in np.flatnonzero((s[:i] == s[i]) & (f[:i] == f[i])):
            m = 1
            while i + m < len(s) and j + m < i and s[i + m] == s[j + m] and f[i + m] == f[j + m]:
                m += 1
            if m >= 2 and s[i + m - 1] - s[i] > tol:
                return int(i), int(j), m
    return None


def pasted_note(block, row) -> str:
    """What a refusal of a step back adds where :func:`pasted_block` found the rows it starts to be a copy."""
    i, j, m = block
    return (f"rows {row(i)}-{row(i + m - 1)} repeat rows {row(j)}-{row(j + m - 1)} in strain and force: rows pasted "
            "twice? Delete the copy")


def refuse_few_rows(source, rows) -> None:
    """Refuse a measured file of fewer than :data:`MIN_CURVE_ROWS` data rows (``rows``: their line numbers)."""
    if len(rows) < MIN_CURVE_ROWS:
        raise KnitsimInputError(f"{source}: {len(rows)} data row(s) (rows {', '.join(map(str, rows))}): a measured "
                                f"curve needs at least {MIN_CURVE_ROWS}, for its shape and its noise")


def read_measured_curve(path: str | Path, noise_N: float | None = None) -> MeasuredCurve:
    """Read and validate a measured curve CSV (see the module docstring).

    ``noise_N`` is the file's noise sd [N] when known (else estimated from the curve).

    Raises
    ------
    KnitsimInputError
        Missing column, NaN or text, force below zero beyond the noise, strain
        going back within a branch beyond the jitter tolerance, bad direction /
        cycle / rate; the message names the file, row and column.
    """
    try:
        cols = read_csv_columns(path, REQUIRED, OPTIONAL, numeric=("strain", "force_per_wale_N", "cycle", "rate_mm_s"),
                                aliases=LAB_ALIASES, labels=TEST_LABELS + TIME_LABELS)
    except KnitsimInputError as exc:
        raise KnitsimInputError(str(exc) + _total_force_hint(path, str(exc))) from None
    cols = drop_copied_rows(refuse_several_tests(path, cols))
    refuse_few_rows(path, cols["_row"])
    # (a file only: arrays made in code keep the convention that the first row ends a loading from rest, as a
    # hand-made unloading logged from its peak does, tests/diagnosis/test_diagnose.py)
    tol = strain_tolerance(cols["strain"])
    refuse_reversed_rows(str(path), cols["strain"], tol, lambda i: int(cols["_row"][i]))
    # a block of rows pasted again after later ones (the strain back to an earlier reading and on, repeating it in
    # both columns): without a direction column, read as a short unloading and reload or, within 10 tolerances of
    # travel, as a hold at the running maximum (a probe's 10 rows pasted back 0.047 were read so, without a word)
    block = pasted_block(cols["strain"], cols["force_per_wale_N"], tol)
    if block is not None:
        raise KnitsimInputError(f"{path}: {pasted_note(block, lambda i: int(cols['_row'][i]))} (a test never "
                                "retraces its readings to the last digit of both columns)")
    curve = curve_from_arrays(cols["strain"], cols["force_per_wale_N"], cols.get("cycle"), cols.get("direction"),
                              cols.get("rate_mm_s"), source=str(path), rows=cols["_row"], noise_N=noise_N)
    if notes_of(cols):
        curve = replace(curve, notes=tuple(notes_of(cols)) + tuple(curve.notes))
    start = unrecorded_loading(curve, tol)
    if start:
        curve = replace(curve, notes=tuple(curve.notes) + (start,))
    if len(curve) > LONG_CURVE_ROWS:
        k = -(-len(curve) // THINNED_CURVE_ROWS)
        curve = replace(curve, notes=tuple(curve.notes) + (
            f"{len(curve)} rows: each is an increment of every simulation the diagnosis runs, so it will take long "
            f"(a 5,000-row curve took about a minute a simulation on one core); one row in {k} of the file keeps "
            f"the curve's shape in ~{-(-len(curve) // k)} rows",))
    check_response(curve)
    return curve


def unrecorded_loading(curve: MeasuredCurve, tol: float) -> str | None:
    """What to say of a file that starts by unloading (its first row above strain 0 by more than ``tol``, its second
    row lower): the loading that reached the first row is not in the file, and the replay (:func:`program_for_curve`)
    makes it one monotonic loading from rest, whose force no row checks.  A log started at a peak reads so; its
    unloading and later cycles depend on that loading (a blind probe: such a file was read without a word).  None
    for a file that starts by loading, from rest or from a pretension."""
    s = curve.strain
    if len(s) < 2 or not s[0] > tol or curve.direction[1] != -1:
        return None
    row = int(curve.rows[0]) if curve.rows is not None else 1
    return (f"starts by unloading from strain {float(s[0]):.4g} (row {row}, {float(curve.force[0]):.3g} N per wale): "
            "the loading that reached it is not in the file; it is replayed as one loading from rest to that strain, "
            "which no row checks (the unloading and later cycles depend on it)")


#: a measured curve of more rows than this is said, when read, to be slow to diagnose: every row is an increment of
#: every simulation (program_for_curve).  A probe's logger files, one effect on one core: 1,000 rows 16 s, 5,000 rows
#: 57 s; 10^5 rows (100 Hz) had not finished the baseline after 8 min
LONG_CURVE_ROWS = 5000
#: the rows the note of a long curve suggests thinning it to
THINNED_CURVE_ROWS = 2000


def _total_force_hint(path, message: str) -> str:
    """Where a file lacks force_per_wale_N but holds a total force (``load_N`` / ``force_N``, or a machine's
    name for one with its unit): what to do with it ("" otherwise).  A blind probe's Bluehill export (``Load``
    over ``(N)``) was refused without a word on the force it had."""
    if "missing column" not in message or "force_per_wale_N" not in message:
        return ""
    try:
        cols = read_csv_columns(path, [], ("load_N", "force_N"), numeric=(), aliases=LAB_ALIASES)
    except KnitsimInputError as exc:
        # a total force's name with a per-wale unit (load_N [N/wale]) says two things: the reading of that total
        # refuses it naming the header cell, which is what to fix (before, only "missing force_per_wale_N")
        return f"; {exc}" if "/wale" in str(exc) else ""
    total = next((k for k in ("load_N", "force_N") if k in cols), None)
    if total is None:
        return ""
    return (f"; the file holds a total force (read as {total}): diagnose compares the force per wale, so divide it "
            "by the specimen's wale count into a column force_per_wale_N, or run knitsim calibrate, which reads "
            "total forces with the specimen's wales or width")


def program_for_curve(curve: MeasuredCurve, max_increment: float = 0.005) -> tuple[LoadProgram, np.ndarray]:
    """The load program that replays a measured strain history.

    Every measured strain is a corner of a :func:`piecewise_linear` program
    (the turning points among them), refined to steps of at most
    ``max_increment``, so every measured row is an increment of the program.

    Returns
    -------
    program : LoadProgram
    rows : ndarray of int, shape [len(curve)]
        The program increment of each measured row; -1 for rows at rest
        (strain 0 before the first move), whose simulated force is 0.
    """
    s = curve.strain
    program = piecewise_linear(s, max_increment, field=f"{curve.source}: strain")
    # walk the corners as piecewise_linear does: each non-zero segment adds its increments,
    # the last of which is the segment's end (the measured row)
    pts = [0.0] + list(s) if s[0] != 0.0 else list(s)
    offset = 1 if s[0] != 0.0 else 0
    rows = np.empty(len(s), np.int64)
    rate = np.zeros(len(program)) if curve.rate_mm_s is not None else None
    count = 0
    if offset == 0:
        rows[0] = -1
    for j, (a, b) in enumerate(zip(pts[:-1], pts[1:])):
        start = count
        if b != a:
            count += max(1, int(np.ceil(abs(b - a) / max_increment - 1e-12)))
        rows[j + 1 - offset] = count - 1
        if rate is not None:
            rate[start:count] = curve.rate_mm_s[j + 1 - offset]  # the rate of the row the segment reaches
    if count != len(program):  # pragma: no cover - guards against a change of piecewise_linear
        raise RuntimeError(f"program_for_curve: counted {count} increments, the program has {len(program)}")
    if rate is not None:
        program = replace(program, rate=rate)
    return program, rows


def force_at_rows(history: BatchHistory, rows: np.ndarray, cell: int = 0) -> tuple[np.ndarray, list[str]]:
    """Simulated force per wale [N] and stage label at the measured rows.

    ``rows`` from :func:`program_for_curve`; a row at rest (-1) has the force of the
    cell's rest state (Table 4's initial state, not zero; 0 where the history records
    none) and the label ``adherence`` (the rest state sticks until the first move).
    A blind probe found every real curve's row at strain 0 scored against 0 N: with a
    fitted offset cancelling the rest force on the other rows, that one row was half the
    best fit's chi^2.
    """
    F = history.force_per_wale[:, cell]
    rows = np.asarray(rows)
    at = np.maximum(rows, 0)
    rest = float(history.rest["F"][cell]) if history.rest is not None else 0.0
    force = np.where(rows >= 0, F[at], rest)
    lab = np.where(rows >= 0, history.label_array(cell)[at], "adherence").tolist()
    return force, lab
