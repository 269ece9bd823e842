"""Tests of CellParams validation (bad input refused with the field named).

Bounds: W0 >= 4d (Hong et al. 2002: loops jammed at W = 4d), L > 2 C0 + W0 - 4d
(a quarter of the stitch must reach from A to the apex, docs/model.md eq 6),
|phi0| <= phimax = atan(m) (Dusserre 2015 section 3.3.1).
"""
from __future__ import annotations

import math

import pytest

from knitsim.cell.material import CellParams
from knitsim.errors import KnitsimInputError

OK = dict(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7)   # E-glass, Dusserre (2015) Table 1, section 2.2


def test_paper_knit_is_valid_and_phimax():
    p = CellParams(**OK, m=0.2, phi0=math.atan(0.2)).validated()
    assert p.phimax == pytest.approx(math.atan(0.2))


@pytest.mark.parametrize("field,value", [
    ("W0", 4 * 0.58 - 1e-6), ("L", 2 * 2.7 + 4.4 - 4 * 0.58), ("B", -0.31), ("B", 0.0),
    ("d", float("nan")), ("C0", float("inf")), ("m", -0.01), ("phi0", 0.5),
    ("unloading_rule", "hong"), ("reload_rule", "nope"), ("jamming_criterion", "gap"),
    ("friction", "viscous"), ("force_cap_N", 0.0), ("in_plane_width", 0.1), ("in_plane_width", -1.0),
])
def test_bad_field_named_in_message(field, value):
    kw = dict(OK, m=0.2)
    kw[field] = value
    with pytest.raises(KnitsimInputError, match=field):
        CellParams(**kw).validated()


def test_dahl_needs_sigma():
    with pytest.raises(KnitsimInputError, match="dahl_sigma"):
        CellParams(**OK, m=0.2, friction="dahl").validated()


def test_a_dahl_stiffness_beyond_the_coulomb_limit_is_refused_with_what_to_use():
    # a blind probe: sigma = 1e7 1/mm failed on the Warp engine at strain 0.49 (on its first increment at
    # increments of 0.001) while the law there is Coulomb's to 1e-6 N; 1e6 runs a cycle (tests/cell/test_batch)
    CellParams(**OK, m=0.2, friction="dahl", dahl_sigma=1e6).validated()
    with pytest.raises(KnitsimInputError, match=r'dahl_sigma = 10000000.0: above 1e\+06 1/mm the Dahl law is '
                                                r'Coulomb friction .* use friction.model = "coulomb"'):
        CellParams(**OK, m=0.2, friction="dahl", dahl_sigma=1e7).validated()


def test_phi0_at_minus_phimax_accepted():
    CellParams(**OK, m=0.3, phi0=-math.atan(0.3)).validated()


def test_numpy_numbers_are_numbers():
    """np.float32(0.31), np.int64(14) and a 0-d array are finite numbers (refused as "must be a finite number"
    before: a blind probe of the API); read as Python floats, the value kept to its own precision."""
    import numpy as np
    c = CellParams(B=np.float32(0.31), d=0.58, L=np.int64(14), W0=4.4, C0=np.array(2.7), m=0.2, phi0=0.0).validated()
    assert type(c.B) is float and c.B == float(np.float32(0.31)) and c.L == 14.0 and c.C0 == 2.7
    with pytest.raises(KnitsimInputError, match=r"cell.B = nan: must be a finite number"):
        CellParams(B=np.float32("nan"), d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, phi0=0.0).validated()
