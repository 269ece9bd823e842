"""Material library vs the numbers printed in Dusserre (2015): Table 1, Table 3, sections 2.2 and 3.4."""
from __future__ import annotations

import pytest

from knitsim import materials
from knitsim.errors import KnitsimInputError

# (d [mm], B [N mm^2]) Table 1; (b, p, n) Table 3; mu_k, mean coiling angle [deg], m: section 3.4
YARNS = {
    "e_glass": dict(d=0.58, B=0.31, friction_b=0.159, friction_p=0.0246, friction_n=0.948,
                    mu_k=0.156, coiling_angle_deg=110.0, m=0.20),
    "basalt": dict(d=0.56, B=0.20, friction_b=0.137, friction_p=0.0, friction_n=0.909,
                   mu_k=0.137, coiling_angle_deg=106.0, m=0.17),
}
# section 2.2: stitch length L, wale width W0 and course length C0 [mm]
KNITS = {"e_glass_plain": dict(yarn="e_glass", L=14.1, W0=4.4, C0=2.7),
         "basalt_plain": dict(yarn="basalt", L=13.1, W0=4.4, C0=2.7)}


@pytest.mark.parametrize("name", sorted(YARNS))
def test_yarn_values_are_the_papers(name):
    y = materials.yarn(name)
    for key, value in YARNS[name].items():
        assert getattr(y, key) == value, key
    assert "Table 1" in y.source and "Table 3" in y.source


@pytest.mark.parametrize("name", sorted(KNITS))
def test_knit_values_are_the_papers(name):
    k = materials.knit(name)
    for key, value in KNITS[name].items():
        assert getattr(k, key) == value, key
    assert "section 2.2" in k.source


def test_names():
    assert materials.yarn_names() == ["basalt", "e_glass"]
    assert materials.knit_names() == ["basalt_plain", "e_glass_plain"]


def test_unknown_names_list_the_known_ones():
    with pytest.raises(KnitsimInputError, match=r'^yarn.material = \'kevlar\': unknown yarn \(known: basalt, e_glass\)$'):
        materials.yarn("kevlar")
    with pytest.raises(KnitsimInputError, match=r"^cells\[1\].knit.material = 'rib'.*known: basalt_plain, e_glass_plain"):
        materials.knit("rib", "cells[1].knit.material")


def test_library_knits_are_admissible_cells():
    # W0 >= 4 d (Hong 2002) and L > 2 C0 + W0 - 4 d (a loop closes): section 3.1 geometry
    for k in KNITS:
        kn = materials.knit(k)
        y = materials.yarn(kn.yarn)
        assert kn.W0 >= 4 * y.d and kn.L > 2 * kn.C0 + kn.W0 - 4 * y.d
