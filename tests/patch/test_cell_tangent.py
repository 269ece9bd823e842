"""The cell tangent dF/dC of the patch coupling (implicit function theorem on the cell Newton's
Jacobian, kernels/cell_tangent.py) against an independent method: finite differences of the cell's
own force along its branch, from trial steps of the cell kernel (second-order one-sided stencil
(-3 F_0 + 4 F_1 - F_2) / (2 h), whose error is O(h^2) ~ 1e-8 relative here)."""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.cell.material import CellParams
from knitsim.cell.stages import Stage
from knitsim.patch.coupling import WarpBackend

# Table 1 / section 2.2 / section 3.4 (dusserre2015.toml), phi0 off zero as in a random patch
P = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, phi0=0.05, force_cap_N=10.0)


def _state_at(strains):
    be = WarpBackend([P] * 3)
    for i, e in enumerate(strains):
        be.begin_increment()
        be.trial(np.full(3, e), 1, i)
        be.accept(np.ones(3, bool))
        be.end_increment()
    return be


def _fd_slope(be, direction, h):
    C0 = be.committed()["C"][0]
    F0 = be.committed()["F"][0]
    Cs = C0 + direction * h * np.array([1.0, 2.0, 2.0])
    t = be.trial(Cs / P.C0 - 1.0, direction, 99)
    F1, F2 = t["F"][0], t["F"][1]
    return direction * (-3.0 * F0 + 4.0 * F1 - F2) / (2.0 * h), t


@pytest.mark.parametrize("direction", [1, -1])
def test_cell_tangent_is_the_slope_of_the_branch(direction):
    # loading to strain 0.3 slides (S+); a reversal there enters the stick branch SF-
    be = _state_at(np.arange(0.01, 0.305, 0.01))
    assert be.committed()["stage"][0] == int(Stage.S_LOAD)
    k = be.tangent(False, direction)[0]
    fd, t = _fd_slope(be, direction, 1e-5)
    assert np.all(t["status"] == 0)
    assert t["stage"][0] == (int(Stage.S_LOAD) if direction > 0 else int(Stage.SF_UNLOAD))
    assert k > 0
    np.testing.assert_allclose(k, fd, rtol=1e-5)
    # the stick branch is much stiffer than the sliding one (Table 4: beta frozen)
    if direction < 0:
        assert k > 5.0 * be.tangent(False, 1)[0]


def test_cell_tangent_at_a_trial_end_and_where_undefined():
    be = _state_at(np.arange(0.01, 0.105, 0.01))
    C = be.committed()["C"][0] + np.array([1e-3, 1e-3 + 1e-5, 1e-3 + 2e-5])
    be.trial(C / P.C0 - 1.0, 1, 50)
    k = be.tangent(True)
    t = be.trial(C[[0, 1, 2]] / P.C0 - 1.0, 1, 50)
    fd = (-3.0 * t["F"][0] + 4.0 * t["F"][1] - t["F"][2]) / (2.0 * 1e-5)
    np.testing.assert_allclose(k[0], fd, rtol=1e-5)
    # a Dahl cell has no IFT tangent here (NaN: the coupling keeps its secant)
    bd = WarpBackend([P.replace(friction="dahl", dahl_sigma=30.0)])
    assert np.isnan(bd.tangent(False, 1)[0])
