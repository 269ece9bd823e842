"""Gap between a measured and a simulated curve, stage by stage.

The simulated stage labels (:func:`knitsim.cell.stages.stage_label`:
adherence / sliding / jamming / slack) and the branch of each measured row
give a *stage key*: ``loading_<label>`` on the first loading branch,
``reloading_<label>`` on the loading branches of later cycles,
``unloading_<label>`` on unloading.  The force error ``e = F_sim - F_meas`` is
split by key; since the keys partition the rows,

    sum_k n_k rms_k^2 = n rms^2    and    sum_k share_k = 1,

with ``share_k = sum_{rows of k} e^2 / sum e^2`` (the identity the tests check).

Global indicators of a curve (each per cycle): peak force and its strain,
residual strain (the first zero of the force on the unloading branch, linear
interpolation between rows), hysteresis energy ``oint F d(strain)``
(:func:`knitsim.cell.cycle.dissipated_energy`, from the last row of the
previous cycle, or the first row of the curve), and the strain at the first
row labelled ``jamming``.
"""
from __future__ import annotations

import math

import numpy as np

from ..cell.cycle import dissipated_energy
from ..errors import KnitsimInputError


def stage_keys(labels, direction, cycle) -> list[str]:
    """Stage key of each row: ``loading_*``, ``reloading_*`` (cycle > 1) or ``unloading_*``."""
    out = []
    for lab, d, c in zip(labels, direction, cycle):
        prefix = "unloading" if int(d) < 0 else ("loading" if int(c) <= 1 else "reloading")
        out.append(f"{prefix}_{lab}")
    return out


def stage_gap(measured, simulated, keys, weights=None) -> dict:
    """Force error per stage key.

    Parameters
    ----------
    measured, simulated : array of float
        Force per wale [N] at the same rows.
    keys : sequence of str
        Stage key of each row (:func:`stage_keys`).
    weights : array of float, optional
        1 / noise sd of each row.  With them every stage also has ``chi2`` and ``chi2_excess``
        (chi2 less its rows, what noise alone gives), and ``share`` is the stage's part of the
        positive excesses: where curves of different noise are pooled, squared newtons would rank
        the stages by the noisier curve's rows (a blind probe: 86 % "loading_sliding" on effect-free
        curves, the pull's rows of sd 0.036 N beside cycles of sd 0.004 N).

    Returns
    -------
    dict
        ``total``: ``n``, ``rms_N``, ``max_abs_N``, ``sse_N2``; ``stages``: the same
        per key, plus ``share`` (its part of the total squared error, or of the chi^2 excess
        with ``weights``; NaN when the total is 0).
    """
    fm = np.asarray(measured, float)
    fs = np.asarray(simulated, float)
    keys = list(keys)
    if not (len(fm) == len(fs) == len(keys)) or len(fm) == 0:
        raise KnitsimInputError(f"gap: measured ({len(fm)}), simulated ({len(fs)}) and keys ({len(keys)}) "
                                "must have the same non-zero length")
    e = fs - fm
    sse = float(np.sum(e * e))
    stages = {}
    karr = np.asarray(keys, dtype=object)
    for k in dict.fromkeys(keys):
        ek = e[karr == k]
        sk = float(np.sum(ek * ek))
        stages[k] = {"n": int(len(ek)), "rms_N": math.sqrt(sk / len(ek)), "max_abs_N": float(np.max(np.abs(ek))),
                     "sse_N2": sk, "share": sk / sse if sse > 0 else float("nan")}
    if weights is not None:
        z = e * np.asarray(weights, float)
        for k in stages:
            c2 = float(np.sum(z[karr == k] ** 2))
            stages[k].update(chi2=c2, chi2_excess=c2 - stages[k]["n"])
        pos = sum(max(v["chi2_excess"], 0.0) for v in stages.values())
        for v in stages.values():
            v["share"] = max(v["chi2_excess"], 0.0) / pos if pos > 0 else float("nan")
    total = {"n": int(len(e)), "rms_N": math.sqrt(sse / len(e)), "max_abs_N": float(np.max(np.abs(e))),
             "sse_N2": sse}
    return {"total": total, "stages": stages}


def curve_indicators(strain, force, cycle, direction, labels=None) -> dict:
    """Global indicators of one curve (see the module docstring).

    Returns
    -------
    dict
        ``cycles``: list of {cycle, peak_force_N, strain_at_peak, residual_strain
        (None if the force never reaches 0 while unloading), energy_N_per_strain};
        ``strain_at_first_jamming``: None without labels or without a jammed row.
    """
    s = np.asarray(strain, float)
    f = np.asarray(force, float)
    cycle = np.asarray(cycle)
    direction = np.asarray(direction)
    out = []
    for k in np.unique(cycle):
        rows = np.nonzero(cycle == k)[0]
        j = rows[np.argmax(f[rows])]
        res = None
        unload = rows[direction[rows] < 0]
        if len(unload):
            path = np.concatenate([[unload[0] - 1], unload]) if unload[0] > 0 else unload
            for a, b in zip(path[:-1], path[1:]):
                if f[a] > 0 >= f[b]:
                    t = f[a] / (f[a] - f[b])
                    res = float(s[a] + t * (s[b] - s[a]))
                    break
        path = np.concatenate([[rows[0] - 1], rows]) if rows[0] > 0 else rows
        w = dissipated_energy(s[path], f[path]) if len(path) > 1 else 0.0
        out.append({"cycle": int(k), "peak_force_N": float(f[j]), "strain_at_peak": float(s[j]),
                    "residual_strain": res, "energy_N_per_strain": w})
    jam = None
    if labels is not None:
        idx = [i for i, lab in enumerate(labels) if lab == "jamming"]
        jam = float(s[idx[0]]) if idx else None
    return {"cycles": out, "strain_at_first_jamming": jam}


def gap_report(strain, measured, simulated, labels, cycle, direction) -> dict:
    """Gap per stage plus the indicators of both curves at the measured rows.

    ``labels`` are the simulation's stage labels at the rows; the measured
    curve has no labels of its own, so its jamming strain is not reported.
    """
    keys = stage_keys(labels, direction, cycle)
    return {"gap": stage_gap(measured, simulated, keys), "keys": keys,
            "measured": curve_indicators(strain, measured, cycle, direction),
            "simulated": curve_indicators(strain, simulated, cycle, direction, labels)}


def bic(rss: float, n: int, k: int) -> float:
    """Bayesian information criterion of a least-squares fit, ``n ln(rss / n) + k ln(n)``.

    Gaussian errors of unknown variance (Schwarz 1978), up to a constant that
    cancels between models fitted to the same ``n`` points.
    """
    if not (n >= 1 and rss > 0 and k >= 0):
        raise KnitsimInputError(f"bic: needs n >= 1, rss > 0, k >= 0 (got n = {n}, rss = {rss}, k = {k})")
    return n * math.log(rss / n) + k * math.log(n)
