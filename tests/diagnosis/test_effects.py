"""The diagnosis' effect variables (knitsim.diagnosis.effects).

The rest state's crossing angle is solved by Newton from the nearest rest state solved
before (fast); the expected value comes from the independent multistart of
knitsim.cell.inverse.initial_state at each geometry (the paper's knits have one rest state).
"""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.cell.inverse import initial_state
from knitsim.diagnosis import effects
from knitsim.diagnosis.synthetic import material_params


@pytest.mark.parametrize("material", ["e_glass", "basalt"])
def test_warm_started_rest_beta_equals_the_multistart_solution(material):
    b = material_params(material)
    effects._REST_CACHE.clear()
    rng = np.random.default_rng(7)
    for _ in range(6):
        f = 1.0 + 0.02 * rng.standard_normal(3)
        g = (b.B, b.d * f[0], b.L * f[1], b.W0, b.C0 * f[2])
        ref = initial_state(g[4], g[3], g[2], 0.0, g[0], g[1])
        assert effects.rest_beta(*g) == pytest.approx(float(ref.x[1]), abs=1e-10)
    assert len(effects._REST_CACHE) == 6
