"""Dahl law (Gemtex KES paper, eqs 1-3): limits, exactness, energy, identification.

Sources of expected values: eq 1 itself (slope), its closed-form integrals
(derived in knitsim/friction/dahl.py), an independent ODE integration
(scipy solve_ivp, DOP853), the steady-loop closed forms derived from the exact
branch (peak Fc tanh(kA), area 4 Fc (A - tanh(kA)/k)), the energy balance of
eq 3 (stored F^2/(2 sigma), dissipation rate F^2 |v| / Fc), and the parameters
of knitsim/data/dahl_kes.toml (paper table) for identification.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from knitsim.data import dahl_kes
from knitsim.errors import KnitsimInputError
from knitsim.friction.dahl import (
    DahlParams,
    dahl_increment,
    dahl_response,
    fit_dahl_loop,
    initial_guess,
    kes_loop,
    kes_loop_path,
    loop_work,
    steady_loop_energy,
    steady_loop_peak,
    turning_points,
)

ROWS = dahl_kes()["dahl"]
KES_K = 2.5  # KES-FB2 pure bending range, +-2.5 1/cm (units of the paper's table)


def eq1_slope(F, s, sigma, Fc, alpha):
    """dF/dx of eq 1, extended oddly beyond Fc (sign(u)|u|^alpha)."""
    u = 1.0 - s * F / Fc
    return sigma * math.copysign(abs(u) ** alpha, u)


def ode_increment(F0, dx, sigma, Fc, alpha):
    """Independent method: integrate eq 1 over dx with solve_ivp."""
    s = math.copysign(1.0, dx)
    sol = solve_ivp(lambda x, F: [eq1_slope(F[0], s, sigma, Fc, alpha)], (0.0, dx), [F0],
                    method="DOP853", rtol=1e-12, atol=1e-14 * Fc)
    return sol.y[0, -1]


def step_through(x, F0, sigma, Fc, alpha):
    """Drive the increment update sample by sample (as a cell does)."""
    F = [F0]
    for d in np.diff(x):
        F.append(float(dahl_increment(F[-1], d, sigma, Fc, alpha)))
    return np.array(F)


# ---------------------------------------------------------------- parameters
@pytest.mark.parametrize("field,kwargs", [
    ("sigma", dict(sigma=0.0, Fc=1.0)),
    ("Fc", dict(sigma=1.0, Fc=-1.0)),
    ("alpha", dict(sigma=1.0, Fc=1.0, alpha=float("nan"))),
])
def test_params_validation_names_field(field, kwargs):
    with pytest.raises(KnitsimInputError, match=field):
        DahlParams(**kwargs)


# ---------------------------------------------------------------- limits
@pytest.mark.parametrize("alpha", [0.5, 1.0, 2.0])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_small_displacement_stiffness_is_sigma(alpha, sign):
    # eq 1 at F = 0: dF/dx = sigma for either direction
    sigma, Fc = 3.0, 0.7
    dx = sign * 1e-9 * Fc / sigma
    assert float(dahl_increment(0.0, dx, sigma, Fc, alpha)) / dx == pytest.approx(sigma, rel=1e-7)


@pytest.mark.parametrize("alpha", [0.5, 1.0, 2.0])
@pytest.mark.parametrize("F", [-0.9, 0.4, 1.3])
def test_local_slope_matches_eq1(alpha, F):
    # eq 1 away from F = 0, including the odd extension beyond Fc
    sigma, Fc, s = 2.0, 1.0, 1.0
    dx = 1e-8
    slope = (float(dahl_increment(F, dx, sigma, Fc, alpha)) - F) / dx
    assert slope == pytest.approx(eq1_slope(F, s, sigma, Fc, alpha), rel=1e-6, abs=1e-7)


def test_zero_increment_keeps_state():
    assert float(dahl_increment(0.37, 0.0, 2.0, 1.0, 1.7)) == 0.37


@pytest.mark.parametrize("alpha", [1.0, 0.5])
@pytest.mark.parametrize("s", [1.0, -1.0])
def test_saturates_at_plus_minus_Fc(alpha, s):
    # closed form: alpha = 1 decays like exp(-k p); alpha < 1 reaches Fc exactly
    sigma, Fc = 2.0, 0.5
    F = dahl_increment(-s * 0.8 * Fc, s * 40.0 * Fc / sigma, sigma, Fc, alpha)
    assert float(F) == pytest.approx(s * Fc, rel=1e-15, abs=0)


def test_alpha_above_one_saturates_asymptotically():
    # alpha = 2: u = u0 / (1 + k p u0) -> 1/(k p); never quite reaches Fc
    sigma, Fc, p = 2.0, 0.5, 1e6
    F = float(dahl_increment(0.0, p, sigma, Fc, 2.0))
    assert F < Fc
    assert 1.0 - F / Fc == pytest.approx(1.0 / (1.0 + sigma / Fc * p), rel=1e-9)


def test_alpha_below_one_saturation_travel():
    # alpha < 1: u^(1-alpha) falls linearly, reaching 0 at p* = u0^(1-alpha) Fc / ((1-alpha) sigma)
    sigma, Fc, alpha, F0 = 2.0, 0.5, 0.5, -0.2
    u0 = 1.0 - F0 / Fc
    p_star = u0 ** (1 - alpha) * Fc / ((1 - alpha) * sigma)
    assert float(dahl_increment(F0, 0.999 * p_star, sigma, Fc, alpha)) < Fc
    assert float(dahl_increment(F0, 1.001 * p_star, sigma, Fc, alpha)) == Fc
    assert float(dahl_increment(F0, 0.9 * p_star, sigma, Fc, alpha)) == pytest.approx(
        ode_increment(F0, 0.9 * p_star, sigma, Fc, alpha), rel=1e-9)


def test_coulomb_limit_large_sigma():
    # sigma -> infinity: F = Fc sign(dx) after an infinitesimal travel, and the
    # loop becomes the Coulomb rectangle of area 2A x 2Fc
    Fc, A = 0.3, 1.0
    sigma = 1e9 * Fc / A
    for s in (1.0, -1.0):
        assert float(dahl_increment(0.1, s * 1e-6 * A, sigma, Fc)) == pytest.approx(s * Fc, rel=1e-12)
    x = kes_loop_path(A, cycles=2, points_per_quarter=400)
    F = dahl_response(x, sigma, Fc)
    turns = turning_points(x)
    cycle = slice(turns[1], turns[3] + 1)
    assert loop_work(x[cycle], F[cycle]) == pytest.approx(4.0 * Fc * A, rel=1e-2)


def test_alpha_near_one_is_continuous():
    # the general closed form tends to the alpha = 1 exponential (log1p keeps accuracy)
    args = (0.3, 0.7, 2.0, 0.5)
    exact = float(dahl_increment(*args, 1.0))
    for a in (1.0 - 1e-10, 1.0 + 1e-10):
        assert float(dahl_increment(*args, a)) == pytest.approx(exact, rel=1e-9)


def test_crossing_form_of_model_md():
    # model.md "Dahl at the crossing": tan(phi) driven by slip xi with ratio m
    tan_phi, dxi, m, stiffness = -0.05, 0.02, 0.21, 30.0
    s = 1.0
    expected = s * m + (tan_phi - s * m) * math.exp(-stiffness * abs(dxi) / m)
    assert float(dahl_increment(tan_phi, dxi, stiffness, m)) == pytest.approx(expected, rel=1e-15)


# ---------------------------------------------------------------- exactness
@pytest.mark.parametrize("alpha", [1.0, 0.5, 0.8, 1.5, 3.0])
def test_update_matches_solve_ivp(alpha):
    rng = np.random.default_rng(11)
    sigma, Fc = 4.0, 0.8
    for _ in range(12):
        F0 = rng.uniform(-1.2, 1.2) * Fc  # includes |F| > Fc (u < 0)
        dx = rng.choice([-1, 1]) * 10 ** rng.uniform(-3, -0.7)
        if alpha < 1:  # stay short of the finite saturation travel (tested separately)
            s = math.copysign(1.0, dx)
            u0 = abs(1.0 - s * F0 / Fc)
            p_star = u0 ** (1 - alpha) * Fc / ((1 - alpha) * sigma)
            dx = s * min(abs(dx), 0.9 * p_star)
        got = float(dahl_increment(F0, dx, sigma, Fc, alpha))
        assert got == pytest.approx(ode_increment(F0, dx, sigma, Fc, alpha), rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("alpha", [1.0, 2.0, 0.6])
def test_rate_independence(alpha):
    # same path sampled at two densities: identical force at the shared samples
    sigma, Fc, A = 5.0, 1.0, 1.0
    coarse = kes_loop_path(A, cycles=2, points_per_quarter=5)
    dense = kes_loop_path(A, cycles=2, points_per_quarter=500)
    Fc_ = step_through(coarse, 0.0, sigma, Fc, alpha)
    Fd = step_through(dense, 0.0, sigma, Fc, alpha)
    np.testing.assert_allclose(Fd[::100], Fc_, rtol=1e-11, atol=1e-13)
    # the run-wise history equals stepping
    np.testing.assert_allclose(dahl_response(dense, sigma, Fc, alpha), Fd, rtol=1e-12, atol=1e-14)


def test_response_is_vectorised_over_states():
    x = kes_loop_path(1.0, cycles=1, points_per_quarter=20)
    sig = np.array([1.0, 3.0, 9.0])
    al = np.array([1.0, 0.7, 2.0])
    F = dahl_response(x, sig, 0.5, al, 0.1)
    assert F.shape == (3, x.size)
    for i in range(3):
        np.testing.assert_allclose(F[i], step_through(x, 0.1, sig[i], 0.5, al[i]), rtol=1e-12)


# ---------------------------------------------------------------- loops
def test_steady_loop_peak_and_symmetry_alpha1():
    sigma, Fc, A = 2.0, 0.5, 0.6
    Fmax = steady_loop_peak(sigma, Fc, A)
    up = np.linspace(-A, A, 201)
    F_up = dahl_response(up, sigma, Fc, F0=-Fmax)
    assert F_up[-1] == pytest.approx(Fmax, rel=1e-13)  # fixed point of one branch
    F_down = dahl_response(up[::-1], sigma, Fc, F0=Fmax)[::-1]
    np.testing.assert_allclose(F_down, -F_up[::-1], rtol=1e-12, atol=1e-15)  # F_desc(x) = -F_asc(-x)


@pytest.mark.parametrize("alpha", [0.5, 2.0])
def test_loop_symmetry_after_transient(alpha):
    sigma, Fc, A = 4.0, 0.5, 1.0
    x = kes_loop_path(A, cycles=8, points_per_quarter=50)
    F = dahl_response(x, sigma, Fc, alpha)
    t = turning_points(x)
    asc_x, asc_F = x[t[-3]:t[-2] + 1], F[t[-3]:t[-2] + 1]  # -A -> +A
    desc_x, desc_F = x[t[-2]:t[-1] + 1], F[t[-2]:t[-1] + 1]  # +A -> -A
    np.testing.assert_allclose(desc_x, -asc_x, atol=1e-14)
    np.testing.assert_allclose(desc_F, -asc_F, atol=1e-6 * Fc)


@pytest.mark.parametrize("kA", [0.3, 2.0, 12.0])
def test_loop_energy_equals_closed_form_and_dissipation(kA):
    sigma, Fc = 1.5, 0.4
    A = kA * Fc / sigma
    Fmax = steady_loop_peak(sigma, Fc, A)
    x = np.concatenate([np.linspace(-A, A, 20001), np.linspace(A, -A, 20001)[1:]])
    F = dahl_response(x, sigma, Fc, F0=-Fmax)
    W = loop_work(x, F)
    assert W > 0
    assert W == pytest.approx(steady_loop_energy(sigma, Fc, A), rel=1e-6)
    # eq 3 energy balance: stored F^2/(2 sigma) returns, dissipation F^2 |dx| / Fc
    F2 = 0.5 * (F[1:] ** 2 + F[:-1] ** 2)
    assert W == pytest.approx(float(np.sum(F2 * np.abs(np.diff(x)))) / Fc, rel=1e-6)


@pytest.mark.parametrize("alpha", [0.5, 2.0])
@pytest.mark.parametrize("A", [0.05, 1.0])
def test_loop_energy_nonnegative(alpha, A):
    x = kes_loop_path(A, cycles=4, points_per_quarter=400)
    F = dahl_response(x, 3.0, 0.5, alpha)
    t = turning_points(x)
    W = loop_work(x[t[-3]:t[-1] + 1], F[t[-3]:t[-1] + 1])
    assert W > 0
    assert W <= 4.0 * 0.5 * A  # at most the Coulomb rectangle


def test_kes_loop_path_hits_turning_points():
    x = kes_loop_path(2.5, cycles=3, points_per_quarter=10)
    assert x[0] == 0.0 and x[-1] == 0.0
    np.testing.assert_array_equal(x[turning_points(x)], [2.5, -2.5] * 3)


# ---------------------------------------------------------------- identification
def _check_recovered(fit, truth, names, tol_rel):
    for name in names:
        got, true, se = getattr(fit, name), truth[name], fit.stderr[name]
        assert abs(got - true) <= 3.0 * se, f"{name}: {got} vs {true} (se {se})"
        assert abs(got - true) <= tol_rel * abs(true), f"{name}: {got} vs {true}"


@pytest.mark.parametrize("row", ROWS, ids=[r["sample"] for r in ROWS])
@pytest.mark.parametrize("elastic", [False, True], ids=["dahl", "dahl+B"])
def test_identification_recovers_paper_rows(row, elastic):
    p = DahlParams(row["sigma"], row["Fc"], row["alpha"])
    B = 0.5 * row["sigma"] if elastic else 0.0  # an elastic part comparable to sigma
    x, M = kes_loop(p, KES_K, cycles=3, points_per_quarter=100, B=B, noise=0.01 * row["Fc"], seed=2024)
    fit = fit_dahl_loop(x, M, elastic=elastic, alpha=1.0)
    assert fit.success
    truth = {"sigma": p.sigma, "Fc": p.Fc, "B": B}
    _check_recovered(fit, truth, ["sigma", "Fc"] + (["B"] if elastic else []), 0.02)
    assert fit.rms == pytest.approx(0.01 * row["Fc"], rel=0.1)  # residuals are the added noise


@pytest.mark.parametrize("alpha", [1.0, 2.0, 0.6])
def test_identification_with_free_alpha(alpha):
    row = ROWS[1]
    p = DahlParams(row["sigma"], row["Fc"], alpha)
    x, M = kes_loop(p, KES_K, cycles=3, points_per_quarter=100, B=0.1, noise=0.005 * row["Fc"], seed=7)
    fit = fit_dahl_loop(x, M, elastic=True, alpha=None)
    _check_recovered(fit, {"sigma": p.sigma, "Fc": p.Fc, "alpha": alpha, "B": 0.1}, ["sigma", "Fc", "alpha", "B"], 0.03)


def test_identification_of_initial_state():
    # a record that starts at -K on the descending-branch end (F0 = -Fc tanh(kA))
    p = DahlParams(0.55, 0.16)
    F0 = -steady_loop_peak(p.sigma, p.Fc, KES_K)
    x = np.concatenate([np.linspace(-KES_K, KES_K, 201), np.linspace(KES_K, -KES_K, 201)[1:]])
    M = p.response(x, F0) + np.random.default_rng(3).normal(0, 1e-3, x.size)
    fit = fit_dahl_loop(x, M)
    assert abs(fit.F0 - F0) <= 3 * fit.stderr["F0"]


def test_initial_guess_reads_loop():
    # half-width at mid-range = Fc (1 - sech(kA)), close to Fc on a KES loop
    row = ROWS[0]
    p = DahlParams(row["sigma"], row["Fc"])
    x, M = kes_loop(p, KES_K, cycles=2, points_per_quarter=100)
    sigma0, Fc0, B0, F00 = initial_guess(x, M)
    kA = p.sigma / p.Fc * KES_K
    assert Fc0 == pytest.approx(p.Fc * (1 - 1 / math.cosh(kA)), rel=1e-3)
    assert 0.3 * p.sigma < sigma0 < 3 * p.sigma
    assert B0 == 0.0


@pytest.mark.parametrize("kwargs,match", [
    ({"sigma": 1.0, "Fc": -1.0}, "Fc"),          # no limit to approach (eq 1)
    ({"sigma": 0.0, "Fc": 0.5}, "sigma"),
    ({"sigma": 1.0, "Fc": 0.5, "alpha": 0.0}, "alpha"),
    ({"sigma": 1.0, "Fc": [0.5, float("nan")]}, "Fc"),
    ({"sigma": 1.0, "Fc": 0.5, "F0": float("inf")}, "F0"),
])
def test_dahl_response_refuses_parameters_eq1_cannot_mean(kwargs, match):
    with pytest.raises(KnitsimInputError, match=match):
        dahl_response(np.linspace(0.0, 1.0, 5), **kwargs)


def test_dahl_response_refuses_a_nan_displacement():
    with pytest.raises(KnitsimInputError, match="sample 2"):
        dahl_response(np.array([0.0, 0.1, np.nan]), 1.0, 0.5)


@pytest.mark.parametrize("x,F,match", [
    (np.linspace(0, 1, 10), np.zeros(10), "at least"),
    (np.linspace(0, 1, 50), np.zeros(50), "no reversal"),
    (np.r_[np.linspace(0, 1, 30), np.linspace(1, 0, 30)], np.r_[np.zeros(59), np.nan], "not finite"),
])
def test_fit_rejects_bad_loops(x, F, match):
    with pytest.raises(KnitsimInputError, match=match):
        fit_dahl_loop(x, F)


# ---------------------------------------------------------------- believable fits
def _triangle(n_branch=40):
    return np.r_[np.linspace(0, 1, n_branch + 1), np.linspace(1, -1, 2 * n_branch + 1)[1:],
                 np.linspace(-1, 1, 2 * n_branch + 1)[1:]]


@pytest.mark.parametrize("value", [0.0, 3.5])
def test_fit_rejects_constant_force(value):
    # a force that never changes carries no friction: sigma, Fc not identifiable
    x = _triangle()
    with pytest.raises(KnitsimInputError, match="cannot be identified"):
        fit_dahl_loop(x, np.full(x.size, value), labels=("x_mm", "F_N"))


@pytest.mark.parametrize("alpha", [1e9, 0.001, math.nan, -1.0])
def test_fit_rejects_alpha_out_of_range(alpha):
    # ALPHA_MIN = 0.02 .. ALPHA_MAX = 50: the box the free fit searches
    x = _triangle()
    with pytest.raises(KnitsimInputError, match="alpha"):
        fit_dahl_loop(x, np.sin(3 * x), alpha=alpha)


def test_reversal_warning_threshold():
    # a KES record: 6 reversals in 1201 points is a loop; 746 in 1201 is not
    from knitsim.friction.dahl import reversal_warning

    assert reversal_warning(1201, 6) is None
    assert reversal_warning(40, 6) is None            # a short coarse loop: a few reversals are fine
    assert "out of order" in reversal_warning(1201, 746)


def test_a_loop_that_gains_energy_says_its_rows_are_reversed_or_a_sign_flipped():
    # paper row 'fabric weft', 1 % noise: the loop as acquired dissipates (oint M dK > 0, no warning); the
    # same rows in reverse order, or with M or K negated, circulate the other way (the identity
    # oint F dx -> -oint F dx), which no Dahl loop does: the fit says so beside "not identified"
    row = ROWS[1]
    p = DahlParams(row["sigma"], row["Fc"], row["alpha"])
    x, M = kes_loop(p, KES_K, cycles=2, points_per_quarter=50, noise=0.01 * row["Fc"], seed=5)
    assert not [w for w in fit_dahl_loop(x, M).warnings if "gains energy" in w]
    for xx, MM in ((x[::-1], M[::-1]), (x, -M), (-x, M)):
        (w,) = [w for w in fit_dahl_loop(xx, MM, labels=("kappa", "M")).warnings if "gains energy" in w]
        assert "oint M dkappa = -" in w and "reverse order" in w


def test_fit_status_identified_on_clean_loop():
    # paper row 'fabric weft', 1 % noise: all fitted parameters identified
    row = ROWS[1]
    p = DahlParams(row["sigma"], row["Fc"], row["alpha"])
    x, M = kes_loop(p, KES_K, cycles=2, points_per_quarter=50, noise=0.01 * row["Fc"], seed=5)
    fit = fit_dahl_loop(x, M)
    assert fit.param_status == {"alpha": "fixed", "B": "fixed", "sigma": "identified", "Fc": "identified",
                                "F0": "identified"}
    assert fit.identified and fit.warnings == []


def _closed_form_loop(sigma, Fc, A, rows_per_branch=100, cycles=2, noise=2e-4, seed=3):
    """A Dahl loop (alpha = 1) written from its closed-form branches, F = s Fc - (s Fc - F_start)
    exp(-sigma |x - x_start| / Fc) (Dahl 1976), not through dahl_response: 0 -> A, then A <-> -A."""
    xs, Fs, x0, F0 = [0.0], [0.0], 0.0, 0.0
    for x1 in [A] + [-A, A] * cycles:
        x = np.linspace(x0, x1, rows_per_branch + 1)[1:]
        s = np.sign(x1 - x0)
        xs.extend(x)
        Fs.extend(s * Fc - (s * Fc - F0) * np.exp(-sigma * np.abs(x - x0) / Fc))
        x0, F0 = x1, Fs[-1]
    return np.array(xs), np.array(Fs) + noise * np.random.default_rng(seed).standard_normal(len(Fs))


@pytest.mark.parametrize("sigma", [5.0, 50.0])
def test_a_transition_shorter_than_the_rows_gives_sigma_a_lower_bound_only(sigma):
    """Rows every 0.05 with Fc = 0.014: the transition travel Fc / sigma is 2.8e-3 (sigma 5) or 2.8e-4
    (sigma 50), over before the next row.  Before, both fitted at sigma = 1.90 +- 0.23, "identified"
    (a blind probe: z = -206 for sigma = 50).  The data bound sigma from below only: the status says
    so, and the bound (one-sided 95 %) lies below the truth."""
    x, F = _closed_form_loop(sigma, 0.014, 2.5)
    fit = fit_dahl_loop(x, F)
    assert fit.param_status["sigma"] == "lower_bound_only" and not fit.identified
    assert 1.0 < fit.lower_bounds["sigma"] < sigma
    (w,) = [w for w in fit.warnings if w.startswith("sigma:")]
    assert "only a lower bound" in w and "mean nothing" in w
    assert fit.param_status["Fc"] == "identified" and abs(fit.Fc - 0.014) < 3 * fit.stderr["Fc"]


def test_a_transition_over_a_few_rows_keeps_sigma_identified():
    """The same rows with sigma = 0.3 (travel 0.047, about a row) and 1.0 (0.014: the first row after a
    reversal still 0.027 of 2 Fc off the plateau, 3.8 noise sd): the decay is measured, sigma is
    identified and within 3 standard errors of the truth."""
    for sigma in (0.3, 1.0):
        x, F = _closed_form_loop(sigma, 0.014, 2.5)
        fit = fit_dahl_loop(x, F)
        assert fit.param_status["sigma"] == "identified" and fit.lower_bounds == {}
        assert abs(fit.sigma - sigma) < 3 * fit.stderr["sigma"]


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5, 6])
def test_a_sharp_loop_whose_sigma_column_vanishes_gives_a_lower_bound_and_identifies_fc(seed):
    """A blind probe's sharp loops: sigma = 1000 at Fc = 0.8, amplitude 1, 20 rows a branch (travel Fc /
    sigma = 8e-4 against rows every 0.1), noise 0.01 N.  On four seeds in six the fit ended where chi^2 no
    longer depends on sigma: its Jacobian column vanished, every standard error was infinite and sigma, Fc
    and F0 were all "not identified".  The data bound sigma from below and set Fc (the plateau): sigma is
    lower_bound_only on every seed, Fc identified within 3 standard errors of the truth."""
    x, F = _closed_form_loop(1000.0, 0.8, 1.0, rows_per_branch=20, noise=0.01, seed=seed)
    fit = fit_dahl_loop(x, F)
    assert fit.param_status["sigma"] == "lower_bound_only"
    assert 0.0 < fit.lower_bounds["sigma"] < 1000.0
    assert fit.param_status["Fc"] == "identified" and math.isfinite(fit.stderr["Fc"])
    assert abs(fit.Fc - 0.8) < 3 * fit.stderr["Fc"]


@pytest.mark.parametrize("noise", [0.0, 1e-4])
def test_a_loop_without_hysteresis_does_not_identify_fc(noise):
    """The limit case Fc -> infinity: a straight spring F = 0.3 x over a KES-like path of 4 reversals has no
    loop; a blind probe's fit read Fc = 1.9e5 N +- 1.1e3, "identified".  The data bound Fc from below only."""
    x = kes_loop_path(1.0, cycles=2, points_per_quarter=30)
    F = 0.3 * x + noise * np.random.default_rng(0).standard_normal(x.size)
    fit = fit_dahl_loop(x, F, alpha=1.0)
    assert fit.param_status["Fc"] == "not_identified"
    assert fit.param_status["sigma"] == "identified" and fit.sigma == pytest.approx(0.3, rel=1e-3)
    assert not fit.identified


def test_a_dahl_loop_still_identifies_fc():
    """The closed-form Dahl loop (sigma 2, Fc 0.5: forces reach the saturation) is no straight spring."""
    x = kes_loop_path(1.0, cycles=2, points_per_quarter=30)
    fit = fit_dahl_loop(x, dahl_response(x, 2.0, 0.5), alpha=1.0)
    assert fit.param_status["Fc"] == "identified" and fit.Fc == pytest.approx(0.5, rel=1e-6)


# ---------------------------------------------------------------- does the law describe the loop?
def _hand_made_loop(sigma, Fc, A=1.0, per_quarter=50, cycles=3, alpha=1.0):
    """A KES-like path 0 -> A -> -A -> ... -> 0 and the Dahl force along it, written here (not by knitsim) from
    the closed forms of eq 1 along a run of direction s, u = 1 - s F / Fc: u = u0 exp(-sigma p / Fc) for
    alpha 1, u = u0 (1 + (alpha - 1) (sigma / Fc) p u0^(alpha - 1))^(-1 / (alpha - 1)) for alpha > 1."""
    legs = [np.linspace(0.0, A, per_quarter + 1)]
    for _ in range(cycles):
        legs += [np.linspace(A, -A, 2 * per_quarter + 1)[1:], np.linspace(-A, A, 2 * per_quarter + 1)[1:]]
    legs.append(np.linspace(A, 0.0, per_quarter + 1)[1:])
    x = np.concatenate(legs)
    F = np.zeros_like(x)
    for i in range(1, x.size):
        s, p = np.sign(x[i] - x[i - 1]), abs(x[i] - x[i - 1])
        u0 = 1.0 - s * F[i - 1] / Fc
        if alpha == 1.0:
            u = u0 * math.exp(-sigma * p / Fc)
        else:
            u = u0 * (1.0 + (alpha - 1.0) * sigma / Fc * p * u0 ** (alpha - 1.0)) ** (-1.0 / (alpha - 1.0))
        F[i] = s * Fc * (1.0 - u)
    return x, F


@pytest.mark.parametrize("sd", [1e-3, 1e-2])
def test_loop_noise_reads_the_noise_added_without_a_fit(sd):
    """The noise the test adds is the truth: white noise of sd 1e-3 and 1e-2 on a closed-form loop (sigma 2,
    Fc 0.5, 701 rows) is read back from the rows alone within 10 % (the estimate's relative sd is about
    1/sqrt(rows), 4 %); the noise-free loop (the limit case) is smoother than any measurement: its sd is
    assumed, 0.5 % of the force range, as diagnose assumes for a curve read off a figure."""
    from knitsim.friction.dahl import loop_noise

    x, F = _hand_made_loop(2.0, 0.5)
    got, rows, estimated = loop_noise(x, F + np.random.default_rng(11).normal(0.0, sd, x.size))
    assert estimated and rows > 600 and got == pytest.approx(sd, rel=0.10)
    got, _, estimated = loop_noise(x, F)
    assert not estimated and got == pytest.approx(0.005 * np.ptp(F), rel=1e-12)


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("row", ROWS, ids=[r["sample"] for r in ROWS])
def test_the_law_that_made_a_loop_is_not_flagged_as_missing_it(row, seed):
    """The limit case of the loop checks: data made by the law fitted, plus white noise (1 % of Fc, the
    bundled loop's), over three cycles of the paper's KES range.  The residuals are the noise, so the rms is
    about the noise read off the rows (within 20 %), and no offset or drift shows."""
    x, F = _hand_made_loop(row["sigma"], row["Fc"], A=KES_K, per_quarter=100)
    F = F + np.random.default_rng(seed).normal(0.0, 0.01 * row["Fc"], x.size)
    fit = fit_dahl_loop(x, F)
    assert fit.loop_flags == [] and fit.rms / fit.noise_sd == pytest.approx(1.0, abs=0.2)
    assert abs(fit.closure["offset"]) < 5 * fit.closure["offset_se"]


def test_a_loop_with_a_mild_elastic_part_fitted_without_it_is_said_to_miss():
    """Dahl (sigma 2, Fc 0.5) with an elastic part 1.5 x, noise 2e-3, fitted without --elastic: Fc comes out
    near 3.4, under 3 times the largest force (so the Fc-beyond-the-loop check is silent), but the residuals
    are the missing 1.5 x's, tens of times the noise (2e-3, added here).  Flagged, with the hint; fitted
    with the elastic part, the truth (B 1.5, Fc 0.5) within 2 % and nothing flagged."""
    x, F = _hand_made_loop(2.0, 0.5, per_quarter=40)
    F = F + 1.5 * x + np.random.default_rng(5).normal(0.0, 2e-3, x.size)
    fit = fit_dahl_loop(x, F)
    assert fit.param_status["Fc"] == "identified"          # not the Fc check: the residual one
    (flag,) = [f for f in fit.loop_flags if f.startswith("residuals")]
    assert fit.rms > 10 * 2e-3 and fit.noise_sd == pytest.approx(2e-3, rel=0.15)
    assert any(w.startswith("the fit misses the loop") and "try --elastic" in w for w in fit.warnings)
    ok = fit_dahl_loop(x, F, elastic=True)
    assert ok.loop_flags == [] and ok.B == pytest.approx(1.5, rel=0.02) and ok.Fc == pytest.approx(0.5, rel=0.02)


def test_a_fixed_alpha_the_loop_does_not_have_is_said_to_miss():
    """A loop of alpha 1.6 (closed form, noise 5e-3) fitted at the paper's alpha 1: residuals beyond the noise
    added, the hint --alpha free; fitted with alpha free, alpha 1.6 within 5 % and nothing flagged."""
    x, F = _hand_made_loop(2.0, 0.5, per_quarter=100, alpha=1.6)
    F = F + np.random.default_rng(2).normal(0.0, 5e-3, x.size)
    fit = fit_dahl_loop(x, F, alpha=1.0)
    assert any(f.startswith("residuals") for f in fit.loop_flags)
    assert any("try --alpha free" in w for w in fit.warnings)
    free = fit_dahl_loop(x, F, alpha=None)
    assert free.loop_flags == [] and free.alpha == pytest.approx(1.6, rel=0.05)


def test_an_offset_below_fc_is_read_and_flagged():
    """An offset of 22 % of Fc (a blind probe's 3e-5 on the bundled loop's Fc 1.37e-4; below Fc, so |F0| > Fc
    does not catch it) added to a closed-form loop with noise 1 % of Fc: the offset read is the one added,
    within 5 standard errors, and flagged; the loop as made is not."""
    sigma, Fc, c = 0.06, 1.37e-3, 0.22 * 1.37e-3
    x, F = _hand_made_loop(sigma, Fc, A=0.25, per_quarter=100)
    F = F + np.random.default_rng(1).normal(0.0, 0.01 * Fc, x.size)
    fit = fit_dahl_loop(x, F + c)
    off, se = fit.closure["offset"], fit.closure["offset_se"]
    assert abs(off - c) < 5 * se and abs(off - c) < 0.05 * c
    assert any(f.startswith("the loop is off centre") for f in fit.loop_flags)
    assert fit_dahl_loop(x, F).loop_flags == []


def test_a_drifting_loop_is_said_not_to_close():
    """A linear drift added to a closed-form loop (noise 1 % of Fc), 0 at the first row to 30 noise sd at the
    last (a blind probe's drift of the bundled loop moved sigma 5 %, nothing said): the loop does not close,
    the drift read is the one added within 10 %; a drift of half a noise sd over the file is no flag."""
    sigma, Fc = 0.06, 1.37e-3
    x, F = _hand_made_loop(sigma, Fc, A=0.25, per_quarter=100)
    F = F + np.random.default_rng(4).normal(0.0, 0.01 * Fc, x.size)
    ramp = np.linspace(0.0, 1.0, x.size)
    fit = fit_dahl_loop(x, F + 0.3 * Fc * ramp)
    assert fit.closure["drift"] == pytest.approx(0.3 * Fc, rel=0.10)
    assert any(f.startswith("the loop does not close") for f in fit.loop_flags)
    assert fit_dahl_loop(x, F + 0.005 * Fc * ramp).loop_flags == []


def test_kes_loop_path_longer_than_a_load_program_is_refused_before_it_is_built():
    # the path has 1 + 4 n cycles samples (a quarter of n, 2 cycles - 1 half swings of 2 n, a last quarter: the
    # default 100 x 3 gives 1201); a load program may have at most MAX_INCREMENTS increments, MAX_INCREMENTS + 1
    # samples.  Before, any length was built: `dahl simulate --points 1000000000` was killed for memory.
    from knitsim.cell.load_program import MAX_INCREMENTS
    assert kes_loop_path(1.0).size == 1 + 4 * 100 * 3
    n_ok = MAX_INCREMENTS // 4                            # 1 + 4 n = MAX_INCREMENTS + 1: the longest accepted
    assert kes_loop_path(1.0, cycles=1, points_per_quarter=n_ok).size == MAX_INCREMENTS + 1
    with pytest.raises(KnitsimInputError, match=r"cycles = 1 and points_per_quarter = 250001 make a path of "
                                                r"1000005 samples"):
        kes_loop_path(1.0, cycles=1, points_per_quarter=n_ok + 1)
    with pytest.raises(KnitsimInputError, match="points_per_quarter"):
        kes_loop_path(1.0, cycles=10**8, points_per_quarter=100)
