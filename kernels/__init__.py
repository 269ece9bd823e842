"""Warp device code of knitsim (shipped as :mod:`knitsim.kernels`).

Only ``@wp.func`` building blocks and ``@wp.kernel`` s live here; Python
orchestration lives in :mod:`knitsim`.  Each function has a float64 NumPy twin
in :mod:`knitsim` that reads like the paper and is its test oracle.

Modules
-------
friction
    Friction laws at a yarn crossing: Howell power law (Dusserre eqs 2-5),
    coiling-angle ratio m(theta) (eq 10), Dahl update (Dahl 1976).
"""
