"""The band likelihood of a calibration (issue 16): :func:`knitsim.calibration.specimen.band_residuals`.

Independent checks: the density of a reading is the box of the band convolved with the Gaussian
of the force accuracy, integrated here numerically (scipy.integrate.quad) instead of with the
closed form in normal CDFs; the limit of a band of no width is the Gaussian of the reading,
r = (f - low) / s exactly; at the edge of a band wide against s the density is half the middle's
(one Gaussian half-mass), r^2 = 2 ln 2; well inside it is flat (r ~ 0).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.stats import norm

from knitsim.calibration.specimen import SpecimenData, band_residuals, cauchy_tail


def _quad_residual(f, lo, hi, s):
    """sign(f - mid) sqrt(2 [ln p(mid) - ln p(f)]), p by numerical integration of the box x Gaussian."""
    def p(x):
        return quad(lambda t: norm.pdf(x, t, s), lo, hi, points=[min(max(x, lo), hi)], epsabs=0.0,
                    epsrel=1e-12, limit=200)[0] / (hi - lo)
    mid = 0.5 * (lo + hi)
    return math.copysign(math.sqrt(max(2.0 * (math.log(p(mid)) - math.log(p(f))), 0.0)), f - mid)


@pytest.mark.parametrize("lo, hi, s", [(1.0, 1.3, 0.01), (5.0, 5.02, 0.025), (0.2, 0.4, 0.05)])
def test_band_residuals_match_the_numerically_integrated_density(lo, hi, s):
    f = np.array([lo - 4 * s, lo - s, lo, 0.5 * (lo + hi) + 0.1 * (hi - lo), hi - 0.01 * (hi - lo), hi + 2 * s,
                  hi + 6 * s])
    r = band_residuals(f, np.full(f.shape, lo), np.full(f.shape, hi), np.full(f.shape, s))
    expect = [_quad_residual(x, lo, hi, s) for x in f]
    np.testing.assert_allclose(r, expect, rtol=1e-6, atol=1e-8)


def test_band_of_no_width_is_the_gaussian_of_the_reading_and_a_wide_band_is_flat_inside():
    # no width: p(f) = N(f; low, s), so r = (f - low) / s exactly (and its tiny-width limit too)
    f = np.array([0.97, 1.0, 1.004, 1.05])
    for w in (0.0, 1e-9):
        r = band_residuals(f, np.full(4, 1.0), np.full(4, 1.0 + w), np.full(4, 0.01))
        np.testing.assert_allclose(r, (f - 1.0 - 0.5 * w) / 0.01, rtol=1e-6, atol=1e-6)
    # a band 100 s wide: anywhere in its middle 80 % costs < 1e-6 (Phi tails of >= 10 s)
    lo, hi, s = 0.0, 1.0, 0.01
    inside = np.linspace(0.1, 0.9, 9)
    r = band_residuals(inside, np.zeros(9), np.ones(9), np.full(9, s))
    assert np.all(np.abs(r) < 1e-6)
    # at its edge p falls to one half of the middle's: r^2 = 2 ln 2
    r_edge = band_residuals(np.array([hi]), np.array([lo]), np.array([hi]), np.array([s]))
    assert r_edge[0] == pytest.approx(math.sqrt(2 * math.log(2)), rel=1e-9)
    # symmetric about the mid-line, increasing outside
    a = band_residuals(np.array([-0.05, 1.05]), np.zeros(2), np.ones(2), np.full(2, s))
    assert a[0] == pytest.approx(-a[1], rel=1e-12) and a[1] > 5.0


def test_specimen_band_residuals_use_the_force_accuracy_as_the_reading_sd():
    strain = np.array([0.1, 0.2])
    low, high = np.array([1.0, 2.0]), np.array([1.0, 2.4])
    sp = SpecimenData("x", strain, 0.5 * (low + high), np.array([0.005, 0.2]), low, high, True, 50.0, 100.0,
                      {"L": 4.5, "W0": 1.2, "C0": 0.9}, accuracy_rel=0.005)
    np.testing.assert_allclose(sp.accuracy_N, [0.005, 0.011])
    f = np.array([1.01, 2.5])
    np.testing.assert_allclose(sp.band_residuals(f), cauchy_tail(band_residuals(f, low, high, [0.005, 0.011])))
    # the closed row: Gaussian residual (1.01 - 1) / 0.005 = 2, with the Cauchy tail sqrt(2 ln 3)
    assert sp.band_residuals(f)[0] == pytest.approx(math.sqrt(2 * math.log(3.0)), rel=1e-9)


def test_cauchy_tail_is_scipys_cauchy_loss():
    """sum cauchy_tail(r)^2 = 2 sum ln(1 + r^2 / 2): least squares on it has the minimiser of scipy's own
    loss="cauchy" with f_scale = sqrt 2 (an independent implementation); near 0 it is r to first order
    (-2 ln p = r^2 + O(r^4): the Gaussian near the band)."""
    from scipy.optimize import least_squares

    r = np.array([-30.0, -1.0, -1e-4, 0.0, 0.5, 7.0])
    np.testing.assert_allclose(cauchy_tail(r) ** 2, 2 * np.log(1 + r * r / 2), rtol=1e-7)
    assert np.all(np.sign(cauchy_tail(r)) == np.sign(r)) and cauchy_tail(np.array([1e-4]))[0] == pytest.approx(1e-4)
    y = np.array([0.1, -0.2, 0.05, 0.15, -0.1, 9.0, 12.0])          # two outliers
    ours = least_squares(lambda c: cauchy_tail(y - c[0]), [1.0], xtol=1e-14, ftol=1e-14, gtol=1e-14).x[0]
    scipy_own = least_squares(lambda c: y - c[0], [1.0], loss="cauchy", f_scale=math.sqrt(2), xtol=1e-14, ftol=1e-14, gtol=1e-14).x[0]
    assert ours == pytest.approx(scipy_own, abs=1e-7)
    assert abs(ours) < 0.2 < abs(np.mean(y))                          # the outliers do not drag it


def test_band_objective_keeps_the_fit_in_the_band_despite_a_knee_the_model_cannot_make():
    """A band made by the model itself (E-glass cell of the joint tests, B = 0.31: force x 0.98 .. x 1.02)
    whose first five rows carry an extra step of +40 % (a stiff start the model has no mechanism for):
    the band objective fits B so that the model lies inside the band at every other row, 20 / 25 rows
    (B within the band's 2 % of the truth); the knee rows cost a Cauchy tail.  The mid-line objective
    (sd = half-width) on the same rows is dragged up by the knee and leaves the band nearly everywhere
    (measured: 0 / 25): the reason for the band objective."""
    from knitsim.calibration.joint import JointSetup, calibrate_joint
    from knitsim.cell.batch import run_batch
    from knitsim.cell.load_program import monotonic
    from knitsim.cell.material import CellParams
    k = {"L": 14.1, "W0": 4.4, "C0": 2.7}
    truth = CellParams(B=0.31, d=0.58, m=0.45, in_plane_width=0.79, force_cap_N=200.0, **k)
    h = run_batch([truth], monotonic(0.5, 0.02))
    F = h.force_per_wale[:, 0] * 100.0 / k["W0"]
    F[:5] *= 1.4
    low, high = 0.98 * F, 1.02 * F
    sp = SpecimenData("knee", h.strain, 0.5 * (low + high), 0.5 * (high - low), low, high, True, 100.0, 200.0, k)
    base = CellParams(B=0.2, d=0.58, m=0.45, in_plane_width=0.79, force_cap_N=200.0, **k)
    fits = {}
    for objective in ("band", "midline"):
        setup = JointSetup(base=base, shared=("B",), per_specimen=(), max_increment=0.02, starts=4, refine=1,
                           max_nfev=40, bounds={"B": (0.05, 2.0)}, objective=objective)
        fits[objective] = calibrate_joint([sp], setup)
    r = fits["band"]
    inside = sp.in_band(r.fits[0].simulated_N)
    assert not inside[:5].any() and inside[5:].all()
    assert r.fits[0].in_band_fraction == pytest.approx(20 / 25)
    assert abs(r.estimate("B").value / 0.31 - 1) < 0.02
    assert [s["objective"] for s in r.starts] == ["midline", "band"]
    assert fits["midline"].fits[0].in_band_fraction < 0.5
