"""Synthetic measured curves with a hidden effect, for the blind study of the diagnosis (issue 6).

This is the *generator* of the blind study (:mod:`knitsim.diagnosis.study`).
It is a code path of its own: it never imports the diagnosis
(:mod:`knitsim.diagnosis.diagnose`), and what the diagnosis sees of a case,
:attr:`SyntheticCase.curves`, is a list of plain
:class:`~knitsim.diagnosis.measured.MeasuredCurve` (strain, force, cycle,
direction, rate), with no field that could carry the label.  The label (the
hidden effect, its strength, the true parameters, the stage where it acts
most, whether it is identifiable at all) stays in :attr:`SyntheticCase.label`.

A case is made in four steps, all drawn from one ``numpy.random.Generator``
seeded by the case's seed (so a seed gives the same arrays every time):

1. *Specimen*: the material of Dusserre (2015) (Table 1: d, B; section 2.2:
   L, W0, C0; section 3.4: m) with specimen-to-specimen scatter, L, W0, C0
   and d each multiplied by ``1 + scatter_rel N(0, 1)`` (re-drawn while the
   cell is invalid, e.g. L too short to close a loop), the friction ratio
   ``m = m_material exp(0.15 N(0, 1))`` and the initial friction angle
   ``phi0 = u phimax``, u uniform in [-0.9, 0.9] (section 3.3.1: phi0 lies in
   [-phimax, phimax] and is not known for a real specimen).
2. *Test*: cyclic (3 cycles 0.10 - 0.60, section 2.3) or monotonic to 0.60,
   measured every 0.02 (cyclic, 155 rows) or 0.004 (monotonic, 150 rows) of
   strain; one curve per test rate in ``rates`` (column ``rate_mm_s``).
3. *Hidden effect* at a strength s in [0, 1], mapped to a parameter range
   (:data:`EFFECT_RANGES`; the ranges and why are given there).
4. *Noise*: additive Gaussian on the force, sd = ``noise_rel`` x the curve's
   peak force, forces clipped at >= 0.  The default ``noise_rel`` is the
   scatter of the paper's capstan tests (:func:`paper_noise_rel`).

Whether a hidden effect is *identifiable* is decided on the noise-free curves
by an oracle (:func:`oracle_evidence`): the baseline model (effect off) is
refitted to them from the true specimen, over the parameters the diagnosis
calibrates, and the effect counts as identifiable when what the refit cannot
absorb is evidence enough for the diagnosis' criterion with high probability.
An effect that moves the curve a lot but that m, phi0 and the geometry can
mimic (e.g. compaction on a monotonic curve, close to a thinner yarn) is not
identifiable from these data, whatever the diagnosis does.

The curves are simulated with the Warp batch (:func:`knitsim.cell.batch.run_batch`)
on a finer strain increment than the diagnosis uses (default 0.0025 vs
0.005), so that the "real" curve is not the diagnosis' own discretisation.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..cell.batch import run_batch
from ..cell.effects import EFFECT_NAMES, NO_EFFECTS
from ..cell.material import CellParams
from ..data import dusserre2015
from ..errors import KnitsimInputError
from ..friction.coiling import m_eq10
from .gap import stage_keys
from .measured import MeasuredCurve, curve_from_arrays, force_at_rows, program_for_curve

MATERIALS = ("e_glass", "basalt")
TESTS = ("cyclic", "monotonic")
#: a lab specimen: two tests of one specimen (a monotonic pull to PULL_FORCE_N and the paper's cycles)
LAB = "lab"

#: test (crosshead) rate of the paper's tensile tests, 50 mm/min (section 2.3) [mm/s]
PAPER_RATE_MM_S = 50.0 / 60.0

#: strain step between measured rows: cyclic 3 x (0.60 up, 0.50 down) / 0.02 = 155 rows, monotonic 0.6 / 0.004 = 150
ROW_STEP = {"cyclic": 0.02, "monotonic": 0.004}

#: spread of the friction ratio between specimens (log-normal, sd of ln m); section 3.4 gives m = 0.06 .. 0.6
#: over a test, so a +-15 % uncertainty of the mean ratio of a specimen is modest
M_LOG_SD = 0.15
#: phi0 as a fraction of phimax, drawn uniformly in [-PHI0_FRACTION, PHI0_FRACTION]
PHI0_FRACTION = 0.9

#: Parameter of each hidden effect as a function of the strength s in [0, 1] (lo at s = 0, hi at s = 1;
#: "log": log-uniform).  Checked by :func:`effect_range_check` (every case runs, status ok, and the curve moves).
#: - dahl_transition: Dahl stiffness [1/mm]; smaller sigma = longer transition = stronger effect;
#: - coiling_angle_friction: mu_k of eq 10 as a multiple of the mu_k that gives the material's m at its mean
#:   coiling angle (section 3.4: 110 deg E-glass, 106 deg basalt), 0.5 .. 1.5;
#: - normal_load_friction: n of eq 5, 1 - 0.1 .. 1 - 0.4 (Table 3: n = 0.948 E-glass, 0.909 basalt;
#:   the ratio equals m at the crossing load of the rest-to-peak median of the effect-free run);
#: - velocity_friction: p of eq 5, 0.05 .. 0.2 (Table 3: 0.025 E-glass), reference rate the geometric mean
#:   of the test rates (so m is the ratio at the middle rate);
#: - yarn_compaction: k [1/N], 5 .. 50;
#: - bending_hysteresis: h, 0.1 .. 0.6 (bend_sigma kept at its default 20); 0.05 .. 0.3 changed the E-glass
#:   curve by < 2 % of its peak force (below the noise), hence the wider range;
#: - yarn_extension: c = 1/EA [1/N], 0.005 .. 0.03.
EFFECT_RANGES: dict[str, tuple[str, float, float, str]] = {
    "dahl_transition": ("dahl_sigma", 50.0, 2.0, "log"),
    "coiling_angle_friction": ("coil_mu_k_factor", 0.5, 1.5, "lin"),
    "normal_load_friction": ("load_n", 0.9, 0.6, "lin"),
    "velocity_friction": ("rate_p", 0.05, 0.2, "lin"),
    "yarn_compaction": ("compaction_k", 5.0, 50.0, "lin"),
    "bending_hysteresis": ("bend_h", 0.1, 0.6, "lin"),
    "yarn_extension": ("ext_c", 0.005, 0.03, "lin"),
}

#: specimens drawn at most per case (a draw whose simulation does not finish is replaced)
MAX_REDRAWS = 20

#: relative noise used when the paper's capstan data give none
FALLBACK_NOISE_REL = 0.02

#: evidence (drop of BIC) that names an effect: 2 ln B > 10, "very strong" (Kass and Raftery 1995); the
#: diagnosis' threshold, restated here so that the generator does not import the diagnosis
EVIDENCE_THRESHOLD = 10.0
#: evaluations each start of the oracle's refit gets before the best goes on
ORACLE_RACE_NFEV = 8
#: sds of the score's noise by which the expected evidence must clear the threshold (one-sided 2 sd:
#: detected in about 98 % of noise draws)
EVIDENCE_MARGIN_SD = 2.0


@dataclass
class SyntheticCase:
    """One synthetic specimen: what the diagnosis sees, and the hidden truth.

    Attributes
    ----------
    curves : list of MeasuredCurve
        The noisy measured curves (the only thing handed to the diagnosis).
    label : dict
        Hidden: ``effect`` (name or None), ``parameter``, ``value``,
        ``strength``, ``params`` (the true CellParams as a dict), ``true_stage``
        (stage key where the effect changes the noise-free curve most; None
        without an effect), ``stage_sse`` (that sum of squares per key),
        ``identifiable`` (bool), ``reason``, ``rms_effect_N``, ``max_effect_N``
        (RMS and largest |change| of the noise-free curve due to the effect),
        ``noise_sd_N`` (per curve), ``seed``, ``material``, ``test``, ``rates``.
    clean : list of ndarray
        Noise-free forces with the effect, per curve (for the tests and plots; not for the diagnosis).
    baseline : list of ndarray
        Noise-free forces of the same params without the effect, per curve.
    """

    curves: list
    label: dict
    clean: list = field(default_factory=list, repr=False)
    baseline: list = field(default_factory=list, repr=False)


def paper_noise_rel() -> tuple[float, str]:
    """Relative force scatter of the paper's capstan tests, and how it is obtained.

    Section 2.4 gives the largest standard deviation of the output force F1 of
    the repeated capstan tests, 0.13 N at 10 mm/s (``capstan.max_std_F1_N``).
    The mean F1 at that rate follows from eq 1, ``F1 = F0 exp(mu_k (theta1 +
    theta2))`` with F0 = 6.31 N, theta1 = theta2 = pi/2 and the Table 2 mu_k
    (ascent, 10 mm/s): 10.8 N for E-glass, 9.95 N for basalt (the text quotes
    10.7 and 9.94 N).  The relative scatter is the larger of the two ratios,
    0.13 / 9.95 = 0.013.

    Returns
    -------
    noise_rel : float
    how : str
    """
    paper = dusserre2015()
    cap = paper.get("capstan", {})
    std = cap.get("max_std_F1_N")
    rows = cap.get("table2", {}).get("rows", [])
    if not std or not rows:
        return FALLBACK_NOISE_REL, "fallback 0.02: the capstan data give no scatter"
    theta = 2.0 * float(cap["theta_each_rad"])
    ratios = {}
    for fibre, F0, direction, V, mu in rows:
        if direction == "ascent" and float(V) == 10.0:
            ratios[fibre] = float(std) / (float(F0) * math.exp(float(mu) * theta))
    if not ratios:
        return FALLBACK_NOISE_REL, "fallback 0.02: no Table 2 row at 10 mm/s"
    fibre = max(ratios, key=ratios.get)
    how = (f"capstan max std(F1) = {std} N at 10 mm/s (section 2.4) / mean F1 = F0 exp(mu_k pi) (eq 1, Table 2): "
           + ", ".join(f"{k} {v:.4f}" for k, v in ratios.items()) + f"; the larger ({fibre})")
    return ratios[fibre], how


DEFAULT_NOISE_REL = paper_noise_rel()[0]


def material_params(material: str) -> CellParams:
    """The paper's cell of ``material`` (Table 1, section 2.2, section 3.4), phi0 = 0."""
    from .. import materials

    if material not in MATERIALS:
        raise KnitsimInputError(f"material = {material!r}: expected one of {', '.join(MATERIALS)}")
    y = materials.yarn(material)
    k = materials.knit(f"{material}_plain")
    return CellParams(B=y.B, d=y.d, L=k.L, W0=k.W0, C0=k.C0, m=y.m, phi0=0.0).validated(where=material)


def coil_mu_match(material: str) -> float:
    """mu_k of eq 10 that gives the material's m at its mean coiling angle (section 3.4), by bisection."""
    from .. import materials

    y = materials.yarn(material)
    theta = math.radians(y.coiling_angle_deg)
    lo, hi = 1e-6, 5.0
    for _ in range(200):  # m_eq10 increases with mu_k (tanh)
        mid = 0.5 * (lo + hi)
        if float(m_eq10(theta, mid)) < y.m:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def measured_strains(test: str) -> np.ndarray:
    """Strains of the measured rows of a test (section 2.3 programs), turning points included."""
    if test not in TESTS:
        raise KnitsimInputError(f"test = {test!r}: expected one of {', '.join(TESTS)}")
    h = ROW_STEP[test]
    corners = [0.0, 0.6] if test == "monotonic" else [0.0, 0.6, 0.1, 0.6, 0.1, 0.6, 0.1]
    out = []
    for a, b in zip(corners[:-1], corners[1:]):
        n = int(round(abs(b - a) / h))
        out.extend((a + (b - a) * np.arange(1, n + 1) / n).tolist())
    return np.asarray(out)


def draw_specimen(rng: np.random.Generator, material: str, scatter_rel: float) -> CellParams:
    """The paper's material with specimen scatter (module docstring, step 1); re-drawn while invalid."""
    base = material_params(material)
    for _ in range(1000):
        f = [float(x) for x in 1.0 + scatter_rel * rng.standard_normal(4)]
        m = base.m * math.exp(M_LOG_SD * float(rng.standard_normal()))
        u = float(rng.uniform(-PHI0_FRACTION, PHI0_FRACTION))
        if min(f) <= 0:
            continue
        try:
            return base.replace(L=base.L * f[0], W0=base.W0 * f[1], C0=base.C0 * f[2], d=base.d * f[3],
                                m=m, phi0=u * math.atan(m))
        except KnitsimInputError:
            continue
    raise KnitsimInputError(f"scatter_rel = {scatter_rel!r}: no valid specimen in 1000 draws; use a smaller scatter")


def effect_value(effect: str, strength: float) -> float:
    """The parameter of ``effect`` at ``strength`` (:data:`EFFECT_RANGES`)."""
    _, lo, hi, kind = EFFECT_RANGES[effect]
    if kind == "log":
        return float(math.exp(math.log(lo) + strength * (math.log(hi) - math.log(lo))))
    return float(lo + strength * (hi - lo))


def apply_effect(params: CellParams, effect: str | None, strength: float, material: str,
                 rates, load_ref_N: float) -> tuple[CellParams, str | None, float | None]:
    """``params`` with the hidden effect switched on; returns (params, parameter name, value)."""
    if effect is None:
        return params, None, None
    name, _, _, _ = EFFECT_RANGES[effect]
    v = effect_value(effect, strength)
    if effect == "dahl_transition":
        return params.replace(friction="dahl", dahl_sigma=v), name, v
    if effect == "coiling_angle_friction":
        mu = v * coil_mu_match(material)
        return params.replace(effects=NO_EFFECTS.with_on(effect, coil_mu_k=mu)), "coil_mu_k", mu
    if effect == "normal_load_friction":
        return params.replace(effects=NO_EFFECTS.with_on(effect, load_n=v, load_ref_N=load_ref_N)), name, v
    if effect == "velocity_friction":
        ref = float(math.exp(np.mean(np.log(np.asarray(rates, float)))))
        return params.replace(effects=NO_EFFECTS.with_on(effect, rate_p=v, rate_ref_mm_s=ref)), name, v
    return params.replace(effects=NO_EFFECTS.with_on(effect, **{name: v})), name, v


def simulate_rows(params_list, curves, max_increment: float, device: str = "cpu"):
    """Noise-free force and stage labels at the measured rows of each curve, for each params.

    Returns
    -------
    list (per params) of list (per curve) of (force ndarray, labels list, status_ok bool)
    """
    out = [[] for _ in params_list]
    for c in curves:
        program, rows = program_for_curve(c, max_increment)
        h = run_batch(list(params_list), program, device=device)
        for j in range(len(params_list)):
            f, lab = force_at_rows(h, rows, cell=j)
            ok = bool(np.all(h.status[:, j] == 0))
            out[j].append((np.asarray(f, float), lab, ok))
    return out


def oracle_evidence(clean_curves, noise_sd, material: str, truth: CellParams, effect: str,
                    free: tuple, max_increment: float, device: str = "cpu", max_nfev: int = 30,
                    offsets: bool = False) -> dict:
    """Evidence for ``effect`` that noise-free curves hold beyond what the baseline can absorb.

    The baseline model (effect off) is fitted to the noise-free curves with
    the effect, over the variables ``free`` that the diagnosis calibrates and
    within its bounds (relative to the paper's nominal ``material``), rows
    weighted by their curve's noise sd, starting from the true specimen
    ``truth`` (the oracle knows it; the diagnosis does not) and from the
    nominal material and other initial friction angles; the best refit counts.
    With ``offsets`` the refit also has a force offset per curve, as the
    diagnosis' (a lab specimen's load cells have a zero of their own, and an
    effect that shifts a curve as a whole is absorbed by it).  Its residual ``r`` is the part of the effect no baseline parameter
    set reproduces.  With Gaussian noise of sd ``sigma_i`` per row, the drop
    of ``RSS / sigma^2`` that adding the effect brings is about

        lambda + 2 sum(eps_i r_i) / sigma_i^2,   lambda = sum(r_i^2 / sigma_i^2),

    whose noise term has sd ``2 sqrt(lambda)``; with the BIC penalty of its
    ``dk`` extra parameters the expected score is ``lambda - dk ln n``.  The
    effect is identifiable when that clears :data:`EVIDENCE_THRESHOLD` by
    :data:`EVIDENCE_MARGIN_SD` sds: ``lambda - dk ln n - 2 x 2 sqrt(lambda) > 10``.

    Returns
    -------
    dict
        ``lambda``, ``expected_score``, ``score_sd``, ``dk``, ``oracle_rms_N``,
        ``oracle_params`` (the refitted baseline), ``identifiable`` (bool).
    """
    from .calibrate import calibrate_baseline
    from .effects import variables_for

    nominal = material_params(material)
    x0 = {}
    for name in free:
        if name == "phi0":
            x0[name] = truth.phi0 / truth.phimax if truth.phimax > 0 else 0.0
        else:
            x0[name] = float(getattr(truth, name))
    # rows weighted by their curve's noise, as the diagnosis weighs them (an unweighted refit lets the
    # curve of large forces dominate and leaves the quiet one's misfit, which the diagnosis would not);
    # cells stop at 3 x the largest force, as the diagnosis' do (a runaway jammed branch beyond it does
    # not converge and would leave a meaningless residual)
    weights = [np.full(len(c.strain), 1.0 / s) for c, s in zip(clean_curves, noise_sd)]
    peak = max(float(np.max(c.force)) for c in clean_curves)
    if 0 < 3.0 * peak < nominal.cap_N:
        nominal = nominal.replace(force_cap_N=3.0 * peak)
    starts = [x0]
    # and from the nominal material (the scene a diagnosis starts from) and other initial friction
    # angles (phi0's least squares has local minima): the refit from the truth may stay in a basin that
    # another baseline beats; the best refit is what the data cannot tell apart.  The starts race for
    # ORACLE_RACE_NFEV evaluations, the best goes on.
    nominal_x = {n: (nominal.phi0 / nominal.phimax if n == "phi0" else float(getattr(nominal, n))) for n in free}
    starts.append(nominal_x)
    if "phi0" in free:
        starts += [dict(x0, phi0=f) for f in (-0.6, 0.0, 0.6) if abs(f - x0["phi0"]) > 0.25]

    def refit(x, nfev):
        return calibrate_baseline(list(clean_curves), nominal, free=tuple(free), device=device,
                                  max_increment=max_increment, x0=x, max_nfev=nfev, weights=weights,
                                  offsets=offsets)

    fit = min((refit(st, ORACLE_RACE_NFEV) for st in starts), key=lambda f: f["chi2"])
    if not fit["success"]:
        more = refit(fit["fit_variables"], max_nfev)
        fit = more if more["chi2"] <= fit["chi2"] else fit
    r = np.concatenate([np.asarray(c["simulated"]) - np.asarray(c["measured"]) for c in fit["curves"]])
    sd = np.concatenate([np.full(len(c.strain), s) for c, s in zip(clean_curves, noise_sd)])
    lam = float(np.sum((r / sd) ** 2))
    n = len(r)
    dk = len(variables_for(tuple(free), (effect,))) - len(free)  # coiling replaces m: dk = 0
    expected = lam - dk * math.log(n)
    score_sd = 2.0 * math.sqrt(lam)
    return {"lambda": lam, "expected_score": expected, "score_sd": score_sd, "dk": int(dk),
            "oracle_rms_N": float(math.sqrt(np.mean(r * r))), "oracle_params": dict(fit["values"]),
            "identifiable": bool(expected - EVIDENCE_MARGIN_SD * score_sd > EVIDENCE_THRESHOLD)}


def make_case(seed: int, material: str = "e_glass", test: str = "cyclic", effect: str | None = None,
              strength: float = 0.5, noise_rel: float | None = None, scatter_rel: float = 0.01,
              rates=(0.1, 10.0), max_increment: float = 0.0025, device: str = "cpu",
              oracle_free: tuple | None = None, oracle_increment: float = 0.01) -> SyntheticCase:
    """Generate one synthetic case (module docstring).

    Parameters
    ----------
    seed : int
        Seed of the case's random generator (everything is drawn from it).
    material : {"e_glass", "basalt"}
    test : {"cyclic", "monotonic"}
    effect : str or None
        Hidden effect (:data:`knitsim.cell.effects.EFFECT_NAMES`), or None.
    strength : float
        In [0, 1], mapped by :data:`EFFECT_RANGES`.
    noise_rel : float, optional
        Force noise sd as a fraction of each curve's peak force (default :data:`DEFAULT_NOISE_REL`).
    scatter_rel : float
        Relative specimen scatter of L, W0, C0, d (>= 0).
    rates : sequence of float
        Test rates [mm/s], one curve per rate.
    max_increment : float
        Strain increment of the generator's simulation.
    device : str
        Warp device.
    oracle_free : tuple of str, optional
        Baseline variables the diagnosis will calibrate: with them, whether the
        effect is identifiable is decided by :func:`oracle_evidence` (simulated
        at ``oracle_increment``, the diagnosis' increment); without, by the
        cheap screen "RMS change of the noise-free curve > 2 noise sd", which
        ignores what the calibration absorbs.
    oracle_increment : float
        Strain increment of the oracle refit.

    Returns
    -------
    SyntheticCase
    """
    if effect is not None and effect not in EFFECT_NAMES:
        raise KnitsimInputError(f"effect = {effect!r}: expected None or one of {', '.join(EFFECT_NAMES)}")
    if not (isinstance(strength, (int, float)) and 0.0 <= strength <= 1.0):
        raise KnitsimInputError(f"strength = {strength!r}: expected a number in [0, 1]")
    noise_rel = DEFAULT_NOISE_REL if noise_rel is None else noise_rel
    if not (isinstance(noise_rel, (int, float)) and math.isfinite(noise_rel) and noise_rel >= 0):
        raise KnitsimInputError(f"noise_rel = {noise_rel!r}: expected a number >= 0")
    if not (isinstance(scatter_rel, (int, float)) and math.isfinite(scatter_rel) and 0 <= scatter_rel < 0.2):
        raise KnitsimInputError(f"scatter_rel = {scatter_rel!r}: expected a number in [0, 0.2)")
    rates = tuple(float(r) for r in rates)
    if not rates or not all(math.isfinite(r) and r > 0 for r in rates):
        raise KnitsimInputError(f"rates = {rates!r}: expected one or more rates > 0 [mm/s]")
    rng = np.random.default_rng(int(seed))
    strain = measured_strains(test)
    shells = [curve_from_arrays(strain, np.zeros_like(strain), rate_mm_s=np.full(len(strain), r),
                                source=f"synthetic_{test}_{r:g}mm_s") for r in rates]
    # a specimen whose simulation (with or without the effect) does not finish is re-drawn from the same
    # generator: e.g. phi0 outside the effective friction cone of eq 10 at rest ends at the force cap
    for redraws in range(MAX_REDRAWS):
        true0 = draw_specimen(rng, material, float(scatter_rel))
        load_ref = 0.1
        if effect == "normal_load_friction":
            # reference load = median crossing load of the effect-free run (m keeps its meaning there)
            prog, _ = program_for_curve(shells[0], max_increment)
            h = run_batch([true0], prog, device=device)
            rn = np.abs(h.values["Rn"][:, 0])
            load_ref = float(max(np.median(rn[rn > 0]) if np.any(rn > 0) else 0.1, 1e-3))
        true, pname, pval = apply_effect(true0, effect, float(strength), material, rates, load_ref)
        sims = simulate_rows([true0, true] if effect is not None else [true0], shells, max_increment, device)
        if all(ok for per in sims for (_, _, ok) in per):
            break
    else:
        raise RuntimeError(f"synthetic case seed {seed}: no specimen of {material} runs ({test}, effect {effect}, "
                           f"strength {strength}) in {MAX_REDRAWS} draws")
    base_rows = sims[0]
    eff_rows = sims[-1]
    curves, clean, baseline, noise_sd = [], [], [], []
    for c, (fb, lab, okb), (fe, _, oke) in zip(shells, base_rows, eff_rows):
        sd = float(noise_rel) * float(np.max(fe))
        noisy = np.maximum(fe + sd * rng.standard_normal(len(fe)), 0.0)
        curves.append(curve_from_arrays(c.strain, noisy, c.cycle, c.direction, c.rate_mm_s, source=c.source))
        clean.append(fe)
        baseline.append(fb)
        noise_sd.append(sd)
    # where and how much the effect changes the noise-free curve (keys of the effect-free run)
    sse: dict[str, float] = {}
    diffs = []
    for c, (fb, lab, _), fe in zip(shells, base_rows, clean):
        keys = stage_keys(lab, c.direction, c.cycle)
        e = fe - fb
        diffs.append(e)
        for k, ek in zip(keys, e):
            sse[k] = sse.get(k, 0.0) + float(ek * ek)
    alld = np.concatenate(diffs)
    rms = float(math.sqrt(np.mean(alld * alld)))
    noise_rms = float(math.sqrt(np.mean(np.square(noise_sd))))
    oracle = None
    if effect is None:
        identifiable, reason, stage = False, "no effect", None
    else:
        stage = max(sse, key=sse.get) if any(v > 0 for v in sse.values()) else None
        if effect == "velocity_friction" and len(set(rates)) < 2:
            identifiable = False
            reason = "one test rate: a rate factor on m is absorbed by the calibrated m"
        elif oracle_free is not None:
            # the noise-free curves with the noise the oracle knows (a noise-free curve is smooth, and its
            # noise cannot be estimated from it: a model force a hair below zero would be refused)
            clean_curves = [curve_from_arrays(c.strain, fe, c.cycle, c.direction, c.rate_mm_s, source=c.source,
                                              noise_N=sd if sd > 0 else None)
                            for c, fe, sd in zip(shells, clean, noise_sd)]
            oracle = oracle_evidence(clean_curves, noise_sd, material, true0, effect, tuple(oracle_free),
                                     oracle_increment, device)
            identifiable = oracle["identifiable"]
            reason = (f"oracle refit of the baseline leaves lambda = {oracle['lambda']:.4g}: expected score "
                      f"{oracle['expected_score']:.4g} +- {oracle['score_sd']:.3g} "
                      + ("clears" if identifiable else "does not clear")
                      + f" {EVIDENCE_THRESHOLD:g} by {EVIDENCE_MARGIN_SD:g} sd")
        elif rms > 2.0 * noise_rms:
            identifiable = True
            reason = f"rms change {rms:.4g} N > 2 x noise sd {noise_rms:.4g} N (screen: no oracle refit)"
        else:
            identifiable = False
            reason = f"rms change {rms:.4g} N <= 2 x noise sd {noise_rms:.4g} N (screen: no oracle refit)"
    label = {
        "seed": int(seed), "material": material, "test": test, "rates": list(rates),
        "effect": effect, "strength": float(strength), "parameter": pname, "value": pval,
        "params": _plain(true.as_dict()), "true_stage": stage, "stage_sse": sse,
        "identifiable": bool(identifiable), "reason": reason,
        "rms_effect_N": rms, "max_effect_N": float(np.max(np.abs(alld))),
        "redraws": int(redraws), "noise_rel": float(noise_rel), "noise_sd_N": noise_sd, "scatter_rel": float(scatter_rel),
        "oracle": oracle,
    }
    return SyntheticCase(curves, label, clean, baseline)


def _plain(d):
    """Python floats in a (nested) dict, for JSON."""
    if isinstance(d, dict):
        return {k: _plain(v) for k, v in d.items()}
    if isinstance(d, (list, tuple)):
        return [_plain(v) for v in d]
    if isinstance(d, np.generic):
        return d.item()
    return d


def effect_range_check(material: str = "e_glass", test: str = "cyclic", strength: float = 0.5,
                       seed: int = 0, device: str = "cpu") -> dict:
    """Largest and RMS change of the noise-free curve per effect at ``strength`` (no scatter, no noise).

    An effect whose simulation never finishes is reported with ``error``.
    """
    out = {}
    for eff in EFFECT_NAMES:
        try:
            case = make_case(seed, material, test, eff, strength, noise_rel=0.0, scatter_rel=0.0, device=device)
        except RuntimeError as exc:
            out[eff] = {"error": str(exc)}
            continue
        out[eff] = {"max_change_N": case.label["max_effect_N"], "rms_change_N": case.label["rms_effect_N"],
                    "peak_N": float(max(np.max(c) for c in case.clean)), "true_stage": case.label["true_stage"],
                    "parameter": case.label["parameter"], "value": case.label["value"]}
    return out


# ============================================================================ lab specimens (issue 12)
#: the monotonic pull of a lab specimen stops at this force per wale [N]
PULL_FORCE_N = 5.0
#: strain between the rows of the pull and of the cycles (about 1,200 rows for the two tests)
LAB_ROW_STEP = {"pull": 0.0025, "cycles": 0.0035}
#: noise of a test: LAB_NOISE_REL x its peak force + LAB_NOISE_ABS [N] (a load cell's range and resolution)
LAB_NOISE_REL = 0.01
LAB_NOISE_ABS = 0.002
#: load-cell zero: an offset drawn uniformly in +-LAB_OFFSET_N per test
LAB_OFFSET_N = 0.002
#: extensometer jitter: sd of the strain read [-] (well below the reader's tolerance, 1e-3 of the range)
LAB_STRAIN_JITTER = 2.0e-6
#: probability that a test has one outlier row, off by 8 to 15 of its noise sd
LAB_OUTLIER_PROB = 0.3
#: share of rows logged twice, the second read stepping back by 1e-16 or 1e-6 (module make_specimen)
LAB_DUPLICATE_PROB = 0.02
#: specimen-to-specimen scatter of L, W0, C0, d
LAB_SCATTER_REL = 0.005


def _lab_strains(kind: str, top: float = 0.6) -> np.ndarray:
    h = LAB_ROW_STEP[kind]
    corners = [0.0, top] if kind == "pull" else [0.0, 0.6, 0.1, 0.6, 0.1, 0.6, 0.1]
    out = []
    for a, b in zip(corners[:-1], corners[1:]):
        n = int(round(abs(b - a) / h))
        out.extend((a + (b - a) * np.arange(1, n + 1) / n).tolist())
    return np.asarray(out)


def pull_end_strain(params: CellParams, force_N: float = PULL_FORCE_N, max_increment: float = 0.0025,
                    device: str = "cpu") -> float:
    """Strain at which a monotonic pull of ``params`` reaches ``force_N`` per wale (located by the
    force-cap event of the cell, :mod:`knitsim.cell.stages`)."""
    from ..cell.load_program import monotonic
    limit = params.L / (2.0 * params.C0) - 1.0
    h = run_batch([params.replace(force_cap_N=force_N)], monotonic(0.98 * limit, max_increment), device=device)
    caps = [e for e in h.events if e.get("kind") == "force_cap"]
    if not caps:
        raise RuntimeError(f"the pull does not reach {force_N} N before the yarn is straight")
    return float(caps[0]["C"] / params.C0 - 1.0)


def make_specimen(seed: int, material: str = "e_glass", effect: str | None = None, strength: float = 0.5,
                  noise_rel: float = LAB_NOISE_REL, noise_abs: float = LAB_NOISE_ABS,
                  scatter_rel: float = LAB_SCATTER_REL, rate: float = PAPER_RATE_MM_S,
                  max_increment: float = 0.0025, device: str = "cpu", oracle_free: tuple | None = None,
                  oracle_increment: float = 0.01) -> SyntheticCase:
    """A specimen as a laboratory tests it: two tests with their own noise, the way real files look.

    Tests: a monotonic pull to :data:`PULL_FORCE_N` per wale (rows every 0.0025 strain) and the
    paper's three cycles 0.10-0.60 (rows every 0.0035), at the paper's rate.  Each test's force
    noise is Gaussian, ``noise_rel`` x its peak + ``noise_abs`` (so the pull is about ten times
    noisier than the cycles, as a load cell sized for 5 N reads 0.2 N); forces are not clipped (a
    load cell reads around zero); each test has a load-cell offset (uniform within
    +-:data:`LAB_OFFSET_N`), strain jitter (:data:`LAB_STRAIN_JITTER`) and, with probability
    :data:`LAB_OUTLIER_PROB`, one outlier row; :data:`LAB_DUPLICATE_PROB` of the rows are logged
    twice, the second read stepping back by 1e-16 or 1e-6 (so the measured curves hold a few more
    rows than ``clean``, which stays on the planned rows).  The specimen scatters by ``scatter_rel``
    in L, W0, C0, d (:func:`draw_specimen`).  Hidden effect and identifiability as :func:`make_case`.
    """
    if effect is not None and effect not in EFFECT_NAMES:
        raise KnitsimInputError(f"effect = {effect!r}: expected None or one of {', '.join(EFFECT_NAMES)}")
    rng = np.random.default_rng(int(seed))
    rates = (float(rate),)
    for redraws in range(MAX_REDRAWS):
        true0 = draw_specimen(rng, material, float(scatter_rel))
        true, pname, pval = apply_effect(true0, effect, float(strength), material, rates, 0.1)
        if effect == "normal_load_friction":
            prog, _ = program_for_curve(curve_from_arrays(_lab_strains("cycles"), np.zeros(len(_lab_strains("cycles")))),
                                        max_increment)
            rn = np.abs(run_batch([true0], prog, device=device).values["Rn"][:, 0])
            ref = float(max(np.median(rn[rn > 0]) if np.any(rn > 0) else 0.1, 1e-3))
            true, pname, pval = apply_effect(true0, effect, float(strength), material, rates, ref)
        try:
            top = pull_end_strain(true, device=device)
        except RuntimeError:
            continue
        strains = {"pull": _lab_strains("pull", top), "cycles": _lab_strains("cycles")}
        shells = [curve_from_arrays(s, np.zeros(len(s)), rate_mm_s=np.full(len(s), rate), source=f"specimen_{k}.csv")
                  for k, s in strains.items()]
        sims = simulate_rows([true0, true] if effect is not None else [true0], shells, max_increment, device)
        # the specimen's own curves must run through; its effect-free twin (only the measure of the effect's
        # size) may stop at its force cap on a pull that the effect made longer
        if all(ok for (_, _, ok) in sims[-1]):
            break
    else:
        raise RuntimeError(f"lab specimen seed {seed}: no specimen of {material} runs (effect {effect}, "
                           f"strength {strength}) in {MAX_REDRAWS} draws")
    curves, clean, baseline, noise_sd, outliers = [], [], [], [], []
    for c, (fb, lab, _), (fe, _, _) in zip(shells, sims[0], sims[-1]):
        sd = float(noise_rel) * float(np.max(fe)) + float(noise_abs)
        force = fe + sd * rng.standard_normal(len(fe)) + float(rng.uniform(-LAB_OFFSET_N, LAB_OFFSET_N))
        if rng.random() < LAB_OUTLIER_PROB:
            i = int(rng.integers(5, len(fe) - 5))
            force[i] += float(rng.choice([-1.0, 1.0])) * float(rng.uniform(8.0, 15.0)) * sd
            outliers.append({"curve": c.source, "index": i})
        strain = c.strain + LAB_STRAIN_JITTER * rng.standard_normal(len(fe))
        # a logger sampling faster than the extensometer moves: some rows logged twice, the second read a
        # hair behind the first (a step back of 1e-16 .. 1e-6 inside a branch), with its own force noise
        dup = np.nonzero(rng.random(len(fe)) < LAB_DUPLICATE_PROB)[0]
        back = np.where(rng.random(len(dup)) < 0.5, 1e-16, 1e-6) * (1.0 + rng.random(len(dup)))
        strain = np.insert(strain, dup + 1, strain[dup] - back)
        force = np.insert(force, dup + 1, fe[dup] + sd * rng.standard_normal(len(dup)))
        # what a laboratory hands over: strain and force, no cycle or direction column
        curves.append(curve_from_arrays(strain, force, rate_mm_s=np.full(len(strain), rate), source=c.source))
        clean.append(fe)
        baseline.append(fb)
        noise_sd.append(sd)
    sse: dict[str, float] = {}
    diffs = []
    for c, (fb, lab, _), fe in zip(shells, sims[0], clean):
        e = fe - fb
        diffs.append(e)
        for k, ek in zip(stage_keys(lab, c.direction, c.cycle), e):
            sse[k] = sse.get(k, 0.0) + float(ek * ek)
    alld = np.concatenate(diffs)
    oracle = None
    if effect is None:
        identifiable, reason, stage = False, "no effect", None
    else:
        stage = max(sse, key=sse.get) if any(v > 0 for v in sse.values()) else None
        if effect == "velocity_friction":
            identifiable, reason = False, "one test rate: a rate factor on m is absorbed by the calibrated m"
        elif oracle_free is not None:
            # the noise-free curves with the noise the oracle knows (a noise-free curve is smooth, and its
            # noise cannot be estimated from it: a model force a hair below zero would be refused)
            clean_curves = [curve_from_arrays(c.strain, fe, c.cycle, c.direction, c.rate_mm_s, source=c.source,
                                              noise_N=sd if sd > 0 else None)
                            for c, fe, sd in zip(shells, clean, noise_sd)]
            oracle = oracle_evidence(clean_curves, noise_sd, material, true0, effect, tuple(oracle_free),
                                     oracle_increment, device, offsets=True)
            identifiable = oracle["identifiable"]
            reason = (f"oracle refit of the baseline leaves lambda = {oracle['lambda']:.4g}: expected score "
                      f"{oracle['expected_score']:.4g} +- {oracle['score_sd']:.3g} "
                      + ("clears" if identifiable else "does not clear")
                      + f" {EVIDENCE_THRESHOLD:g} by {EVIDENCE_MARGIN_SD:g} sd")
        else:
            rms = float(math.sqrt(np.mean(alld * alld)))
            noise_rms = float(math.sqrt(np.mean(np.square(noise_sd))))
            identifiable = rms > 2.0 * noise_rms
            reason = f"rms change {rms:.4g} N vs 2 x noise sd {noise_rms:.4g} N (screen: no oracle refit)"
    label = {
        "seed": int(seed), "material": material, "test": LAB, "rates": list(rates),
        "effect": effect, "strength": float(strength), "parameter": pname, "value": pval,
        "params": _plain(true.as_dict()), "true_stage": stage, "stage_sse": sse,
        "identifiable": bool(identifiable), "reason": reason,
        "rms_effect_N": float(math.sqrt(np.mean(alld * alld))), "max_effect_N": float(np.max(np.abs(alld))),
        "redraws": int(redraws), "noise_sd_N": noise_sd, "scatter_rel": float(scatter_rel),
        "pull_end_strain": float(top), "outliers": outliers, "oracle": oracle,
    }
    return SyntheticCase(curves, label, clean, baseline)
