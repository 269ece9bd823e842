"""Inverse solve of the quarter stitch: four imposed quantities -> state (Dusserre 2015 section 3.3).

Unknowns (alpha, beta, gamma, phi, P).  Equations: the intrinsic condition
``g = X_B - X_A - (d/2) sin(beta) = 0`` (eq 6, third line), which every state
satisfies, plus four imposed quantities ``{name: target}`` (Table 4, e.g. the
initial state {C, W, L, phi}).

Newton's method works in ``z = (ln(alpha - gamma), beta, R/P, phi, ln P)``:
``alpha - gamma`` falls toward 1e-7 at high load and must stay positive (the
elastica of AB needs it, :mod:`knitsim.cell.elastica`), and P > 0.  R/P
replaces gamma (``sin gamma = -(R/P) cos(beta + phi)``, eq 7): with gamma as the
unknown, R = -P sin(gamma)/cos(beta + phi) and k1' are 0/0 where the contact
force is horizontal (beta + phi = pi/2) at zero force per wale (gamma = 0), a
state every unloading passes near (phi goes from +phimax to -phimax).  The
Jacobian is a central finite difference in float64 (all 11 states evaluated in
one vectorised call); the step is damped by backtracking.  When Newton fails,
``scipy.optimize.least_squares`` (trust region) takes over from the guess.

The paper used Matlab's fminsearch on the same conditions (section 3.3.1).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np
from scipy.optimize import least_squares

from knitsim.cell.quantities import QUANTITY_NAMES, UNKNOWN_NAMES
from knitsim.cell.head_gap import head_gap_of
from knitsim.cell.quarter_loop import QuarterLoop, closing_force, quarter_loop
from knitsim.errors import KnitsimInputError, require

_ANGLES = {"alpha", "beta", "gamma", "phi"}
_LENGTHS = {"W", "C", "L", "s_AB", "s_BC", "X_A", "X_B", "Y_B", "Y_C", "head_gap"}
#: conditions besides the quantities of the forward map: the centreline gap between the heads of
#: neighbouring loops (knitsim.cell.head_gap), imposed by jamming by contact
EXTRA_CONDITIONS = ("head_gap",)
_FORCES = {"P", "T", "R", "Rn", "Rt", "F"}


@dataclass
class InverseResult:
    """Outcome of an inverse solve, in the manner of scipy's ``OptimizeResult``.

    Attributes
    ----------
    x : ndarray
        ``(alpha, beta, gamma, phi, P)`` [rad, N].
    state : QuarterLoop
        Every quantity at ``x``.
    success : bool
    status : int
        0 Newton converged, 1 fallback converged, 2 Newton stalled at the residuals' rounding floor below
        ``tol_stalled`` (converged), -1 failed.
    message : str
    nit : int
        Newton iterations (plus fallback evaluations when it ran).
    residual_norm : float
        Euclidean norm of the scaled residuals (g/d and (Q - target)/scale).
    conditions : dict
        The four imposed quantities.
    method : str
        ``"newton"`` or ``"least_squares"``.
    """

    x: np.ndarray
    state: QuarterLoop
    success: bool
    status: int
    message: str
    nit: int
    residual_norm: float
    conditions: dict[str, float]
    method: str
    extra: dict[str, Any] = field(default_factory=dict)

    def unknowns(self) -> dict[str, float]:
        """``{alpha, beta, gamma, phi, P}`` as floats."""
        return {n: float(v) for n, v in zip(UNKNOWN_NAMES, self.x)}


#: the reference's load steps (knitsim.cell.cycle): a Newton that stalls (its line search finds no decrease:
#: the residual is at its rounding floor) or reaches its iteration cap with its residual norm at or below this
#: has converged.  On a jammed branch at high load (alpha - gamma ~ 1e-6) the residuals' rounding floor, 2.3e-12,
#: lies above ``tol`` (1e-12): the solve was halved down to failure, and the reference lost the jammed branch at
#: 30-49 B / d^2, below the default force cap, in 13 of 30 random domain cells.  Not for the rest state (Table
#: 4's initial state, solved to ``tol``): a rest state at its floor (a tight loop, L ratio 1.775 at d = 0.1,
#: B = 10, W0 = 5.5 d, C0 = 4 d: 8e-12) is one whose loading this engine cannot follow (its first increment
#: failed after 37 s), refused before any work with the Warp engine named.  Not the
#: Warp engine's 1e-9 (kernels.cell_step.NEWTON_TOL_STALLED, a max norm): where the floor reaches 1e-10
#: (alpha - gamma ~ 1e-7, the jammed force near its asymptote) this engine's states are already ~1e-7 off in F,
#: and accepting them there let its sub-steps crawl (~1e-9 mm each, 6,000 solves, 320 s) toward an asymptote
#: it cannot resolve; the Newton of the Warp engine, in ln(alpha - gamma), follows it to the cap.
TOL_STALLED = 1.0e-10
#: a stalled Newton whose residual norm is at or below this is at the residuals' rounding floor (see solve_state)
STALL_NEAR_ROOT = 1.0e-6


def _scale(name: str, target: float, B: float, d: float) -> float:
    """Residual scale: natural unit of the quantity (angles 1, lengths d, forces B/d^2)."""
    if name in _ANGLES:
        return 1.0
    if name in _LENGTHS:
        return max(abs(target), d)
    if name in _FORCES:
        return max(abs(target), B / d ** 2)
    return max(abs(target), B / d)                        # moment M


def _check_conditions(conditions: Mapping[str, float]) -> dict[str, float]:
    require(len(conditions) == 4,
            f"conditions: exactly four imposed quantities needed, got {len(conditions)} "
            f"({', '.join(conditions)})")
    out = {}
    for name, target in conditions.items():
        require(name in QUANTITY_NAMES or name in EXTRA_CONDITIONS,
                f"conditions: unknown quantity {name!r}; known: {', '.join(QUANTITY_NAMES + EXTRA_CONDITIONS)}")
        t = float(target)
        require(np.isfinite(t), f"conditions[{name}] = {target!r} is not a finite number")
        out[name] = t
    return out


def _check_bd(B: float, d: float) -> None:
    require(np.isfinite(B) and B > 0.0, f"B = {B!r}: bending stiffness must be > 0 N mm^2")
    require(np.isfinite(d) and d > 0.0, f"d = {d!r}: yarn diameter must be > 0 mm")


def _as_x(guess) -> np.ndarray:
    """Unknown vector from an InverseResult, a QuarterLoop, a dict or a sequence."""
    if isinstance(guess, InverseResult):
        return np.array(guess.x, dtype=np.float64)
    if isinstance(guess, QuarterLoop):
        return np.array([float(getattr(guess, n)) for n in UNKNOWN_NAMES])
    if isinstance(guess, Mapping):
        return np.array([float(guess[n]) for n in UNKNOWN_NAMES])
    x = np.asarray(guess, dtype=np.float64).reshape(-1)
    require(x.size == 5, f"guess: five unknowns {UNKNOWN_NAMES} needed, got {x.size}")
    return x


def _to_z(x: np.ndarray) -> np.ndarray:
    alpha, beta, gamma, phi, p = x
    rho = -np.sin(gamma) / np.cos(beta + phi)
    return np.array([np.log(max(alpha - gamma, 1e-300)), beta, rho, phi, np.log(p)])


def _states(z: np.ndarray, B: float, d: float) -> QuarterLoop:
    """States at the rows of ``z`` (shape (..., 5)); NaN where |sin gamma| > 1."""
    a = np.exp(z[..., 0])
    beta, rho, phi = z[..., 1], z[..., 2], z[..., 3]
    sin_g = -rho * np.cos(beta + phi)
    gamma = np.arcsin(np.where(np.abs(sin_g) <= 1.0, sin_g, np.nan))
    return quarter_loop(gamma + a, beta, gamma, phi, np.exp(z[..., 4]), B, d, a=a, rho=rho)


def _residuals(st: QuarterLoop, cond: dict[str, float], scales: dict[str, float], d: float, B: float, a):
    def value(n):
        return head_gap_of(st, B, a=a) if n == "head_gap" else st.quantity(n)

    cols = [st.g / d] + [(value(n) - t) / scales[n] for n, t in cond.items()]
    return np.stack(cols, axis=-1)


def solve_state(conditions: Mapping[str, float], guess, B: float, d: float, *,
                tol: float = 1e-12, max_iter: int = 60, fallback: bool = True,
                fd_step: float = 1e-6, tol_stalled: float = 0.0) -> InverseResult:
    """Find (alpha, beta, gamma, phi, P) with g = 0 and the four ``conditions``.

    Parameters
    ----------
    conditions : mapping
        Four ``{name: target}`` with names from :data:`QUANTITY_NAMES`
        (units N, mm, rad), e.g. ``{"C": 2.7, "W": 4.4, "L": 14.1, "phi": 0.0}``.
    guess : InverseResult, QuarterLoop, mapping or sequence
        Initial ``(alpha, beta, gamma, phi, P)``.
    B, d : float
        Bending stiffness [N mm^2] and yarn diameter [mm].
    tol : float
        Convergence threshold on the norm of the scaled residuals.
    max_iter : int
        Newton iterations before the fallback.
    fallback : bool
        Try ``scipy.optimize.least_squares`` when Newton fails (with ``tol_stalled`` > 0, not when it stalled
        within :data:`STALL_NEAR_ROOT` of the root: its rounding floor).
    fd_step : float
        Central-difference step in z.
    tol_stalled : float
        A Newton that stalls (its line search finds no decrease) or reaches ``max_iter`` with its residual
        norm at or below this has converged to the residuals' rounding floor (``status`` 2; at high load,
        alpha - gamma ~ 1e-6, that floor lies above ``tol``).  0 (default) asks for ``tol`` or the
        fallback; the reference's load steps pass :data:`TOL_STALLED`.
    """
    _check_bd(B, d)
    cond = _check_conditions(conditions)
    scales = {n: _scale(n, t, B, d) for n, t in cond.items()}
    x0 = _as_x(guess)
    require(x0[0] > x0[2], f"guess: alpha = {x0[0]!r} must exceed gamma = {x0[2]!r}")
    require(x0[4] > 0.0, f"guess: P = {x0[4]!r} must be > 0 N")
    z = _to_z(x0)

    def res(zz):
        return _residuals(_states(zz, B, d), cond, scales, d, B, np.exp(zz[..., 0]))

    r = res(z)
    norm = float(np.linalg.norm(r)) if np.all(np.isfinite(r)) else np.inf
    nit = 0
    stalled = False
    # Newton with the central-difference Jacobian; when its line search stalls, once more with a
    # 100 times smaller difference step (the Jacobian of a state next to a fold, or where a step
    # of fd_step leaves the smooth part of the map, is off by more than the Newton step can bear)
    for h in (fd_step, 0.01 * fd_step):
        eye = np.eye(5) * h
        while nit < max_iter and norm > tol:
            nit += 1
            pts = np.concatenate([z + eye, z - eye])            # 10 states in one call
            rr = res(pts)
            jac = ((rr[:5] - rr[5:]) / (2.0 * h)).T
            if not np.all(np.isfinite(jac)):
                break
            try:
                step = np.linalg.solve(jac, -r)
            except np.linalg.LinAlgError:
                step = np.linalg.lstsq(jac, -r, rcond=None)[0]
            # keep angle steps moderate: the map is only locally smooth
            big = np.max(np.abs(step[[1, 3]]))
            if big > 0.3:
                step *= 0.3 / big
            t = 1.0
            while t > 1e-6:
                zt = z + t * step
                rt = res(zt)
                nt = float(np.linalg.norm(rt)) if np.all(np.isfinite(rt)) else np.inf
                if nt < (1.0 - 1e-4 * t) * norm or (nt < 10 * tol and nt <= norm):
                    break
                t *= 0.5
            else:
                stalled = True
                break
            z, r, norm = zt, rt, nt
        if norm <= tol or not np.isfinite(norm):
            break
    method = "newton"
    status = 0
    at_floor = not norm <= tol and norm <= tol_stalled and (stalled or nit >= max_iter)
    # where a floor is accepted (the load steps), a Newton stalled within STALL_NEAR_ROOT of the root is at
    # its residuals' rounding floor, which the trust region cannot go below either: the fallback is not tried
    # (on a jammed branch at alpha - gamma ~ 1e-7, floor 4e-9, each of its 2,000 evaluations failed, 1.5 s
    # a sub-step); the other callers (rest states, continuations) keep it
    near_root = tol_stalled > 0.0 and (stalled or nit >= max_iter) and norm <= STALL_NEAR_ROOT
    if at_floor:
        method = "newton (rounding floor)"
        status = 2
    elif not norm <= tol and fallback and not near_root:
        method = "least_squares"
        status = 1

        def fun(zz):
            v = res(zz)
            return np.where(np.isfinite(v), v, 1e3)

        ls = least_squares(fun, z, method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15,
                           max_nfev=2000)
        nit += int(ls.nfev)
        r_ls = res(ls.x)
        n_ls = float(np.linalg.norm(r_ls)) if np.all(np.isfinite(r_ls)) else np.inf
        if n_ls < norm:
            z, r, norm = ls.x, r_ls, n_ls
    success = bool(norm <= tol) or at_floor
    if not success:
        status = -1
    state = _states(z, B, d)
    x = np.array([float(getattr(state, n)) for n in UNKNOWN_NAMES])
    msg = (f"converged ({method}), |residual| = {norm:.2e}" if success
           else f"not converged after {nit} iterations, |residual| = {norm:.2e}")
    return InverseResult(x=x, state=state, success=success, status=status, message=msg,
                         nit=nit, residual_norm=norm, conditions=cond, method=method)


def check_knit(C0: float, W0: float, L: float, phi0: float, B: float, d: float) -> None:
    """Raise :class:`KnitsimInputError` for a knit that cannot form a quarter stitch.

    ``W0 >= 4 d`` (Hong's jamming limit: neighbouring heads touch at W = 4d);
    ``L / 4 > C0 / 2 + W0 / 4 - d``: the yarn goes from A = (W/4, 0) to within
    d/2 of S = (W/4, C/2) and on to the axis X = 0, so a quarter of the stitch
    length must exceed ``(C/2 - d/2) + (W/4 - d/2)`` to close the loop.
    """
    _check_bd(B, d)
    for name, v in (("C0", C0), ("W0", W0), ("L", L), ("phi0", phi0)):
        require(np.isfinite(v), f"{name} = {v!r} is not a finite number")
    require(C0 > 0.0, f"C0 = {C0!r}: course length must be > 0 mm")
    require(W0 >= 4.0 * d, f"W0 = {W0!r}: wale width must be >= 4 d = {4.0 * d!r} mm "
                           f"(jammed loops, Hong's W = 4d)")
    lmin = 2.0 * C0 + W0 - 4.0 * d
    require(L > lmin, f"L = {L!r}: stitch length too short to close a loop "
                      f"(needs > 2 C0 + W0 - 4 d = {lmin!r} mm)")
    require(abs(phi0) < 0.5 * np.pi, f"phi0 = {phi0!r}: friction angle must lie in (-pi/2, pi/2)")


#: guesses (alpha, beta, gamma) tried by :func:`initial_state`, P from g = 0
DEFAULT_STARTS: tuple[tuple[float, float, float], ...] = tuple(
    (al, al + db, ga)
    for al in (0.9, 1.2, 1.5)
    for db in (0.2, 0.5, 0.9)
    for ga in (0.0, 0.1, 0.3, 0.6)
    if al + db < np.pi and ga < al
)


def initial_state(C0: float, W0: float, L: float, phi0: float, B: float, d: float, *,
                  starts: Sequence[Sequence[float]] | None = None,
                  phi_step: float = 0.05) -> InverseResult:
    """Initial state of Table 4: C = C0, W = W0, L, phi = phi0.

    Multistart at phi = 0 from ``starts`` (alpha, beta, gamma) with P from the
    intrinsic condition (:func:`closing_force`), then continuation in phi from 0 to
    ``phi0``.  ``result.extra`` holds ``"starts"`` (each start and whether it
    converged, and to which of the solutions) and ``"solutions"`` (the distinct
    (alpha, beta, gamma, phi, P) found at phi = 0).  With the paper's two knits
    every converging default start reaches the same single state.
    """
    check_knit(C0, W0, L, phi0, B, d)
    starts = DEFAULT_STARTS if starts is None else tuple(tuple(s) for s in starts)
    cond0 = {"C": C0, "W": W0, "L": L, "phi": 0.0}
    record = []
    solutions: list[InverseResult] = []
    for al, be, ga in starts:
        p = float(closing_force(al, be, ga, 0.0, B, d))
        if not np.isfinite(p):
            record.append({"start": (al, be, ga), "converged": False, "solution": None,
                           "why": "no P closes g = 0 at this start"})
            continue
        res = solve_state(cond0, (al, be, ga, 0.0, p), B, d, fallback=False)
        idx = None
        if res.success:
            for i, sol in enumerate(solutions):
                if np.allclose(sol.x, res.x, rtol=1e-7, atol=1e-9):
                    idx = i
                    break
            else:
                solutions.append(res)
                idx = len(solutions) - 1
        record.append({"start": (al, be, ga), "converged": res.success, "solution": idx,
                       "why": res.message})
    if not solutions:
        raise RuntimeError("initial_state: no start converged; pass starts=...")
    best = solutions[0]
    if phi0 != 0.0:
        path = continue_along(cond0, "phi", 0.0, phi0, best, B, d,
                              n_steps=max(1, int(np.ceil(abs(phi0) / phi_step))))
        if path:                # empty when phi0 is within rounding of 0 (nothing to continue)
            best = path[-1]
    best.extra["starts"] = record
    best.extra["solutions"] = [s.x for s in solutions]
    return best


def continue_along(conditions: Mapping[str, float], name: str, start: float, stop: float,
                   guess, B: float, d: float, *, n_steps: int = 10,
                   max_halvings: int = 8) -> list[InverseResult]:
    """Step the target of ``name`` from ``start`` to ``stop``, re-using each solution.

    The other three conditions keep their targets.  A failed step is halved (up
    to ``max_halvings`` times); the list holds one converged result per accepted
    value, ending at ``stop``, or ends with the failed result.
    """
    cond = dict(_check_conditions(conditions))
    require(name in cond, f"continue_along: {name!r} is not one of the conditions {list(cond)}")
    require(n_steps >= 1, f"n_steps = {n_steps!r} must be >= 1")
    x = _as_x(guess)
    out: list[InverseResult] = []
    value = float(start)
    h = (float(stop) - value) / n_steps
    halvings = 0
    while (stop - value) * np.sign(h) > 1e-14 * max(1.0, abs(stop)):
        nxt = value + h
        if (stop - nxt) * np.sign(h) < 0.0:
            nxt = float(stop)
        cond[name] = nxt
        res = solve_state(cond, x, B, d)
        if res.success:
            out.append(res)
            x = res.x
            value = nxt
        else:
            halvings += 1
            if halvings > max_halvings:
                out.append(res)
                break
            h *= 0.5
    return out
