"""The quarter-stitch cell: float64 NumPy/SciPy reference (Dusserre 2015 section 3).

Hong et al. (2002) elastica model of a plain-knit loop with Dusserre's friction
angle phi at the crossing point B.  :mod:`~knitsim.cell.elastica` holds the
integrals of eqs 8-9, :mod:`~knitsim.cell.quarter_loop` the forward map
(angles, force -> every quantity of :mod:`~knitsim.cell.quantities`),
:mod:`~knitsim.cell.inverse` the inverse solve (four imposed quantities of
Table 4 -> state) and :mod:`~knitsim.cell.ode_check` an independent shooting of
the rod equations.  This package is the test oracle of the Warp kernels.
"""
from __future__ import annotations

from knitsim.cell.quantities import CODE, QUANTITY_NAMES, UNKNOWN_NAMES
from knitsim.cell.quarter_loop import (
    QuarterLoop, centreline, closing_force, intrinsic_residual, k1_prime, quarter_loop,
)
from knitsim.cell.inverse import (
    InverseResult, continue_along, initial_state, solve_state,
)
from knitsim.cell.ode_check import OdeShape, integrate_quarter_loop

__all__ = [
    "CODE", "QUANTITY_NAMES", "UNKNOWN_NAMES",
    "QuarterLoop", "quarter_loop", "closing_force", "intrinsic_residual", "k1_prime",
    "centreline",
    "InverseResult", "solve_state", "initial_state", "continue_along",
    "OdeShape", "integrate_quarter_loop",
]
