"""Cost of the quarter-stitch forward map and of the batched load cycle (one CPU core).

Two numbers, both after compilation:

1. microseconds per forward + Jacobian evaluation (``kernels.inverse.forward_kernel``,
   which carries the forward-mode gradient) on states collected from load cycles and
   a monotonic stretch to high load (alpha - gamma down to ~1e-8);
2. cell-increments per second of :func:`knitsim.cell.batch.run_batch` for the E-glass
   cell (Table 1, m = 0.2, force cap 5 N) on a monotonic stretch to 0.6 and on the
   paper's 3 cycles 0.10-0.60 (increment 0.01).

``--save PATH`` stores the forward values and Jacobians at the collected states,
``--compare PATH`` prints the largest relative difference to a stored run (how the
node tables in kernels/elastica.py were chosen).  Not a test.

    python benchmarks/bench_kernels.py [--cells 200] [--save base.npz | --compare base.npz]
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import warp as wp

from knitsim import warp_runtime
from knitsim.cell import warp_solve
from knitsim.cell.batch import run_batch
from knitsim.cell.load_program import cycles, monotonic
from knitsim.cell.material import CellParams

E_GLASS = dict(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7)  # dusserre2015.toml, Table 1 / section 2.2
BASALT = dict(B=0.20, d=0.56, L=13.1, W0=4.4, C0=2.7)


def collect_states() -> np.ndarray:
    """(alpha, beta, gamma, phi, P, B, d) of converged states along cycles and a high-load stretch."""
    rows = []
    runs = [
        ([CellParams(**E_GLASS, m=m, force_cap_N=5.0, unloading_rule=r)
          for m in (0.0, 0.2, 0.4) for r in ("dusserre", "hong_constant_t")], cycles(0.10, 0.60, 3, 0.01)),
        ([CellParams(**E_GLASS, m=0.2, force_cap_N=200.0), CellParams(**BASALT, m=0.3, force_cap_N=200.0)],
         monotonic(0.75, 0.005)),
    ]
    for ps, prog in runs:
        h = run_batch(ps, prog)
        for i, p in enumerate(ps):
            X = np.stack([h.values[k][:, i] for k in ("alpha", "beta", "gamma", "phi", "P")], axis=1)
            ok = np.isfinite(X).all(axis=1) & (h.status[:, i] == 0) & (X[:, 4] > 0)
            rows.append(np.column_stack([X[ok], np.full(ok.sum(), p.B), np.full(ok.sum(), p.d)]))
    return np.concatenate(rows)


def time_forward(S: np.ndarray, repeat: int = 5) -> float:
    """Best-of-``repeat`` microseconds per forward evaluation (values + gradients)."""
    from knitsim.kernels import inverse

    reps = max(1, 30000 // len(S))
    X = np.tile(S[:, :5], (reps, 1))
    n = len(X)
    x = wp.array(X, dtype=wp.float64)
    B = wp.array(np.tile(S[:, 5], reps), dtype=wp.float64)
    d = wp.array(np.tile(S[:, 6], reps), dtype=wp.float64)
    q = wp.empty((n, 20), dtype=wp.float64)
    g = wp.empty(n, dtype=wp.float64)
    wp.launch(inverse.forward_kernel, dim=n, inputs=[x, B, d], outputs=[q, g])
    wp.synchronize()
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        wp.launch(inverse.forward_kernel, dim=n, inputs=[x, B, d], outputs=[q, g])
        wp.synchronize()
        best = min(best, time.perf_counter() - t0)
    return best / n * 1e6


def throughput(n_cells: int) -> dict:
    """Cell-increments per second of run_batch (E-glass, m = 0.2, cap 5 N), no cell failing."""
    ps = [CellParams(**E_GLASS, m=0.2, phi0=0.0, force_cap_N=5.0, unloading_rule="hong_constant_t")] * n_cells
    out = {}
    for name, prog in [("monotonic 0-0.6", monotonic(0.6, 0.01)), ("3 cycles 0.1-0.6", cycles(0.1, 0.6, 3, 0.01))]:
        run_batch(ps[:2], prog)  # compile
        t0 = time.perf_counter()
        h = run_batch(ps, prog)
        dt = time.perf_counter() - t0
        out[name] = dict(increments=len(prog), rate=n_cells * len(prog) / dt,
                         status=np.bincount(h.status[-1], minlength=4).tolist())
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=200)
    ap.add_argument("--save", default=None)
    ap.add_argument("--compare", default=None)
    a = ap.parse_args(argv)
    warp_runtime.init()
    S = collect_states()
    q, dq, g, dg = warp_solve.forward_jacobian_batch(S[:, :5], S[:, 5], S[:, 6])
    V = np.concatenate([q, g[:, None]], axis=1)
    J = np.concatenate([dq, dg[:, None, :]], axis=1)
    print(f"{len(S)} states, alpha - gamma in [{(S[:, 0] - S[:, 2]).min():.1e}, {(S[:, 0] - S[:, 2]).max():.2f}],"
          f" P up to {S[:, 4].max():.2f} N")
    if a.save:
        np.savez(a.save, S=S, V=V, J=J)
    if a.compare:
        base = np.load(a.compare)
        if base["S"].shape == S.shape and np.array_equal(base["S"], S):
            V0, J0 = base["V"], base["J"]
        else:  # the states moved with the code: evaluate at the stored ones
            q, dq, g, dg = warp_solve.forward_jacobian_batch(base["S"][:, :5], base["S"][:, 5], base["S"][:, 6])
            V0, J0 = base["V"], base["J"]
            V = np.concatenate([q, g[:, None]], axis=1)
            J = np.concatenate([dq, dg[:, None, :]], axis=1)
        ev = np.nanmax(np.abs(V - V0) / np.maximum(np.abs(V0), 1.0))
        ej = np.nanmax(np.abs(J - J0) / (np.abs(J0).max(axis=2, keepdims=True) + 1e-300))
        print(f"max relative difference to {a.compare}: values {ev:.2e}, Jacobian {ej:.2e} (row-scaled)")
    print(f"forward + gradient: {time_forward(S):.2f} us per evaluation")
    for name, r in throughput(a.cells).items():
        print(f"{name:>18}: {r['increments']} increments x {a.cells} cells: {r['rate']:.0f} cell-increments/s,"
              f" status {r['status']}")


if __name__ == "__main__":
    main()
