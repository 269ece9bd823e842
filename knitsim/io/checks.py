"""Checks that make a result say why it may not be believable (summaries of ``cell`` and ``run``).

Each check returns :class:`ResultWarning` s, written to ``summary.json`` (``warnings``)
and printed by the commands:

``zero_force_cycle``
    A cycle whose peak force is (near) zero, below a tenth of the previous cycle's,
    after a cycle that carried load: the knit went slack and took (almost) no load
    again up to the upper strain.  With
    Table 4 it has physical reasons (README, "the reload pocket"), but a user
    must see it rather than read ``all_converged: true``.  Where the cycle never loads past the residual
    strain an earlier unloading left (the slack knit's length), the message says that instead.
``reload_below_earlier_loading``
    A later cycle whose loading, where it passes the largest strain of the cycles before it, carries less
    than :data:`RELOAD_SHARE_MIN` of the force the knit carried there before
    (:func:`reloads_below_earlier_loading`).  Table 4's sliding stage S+ keeps the contact's normal force
    Rn at its value where sliding began; a reload from slack, or from a low force, starts sliding at a low
    Rn and its branch stays below the first loading at every strain, the earlier maximum and beyond (a
    blind probe: cycles to 0.2, 0.3, 0.45 and 0.6 peaked at 0.048 N per wale at 0.6, where a single pull
    carries 0.167 N).  A measured knit reloads to most of its earlier force there (Dusserre 2015
    Fig. 10: 5 N, then 4 N).
``reload_above_first_loading``
    A later cycle whose loading, below the largest strain reached before it, carries more than
    :data:`RELOAD_ABOVE_FACTOR` times the force of the first loading at the same strain
    (:func:`reloads_above_first_loading`).  Friction at the crossing only resists the slip, so a knit
    reloaded after an unloading rejoins its first loading from below at the earlier maximum strain
    (Masing's rule of frictional assemblies; a measured knit's reload lies below its first loading).
    Table 4's loading stages hold a force (Rn, or T after a mirror reload) at its value where the stage
    began: a reload that begins from a state of higher contact force than the first loading (left by a
    jam) slides on a higher plateau, with Coulomb or Dahl friction and every reload and unloading rule
    (the calibrated specimen: 0.53 N per wale at grip strain 0.3 in cycles 2 and 3, 0.17 N on the first
    loading; README, "Reloads above the first loading").
``reload_loss_continues``
    Cycles loading to the same strain whose peaks go on falling after the first reload, a second or later
    reload below :data:`SHAKEDOWN_RATIO` of the cycle before it (:func:`reloads_without_shakedown`): a
    measured knit settles after its first cycle (Fig. 10: cycle 3 close to cycle 2); Table 4's frozen Rn
    starts each reload's sliding lower than the last.
``loop_creates_energy``
    A load-then-unload excursion that comes back to the strain it started from
    (:func:`closed_excursions`) with ``oint F dC < 0``: its unloading returned above
    its loading curve.  Friction at the crossing only dissipates (``-int Rt ds_BC >= 0``:
    Rt opposes the slip in S+ and S-, the stick holds s_BC), and the elastica stores
    energy; what supplies it is Table 4's closures, force-type conditions frozen
    without a conjugate displacement (Rn on loading, T on unloading) while the width
    W is free, so the lateral direction works on the cell unaccounted.  Met after a
    reversal from a jammed state, where T frozen at the slide carries the tension
    the jamming raised into the unjammed unloading (README, "Loops that return energy").
``force_cap_reached``
    Cells of a patch stopped at their force cap (status ``force_cap``) or held within
    :data:`FORCE_CAP_RTOL` of it (a column that cannot pass the cap and does not converge): from that
    grip strain on the curve is the cap, not the knit's response (:func:`force_cap_reached`).
``heads_interpenetrate``
    States where the centreline gap between the heads of neighbouring loops of a
    course is below the yarn's in-plane width: the loops pass through each other
    (W = 4 d does not stop the heads at contact, on loading or, as in the calibrated
    specimen, on unloading; ``jamming_criterion = "head_gap"`` does).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

#: what a cycle's ``oint F d(strain)`` is (:func:`cycle_work`): a closed path's dissipated energy, an open
#: path's work (elastic energy included), a path that only loads, a path that only unloads (a program that
#: starts by unloading from rest: its first "cycle" is no loop, and its peak is where it starts)
ENERGY_KINDS = ("hysteresis", "work", "loading_work", "unloading_work")
#: a patch cycle's energy whose estimated error (:func:`knitsim.cell.cycle.dissipated_energy_error`) passes this share
#: of it is warned of (``energy_under_resolved``): a blind probe's E-glass/basalt column, cycles 0.1-0.4 at the largest
#: increment allowed, 0.1, printed a hysteresis of 1.121 N mm without a word, 28 % below the 1.562 N mm of 0.0025
ENERGY_ERROR_SHARE = 0.05


def cycle_work(strain: np.ndarray, force: np.ndarray, unloads: bool, loads: bool = True,
               imposed: np.ndarray | None = None) -> dict:
    """The work of one cycle's path, named for what it is.

    ``oint F d(strain)`` by trapezoids (:func:`~knitsim.cell.cycle.dissipated_energy`) is the
    energy dissipated (the *hysteresis*) only when the path is closed: it ends at the strain it
    started from (within 1e-9 of the strain range).  An open path (the paper's first cycle goes
    0 -> 0.6 -> 0.1) holds elastic energy too: its ``work``; a path that only loads, its
    ``loading work``; one that only unloads (``loads`` false: a program that starts by unloading from
    rest), its ``unloading work`` (the energy the knit gives back, negative where it carries force).

    ``imposed``: the program's strain along the same rows, where closure is judged (as a test judges it, by
    the grip's return): a cell slack at a cycle's end stays at the length where its force reached 0, its own
    strain short of the program's, and a returning cycle was called open ("work") by ``knitsim cell`` and
    closed ("hysteresis") by ``knitsim run`` on the same knit (a blind probe).  The slack rows carry no
    force, so the value is the same either way.

    Returns
    -------
    dict
        ``{"kind": "hysteresis" | "work" | "loading_work" | "unloading_work", "closed": bool, "value": float}``
        (per unit strain).
    """
    from ..cell.cycle import dissipated_energy

    s, f = np.asarray(strain, float), np.asarray(force, float)
    w = dissipated_energy(s, f) if len(s) > 1 else 0.0
    c = s if imposed is None else np.asarray(imposed, float)
    span = c.max() - c.min() if len(c) else 0.0
    closed, kind = work_kinds(unloads, loads, len(c), c[0] if len(c) else 0.0, c[-1] if len(c) else 0.0, span)
    return {"kind": ENERGY_KINDS[int(kind)], "closed": bool(closed), "value": float(w)}


def work_kinds(unloads, loads, n, first, last, span) -> tuple[np.ndarray, np.ndarray]:
    """:func:`cycle_work`'s ``closed`` and ``kind`` (an index into :data:`ENERGY_KINDS`) of paths (numbers, or
    arrays of them: knitsim.io.results.cycle_numbers judges many cells' cycles at once) that unload or not, load
    or not, of ``n`` rows whose closure strain goes from ``first`` to ``last`` over a range ``span`` (max - min)."""
    span = np.asarray(span, float)
    # (max(span, 1e-12), NaN kept as Python's max keeps it)
    closed = (np.asarray(unloads, bool) & (np.asarray(n) > 1)
              & (np.abs(np.asarray(last, float) - first) <= 1e-9 * np.where(1e-12 > span, 1e-12, span)))
    kind = np.where(closed, 0, np.where(~np.asarray(unloads, bool), 2, np.where(np.asarray(loads, bool), 1, 3)))
    return closed, kind


def _turns(s: np.ndarray) -> list[int]:
    """Rows where the strain path turns (its steps before and after change sign, neither a hold)."""
    ds = np.sign(np.diff(s))
    # (vectorised: a patch judges every distinct cell's path, 90,000 of them on a 300 x 300 random patch, where
    # the loop over rows took 33 s)
    turn = (ds[:-1] != 0) & (ds[1:] != 0) & (ds[1:] != ds[:-1])
    return (np.flatnonzero(turn) + 1).tolist()


def closed_excursions(strain: np.ndarray, atol: float = 1e-12, turns: list[int] | None = None) -> list[tuple[int, int]]:
    """Load-then-unload excursions that come back to where they started.

    Parameters
    ----------
    strain : ndarray, shape [n + 1]
        Imposed strains with the rest state first (index 0).
    atol : float
        How close the strain must come back (1e-12: an imposed strain; a cell of a patch, whose strain
        the column coupling solves, comes back only to within its solution).
    turns : list of int, optional
        The path's turning points, where already found (:func:`_turns`; the three excursion finders share them).

    Returns
    -------
    list of (i, j)
        ``strain[i] == strain[j]`` (within ``atol``) with one turning point, a maximum, strictly between.
        An unload-reload excursion from a peak is not one (:func:`reload_excursions`): it may come back
        with less stored bending energy, so its work alone does not tell.
    """
    s = np.asarray(strain, float)
    turns = _turns(s) if turns is None else turns
    out = []
    for n, t in enumerate(turns):
        i = turns[n - 1] if n > 0 else 0                # where the excursion starts
        end = turns[n + 1] if n + 1 < len(turns) else len(s) - 1
        back = np.flatnonzero(np.abs(s[t + 1:end + 1] - s[i]) < atol)
        if len(back) and s[t] > s[i]:                   # loaded first, then unloaded back
            out.append((i, t + 1 + int(back[0])))
    return out


def reload_excursions(strain: np.ndarray, atol: float = 1e-12, turns: list[int] | None = None) -> list[tuple[int, int]]:
    """Unload-then-reload excursions from a peak that come back to its strain: ``(i, j)`` with ``i`` a
    maximum turning point, ``strain[j] == strain[i]`` (within ``atol``) and one turning point, a minimum,
    strictly between (:func:`closed_excursions` gives the load-then-unload ones; ``turns`` as there)."""
    s = np.asarray(strain, float)
    turns = _turns(s) if turns is None else turns
    out = []
    for n, t in enumerate(turns[:-1]):
        if s[t] <= s[t - 1]:
            continue                                    # a minimum
        end = turns[n + 2] if n + 2 < len(turns) else len(s) - 1
        back = np.flatnonzero(np.abs(s[turns[n + 1] + 1:end + 1] - s[t]) < atol)
        if len(back):
            out.append((t, turns[n + 1] + 1 + int(back[0])))
    return out


def crossing_excursions(strain: np.ndarray, atol: float = 1e-12,
                        turns: list[int] | None = None) -> list[tuple[int, float, int]]:
    """Load-then-unload excursions that start on a loading branch, not at its turning point: ``(k, t, j)``
    with ``j`` the end of an unloading branch (the next turning point, or the path's end) above the start of
    the loading branch before it (by more than ``atol``: else :func:`closed_excursions` has it), and the
    loading passing ``strain[j]`` at ``strain[k] + t (strain[k + 1] - strain[k])``, ``0 <= t < 1``.  The
    first cycle of a program whose lower strain is above 0 (0 -> 0.8 -> 0.32) is one.  ``turns``: as
    :func:`closed_excursions`."""
    s = np.asarray(strain, float)
    turns = _turns(s) if turns is None else turns
    out = []
    for n, top in enumerate(turns):
        if s[top] <= s[top - 1]:
            continue                                     # a minimum
        start = turns[n - 1] if n > 0 else 0
        j = turns[n + 1] if n + 1 < len(turns) else len(s) - 1
        if not (s[start] + atol < s[j] < s[top]):
            continue
        k = start + int(np.nonzero(s[start:top + 1] <= s[j])[0][-1])
        out.append((k, float((s[j] - s[k]) / (s[k + 1] - s[k])), j))
    return out


def _between_rows(strain: np.ndarray, force: np.ndarray) -> float:
    """Bound of the trapezoids' error on ``int F d(strain)`` where the force is monotone between rows: half
    the rectangle of each increment (an unloading from a peak drops steeply, often going slack inside one)."""
    return 0.5 * float(np.sum(np.abs(np.diff(force)) * np.abs(np.diff(strain))))


def loop_work_tolerance(strain: np.ndarray, force: np.ndarray) -> float:
    """Rounding of ``oint F d(strain)`` by trapezoids over a loop's rows [N per unit strain]."""
    s, f = np.asarray(strain, float), np.asarray(force, float)
    return 1e-9 * (np.max(np.abs(f)) + 1e-12) * (np.ptp(s) + 1e-12) * len(s)


def energy_creating_loops(strain: np.ndarray, force: np.ndarray, C0: float,
                          what: str = "the cell", atol: float = 1e-12,
                          stored_at: Callable[[int], float] | None = None, first: bool = False) -> list[ResultWarning]:
    """Warnings for closed load-then-unload excursions whose work ``oint F dC`` is negative, and, with
    ``stored_at``, for unload-then-reload excursions from a peak whose work is negative while the stored
    bending energy did not fall.

    Parameters
    ----------
    strain, force : ndarray, shape [n + 1]
        Imposed strains and forces per wale [N], the rest state first.
    C0 : float
        Course length at rest [mm] (the work in N mm is the per-strain work times C0).
    what : str
        What the path is, for the message.
    atol : float
        Closure of a loop (:func:`closed_excursions`).  A loop that comes back to within
        ``delta = |s_j - s_i|`` differs from a closed one by at most ``max|F| delta`` of work (the segment
        that would close it), added to the rounding tolerance: only a loop that returns energy beyond it
        is flagged.
    stored_at : callable, optional
        ``stored_at(k)``: the bending energy stored in one stitch at row ``k`` [N mm], four quarter stitches
        (:func:`knitsim.cell.quarter_loop.stored_energy`).  An unload-reload loop from a peak ends in
        another state than it started (the state is path-dependent), so its work ``W`` may be negative by
        the stored energy it released, ``W = dU + D`` with friction's ``D >= 0``; where ``W < 0`` and
        ``dU >= 0`` nothing was released and the loop created energy (a blind probe: m = 0.2, phi0 = 0.19,
        0.6 -> 0.1 -> 0.6: W = -3.3e-3 N mm, dU = +3.4e-3 N mm, the reload pocket of cycle 2; -2.29e-3 N mm
        at increments of 5e-4).  The work by trapezoids is judged against its error bound where the force is
        monotone between rows, half of ``|dF| |dC|`` summed: a force that drops to slack inside one increment
        would otherwise pass for energy created.  So are load-then-unload loops that start on a loading
        branch rather than at its turning point (:func:`crossing_excursions`; the first cycle of a program
        whose lower strain is above 0: E-glass, 0 -> 0.8 -> 0.32, -0.875 N mm with the stored energy up
        0.19 N mm), with the start interpolated between rows.  Without ``stored_at`` these loops are not judged.
    first : bool
        Stop at the first warning (a caller that asks only whether the path warns: a sweep's flag).

    A loop that starts at a compressive rest state (``force[0] < 0``: Table 4's initial state at C0, W0
    needs the grips to push) is not judged: that state is not free, and a path that comes back to its
    strain slack (F = 0) has released the energy stored at rest, which no friction law forbids.
    :func:`compressive_rest_state` says so instead.
    """
    from ..cell.cycle import dissipated_energy

    s, f = np.asarray(strain, float), np.asarray(force, float)
    out = []
    turns = _turns(s)          # (once for the three finders: a patch calls this for each of its distinct cells)
    for i, j in closed_excursions(s, atol, turns):
        if i == 0 and f[0] < 0.0:
            continue
        w = dissipated_energy(s[i:j + 1], f[i:j + 1])
        gap = abs(s[j] - s[i]) * float(np.max(np.abs(f[i:j + 1])))
        if np.isfinite(w) and w < -(loop_work_tolerance(s[i:j + 1], f[i:j + 1]) + gap):
            top = float(np.max(s[i:j + 1]))
            out.append(ResultWarning(
                "loop_creates_energy",
                f"{what}: the loop {s[i]:g} -> {top:g} -> {s[i]:g} returns energy (oint F dC = {w * C0:.3g} N mm "
                f"per wale < 0; force {f[j]:.3g} N back at strain {s[j]:g} against {f[i]:.3g} N on the way up): not "
                f"a hysteresis; friction only dissipates, the energy comes from Table 4's frozen force closures (T "
                f"frozen on unloading from a jammed state) (README, 'Loops that return energy')"))
            if first:
                return out
    if stored_at is None:
        return out
    for k, t, j in crossing_excursions(s, atol, turns):
        # from where the loading passed strain[j] (interpolated between rows k and k + 1) to j
        fx = f[k] + t * (f[k + 1] - f[k])
        ss = np.concatenate([[s[j]], s[k + 1:j + 1]])
        ff = np.concatenate([[fx], f[k + 1:j + 1]])
        w = dissipated_energy(ss, ff)
        if not (np.isfinite(w) and w < -(loop_work_tolerance(ss, ff) + _between_rows(s[k:j + 1], f[k:j + 1]))):
            continue
        ux = float(stored_at(k)) + t * (float(stored_at(k + 1)) - float(stored_at(k)))
        dU = float(stored_at(j)) - ux
        if np.isfinite(dU) and dU >= 0.0:
            top = float(np.max(s[k:j + 1]))
            out.append(ResultWarning(
                "loop_creates_energy",
                f"{what}: the loop {s[j]:g} -> {top:g} -> {s[j]:g} (from the loading at strain {s[j]:g}) returns "
                f"energy (oint F dC = {w * C0:.3g} N mm per wale < 0; force {f[j]:.3g} N back at strain {s[j]:g} "
                f"against {fx:.3g} N on the way up) while the bending energy stored in the stitch rose by "
                f"{dU:.3g} N mm: no stored energy was released; it comes from Table 4's closures (README, 'Loops "
                f"that return energy')"))
            if first:
                return out
    for i, j in reload_excursions(s, atol, turns):
        w = dissipated_energy(s[i:j + 1], f[i:j + 1])
        gap = abs(s[j] - s[i]) * float(np.max(np.abs(f[i:j + 1])))
        tol = loop_work_tolerance(s[i:j + 1], f[i:j + 1]) + gap + _between_rows(s[i:j + 1], f[i:j + 1])
        if not (np.isfinite(w) and w < -tol):
            continue
        dU = float(stored_at(j)) - float(stored_at(i))
        if np.isfinite(dU) and dU >= -tol * C0:
            low = float(np.min(s[i:j + 1]))
            # (a blind probe read "rose by -0.00313 N mm: no stored energy was released" where a release within
            # the work's tolerance was meant)
            stored = (f"the bending energy stored in the stitch rose by {dU:.3g} N mm: no stored energy was released"
                      if dU >= 0.0 else
                      f"the bending energy stored in the stitch fell by only {-dU:.3g} N mm, within the loop work's "
                      f"tolerance ({tol * C0:.3g} N mm), less than the {-w * C0:.3g} N mm returned")
            out.append(ResultWarning(
                "loop_creates_energy",
                f"{what}: the loop {s[i]:g} -> {low:g} -> {s[i]:g} (unloaded from a peak and reloaded) returns energy "
                f"(oint F dC = {w * C0:.3g} N mm per wale < 0; force {f[j]:.3g} N back at strain {s[j]:g} against "
                f"{f[i]:.3g} N at the peak) while {stored}; it comes from Table 4's closures (README, 'Loops that "
                f"return energy')"))
            if first:
                return out
    return out


#: values per temporary array of :func:`energy_loop_candidates` (its paths are judged in blocks of so many
#: values: 2^22 float64, 32 MB; on 90,000 paths x 311 rows, blocks of 13,486 paths took 3.2 s against 8.4 s unblocked)
CANDIDATE_BLOCK = 1 << 22


def energy_loop_candidates(strain: np.ndarray, force: np.ndarray, atol: float = 1e-12,
                           judge_open: bool = True) -> np.ndarray:
    """The paths for which :func:`energy_creating_loops` may warn, found for many paths at once.

    A prefilter: every path it leaves out would get no warning from :func:`energy_creating_loops` (same
    ``atol``; ``judge_open`` where ``stored_at`` is given), so a caller runs that function only on the paths
    it keeps.  Each excursion of the three finders (:func:`closed_excursions`, :func:`crossing_excursions`,
    :func:`reload_excursions`) is found for all paths with one set of turning rows at once, and kept where its
    work, by cumulative trapezoids, is below minus that function's tolerance plus a margin for the summation
    order (the stored-energy test and the compressive-rest exemption are left to that function: a superset).
    A path with a non-finite value is always kept.  (A patch judges every distinct cell's path: 90,000 on a
    300 x 300 random patch, where the loop of calls took 15 s of a 87 s run on a GPU host.)

    Parameters
    ----------
    strain, force : ndarray, shape [n + 1, m]
        One path per column, the rest state first (as :func:`energy_creating_loops` takes them).
    atol : float
        Closure of a loop, as there.
    judge_open : bool
        Whether load-then-unload loops from a loading and unload-reload loops from a peak are judged (the
        function's ``stored_at`` given).

    Returns
    -------
    ndarray of bool, shape [m]
    """
    S, F = np.asarray(strain, float), np.asarray(force, float)
    if S.ndim != 2 or F.shape != S.shape:
        raise ValueError(f"energy_loop_candidates: strain {S.shape} and force {F.shape} must be [n + 1, m] arrays")
    R, m = S.shape
    # in blocks of paths: a dozen [n + 1, block] temporaries of ~32 MB each, whatever the patch
    block = max(1, CANDIDATE_BLOCK // max(R, 1))
    if m > block:
        return np.concatenate([energy_loop_candidates(S[:, c:c + block], F[:, c:c + block], atol, judge_open)
                               for c in range(0, m, block)])
    keep = ~np.all(np.isfinite(S) & np.isfinite(F), axis=0)
    if R < 3 or m == 0:
        return keep
    dS = np.diff(S, axis=0)
    seg = 0.5 * (F[1:] + F[:-1]) * dS
    zero = np.zeros((1, m))
    work = np.vstack([zero, np.cumsum(seg, axis=0)])                 # work[j] - work[a]: trapezoids a .. j
    size = np.vstack([zero, np.cumsum(np.abs(seg), axis=0)])
    between = np.vstack([zero, np.cumsum(0.5 * np.abs(np.diff(F, axis=0)) * np.abs(dS), axis=0)])
    eps = np.finfo(float).eps
    ds = np.sign(dS)
    turn = (ds[:-1] != 0) & (ds[1:] != 0) & (ds[1:] != ds[:-1])      # as _turns, row r + 1 of each path
    packed = np.ascontiguousarray(np.packbits(turn, axis=0).T)        # one row of bytes per path
    if np.all(packed == packed[:1]):
        pattern = np.zeros(m, int)
    else:
        _, pattern = np.unique(packed.view(np.dtype((np.void, packed.shape[1]))).ravel(), return_inverse=True)
        pattern = np.asarray(pattern).ravel()
    absF = np.abs(F)
    for u in np.unique(pattern):
        cols = np.flatnonzero(pattern == u)
        turns = (np.flatnonzero(turn[:, cols[0]]) + 1).tolist()
        if not turns:
            continue
        pick = slice(None) if len(cols) == m else cols            # (no copies where every path turns alike)
        keep[cols] |= _negative_excursions(S[:, pick], F[:, pick], absF[:, pick], work[:, pick], size[:, pick],
                                           between[:, pick], turns, atol, judge_open, eps)
    return keep


def _span(a: np.ndarray, lo, hi, lowest: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """Per column c, the max and (with ``lowest``) min of a[lo .. hi, c] (inclusive), one of ``lo`` and
    ``hi`` a row for all columns, the other a row per column: running extremes from the common end."""
    cols = np.arange(a.shape[1])
    if np.ndim(lo) == 0:
        lo = int(lo)
        block = a[lo:int(np.max(hi)) + 1]
        at = np.asarray(hi) - lo
    else:
        hi = int(hi)
        block = a[int(np.min(lo)):hi + 1][::-1]
        at = hi - np.asarray(lo)
    low = np.minimum.accumulate(block, axis=0)[at, cols] if lowest else None
    return np.maximum.accumulate(block, axis=0)[at, cols], low


def _negative_excursions(s, f, absf, work, size, between, turns, atol, judge_open, eps) -> np.ndarray:
    """:func:`energy_loop_candidates` for paths with the same turning rows ``turns``."""
    R, m = s.shape
    cols = np.arange(m)
    keep = np.zeros(m, bool)

    def below(w, fmax, smax, smin, rows, extra, mag):
        # w < -(loop_work_tolerance + extra), with a margin for the order of summation
        tol = 1e-9 * (fmax + 1e-12) * (smax - smin + 1e-12) * rows + extra
        return w < -tol + 64.0 * R * eps * (mag + tol)

    for n, t in enumerate(turns):                                     # closed_excursions
        i = turns[n - 1] if n > 0 else 0
        end = turns[n + 1] if n + 1 < len(turns) else R - 1
        near = np.abs(s[t + 1:end + 1] - s[i]) < atol
        has = near.any(axis=0) & (s[t] > s[i])
        if not has.any():
            continue
        j = t + 1 + near.argmax(axis=0)
        fmax = _span(absf, i, j, False)[0]
        smax, smin = _span(s, i, j)
        w = work[j, cols] - work[i]
        gap = np.abs(s[j, cols] - s[i]) * fmax
        keep |= has & below(w, fmax, smax, smin, j - i + 1, gap, size[j, cols] - size[i])
    if not judge_open:
        return keep
    for n, top in enumerate(turns):                                   # crossing_excursions
        start = turns[n - 1] if n > 0 else 0
        j = turns[n + 1] if n + 1 < len(turns) else R - 1
        sj = s[j]
        has = (s[top] > s[top - 1]) & (s[start] + atol < sj) & (sj < s[top])
        if not has.any():
            continue
        under = s[start:top + 1] <= sj
        k = start + (top - start) - under[::-1].argmax(axis=0)       # the last row at or below s[j]
        k = np.where(has, np.minimum(k, top - 1), start)
        sk, sk1, fk, fk1 = s[k, cols], s[k + 1, cols], f[k, cols], f[k + 1, cols]
        # (a path without such an excursion, k its start: where its first rows hold one strain, tt is infinite and
        # fx NaN, unread; outside this block a patch's held column printed numpy's RuntimeWarning on the console)
        with np.errstate(divide="ignore", invalid="ignore"):
            tt = (sj - sk) / (sk1 - sk)
            fx = fk + tt * (fk1 - fk)
        w = 0.5 * (fx + fk1) * (sk1 - sj) + (work[j] - work[k + 1, cols])
        fmax = np.maximum(_span(absf, k + 1, j, False)[0], np.abs(fx))
        smax, smin = _span(s, k + 1, j)
        smax, smin = np.maximum(smax, sj), np.minimum(smin, sj)
        mag = np.abs(0.5 * (fx + fk1) * (sk1 - sj)) + size[j] - size[k + 1, cols]
        keep |= has & below(w, fmax, smax, smin, j - k + 1, between[j] - between[k, cols], mag)
    for n, t in enumerate(turns[:-1]):                                # reload_excursions
        end = turns[n + 2] if n + 2 < len(turns) else R - 1
        first = turns[n + 1] + 1
        near = np.abs(s[first:end + 1] - s[t]) < atol
        has = (s[t] > s[t - 1]) & near.any(axis=0)
        if not has.any():
            continue
        j = first + near.argmax(axis=0)
        fmax = _span(absf, t, j, False)[0]
        smax, smin = _span(s, t, j)
        w = work[j, cols] - work[t]
        extra = np.abs(s[j, cols] - s[t]) * fmax + (between[j, cols] - between[t])
        keep |= has & below(w, fmax, smax, smin, j - t + 1, extra, size[j, cols] - size[t])
    return keep


def is_compressive(force_rest):
    """:func:`compressive_rest_state`'s rule: a finite rest force per wale below 0 (a number, or an array of them:
    :func:`knitsim.sweep.runner.reduce_history` judges a batch at once)."""
    f = np.asarray(force_rest, float)
    return np.isfinite(f) & (f < 0.0)


def compressive_rest_state(force_rest: float, what: str = "the cell") -> list[ResultWarning]:
    """A warning when the rest state's force per wale is compressive (< 0).

    The rest state is Table 4's initial state at C = C0, W = W0 (eq 6 with the contact force R >= 0,
    :func:`knitsim.cell.domain.rest_state_problem`); its force F is what the grips must apply to hold the
    loop there.  F < 0 means they push: the knit as described is not free at C0, W0 and springs back when
    released.  Its stored energy comes back in the first unloading that goes slack, so loops from rest are
    not judged (:func:`energy_creating_loops`)."""
    f = float(force_rest)
    if not is_compressive(f):
        return []
    return [ResultWarning(
        "rest_state_compressive",
        f"{what}: the rest state carries a compressive force per wale (F = {f:.3g} N at C0, W0): the grips must "
        f"push to hold the loop there, so the knit as described is not free at rest and springs back when "
        f"released; check W0 and C0 against the relaxed knit (a smaller C0 or W0 gives F >= 0). Loops from rest "
        f"are not checked for energy balance (they release the energy stored at rest)")]


#: a cycle peak below this fraction of the previous cycle's peak is flagged: it lost (nearly) all its
#: load (a tenth: well below the 20-30 % drops of a knit's shakedown in a cyclic test, e.g. 5 N -> 4 N in
#: Dusserre 2015 Fig. 10)
ZERO_CYCLE_FRACTION = 0.1


#: a second or later reload peaking below this share of the cycle before it (at the same largest strain) is
#: flagged (reload_loss_continues): a measured knit's third cycle peaks close to its second (Dusserre 2015
#: Fig. 10), a loss of a few per cent; a tenth is well above that and below the model's fifths per cycle
SHAKEDOWN_RATIO = 0.9
#: a later loading carrying less than this share of the earlier force at the earlier maximum strain is
#: flagged (reload_below_earlier_loading): half, well below a measured knit's 70-90 % (5 N -> 4 N in
#: Dusserre 2015 Fig. 10), above the tenth that zero_force_cycle flags
RELOAD_SHARE_MIN = 0.5
#: a cycle that reaches a new maximum strain and peaks below this share of an earlier peak is flagged
#: (reload_below_earlier_loading): the envelope of a knit's cycles rises with the strain; a tenth of slack
#: for the noise of a peak read at a row
ENVELOPE_SHARE_MIN = 0.9

#: a later loading carrying more than this multiple of the first loading's force at the same strain (below the
#: earlier maximum strain) is flagged (reload_above_first_loading): a frictional knit reloads at or below its
#: first loading; a quarter of slack for the noise of a curve read at rows and interpolated between them
RELOAD_ABOVE_FACTOR = 1.25
#: ... and only where the excess is more than this share of the largest earlier peak (a reload near zero force,
#: e.g. from a slack start, is not judged by its ratio alone)
RELOAD_ABOVE_FLOOR = 0.02


@dataclass(frozen=True)
class ResultWarning:
    """A warning of a result: a stable ``code`` and a one-line ``message``."""

    code: str
    message: str
    #: the cycle a cycle check judged (None for the others): lets a later check leave a flagged cycle alone
    cycle: int | None = field(default=None, compare=False)

    def as_dict(self) -> dict:
        """``{"code": ..., "message": ...}``."""
        return {"code": self.code, "message": self.message}


def zero_force_cycles(peaks, unit: str = "N per wale", fraction: float = ZERO_CYCLE_FRACTION) -> list[ResultWarning]:
    """Warnings for cycles whose peak falls below ``fraction`` of the largest peak of the cycles before it.

    Against the largest earlier peak, not the previous cycle's: a knit that went slack carries (almost) no
    force in every later cycle, and cycle 3 at 8 % of cycle 1 is as empty as cycle 2 was (compared with
    cycle 2 alone it passed unflagged).

    Parameters
    ----------
    peaks : sequence of (cycle, peak)
        Cycle numbers and peak forces, in order.
    unit : str
        Unit of the peaks, for the message.
    fraction : float
        Share of the largest earlier peak below which a cycle carries no force.
    """
    return [_zero_force_warning(found, unit) for found in _empty_cycles(peaks, fraction)]


def _zero_force_warning(found, unit: str, slack=None, strain_name: str = "strain") -> ResultWarning:
    """The ``zero_force_cycle`` warning of ``found`` (:func:`_empty_cycles`).  ``slack``: (the cycle's highest
    strain, the residual strain the cycles before it left, the cycle that left it), where the first is at or below
    the second (:func:`_slack_reload`): the program asks for less than the slack knit's length, a plainer cause
    than the reload pocket, said instead."""
    c1, p1, c0, p0 = found
    if slack is not None:
        top, res, ck = slack
        why = (f"its highest {strain_name}, {top:.4g}, is at or below the residual {strain_name} {res:.4g} that "
               f"cycle {ck}'s unloading left: the program asks for less than the slack knit's length, so the knit "
               f"stays slack; load past {res:.4g} to load it again")
    else:
        why = ("the knit takes (almost) no load again up to the upper strain, after an unloading that left it slack "
               "or a force that decays from cycle to cycle (each unloading leaving it longer) (README, 'the reload "
               "pocket')")
    return ResultWarning("zero_force_cycle", cycle=int(c1), message=(
        f"cycle {c1} peaks at {p1:.3g} {unit}, {p1 / p0:.1%} of cycle {c0} ({p0:.3g} {unit}): {why}"))


def _slack_reload(c1: int, strain, cycle, residuals):
    """(cycle ``c1``'s highest strain, the slack length, the cycle that left it) where that strain is at or
    below the slack length: the residual strain of the last cycle before ``c1`` whose unloading reached zero
    force (``residuals``: cycle -> residual strain, None or NaN where it did not); else None."""
    if not residuals:
        return None
    left = [(int(k), float(r)) for k, r in residuals.items()
            if int(k) < int(c1) and r is not None and np.isfinite(r)]
    s = np.asarray(strain, float)[np.asarray(cycle) == c1]
    s = s[np.isfinite(s)]
    if not left or not len(s):
        return None
    ck, res = max(left)
    top = float(s.max())
    return (top, res, ck) if top <= res else None


def _empty_cycles(peaks, fraction: float = ZERO_CYCLE_FRACTION):
    """(cycle, peak, earlier cycle, its peak) of each cycle peaking below ``fraction`` of the largest earlier peak."""
    best = None                                   # (cycle, peak) of the largest finite peak so far
    for c1, p1 in peaks:
        if p1 is None or not np.isfinite(p1):
            continue
        if best is not None and best[1] > 0 and p1 < fraction * best[1]:
            yield c1, p1, best[0], best[1]
        if best is None or p1 > best[1]:
            best = (c1, p1)


def cycle_warnings(peaks, strain, force, cycle, direction, unit: str = "N per wale",
                   strain_name: str = "strain", residuals: dict | None = None) -> list[ResultWarning]:
    """The warnings on a program's cycles: :func:`unloading_only_cycles`, :func:`zero_force_cycles`, then, for
    the cycles that carry load, :func:`reloads_below_earlier_loading` and :func:`reloads_above_first_loading`.

    Parameters
    ----------
    peaks : sequence of (cycle, peak)
        Cycle numbers and peak forces, in order.
    strain, force, cycle, direction : array-like
        The recorded rows (the checks' own parameters).
    unit, strain_name : str
        For the messages.
    residuals : dict, optional
        Cycle -> its residual strain (None where its unloading did not reach zero force), as the summary
        located it: a cycle that carries no force because it does not load past the slack length an earlier
        cycle left is said to be one (:func:`_slack_reload`), not pointed to the reload pocket.
    """
    return (unloading_only_cycles(strain, cycle, direction, strain_name=strain_name)
            + load_cycle_warnings(peaks, strain, force, cycle, direction, unit=unit, strain_name=strain_name,
                                  residuals=residuals))


def load_cycle_warnings(peaks, strain, force, cycle, direction, unit: str = "N per wale",
                        strain_name: str = "strain", residuals: dict | None = None) -> list[ResultWarning]:
    """:func:`cycle_warnings` but :func:`unloading_only_cycles` (which a sweep's flags do not carry), in its order."""
    return load_cycle_warnings_of([peaks], strain, np.asarray(force, float)[:, None], cycle, direction, unit,
                                  strain_name, residuals=None if residuals is None else [residuals])[0]


def load_cycle_warnings_of(peaks, strain, force, cycle, direction, unit: str = "N per wale",
                           strain_name: str = "strain", residuals: list | None = None) -> list[list[ResultWarning]]:
    """:func:`load_cycle_warnings` of the columns of ``force`` [n, m] (cells of a batch on the same rows; ``peaks``
    and ``residuals``: one per column) at once: a list of warnings per column."""
    empty = [list(_empty_cycles(p)) for p in peaks]
    skips = [[int(c) for c, _, _, _ in e] for e in empty]
    rows = (strain, force, cycle, direction)
    below = reloads_below_earlier_loading_of(*rows, unit=unit, strain_name=strain_name, skips=skips)
    above = reloads_above_first_loading_of(*rows, unit=unit, strain_name=strain_name, skips=skips)
    tops = loading_tops(strain, cycle, direction)
    res = residuals or [None] * len(peaks)
    return [[_zero_force_warning(found, unit, _slack_reload(found[0], strain, cycle, res[c]), strain_name)
             for found in empty[c]]
            + below[c]
            + reloads_without_shakedown(peaks[c], strain, cycle, direction, unit=unit, strain_name=strain_name,
                                        flagged=set(skips[c]) | {w.cycle for w in below[c]}, tops=tops)
            + above[c] for c in range(len(peaks))]


def loading_tops(strain, cycle, direction) -> dict:
    """Cycle -> the largest strain its loading rows reach (cycles that do not load left out)."""
    s, c, d = np.asarray(strain, float), np.asarray(cycle), np.asarray(direction)
    top = {}
    for k in np.unique(c):
        load = (c == k) & (d > 0) & np.isfinite(s)
        if np.any(load):
            top[int(k)] = float(s[load].max())
    return top


def reloads_without_shakedown(peaks, strain, cycle, direction, unit: str = "N per wale",
                              strain_name: str = "strain", flagged=(),
                              ratio: float = SHAKEDOWN_RATIO, tops: dict | None = None) -> list[ResultWarning]:
    """A warning where cycles that load to the same strain keep losing peak force after their first reload.

    A measured knit settles: its second cycle peaks lower than its first, its third close to its second
    (Dusserre 2015 Fig. 10: 5 N, 4 N, "cycle 3 close to cycle 2").  Table 4's sliding stage keeps the
    contact's normal force Rn at its value where sliding began, and a reload that starts sliding at a lower
    Rn peaks lower, unloads to a lower state and starts the next reload lower again: a loss that goes on
    from cycle to cycle (a blind probe: m 0.1, cycles 0.27 <-> 0.3 peaking at 0.095, 0.076, 0.062 N per
    wale, each reload losing a fifth, with no warning: every peak above the half that
    ``reload_below_earlier_loading`` flags).  Flagged: a second or later reload of a run of cycles
    reaching the same largest strain that peaks below ``ratio`` of the cycle before it, where at least one
    cycle of the run is flagged by no other check.  One warning per run.

    Parameters
    ----------
    peaks : sequence of (cycle, peak)
        Cycle numbers and peak forces, in order.
    strain, cycle, direction : array-like
        The recorded rows (imposed or grip strain, cycle number, +1 loading / -1 unloading).
    unit, strain_name : str
        For the message.
    flagged : iterable of int
        Cycles other checks flagged (zero_force_cycle, reload_below_earlier_loading).
    ratio : float
        A later reload's peak over the previous cycle's below which the loss goes on.
    tops : dict, optional
        :func:`loading_tops` of the rows, where known (the cells of a batch on the same rows share it).
    """
    flagged = set(int(k) for k in flagged)
    top = loading_tops(strain, cycle, direction) if tops is None else tops
    runs, run = [], []
    for k, p in peaks:
        k = int(k)
        if p is None or not np.isfinite(p) or k not in top:
            runs.append(run)
            run = []
            continue
        if run and abs(top[k] - top[run[-1][0]]) > 1e-9 * max(1.0, abs(top[k])):
            runs.append(run)
            run = []
        run.append((k, float(p)))
    runs.append(run)
    out = []
    for run in runs:
        if len(run) < 3 or all(k in flagged for k, _ in run[1:]):
            continue
        lossy = [(k, p / q) for (k, p), (_, q) in zip(run[2:], run[1:-1]) if q > 0 and p < ratio * q]
        if not lossy:
            continue
        k, r = lossy[0]
        shown = ", ".join(f"{p:.3g}" for _, p in run)
        out.append(ResultWarning(
            "reload_loss_continues", cycle=k, message=(
                f"cycles {run[0][0]}-{run[-1][0]} load to {strain_name} {top[run[0][0]]:.4g} and peak at {shown} "
                f"{unit}: cycle {k} still loses {1 - r:.0%} of the cycle before it, and the loss does not settle "
                f"as a measured knit's does (Dusserre 2015 Fig. 10: 5 N, then 4 N, cycle 3 close to cycle 2): "
                f"Table 4's sliding stage keeps the contact's normal force Rn at its value where sliding began, "
                f"and each reload begins sliding at a lower one, so the model's later cycles carry less and less "
                f"(README, 'the reload pocket')")))
    return out


#: a loading beyond the largest strain reached before it that carries less than this share of a monotonic pull
#: of the same knit at the same strain is flagged (reload_below_first_loading): a frictional assembly's reload
#: rejoins its first loading past the earlier maximum (Masing); a tenth for a measured knit's scatter
VIRGIN_SHARE_MIN = 0.9


def needs_first_loading_reference(strain, direction) -> bool:
    """Whether a program loads beyond its earlier maximum after an unloading (where
    :func:`reloads_below_first_loading` needs a monotonic pull of the same knit to compare with)."""
    s, d = np.asarray(strain, float), np.asarray(direction)
    top, unloaded = 0.0, False
    for v, k in zip(s, d):
        if k < 0:
            unloaded = True
        elif unloaded and v > top + 1e-12:
            return True
        top = max(top, float(v))
    return False


def reloads_below_first_loading(strain, force, cycle, direction, ref_strain, ref_force, unit: str = "N per wale",
                                strain_name: str = "strain", flagged=(),
                                share: float = VIRGIN_SHARE_MIN) -> list[ResultWarning]:
    """A warning where, after an unloading, the loading beyond the largest strain reached before it stays below
    ``share`` of a monotonic pull of the same knit at the same strain (``ref_strain``, ``ref_force``: its
    rows; the first loading's continuation).

    Friction at the crossing only resists the slip: a frictional assembly reloaded past its earlier maximum
    strain rejoins its first loading (Masing's rule; a measured knit's reload does).  Table 4's sliding stage
    keeps the contact's normal force (or T) at its value where sliding began, and a reload from a small
    unloading starts sliding lower, parallel to the first loading, for good: a blind probe's waypoints 0.3,
    0.29, 0.5 (Hong's constant-T unloading) ended at 0.122 N per wale at 0.5, a monotonic pull at 0.149 N,
    with no warning; ten reversals of 0.001 left 0.084 N against 0.141 N.  One warning, at the largest
    shortfall, naming the unloading before it; cycles in ``flagged`` (warned already) are left out."""
    s, f = np.asarray(strain, float), np.asarray(force, float)
    c, d = np.asarray(cycle), np.asarray(direction)
    rs, rf = np.asarray(ref_strain, float), np.asarray(ref_force, float)
    ok = np.isfinite(rs) & np.isfinite(rf)
    rs, rf = rs[ok], rf[ok]
    if len(rs) < 2:
        return []
    flagged = set(int(k) for k in flagged)
    if not len(s):
        return []
    # (by rows at once: a sweep judges every cell; the loop over rows took 0.5 ms a cell)
    # the largest finite strain before each row (0 before any), and whether an unloading came before it
    reached = np.concatenate([[-np.inf], np.maximum.accumulate(np.where(np.isfinite(s), s, -np.inf))[:-1]])
    top = np.where(reached > 0.0, reached, 0.0)
    down = d < 0
    unloaded = np.concatenate([[False], np.logical_or.accumulate(down)[:-1]])
    # a loading row past the earlier maximum, after an unloading, within the pull's strains, in a cycle not flagged
    with np.errstate(invalid="ignore"):
        judged = (~down & unloaded & (s > top + 1e-12) & (s <= rs[-1]) & np.isfinite(f)
                  & ~np.isin(c, list(flagged)))
    rows = np.flatnonzero(judged)
    if not len(rows):
        return []
    ref_at = np.interp(s[rows], rs, rf)
    with np.errstate(invalid="ignore", divide="ignore"):
        low_rows = (ref_at > 0) & (f[rows] < share * ref_at)
    if not low_rows.any():
        return []
    cand = np.flatnonzero(low_rows)
    k = cand[np.argmin(f[rows[cand]] / ref_at[cand])]     # the largest shortfall, the first of equal ones
    i, ref = int(rows[k]), float(ref_at[k])
    r, before = f[i] / ref, float(top[i])
    # the unloading before it: from the row before its first unloading row (0 at the start) to that row
    starts = np.flatnonzero(down & (~unloaded | np.concatenate([[False], d[:-1] > 0])))
    u = int(starts[starts < i][-1])
    peak, low = (float(s[u - 1]) if u > 0 else 0.0, float(s[u]))
    return [ResultWarning("reload_below_first_loading", cycle=int(c[i]), message=(
        f"past the earlier maximum ({strain_name} {before:.4g}), the loading after the unloading from {peak:.4g} "
        f"to {low:.4g} carries {f[i]:.3g} {unit} at {strain_name} {s[i]:.4g}, {r:.0%} of the {ref:.3g} {unit} of a "
        f"monotonic pull of the same knit there: a frictional assembly's reload rejoins its first loading past "
        f"the earlier maximum (Masing's rule; a measured knit's does); Table 4's sliding stage keeps the "
        f"contact's normal force (or T) at its value where sliding began, and this reload began lower, so every "
        f"later force stays low (README, 'Reloads below the first loading')"))]


def unloading_only_cycles(strain, cycle, direction, strain_name: str = "strain") -> list[ResultWarning]:
    """A warning for each cycle of the recorded rows that never loads (a program that starts by unloading
    from rest: its first "cycle" only unloads).  Its figures are not a loop's: its peak is where it starts
    (the rest state), its energy the unloading's work (:func:`cycle_work`'s ``unloading_work``), no
    hysteresis.  A blind probe found such a cycle reported with the rest force as its peak and a negative
    energy, and no remark.

    Parameters
    ----------
    strain, cycle, direction : array-like, shape [n]
        The recorded rows' imposed strain, cycle and direction (+1 loading, -1 unloading).
    strain_name : str
        For the message.
    """
    s, c, d = np.asarray(strain, float), np.asarray(cycle), np.asarray(direction)
    out = []
    for k in np.unique(c):
        rows = np.nonzero(c == k)[0]
        if len(rows) and np.all(d[rows] < 0):
            out.append(ResultWarning("cycle_without_loading", (
                f"cycle {int(k)} only unloads ({strain_name} down to {float(s[rows[-1]]):.4g}; the program starts "
                "by unloading): its peak is its start, not a loaded state, and its energy the unloading's work "
                "(energy_kind unloading_work), not a hysteresis")))
    return out


def cut_by_force_cap(strain: np.ndarray, direction: np.ndarray, cycle: np.ndarray, stop_row: int,
                     cap_N: float, unit: str = "N per wale") -> list[ResultWarning]:
    """A warning when the force cap stopped a cell before an unloading of its program was run.

    The cap is a stop, not a failure (a monotonic pull to the cap ends there by design), but a cyclic
    program cut by it has unloadings and later cycles that were never run: its summary would
    otherwise list only the cycles reached, which reads like a complete result.

    Parameters
    ----------
    strain, direction, cycle : ndarray, shape [n]
        The program's imposed strain, direction (+1 / -1) and cycle of each increment.
    stop_row : int
        The increment at which the cell stopped at the cap.
    cap_N : float
        The cap.
    unit : str
        Unit of the cap, for the message.
    """
    direction, cycle = np.asarray(direction), np.asarray(cycle)
    later = np.nonzero(direction[stop_row + 1:] < 0)[0]
    if stop_row >= len(direction) - 1 or not len(later):
        return []
    c_stop, c_last = int(cycle[stop_row]), int(cycle.max())
    rest = (f"the rest of cycle {c_stop}" + (f" and cycles {c_stop + 1}-{c_last}" if c_last > c_stop + 1 else
                                             f" and cycle {c_last}" if c_last > c_stop else ""))
    return [ResultWarning(
        "program_cut_by_force_cap",
        f"stopped at the force cap ({cap_N:g} {unit}) at strain {float(strain[stop_row]):.4g} in cycle {c_stop} "
        f"of {c_last}: {rest} {'were' if c_last > c_stop else 'was'} not run; raise force_cap_N to run "
        f"{'them' if c_last > c_stop else 'it'}")]


#: a cell's force per wale within this fraction of its force_cap_N is at the cap: a column whose cells would
#: cross the cap does not converge and keeps its last committed state, one trial step below the cap (0.25 %
#: below it in a 3 x 4 E-glass patch pulled to grip strain 1.2 with force_cap_N = 10: 9.975 N per wale); the
#: coupling stops such a column there, its cells status force_cap (knitsim.patch.coupling.PatchSolver.step)
FORCE_CAP_RTOL = 0.01


def held_at_force_cap(force: np.ndarray, status: np.ndarray, cap_N, column_not_ok: np.ndarray | None = None,
                      rtol: float = FORCE_CAP_RTOL) -> np.ndarray:
    """Where a cell's force is its force cap, not the knit's response.

    Parameters
    ----------
    force, status : ndarray, shape [n, k]
        Force per wale [N] and status code (:data:`knitsim.cell.history.STATUS_NAMES`) of k cells.
    cap_N : float or ndarray, shape [k], or None
        Their ``force_cap_N`` (None: unknown, only the status counts).
    column_not_ok : ndarray of bool, shape [n, k], optional
        Where the column holding the cell did not converge or stopped.
    rtol : float
        At the cap: ``force >= (1 - rtol) cap``.

    Returns
    -------
    ndarray of bool, shape [n, k]
        True where the cell stopped at the cap (status force_cap) or is held at it: within ``rtol`` of it
        while its column did not converge or stopped, or over two or more increments in a row (a plateau;
        one increment near the cap that a converged column passes through is a response).
    """
    from ..cell.history import STATUS_FORCE_CAP

    status = np.asarray(status)
    out = status == STATUS_FORCE_CAP
    if cap_N is None:
        return out
    F = np.asarray(force, float)
    cap = np.broadcast_to(np.asarray(cap_N, float), F.shape[-1:])
    with np.errstate(invalid="ignore"):
        near = np.isfinite(F) & (F >= (1.0 - rtol) * cap)
    held = np.zeros_like(near)
    held[1:] |= near[:-1]
    held[:-1] |= near[1:]
    if column_not_ok is not None:
        held |= np.asarray(column_not_ok, bool)
    return out | (near & held)


def force_cap_reached(grip_strain: np.ndarray, at_cap: np.ndarray, cap_N, cells: int, cells_at_cap: int,
                      cells_stopped: int, columns: int, columns_at_cap: int, peak: float | None = None,
                      what: str = "cell", column: str = "column", unit: str = "N per wale",
                      remedy: str = "", cap_text: str | None = None) -> list[ResultWarning]:
    """A warning when the force of a patch is its cells' force cap from some grip strain on.

    The cap stops a cell (status ``force_cap``), or holds a column that cannot pass it (not converged, its
    force one trial step below the cap): past that grip strain the curve is a plateau at the cap, and a
    peak there is the cap, not the knit's strength.

    Parameters
    ----------
    grip_strain : ndarray, shape [n]
    at_cap : ndarray of bool, shape [n]
        Increments where some cell is at its cap (:func:`held_at_force_cap`).
    cap_N : float, sequence of float, or None
        The caps of the cells at the cap (None: not known).
    cells, cells_at_cap, cells_stopped : int
        Cells of the patch, those at the cap at some increment, those of them stopped (status force_cap).
    columns, columns_at_cap : int
        Columns, and those holding a cell at the cap.
    peak : float, optional
        The largest force in ``unit`` (said where it is the cap).
    what, column, unit : str
        What a cell and a column are called in the message (``cell`` / ``block``, ``column`` / ``strip``)
        and the unit of the forces.
    remedy : str
        Appended to the message (another way out, e.g. a smaller pretension).
    cap_text : str, optional
        The cap as the message says it, in place of ``cap_N`` in ``unit`` (a specimen's cap per wale of its
        strip where a capped block's wales are not its strip's mean).
    """
    at = np.asarray(at_cap, bool)
    if not at.any():
        return []
    rows = np.nonzero(at)[0]
    e = np.asarray(grip_strain, float)
    e0 = float(e[rows[0]])
    if cap_N is None:
        cap = "force_cap_N"
    else:
        caps = np.unique(np.asarray(cap_N, float).ravel())
        cap = f"{caps[0]:g} {unit}" if len(caps) == 1 else f"{caps.min():g}-{caps.max():g} {unit}"
    cap = cap if cap_text is None else cap_text
    how = []
    if cells_stopped:
        how.append(f"{cells_stopped} stopped at it, status force_cap")
    if cells_at_cap - cells_stopped > 0:
        how.append(f"{cells_at_cap - cells_stopped} held within {FORCE_CAP_RTOL:.0%} of it, their column unable "
                   "to pass it")
    peak_txt = f"; the peak {peak:.4g} {unit} is the cap, not the knit's strength" if peak is not None else ""
    return [ResultWarning(
        "force_cap_reached",
        f"from grip strain {e0:.4g} the force is the force cap ({cap}), not the knit's response: {cells_at_cap} "
        f"of {cells} {what}(s) in {columns_at_cap} of {columns} {column}(s) reached it ({', '.join(how)}), "
        f"in {len(rows)} of {len(e)} increments{peak_txt}; raise rules.force_cap_N, or lower the program's "
        f"largest grip strain below {e0:.4g} (load.target_strain / load.upper_strain){remedy}")]


def calibration_warnings(flagged) -> list[dict]:
    """The warning a result carries where its scene's values come from a calibration flagged as not one to use
    (``flagged``: :func:`knitsim.material_library.flagged_materials`'s ``(what, flags)``): a blind probe ran
    the bundled calibration's scenes and library, NOT A CALIBRATION YOU CAN USE, and read "completed the load
    program" with nothing about it in the console or summary.json."""
    out = []
    for what, flags in flagged:
        shown = "; ".join(flags[:2]) + (f"; and {len(flags) - 2} more" if len(flags) > 2 else "")
        out.append({"code": "from_unusable_calibration", "cell": "all", "message": (
            f"{what} {'come' if ' and ' in what else 'comes'} from a calibration that is NOT ONE YOU CAN USE ({len(flags)} flag(s): {shown}): these "
            "results are that calibration's, not a yarn's you can rely on")})
    return out


def inert_effect_warnings(effects, labels, prefixed: bool = True) -> list[dict]:
    """A warning per effect switched on at the strength where it changes nothing (:meth:`EffectSet.inert`),
    naming the cells (``labels``, one per EffectSet of ``effects``; ``prefixed``: a warning of one cell is
    printed after its label, which the message then leaves out): a blind probe's README example
    ``--set 'effects.on=["yarn_compaction"]'`` ran bit for bit as without it (compaction_k defaults to 0).
    And one per effect that is off with a parameter set away from its default (``--set effects.bend_h=0.5``
    without bending_hysteresis on ran bit for bit as without it, a blind probe): the kernels read an effect's
    parameters only where it is on (a calibration writes every parameter, the off effects' at their defaults:
    not warned)."""
    from ..cell.effects import EFFECT_PARAMETERS, NO_EFFECTS, NEUTRAL_STRENGTH
    cells: dict[str, list] = {}
    unused: dict[str, list] = {}
    for eff, label in zip(effects, labels):
        for name in eff.inert():
            cells.setdefault(name, []).append(label)
        for name, params in EFFECT_PARAMETERS.items():
            set_ = [c for c in params if getattr(eff, c) != getattr(NO_EFFECTS, c)]
            if name not in eff.on and set_:
                unused.setdefault(name, []).append((label, set_[0], getattr(eff, set_[0])))
    out = []
    for name, where in unused.items():
        _, key, value = where[0]
        shown = ", ".join(str(w[0]) for w in where[:5]) + (f" and {len(where) - 5} more" if len(where) > 5 else "")
        one = prefixed and len(where) == 1
        out.append({"code": "effect_parameter_unused", "cell": where[0][0] if one else "all",
                    "message": f"effects.{key} = {value:g} is a parameter of the effect {name}, which is off "
                               f"(effects.on){'' if one else f' ({shown})'}: it changes nothing; switch the effect "
                               "on, or leave the parameter out"})
    for name, where in cells.items():
        key, value = NEUTRAL_STRENGTH[name]
        shown = ", ".join(map(str, where[:5])) + (f" and {len(where) - 5} more" if len(where) > 5 else "")
        one = prefixed and len(where) == 1
        out.append({"code": "effect_without_strength", "cell": where[0] if one else "all",
                    "message": f"effect {name} is on at effects.{key} = {value:g}, where it changes nothing"
                               f"{'' if one else f' ({shown})'}: give effects.{key} its strength, or leave the "
                               "effect off"})
    out += _beyond_howell(effects, labels, prefixed)
    return out


def _beyond_howell(effects, labels, prefixed: bool) -> list[dict]:
    """A warning where ``normal_load_friction`` is on with ``load_n`` above Howell's bound (``knitsim.friction.capstan.
    HOWELL_N_MAX`` = 1, what ``knitsim capstan`` fits and predicts): the cell takes n up to 2 and the diagnosis
    searches 0.4-1.6, both sides of n = 1, but friction rising faster than the crossing's load is no Howell law and
    its n no capstan's (README, "The normal-load exponent n").  Before, a cell of n = 1.5 ran without a word, where
    ``capstan predict --n 1.5`` is refused."""
    from ..friction.capstan import HOWELL_N_MAX
    where = [label for eff, label in zip(effects, labels)
             if "normal_load_friction" in eff.on and eff.load_n > HOWELL_N_MAX]
    if not where:
        return []
    ns = {e.load_n for e in effects if "normal_load_friction" in e.on and e.load_n > HOWELL_N_MAX}
    top = f"= {max(ns):g}" if len(ns) == 1 else f"up to {max(ns):g}"
    shown = ", ".join(map(str, where[:5])) + (f" and {len(where) - 5} more" if len(where) > 5 else "")
    one = prefixed and len(where) == 1
    return [{"code": "normal_load_beyond_howell", "cell": where[0] if one else "all",
             "message": f"effect normal_load_friction is on at effects.load_n {top}"
                        f"{'' if one else f' ({shown})'}, above Howell's n <= {HOWELL_N_MAX:g} (eq 2: the contact area "
                        "grows as Fn^n, n from 2/3 elastic to 1 Amontons; Table 3: 0.909-0.948): the friction ratio "
                        "rises with the crossing's load, an effective exponent, not a yarn's Howell index (knitsim "
                        "capstan refuses it)"}]


#: overlaps of the heads below this share of the in-plane width are not warned of (a micrometre on a 0.6 mm yarn)
HEAD_OVERLAP_RTOL = 1e-3


#: a state whose wale spacing W is below 4 w by more than this fraction of 4 w is past Table 4's jamming limit
#: (rounding of a state held at W = 4 w, the w_4d criterion's contact, is not)
WALE_SPACING_RTOL = 1e-3


def jam_width_floor(d_jam, effects) -> np.ndarray:
    """The smallest width at which a cell can jam [mm]: its in-plane width ``d_jam``, times ``compaction_min``
    where its effect set (:class:`~knitsim.cell.effects.EffectSet`, one per cell) has yarn_compaction on."""
    eff = np.broadcast_to(np.asarray(effects, dtype=object), np.shape(d_jam))
    floor = np.array([e.compaction_min if e is not None and "yarn_compaction" in e.on else 1.0
                      for e in np.ravel(eff)], float).reshape(np.shape(d_jam))
    return np.asarray(d_jam, float) * floor


def _branch_text(direction: np.ndarray | None, rows: np.ndarray) -> str:
    """`` while loading``, `` while unloading`` or `` while loading and unloading``: the directions of ``rows``
    (``""`` without ``direction``)."""
    if direction is None:
        return ""
    dirs = frozenset(np.sign(np.asarray(direction)[rows]).astype(int).tolist())
    return {frozenset({1}): " while loading", frozenset({-1}): " while unloading"}.get(
        dirs, " while loading and unloading")


def below_jamming_width(W: np.ndarray, d_jam) -> tuple[np.ndarray, np.ndarray]:
    """Where the wale spacing ``W`` [n, k] is below 4 ``d_jam`` (scalar or one per column) by more than
    :data:`WALE_SPACING_RTOL` (:func:`wale_spacing_below_jamming`'s rule, also judged on a whole batch at once by
    :func:`knitsim.sweep.runner.reduce_history`), and the limit 4 ``d_jam`` per element."""
    W = np.asarray(W, float)
    lim = 4.0 * np.broadcast_to(np.asarray(d_jam, float), W.shape)
    with np.errstate(invalid="ignore"):
        return W < lim * (1.0 - WALE_SPACING_RTOL), lim


def wale_spacing_below_jamming(strain: np.ndarray, W: np.ndarray, d_jam, what: str = "cell",
                               direction: np.ndarray | None = None, strain_is: str = "strain",
                               note: str = "") -> list[ResultWarning]:
    """A warning when any state's wale spacing W falls below 4 w, w the in-plane width.

    W = 4 d is the model's jamming limit (Hong et al. 2002; Dusserre 2015, Table 4: J+ holds W = 4 d): across a
    wale four yarn widths lie side by side, and a narrower W makes the legs of neighbouring loops cross each
    other.  ``jamming_criterion = "w_4d"`` holds W >= 4 w; ``"head_gap"`` jams where the heads touch and then
    lets W fall on below 4 w on its jammed branch (a blind probe: the calibrated specimen's cell to W = 0.956 x
    4 w at strain 0.6, silently).  Such states are outside the model's box: warned (code
    ``wale_spacing_below_jamming``).

    Parameters
    ----------
    strain : ndarray, shape [n]
        Imposed strain of each row.
    W : ndarray, shape [n, k] (or [n])
        Wale spacing of each row's state [mm] (NaN: no state; not judged).
    d_jam : float or ndarray, shape [k]
        The cells' in-plane widths w [mm]; with yarn_compaction on, the smallest the compacted width can be
        (w x compaction_min: the effect jams at W = 4 d_eff, d_eff down to that floor; :func:`jam_width_floor`).
    what, direction, strain_is, note
        As :func:`interpenetration`.
    """
    W = np.asarray(W, float)
    if W.ndim == 1:
        W = W[:, None]
    flags, lim = below_jamming_width(W, d_jam)
    if not flags.any():
        return []
    rows = np.nonzero(flags.any(axis=1))[0]
    cols = np.nonzero(flags.any(axis=0))[0]
    ratio = float(np.nanmin(np.where(flags, W / lim, np.inf)))
    e = np.asarray(strain, float)[rows]
    branch = _branch_text(direction, rows)
    lo, hi = float(e.min()), float(e.max())
    where = (f"at {strain_is} {lo:.4g}" if lo == hi else f"from {strain_is} {float(e[0]):.4g} ({strain_is}s "
             f"{lo:.4g} to {hi:.4g})") + note
    return [ResultWarning(
        "wale_spacing_below_jamming",
        f"OUTSIDE THE MODEL: the wale spacing W falls below 4 w (w the in-plane width, compacted where "
        f"yarn_compaction is on; W = 4 w is the model's "
        f"jamming limit, Dusserre 2015 Table 4) {where}{branch}, in {len(rows)} of {W.shape[0]} increments and "
        f"{len(cols)} {what}(s), down to W = {ratio:.3g} x 4 w: the legs of neighbouring loops would pass through "
        f"each other across the wale, so these forces are not the knit's (jamming_criterion = \"head_gap\" does "
        f"not hold W >= 4 w after the heads touch; \"w_4d\" does)")]


def heads_overlap(flags: np.ndarray, gap: np.ndarray, d_jam) -> np.ndarray:
    """Where the heads overlap (:func:`interpenetration`'s rule, also judged on a whole batch at once by
    :func:`knitsim.sweep.runner.reduce_history`): ``flags`` [n, k] set (``values["interpenetrating"]``) and the
    gap ``gap`` [n, k] below the in-plane width ``d_jam`` (scalar or one per column) by more than
    :data:`HEAD_OVERLAP_RTOL` of it."""
    flags = np.asarray(flags) > 0
    # an overlap below HEAD_OVERLAP_RTOL of the width is rounding, not heads passing through each other (a blind
    # probe's warning for 2.2e-5 mm in one increment)
    with np.errstate(invalid="ignore"):
        return flags & ~(np.broadcast_to(np.asarray(d_jam, float), flags.shape) - np.asarray(gap, float)
                         <= HEAD_OVERLAP_RTOL * np.broadcast_to(np.asarray(d_jam, float), flags.shape))


def interpenetration(strain: np.ndarray, flags: np.ndarray, gap: np.ndarray, d_jam,
                     what: str = "cell", direction: np.ndarray | None = None, strain_is: str = "strain",
                     note: str = "") -> list[ResultWarning]:
    """A warning when any state's heads overlap.

    Parameters
    ----------
    strain : ndarray, shape [n]
        Imposed strain of each row.
    flags : ndarray, shape [n, k]
        1 where the row's state of a cell interpenetrates (``values["interpenetrating"]``).
    gap : ndarray, shape [n, k]
        Head gaps [mm].
    d_jam : float or ndarray, shape [k]
        The cells' in-plane widths [mm].
    what : str
        What the k columns are, for the message.
    direction : ndarray, shape [n], optional
        +1 loading, -1 unloading: the message says on which branches the heads overlap.
    strain_is : str
        What ``strain`` is, for the message: ``"strain"`` (a cell's own) or ``"grip strain"`` (a patch's rows,
        whose cells reach other strains: ``note`` can say which).
    note : str
        Appended after the strains, e.g. ``" (cell strains 0.31 to 0.69)"``.
    """
    flags = np.asarray(flags)
    if flags.ndim == 1:
        flags = flags[:, None]
        gap = np.asarray(gap)[:, None]
    flags = heads_overlap(flags, gap, d_jam)
    if not flags.any():
        return []
    rows = np.nonzero(flags.any(axis=1))[0]
    cols = np.nonzero(flags.any(axis=0))[0]
    with np.errstate(invalid="ignore"):
        depth = np.where(flags, np.broadcast_to(np.asarray(d_jam, float), flags.shape) - np.asarray(gap, float), 0.0)
    e = np.asarray(strain, float)[rows]
    branch = _branch_text(direction, rows)
    lo, hi, first = float(e.min()), float(e.max()), float(e[0])
    if lo == hi:
        where = f"at {strain_is} {lo:.4g}"
    elif first == lo:
        where = f"at {strain_is}s {lo:.4g} to {hi:.4g}"
    else:   # first met on an unloading, below which it later overlaps too
        where = f"first at {strain_is} {first:.4g}, at {strain_is}s {lo:.4g} to {hi:.4g} in all"
    where += note
    return [ResultWarning(
        "heads_interpenetrate",
        f"the heads of neighbouring loops overlap (centreline gap below the in-plane width) {where}{branch}, in "
        f"{len(rows)} "
        f"of {flags.shape[0]} increments and {len(cols)} {what}(s), by up to {float(np.nanmax(depth)):.3g} mm: "
        f"the jamming criterion lets the heads pass through each other (jamming_criterion = \"head_gap\" "
        f"stops them at contact)")]


def reloads_below_earlier_loading(strain, force, cycle, direction, unit: str = "N per wale",
                                  strain_name: str = "strain", skip=(),
                                  share: float = RELOAD_SHARE_MIN) -> list[ResultWarning]:
    """Warnings for later cycles whose loading carries less than ``share`` of the earlier force at the largest
    strain of the cycles before them (module docstring, ``reload_below_earlier_loading``).

    Also where a cycle reaches a new maximum strain but peaks below :data:`ENVELOPE_SHARE_MIN` of an earlier
    peak: the envelope falls as the knit is stretched further (cycles to 0.2, 0.3, 0.45, 0.6 peaking at
    0.10, 0.085, 0.074, 0.048 N per wale).  One warning per cycle.

    Parameters
    ----------
    strain, force, cycle, direction : array-like
        The recorded rows (the imposed or grip strain, the force, the cycle number, +1 loading / -1
        unloading); rows whose force is not finite (not run, or after a stop) are left out.
    unit, strain_name : str
        For the message.
    skip : iterable of int
        Cycles not judged (flagged already: zero_force_cycle).
    share : float
        Share of the earlier force below which a reload is flagged.
    """
    return reloads_below_earlier_loading_of(strain, np.asarray(force, float)[:, None], cycle, direction, unit,
                                            strain_name, [skip], share)[0]


def _same_rows(ok: np.ndarray):
    """(columns, rows) of the columns of ``ok`` [n, m] (bool) that hold the same rows: a batch's cells judged at
    once where the same rows of theirs count."""
    n, m = ok.shape
    if not m:
        return []
    if ok.all():
        return [(np.arange(m), np.ones(n, bool))]
    packed = np.ascontiguousarray(np.packbits(ok, axis=0).T)
    _, first, inverse = np.unique(packed.view(np.dtype((np.void, packed.shape[1]))).ravel(), return_index=True,
                                  return_inverse=True)
    inverse = np.asarray(inverse).ravel()
    return [(np.flatnonzero(inverse == u), ok[:, first[u]]) for u in range(len(first))]


def reloads_below_earlier_loading_of(strain, force, cycle, direction, unit: str = "N per wale",
                                     strain_name: str = "strain", skips=None,
                                     share: float = RELOAD_SHARE_MIN) -> list[list[ResultWarning]]:
    """:func:`reloads_below_earlier_loading` of the columns of ``force`` [n, m] (cells of a batch on the same rows;
    ``skips``: one ``skip`` per column) at once: a list of warnings per column."""
    s = np.asarray(strain, float)
    F = np.asarray(force, float)
    cyc = np.asarray(cycle)
    dirn = np.asarray(direction)
    m = F.shape[1]
    skips = [set(int(k) for k in sk) for sk in (skips if skips is not None else [()] * m)]
    out = [[] for _ in range(m)]
    for cols, ok in _same_rows(np.isfinite(F) & np.isfinite(s)[:, None]):
        f = F[:, cols]
        for k in np.unique(cyc[ok]):
            earlier = np.nonzero(ok & (cyc < k))[0]
            judged = np.array([int(k) not in skips[c] for c in cols])
            if not len(earlier) or not judged.any():
                continue
            i = earlier[np.argmax(s[earlier])]          # where the strain first reached the earlier maximum
            s0, f0 = s[i], f[i]
            load = np.nonzero(ok & (cyc == k) & (dirn > 0))[0]
            judged &= f0 > 0
            if not judged.any() or not len(load) or s[load].max() < s0 - 1e-12:
                continue
            j = load[np.nonzero(s[load] >= s0 - 1e-12)[0][0]]
            fk = f[j]
            if j > 0 and ok[j - 1] and s[j] > s[j - 1] and s[j - 1] < s0:
                fk = f[j - 1] + (f[j] - f[j - 1]) * (s0 - s[j - 1]) / (s[j] - s[j - 1])
            # a new maximum strain that peaks below an earlier peak: the envelope falls as the knit is stretched
            # further (each reload starts sliding at a lower Rn), which the share at the earlier maximum may pass
            rows_k = np.nonzero(ok & (cyc == k))[0]
            g_all = np.arange(len(cols))
            jk = rows_k[np.argmax(f[rows_k], axis=0)]
            ip = earlier[np.argmax(f[earlier], axis=0)]
            low = judged & (fk < share * f0)
            envelope = judged & ~low & (s[load].max() > s0 + 1e-9) & (f[jk, g_all] < ENVELOPE_SHARE_MIN * f[ip, g_all])
            for g in np.flatnonzero(low | envelope):
                c, fk_g, f0_g = int(cols[g]), fk[g], f0[g]
                if low[g]:
                    out[c].append(ResultWarning(
                        "reload_below_earlier_loading", cycle=int(k), message=(
                            f"cycle {int(k)} carries {fk_g:.3g} {unit} at {strain_name} {s0:.4g}, {fk_g / f0_g:.0%} of "
                            f"the {f0_g:.3g} {unit} the knit carried there in cycle {int(cyc[i])} (where it first "
                            f"reached that strain): Table 4's sliding stage keeps the contact's normal force Rn at its "
                            f"value where sliding began, and this reload began sliding at a lower one, so its branch "
                            f"stays below the earlier loading there and beyond (a measured knit reloads to most of its "
                            f"earlier force: 5 N, then 4 N in Dusserre 2015 Fig. 10)")))
                else:
                    fj, fi, ipg = f[jk[g], g], f[ip[g], g], ip[g]
                    out[c].append(ResultWarning(
                        "reload_below_earlier_loading", cycle=int(k), message=(
                            f"cycle {int(k)} stretches the knit further than before ({strain_name} "
                            f"{s[load].max():.4g}) but peaks at {fj:.3g} {unit}, {fj / fi:.0%} of the {fi:.3g} {unit} "
                            f"of cycle {int(cyc[ipg])} at {strain_name} {s[ipg]:.4g}: the knit's envelope falls as it "
                            f"is stretched further (Table 4's sliding stage keeps the contact's normal force Rn at its "
                            f"value where sliding began, and each reload begins sliding at a lower one); a measured "
                            f"knit's envelope rises with the strain")))
    return out


def reloads_above_first_loading(strain, force, cycle, direction, unit: str = "N per wale",
                                strain_name: str = "strain", skip=(), factor: float = RELOAD_ABOVE_FACTOR,
                                floor: float = RELOAD_ABOVE_FLOOR) -> list[ResultWarning]:
    """Warnings for later cycles whose loading carries more than ``factor`` times the first loading's force at
    the same strain, below the largest strain reached before them (module docstring,
    ``reload_above_first_loading``).  One warning per cycle, at its largest excess.

    The first loading is the rows that first reached their strain (each beyond every strain before it, on
    loading); a later loading is compared with it by linear interpolation in the strain, where both exist.

    Parameters
    ----------
    strain, force, cycle, direction : array-like
        The recorded rows (the imposed or grip strain, the force, the cycle number, +1 loading / -1
        unloading); rows whose force is not finite (not run, or after a stop) are left out.
    unit, strain_name : str
        For the message.
    skip : iterable of int
        Cycles not judged (flagged already: zero_force_cycle).
    factor : float
        Multiple of the first loading's force above which a reload is flagged.
    floor : float
        Share of the largest earlier peak by which the reload must exceed the first loading too.
    """
    return reloads_above_first_loading_of(strain, np.asarray(force, float)[:, None], cycle, direction, unit,
                                          strain_name, [skip], factor, floor)[0]


def reloads_above_first_loading_of(strain, force, cycle, direction, unit: str = "N per wale",
                                   strain_name: str = "strain", skips=None, factor: float = RELOAD_ABOVE_FACTOR,
                                   floor: float = RELOAD_ABOVE_FLOOR) -> list[list[ResultWarning]]:
    """:func:`reloads_above_first_loading` of the columns of ``force`` [n, m] (cells of a batch on the same rows;
    ``skips``: one ``skip`` per column) at once: a list of warnings per column."""
    s_all = np.asarray(strain, float)
    F = np.asarray(force, float)
    m = F.shape[1]
    skips = [set(int(k) for k in sk) for sk in (skips if skips is not None else [()] * m)]
    out = [[] for _ in range(m)]
    for cols, ok_rows in _same_rows(np.isfinite(F) & np.isfinite(s_all)[:, None]):
        ok = np.flatnonzero(ok_rows)
        s, cyc, dirn = s_all[ok], np.asarray(cycle)[ok], np.asarray(direction)[ok]
        f = F[np.ix_(ok, cols)]
        # the first loading: loading rows beyond every strain before them (strictly increasing in the strain)
        reached = np.maximum.accumulate(s)
        first = (dirn > 0) & (s > np.concatenate([[-np.inf], reached[:-1]]))
        for k in np.unique(cyc):
            before = cyc < k
            virgin = np.flatnonzero(first & before)
            if len(virgin) < 2 or not before.any():
                continue
            peak = np.max(f[before], axis=0)
            load = np.flatnonzero((cyc == k) & (dirn > 0) & (s >= s[virgin[0]]) & (s <= s[virgin[-1]]))
            judged = np.array([int(k) not in skips[c] for c in cols]) & (peak > 0)
            if not judged.any() or not len(load):
                continue
            g_judged = np.flatnonzero(judged)
            f_first = np.stack([np.interp(s[load], s[virgin], f[virgin, g]) for g in g_judged], axis=1)
            f_load = f[load][:, g_judged]
            above = (f_load > factor * f_first) & (f_load - f_first > floor * peak[g_judged])
            for h in np.flatnonzero(above.any(axis=0)):
                g = g_judged[h]
                at = np.flatnonzero(above[:, h])
                j = at[np.argmax(f_load[at, h] - f_first[at, h])]
                r, fr, ff = load[j], f[load[j], g], f_first[j, h]
                c_first = int(cyc[virgin[min(np.searchsorted(s[virgin], s[r]), len(virgin) - 1)]])
                lo, hi = float(s[load][at].min()), float(s[load][at].max())
                span = f"{strain_name} {lo:.4g}" if hi == lo else f"{strain_name}s {lo:.4g} to {hi:.4g}"
                out[int(cols[g])].append(ResultWarning(
                    "reload_above_first_loading",
                    f"cycle {int(k)} reloads above the first loading: {fr:.3g} {unit} at {strain_name} {s[r]:.4g}, "
                    + (f"{fr / ff:.1f} times the " if ff > 0 else "against the ")
                    + f"{ff:.3g} {unit} the knit carried there when first loaded "
                    f"(cycle {c_first}), over {span}: friction at the crossing only resists the slip, so a knit "
                    f"reloads at or below its first loading; the cause is the model's: Table 4's loading stages hold "
                    f"a force (Rn, or T after a mirror reload) at its value where the stage began, and this reload "
                    f"began from a state of higher contact force than the first loading did (README, 'Reloads above "
                    f"the first loading')"))
    return out

