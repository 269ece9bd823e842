"""Sim-to-real gap diagnosis: where the gap lies, which unmodelled effect causes it, how far it shrinks.

Dusserre (2015, sections 4-5) explains why his curves are too sharp by
effects his model leaves out; :func:`diagnose` tests that reasoning on
measured curves (issue 6):

1. **Calibrate** the baseline's free parameters (m, phi0; optionally B, d and
   the knit geometry L, W0, C0) on every curve at once
   (:func:`~knitsim.diagnosis.calibrate.calibrate_baseline`: least squares, one
   batched launch per evaluation), from the scene's start and the three best
   points of a coarse (m, phi0) grid (:func:`_grid_starts`, one launch); the
   starts race (:func:`_fit`).  After the candidates are fitted, the baseline
   is re-calibrated from any candidate's baseline parameters that fit better
   (a better basin), so that no effect is credited with what the baseline can
   do itself; when it moved by more than the evidence threshold, the
   candidates that did not reach that basin are fitted again from there.
2. **Where**: the rows are keyed by the stage the calibrated baseline
   simulates there (``loading_sliding``, ``unloading_adherence``, ...;
   :func:`~knitsim.diagnosis.gap.stage_keys`); the gap is split by key (RMS,
   max error, share of the squared error).  The keys stay those of the
   baseline for every candidate, so that shares compare.
3. **Which**: each effect is added and the model recalibrated (the effect's
   variables plus the baseline's).  Candidates are ranked by the Bayesian
   information criterion with the measurement noise known,

       score = (RSS_base - RSS_effect) / sigma^2 - dk ln n,

   i.e. the drop in ``BIC = RSS / sigma^2 + k ln n`` (Schwarz 1978); sigma is
   estimated from the measured curves alone (:func:`estimate_noise`) or given.
   An effect is *significant* when its score exceeds :data:`STRONG` (Kass and
   Raftery 1995: a BIC difference above 10 is very strong evidence); for
   noise alone, a one-parameter effect passes with probability
   P(chi2_1 > 10 + ln n) < 1e-3.  Whether the baseline already fits within
   the noise (chi-square bound on RSS / sigma^2) is reported beside it.  Two significant effects whose scores differ by less than
   :data:`STRONG` cannot be told apart by these data; the verdict then is not
   confident and names both.  An effect that the data cannot identify at all
   (``velocity_friction`` with all curves at one rate, where any rate factor
   is a change of m) is reported with ``identifiable = false`` and not fitted.
4. **How far**: the gap per stage after the best effect, and after the best
   pair (greedy: the best effect plus each of the :data:`PAIR_PARTNERS` next
   effects whose own fit lowered the RSS; one that explains nothing alone is
   not tried).

``shrink = 1 - rms_after / rms_before``.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from ..cell.effects import EFFECT_NAMES
from ..cell.material import CellParams
from ..errors import KnitsimInputError
from .calibrate import calibrate_baseline, rss_of_cells
from .effects import BASELINE_VARIABLES, EFFECT_SPECS, build_params, check_effects, variables_for
from .gap import curve_indicators, stage_gap
from .measured import MeasuredCurve

#: BIC difference counted as very strong evidence (Kass and Raftery 1995, 2 ln B > 10)
STRONG = 10.0


@dataclass(frozen=True)
class DiagnosisSetup:
    """What the diagnosis knows of the specimen and how to run it.

    Attributes
    ----------
    base : CellParams
        The specimen (material, knit, rules); start of the free parameters.
    free : tuple of str
        Baseline parameters to calibrate: any of ``m``, ``phi0``, ``B``, ``d``.
    bounds : dict
        ``name -> (low, high)`` of fitted variables (phi0 as a fraction of phimax).
    effects : tuple of str
        Effects to try (default: all seven).
    fixed : dict
        Effect parameters held fixed (EffectSet field names: ``load_ref_N``,
        ``rate_ref_mm_s``, ``compaction_min``, ``bend_sigma``).
    max_increment : float
        Largest strain increment of the replay programs.
    noise_N : float or None
        Measurement noise sd [N per wale]; None: estimated from the curves.
    device : str
        Warp device.
    max_nfev : int
        Evaluations per calibration.
    pair : bool
        Also fit the best pair of effects (greedy).
    title : str
    """

    base: CellParams
    free: tuple = ("m", "phi0")
    bounds: dict = field(default_factory=dict)
    effects: tuple = EFFECT_NAMES
    fixed: dict = field(default_factory=dict)
    max_increment: float = 0.01
    noise_N: float | None = None
    device: str = "cpu"
    max_nfev: int = 20
    pair: bool = True
    title: str = ""

    def validated(self) -> "DiagnosisSetup":
        if not isinstance(self.base, CellParams):
            raise KnitsimInputError(f"diagnosis.base = {self.base!r}: expected a CellParams")
        self.base.validated(where="scene")
        free = tuple(self.free)
        for n in free:
            if n not in BASELINE_VARIABLES:
                raise KnitsimInputError(f"diagnosis.free: unknown parameter {n!r}; expected some of "
                                        f"{', '.join(BASELINE_VARIABLES)}")
        if not free or len(set(free)) != len(free):
            raise KnitsimInputError(f"diagnosis.free = {list(free)!r}: expected distinct names, at least one")
        check_effects(self.effects)
        if self.noise_N is not None and not (isinstance(self.noise_N, (int, float)) and self.noise_N > 0
                                             and math.isfinite(self.noise_N)):
            raise KnitsimInputError(f"diagnosis.noise_N = {self.noise_N!r}: must be a number > 0 [N]")
        if not (isinstance(self.max_increment, (int, float)) and 0 < self.max_increment <= 0.05):
            raise KnitsimInputError(f"diagnosis.max_increment = {self.max_increment!r}: expected 0 < x <= 0.05")
        return self


def estimate_noise(curves: Sequence[MeasuredCurve]) -> float:
    """Measurement noise sd [N] from the measured curves alone.

    On each branch (rows of one cycle and direction) every inner row is
    compared with the straight line through its two neighbours; for white
    noise of sd sigma the difference has variance ``sigma^2 (1 + w1^2 + w2^2)``
    (w the interpolation weights), whatever the smooth curve's slope.  The
    median absolute value makes it robust to the few rows at stage changes
    (sigma = 1.4826 MAD for Gaussian noise).  Rows at zero force (a slack
    knit, where a force reading is clipped at 0) are left out.
    """
    z = []
    for c in curves:
        s, f = c.strain, c.force
        br = np.concatenate([[0], np.nonzero((np.diff(c.cycle) != 0) | (np.diff(c.direction) != 0))[0] + 1, [len(s)]])
        for a, b in zip(br[:-1], br[1:]):
            for i in range(a + 1, b - 1):
                h1, h2 = s[i] - s[i - 1], s[i + 1] - s[i]
                if h1 == 0 or h2 == 0 or h1 * h2 < 0 or min(f[i - 1], f[i], f[i + 1]) <= 0.0:
                    continue  # rows at exactly zero force are clipped (a slack knit): not noise samples
                w1, w2 = h2 / (h1 + h2), h1 / (h1 + h2)
                r = f[i] - (w1 * f[i - 1] + w2 * f[i + 1])
                z.append(abs(r) / math.sqrt(1.0 + w1 * w1 + w2 * w2))
    if len(z) < 5:
        raise KnitsimInputError("curves: too few rows on monotone branches to estimate the noise; give diagnosis.noise_N")
    return float(1.4826 * np.median(z))


def _stages(measured, simulated, keys) -> dict:
    g = stage_gap(measured, simulated, keys)
    return {k: {"n": v["n"], "rms_N": v["rms_N"], "max_abs_N": v["max_abs_N"], "share": v["share"],
                "sse_N2": v["sse_N2"]} for k, v in g["stages"].items()}


#: effects tried beside the best one in the greedy pair (the next best that lowered the RSS on their own)
PAIR_PARTNERS = 3

#: evaluations each start of a multi-start calibration gets before the best one goes on alone
RACE_NFEV = 6


def _fit(curves, setup: DiagnosisSetup, effects: tuple, x0: dict | None = None, extra_starts=()) -> dict:
    """Calibrate the model with ``effects`` on from several starts; the least RSS is kept.

    The variables start from the specimen as calibrated so far (``x0``, in the
    fitted variables: phi0 as a fraction of phimax) or where the effect
    vanishes; each of ``extra_starts`` overrides some of them.  With more than
    one start, each gets :data:`RACE_NFEV` evaluations and only the best goes on
    to ``setup.max_nfev`` (a race: the starts are there to pick a basin, which
    the first few trust-region steps show).
    """
    variables = variables_for(tuple(setup.free), effects)
    free = tuple(v.name for v in variables)
    bounds = {k: tuple(v) for k, v in setup.bounds.items() if k in free}
    x0 = dict(x0 or {})
    try:
        ref = build_params(setup.base, (), {k: v for k, v in x0.items() if k in BASELINE_VARIABLES})
    except KnitsimInputError:
        ref = setup.base
    start = {v.name: v.start(ref) for v in variables}
    start.update({k: v for k, v in x0.items() if k in free})
    starts = [start]
    for e in extra_starts:
        st = dict(start, **{k: v for k, v in e.items() if k in free})
        if st not in starts:
            starts.append(st)

    def calibrate(st, nfev):
        return calibrate_baseline(curves, setup.base, free=free, bounds=bounds, device=setup.device,
                                  max_increment=setup.max_increment, x0=st, max_nfev=nfev,
                                  effects=effects, fixed=setup.fixed)

    if len(starts) == 1 or setup.max_nfev <= RACE_NFEV:
        fits = [calibrate(st, setup.max_nfev) for st in starts]
        return min(fits, key=lambda f: f["rss_N2"])
    best = min((calibrate(st, RACE_NFEV) for st in starts), key=lambda f: f["rss_N2"])
    if best["success"]:
        return best
    fit = calibrate(best["fit_variables"], setup.max_nfev - RACE_NFEV)
    return fit if fit["rss_N2"] <= best["rss_N2"] else best


#: coarse grid of the baseline's friction: m (eq 10's ratio; section 3.4 reports 0.06 .. 0.6 over a test) and
#: phi0 as a fraction of phimax (section 3.3.1: anywhere in the cone)
GRID_M = (0.05, 0.08, 0.12, 0.18, 0.27, 0.4)
GRID_PHI0 = (-0.9, -0.45, 0.0, 0.45, 0.9)
#: grid points kept as starts of the baseline's calibration
GRID_STARTS = 3


def _grid_starts(curves, setup: DiagnosisSetup) -> tuple:
    """The best :data:`GRID_STARTS` points of a coarse grid of (m, phi0), as starts of the baseline fit.

    Every grid cell is evaluated in one batched launch per distinct load
    program (the other variables at the scene's values); points outside the
    calibration's bounds are left out.  Returns ``()`` when neither m nor
    phi0 is free.
    """
    free = tuple(setup.free)
    if "m" not in free and "phi0" not in free:
        return ()
    lo_m, hi_m = setup.bounds.get("m", BASELINE_VARIABLES["m"].bounds)
    lo_f, hi_f = setup.bounds.get("phi0", BASELINE_VARIABLES["phi0"].bounds)
    ms = [m for m in GRID_M if lo_m <= m <= hi_m] if "m" in free else [setup.base.m]
    fs = [f for f in GRID_PHI0 if lo_f <= f <= hi_f] if "phi0" in free else [None]
    points, cells = [], []
    for m in ms:
        for f in fs:
            pt = {"m": m} if "m" in free else {}
            if f is not None:
                pt["phi0"] = f
            try:
                cells.append(build_params(setup.base, (), pt, setup.fixed))
            except KnitsimInputError:
                continue
            points.append(pt)
    if not cells:
        return ()
    rss = rss_of_cells(curves, cells, setup.max_increment, setup.device)
    order = np.argsort(rss, kind="stable")
    return tuple(points[j] for j in order[:GRID_STARTS])


def _phi0_alternative(values: dict) -> tuple:
    """A start of phi0 away from the baseline's, when that sits near a bound of the cone.

    The least squares in phi0 has local minima (the initial stick stage ends
    where phi reaches +-phimax), and a baseline at phi0 = +-phimax may be a
    local minimum that the effect's own optimum does not share.
    """
    f = values.get("phi0")
    if f is None or abs(f) < 0.5:
        return ()
    return ({"phi0": 0.0},)


def _baseline_rss_at(curves, setup: DiagnosisSetup, fits: dict) -> dict:
    """RSS of the baseline at each fit's values of the baseline's variables, in one launch.

    Fits that lack one of them (coiling_angle_friction replaces m) or whose
    values make no valid baseline cell are left out.
    """
    free = tuple(setup.free)
    names, cells = [], []
    for name, fit in fits.items():
        x = fit["fit_variables"]
        if not all(k in x for k in free):
            continue
        try:
            cells.append(build_params(setup.base, (), {k: x[k] for k in free}, setup.fixed))
        except KnitsimInputError:
            continue
        names.append(name)
    if not cells:
        return {}
    return dict(zip(names, rss_of_cells(curves, cells, setup.max_increment, setup.device).tolist()))


def _summary(fit: dict, keys: list, measured: np.ndarray, base_rss: float, sigma: float, n: int, k0: int) -> dict:
    sim = np.concatenate([c["simulated"] for c in fit["curves"]])
    e = sim - measured
    rss = float(e @ e)
    dk = fit["k"] - k0
    flagged = [c["source"] for c in fit["curves"] if c["final_status"] not in ("ok", "force_cap")]
    return {"params": dict(fit["values"]), "std_errors": dict(fit["std_errors"]), "rms_N": math.sqrt(rss / n),
            "rss_N2": rss, "stages": _stages(measured, sim, keys),
            "shrink": 1.0 - math.sqrt(rss / base_rss) if base_rss > 0 else 0.0,
            "score": (base_rss - rss) / sigma ** 2 - dk * math.log(n), "k": fit["k"],
            "flagged_curves": flagged, "nfev": fit["nfev"]}


def diagnose(curves: Sequence[MeasuredCurve], setup: DiagnosisSetup,
             progress: Callable[[str], None] | None = None) -> dict:
    """Diagnose the gap between measured curves and the model (see the module docstring).

    Parameters
    ----------
    curves : list of MeasuredCurve
        Curves of one specimen; each replays its own strain history (and rate).
    setup : DiagnosisSetup
    progress : callable, optional
        ``progress(message)`` after each calibration.

    Returns
    -------
    dict
        ``baseline``, ``where``, ``candidates`` (best first), ``pair``,
        ``indistinguishable``, ``verdict``, ``noise``, ``curves`` and
        ``timing_s`` (the JSON of ``knitsim diagnose``).
    """
    t0 = time.perf_counter()
    setup = setup.validated()
    curves = list(curves)
    if not curves or not all(isinstance(c, MeasuredCurve) for c in curves):
        raise KnitsimInputError("curves: expected one or more measured curves")
    say = progress or (lambda msg: None)
    measured = np.concatenate([c.force for c in curves])
    n = len(measured)
    if setup.noise_N is not None:
        sigma, how = float(setup.noise_N), "given (diagnosis.noise_N)"
    else:
        sigma = estimate_noise(curves)
        how = "estimated from the measured curves (deviation from the neighbours' chord, 1.4826 MAD)"
    sigma = max(sigma, 1e-6 * float(np.max(np.abs(measured)) or 1.0))
    rates = sorted({float(r) for c in curves if c.rate_mm_s is not None for r in np.unique(c.rate_mm_s)})

    # 1. baseline: from the scene's start and the best points of a coarse (m, phi0) grid (its least
    # squares has local minima in both, and a grid of cells costs one batched launch)
    grid = _grid_starts(curves, setup)
    base_fit = _fit(curves, setup, (), extra_starts=grid)
    say(f"baseline: rms {base_fit['rms_N']:.4g} N")

    # 3. which (fits first; they are scored once the baseline is final)
    def fit_candidates(base_x: dict, names, quick: bool = False) -> dict:
        out = {}
        for name in names:
            spec = EFFECT_SPECS[name]
            if max(len(rates), 1) < spec.min_rates:
                continue
            if quick:
                # from the new baseline only, where the effect vanishes: the other starts were raced already
                out[name] = _fit(curves, setup, (name,), x0=base_x)
            else:
                out[name] = _fit(curves, setup, (name,), x0=base_x,
                                 extra_starts=spec.extra_starts + _phi0_alternative(base_x))
            say(f"{name}: rms {out[name]['rms_N']:.4g} N")
        return out

    fits = fit_candidates(base_fit["fit_variables"], setup.effects)
    # a candidate's fit may have found a better basin of the baseline's own parameters: the baseline
    # is re-calibrated from there, so that no effect is credited with what the baseline can do itself
    # (candidates stuck above it are fitted again from there, the better of their two fits kept)
    trial = _baseline_rss_at(curves, setup, fits)
    trial = {k: v for k, v in trial.items() if v < base_fit["rss_N2"] - sigma * sigma}  # below sigma^2: no change
    basin_note = ""
    if trial:
        src = min(trial, key=trial.get)
        refit = _fit(curves, setup, (), x0=fits[src]["fit_variables"])
        old_rss = base_fit["rss_N2"]
        if refit["rss_N2"] < old_rss - sigma * sigma:
            basin_note = (f"baseline re-calibrated from the {src} fit's parameters: rms "
                          f"{base_fit['rms_N']:.4g} -> {refit['rms_N']:.4g} N")
            base_fit = refit
            # only the candidates that did not reach the new baseline's basin themselves, and only when the
            # baseline moved by more than the evidence threshold (a smaller move changes no verdict's margin)
            moved = old_rss - base_fit["rss_N2"] > STRONG * sigma * sigma
            stuck = [k for k, f in fits.items() if moved and f["rss_N2"] > base_fit["rss_N2"]]
            again = fit_candidates(base_fit["fit_variables"], stuck, quick=True)
            fits.update({k: f for k, f in again.items() if f["rss_N2"] < fits[k]["rss_N2"]})
            if stuck:
                basin_note += f"; {', '.join(stuck)} fitted again from there"
            say(basin_note)

    # 2. where
    keys = [k for c in base_fit["curves"] for k in c["keys"]]
    k0 = base_fit["k"]
    base_rss = base_fit["rss_N2"]
    baseline = _summary(base_fit, keys, measured, base_rss, sigma, n, k0)
    baseline["bic"] = base_rss / sigma ** 2 + k0 * math.log(n)
    for key in ("shrink", "score"):
        baseline.pop(key)
    if basin_note:
        baseline["note"] = basin_note
    where = sorted(baseline["stages"], key=lambda k: -np.nan_to_num(baseline["stages"][k]["share"]))
    # the baseline already fits within the noise: RSS / sigma^2 below the chi-square(n - k) 99.9 % bound
    chi2_bound = (n - k0) + 3.1 * math.sqrt(2.0 * (n - k0))
    within_noise = base_rss / sigma ** 2 <= chi2_bound

    candidates = []
    for name in setup.effects:
        spec = EFFECT_SPECS[name]
        cand = {"effect": name, "doc": spec.doc, "identifiable": True, "note": ""}
        if name not in fits:
            cand.update(identifiable=False, params={}, std_errors={}, rms_N=None, stages={}, shrink=None, score=None,
                        significant=False,
                        note=f"needs curves at >= {spec.min_rates} distinct rates (have "
                             f"{len(rates) if rates else 'none given'}): at one rate the rate factor of eq 5 is "
                             "a change of m")
            candidates.append(cand)
            continue
        fit = fits[name]
        cand.update(_summary(fit, keys, measured, base_rss, sigma, n, k0))
        if spec.nests_baseline and fit["rss_N2"] > base_rss:
            # where the effect vanishes the model is the baseline bit for bit: a fit above it is a local
            # minimum, and the effect explains nothing
            cand.update(rss_N2=base_rss, rms_N=baseline["rms_N"], stages=baseline["stages"], shrink=0.0,
                        score=-(fit["k"] - k0) * math.log(n))
            cand["note"] = "its fit ended above the baseline (a local minimum); where it vanishes it is the baseline"
        cand["significant"] = bool(cand["score"] > STRONG)
        if cand["flagged_curves"]:
            cand["note"] = (f"some increments did not converge on {', '.join(cand['flagged_curves'])} "
                            "(those rows keep the last converged force): a verdict on it is not confident")
        candidates.append(cand)
    fitted = [c for c in candidates if c["score"] is not None]
    fitted.sort(key=lambda c: -c["score"])
    candidates = fitted + [c for c in candidates if c["score"] is None]

    sig = [c for c in fitted if c["significant"]]
    indist = []
    for i, a in enumerate(sig):
        for b in sig[i + 1:]:
            if a["score"] - b["score"] < STRONG:
                indist.append([a["effect"], b["effect"]])

    # 4. how far: best, then the best pair (greedy)
    best = sig[0] if sig else None
    pair = None
    if best is not None and setup.pair:
        trials = []
        partners = [c for c in fitted if c["effect"] != best["effect"] and c["rss_N2"] < base_rss]
        for other in partners[:PAIR_PARTNERS]:
            effs = (best["effect"], other["effect"])
            # from the best effect's fit with the partner where it vanishes, or at its own fitted strength
            x0 = {**base_fit["fit_variables"], **fits[best["effect"]]["fit_variables"]}
            own = {v.name: fits[other["effect"]]["fit_variables"][v.name]
                   for v in EFFECT_SPECS[other["effect"]].variables}
            fit = _fit(curves, setup, effs, x0=x0, extra_starts=(own,))
            summ = _summary(fit, keys, measured, base_rss, sigma, n, k0)
            summ["effects"] = list(effs)
            summ["gain_over_best"] = summ["score"] - best["score"]
            summ["significant"] = bool(summ["gain_over_best"] > STRONG and not summ["flagged_curves"])
            trials.append((summ, fit))
            say(f"pair {effs}: rms {summ['rms_N']:.4g} N")
        if trials:
            pair, pair_fit = max(trials, key=lambda t: t[0]["score"])
            fits["__pair__"] = pair_fit

    # verdict
    if best is None:
        top = fitted[0] if fitted else None
        reason = "no effect improves the fit by more than the BIC penalty plus 10 (very strong evidence)"
        if within_noise:
            reason = "the baseline fits within the measurement noise; " + reason
        verdict = {"effect": None, "stage": where[0] if where else None,
                   "shrink": 0.0, "confident": bool(within_noise or top is None or top["score"] < 0),
                   "reason": reason}
    else:
        drops = {k: baseline["stages"][k]["sse_N2"] - best["stages"][k]["sse_N2"] for k in baseline["stages"]}
        stage = max(drops, key=drops.get)
        rivals = [p[1] for p in indist if p[0] == best["effect"]] + [p[0] for p in indist if p[1] == best["effect"]]
        confident = not rivals and not best["flagged_curves"]
        if rivals:
            reason = f"the data cannot tell {best['effect']} from {', '.join(rivals)} (BIC scores within {STRONG:g})"
        elif best["flagged_curves"]:
            reason = "its best fit has increments that did not converge"
        else:
            reason = (f"BIC score {best['score']:.4g}; the next effect is more than {STRONG:g} behind")
        verdict = {"effect": best["effect"], "stage": stage, "shrink": best["shrink"], "confident": confident,
                   "reason": reason, "alternatives": rivals}

    # curves
    out_curves = []
    best_fit = fits.get(best["effect"]) if best else None
    pair_fit = fits.get("__pair__")
    for i, c in enumerate(curves):
        bc = base_fit["curves"][i]
        entry = {"source": c.source, "strain": c.strain.tolist(), "measured": c.force.tolist(),
                 "baseline": np.asarray(bc["simulated"]).tolist(),
                 "best": None if best_fit is None else np.asarray(best_fit["curves"][i]["simulated"]).tolist(),
                 "pair": None if pair_fit is None else np.asarray(pair_fit["curves"][i]["simulated"]).tolist(),
                 "keys": list(bc["keys"]), "cycle": c.cycle.tolist(), "direction": c.direction.tolist(),
                 "indicators": {"measured": curve_indicators(c.strain, c.force, c.cycle, c.direction),
                                "baseline": curve_indicators(c.strain, bc["simulated"], c.cycle, c.direction,
                                                             bc["labels"])}}
        if best_fit is not None:
            bf = best_fit["curves"][i]
            entry["indicators"]["best"] = curve_indicators(c.strain, bf["simulated"], c.cycle, c.direction,
                                                           bf["labels"])
        out_curves.append(entry)
    return {"scene": setup.title, "inputs": [c.source for c in curves],
            "noise": {"sigma_N": sigma, "method": how, "rates_mm_s": rates,
                      "baseline_chi2_per_dof": base_rss / sigma ** 2 / max(n - k0, 1),
                      "baseline_within_noise": bool(within_noise)},
            "n_rows": n, "baseline": baseline, "where": where, "candidates": candidates, "pair": pair,
            "indistinguishable": indist, "verdict": verdict, "curves": out_curves,
            "timing_s": time.perf_counter() - t0}
