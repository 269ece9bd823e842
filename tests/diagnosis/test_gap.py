"""Gap per stage and curve indicators.

Sources: the partition identities (shares of the squared error sum to 1;
sum_k n_k rms_k^2 = n rms^2), a hand-computed triangle loop (peak, residual
strain, enclosed area), and the BIC formula n ln(rss/n) + k ln(n) (Schwarz 1978)
on a hand example.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from knitsim.diagnosis.gap import bic, curve_indicators, gap_report, stage_gap, stage_keys
from knitsim.errors import KnitsimInputError


def test_stage_keys():
    keys = stage_keys(["adherence", "sliding", "sliding", "slack", "jamming"], [1, 1, -1, -1, 1], [1, 1, 1, 1, 2])
    assert keys == ["loading_adherence", "loading_sliding", "unloading_sliding", "unloading_slack",
                    "reloading_jamming"]


def test_shares_and_rms_recombine():
    rng = np.random.default_rng(0)
    n = 57
    fm = rng.uniform(0, 1, n)
    fs = fm + rng.normal(0, 0.1, n)
    keys = list(rng.choice(["loading_adherence", "loading_sliding", "unloading_sliding", "reloading_jamming"], n))
    g = stage_gap(fm, fs, keys)
    st = g["stages"]
    assert sum(v["share"] for v in st.values()) == pytest.approx(1.0, rel=1e-12)
    assert sum(v["n"] for v in st.values()) == n
    recombined = math.sqrt(sum(v["n"] * v["rms_N"] ** 2 for v in st.values()) / n)
    assert recombined == pytest.approx(g["total"]["rms_N"], rel=1e-12)
    # independent: the total from NumPy directly
    assert g["total"]["rms_N"] == pytest.approx(float(np.sqrt(np.mean((fs - fm) ** 2))), rel=1e-12)
    assert g["total"]["max_abs_N"] == max(v["max_abs_N"] for v in st.values())


def test_triangle_loop_indicators():
    # load F = s to 0.5, unload F = 2 (s - 0.25) to 0 at 0.25, then slack: peak 0.5 at 0.5,
    # residual strain 0.25, enclosed area 0.5*0.5*0.5 - 0.5*0.25*0.5 = 0.0625 (exact for
    # the trapezoid rule: the curve is linear between rows)
    s = np.array([0.125, 0.25, 0.375, 0.5, 0.375, 0.25, 0.125, 0.0])
    f = np.array([0.125, 0.25, 0.375, 0.5, 0.25, 0.0, 0.0, 0.0])
    d = np.array([1, 1, 1, 1, -1, -1, -1, -1])
    ind = curve_indicators(np.concatenate([[0.0], s]), np.concatenate([[0.0], f]), np.ones(9, int),
                           np.concatenate([[1], d]), ["adherence"] * 2 + ["jamming"] * 7)
    c = ind["cycles"][0]
    assert c["peak_force_N"] == 0.5 and c["strain_at_peak"] == 0.5
    assert c["residual_strain"] == pytest.approx(0.25, abs=1e-15)
    assert c["energy_N_per_strain"] == pytest.approx(0.0625, rel=1e-12)
    assert ind["strain_at_first_jamming"] == 0.25


def test_gap_report_zero_gap():
    s = np.array([0.1, 0.2, 0.1])
    r = gap_report(s, [0.1, 0.2, 0.0], [0.1, 0.2, 0.0], ["sliding"] * 3, [1, 1, 1], [1, 1, -1])
    assert r["gap"]["total"]["rms_N"] == 0.0
    assert math.isnan(r["gap"]["stages"]["loading_sliding"]["share"])
    assert r["measured"]["cycles"] == r["simulated"]["cycles"]


def test_bic_hand_example():
    # n = 4, rss = 2, k = 1: 4 ln(1/2) + ln 4 = -2 ln 2
    assert bic(2.0, 4, 1) == pytest.approx(-2.0 * math.log(2.0), rel=1e-14)
    # one more parameter costs ln(n)
    assert bic(2.0, 4, 2) - bic(2.0, 4, 1) == pytest.approx(math.log(4.0), rel=1e-14)
    with pytest.raises(KnitsimInputError, match="rss"):
        bic(0.0, 4, 1)


def test_stages_are_ranked_by_their_chi2_excess_where_the_noise_is_known():
    """Two curves pooled: a quiet one (sd 0.004 N) missed by 3 sd on its 10 unloading rows, a noisy one
    (sd 0.036 N) missed by 1 sd on its 10 loading rows.  In squared newtons the noisy stage dominates
    (10 x 0.036^2 = 0.01296 against 10 x 0.012^2 = 0.00144); in chi^2 its excess is 0 (10 rows at 1 sd:
    chi^2 10, what noise alone gives) and the quiet stage's is 90 - 10 = 80: it is the whole gap (a blind
    probe: effect-free curves read "loading_sliding 86 %" from the noisy pull)."""
    from knitsim.diagnosis.gap import stage_gap
    measured = np.zeros(20)
    simulated = np.concatenate([np.full(10, 0.012), np.full(10, 0.036)])
    keys = ["unloading_sliding"] * 10 + ["loading_sliding"] * 10
    plain = stage_gap(measured, simulated, keys)["stages"]
    assert plain["loading_sliding"]["share"] == pytest.approx(0.01296 / (0.01296 + 0.00144))
    weighted = stage_gap(measured, simulated, keys, np.concatenate([np.full(10, 1 / 0.004), np.full(10, 1 / 0.036)]))
    st = weighted["stages"]
    assert st["unloading_sliding"]["chi2"] == pytest.approx(90.0) and st["loading_sliding"]["chi2"] == pytest.approx(10.0)
    assert st["unloading_sliding"]["share"] == pytest.approx(1.0) and st["loading_sliding"]["share"] == 0.0
    assert st["loading_sliding"]["sse_N2"] == pytest.approx(0.01296)        # the newtons stay reported
