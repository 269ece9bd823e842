"""Tests of the Dusserre (2015) study module: structure and definitions only.

The paper's claims are a reported table (``knitsim study dusserre2015``),
never asserted here.  Checked: every claim (a)-(e) of dusserre2015.toml
[claims] has rows, numbers are finite where defined, figures are written, and the E-glass cell is Table 1 / section 2.2.
Every claim row carries a verdict (reproduced / partly / not reproduced) and why.
"""
from __future__ import annotations

import math

import pytest

from knitsim.data import dusserre2015
from knitsim.errors import KnitsimInputError
from knitsim.studies import dusserre2015 as study


def test_eglass_cell_is_table_1():
    d = dusserre2015()
    p = study.eglass(m=0.2)
    assert (p.B, p.d, p.L, p.W0, p.C0) == (d["yarn"]["e_glass"]["bending_stiffness_N_mm2"],
                                           d["yarn"]["e_glass"]["yarn_diameter_mm"],
                                           d["knit"]["stitch_length_mm"]["e_glass"],
                                           d["knit"]["wale_width_mm"], d["knit"]["course_length_mm"])


@pytest.mark.parametrize("kw", [dict(force_cut="3P"), dict(increment=0.0), dict(increment=float("nan"))])
def test_bad_variant_refused(kw):
    with pytest.raises(KnitsimInputError):
        study.run(**kw)


@pytest.mark.slow
def test_study_table_has_every_claim(tmp_path):
    res = study.run(increment=0.05)
    claims = {r["claim"] for r in res["rows"]}
    assert claims == {"a", "b", "c", "d", "e"}
    rules = {r["unloading_rule"] for r in res["rows"] if r["claim"] == "e"}
    assert rules == {"dusserre", "hong_constant_t"}
    for r in res["rows"]:
        if isinstance(r["ours"], float) and r["claim"] in "bd":
            assert math.isfinite(r["ours"])
        assert r["verdict"] in (study.REPRODUCED, study.PARTLY, study.NOT_REPRODUCED, study.CONTEXT)
        assert r["why"]
        assert (r["verdict"] == study.CONTEXT) == (r["paper"] is None)
    paths = study.figures(res, tmp_path)
    assert all(p.exists() and p.stat().st_size > 0 for p in paths)


@pytest.mark.parametrize("paper, ours, verdict", [
    (0.2, 0.2, study.REPRODUCED),          # identity
    (0.2, 0.24, study.REPRODUCED),         # within 25 %
    (0.2, 0.35, study.PARTLY),             # same sign, factor 1.75
    (-0.04, 0.73, study.NOT_REPRODUCED),   # opposite sign
    (5.0, 0.167, study.NOT_REPRODUCED),    # factor 30
    (0.15, float("nan"), study.NOT_REPRODUCED),
])
def test_numeric_verdict_limit_cases(paper, ours, verdict):
    assert study.numeric_verdict(paper, ours)[0] == verdict


def test_numeric_verdict_absolute_tolerance():
    assert study.numeric_verdict(0.15, 0.19, tol=0.05)[0] == study.REPRODUCED
    assert study.numeric_verdict(0.15, 0.21, tol=0.05)[0] != study.REPRODUCED
