"""Baseline calibration of a cell's free parameters on measured curves.

Least squares on the force per wale at the measured rows
(:func:`scipy.optimize.least_squares`, trust region reflective, bounds).
Each residual evaluation is ONE batched launch per distinct load program
(:func:`knitsim.cell.batch.run_batch`): the k + 1 cells of the batch are the
point itself and its k forward finite-difference perturbations, so the
Jacobian comes with the residual and ``jac`` only reads the cache (least
squares asks for the Jacobian at points whose residual it has evaluated).
Curves that share their strain history share one launch.

``phi0`` is parametrised as a fraction of phimax = atan(m) (eq 10;
section 3.3.1 bounds phi0 to [-phimax, phimax]), in [-1, 1], so the bounds stay
valid while m moves.

Rows are weighted by their curve's noise (``weights``: 1 / sd per row, 0 for
a row left out): the fit minimises chi^2 = sum((w (sim - measured))^2), so
that two tests of different noise count by what each tells.  With
``offsets`` each curve also has a force offset (a load cell's zero): the
weighted mean of its residual, eliminated in closed form at every
evaluation (variable projection), counted among the parameters.

A row the simulation did not reach (an increment that did not converge: the
cell keeps its last converged state in later rows) is no model's prediction,
whatever its residual.  With ``penalise_failed`` its weighted residual counts
at least :data:`FAILED_ROW_Z` (``sqrt(z^2 + FAILED_ROW_Z^2)``, sign kept), so
that the fit moves to where the model runs through its curves: the repair of
a fit that ended at such a point (a parameter set that fails on the first
unloading after a slack cycle, whose frozen force of ~0 N matches the
measured ~0 N by chance).  It is not the default: on the way to its optimum
a fit may cross parameter sets that fail, and the penalty's cliff stops it
there (a normal-load fit stayed at chi^2 1779 instead of reaching 1193).

A free ``strain_scale`` k (:data:`knitsim.diagnosis.effects.STRAIN_SCALE`: the strain read is k times the
knit's, an extensometer's gauge length off) replays every curve at strain / k: the point and its
other neighbours share one launch per program at k, its own neighbour runs at k + h.

Standard errors: ``cov = s^2 (J^T J)^-1`` of the weighted residuals, with
``s^2 = chi^2 / (n - k)`` (1 when the weights are the true noise), mapped to
(m, phi0) by the delta method through phi0 = f atan(m).
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Sequence

import numpy as np
from scipy.optimize import least_squares

from ..cell.batch import run_batch
from ..cell.history import STATUS_FORCE_CAP, STATUS_NAMES, STATUS_OK
from ..cell.material import CellParams
from ..errors import KnitsimInputError
from .effects import BASELINE_VARIABLES, EFFECT_SPECS, STRAIN_SCALE, build_params, check_effects
from .gap import stage_keys
from .measured import MeasuredCurve, force_at_rows, program_for_curve

def _to_params(base: CellParams, free: Sequence[str], x: np.ndarray, effects: tuple, fixed: dict | None) -> CellParams:
    # build_params re-validates: a bad point is refused before any solve
    return build_params(base, effects, dict(zip(free, (float(v) for v in x))), fixed)


def _variables(free: tuple, effects: tuple) -> dict:
    known = dict(BASELINE_VARIABLES, **{STRAIN_SCALE.name: STRAIN_SCALE})
    for e in effects:
        known.update({v.name: v for v in EFFECT_SPECS[e].variables})
    for name in free:
        if name not in known:
            raise KnitsimInputError(f"free = {name!r}: expected one of {', '.join(known)}")
    return known


#: the default upper bound of d as a fraction of W0 / 4 (the loops jam at rest at W0 = 4 d)
D_MAX_OF_W0 = 0.999

#: share of a variable's range within which a fitted value counts as at its bound
AT_BOUND_SHARE = 1.0e-3


def at_bounds(names: Sequence[str], x: np.ndarray, lo: np.ndarray, hi: np.ndarray, r: np.ndarray,
              J: np.ndarray) -> dict[str, str]:
    """The fitted variables the data pushed against a bound of their search: ``{name: "lower" | "upper"}``.

    At a bound where the variable ends within :data:`AT_BOUND_SHARE` of its range from it *and* the fit's
    unconstrained Gauss-Newton step from there (``J dx = -r``, the linearised least squares at the solution)
    would take it to the bound or beyond: the data ask for more than the search allows, and the value (and
    its standard error) is the bound's, not an estimate.  A minimum inside the range near its end is an
    estimate: a blind probe's compaction_k = 0.029 1/N (range 0-200) removed 81 % of a real knit's gap and was
    reported "at its lower bound (values not estimated)" by the share alone."""
    x, lo, hi = (np.asarray(v, float) for v in (x, lo, hi))
    span = hi - lo
    step = np.linalg.lstsq(np.asarray(J, float), -np.asarray(r, float), rcond=None)[0] if len(x) else x
    out = {}
    for j, n in enumerate(names):
        # (the step must point out: a variable the data do not constrain gets none, wherever it rests)
        if x[j] <= lo[j] + AT_BOUND_SHARE * span[j] and step[j] < 0 and x[j] + step[j] <= lo[j]:
            out[n] = "lower"
        elif x[j] >= hi[j] - AT_BOUND_SHARE * span[j] and step[j] > 0 and x[j] + step[j] >= hi[j]:
            out[n] = "upper"
    return out


def default_bounds(base: CellParams, var) -> tuple[float, float]:
    """Default search bounds (low, high) of the fitted variable ``var`` for the cell ``base``.

    B and d within a factor of 2 of ``base``'s; in_plane_width from d to :data:`D_MAX_OF_W0` x W0 / 4
    (the loops jammed at rest); L, W0 and C0 within 5 %; any other variable its own ``var.bounds``.
    """
    if var.name in ("B", "d"):
        v = getattr(base, var.name)
        return 0.5 * v, 2.0 * v
    if var.name == "in_plane_width":
        # from the compact diameter to the width at which the loops would be jammed at rest
        return base.d, D_MAX_OF_W0 * base.W0 / 4.0
    if var.name in ("L", "W0", "C0"):
        # specimen-to-specimen scatter of the knit geometry: a few per cent
        v = getattr(base, var.name)
        return 0.95 * v, 1.05 * v
    return var.bounds


def _replay_programs(curves, max_increment: float):
    """Each curve's replay program and measured rows, and the groups of curves that share a program.

    Curves with the same strain history and test rate share one launch.
    """
    groups: dict[tuple, list[int]] = {}
    programs, rows = [], []
    for i, c in enumerate(curves):
        prog, r = program_for_curve(c, max_increment)
        programs.append(prog)
        rows.append(r)
        rate = () if prog.rate is None else tuple(np.round(prog.rate, 15))
        groups.setdefault((tuple(np.round(prog.strain, 15)), rate), []).append(i)
    return programs, rows, list(groups.values())


def _curve_weights(curves, weights) -> list[np.ndarray]:
    if weights is None:
        return [np.ones(len(c)) for c in curves]
    out = [np.asarray(w, float) for w in weights]
    if len(out) != len(curves) or any(len(w) != len(c) for w, c in zip(out, curves)):
        raise KnitsimInputError("weights: one array per curve, one weight per row")
    return out


#: least weighted residual of a row the simulation did not reach (module docstring)
FAILED_ROW_Z = 10.0
#: replays at strain / k kept besides the measured strain's (calibrate_baseline's cache): a fit's point and its
#: finite-difference steps
REPLAYS_KEPT = 4


def _failed_rows(history, rows: np.ndarray, cell: int) -> np.ndarray:
    """Rows whose increment (or an earlier one) did not converge: status neither ok nor force cap."""
    st = history.status[:, cell]
    rows = np.asarray(rows)
    s = np.where(rows >= 0, st[np.maximum(rows, 0)], 0)
    return (s != STATUS_OK) & (s != STATUS_FORCE_CAP)


def _penalised(z: np.ndarray, failed: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Weighted residuals ``z`` with the rows the simulation did not reach counted at least
    :data:`FAILED_ROW_Z` (rows of weight 0 stay 0)."""
    if not np.any(failed):
        return z
    z = z.copy()
    m = failed & (w > 0)
    z[m] = np.where(z[m] < 0, -1.0, 1.0) * np.sqrt(z[m] ** 2 + FAILED_ROW_Z ** 2)
    return z


def _project(e: np.ndarray, w: np.ndarray, offsets: bool) -> np.ndarray:
    """Weighted residuals ``w e`` of one curve, less their best force offset when ``offsets``."""
    if offsets:
        w2 = w * w
        tot = float(np.sum(w2))
        if tot > 0:
            e = e - float(np.sum(w2 * e)) / tot
    return w * e


def offset_of(e: np.ndarray, w: np.ndarray) -> float:
    """The force offset [N] that best fits a curve's residual ``e = sim - measured`` (weights ``w``)."""
    w2 = w * w
    tot = float(np.sum(w2))
    return -float(np.sum(w2 * e)) / tot if tot > 0 else 0.0


def rss_of_cells(curves, cells: Sequence[CellParams], max_increment: float = 0.005,
                 device: str = "cpu", weights=None, offsets: bool = False) -> np.ndarray:
    """Weighted residual sum of squares (chi^2; N^2 without weights) of each cell over the measured curves.

    All cells run in one batched launch per distinct load program (no
    Jacobian): the cheap way to compare many parameter sets, e.g. a grid of
    starts or candidate basins.  ``weights`` and ``offsets`` as
    :func:`calibrate_baseline`.

    Returns
    -------
    ndarray, shape [len(cells)]
    """
    curves = [curves] if isinstance(curves, MeasuredCurve) else list(curves)
    cells = list(cells)
    ws = _curve_weights(curves, weights)
    programs, rows, groups = _replay_programs(curves, max_increment)
    rss = np.zeros(len(cells))
    for g in groups:
        hist = run_batch(cells, programs[g[0]], device=device)
        for i in g:
            for j in range(len(cells)):
                e = _penalised(_project(force_at_rows(hist, rows[i], j)[0] - curves[i].force, ws[i], offsets),
                               _failed_rows(hist, rows[i], j), ws[i])
                rss[j] += float(e @ e)
    return rss


def calibrate_baseline(curves, base: CellParams, free: Sequence[str] = ("m", "phi0"), bounds: dict | None = None,
                       device: str = "cpu", max_increment: float = 0.005, rel_step: float = 1e-6,
                       x0: dict | None = None, max_nfev: int = 50, ftol: float = 1e-10, xtol: float = 1e-10,
                       effects: Sequence[str] = (), fixed: dict | None = None, weights=None,
                       penalise_failed: bool = False,
                       offsets: bool = False) -> dict:
    """Fit the ``free`` parameters of ``base`` (with ``effects`` on) to measured curves.

    Parameters
    ----------
    curves : MeasuredCurve or list of MeasuredCurve
    base : CellParams
        Fixed parameters, and the start point of the free ones.
    free : sequence of str
        Names of the fitted variables: ``m``, ``phi0`` (as a fraction of
        phimax, see the module docstring), ``B``, ``d``, and the variables of
        the ``effects`` (:mod:`knitsim.diagnosis.effects`); ``strain_scale``, a factor on the
        measured strain (module docstring).
    bounds : dict, optional
        ``name -> (low, high)`` in the fitted variable (phi0: fraction in [-1, 1]);
        default m in [0, 1], phi0 in [-1, 1], others 0.5x..2x their base value.
    device : str
        Warp device of the batches.
    max_increment : float
        Largest strain increment of the replay programs (:func:`program_for_curve`).
    rel_step : float
        Finite-difference step, times max(|x|, 1); taken backwards at an upper bound.
    x0 : dict, optional
        Start of the free variables (phi0 as a fraction); default from ``base``.
    max_nfev, ftol, xtol
        Passed to :func:`scipy.optimize.least_squares`.
    effects : sequence of str
        Effects switched on (:data:`knitsim.cell.effects.EFFECT_NAMES`).
    fixed : dict, optional
        Effect parameters held fixed (:func:`knitsim.diagnosis.effects.build_params`).
    weights : list of ndarray, optional
        Per curve, the weight of each row: 1 / its noise sd [1/N], 0 to leave a row out
        (default 1: the unweighted residual in N).
    offsets : bool
        Fit a force offset per curve (module docstring).
    penalise_failed : bool
        Count rows the simulation did not reach at least :data:`FAILED_ROW_Z` (module docstring).

    Returns
    -------
    dict
        ``params`` (fitted CellParams), ``values`` / ``std_errors`` (name -> float, in
        the model's units, phi0 in rad), ``phi0_fraction`` (value, std error) when fitted,
        ``fit_variables`` (the same in the fitted variables, phi0 as a fraction of
        phimax: what ``x0`` takes), ``chi2`` (the weighted RSS), ``rms_N`` and ``rss_N2`` (of the rows
        kept, offsets removed), ``n`` (rows kept), ``k`` (offsets included), ``offsets_N`` (per curve), ``covariance`` (of ``values``), ``curves``
        (per curve: strain, measured, simulated, labels, keys, status), ``nfev``,
        ``njev``, ``n_batch_calls``, ``success``, ``message``.
    """
    if isinstance(curves, MeasuredCurve):
        curves = [curves]
    curves = list(curves)
    if not curves or not all(isinstance(c, MeasuredCurve) for c in curves):
        raise KnitsimInputError("curves: expected one or more MeasuredCurve")
    free = tuple(free)
    effects = check_effects(effects, where="effects")
    known = _variables(free, effects)
    if len(set(free)) != len(free) or not free:
        raise KnitsimInputError(f"free = {free!r}: expected distinct names, at least one")
    base = base.validated(where="base")
    bounds = dict(bounds or {})
    lo, hi = np.empty(len(free)), np.empty(len(free))
    for j, name in enumerate(free):
        lo[j], hi[j] = bounds.get(name, default_bounds(base, known[name]))
    if "d" in free and "d" not in bounds:
        # the default range of d (up to 2 d) must keep the knit a knit at every W0 the fit may take: W0 >= 4 d
        # (a scene's own bound is refused otherwise, knitsim.scene.diagnosis_scene); the paper's E-glass knit
        # has W0 = 4.4 mm < 8 d = 4.64 mm, and a trial point at W0 < 4 d stopped the fit with an input error
        W0_low = lo[free.index("W0")] if "W0" in free else base.W0
        j = free.index("d")
        hi[j] = min(hi[j], D_MAX_OF_W0 * W0_low / 4.0)
    for j, name in enumerate(free):
        if not lo[j] < hi[j]:
            raise KnitsimInputError(f"bounds[{name!r}] = ({lo[j]}, {hi[j]}): expected low < high")
    start = {n: known[n].start(base) for n in free}
    start.update(x0 or {})
    x_start = np.clip(np.array([start[n] for n in free], float), lo, hi)

    replays: dict[float, tuple] = {}

    def replay(scale: float) -> tuple:
        # the programs and rows of the replay at strain / scale (curves that share a program share it at any scale).
        # Kept: the measured strain's and the last few scales' (a fit's point and its finite-difference steps);
        # each evaluation of a new k is new, so a cache of every one grew over the fit
        if scale not in replays:
            scaled = curves if scale == 1.0 else [replace(c, strain=c.strain / scale) for c in curves]
            replays[scale] = _replay_programs(scaled, max_increment)
            for old in [k for k in replays if k != 1.0][:-REPLAYS_KEPT]:
                del replays[old]
        return replays[scale]

    group_list = replay(1.0)[2]
    j_scale = free.index(STRAIN_SCALE.name) if STRAIN_SCALE.name in free else None
    ws = _curve_weights(curves, weights)
    n_rows = int(sum(np.count_nonzero(w) for w in ws))
    k = len(free)
    k_total = k + (len(curves) if offsets else 0)
    if n_rows <= k_total:
        names = ", ".join(getattr(c, "source", "curve") for c in curves)
        raise KnitsimInputError(f"{names}: {n_rows} measured rows cannot fit {k_total} parameters "
                                f"({k} of the knit{f' and a force offset per curve' if offsets else ''}); "
                                "give more rows or fewer free parameters")

    cache: dict[bytes, tuple] = {}
    counter = {"calls": 0}

    def steps(x):
        h = rel_step * np.maximum(np.abs(x), 1.0)
        return np.where(x + h > hi, -h, h)

    def evaluate(x):
        key = np.asarray(x, float).tobytes()
        if key in cache:
            return cache[key]
        h = steps(x)
        points = [x] + [x + h[j] * np.eye(k)[j] for j in range(k)]
        cells = [_to_params(base, free, p, effects, fixed) for p in points]
        # per curve and point: (history, the point's cell in it, the rows); one launch per program and strain scale
        sims = [[None] * len(points) for _ in curves]
        by_scale: dict[float, list] = {}
        for j, p in enumerate(points):
            by_scale.setdefault(1.0 if j_scale is None else float(p[j_scale]), []).append(j)
        for scale, idx in by_scale.items():
            programs, rows, _ = replay(scale)
            for g in group_list:
                counter["calls"] += 1
                hist = run_batch([cells[j] for j in idx], programs[g[0]], device=device)
                for i in g:
                    for cell, j in enumerate(idx):
                        sims[i][j] = (hist, cell, rows[i])

        def at_rows(i, j):
            hist, cell, rows = sims[i][j]
            return force_at_rows(hist, rows, cell)[0]

        def resid(j):
            # a row the model gives no force at (a cell without a rest state, status no_rest_state: every row
            # NaN) is no prediction: its residual is 0 here, before the offset's projection (which would spread
            # the NaN over its curve), and counted at FAILED_ROW_Z below (scipy stopped the whole diagnosis at
            # such a start of a race: "Residuals are not finite in the initial point", blind study seed 2, case 5)
            e = [at_rows(i, j) - c.force for i, c in enumerate(curves)]
            return (np.concatenate([_project(np.where(np.isfinite(ei), ei, 0.0), ws[i], offsets)
                                    for i, ei in enumerate(e)]),
                    np.concatenate([~np.isfinite(ei) for ei in e]))
        r0, no_force = resid(0)
        J = np.empty((len(r0), k))
        for j in range(k):
            # the Jacobian of the model as simulated (a neighbour that fails near the boundary of the
            # region where the model runs must not make the step vanish); the residual itself is penalised
            rj, no_force_j = resid(j + 1)
            J[:, j] = np.where(no_force | no_force_j, 0.0, (rj - r0) / h[j])
        failed = no_force
        if penalise_failed:
            failed = failed | np.concatenate([_failed_rows(hist, r, cell)
                                              for hist, cell, r in (sim[0] for sim in sims)])
        r = _penalised(r0, failed, np.concatenate(ws))
        cache[key] = (r, J, sims)
        return cache[key]

    res = least_squares(lambda x: evaluate(x)[0], x_start, jac=lambda x: evaluate(x)[1], bounds=(lo, hi),
                        method="trf", x_scale="jac", max_nfev=max_nfev, ftol=ftol, xtol=xtol, gtol=1e-12)
    x = res.x
    r, J, sims = evaluate(x)
    chi2 = float(r @ r)
    dof = n_rows - k_total
    s2 = chi2 / dof
    cov_x = s2 * np.linalg.pinv(J.T @ J)
    # delta method to model units: only phi0 = f atan(m) is not the identity
    fitted = _to_params(base, free, x, effects, fixed)
    G = np.eye(k)
    if "phi0" in free:
        jp = free.index("phi0")
        m = fitted.m  # (eq 10's m at rest with coiling_angle_friction: its dependence on mu_k is left out)
        f = x[jp]
        G[jp, jp] = math.atan(m)
        if "m" in free:
            G[jp, free.index("m")] = f / (1.0 + m * m)
    cov = G @ cov_x @ G.T
    values = {n: float(getattr(fitted, n)) if n in BASELINE_VARIABLES else float(x[j]) for j, n in enumerate(free)}
    se = {n: float(math.sqrt(max(cov[j, j], 0.0))) for j, n in enumerate(free)}
    out_curves, rss, offs = [], 0.0, {}
    for i, c in enumerate(curves):
        hist, cell, rows = sims[i][0]
        fs, lab = force_at_rows(hist, rows, cell)
        off = offset_of(fs - c.force, ws[i]) if offsets else 0.0
        offs[c.source] = off
        fs = fs + off
        e = (fs - c.force)[ws[i] > 0]
        rss += float(e @ e)
        st = hist.status[:, cell]
        out_curves.append({"source": c.source, "strain": c.strain, "measured": c.force, "simulated": fs,
                           "labels": lab, "keys": stage_keys(lab, c.direction, c.cycle),
                           "final_status": STATUS_NAMES[int(st[-1])], "offset_N": off})
    out = {"params": fitted, "free": free, "effects": effects, "x": x.copy(), "J": J, "values": values,
           "fit_variables": {n: float(x[j]) for j, n in enumerate(free)}, "std_errors": se, "covariance": cov,
           "rms_N": math.sqrt(rss / n_rows), "rss_N2": rss, "chi2": chi2, "n": n_rows, "k": k_total,
           "offsets_N": offs, "curves": out_curves,
           "nfev": int(res.nfev), "njev": int(res.njev or 0), "n_batch_calls": counter["calls"],
           "success": bool(res.success), "message": str(res.message)}
    out["at_bounds"] = at_bounds(free, x, lo, hi, r, J)
    if "phi0" in free:
        jp = free.index("phi0")
        out["phi0_fraction"] = (float(x[jp]), float(math.sqrt(max(cov_x[jp, jp], 0.0))))
    return out
