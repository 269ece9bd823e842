"""Whether a fitted parameter is identified: the one classifier of the capstan and Dahl fits.

A fit's value is believable only where the data set it.  A parameter is *not identified* when it ends
at a bound of the search (the bound, not the data, set it), when its standard error is not finite, or
0 while the residual is not (a singular Jacobian), or wider than the search's box (the data narrow it to
nothing the box does not), or, for a parameter that must be positive, larger than its value (its
one-standard-error interval reaches 0).  The statuses and the sentences go to the
user (the printed table, the JSON, the plot title), not to a log.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: A fitted value this close to a bound, relative to the bound (or to 1e-3 of the box width for a bound
#: near 0), counts as sitting at the bound.
AT_BOUND_RTOL = 1e-3
#: What a printed table appends to a parameter by its status (nothing where identified or fixed).
FLAG_TEXT = {"at_lower_bound": "AT LOWER BOUND: not identified", "at_upper_bound": "AT UPPER BOUND: not identified",
             "not_identified": "NOT IDENTIFIED", "lower_bound_only": "ONLY A LOWER BOUND: not identified"}


def rounding_sd(step):
    """The sd of a reading written to the last digit ``step`` about the value it rounds (same units):
    ``step / sqrt(12)``, a uniform error over one digit (variance ``step^2 / 12``; half a digit ``h`` either side:
    ``h^2 / 3``).  The one rounding law of the capstan fit's floor on its standard errors and of the diagnosis's
    noise (:mod:`knitsim.diagnosis.noise`)."""
    return step / np.sqrt(12.0)


def covariance(J: np.ndarray, s2: float) -> np.ndarray:
    """Covariance of least-squares parameters, ``s2 (J^T J)^-1``, by the SVD of ``J`` (V diag(1/sv^2) V^T): the one
    routine of the capstan and Dahl fits.  Infinite everywhere where ``J`` is singular (a singular value below
    ``eps max(J.shape)`` of the largest) or not finite: its parameters are undetermined.  The pseudo-inverse of
    ``J^T J`` drops the undetermined direction instead (and squares J's condition number, so it drops any below
    ~3e-8 of the largest): a capstan probe's speeds 1 and 1 + 1e-7 mm/s gave p "+/- 4.6e-10" and b an error 17 %
    short."""
    k = J.shape[1]
    with np.errstate(all="ignore"):
        if np.all(np.isfinite(J)):
            _, sv, vt = np.linalg.svd(J, full_matrices=False)
            tol = np.finfo(float).eps * max(J.shape) * (sv[0] if sv.size else 0.0)
            if sv.size == k and np.all(sv > tol):
                return (vt.T / sv ** 2) @ vt * s2
    return np.full((k, k), np.inf)


def at_bound(value: float, lower: float, upper: float, rtol: float = AT_BOUND_RTOL,
             atol: float = 0.0) -> str | None:
    """``"lower"`` / ``"upper"`` when ``value`` sits at (within ``rtol`` relative, plus ``atol``) that
    bound, else None."""
    width = upper - lower if np.isfinite(upper - lower) else 0.0
    for side, bound in (("lower", lower), ("upper", upper)):
        if not np.isfinite(bound):
            continue
        if abs(value - bound) <= rtol * max(abs(bound), 1e-3 * width) + atol:
            return side
    return None


def wider_than_box(stderr: float, lower: float, upper: float) -> bool:
    """A standard error larger than the width of a finite box ``[lower, upper]``: one standard error either side
    spans every value the fit searches, so the data do not narrow the parameter (a capstan probe's speeds
    proportional to the dead weight set only p + n: p "0.45 +/- 52" and n "0.52 +/- 52" in a box of width 2 and
    0.7 were "identified")."""
    width = float(upper) - float(lower)
    return bool(np.isfinite(width) and np.isfinite(stderr) and stderr > width)


def parameter_status(names: Sequence[str], values: Sequence[float], stderr: Sequence[float],
                     lower: Sequence[float], upper: Sequence[float], fixed: Sequence[str] = (),
                     exact_fit: bool = False, positive: Sequence[str] = (), shown: Sequence[float] | None = None,
                     atol: Sequence[float] | None = None,
                     bound_text: Sequence[str | None] | None = None) -> tuple[dict, list]:
    """Classify fitted parameters; return ``(status, warnings)``.

    Parameters
    ----------
    names, values, stderr, lower, upper : sequences, one entry per parameter
        The fit's variables as the optimiser saw them (``values`` inside ``[lower, upper]``) and the
        standard errors of the reported values.
    fixed : names held fixed (status ``"fixed"``)
    exact_fit : bool
        Zero residual: every standard error is legitimately 0; one warning says so instead.
    positive : names that must be > 0 (a standard error above the value: not identified)
    (any parameter whose standard error exceeds the width of a finite box, :func:`wider_than_box`, is not
    identified: ``stderr`` is compared with ``upper - lower``, so a parameter with a finite box is given in the
    units of its bounds)
    shown : the reported values where they differ from ``values`` (a fit in scaled units)
    atol : per parameter, an absolute tolerance added at its bounds (a floor such as 1e-12)
    bound_text : per parameter, how its lower bound is written for the user (e.g. ``"0"``)

    Returns
    -------
    status : dict
        Per name ``"identified"``, ``"fixed"``, ``"at_lower_bound"``, ``"at_upper_bound"`` or
        ``"not_identified"``.
    warnings : list of str
    """
    shown = values if shown is None else shown
    atol = [0.0] * len(names) if atol is None else atol
    bound_text = [None] * len(names) if bound_text is None else bound_text
    status, warns = {}, []
    for nm, v, sv, se, lo, hi, at, bt in zip(names, values, shown, stderr, lower, upper, atol, bound_text):
        if nm in fixed:
            status[nm] = "fixed"
            continue
        side = at_bound(v, lo, hi, atol=at)
        if side is not None:
            status[nm] = f"at_{side}_bound"
            where = (bt if side == "lower" and bt else f"{lo if side == 'lower' else hi:g}")
            warns.append(f"{nm} = {sv:.4g} is at the {side} bound ({where}) of the fit: the bound, not the data, "
                         "sets it (not identified; its standard error means nothing)")
        elif not np.isfinite(se) or (se == 0.0 and not exact_fit):
            status[nm] = "not_identified"
            warns.append(f"{nm} = {sv:.4g} has a standard error of {se:g}: the data do not determine it "
                         "(not identified)")
        elif wider_than_box(se, lo, hi):
            status[nm] = "not_identified"
            warns.append(f"{nm} = {sv:.4g} has a standard error of {se:.2g}, wider than every value the fit searches "
                         f"({lo:g} to {hi:g}): the data do not narrow it (not identified)")
        elif nm in positive and se > abs(sv):
            status[nm] = "not_identified"
            warns.append(f"{nm} = {sv:.4g} has a standard error of {se:.2g}, larger than the value: the data do not "
                         "determine it (not identified)")
        else:
            status[nm] = "identified"
    if exact_fit:
        warns.append("the fit is exact (zero residual): the standard errors are 0 and say nothing about "
                     "the uncertainty")
    return status, warns
