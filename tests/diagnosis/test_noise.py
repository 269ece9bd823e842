"""Noise of one measured curve (knitsim.diagnosis.noise).

Expected values: for white noise the deviations of two neighbouring rows from their
neighbours' chords, r_i = f_i - (f_{i-1} + f_{i+1}) / 2 and r_{i+1}, share two rows with
weights (1, -1/2) and (-1/2, 1): cov = -sigma^2, var = 1.5 sigma^2, correlation -2/3 (an
identity); a moving average of white noise, or a curve with no noise at all, is not white
(its deviations follow the curve) and its noise cannot be estimated from it.
"""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.diagnosis.noise import WHITE_RHO_MAX, chord_correlation, cubic_correlation, curve_noise

N = 600
S = np.linspace(0.001, 0.6, N)
ONE = np.ones(N, int)


def test_white_noise_gives_the_correlation_of_minus_two_thirds_and_its_sd():
    rng = np.random.default_rng(11)
    f = 0.2 + 0.5 * S ** 2 + rng.normal(0.0, 0.003, N)
    rho, pairs = chord_correlation(S, f, ONE, ONE)
    assert pairs > 500
    assert rho == pytest.approx(-2.0 / 3.0, abs=4.0 / np.sqrt(pairs))   # 4 standard errors (se < 1/sqrt(n))
    c = curve_noise(S, f, ONE, ONE, "white")
    assert c.method == "estimated" and c.sigma_N == pytest.approx(0.003, rel=4.0 / np.sqrt(N))


def test_a_logger_reading_the_force_twice_at_one_strain_tells_its_noise():
    """A logger faster than the extensometer: every strain written twice, each row its own reading of the
    force (independent white noise of sd 0.05 N). No chord spans two rows at one strain, but the
    difference of the two readings has sd sqrt(2) x 0.05: the estimate is 0.05 within 4 standard errors
    (relative se about 1 / sqrt(2 x 300 samples)); before, no sample was counted and the noise was
    "assumed" at 0.5 % of the force range."""
    rng = np.random.default_rng(5)
    s = np.repeat(np.linspace(0.0025, 0.75, 300), 2)
    f = 0.1 + 5.0 * s ** 3 + rng.normal(0.0, 0.05, len(s))
    one = np.ones(len(s), int)
    c = curve_noise(s, f, one, one, "logger twice")
    assert c.method == "estimated" and c.samples == 300
    assert c.sigma_N == pytest.approx(0.05, rel=4.0 / np.sqrt(2 * 300))


@pytest.mark.parametrize("kind", ["smooth law", "read off a figure"])
def test_a_smooth_curve_says_its_noise_cannot_be_estimated(kind):
    """A curve with no measurement noise: a smooth law (its deviations from the cubics through the neighbours
    follow its fourth derivative, in step: correlation +1 where the identity gives -0.8 for white noise), or 40
    points read off a figure's smooth line rounded to 1e-4 N (their scatter about the cubics is the rounding,
    sd 1e-4 / sqrt(12) = 2.9e-5 N: within the last digit written)."""
    s = S if kind == "smooth law" else np.linspace(0.015, 0.6, 40)
    f = 0.2 + 0.5 * s ** 2 + 2.0 * s ** 4
    if kind == "read off a figure":
        f = np.round(f, 4)
    one = np.ones(len(s), int)
    rho, _ = chord_correlation(s, f, one, one)
    assert rho > WHITE_RHO_MAX
    c = curve_noise(s, f, one, one, kind)
    assert c.method == "assumed" and not c.estimable and not c.known
    assert ("in step" if kind == "smooth law" else "the rounding to the last digit its forces are written to (0.0001 N)") \
        in c.note and "--noise-N" in c.note


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_noise_read_through_a_coarse_last_digit_is_estimated_with_the_roundings_variance(seed):
    """A logger printing 0.01 N over white noise of sd 0.004 N (below the digit): each row is the curve plus the
    noise plus a rounding error uniform on (-0.005, 0.005), independent of the noise where the curve moves by more
    than the digit between rows, so the rows scatter about the curve by sqrt(0.004^2 + 0.01^2 / 12) = 0.00493 N
    (the rounding's variance q^2 / 12: an identity).  The estimate is that within 4 standard errors (relative se
    about 1 / sqrt(600)); before, any scatter below the digit itself was read as a rounded smooth curve and the
    noise assumed at 0.5 % of the force range, 0.025 N, 5 times too large.  The same law rounded without noise
    still says its noise cannot be estimated (its scatter, 0.01 / sqrt(12) = 0.0029 N, is the rounding alone)."""
    s = np.linspace(0.0, 0.6, N)
    f0 = 0.5 * (np.exp(4.0 * s) - 1.0)                  # 0 .. 5 N: about 0.05 N between rows at the end
    f = np.round((f0 + np.random.default_rng(seed).normal(0.0, 0.004, N)) / 0.01) * 0.01
    c = curve_noise(s, f, ONE, ONE, "logger 0.01 N")
    assert c.method == "estimated" and c.estimable
    assert c.sigma_N == pytest.approx(np.sqrt(0.004 ** 2 + 0.01 ** 2 / 12.0), rel=4.0 / np.sqrt(N))
    smooth = curve_noise(s[100:], np.round(f0[100:] / 0.01) * 0.01, ONE[100:], ONE[100:], "rounded law")
    assert smooth.method == "assumed" and "rounding" in smooth.note



def test_a_curve_written_to_a_coarse_digit_is_not_assumed_more_precise_than_that_digit():
    """A logger printing 0.01 N over a small curve (0.03 -> 0.17 N, white noise of sd 0.002 N below the digit):
    its scatter is the rounding's alone, so its noise is assumed.  Every row is off the curve by the rounding,
    uniform on (-0.005, 0.005): sd 0.01 / sqrt(12) = 0.00289 N (an identity), which no assumed sd may undercut.
    0.5 % of the force range is 0.00085 N: the true curve's rows would read 11 times chi2's expectation, and a
    reading of -0.01 N at rest (a -2 mN zero) would be 12 of those sd below zero, a file refused.  The assumed sd
    is the rounding's; the true curve's rows scatter by sqrt(0.002^2 + 0.01^2 / 12) = 0.0035 N (the noise read
    through the rounding), no less than it."""
    n = 300
    s = np.linspace(0.0, 0.6, n)
    f0 = 0.034 + 0.23 * s
    f = np.round((f0 + np.random.default_rng(3).normal(0.0, 0.002, n)) / 0.01) * 0.01
    c = curve_noise(s, f, np.ones(n, int), np.ones(n, int), "logger 0.01 N")
    assert c.method == "assumed" and not c.known and "rounding" in c.note
    assert c.sigma_N == pytest.approx(0.01 / np.sqrt(12.0), rel=1e-9)
    assert c.sigma_N <= np.sqrt(np.mean((f - f0) ** 2)) <= 1.3 * c.sigma_N

def test_heavy_tailed_noise_weights_the_rows_as_the_fit_counts_them():
    """Student t noise with 3 degrees of freedom (scale 0.01 N, sd 0.0173 N) on a smooth pull of 1200 rows, 20 draws.
    Every row within the fit's outlier limit (6 sd) counts in chi^2, so the sd that weights the rows is the noise's
    RMS within it: weighted so, the true curve's rows give chi^2 per row 1 (an identity; the median of the 20 draws
    within 0.1 of it).  Before, the clipped RMS corrected for a Gaussian's truncation cut off the tail's variance:
    the true curve read chi^2 per row 1.17 (median of these 20 draws), a long file `unexplained`.  Gaussian noise of the
    same sd on the same curve is read as before: no tail factor in any draw, the sd within 4 standard errors."""
    n = 1200
    s = np.linspace(0.0, 0.6, n)
    f0 = 0.5 * (np.exp(4.0 * s) - 1.0)
    one = np.ones(n, int)
    per_row = []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        e = 0.01 * rng.standard_t(3, n)
        c = curve_noise(s, f0 + e, one, one, "t3")
        # a strain column's float rounding read as a jitter (1e-17: a program's own steps) moves nothing
        assert curve_noise(s, f0 + e, one, one, "t3", strain_sd=1e-17).sigma_N == c.sigma_N
        z = e / c.sigma_N
        per_row.append(float(np.mean(z[np.abs(z) < 6.0] ** 2)))
        g = curve_noise(s, f0 + rng.normal(0.0, 0.0173, n), one, one, "gauss")
        assert "heavy-tailed" not in g.note and g.sigma_N == pytest.approx(0.0173, rel=4.0 / np.sqrt(n))
    assert np.median(per_row) == pytest.approx(1.0, abs=0.1)


def test_isolated_outlier_rows_are_no_heavy_tail():
    """Gaussian noise (sd 0.01 N, 600 rows) with three single rows 12 to 15 sd off, 20 draws: the fit leaves such rows
    out (beyond 6 sd), so they must not raise the sd either.  Each moves the cubics of the two rows on either side by
    2/3 and 1/6 of itself (the Lagrange weights), 5.7 to 7.2 sd after scaling, between the two clips; those are left
    out with the row (before, the factor was taken in 2 of the 20 draws).  Expected: the Gaussian's own sd, within 4
    standard errors, in every draw."""
    n = 600
    s = np.linspace(0.0, 0.6, n)
    f0 = 0.5 * (np.exp(4.0 * s) - 1.0)
    one = np.ones(n, int)
    for seed in range(20):
        e = np.random.default_rng(seed).normal(0.0, 0.01, n)
        e[[100, 250, 400]] += [0.15, -0.12, 0.13]
        c = curve_noise(s, f0 + e, one, one, "outliers")
        assert "heavy-tailed" not in c.note and c.sigma_N == pytest.approx(0.01, rel=4.0 / np.sqrt(n)), seed


def _stiffening(s):
    """A pull that stiffens as a knit jams: 0.02 N at the start, 3.6 N at strain 0.6 (hand-made law)."""
    return 0.02 + 0.05 * (np.exp(7.0 * s) - 1.0)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_noise_that_grows_with_the_force_is_read_as_such(seed):
    """A load cell accurate to 1 % of its reading plus 0.002 N (sd = 0.002 + 0.01 F, white): one sd per
    curve weighted the rows at the peak too much (a blind probe: a curve of the model itself judged
    `unexplained` at chi2/dof 1.35).  The estimate gives both parts: the floor within 25 % and the share
    within 0.25 percentage points of the construction (600 rows: relative se about 1/sqrt(600 / 2) for
    each, 4 to 5 of them), and the sd of a row is floor + share x its force."""
    f0 = _stiffening(S)
    f = f0 + (0.002 + 0.01 * f0) * np.random.default_rng(seed).standard_normal(N)
    c = curve_noise(S, f, ONE, ONE, "load cell")
    assert c.method == "estimated" and c.per_N > 0
    assert c.sigma_N == pytest.approx(0.002, rel=0.25)
    assert c.per_N == pytest.approx(0.01, abs=0.0025)
    assert c.sd_at([0.0, 2.0]) == pytest.approx([c.sigma_N, c.sigma_N + 2.0 * c.per_N])
    assert "grows with the force" in c.note and c.rel_var == pytest.approx(2.0 / c.samples)


def test_constant_noise_on_a_stiffening_curve_keeps_one_sd():
    """The same stiffening pull with one sd for every row, 20 noise draws: 0.01 N on rows every 0.002 of
    strain, and 0.004 N on rows every 0.006 (coarse: the chord deviation of the law, f'' h^2 / 4 = 0.0015 N
    at the peak, f'' = 0.05 x 49 e^4.2 = 163 N, is 0.37 sd there: a bias of the
    chord deviations that grows with the force).  One sd is kept in at least 19 of 20 draws per grid (the test's false rate is 1e-3 a curve),
    within 4 standard errors of the construction's sd."""
    for n, sd in ((300, 0.01), (100, 0.004)):
        s = np.linspace(0.001, 0.6, n)
        one = np.ones(n, int)
        grown = 0
        for seed in range(20):
            f = _stiffening(s) + np.random.default_rng(seed).normal(0.0, sd, n)
            c = curve_noise(s, f, one, one, "constant")
            grown += c.per_N > 0
            if c.per_N == 0:
                assert c.sigma_N == pytest.approx(sd, rel=4.0 / np.sqrt(n))
        assert grown <= 1, (n, grown)


def test_a_rows_sd_adds_the_strain_jitter_times_the_curves_steeper_slope():
    """Effective variance (errors in the strain): sd^2 = sd_F^2 + (e f')^2, f' the steeper of the two
    segments beside a row, on each branch apart.  Hand-made: a V, up at slope 2 then down at slope 10, a
    knee inside the first branch (slope 1 then 3)."""
    from knitsim.diagnosis.noise import CurveNoise, row_slopes
    s = np.array([0.0, 0.1, 0.2, 0.3, 0.2, 0.1])
    f = np.array([0.0, 0.1, 0.4, 0.7, -0.3, -1.3])          # up: slopes 1, 3, 3; down: 10, 10
    cyc, d = np.ones(6, int), np.array([1, 1, 1, 1, -1, -1])
    k = row_slopes(s, f, cyc, d)
    assert k == pytest.approx([1.0, 3.0, 3.0, 3.0, 10.0, 10.0])
    n = CurveNoise("x", 0.003, "estimated", 100, True, "", strain_sd=4e-4)
    assert n.sd_at(f, k) == pytest.approx(np.sqrt(0.003 ** 2 + (4e-4 * k) ** 2))
    assert n.sd_at(f) == pytest.approx(np.full(6, 0.003))       # without slopes: the force's sd
    assert "strain jitter 0.0004" in n.describe()


def test_the_jitter_of_a_reading_is_told_from_steps_that_vary_while_read_exactly():
    """reading_jitter: white jitter e on steady steps makes the steps h + e_{i+1} - e_i, their lag-one
    correlation -1/2: the jitter counts (strain_jitter's estimate, within 15 % at 600 rows); steps that vary
    (0.01 +- 30 %, iid: correlation 0) while each strain is exact are no jitter, whatever their second
    differences say.  Hand-made: a ramp 0 -> 0.6 -> 0.1 (numpy)."""
    from knitsim.diagnosis.noise import reading_jitter, strain_jitter
    rng = np.random.default_rng(4)
    s = np.r_[np.arange(0.0, 0.6, 0.002), np.arange(0.6, 0.1, -0.002)]
    d = np.r_[np.ones(300, int), -np.ones(250, int)]
    jittered = s + rng.normal(0.0, 1e-4, len(s))
    assert reading_jitter(jittered, d) == pytest.approx(1e-4, rel=0.15)
    steps = 0.01 * (1 + rng.uniform(-0.3, 0.3, 120))
    irregular = np.r_[np.cumsum(steps[:60]), np.cumsum(steps[:60])[-1] - np.cumsum(steps[60:])]
    d2 = np.r_[np.ones(60, int), -np.ones(60, int)]
    assert strain_jitter(irregular) > 5e-4 and reading_jitter(irregular, d2) == 0.0


def test_white_noise_on_a_bending_curve_is_white_on_the_cubics():
    """A blind probe: a model pull through the jamming (to 8.5 N at steps of 0.005) with 3 mN of white noise
    read -0.14 on its chords, "not white", and its noise was assumed 14 times too large (the verdict then
    "unexplained" on effect-free data).  The cubic deviations follow the bending: their lag-one correlation is
    the identity's -0.8 (the filter (1/6, -2/3, 1, -2/3, 1/6): -14/9 over 35/18) within 4 standard errors, and
    the noise is estimated within 35 % (the chords' clipped RMS, which the bending still lifts: noise.py)."""
    rng = np.random.default_rng(4)
    s = np.arange(161) * 0.005
    f0 = 0.04 + 0.3 * s + 0.003 * (np.exp(s / 0.1) - 1.0)        # hand-made: a plateau, then jamming to 9 N
    f = f0 + rng.normal(0.0, 0.003, len(s))
    one = np.ones(len(s), int)
    rho, pairs = cubic_correlation(s, f, one, one)
    assert rho == pytest.approx(-0.8, abs=4.0 / np.sqrt(pairs))
    c = curve_noise(s, f, one, one, "jamming")
    assert c.method == "estimated" and c.sigma_N == pytest.approx(0.003, rel=0.35)


def _ar1(rng, rho, sd, n):
    """Noise correlated from row to row: AR(1) of coefficient ``rho`` and marginal sd ``sd`` (a load cell's
    first-order filter, slower than its logger, sampled at every row)."""
    e = np.empty(n)
    e[0] = rng.normal(0.0, sd)
    w = rng.normal(0.0, sd * np.sqrt(1.0 - rho * rho), n)
    for i in range(1, n):
        e[i] = rho * e[i - 1] + w[i]
    return e


def test_noise_correlated_from_row_to_row_is_not_read_as_a_smaller_white_noise():
    """A probe's model-made cycles with AR(1) noise (coefficient 0.6, marginal sd 3 mN) had their noise estimated
    at 1.4 mN (+0.46 % of the force) from the neighbours, and nothing missing read as a confident `unexplained`
    (chi2/dof 2.99).  Expected, from the filter (1/6, -2/3, 1, -2/3, 1/6) of the cubic deviations over the
    noise's autocorrelation rho^|k| (an independent sum, below): their variance is 0.282 of the noise's over
    neighbouring rows and 0.517 (rho^2's) over every second row, so the sd ratio (spacing_ratio) is
    sqrt(0.517 / 0.282) = 1.35, where white noise gives 1; the lag-one correlation of the cubics (-0.756) cannot
    tell it from white noise's (-0.8).  On a smooth hand-made curve (600 rows): the ratio's mean over 12 seeds
    within 0.08 of 1.35 (its scatter over seeds is about 0.09: 3 standard errors of the mean); seeds 1-3 not
    estimated (assumed, saying why); white noise of the same sd: the ratio within 4 standard errors of 1, and
    estimated."""
    smooth = 0.2 + 0.5 * S ** 2
    for seed in (1, 2, 3):
        c = curve_noise(S, smooth + _ar1(np.random.default_rng(seed), 0.6, 0.003, N), ONE, ONE, "filtered")
        assert c.method == "assumed" and not c.known and "noise correlated from row to row" in c.note, c.note
        white = smooth + np.random.default_rng(seed).normal(0.0, 0.003, N)
        assert curve_noise(S, white, ONE, ONE, "white").method == "estimated"
    from knitsim.diagnosis.noise import spacing_ratio
    w = np.array([1 / 6, -2 / 3, 1.0, -2 / 3, 1 / 6])

    def var(r):
        return sum(w[a] * w[b] * r ** abs(a - b) for a in range(5) for b in range(5)) / float(w @ w)

    expect = np.sqrt(var(0.36) / var(0.6))
    assert expect == pytest.approx(1.35, abs=0.01)
    ratios = [spacing_ratio(S, smooth + _ar1(np.random.default_rng(k), 0.6, 0.003, N), ONE, ONE)[0]
              for k in range(1, 13)]
    assert np.mean(ratios) == pytest.approx(expect, abs=0.08)
    for seed in (1, 2, 3):
        ratio, se = spacing_ratio(S, smooth + np.random.default_rng(seed).normal(0.0, 0.003, N), ONE, ONE)
        assert ratio == pytest.approx(1.0, abs=4.0 * se)


def test_kinks_of_the_models_own_jamming_cycles_are_not_noise_that_grows_with_the_force():
    """The model's own cycles through the jamming (E-glass, m 0.20, phi0 0.05 rad, three cycles 0.2-0.72 replayed at
    increments of 0.001 and read every 0.01 of strain on each branch, as tests/diagnosis/data/README.md's files) with
    white noise of one sd, 2 mN.  Where the knit jams or an unloading's stick ends, the slope changes 50-fold between
    two rows: the cubic through the neighbours cannot follow (26 deviations of 1 to 11 sd with no noise at all), and
    those rows are most of the few samples at high force.  The level model read them as noise growing with the force
    in 9 of 20 draws (0.002 N + 0.7 %: the peak's rows weighted ~5 times too little), and the bundled x1.03 file
    (the same cycles, 2 mN, rows written to 5 decimals) as 0.00195 N + 0.58 %.  Expected: one sd (the
    construction's), in at least 19 of 20 draws (the test's false rate is 1e-3 a curve) and for the file, within
    4 standard errors of 2 mN where kept; a load cell of 0.002 N + 1 % of the force on the same cycles at rows
    0.005 apart is still read as growing."""
    from pathlib import Path

    from knitsim.cell.batch import run_batch
    from knitsim.cell.load_program import cycles
    from knitsim.cell.material import CellParams
    from knitsim.diagnosis.measured import read_measured_curve
    cell = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, phi0=0.05, unloading_rule="dusserre",
                      reload_rule="mirror_unloading", force_cap_N=50.0)
    program = cycles(0.2, 0.72, 3, 0.001)
    F = run_batch([cell], program).values["F"][:, 0]

    def read_every(step):
        s, d = program.strain, program.direction
        rows, last = [0], s[0]
        for i in range(1, len(s)):
            if d[i] != d[i - 1] or abs(s[i] - last) >= step - 1e-9:
                rows.append(i)
                last = s[i]
        return np.asarray(rows)

    rows = read_every(0.01)
    s, c, d, f0 = program.strain[rows], program.cycle[rows], program.direction[rows], F[rows]
    grown = 0
    for seed in range(20):
        n = curve_noise(s, f0 + np.random.default_rng(seed).normal(0.0, 0.002, len(f0)), c, d, "model cycles")
        grown += n.per_N > 0
        if n.per_N == 0:
            assert n.sigma_N == pytest.approx(0.002, rel=4.0 / np.sqrt(n.samples))
    assert grown <= 1
    cv = read_measured_curve(Path(__file__).parent / "data" / "eglass_3cycles_to0.72_x1.03_noise2mN.csv")
    n = curve_noise(cv.strain, cv.force, cv.cycle, cv.direction, "x1.03")
    assert n.per_N == 0 and n.sigma_N == pytest.approx(0.002, rel=4.0 / np.sqrt(n.samples))
    rows = read_every(0.005)
    s, c, d, f0 = program.strain[rows], program.cycle[rows], program.direction[rows], F[rows]
    grows = [curve_noise(s, f0 + (0.002 + 0.01 * np.maximum(f0, 0.0)) * np.random.default_rng(seed).standard_normal(
        len(f0)), c, d, "load cell").per_N for seed in range(5)]
    assert sum(g > 0 for g in grows) >= 4


def test_the_tail_factor_of_too_few_deviations_is_one_without_an_empty_mean():
    # A log that starts by unloading, or a logger reading each strain twice, leaves every cubic deviation out
    # (kinks, or none at all): the factor is 1 by its own rule (fewer than MIN_SAMPLES), and it was reached through
    # the median of an empty array (numpy's "Mean of empty slice" RuntimeWarning in every such diagnosis).
    import warnings

    from knitsim.diagnosis.noise import MIN_SAMPLES, tail_factor
    z = np.linspace(0.1, 2.0, MIN_SAMPLES + 5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert tail_factor(z, jumps=np.full(len(z), 1e9)) == 1.0       # every deviation at a kink
        assert tail_factor(np.array([])) == 1.0


def test_a_programs_float_rounding_is_no_strain_jitter():
    # Strains written by a program (0.013 + i x 0.0037 in float64) have second differences of a few ulp: read as
    # 1.7e-17 of "jitter" (a probe's 8.4e-18, printed by knitsim diagnose).  Expected: 0 there (the floats'
    # rounding, 8 ulp of the largest strain, is no extensometer's noise), while a real jitter of sd 1e-6 is still
    # read within the estimate's scatter (1.4826 x the median of |second differences| / sqrt(6), ~200 rows: +-20 %).
    from knitsim.cell.load_program import cycles
    from knitsim.diagnosis.noise import reading_jitter, strain_jitter
    s = 0.013 + np.arange(200) * 0.0037
    assert np.median(np.abs(np.diff(s, 2))) > 0.0                     # the rounding is there to be read
    prog = cycles(0.1, 0.6, 3, 0.01)
    assert strain_jitter(s) == 0.0 and reading_jitter(prog.strain, prog.direction) == 0.0
    jittered = s + np.random.default_rng(1).normal(0.0, 1e-6, len(s))
    assert strain_jitter(jittered) == pytest.approx(1e-6, rel=0.2)
