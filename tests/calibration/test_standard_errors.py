"""The standard errors of a joint calibration: covariance max(s^2, 1) (J^T W J)^-1 (knitsim.calibration.joint).

Hand-made files of known truth: the two model curves of one yarn of tests/calibration/data (Dusserre's E-glass,
B = 0.31 N mm^2, m = 0.20; knitA phi0 = 0, knitB phi0 = 0.03: truth_knit*.toml, run here), read every 0.005
(the rows' own grid: no interpolation between readings), total force over a 50 mm strip.  Fits with the probe's
settings of tests/calibration/test_offsets.py (B and m shared, phi0 per specimen).

Coverage measured on these files (10 seeds each, B, m and both phi0; |estimate - truth| within 2 standard
errors, before -> after): white noise, sds stated right 90 % -> 90 %; sds stated 3 x the noise 90 % -> 100 %
(within 1: 68 % -> 100 %: conservative); AR(1) noise of 0.8 52 % -> 100 % (within 1: 45 % -> 75 %); two tests
+-3 % about the truth given as a band (mid-line objective) 28 % -> 100 % (the yarn 15 standard errors off
before); knits stated 5 % off with 5 % priors and sds 3 x the noise 83 % -> 100 %.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from knitsim.calibration.joint import (JointSetup, _covariance, _fit_variables, _Problem, _reported,
                                       _row_information, calibrate_joint, identification_rule, weighted_covariance)
from knitsim.calibration.scene import load_calibration_scene
from knitsim.calibration.specimen import SpecimenData

DATA = Path(__file__).resolve().parent / "data"
KNITS = {"knitA": {"L": 14.1, "W0": 4.4, "C0": 2.7}, "knitB": {"L": 16.0, "W0": 5.0, "C0": 3.06}}
TRUTH = {("B", None): 0.31, ("m", None): 0.20, ("phi0", "knitA"): 0.0, ("phi0", "knitB"): 0.03}
NOISE = {"knitA": 0.005, "knitB": 0.002}
STRAIN = 0.005 * np.arange(101)


@pytest.fixture(scope="module")
def truth_N():
    """Each truth knit's total force over the 50 mm strip at STRAIN (its cell scene run as `knitsim cell` runs it)."""
    from knitsim.cell.batch import run_batch
    from knitsim.scene.cell_scene import load_cell_scene
    out = {}
    for name, f in (("knitA", "truth_knitA.toml"), ("knitB", "truth_knitB.toml")):
        cs = load_cell_scene(DATA / f)
        h = run_batch(cs.params, cs.program)
        out[name] = np.interp(STRAIN, h.strain, h.force_per_wale[:, 0]) * 50.0 / KNITS[name]["W0"]
    return out


def _write(path: Path, force) -> str:
    path.write_text("strain,load_N\n" + "".join(f"{s:.6f},{f:.8g}\n" for s, f in zip(STRAIN, force)))
    return str(path)


def _fit(specimens: dict):
    """``specimens``: name -> the specimen's file keys (curve and noise_N, or band)."""
    doc = {"title": "standard errors", "device": "cpu", "yarn": {"d": 0.58, "B": 0.25},
           "friction": {"model": "coulomb", "m": 0.25, "phi0": 0.0},
           "rules": {"unloading_rule": "dusserre", "force_cap_N": 10.0, "jamming_criterion": "w_4d"},
           "calibration": {"shared": ["B", "m"], "per_specimen": ["phi0"], "bounds": {"B": [0.05, 1.0], "m": [0.05, 0.6]},
                           "starts": 16, "refine": 2, "max_nfev": 100, "row_step": 0.005, "max_increment": 0.001},
           "specimens": [{"name": n, "width": 50.0, "gauge_length": 100.0, "knit": KNITS[n], **keys}
                         for n, keys in specimens.items()]}
    sc = load_calibration_scene(doc)
    return calibrate_joint(sc.specimens, sc.setup)


def test_a_wider_band_about_the_same_midline_gives_wider_standard_errors(tmp_path, truth_N):
    """Identity: the same mid-line with every row's sd (the band's half-width) three times larger has the same
    minimum and three times the standard errors (J / 3, the factor 1 while the rows scatter less than their sds).
    Before, s^2 = chi2 / (n - k) < 1 scaled the covariance down by as much as the band widened it: a +-2 % and a
    +-6 % band gave the same standard errors, and two tests +-3 % apart put the yarn 15 of them off the truth."""
    rng = np.random.default_rng(3)
    mids = {n: f + NOISE[n] * rng.standard_normal(len(f)) for n, f in truth_N.items()}
    se = {}
    for half in (0.02, 0.06):
        keys = {n: {"band": [_write(tmp_path / f"{n}_{half}_lo.csv", m * (1 - half)),
                             _write(tmp_path / f"{n}_{half}_hi.csv", m * (1 + half))]} for n, m in mids.items()}
        r = _fit(keys)
        assert r.s2 < 1.0 and r.variance_factor == 1.0
        se[half] = {(e.name, e.specimen): (e.value, e.std_error) for e in r.estimates}
    for key in TRUTH:
        assert se[0.06][key][0] == pytest.approx(se[0.02][key][0], rel=1e-3, abs=1e-4)
        assert se[0.06][key][1] / se[0.02][key][1] == pytest.approx(3.0, rel=0.05), key


def test_rows_whose_errors_run_on_count_less(tmp_path, truth_N):
    """AR(1) noise of 0.8 (its sd stated right, 0.005 and 0.002 N): before, the yarn lay 3.5 to 3.9 standard errors
    off the truth on this seed (6 of 10 seeds beyond 2); each specimen's rows now count (1 - rho) / (1 + rho) of
    their residuals' lag-1 autocorrelation (the variance of a mean of n AR(1) errors is that of n (1 - rho) /
    (1 + rho) independent ones): every estimate within 2 standard errors."""
    rng = np.random.default_rng(9)
    keys = {}
    for n, f in truth_N.items():
        e = np.empty(len(f))
        e[0] = rng.standard_normal()
        for i in range(1, len(f)):
            e[i] = 0.8 * e[i - 1] + math.sqrt(1 - 0.8 ** 2) * rng.standard_normal()
        keys[n] = {"curve": _write(tmp_path / f"{n}.csv", f + NOISE[n] * e), "noise_N": NOISE[n]}
    r = _fit(keys)
    assert all(0.0 < q < 0.5 for q in r.row_information.values()), r.row_information
    for e in r.estimates:
        assert abs(e.value - TRUTH[(e.name, e.specimen)]) < 2.0 * e.std_error, (e.label, e.value, e.std_error)


def test_row_information_is_one_for_errors_that_change_sign_and_small_for_a_wave():
    """(1 - rho) / (1 + rho), rho the lag-1 autocorrelation clipped at 0: alternating residuals (rho < 0) count
    fully; a slow wave of 40 rows (rho = sum r_i r_i+1 / sum r_i^2 = 0.9755, computed here) counts 0.0124."""
    from types import SimpleNamespace
    wave = np.sin(2 * np.pi * np.arange(40) / 40)
    rho = float(np.dot(wave[:-1], wave[1:]) / np.dot(wave, wave))
    pb = SimpleNamespace(sp=[SimpleNamespace(strain=np.zeros(40)), SimpleNamespace(strain=np.zeros(40))],
                         objective="midline")
    info = _row_information(pb, np.concatenate([(-1.0) ** np.arange(40), wave, [3.0]]))   # a prior last
    assert info[0] == 1.0 and info[1] == pytest.approx((1 - rho) / (1 + rho), rel=1e-12)
    assert _row_information(SimpleNamespace(sp=pb.sp, objective="band"), np.concatenate([wave, wave])) == [1.0, 1.0]


# ------------------------------------------------ the covariance at a bound, and steps that leave the admissible cells
EDGE_STEP, EDGE_INCREMENT = 0.025, 0.005


def _edge_problem(m_low: float = 0.05):
    """One hand-made specimen, knitA's model curve (B 0.31, m 0.20, phi0 0: tests/calibration/data/truth_knitA.toml)
    read every 0.025 to 0.5 with 1 % + 5 mN noise sds (no noise added: the covariance does not need a minimum), B
    and m shared (m bounded to [0.05, 0.3]), phi0 its own; and the point of the probe's defect: m at its high bound,
    phi0 at +phimax = atan(m) (fit variable 1, a fraction of the cone)."""
    from knitsim.cell.batch import run_batch
    from knitsim.cell.load_program import monotonic
    from knitsim.cell.material import CellParams
    truth = CellParams(B=0.31, d=0.58, m=0.2, force_cap_N=10.0, **KNITS["knitA"])
    h = run_batch([truth], monotonic(0.5, EDGE_INCREMENT))
    strain = EDGE_STEP * np.arange(1, 21)
    F = np.interp(strain, h.strain, h.force_per_wale[:, 0]) * 50.0 / KNITS["knitA"]["W0"]
    sd = 0.01 * np.abs(F) + 0.005
    sp = SpecimenData("knitA", strain, F, sd, None, None, True, 50.0, 100.0, dict(KNITS["knitA"]), {})
    base = CellParams(B=0.25, d=0.58, m=0.25, force_cap_N=10.0, **KNITS["knitA"])
    setup = JointSetup(base=base, shared=("B", "m"), per_specimen=("phi0",), max_increment=EDGE_INCREMENT,
                       starts=0, refine=1, bounds={"B": (0.05, 1.0), "m": (m_low, 0.3)})
    pb = _Problem([sp], setup)
    x = np.array([math.log(0.31), 0.3, 1.0])
    assert x[1] == pb.hi[1] and x[2] == pb.hi[2]
    return pb, x


def _reported_jacobian_covariance(pb, x, steps):
    """Independent reference: the covariance from a forward-difference Jacobian taken in the reported variables
    themselves (B in N mm^2, m, phi0 in rad held), with the given steps (each variable's sign chosen by the
    caller so that every stepped cell is admissible), weighted as :func:`_covariance` weighs the rows."""
    names, y, *_ = _reported(pb, x)
    pts = [x] + [_fit_variables(pb, x, names, y + steps[j] * np.eye(len(y))[j]) for j in range(len(y))]
    for p in pts:                                        # every stepped cell admissible, every row solved
        cells = pb.cells_at(p)
        assert all(c is not None for c in cells)
        assert all(np.all(sim[1] == 0) for sim in pb.simulate(list(enumerate(cells))))
    res = pb.evaluate_points(pts)
    J = np.stack([(res[j + 1] - res[0]) / steps[j] for j in range(len(y))], axis=1)
    info = _row_information(pb, res[0])
    w = np.concatenate([np.repeat(info, [len(s.strain) for s in pb.sp]),
                        np.ones(len(res[0]) - sum(len(s.strain) for s in pb.sp))])
    return np.linalg.pinv(J.T @ (w[:, None] * J)), y


def test_standard_errors_at_m_bound_with_phi0_at_the_cone_edge_are_not_collapsed():
    """The probe's defect (four specimens of two yarns, m at its bound 0.6, every phi0 at +-phimax): the covariance
    stepped m down from its bound with phi0 held in rad, outside the narrower cone, every stepped cell inadmissible;
    the fail residuals read as a derivative of 4e11 and B = 0.3033 +- 1.3e-11 N mm^2, m = 0.6 +- 5.4e-9 followed.
    Now the steps are taken in the fit's variables (phi0 a fraction of the cone) and carried to the reported ones by
    the chain rule.  Expected: the covariance of the Jacobian taken in the reported variables with m stepped *up*
    (beyond the bound the cone is wider: every cell admissible) and phi0 down (into the cone), an independent
    parametrisation and step; the two agree to the finite differences' error."""
    pb, x = _edge_problem()
    y = _reported(pb, x)[1]
    ref, _ = _reported_jacobian_covariance(pb, x, 1e-6 * np.abs(y) * np.array([1.0, 1.0, -1.0]))
    cov = _covariance(pb, x, 1.0)
    se, se_ref = np.sqrt(np.diag(cov)), np.sqrt(np.diag(ref))
    assert np.all(np.isfinite(se)) and np.all(se_ref > 1e-4 * np.abs(y)), (se, se_ref)
    np.testing.assert_allclose(se, se_ref, rtol=1e-3)
    corr = cov[0, 1] / (se[0] * se[1])
    assert corr == pytest.approx(ref[0, 1] / (se_ref[0] * se_ref[1]), abs=1e-3)


def test_at_m_zero_the_steps_hold_phi0_as_the_reported_variables_do():
    """At m = 0 (its natural low bound, "no friction at the crossing") every fraction of the cone is phi0 = 0: the map
    from the fit's variables to the reported ones is singular there.  Stepped from the fit's fraction (0.7 here) m's
    step would move phi0 by 0.7 dm; the covariance steps from the fraction of the reported phi0 (0), so m's
    derivative holds phi0 = 0 as the reported variables' Jacobian does (the reference, its phi0 column zero: phi0
    not identified, infinite)."""
    pb, _ = _edge_problem(m_low=0.0)
    x = np.array([math.log(0.31), 0.0, 0.7])
    y = _reported(pb, x)[1]
    ref, _ = _reported_jacobian_covariance(pb, x, 1e-6 * np.maximum(np.abs(y), 1e-3))
    cov = _covariance(pb, x, 1.0)
    np.testing.assert_allclose(np.sqrt(np.diag(cov))[:2], np.sqrt(np.diag(ref))[:2], rtol=1e-3)
    assert cov[2, 2] == math.inf


def test_a_step_that_leaves_the_admissible_cells_is_taken_the_other_way_or_its_standard_error_is_not_known():
    """A stepped point whose cell is inadmissible (or whose rows fail where the best point's solve) is no
    derivative.  Here B's forward step is made inadmissible by hand: the covariance takes it the other way, and
    agrees with the one whose steps all pass (forward and backward differences: to their error, 1e-3).  With
    B's every step inadmissible its derivative, and so the whole covariance, is not known: NaN (not a number read
    off the fail residuals: on the old code B's standard error collapsed to ~1e-10 of its value), B named, and the
    rule says "not known"."""
    pb, x = _edge_problem()
    x = np.array([math.log(0.31), 0.2, 0.0])            # inside every bound
    clean = _covariance(pb, x, 1.0)
    own = pb.cells_at

    def forward_fails(p):
        return [None] * len(pb.sp) if p[0] > x[0] else own(p)
    pb.cells_at = forward_fails
    cov = _covariance(pb, x, 1.0)
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), np.sqrt(np.diag(clean)), rtol=1e-3)

    def every_step_fails(p):
        return [None] * len(pb.sp) if p[0] != x[0] else own(p)
    pb.cells_at = every_step_fails
    unknown: list = []
    zero_gradient: list = []
    cov = _covariance(pb, x, 1.0, unknown=unknown, zero_gradient=zero_gradient)
    assert np.all(np.isnan(cov)) and unknown == ["B"] and np.all(np.isnan(zero_gradient[0]))
    rule = identification_rule(math.sqrt(cov[1, 1]), 0.05, 0.3, "", ", ".join(unknown))
    assert rule.startswith("its standard error is not known: B's finite-difference step"), rule


# ------------------------------------------------ the covariance's matrix: the capstan and Dahl fits' routine
def test_weighted_covariance_by_hand_and_a_singular_direction_not_identified():
    """``s2 (J^T W J)^-1`` (knitsim.calibration.joint.weighted_covariance, by the SVD of sqrt(w) J as the capstan and Dahl
    fits take theirs).  By hand: J = [[1, 2.5], [2, 4], [3, 6]], w = [4, 1, 1]: sqrt(w) J = [[2, 5], [2, 4], [3, 6]],
    its J^T J = [[17, 36], [36, 77]], det 17 * 77 - 36^2 = 13, the inverse by the 2 x 2 cofactor formula; a third
    column of zeros (a variable the rows do not move) is infinite and leaves the others so.  Two variables that trade
    exactly (columns [1, 2, 3] and [2, 4, 6]: only their combination is set) are infinite, not identified
    (identification_rule); before, the pseudo-inverse of J^T W J gave each a finite standard error (0.08 and 0.16 here),
    "identified"."""
    J = np.array([[1.0, 2.5, 0.0], [2.0, 4.0, 0.0], [3.0, 6.0, 0.0]])
    w = np.array([4.0, 1.0, 1.0])
    cov = weighted_covariance(J, w, 2.0)
    np.testing.assert_allclose(cov[:2, :2], 2.0 * np.array([[77.0, -36.0], [-36.0, 17.0]]) / 13.0, rtol=1e-12)
    assert cov[2, 2] == math.inf and np.all(cov[2, :2] == 0.0) and np.all(cov[:2, 2] == 0.0)
    J[:, 1] = 2.0 * J[:, 0]
    J[:, 2] = [1.0, 0.0, 1.0]
    cov = weighted_covariance(J, np.ones(3), 1.0)
    se = np.sqrt(np.diag(cov))
    assert np.all(np.isinf(se[:2]))
    for j in range(2):
        assert identification_rule(float(se[j]), 0.0, 10.0) == "its standard error is not finite: the rows do not depend on it"
