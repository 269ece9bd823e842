"""Warp device code of knitsim (shipped as :mod:`knitsim.kernels`).

Only ``@wp.func`` building blocks and ``@wp.kernel`` s live here; Python
orchestration lives in :mod:`knitsim`.  Each function has a float64 NumPy twin
in :mod:`knitsim` that reads like the paper and is its test oracle.

Modules
-------
friction
    Friction laws at a yarn crossing: Howell power law with normal-load and
    velocity sensitivity (Dusserre eqs 2-5), coiling-angle ratio m(theta) (eq 10).
    Twin: :mod:`knitsim.friction.capstan`, :mod:`knitsim.friction.coiling`.
dahl
    Dahl (1976) increment update of a friction state (exact for alpha = 1,
    closed form otherwise).  Twin: :mod:`knitsim.friction.dahl`.
elastica
    The elastica integrals of the quarter stitch (eqs 8-9), singularities
    removed, Gauss-Legendre, with hand-differentiated gradients.
    Twin: :mod:`knitsim.cell.elastica`.
quarter_loop
    Forward map (angles, P -> every quantity, eqs 6-7) with forward-mode
    (dual-number) derivatives.  Twin: :mod:`knitsim.cell.quarter_loop`.
inverse
    Per-cell Newton on four imposed quantities (Table 4 condition sets).
    Twin: :mod:`knitsim.cell.inverse`.
cell_step
    One load increment of a batch of cells: stages, events located by
    condition swapping, Dahl residual, halving retries, status flags.
    Twin: :mod:`knitsim.cell.cycle`.
specialise
    Kernel keys (friction law, effects, jamming criterion): one compiled instance
    of ``cell_step`` per key, the code a key does not use left out (``wp.static``).
centreline
    Quarter-loop centreline points of N cells (USD export).
    Twin: :func:`knitsim.cell.quarter_loop.centreline`.
branch_points, column_trials, backend_trials, state_read
    The patch coupling on the device: each group's branch model and each column's scalar solve, each
    trial's bookkeeping (columns judged, points, bounds, fallback tangents), the backend's slide onsets,
    warm starts and trial tangents, and the packed reads of the states.  Twin: the NumPy lines of
    :mod:`knitsim.patch.coupling`.
"""
