"""Batched quarter-stitch cells on a Warp device: forward map and inverse solve.

Thin wrappers over the forward kernels of :mod:`knitsim.kernels.inverse` and the cell step's
Newton (``knitsim.kernels.cell_step.solve_conditions_kernel``; eqs 6-9 of Dusserre 2015 in
``knitsim.kernels.quarter_loop`` / ``knitsim.kernels.elastica``): arrays in, one kernel launch,
arrays out; no Python loop over cells.

Per-cell inputs are broadcast MuJoCo-Warp style: each has a leading axis of
length 1 or N (a scalar counts as length 1), and the kernels read
``p[i % p.shape[0]]``.  N is the largest leading length.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import warp as wp

from knitsim import warp_runtime
from knitsim.cell.quantities import CODE, QUANTITY_NAMES
from knitsim.errors import KnitsimInputError

STATUS_MESSAGES = {
    0: "converged",
    1: "iteration cap reached or line search stalled",
    2: "singular Jacobian",
    3: "non-finite residual or Jacobian",
    4: "left the admissible domain (or the guess is outside it)",
}


def _kernels():
    # imported lazily so that ``import knitsim.cell`` does not need Warp initialised
    from knitsim.kernels import inverse

    return inverse


def _as_2d(name: str, value, width: int) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != width or arr.shape[0] < 1:
        raise KnitsimInputError(f"{name}: expected shape ({width},) or (N, {width}), got {np.shape(value)}")
    if not np.all(np.isfinite(arr)):
        bad = arr[~np.isfinite(arr)][0]
        raise KnitsimInputError(f"{name}: values must be finite, got {bad}")
    return np.ascontiguousarray(arr)


def _as_1d_positive(name: str, value) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(value, dtype=np.float64))
    if arr.ndim != 1 or arr.shape[0] < 1:
        raise KnitsimInputError(f"{name}: expected a scalar or shape (N,), got shape {np.shape(value)}")
    bad = arr[~(np.isfinite(arr) & (arr > 0))]
    if bad.size:
        raise KnitsimInputError(f"{name}: must be finite and > 0, got {bad[0]}")
    return np.ascontiguousarray(arr)


def _batch_size(**arrays: np.ndarray) -> int:
    n = max(a.shape[0] for a in arrays.values())
    for name, a in arrays.items():
        if a.shape[0] not in (1, n):
            raise KnitsimInputError(f"{name}: leading length {a.shape[0]} is neither 1 nor the batch size {n}")
    return n


def _codes(conditions) -> np.ndarray:
    """Condition names or codes, shape (4,) or (N, 4) -> int32 codes (N or 1, 4)."""
    rows = [conditions] if (len(conditions) == 4 and all(isinstance(c, (str, int, np.integer)) for c in conditions)) else list(conditions)
    out = np.empty((len(rows), 4), dtype=np.int32)
    for i, row in enumerate(rows):
        row = list(row)
        if len(row) != 4:
            raise KnitsimInputError(f"conditions: each cell needs 4 conditions, got {row!r}")
        for k, c in enumerate(row):
            if isinstance(c, str):
                if c not in CODE:
                    raise KnitsimInputError(f"conditions: unknown quantity {c!r} (known: {', '.join(QUANTITY_NAMES)})")
                out[i, k] = CODE[c]
            else:
                if not 0 <= int(c) < len(QUANTITY_NAMES):
                    raise KnitsimInputError(f"conditions: quantity code {c!r} out of range 0..{len(QUANTITY_NAMES) - 1}")
                out[i, k] = int(c)
        if len(set(out[i].tolist())) != 4:
            raise KnitsimInputError(f"conditions: a quantity is imposed twice in {row!r}")
    return out


def _wp(arr: np.ndarray, device: str, dtype=wp.float64):
    return wp.array(arr, dtype=dtype, device=device)


def forward_batch(x, B, d, device: str = "cpu") -> dict[str, np.ndarray]:
    """Quantities of N quarter stitches from their unknowns (eqs 6-9).

    Parameters
    ----------
    x : array_like, shape (5,) or (N, 5)
        (alpha, beta, gamma, phi, P) [rad, rad, rad, rad, N].
    B : float or array_like, shape (1 or N,)
        Bending stiffness [N mm^2].
    d : float or array_like, shape (1 or N,)
        Yarn diameter [mm].
    device : str
        Warp device (see :func:`knitsim.warp_runtime.resolve_device`).

    Returns
    -------
    dict
        One array of shape (N,) per name of :data:`~knitsim.cell.quantities.QUANTITY_NAMES`,
        plus ``"g"``, the intrinsic residual X_B - X_A - (d/2) sin(beta) [mm] (zero for
        a state of the model).  NaN for cells whose x is outside the admissible domain.
    """
    q, g = _forward(x, B, d, device, jacobian=False)
    out = {name: q[:, k] for k, name in enumerate(QUANTITY_NAMES)}
    out["g"] = g
    return out


def forward_jacobian_batch(x, B, d, device: str = "cpu"):
    """Quantities and their forward-mode derivatives with respect to x.

    Same inputs as :func:`forward_batch`.  Returns ``(q, dq_dx, g, dg_dx)`` with
    shapes (N, n_quantities), (N, n_quantities, 5), (N,), (N, 5); columns of q in
    the order of :data:`~knitsim.cell.quantities.QUANTITY_NAMES`.
    """
    return _forward(x, B, d, device, jacobian=True)


def _forward(x, B, d, device, jacobian):
    warp_runtime.init()
    device = warp_runtime.resolve_device(device)
    x = _as_2d("x", x, 5)
    B = _as_1d_positive("B", B)
    d = _as_1d_positive("d", d)
    n = _batch_size(x=x, B=B, d=d)
    inv = _kernels()
    nq = len(QUANTITY_NAMES)
    q = wp.empty((n, nq), dtype=wp.float64, device=device)
    g = wp.empty(n, dtype=wp.float64, device=device)
    ins = [_wp(x, device), _wp(B, device), _wp(d, device)]
    if not jacobian:
        wp.launch(inv.forward_kernel, dim=n, inputs=ins, outputs=[q, g], device=device)
        return q.numpy(), g.numpy()
    dq = wp.empty((n, nq, 5), dtype=wp.float64, device=device)
    dg = wp.empty((n, 5), dtype=wp.float64, device=device)
    wp.launch(inv.forward_jacobian_kernel, dim=n, inputs=ins, outputs=[q, dq, g, dg], device=device)
    return q.numpy(), dq.numpy(), g.numpy(), dg.numpy()


def solve_batch(
    conditions: Sequence,
    targets,
    B,
    d,
    x_guess,
    device: str = "cpu",
    max_iter: int = 60,
    tol: float = 1e-11,
):
    """Solve N quarter stitches for the unknowns that meet four conditions each.

    Each cell solves g = 0 (eq 6, third line) and ``quantity[conditions[k]] = targets[k]``
    for k = 0..3 (Dusserre 2015 Table 4) by Newton's method with exact forward-mode
    Jacobian and a backtracking line search: the cell step's Newton
    (:func:`knitsim.kernels.cell_step.newton_solve`, in the variables ln(alpha - gamma), beta, R/P,
    phi, ln P, or ln G(0) in place of R/P near the apex edge), without its relaxed floor: converged
    means every scaled residual <= ``tol``.

    Parameters
    ----------
    conditions : sequence of 4 names or codes, or (N, 4) of them
        Quantities imposed, e.g. ``("C", "W", "L", "phi")`` (initial state).
    targets : array_like, shape (4,) or (N, 4)
        Their values [units of :mod:`knitsim.cell.quantities`].
    B, d : float or array_like, shape (1 or N,)
        Bending stiffness [N mm^2] and yarn diameter [mm].
    x_guess : array_like, shape (5,) or (N, 5)
        Starting point (alpha, beta, gamma, phi, P); needs 0 < alpha - gamma < beta - gamma.
    device : str
        Warp device.
    max_iter : int
        Newton iteration cap (the cell step's, 60).
    tol : float
        Convergence when every scaled residual is <= tol (g and lengths over d,
        forces over B/d^2, moment over B/d, angles in rad).

    Returns
    -------
    x : ndarray, shape (N, 5)
        Solution, or the last admissible iterate where status != 0.
    status : ndarray of int32, shape (N,)
        0 converged; otherwise see :data:`STATUS_MESSAGES`.
    iterations : ndarray of int32, shape (N,)
        Newton steps taken.
    """
    warp_runtime.init()
    device = warp_runtime.resolve_device(device)
    codes = _codes(conditions)
    targets = _as_2d("targets", targets, 4)
    x_guess = _as_2d("x_guess", x_guess, 5)
    B = _as_1d_positive("B", B)
    d = _as_1d_positive("d", d)
    if int(max_iter) < 0:
        raise KnitsimInputError(f"max_iter: must be >= 0, got {max_iter}")
    if not (np.isfinite(tol) and tol > 0):
        raise KnitsimInputError(f"tol: must be finite and > 0, got {tol}")
    n = _batch_size(conditions=codes, targets=targets, x_guess=x_guess, B=B, d=d)
    from knitsim.kernels.specialise import INIT_KEY, cell_step_module

    x_out = wp.empty((n, 5), dtype=wp.float64, device=device)
    status = wp.empty(n, dtype=wp.int32, device=device)
    iters = wp.empty(n, dtype=wp.int32, device=device)
    wp.launch(
        cell_step_module(INIT_KEY).solve_conditions_kernel,
        dim=n,
        inputs=[_wp(codes, device, wp.int32), _wp(targets, device), _wp(B, device), _wp(d, device),
                _wp(x_guess, device), int(max_iter), float(tol)],
        outputs=[x_out, status, iters],
        device=device,
    )
    return x_out.numpy(), status.numpy(), iters.numpy()
