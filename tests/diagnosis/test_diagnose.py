"""The diagnosis (knitsim.diagnosis.diagnose, knitsim.scene.diagnosis_scene, ``knitsim diagnose``).

Synthetic measured curves are simulated here with a known effect switched on
(the kernel effects, tests/cell/test_effects.py) plus white noise; the
diagnosis gets the curves and the nominal specimen only.  Expected values:
the hidden effect (identification), no effect on an effect-free curve (noise
alone must not name one), the noise sd of a known Gaussian (statistics), and
the JSON keys the issue prescribes.
"""
from __future__ import annotations

import json

import re

import numpy as np
import pytest

from knitsim.cell.batch import run_batch
from knitsim.cell.effects import EffectSet
from knitsim.cell.load_program import cycles
from knitsim.cell.material import CellParams
from knitsim.diagnosis.diagnose import DiagnosisSetup, diagnose, estimate_noise
from knitsim.diagnosis.measured import curve_from_arrays
from knitsim.cli import main
from knitsim.errors import KnitsimInputError
from knitsim.scene.diagnosis_scene import load_diagnosis_scene

NOMINAL = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2)   # Dusserre (2015) Table 1, section 2.2
PROGRAM = cycles(0.1, 0.6, 2, 0.01)
FEW = ("coiling_angle_friction", "normal_load_friction", "bending_hysteresis", "yarn_extension")


def _measured(cell: CellParams, seed: int = 1, noise_rel: float = 0.02, rate=None):
    h = run_batch([cell], PROGRAM)
    F = h.values["F"][:, 0]
    rng = np.random.default_rng(seed)
    sd = noise_rel * F.max()
    Fm = np.maximum(F + rng.normal(0.0, sd, len(F)), 0.0)
    r = None if rate is None else np.full(len(F), float(rate))
    return curve_from_arrays(PROGRAM.strain, Fm, PROGRAM.cycle, PROGRAM.direction, r, source="synthetic"), sd


@pytest.fixture(scope="module")
def coiling_result():
    truth = NOMINAL.replace(phi0=-0.05, effects=EffectSet(on=("coiling_angle_friction",), coil_mu_k=0.3))
    curve, _ = _measured(truth)
    return diagnose([curve], DiagnosisSetup(base=NOMINAL, effects=FEW, pair=True)).as_dict()


def test_a_hidden_coiling_effect_is_named(coiling_result):
    r = coiling_result
    assert r["verdict"]["effect"] == "coiling_angle_friction"
    assert r["verdict"]["confident"]
    best = r["candidates"][0]
    assert best["effect"] == "coiling_angle_friction" and best["significant"]
    assert best["params"]["coil_mu_k"] == pytest.approx(0.3, rel=0.05)
    assert best["shrink"] > 0.5
    # the model with the true effect fits within the noise, the baseline does not (adequacy test, step 5)
    assert best["within_noise"] is True and r["noise"]["baseline_within_noise"] is False
    assert best["chi2_per_dof"] < r["noise"]["baseline_chi2_per_dof"]
    # candidates sorted best first by score; shrink = 1 - rms_after / rms_before (issue 6)
    scores = [c["score"] for c in r["candidates"] if c["score"] is not None]
    assert scores == sorted(scores, reverse=True)
    assert best["shrink"] == pytest.approx(1 - best["rms_N"] / r["baseline"]["rms_N"], rel=1e-12)


def test_stage_shares_partition_the_gap(coiling_result):
    """sum_k share_k = 1 and sum_k n_k rms_k^2 = n rms^2 (the keys partition the rows)."""
    b = coiling_result["baseline"]
    assert sum(s["share"] for s in b["stages"].values()) == pytest.approx(1.0, abs=1e-12)
    n = sum(s["n"] for s in b["stages"].values())
    assert sum(s["n"] * s["rms_N"] ** 2 for s in b["stages"].values()) == pytest.approx(n * b["rms_N"] ** 2, rel=1e-10)
    assert coiling_result["where"][0] == max(b["stages"], key=lambda k: b["stages"][k]["share"])


def test_result_has_the_issue_schema(coiling_result):
    r = json.loads(json.dumps(coiling_result))
    assert {"params", "rms_N", "stages"} <= set(r["baseline"])
    assert all({"rms_N", "share"} <= set(s) for s in r["baseline"]["stages"].values())
    assert {"effect", "params", "rms_N", "stages", "shrink", "score"} <= set(r["candidates"][0])
    assert {"effect", "stage", "shrink", "confident"} <= set(r["verdict"])
    assert r["pair"] is None or len(r["pair"]["effects"]) == 2


def test_noise_alone_names_no_effect():
    curve, _ = _measured(NOMINAL.replace(phi0=-0.05), seed=3)
    r = diagnose([curve], DiagnosisSetup(base=NOMINAL, effects=FEW, pair=False)).as_dict()
    assert r["verdict"]["effect"] is None and r["verdict"]["kind"] == "none"
    assert r["noise"]["baseline_within_noise"] is True
    assert not any(c["significant"] and c["practical"] for c in r["candidates"])


def test_evidence_from_a_curve_of_assumed_noise_is_marked():
    """A digitised (noise-free) curve carries the effect; a second test of known, huge noise (sd = its
    peak force) tells next to nothing.  The digitised curve's noise cannot be estimated (it says so, and 0.5 % of
    its range is assumed); the effect is named from it, but its evidence is marked as resting on
    assumed noise and the verdict is not confident (issue 12, item 1)."""
    truth = NOMINAL.replace(phi0=-0.05, effects=EffectSet(on=("coiling_angle_friction",), coil_mu_k=0.3))
    F = run_batch([truth], PROGRAM).values["F"][:, 0]
    smooth = curve_from_arrays(PROGRAM.strain, F, PROGRAM.cycle, PROGRAM.direction, source="digitised")
    noisy, _ = _measured(truth, seed=5, noise_rel=1.0)
    noisy = curve_from_arrays(noisy.strain, noisy.force, noisy.cycle, noisy.direction, source="noisy")
    r = diagnose([smooth, noisy], DiagnosisSetup(base=NOMINAL, effects=("coiling_angle_friction",),
                                                 pair=False)).as_dict()
    by = {c["source"]: c for c in r["noise"]["curves"]}
    assert by["digitised"]["method"] == "assumed" and not by["digitised"]["estimable"]
    assert by["noisy"]["method"] == "estimated"
    (c,) = r["candidates"]
    assert c["drop_by_curve"]["digitised"] > 10 * abs(c["drop_by_curve"]["noisy"])
    assert c["rests_on_assumed_noise"] and "assumed" in c["note"]
    v = r["verdict"]
    assert v["effect"] == "coiling_angle_friction" and not v["confident"]
    assert "digitised is assumed" in v["reason"] and "rests on it" in v["reason"]


def test_force_cap_at_three_peaks_leaves_the_curve_below_it_unchanged():
    """capped_setup stops cells at 3 x the largest measured force; below that force the simulated
    curve is the uncapped one bit for bit (the cap is an event of the jammed branch only), and the
    scene's cap is kept when it is lower."""
    from knitsim.cell.load_program import monotonic
    from knitsim.diagnosis.diagnose import FORCE_CAP_FACTOR, capped_setup

    prog = monotonic(0.9, 0.01)
    F = run_batch([NOMINAL], prog).values["F"][:, 0]
    rows = np.arange(10, 60)
    curve = curve_from_arrays(prog.strain[rows], F[rows], source="pull")
    setup = capped_setup(DiagnosisSetup(base=NOMINAL), [curve])
    assert setup.base.force_cap_N == pytest.approx(FORCE_CAP_FACTOR * F[rows].max())
    Fc = run_batch([setup.base], prog).values["F"][:, 0]
    below = np.nonzero(F < setup.base.force_cap_N)[0]
    below = below[below < np.argmax(F >= setup.base.force_cap_N)] if np.any(F >= setup.base.force_cap_N) else below
    np.testing.assert_array_equal(Fc[below], F[below])
    low = DiagnosisSetup(base=NOMINAL.replace(force_cap_N=0.5 * F[rows].max()))
    assert capped_setup(low, [curve]) is low


def test_velocity_friction_needs_two_rates():
    """At one rate eq 5's V^p factor is a constant, i.e. a change of m: not identifiable."""
    curve, _ = _measured(NOMINAL, rate=1.0)
    r = diagnose([curve], DiagnosisSetup(base=NOMINAL, effects=("velocity_friction",), pair=False)).as_dict()
    (c,) = r["candidates"]
    assert c["identifiable"] is False and c["score"] is None and "rates" in c["note"]


def test_noise_estimate_recovers_a_known_gaussian():
    """sigma from the chord deviations (1.4826 MAD): within 3 standard errors (~1.65 sigma / sqrt(2 n))."""
    rng = np.random.default_rng(7)
    s = np.linspace(0.001, 0.6, 2000)
    f = 0.1 + 0.3 * s ** 2
    sd = 0.004
    c = curve_from_arrays(s, f + rng.normal(0, sd, len(s)), source="x")
    est = estimate_noise([c])
    assert abs(est - sd) < 3 * 1.65 * sd / np.sqrt(2 * len(s)) + 0.02 * sd


SCENE = """
title = "test"
[yarn]
d = 0.58
B = 0.31
[knit]
L = 14.1
W0 = 4.4
C0 = 2.7
[friction]
m = 0.2
[diagnosis]
free = ["m", "phi0"]
effects = ["coiling_angle_friction", "yarn_extension"]
pair = false
"""


@pytest.mark.parametrize("patch, message", [
    (lambda t: t.replace("[diagnosis]", "[diagnosisx]"), "missing table \\[diagnosis\\]"),
    (lambda t: t.replace('"yarn_extension"]', '"magic"]'), "magic.*expected one of"),
    (lambda t: t.replace('free = ["m", "phi0"]', 'free = ["m", "E"]'), "free\\[1\\].*expected one of"),
    (lambda t: t + "bounds = { m = [0.5, 0.1] }\n", "low < high"),
    (lambda t: t + "noise_N = -1\n", "noise_N"),
    (lambda t: t.replace("W0 = 4.4", "W0 = 2.0"), "W0"),
    (lambda t: t + '[load]\ntype = "monotonic"\ntarget_strain = 0.5\n', "no \\[load\\]"),
    # phi0 is fitted as a fraction of phimax (|phi0| <= phimax): a bound of 5 is 5 phimax
    (lambda t: t + "bounds = { phi0 = [-5.0, 5.0] }\n", "bounds.phi0.*within \\[-1, 1\\]"),
    # W0 = 4.4 mm: d above 4.4 / 4 = 1.1 mm would jam the loops at rest (the cell scene's W0 >= 4 d)
    (lambda t: t + "bounds = { d = [0.5, 1.2] }\n", "bounds.d.*W0 >= 4 d.*d <= 1.1 mm"),
])
def test_bad_scenes_are_refused_naming_the_key(tmp_path, patch, message):
    path = tmp_path / "s.toml"
    path.write_text(patch(SCENE))
    with pytest.raises(KnitsimInputError, match=message):
        load_diagnosis_scene(path)


def test_cli_writes_json_and_report(tmp_path, capsys):
    truth = NOMINAL.replace(effects=EffectSet(on=("coiling_angle_friction",), coil_mu_k=0.3))
    curve, _ = _measured(truth, seed=5)
    csv = tmp_path / "m.csv"
    rows = ["strain,force_per_wale_N,cycle,direction"] + [
        f"{float(s)!r},{float(f)!r},{int(c)},{'load' if d > 0 else 'unload'}"
        for s, f, c, d in zip(curve.strain, curve.force, curve.cycle, curve.direction)]
    csv.write_text("\n".join(rows) + "\n")
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE)
    out, rep = tmp_path / "d.json", tmp_path / "d.html"
    # in-process, as the other CLI tests (the installed package, not the source tree, is imported)
    assert main(["diagnose", str(csv), "--scene", str(scene), "--json", str(out), "--report", str(rep),
                 "--quiet"]) == 0
    r = json.loads(out.read_text())
    assert r["verdict"]["effect"] == "coiling_angle_friction"
    assert rep.read_text().startswith("<!DOCTYPE html>")
    capsys.readouterr()
    assert main(["diagnose", str(csv), "--scene", str(tmp_path / "no.toml")]) == 2
    err = capsys.readouterr().err
    assert "no.toml" in err and "Traceback" not in err


def test_size_threshold_half_the_excess_at_its_lower_bound_or_half_the_chi2_spread():
    # hand-made adequacy results: dof 1225, spread s = 0.0712 x 1225 = 87.22 (chi^2 units), so
    # tolerance 3.09 s = 269.5, the excess's 95 % lower bound is excess - 1.645 s = excess - 143.5, and the
    # floor half of chi^2's spread for noise alone: 0.5 sqrt(2 x 1225) = 24.75 (by hand, size_threshold's formula)
    from knitsim.diagnosis.diagnose import Adequacy, is_practical, size_threshold
    within = Adequacy(chi2=1375.0, dof=1225, chi2_per_dof=1375 / 1225, expected_sd=0.0712, within_noise=True,
                      excess=150.0)
    assert size_threshold(within) == pytest.approx(0.5 * np.sqrt(2450.0))     # 0.5 x 6.5 = 3.3 < the floor
    assert is_practical(33.0, within)              # 22 % of a noisy excess, but above the floor 24.75
    assert not is_practical(20.0, within)          # below the floor: a detail no fit of the whole resolves
    below = Adequacy(chi2=1195.0, dof=1225, chi2_per_dof=1195 / 1225, expected_sd=0.0712, within_noise=True,
                     excess=-30.0)
    assert not is_practical(19.0, below)           # chi^2/dof < 1 no longer lets any drop through
    assert is_practical(28.0, below)
    beyond = Adequacy(chi2=2225.0, dof=1225, chi2_per_dof=2225 / 1225, expected_sd=0.0712, within_noise=False,
                      excess=1000.0)
    assert beyond.tolerance == pytest.approx(3.09 * 0.0712 * 1225)
    assert size_threshold(beyond) == pytest.approx(0.5 * (1000.0 - 1.645 * 0.0712 * 1225))   # 428.3
    assert is_practical(430.0, beyond)
    assert not is_practical(420.0, beyond)         # below 428.3, and 580 left beyond the tolerance 269.5
    near = Adequacy(chi2=1725.0, dof=1225, chi2_per_dof=1725 / 1225, expected_sd=0.0712, within_noise=False,
                    excess=500.0)
    assert is_practical(180.0, near)               # threshold 0.5 x (500 - 143.5) = 178.3
    assert not is_practical(150.0, near)           # below it, and 350 left beyond the tolerance 269.5
    edge = Adequacy(chi2=1525.0, dof=1225, chi2_per_dof=1525 / 1225, expected_sd=0.0712, within_noise=False,
                    excess=300.0)
    assert is_practical(40.0, edge)                # below 0.5 x 156.5 = 78.3, but 260 left is within the noise
    assert not is_practical(0.0, near) and not is_practical(-5.0, within)


def test_discretisation_step_refines_the_replay_until_halving_it_changes_nothing():
    """The lab cycles (rows 0.0035 apart) replayed at 0.01 and refined (discretisation_step).

    Limit cases: with a noise sd of 1e3 N no replay change weighs anything, so the coarse increment
    stays; with 1e-4 N (a change of 1e-4 N on one row is already chi^2 1) the increment is refined, and
    an independent replay at a quarter of the chosen increment (rss_of_cells, no weights: in N^2)
    differs from the chosen one by a chi^2 of at most DISCRETISATION_CHI2 (x 2 for the further halving,
    which the step's own two-in-a-row rule bounds by 1 + 1)."""
    from knitsim.diagnosis.calibrate import rss_of_cells
    from knitsim.diagnosis.diagnose import DISCRETISATION_CHI2, _Data, _forces, discretisation_step
    from knitsim.diagnosis.synthetic import _lab_strains
    # a point of the lab calibration (m 0.2017, phi0 -0.5 phimax) under Dahl friction with the coiling
    # angle's friction ratio: a Dahl cell reads that ratio at the start of each increment (increment-
    # lagged, knitsim.cell.effects), so its replay depends on the increment (chi^2 5.7e4 at sd 1e-4
    # between 0.01 and 0.01 / 64).  (Every other law is read at the state itself: the Coulomb events
    # are located inside their increment, the plain cell's slack included since issue 14; a Coulomb
    # cell's coiling or normal-load ratio since issue 12; the bending stiffness at the state's own C
    # since, its replay at 0.01 equal to the one at 0.01 / 64 to chi^2 1e-16 at sd 1e-4.)
    cell = NOMINAL.replace(m=0.2017, phi0=-0.5 * np.arctan(0.2017), d=0.5778, L=14.2313, C0=2.7129,
                           friction="dahl", dahl_sigma=200.0,
                           effects=EffectSet(on=("coiling_angle_friction",), coil_mu_k=0.3))
    strain = _lab_strains("cycles")
    shell = curve_from_arrays(strain, np.zeros(len(strain)), source="rows.csv")
    (f_true,), _ = _forces([shell], [cell], 0.01 / 64, "cpu")
    curve = curve_from_arrays(strain, f_true[:, 0], source="rows.csv")
    for sd, refined in ((1e3, False), (1e-4, True)):
        setup = DiagnosisSetup(base=NOMINAL, max_increment=0.01)
        data = _Data([curve], setup, [np.full(len(curve), 1.0 / sd)])
        disc = discretisation_step(data, [{"params": cell}])
        assert disc.coarse_increment == 0.01
        assert (disc.final_increment < 0.01) == refined
        if refined:
            h = disc.final_increment
            (a,), _ = _forces([curve], [cell], h, "cpu")
            (b,), _ = _forces([curve], [cell], h / 4, "cpu")
            e = (a[:, 0] - b[:, 0]) - np.mean(a[:, 0] - b[:, 0])       # offsets removed, as the fit does
            assert float(e @ e) / sd ** 2 <= 2 * DISCRETISATION_CHI2 + 1e-9 or not disc.resolved
            # the coarse replay does differ here: the refinement was needed
            assert rss_of_cells([curve], [cell], 0.01, offsets=True)[0] / sd ** 2 > DISCRETISATION_CHI2


def test_rivals_step_refits_only_candidates_within_the_margin_of_the_best():
    """Rivals are the significant candidates within RIVAL_MARGIN (100) of the best BIC score (its definition):
    one significant candidate, or a second one 150 behind, leaves nothing to refit (no calibration runs:
    data is not even needed)."""
    from knitsim.diagnosis.diagnose import RIVAL_MARGIN, CandidateResult, rivals_step
    assert RIVAL_MARGIN == 100.0
    best = CandidateResult("yarn_compaction", "", True, score=5150.0, significant=True)
    far = CandidateResult("yarn_extension", "", True, score=5000.0, significant=True)
    weak = CandidateResult("bending_hysteresis", "", True, score=5140.0, significant=False)
    fits = {"yarn_compaction": {}, "yarn_extension": {}}
    assert rivals_step(None, [best], fits, print) == (fits, [])
    assert rivals_step(None, [best, weak, far], fits, print) == (fits, [])


def test_baseline_reaches_the_minimum_of_a_specimen_whose_lengths_are_off():
    """An effect-free specimen whose C0 is 1.1 % long (the study's case 74, seed 0: a 2 sd draw of its
    0.5 % scatter; its friction m = 0.172, phi0 = 0.634 phimax): the generating parameters lie in
    the baseline's family (m, phi0, d, L, C0 free; W0 at the scene's value), so the minimum of
    chi^2 on noise-free curves replayed at the fit's own increment is 0 (an identity).  From the
    scene's geometry alone the fit ended where the yarn diameter took up the offset (d 18 % thick,
    chi^2/dof 6.9 on the noisy specimen); the starts from the corners of the +-1 % square in L and C0
    reach the specimen's basin.  At the searches' replay increment (0.01) chi^2 is a staircase in the
    parameters (an event is caught at the end of the increment it falls in): on the straight line from
    the fit's end to the truth it falls 1663 -> 0 in uneven steps, with the same roughness before the
    slack location by bisection (1606 -> 0 from the same point), so a local fit stops on a step inside
    the basin.  Hence the bound: chi^2/dof < 2 (the scene-geometry starts end at 5.9 on these curves).

    The neighbourhood scan (diagnose.scan_neighbourhood) then moves that fit (chi^2 1663: m 0.160,
    phi0 0.159, d 0.576, C0 2.7304) to a basin of chi^2 114 (m 0.178, phi0 -0.136, d 0.564, C0 2.719,
    L 13.92), lower at every replay increment (0.01 to 0.0025) though not the truth's 0: on these
    noise-free curves both are within the noise (chi^2/dof 1.4 and 0.1), and the lengths and the
    diameter are not identified beyond that.  Checked: the fit is within the noise (the truth's chi^2 is 0)
    and C0 lies nearer the specimen's than the scene's (the corners' purpose)."""
    from knitsim.diagnosis.diagnose import _Data, calibrate_step, noise_step
    from knitsim.diagnosis.effects import DEFAULT_STUDY_FREE
    from knitsim.diagnosis.synthetic import _lab_strains, material_params, pull_end_strain, simulate_rows

    base = material_params("e_glass")
    m = 0.1718
    truth = base.replace(C0=base.C0 * 1.0112, L=base.L * 0.9983, m=m, phi0=0.634 * np.arctan(m))
    shells = [curve_from_arrays(s, np.zeros(len(s)), source=src) for src, s in
              (("pull", _lab_strains("pull", pull_end_strain(truth))), ("cycles", _lab_strains("cycles")))]
    (sims,) = simulate_rows([truth], shells, 0.01)
    sds = [0.01 * float(np.max(f)) + 0.002 for f, _, _ in sims]   # the lab model's noise of each test
    curves = [curve_from_arrays(c.strain, f, c.cycle, c.direction, source=c.source, noise_N=sd)
              for c, (f, _, ok), sd in zip(shells, sims, sds)]
    setup = DiagnosisSetup(base=base, free=DEFAULT_STUDY_FREE).validated()
    data = _Data(curves, setup, noise_step(curves, setup).weights(curves))
    fit, _ = calibrate_step(data, lambda msg: None)
    assert fit["chi2"] / (fit["n"] - fit["k"]) < 2.0
    assert abs(fit["values"]["C0"] - truth.C0) < abs(base.C0 - truth.C0)


def test_outliers_are_isolated_rows_inside_one_stage_not_misfits_at_a_change_of_stage():
    """The outlier rule (diagnose._outliers): a row more than OUTLIER_Z (6) sd off the fit whose neighbours
    are within 3 sd, all three simulated in one stage, or at a change of stage a row that is itself a
    spike of the measured curve.  Hand-made curve (sd 0.01 N, a load to strain 0.1 and back) and fits:
    a 10 sd spike of the fit on an interior loading row is an outlier (z = +10); 10 sd misfits on the
    first unloading row (its neighbour before is loading: a reversal) and on the first row (adherence,
    its neighbour sliding: the end of the initial stick) are the timing of a change of stage and are
    kept; a measured row 20 sd below the smooth curve at the reversal (15 sd below both neighbours) is
    an outlier (z = +20)."""
    from knitsim.diagnosis.diagnose import OUTLIER_Z, _Data, _outliers
    assert OUTLIER_Z == 6.0
    strain = np.concatenate([np.linspace(0.0, 0.1, 11), np.linspace(0.09, 0.0, 10)])
    force = np.concatenate([np.linspace(0.0, 1.0, 11), np.linspace(0.5, 0.0, 10)])
    sd = 0.01
    keys = (["loading_adherence"] + ["loading_sliding"] * 10 + ["unloading_sliding"] * 10)
    weights = [np.full(len(strain), 1.0 / sd)]
    curve = curve_from_arrays(strain, force, source="hand.csv")
    simulated = force.copy()
    simulated[5] += 10 * sd          # a spike inside loading sliding
    simulated[11] -= 10 * sd         # the first unloading row
    simulated[0] += 10 * sd          # the first row, where the initial stick ends
    found = _outliers(_Data([curve], None, weights), {"curves": [{"simulated": simulated, "keys": keys}]})
    assert [(o.source, o.row, round(o.z, 6)) for o in found] == [("hand.csv", 7, 10.0)]   # row 5 is spreadsheet row 7
    spiked = force.copy()
    spiked[11] -= 20 * sd            # a measured spike on the first unloading row
    curve = curve_from_arrays(strain, spiked, source="hand.csv")
    found = _outliers(_Data([curve], None, weights), {"curves": [{"simulated": force, "keys": keys}]})
    assert [(o.row, round(o.z, 6)) for o in found] == [(13, 20.0)]


def test_basins_step_reaches_an_effect_that_moves_the_geometry_that_fits():
    """A bending hysteresis of h = 0.40 on a specimen whose lengths are a hair off the scene's (the
    study's lab case 75, seed 0: its parameters below, W0 0.07 % narrow and not calibrated), with the
    lab model's noise of each test (1 % of its peak + 0.002 N, seeded).  The effect stiffens loading
    and softens unloading, so the geometry that fits moves with it: the candidate's own race (from the
    baseline, with h at 0, 0.2, 0.45) and the screen at the baseline's basins both end at h ~ 0.22,
    chi^2 ~ 2,200 on 1,189 rows, where the truth scores 1,223 (the noise alone: 1,189 +- 49).
    Expected: after the basins step the fit is in the truth's basin (chi^2 within 2 sd of the noise of
    the truth's own, an independent number: the generating cell evaluated on these curves) and its h
    within 0.03 of the generating 0.4014.  Fails without the races from the baseline's grid starts."""
    from knitsim.diagnosis.diagnose import _Data, basins_step, calibrate_step, candidates_step, noise_step
    from knitsim.diagnosis.effects import DEFAULT_STUDY_FREE, build_params
    from knitsim.diagnosis.synthetic import _lab_strains, material_params, pull_end_strain, simulate_rows

    base = material_params("e_glass")
    m, bend_h = 0.2035, 0.4014
    truth = base.replace(d=0.5784, L=14.036, W0=4.3968, C0=2.6995, m=m, phi0=0.2803 * np.arctan(m),
                         effects=EffectSet(on=("bending_hysteresis",), bend_h=bend_h))
    shells = [curve_from_arrays(s, np.zeros(len(s)), source=src) for src, s in
              (("pull", _lab_strains("pull", pull_end_strain(truth))), ("cycles", _lab_strains("cycles")))]
    (sims,) = simulate_rows([truth], shells, 0.01)
    rng = np.random.default_rng(75)
    curves = []
    for c, (f, _, ok) in zip(shells, sims):
        assert ok
        sd = 0.01 * float(np.max(f)) + 0.002
        curves.append(curve_from_arrays(c.strain, f + rng.normal(0.0, sd, len(f)), c.cycle, c.direction,
                                        source=c.source, noise_N=sd))
    setup = DiagnosisSetup(base=base, free=DEFAULT_STUDY_FREE, effects=("bending_hysteresis",)).validated()
    data = _Data(curves, setup, noise_step(curves, setup).weights(curves))
    base_fit, _ = calibrate_step(data, lambda msg: None)
    fits = candidates_step(data, base_fit["fit_variables"], setup.effects, [], lambda msg: None,
                           base_chi2=base_fit["chi2"])
    fits, tried = basins_step(data, base_fit, fits, lambda msg: None)
    assert tried == ["bending_hysteresis"]
    fit = fits["bending_hysteresis"]
    x_truth = dict(m=m, phi0=0.2803, d=truth.d, L=truth.L, C0=truth.C0, bend_h=bend_h)
    (chi2_truth,) = data.chi2_of([build_params(base, ("bending_hysteresis",), x_truth, setup.fixed)])
    n = fit["n"]
    assert fit["chi2"] < chi2_truth + 2.0 * np.sqrt(2.0 * n)
    assert fit["fit_variables"]["bend_h"] == pytest.approx(bend_h, abs=0.03)


def test_a_strain_in_per_cent_is_refused_before_any_solve():
    # L = 14.1 mm, C0 = 2.7 mm: C < L/2 (a straight yarn) means strain < 14.1 / 5.4 - 1 = 1.611; the
    # curve 0 .. 0.03 logged in per cent reaches 3 on its last row (spreadsheet row 5: the header is
    # row 1), and the message says what per cent would mean
    setup = DiagnosisSetup(base=NOMINAL, effects=("yarn_extension",), pair=False)
    c = curve_from_arrays([0.0, 1.0, 2.0, 3.0], [0.0, 0.1, 0.2, 0.3], source="pct.csv")
    with pytest.raises(KnitsimInputError, match=r"pct.csv: row 5, column strain: 3 cannot be reached.*"
                                                r"strain < 1.611.*per cent"):
        diagnose([c], setup)


def test_a_curve_given_twice_is_refused():
    # the same rows twice would double their weight in every chi2
    setup = DiagnosisSetup(base=NOMINAL, effects=("yarn_extension",), pair=False)
    c = curve_from_arrays([0.0, 0.01, 0.02], [0.0, 0.1, 0.2], source="a.csv")
    with pytest.raises(KnitsimInputError, match="a.csv: given more than once"):
        diagnose([c, c], setup)
    # the same file by another path (./a.csv) or a copy (b.csv): the same rows, refused as well
    for other in ("./a.csv", "b.csv"):
        d = curve_from_arrays([0.0, 0.01, 0.02], [0.0, 0.1, 0.2], source=other)
        with pytest.raises(KnitsimInputError, match=f"{other}: the same rows as a.csv"):
            diagnose([c, d], setup)


def test_a_none_verdict_beside_a_heavier_effect_says_its_evidence_is_weak():
    """Step 8 on hand-set candidates: the baseline within its noise, and coiling_angle_friction with a BIC
    score of 2 (below the STRONG 10 that naming needs) yet a probability of 0.41 against none's 0.34. The
    verdict stays none, confident (the rule), and now says why the heavier probability is not a finding;
    with no candidate heavier than none, nothing is added."""
    from knitsim.diagnosis.diagnose import (STRONG, Adequacy, CandidateResult, Localisation, NoiseModel,
                                            verdict_step)
    adequacy = Adequacy(chi2=110.0, dof=100, chi2_per_dof=1.1, expected_sd=0.14, within_noise=True, excess=10.0)
    loc = Localisation(keys=["loading_sliding"], stages={}, where=["loading_sliding"])

    def cand(effect, score, prob):
        return CandidateResult(effect, "", True, score=score, probability=prob, significant=score > STRONG)
    heavy = [cand("coiling_angle_friction", 2.0, 0.41), cand("yarn_extension", -1.0, 0.25)]
    v = verdict_step(adequacy, heavy, loc, {}, NoiseModel([]), [])
    assert v.kind == "none" and v.confident and v.probabilities["none"] == pytest.approx(0.34)
    assert "coiling_angle_friction weighs 0.41 against none 0.34" in v.reason and "weak evidence" in v.reason
    light = [cand("coiling_angle_friction", 2.0, 0.2), cand("yarn_extension", -1.0, 0.1)]
    assert "weighs" not in verdict_step(adequacy, light, loc, {}, NoiseModel([]), []).reason



def test_a_baseline_within_an_assumed_noise_is_none_not_confident_not_unexplained():
    """Step 8 on hand-set candidates, every curve's noise assumed (within_noise None: not judged).  A baseline at
    chi2/dof 0.89 on 300 dof (a probe's logger file printing 0.01 N, its noise assumed at the rounding's sd) lies
    within that noise by the adequacy's own rule (chi2 - dof <= 3.09 sd x dof), so no gap is seen: the verdict is
    `none`, not confident (the noise is a guess), naming no stage, and saying that an effect's heavier probability
    is weak evidence.  Before, it read `unexplained`, "the largest gap
    is in stage loading_sliding ... none of them fits within the noise".  Beyond that tolerance (chi2/dof 1.5, 6
    sd) it stays `unexplained`, not confident."""
    from knitsim.diagnosis.diagnose import Adequacy, CandidateResult, Localisation, NoiseModel, verdict_step
    from knitsim.diagnosis.noise import CurveNoise
    noise = NoiseModel([CurveNoise("logger.csv", 0.00289, "assumed", 304, False, "assumed")])
    loc = Localisation(keys=["loading_sliding"], stages={}, where=["loading_sliding"])
    cands = [CandidateResult("bending_hysteresis", "", True, score=9.4, probability=0.98, significant=False)]
    sd = (2.0 / 300) ** 0.5
    within = Adequacy(chi2=266.0, dof=300, chi2_per_dof=266 / 300, expected_sd=sd, within_noise=None, excess=-34.0)
    v = verdict_step(within, cands, loc, {"stages": {}}, noise, [])
    assert v.kind == "none" and not v.confident and v.stage is None
    assert "within their assumed noise" in v.reason and "logger.csv" in v.reason and "--noise-N" in v.reason
    # its heavier probability without the evidence to be named is said, as beside a `none` of known noise
    assert "bending_hysteresis weighs 0.98" in v.reason and "weak evidence" in v.reason
    beyond = Adequacy(chi2=450.0, dof=300, chi2_per_dof=1.5, expected_sd=sd, within_noise=None, excess=150.0)
    v = verdict_step(beyond, cands, loc, {"stages": {}}, noise, [])
    assert v.kind == "unexplained" and not v.confident

def test_a_verdict_on_curves_that_carry_almost_no_force_is_not_confident():
    """A hand-made unloading logged at the slack end: 60 rows from strain 0.6 down to 0.1, the first two
    carrying 3 and 1 N per wale, the rest a load cell reading 0 +- 4 mN (white noise). Within its noise
    whatever the model (it carries nothing), so "none" would be easy; with 2 rows above 5 noise sd
    (fewer than MIN_LOADED_ROWS = 10) the verdict says the curves say little, and is not confident."""
    from knitsim.diagnosis.diagnose import MIN_LOADED_ROWS
    rng = np.random.default_rng(2)
    s = np.linspace(0.6, 0.1, 60)
    f = np.concatenate([[3.0, 1.0], rng.normal(0.0, 0.004, 58)])
    c = curve_from_arrays(s, f, source="unload.csv")     # the first row ends the loading from rest
    d = diagnose([c], DiagnosisSetup(base=NOMINAL, effects=("yarn_extension",), pair=False))
    assert MIN_LOADED_ROWS == 10 and not d.verdict.confident
    assert "only 2 of 60 rows (3%) carry force above 5 noise sd" in d.verdict.reason


def test_no_share_of_an_excess_that_lies_within_the_noise():
    """Step 6 on a hand-set fit: a candidate's share of the baseline's excess over noise is drop / excess, a number
    only where that excess is beyond the noise.  A probe's effect-free cycles (NumPy reference, m 0.35, 906 dof, an
    excess of 17.8 in chi2 within the noise's tolerance of 230) had coiling_angle_friction, 18,173 worse than the
    baseline, read "share of gap -102064%" (-18173.3 / 17.8, a share of noise); now none.  Beyond the noise the
    share is the quotient, here by hand: a drop of 250 of an excess of 500 is 0.5."""
    from knitsim.diagnosis.diagnose import Adequacy, Localisation, score_step
    setup = DiagnosisSetup(base=NOMINAL, free=("m", "phi0"), effects=("coiling_angle_friction",))
    measured, keep = np.zeros(4), np.ones(4, bool)
    loc = Localisation(keys=["loading_sliding"] * 4, stages={}, where=["loading_sliding"])

    def share(base_chi2, fit_chi2, within):
        base = {"chi2": base_chi2, "k": 2, "rss_N2": 1.0, "stages": {}}
        fit = {"values": {}, "std_errors": {}, "chi2": fit_chi2, "k": 3, "nfev": 1,
               "curves": [{"simulated": np.full(4, 0.1), "final_status": "ok", "source": "x"}]}
        ad = Adequacy(chi2=base_chi2, dof=906, chi2_per_dof=base_chi2 / 906, expected_sd=0.082, within_noise=within,
                      excess=base_chi2 - 906)
        return score_step(setup, {"coiling_angle_friction": fit}, base, ad, loc, measured, keep, [], 4)[0].share_of_excess

    assert share(923.8, 923.8 + 18173.3, True) is None
    assert share(1406.0, 1156.0, False) == pytest.approx(0.5)


def test_an_effect_that_removes_less_than_half_of_a_clear_excess_is_not_confident():
    """Step 8 on hand-set candidates: a baseline beyond its noise (chi2 1,493 on 1,000 dof), one effect with
    the evidence (BIC score 58) and the size (its drop clears half the excess at the excess's 95 % lower bound)
    that removes 48 % of the excess (a blind probe: the forces of a stiffer yarn x 1.3 with B held fixed,
    named normal_load_friction, confident).  Offered as the explanation it should be the larger part of the
    gap: named, not confident, and the reason says why and what to try; at 60 % it stays confident; one
    that leaves the curves beyond their noise says a further cause remains."""
    from knitsim.diagnosis.diagnose import Adequacy, CandidateResult, Localisation, NoiseModel, verdict_step
    adequacy = Adequacy(chi2=1493.0, dof=1000, chi2_per_dof=1.493, expected_sd=0.069, within_noise=False,
                        excess=493.0)
    loc = Localisation(keys=["loading_sliding"], stages={}, where=["loading_sliding"])

    def cand(share, chi2_per_dof=1.04, within_noise=True):
        return CandidateResult("normal_load_friction", "", True, score=58.0, probability=1.0, significant=True,
                               practical=True, share_of_excess=share, chi2_per_dof=chi2_per_dof,
                               within_noise=within_noise)
    v = verdict_step(adequacy, [cand(0.48)], loc, {"stages": {}}, NoiseModel([]), [])
    assert v.kind == "effect" and v.effect == "normal_load_friction" and not v.confident
    assert "removes 48% of the baseline's excess over noise, less than half" in v.reason and "free it" in v.reason
    assert verdict_step(adequacy, [cand(0.6)], loc, {"stages": {}}, NoiseModel([]), []).confident
    v = verdict_step(adequacy, [cand(0.7, 4.018, False)], loc, {"stages": {}}, NoiseModel([]), [])
    assert v.kind == "effect" and "chi2/dof = 4.018): a further cause remains" in v.reason


def test_a_setup_built_in_python_is_checked_as_the_scene_is():
    """DiagnosisSetup from the API: a typo in bounds, a bound on a variable not fitted, phi0 bounds in
    radians beyond a fraction of phimax, free as one string, max_nfev = 0 were ignored or failed mid-fit
    (a blind probe); each is refused before any work, as the scene's [diagnosis] is."""
    for kw, msg in ((dict(bounds={"dd": (0.1, 0.2)}), r"bounds\['dd'\]: not a fitted variable"),
                    (dict(bounds={"B": (0.1, 0.7)}), r"bounds\['B'\]: not a fitted variable"),
                    (dict(bounds={"phi0": (-5.0, 5.0)}), r"a fraction of phimax"),
                    (dict(free="phi0"), r"expected a list of names"),
                    (dict(max_nfev=0), r"max_nfev = 0"),
                    # the largest Dahl stiffness a cell takes is 10^6 / mm (cell.stages.DAHL_SIGMA_MAX): a bound of
                    # 10^7 failed mid-fit, after the baseline's calibration, naming cell.dahl_sigma
                    (dict(bounds={"log10_dahl_sigma": (0.0, 7.0)}),
                     r"log10_dahl_sigma'\] = \(0.0, 7.0\): .* up to 6 ")):
        with pytest.raises(KnitsimInputError, match=msg):
            DiagnosisSetup(base=NOMINAL, **kw).validated()
    DiagnosisSetup(base=NOMINAL, bounds={"m": (0.05, 0.5)}).validated()
    DiagnosisSetup(base=NOMINAL, bounds={"log10_dahl_sigma": (0.0, 6.0)}).validated()


def test_two_curves_met_halfway_are_said_to_disagree():
    """Hand-made: a pull f = 2 s^2 and the same pull x 1.3 (another specimen), one fit through both at 1.15 f
    (what one model does with two that differ): on each curve's loaded rows (f > 5 sd, sd 0.01 N) the fit
    lies above the first (+0.15 f / sd) and below the second (-0.15 f / sd), far beyond 3 standard errors:
    said.  The fit above both (1.5 f): not a disagreement, nothing said."""
    from knitsim.diagnosis.diagnose import NoiseModel, curves_disagree
    from knitsim.diagnosis.noise import curve_noise

    s = np.linspace(0.0, 0.6, 121)
    f = 2.0 * s ** 2
    a = curve_from_arrays(s, f, source="a.csv", noise_N=0.01)
    b = curve_from_arrays(s, 1.3 * f, source="b.csv", noise_N=0.01)
    one = np.ones(len(s), int)
    noise = NoiseModel([curve_noise(s, f, one, one, "a.csv", 0.01), curve_noise(s, 1.3 * f, one, one, "b.csv", 0.01)])
    w = [np.full(len(s), 100.0)] * 2
    said = curves_disagree([a, b], {"curves": [{"simulated": 1.15 * f}] * 2}, w, noise)
    assert "the fit lies above a.csv" in said and "below b.csv" in said
    assert curves_disagree([a, b], {"curves": [{"simulated": 1.5 * f}] * 2}, w, noise) == ""


def test_an_effect_pressed_against_a_bound_that_leaves_a_misfit_larger_than_the_noise_is_not_confirmed():
    """The rule of pressed_and_short on hand-set fits: a blind probe's stiffer yarn (x 1.4, B held fixed) was
    named bending_hysteresis, confident, with phi0 at its upper bound and chi2/dof 4.0 left.  A parameter at a
    bound *and* chi2/dof above 2 (a misfit larger than the noise itself): not confirmed.  Each alone is not
    enough (the blind study's right effects: a bound with chi2/dof 1.28 left, yarn extension removing 99.6 %
    of its excess)."""
    from knitsim.diagnosis.diagnose import SHORT_CHI2_PER_DOF, CandidateResult, pressed_and_short
    assert SHORT_CHI2_PER_DOF == 2.0

    def cand(chi2_per_dof, within):
        return CandidateResult("bending_hysteresis", "", True, score=900.0, probability=1.0, significant=True,
                               practical=True, share_of_excess=0.7, chi2_per_dof=chi2_per_dof, within_noise=within)
    at = {"at_bounds": {"phi0": "upper"}}
    assert pressed_and_short(cand(4.018, False), at)
    assert not pressed_and_short(cand(4.018, False), {"at_bounds": {}})
    assert not pressed_and_short(cand(1.28, False), at)
    assert not pressed_and_short(cand(1.02, True), at)


def test_an_effect_that_a_pure_force_scale_explains_as_well_is_not_named_confidently():
    """The model's own three cycles 0.20-0.72 x 1.1 with B held fixed (tests/diagnosis/data/README.md: a wrong
    wale count or width, or B 10 % off).  No effect is there, but the baseline at B 0.31 misses the jammed
    branches (chi2/dof ~49) and bending_hysteresis removed 85 % of the excess, leaving chi2/dof 8.3 with no
    parameter at a bound: named, confident.  The model's force is proportional to B (the elastica and the
    Coulomb friction are homogeneous in it), so the baseline with B free is the baseline times a factor, which
    must come out 1.1 (the file's own factor) with the friction of the file (m 0.20, phi0 0.05 rad) and fit
    within the noise; it beats the effect, and the verdict is not confident and says so."""
    from pathlib import Path

    from knitsim.diagnosis.diagnose import STRONG
    from knitsim.diagnosis.measured import read_measured_curve
    curve = read_measured_curve(Path(__file__).parent / "data" / "eglass_3cycles_to0.72_x1.1_noise2mN.csv")
    base = NOMINAL.replace(m=0.25, phi0=0.0, unloading_rule="dusserre", reload_rule="mirror_unloading",
                           force_cap_N=50.0)
    r = diagnose([curve], DiagnosisSetup(base=base, effects=("bending_hysteresis", "normal_load_friction"),
                                         pair=False)).as_dict()
    v = r["verdict"]
    assert v["effect"] == "bending_hysteresis" and r["candidates"][0]["within_noise"] is False
    assert not v["confident"] and v["reason"].startswith("a pure force scale explains the curves as well")
    sc = r["force_scale"]
    assert sc["factor"] == pytest.approx(1.1, rel=0.01)
    assert sc["params"]["m"] == pytest.approx(0.20, abs=0.005) and sc["within_noise"] is True
    assert sc["bic_minus_effect"] < -STRONG and sc["rivals_effect"]
    # a factor on the force is no factor on the strain: the strain scale (tests below) does not rival the effect
    assert r["strain_scale"]["bic_minus_effect"] > STRONG and not r["strain_scale"]["rivals_effect"]


def test_an_unexplained_gap_that_a_pure_force_scale_explains_says_so():
    """The same model-made cycles x 1.1 with only normal_load_friction searched: it removes 1 % of the excess, no
    effect is named, and the verdict was a confident `unexplained` (chi2/dof 48.9) that said nothing of the scale,
    where an effect's verdict weighs it.  The scale is weighed against the baseline as an effect would be (BIC drop
    beyond STRONG and a practical chi2 drop): expected 1.1 (the file's own factor), within the noise, said first,
    and the verdict not confident; the JSON's force_scale holds it (no effect to weigh it against)."""
    from pathlib import Path

    from knitsim.diagnosis.diagnose import STRONG
    from knitsim.diagnosis.measured import read_measured_curve
    curve = read_measured_curve(Path(__file__).parent / "data" / "eglass_3cycles_to0.72_x1.1_noise2mN.csv")
    base = NOMINAL.replace(m=0.25, phi0=0.0, unloading_rule="dusserre", reload_rule="mirror_unloading",
                           force_cap_N=50.0)
    r = diagnose([curve], DiagnosisSetup(base=base, effects=("normal_load_friction",), pair=False)).as_dict()
    v, sc = r["verdict"], r["force_scale"]
    assert v["kind"] == "unexplained" and r["noise"]["baseline_within_noise"] is False
    assert not v["confident"] and v["reason"].startswith("a pure force scale explains the gap (the baseline x 1.1")
    assert sc["factor"] == pytest.approx(1.1, rel=0.01) and sc["within_noise"] and sc["explains"]
    assert sc["bic_minus_baseline"] < -STRONG and sc["bic_minus_effect"] is None and not sc["rivals_effect"]
    # the strain scale lowers the chi2 too (11.7 per dof), but the force scale is named as the better of the two
    assert r["strain_scale"]["bic_minus_baseline"] - sc["bic_minus_baseline"] > STRONG
    assert "the force scale fits better than the strain scale" in v["reason"]


def _strain_scaled(name: str, effects=("bending_hysteresis",)) -> dict:
    from pathlib import Path

    from knitsim.diagnosis.measured import read_measured_curve
    curve = read_measured_curve(Path(__file__).parent / "data" / name)
    base = NOMINAL.replace(m=0.25, phi0=0.0, unloading_rule="dusserre", reload_rule="mirror_unloading",
                           force_cap_N=50.0)
    return diagnose([curve], DiagnosisSetup(base=base, effects=effects, pair=False)).as_dict()


def test_an_unexplained_gap_that_a_strain_scale_explains_names_the_strain():
    """The model's own cycles 0.20-0.72 with the strain x 1.03 (tests/diagnosis/data/README.md: an extensometer's
    gauge length 3 % short; no effect, the knit of the file).  The baseline misses the jammed branches by far
    (chi2/dof ~4000) and the verdict was `unexplained`, saying only that a force scale (x 0.5, at the end of B's
    search, chi2/dof 282) explains the gap: the force blamed for the strain.  The strain scale (the replay at
    strain / k, weighed against the baseline as an effect is) must come out 1.03, the file's own factor, within
    its standard error, with the friction of the file (m 0.20, phi0 0.05 rad), within the noise; said first, as
    the better of the two scales, and the verdict not confident."""
    from knitsim.diagnosis.diagnose import STRONG
    r = _strain_scaled("eglass_3cycles_to0.72_strain_x1.03_noise2mN.csv")
    v, sc, fs = r["verdict"], r["strain_scale"], r["force_scale"]
    assert v["kind"] == "unexplained" and r["noise"]["baseline_within_noise"] is False and not v["confident"]
    assert abs(sc["factor"] - 1.03) <= sc["factor_se"], (sc["factor"], sc["factor_se"])
    assert sc["params"]["m"] == pytest.approx(0.20, abs=0.005) and sc["params"]["phi0"] == pytest.approx(0.05, abs=0.01)
    assert sc["within_noise"] and sc["explains"] and sc["bic_minus_baseline"] < -STRONG
    assert v["reason"].startswith("a pure strain scale explains the gap (the replay at strain / 1.03")
    assert "the strain may be off: read x 1.03 the knit's" in v["reason"]
    # both scales lower the chi2 beyond the size threshold here; the reason says which fits better
    assert fs["explains"] and fs["bic_minus_baseline"] - sc["bic_minus_baseline"] > STRONG
    assert "the strain scale fits better than the force scale" in v["reason"]


def test_the_probes_strain_x103_cycles_below_jamming_name_the_strain_not_the_force():
    """The outside probe's file (tests/diagnosis/data/README.md): the model's own cycles 0.1-0.6 with the strain
    x 1.03.  The old verdict, `unexplained`, said that "a pure force scale x 1.043 explains the gap ... the forces
    may be off".  The strain scale fits within the noise and better than the force scale by far: named first.  Below
    jamming the factor trades with the friction (the README: strain / 1.014 and / 1.030 fit within 1 in chi2 of
    each other), so only its range is asked here, a few per cent above 1."""
    from knitsim.diagnosis.diagnose import STRONG
    r = _strain_scaled("eglass_3cycles_strain_x1.03_noise2mN.csv")
    v, sc, fs = r["verdict"], r["strain_scale"], r["force_scale"]
    assert v["kind"] == "unexplained" and not v["confident"]
    assert 1.01 < sc["factor"] < 1.035 and sc["within_noise"] and sc["explains"]
    assert v["reason"].startswith("a pure strain scale explains the gap")
    assert fs["bic_minus_baseline"] - sc["bic_minus_baseline"] > STRONG
    assert "the strain scale fits better than the force scale" in v["reason"]


def test_where_both_scales_explain_the_gap_the_reason_says_which_fits_better_or_that_none_can_tell():
    """Hand-set scale fits (scale_step's keys): both explain an unexplained gap; the better (lower BIC) is said
    first, and the reason says which fits better where their BICs differ by more than STRONG, else that the data
    cannot tell them apart; said before the reason where one fits within the noise, after it otherwise."""
    from knitsim.diagnosis.diagnose import STRONG, scales_said

    def scale(kind, bic, within):
        sc = {"kind": kind, "factor": 1.03, "factor_se": 0.001, "chi2_per_dof": 1.0 if within else 1.5,
              "within_noise": within, "bic_minus_baseline": bic, "bic_minus_effect": None}
        return dict(sc, B=0.32, B_scene=0.31) if kind == "force" else sc
    text = scales_said("REASON", [scale("force", -100.0, False), scale("strain", -100.0 - 2 * STRONG, True)],
                       None, 1.8)
    assert text.startswith("a pure strain scale explains the gap (the replay at strain / 1.03 +- 0.001")
    assert text.index("a pure force scale") > text.index("the strain may be off: read x 1.03 the knit's")
    assert "the strain scale fits better than the force scale (BIC -20)" in text and text.endswith("REASON")
    text = scales_said("REASON", [scale("force", -100.0, False), scale("strain", -100.0 + STRONG / 2, False)],
                       None, 1.8)
    assert text.startswith("REASON; a pure force scale explains the gap")
    assert "the data cannot tell the force scale from the strain scale (BIC within 10: 5)" in text
    # a factor at the end of its search (calibrate.at_bounds) is said to be so, not quoted as an estimate (the blind
    # study's case 39, compaction, v22: its strain scale at the search's 1.25 read "strain / 1.25 +- 0.061")
    text = scales_said("REASON", [dict(scale("strain", -100.0, False), factor=1.25, at_bounds={"strain_scale": "upper"})],
                       None, 1.8)
    assert "strain / 1.25 +- 0.001 (the end of its search: the data ask for more, the value is not an estimate)" in text


def test_the_strain_scale_raises_no_alarm_on_an_effect_free_curve():
    """No false alarm: on the model's own effect-free cycles (2 mN of noise; the file of the next test) the strain
    scale, weighed against the baseline as an effect is, must not explain anything (its BIC drop is noise's) and
    must come out 1 within 3 of its standard errors (the scale the file was made at)."""
    from pathlib import Path

    from knitsim.diagnosis.diagnose import (_Data, calibrate_step, capped_setup, noise_step, scale_step)
    from knitsim.diagnosis.measured import read_measured_curve
    curve = read_measured_curve(Path(__file__).parent / "data" / "eglass_3cycles_m0.20_phi0.05_noise2mN.csv")
    setup = DiagnosisSetup(base=NOMINAL.replace(m=0.25, phi0=0.0, unloading_rule="dusserre",
                                                reload_rule="mirror_unloading", force_cap_N=10.0),
                           effects=("bending_hysteresis",), pair=False).validated()
    noise = noise_step([curve], setup)
    data = _Data([curve], capped_setup(setup, [curve]), noise.weights([curve]))
    base_fit, _ = calibrate_step(data, lambda msg: None)
    sc = scale_step(data, base_fit, None, len(curve), noise, lambda msg: None, "strain")
    assert not sc["explains"] and sc["within_noise"]
    assert abs(sc["factor"] - 1.0) <= 3.0 * sc["factor_se"], (sc["factor"], sc["factor_se"])


def test_a_curve_the_model_made_is_not_read_as_a_gap_beside_a_cliff_of_chi2():
    """Nothing is missing (tests/diagnosis/data/README.md: the model's own curve at m 0.20, phi0 0.05 rad,
    2 mN of noise, made and sampled outside the package's generators).  Started from m 0.25, phi0 0, the
    baseline's local fit stopped at m 0.187 (chi^2 832 on 311 rows, where the truth gives ~326): beside
    it the chi^2 falls by a cliff (a later reload's force jumps from 0.3 to 14 mN as m crosses 0.199),
    and the diagnosis read a confident `unexplained`.  Expected: none, the friction within a few per
    cent of the truth, chi^2/dof within the noise band."""
    from pathlib import Path

    from knitsim.diagnosis.measured import read_measured_curve
    curve = read_measured_curve(Path(__file__).parent / "data" / "eglass_3cycles_m0.20_phi0.05_noise2mN.csv")
    base = NOMINAL.replace(m=0.25, phi0=0.0, unloading_rule="dusserre", reload_rule="mirror_unloading",
                           force_cap_N=10.0)
    r = diagnose([curve], DiagnosisSetup(base=base, effects=("bending_hysteresis",), pair=False)).as_dict()
    assert r["verdict"]["kind"] == "none", r["verdict"]["reason"]
    assert abs(r["baseline"]["params"]["m"] - 0.20) < 0.005
    assert abs(r["baseline"]["params"]["phi0"] - 0.05) < 0.015
    assert r["noise"]["baseline_within_noise"]
    assert r["curves"][0]["slack_start"] is None
    # nothing wrong, nothing flagged: no drift of the zero (force_drift), no glitch, no stall
    assert r["curves"][0]["drift"] is None and r["curves"][0]["glitch_rows"] == [] == r["curves"][0]["stall_rows"]



def test_an_effect_within_the_noise_that_a_force_scale_explains_as_well_is_not_named_confidently():
    """The same model-made cycles x 1.03 (tests/diagnosis/data/README.md): bending_hysteresis brought them within
    their noise (chi2/dof 1.07, score 126) and was named, confident, so that a check asked only where the named
    effect leaves a misfit did not run.  The scale (1.03, the file's own factor) fits as well or better: the
    verdict is not confident.  (That "within the noise" rested on the file's 2 mN read as 0.00195 N + 0.58 % of
    the force, the jamming's kinks taken for noise: noise.KINK_SIGMAS.  Read as made, one sd, bending_hysteresis
    leaves chi2/dof 1.53 and the scale fits within the noise, 0.93: said first.)"""
    from pathlib import Path

    from knitsim.diagnosis.measured import read_measured_curve
    curve = read_measured_curve(Path(__file__).parent / "data" / "eglass_3cycles_to0.72_x1.03_noise2mN.csv")
    base = NOMINAL.replace(m=0.25, phi0=0.0, unloading_rule="dusserre", reload_rule="mirror_unloading",
                           force_cap_N=50.0)
    r = diagnose([curve], DiagnosisSetup(base=base, effects=("bending_hysteresis",), pair=False)).as_dict()
    v = r["verdict"]
    assert r["noise"]["curves"][0]["per_N"] == 0
    assert v["effect"] == "bending_hysteresis"
    assert not v["confident"] and "a pure force scale explains the curves as well" in v["reason"]
    assert r["force_scale"]["factor"] == pytest.approx(1.03, abs=0.004) and r["force_scale"]["rivals_effect"]
    assert r["force_scale"]["within_noise"] and v["reason"].startswith("a pure force scale")


def test_the_console_shares_out_no_gap_where_the_baseline_fits_within_the_noise():
    """A confident `none` ("nothing is missing") printed "gap by stage: unloading_sliding 82 %": the share of a
    chi2 excess that lies within the noise, which reads as a gap.  Where the baseline is within the noise the line
    says there is no gap (the README: a `none` verdict names no stage); beyond it the shares are printed as before.
    Hand-set results: the shares' figures themselves are gap.stage_gap's (tested there)."""
    from knitsim.cli.diagnose import _stage_line

    def result(within):
        return {"where": ["unloading_sliding", "loading_sliding"],
                "baseline": {"stages": {"unloading_sliding": {"share": 0.82}, "loading_sliding": {"share": 0.18}}},
                "noise": {"baseline_within_noise": within}}
    line = _stage_line(result(True))
    assert line.startswith("gap by stage: none beyond the noise") and "%" not in line and "unloading" not in line
    assert _stage_line(result(False)) == "gap by stage: unloading_sliding 82%, loading_sliding 18%"
    # no curve's noise known (adequacy not judged): the shares are printed, as before, but where the verdict is
    # `none` (the baseline within the assumed noise: verdict_step) there is no gap to share out either
    assert _stage_line(result(None)) == "gap by stage: unloading_sliding 82%, loading_sliding 18%"
    assert _stage_line(dict(result(None), verdict={"kind": "none"})).startswith("gap by stage: none beyond the noise")


def test_the_console_says_no_stage_has_a_gap_where_none_exceeds_the_noise(tmp_path, capsys):
    """The model's own single cycle (tests/diagnosis/data/README.md): no stage's chi2 exceeds its rows, so the
    chi2 excess has no share to give out (gap.stage_gap: NaN).  The console printed "nan%" for every stage;
    it says there is no gap beyond the noise."""
    from pathlib import Path
    scene = tmp_path / "s.toml"
    scene.write_text('[yarn]\nd = 0.58\nB = 0.31\n[knit]\nL = 14.1\nW0 = 4.4\nC0 = 2.7\n[friction]\nm = 0.25\n'
                     '[rules]\nunloading_rule = "dusserre"\nreload_rule = "mirror_unloading"\nforce_cap_N = 10.0\n'
                     '[diagnosis]\nfree = ["m", "phi0"]\neffects = ["bending_hysteresis"]\n')
    csv = Path(__file__).parent / "data" / "eglass_1cycle_m0.20_phi0.05_noise2mN.csv"
    assert main(["diagnose", str(csv), "--scene", str(scene), "--no-pair", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "nan" not in out.lower()
    assert "gap by stage: none beyond the noise" in out and "verdict: none" in out
    # the baseline's fitted m and phi0 with their standard errors; the truth (m 0.20, phi0 0.05, the file's
    # README) within 3 of them
    line = next(ln for ln in out.splitlines() if ln.startswith("baseline:"))
    for name, truth in (("m", 0.20), ("phi0", 0.05)):
        value, se = re.search(rf"\b{name} = ([-0-9.e]+) \+- ([0-9.e-]+)", line).groups()
        assert 0 < float(se) and abs(float(value) - truth) <= 3 * float(se), line


def test_a_force_clipped_flat_at_its_largest_reading_leaves_no_verdict_confident(tmp_path, capsys):
    """The model's own single cycle (tests/diagnosis/data/README.md), every force above 80 % of its peak written as
    that limit (a load cell that saturated: 21 rows over the top of the loading and the start of the unloading).
    Expected: the read line names the flat force and its rows (measured.flat_tops), and the verdict is not
    confident, its reason naming the file and the flat rows."""
    from pathlib import Path
    scene = tmp_path / "s.toml"
    scene.write_text('[yarn]\nd = 0.58\nB = 0.31\n[knit]\nL = 14.1\nW0 = 4.4\nC0 = 2.7\n[friction]\nm = 0.25\n'
                     '[rules]\nunloading_rule = "dusserre"\nreload_rule = "mirror_unloading"\nforce_cap_N = 10.0\n'
                     '[diagnosis]\nfree = ["m", "phi0"]\neffects = ["bending_hysteresis"]\n')
    lines = (Path(__file__).parent / "data" / "eglass_1cycle_m0.20_phi0.05_noise2mN.csv").read_text().splitlines()
    j = lines[0].split(",").index("force_per_wale_N")
    limit = round(0.8 * max(float(ln.split(",")[j]) for ln in lines[1:]), 6)
    out_lines = [lines[0]]
    for ln in lines[1:]:
        cells = ln.split(",")
        cells[j] = repr(min(float(cells[j]), limit))
        out_lines.append(",".join(cells))
    flat = [i + 2 for i, ln in enumerate(out_lines[1:]) if float(ln.split(",")[j]) == limit]
    csv = tmp_path / "clipped.csv"
    csv.write_text("\n".join(out_lines) + "\n")
    main(["diagnose", str(csv), "--scene", str(scene), "--no-pair", "--quiet", "--json", str(tmp_path / "d.json")])
    out = capsys.readouterr().out
    assert json.loads((tmp_path / "d.json").read_text())["curves"][0]["flat_top_rows"] == flat
    assert f"flat at {limit:g} N per wale, its largest reading, over rows {flat[0]}-{flat[-1]}" in out, out
    verdict = next(ln for ln in out.splitlines() if ln.startswith("verdict:"))
    assert "not confident" in verdict and f"clipped.csv: the force is flat at its largest reading over {len(flat)} " \
        f"rows from row {flat[0]}" in verdict, verdict


def test_the_console_says_a_parameter_at_its_bound_instead_of_an_error(tmp_path, capsys):
    """The same file (truth m 0.20), m bounded to [0.15, 0.19] and in_plane_width free (a single cycle that never
    jams: the data do not constrain it, and it rests on its lower bound 0.58 = d): the baseline line says m is at
    its bound (the data push it beyond: calibrate.at_bounds) and in_plane_width not determined by the data (they
    do not push it anywhere), never "+- 0" (a blind probe: the covariance's pseudo-inverse gives zero variance to
    a direction the data do not constrain), and gives phi0 its error."""
    from pathlib import Path
    scene = tmp_path / "s.toml"
    scene.write_text('[yarn]\nd = 0.58\nB = 0.31\n[knit]\nL = 14.1\nW0 = 4.4\nC0 = 2.7\n[friction]\nm = 0.25\n'
                     '[rules]\nunloading_rule = "dusserre"\nreload_rule = "mirror_unloading"\nforce_cap_N = 10.0\n'
                     '[diagnosis]\nfree = ["m", "phi0", "in_plane_width"]\nbounds = { m = [0.15, 0.19] }\n'
                     'effects = ["bending_hysteresis"]\n')
    csv = Path(__file__).parent / "data" / "eglass_1cycle_m0.20_phi0.05_noise2mN.csv"
    main(["diagnose", str(csv), "--scene", str(scene), "--no-pair", "--quiet"])
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("baseline:"))
    assert "m = 0.19 (at its upper bound)" in line and "in_plane_width = 0.58 (not determined by the data)" in line, line
    assert "+- 0," not in line and "+- 0)" not in line and re.search(r"phi0 = [0-9.]+ \+- [0-9.]+", line), line


def test_a_curve_that_starts_slack_is_said_where_the_fitted_model_lies_above_its_toe():
    """Hand-made first loading: 5 rows at 0 N +- noise (sd 2 mN) from strain 0 to 0.016, then the knit.
    Expected from the definition (diagnose.slack_start): a fitted model 50 mN above those rows (25 sd) is a
    slack start ending at 0.016 (5 rows, the mean excess 0.05 N); a model that follows the toe (within the
    noise) is not; a toe of 2 rows (< SLACK_MIN_ROWS) is not; the fitted offset is removed first (a model
    50 mN above everywhere with a 50 mN offset is not above the toe)."""
    from knitsim.diagnosis.diagnose import slack_start
    from knitsim.diagnosis.noise import CurveNoise
    s = np.array([0.0, 0.004, 0.008, 0.012, 0.016, 0.02, 0.03, 0.04, 0.05])
    f = np.array([0.001, -0.002, 0.003, -0.004, 0.0, 0.037, 0.071, 0.075, 0.08])
    curve = curve_from_arrays(s, f, source="toe.csv", noise_N=0.002)
    nz = CurveNoise("toe.csv", 0.002, "given", 0, True, "")
    sim = np.r_[np.full(5, 0.05), f[5:]]
    sl = slack_start(curve, nz, sim)
    assert sl is not None and sl["strain_to"] == 0.016 and sl["rows"] == 5
    assert sl["model_above_N"] == pytest.approx(0.05 - np.mean(f[:5]))
    assert "toe.csv" in sl["message"] and "0.016" in sl["message"]
    assert slack_start(curve, nz, np.r_[f[:5] + 0.001, f[5:]]) is None
    assert slack_start(curve, nz, sim + 0.05, offset_N=0.1) is None
    short = curve_from_arrays(s, np.r_[f[:2], 0.02, 0.03, 0.035, f[5:]], source="short.csv", noise_N=0.002)
    assert slack_start(short, nz, sim) is None


def test_a_blind_probes_specimen_mounted_slack_is_not_confident_and_says_so():
    """A blind probe's file (tests/diagnosis/data/README.md): the model's curve shifted by a 2 % slack start
    (5 rows of 0 N +- 2 mN to strain 0.016, then the knit at grip strain (1 + e) 1.02 - 1).  The diagnosis
    cannot make a slack start: its verdict must not be confident and must name the toe (the JSON's curves'
    slack_start, the verdict's reason).  The unshifted curve has none (the cliff test's file)."""
    from pathlib import Path

    from knitsim.diagnosis.measured import read_measured_curve
    curve = read_measured_curve(Path(__file__).parent / "data" / "eglass_3cycles_slack2pc_noise2mN.csv")
    base = NOMINAL.replace(m=0.25, phi0=0.0, unloading_rule="dusserre", reload_rule="mirror_unloading",
                           force_cap_N=10.0)
    r = diagnose([curve], DiagnosisSetup(base=base, effects=("bending_hysteresis",), pair=False)).as_dict()
    sl = r["curves"][0]["slack_start"]
    assert sl is not None and sl["strain_to"] == pytest.approx(0.016) and sl["rows"] == 5
    assert not r["verdict"]["confident"] and "mounted slack" in r["verdict"]["reason"]
    # said first (a second probe's slack start read "yarn_extension ... probability 1" before the toe was said)
    assert r["verdict"]["reason"].startswith(sl["message"] + "; until then: ")


def test_a_rival_stopped_at_the_end_of_its_search_makes_the_verdict_not_confident():
    """A blind probe's yarn extension of 0.5 1/N (ten times the end of ext_c's search, 0.05) was given p 0.000
    beside a confident yarn_compaction.  Expected from the definition (capped_candidates): a candidate other than
    the named one whose effect variable rests at the end of its search, away from where the effect vanishes, is
    said; one resting where its effect vanishes (compaction_k near 0, the Coulomb end of the Dahl stiffness:
    effect-free specimens of the blind study, cases 0-2 and 13 of seed 0, rest there) is not, nor is the named
    effect."""
    from knitsim.diagnosis.diagnose import CandidateResult, capped_candidates
    ext = CandidateResult("yarn_extension", "", True, params={"m": 0.99, "ext_c": 0.05}, at_bounds={"ext_c": "upper"})
    comp = CandidateResult("yarn_compaction", "", True, params={"compaction_k": 1.3e-5},
                           at_bounds={"compaction_k": "lower"})
    dahl = CandidateResult("dahl_transition", "", True, params={"log10_dahl_sigma": 3.0},
                           at_bounds={"log10_dahl_sigma": "upper"})
    text = capped_candidates([ext, comp, dahl], "bending_hysteresis")
    assert text.startswith("yarn_extension's fit stopped at the upper end of its search (ext_c = 0.05 1/N)")
    assert "compaction" not in text and "dahl" not in text and "does not rule it out" in text
    assert capped_candidates([ext, comp], "yarn_extension") == ""
    assert capped_candidates([comp, dahl], None) == ""
    soft = CandidateResult("dahl_transition", "", True, params={"log10_dahl_sigma": -0.5},
                           at_bounds={"log10_dahl_sigma": "lower"})
    assert "dahl_transition's fit stopped at the lower end" in capped_candidates([soft], "none")


def test_a_curve_below_the_knits_force_at_rest_is_said_to_be_on_another_scale():
    """A blind probe's curve in kN under a header in N got a confident "unexplained".  Expected from the definition
    (force_scale_mismatch): every reading below half the fitted model's force at the first row (less its offset)
    is said, naming the largest reading, the model's force and their ratio; a curve that rises above it is not."""
    from types import SimpleNamespace

    from knitsim.diagnosis.diagnose import force_scale_mismatch
    kn = SimpleNamespace(force=np.array([2.2e-5, 9e-5, 1.83e-4]), source="/lab/E_kN_as_N.csv")
    text = force_scale_mismatch(kn, np.array([0.0216, 0.03, 0.05]))
    assert text.startswith("E_kN_as_N.csv: every reading (the largest 0.000183 N per wale) is below the force")
    assert "(0.0216 N per wale, 118 times more)" in text and "kN or mN read as N" in text
    assert force_scale_mismatch(kn, np.array([0.0216, 0.03, 0.05]), offset_N=0.0215) == ""
    ok = SimpleNamespace(force=np.array([0.02, 0.5, 2.0]), source="ok.csv")
    assert force_scale_mismatch(ok, np.array([0.0216, 0.6, 2.1])) == ""


def test_an_extensometer_that_jitters_leaves_an_effect_free_curve_effect_free():
    """A blind probe's model-made cycles (E-glass, m 0.20, phi0 0.05 rad, T frozen on S-, 3 cycles 0.1 <->
    0.7 read every 0.005) with 1 mN of force noise and 1e-4 of strain jitter got a confident
    yarn_extension (probability 0.996; phi0 9 standard errors from its truth): the jitter of a turning row
    shifts the whole branch after it (T is frozen there), and the steep rows weighed as if their strain were
    exact.  The same here, three seeds: the force the model's at the true strains plus 1 mN (numpy), the
    strain column read with a jitter of sd 1e-4 (numpy).  Expected: none each time, m within 0.005 of its
    truth, phi0 within 0.025 (a turn settled on its branch is still off by 0.42 of the jitter, and phi0
    follows the turns: 0.028 to 0.047 here), and the noise said to include the jitter, read off the strain
    column within 20 % (its estimate's spread at 700 rows is ~3 %).  Without the jitter in the noise and
    the turns settled: a confident `unexplained` for all three (chi^2/dof 1.29, 1.92, 1.32).  Not
    reached: at 2e-4 two seeds of three stay `unexplained` (chi^2/dof 1.3-1.4; the probe's own file:
    none)."""
    truth = NOMINAL.replace(phi0=0.05, unloading_rule="hong_constant_t", reload_rule="mirror_unloading",
                            force_cap_N=10.0)
    prog = cycles(0.1, 0.7, 3, 0.005)
    h = run_batch([truth], prog)
    for seed in (22, 23, 24):
        rng = np.random.default_rng(seed)
        force = h.values["F"][:, 0] + rng.normal(0.0, 1e-3, len(prog.strain))
        strain = prog.strain + rng.normal(0.0, 1e-4, len(prog.strain))
        curve = curve_from_arrays(strain, force, prog.cycle, prog.direction, source="jittered")
        assert curve.noise.strain_sd == pytest.approx(1e-4, rel=0.2)
        r = diagnose([curve], DiagnosisSetup(base=truth.replace(m=0.25, phi0=0.0), free=("m", "phi0"),
                                             effects=("yarn_extension", "yarn_compaction"), pair=False)).as_dict()
        assert r["verdict"]["kind"] == "none", (seed, r["verdict"]["reason"])
        p = r["baseline"]["params"]
        assert abs(p["phi0"] - 0.05) < 0.025 and abs(p["m"] - 0.2) < 0.005, (seed, p)
        assert r["noise"]["baseline_within_noise"] and "strain jitter" in r["noise"]["method"]


def test_a_strain_that_jumps_alone_is_said_and_takes_the_verdicts_confidence(tmp_path, capsys):
    """A blind probe's grip slip (the recorded strain 0.015 ahead from 0.4 on, the force running on) was fitted
    as yarn_compaction, confident, chi2/dof 6.2 left.  Hand-made from the bundled effect-free curve (E-glass,
    m 0.20, phi0 0.05, 2 mN; its README): every strain from its row 40 on moved by +0.05 (a slip of four of
    its ~0.0125 steps).  Expected (measured.strain_slips' definition): the read line names the jump between
    rows 40 and 41 (spreadsheet numbers, header = 1), the verdict is not confident and says why; the unchanged
    file has no such jump.  On the sliding plateau (0.3 N per unit strain) the force cannot tell a slip from
    rows missing: said so.  Where it can (a hand-made line of 2 N per unit strain, steps 0.005, 2 mN of noise):
    a strain jump of 0.02 with the force running on as over one step is a slip; four rows left out of the log
    (strain and force jumping together) are not."""
    from pathlib import Path
    from knitsim.diagnosis.measured import read_measured_curve, strain_slips
    src = Path(__file__).parent / "data" / "eglass_1cycle_m0.20_phi0.05_noise2mN.csv"
    lines = src.read_text().splitlines()
    slip = [lines[0]] + [ln if k < 39 else ",".join([f"{float(ln.split(',')[0]) + 0.05:.6f}"] + ln.split(",")[1:])
                         for k, ln in enumerate(lines[1:])]
    (tmp_path / "slip.csv").write_text("\n".join(slip) + "\n")
    assert read_measured_curve(src).slips == ()
    rng = np.random.default_rng(5)
    e = np.arange(60) * 0.005
    f = 0.02 + 2.0 * e + rng.normal(0, 0.002, 60)
    steep = curve_from_arrays(e, f, source="steep.csv", noise_N=0.002)
    assert strain_slips(steep.strain, steep.force, steep.direction, steep.noise) == []
    shifted = curve_from_arrays(np.where(np.arange(60) >= 30, e + 0.02, e), f, source="s.csv", noise_N=0.002)
    found = strain_slips(shifted.strain, shifted.force, shifted.direction, shifted.noise)
    assert [(k, t) for k, _, _, t in found] == [(29, True)] and shifted.slips == (31,)   # (header = row 1)
    keep = np.r_[0:30, 34:60]
    gap = curve_from_arrays(e[keep], f[keep], source="g.csv", noise_N=0.002)
    assert strain_slips(gap.strain, gap.force, gap.direction, gap.noise) == [] and gap.slips == ()
    c = read_measured_curve(tmp_path / "slip.csv")
    assert "too flat to tell" in c.notes[-1]
    assert c.slips == (40,) and "between rows 40 and 41" in c.notes[-1]
    scene = tmp_path / "s.toml"
    scene.write_text('[yarn]\nd = 0.58\nB = 0.31\n[knit]\nL = 14.1\nW0 = 4.4\nC0 = 2.7\n[friction]\nm = 0.25\n'
                     '[rules]\nunloading_rule = "dusserre"\nreload_rule = "mirror_unloading"\nforce_cap_N = 10.0\n'
                     '[diagnosis]\nfree = ["m", "phi0"]\neffects = ["yarn_compaction", "yarn_extension"]\n')
    main(["diagnose", str(tmp_path / "slip.csv"), "--scene", str(scene), "--no-pair", "--quiet"])
    out = capsys.readouterr().out
    verdict = next(ln for ln in out.splitlines() if ln.startswith("verdict:"))
    assert "not confident" in verdict and "the strain jumps alone at row 40" in verdict, verdict
    assert "between rows 40 and 41" in out


def test_readings_far_above_what_the_knit_carries_are_said_as_another_unit():
    """A blind probe's curve in mN under an N header (34 to 8547 "N" per wale on a knit capped at 10 N) got no
    word of the scale (the kN case, every reading below the knit's rest force, did).  Hand-made: a model curve
    rising to 10 N and readings 1000 times it: said, naming mN; the readings themselves: nothing."""
    from knitsim.diagnosis.diagnose import force_scale_mismatch
    s = np.linspace(0.0, 0.8, 41)
    sim = 0.04 + 0.3 * s + 0.003 * (np.exp(s / 0.1) - 1.0)
    same = curve_from_arrays(s, sim, source="n.csv", noise_N=0.002)
    milli = curve_from_arrays(s, 1000 * sim, source="mn.csv", noise_N=2.0)
    assert force_scale_mismatch(same, sim) == ""
    msg = force_scale_mismatch(milli, sim)
    assert "mn.csv" in msg and "mN read as N" in msg


def test_a_force_in_another_unit_is_said_first_and_not_read_as_a_slack_start(tmp_path, capsys):
    """A blind probe's file in kN under an N header: the verdict said first that the specimen reads ~0 N to
    strain 0.345 ("mounted slack: move the origin there") and only at its end that the force may be in another
    unit.  Hand-made from the bundled effect-free curve (its README), every force divided by 1000: the verdict's
    reason opens with the unit, and claims no slack start."""
    from pathlib import Path
    src = Path(__file__).parent / "data" / "eglass_1cycle_m0.20_phi0.05_noise2mN.csv"
    lines = src.read_text().splitlines()
    kn = [lines[0]] + [",".join([a, f"{float(b) / 1000:.9f}"] + rest)
                       for a, b, *rest in (ln.split(",") for ln in lines[1:])]
    (tmp_path / "kn.csv").write_text("\n".join(kn) + "\n")
    scene = tmp_path / "s.toml"
    scene.write_text('[yarn]\nd = 0.58\nB = 0.31\n[knit]\nL = 14.1\nW0 = 4.4\nC0 = 2.7\n[friction]\nm = 0.25\n'
                     '[rules]\nunloading_rule = "dusserre"\nreload_rule = "mirror_unloading"\nforce_cap_N = 10.0\n'
                     '[diagnosis]\nfree = ["m", "phi0"]\neffects = ["bending_hysteresis"]\n')
    main(["diagnose", str(tmp_path / "kn.csv"), "--scene", str(scene), "--no-pair", "--quiet"])
    verdict = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("verdict:"))
    reason = verdict.split("(not confident: ", 1)[1]
    assert reason.startswith("kn.csv: every reading") and "kN or mN read as N" in reason, verdict
    assert "slack" not in reason, verdict


def test_a_load_cells_zero_drifting_over_cycles_is_read_off_the_states_the_knit_returns_to():
    """Hand-made (force_drift's definition): a curve of 3 cycles whose fit (keys, simulated) misses each row by the
    same shape in every cycle (0.01 N x strain: what the model misses, it misses alike each time) plus a zero
    drifting by 0.006 N over the strain travelled (the time at a steady crosshead), noise sd 1 mN weighted.
    Expected: the drift 0.006 N (an identity of the least squares: the per-state misfit drops out, the drift
    is linear in the time), said and its message naming the file; without the drift nothing; a pull (each
    state once) cannot tell a drift from the knit: nothing."""
    from types import SimpleNamespace

    from knitsim.diagnosis.diagnose import force_drift
    up, down = np.linspace(0.1, 0.6, 26), np.linspace(0.58, 0.1, 25)
    s = np.concatenate([up, down] * 3)
    cyc = np.repeat([1, 2, 3], 51)
    keys = (["loading_sliding"] * 26 + ["unloading_sliding"] * 25) * 3
    t = np.r_[0.0, np.cumsum(np.abs(np.diff(s)))]
    sim = 0.1 + 0.2 * s
    w = np.full(len(s), 1000.0)
    for drift, expect in ((0.006, 0.006), (0.0, None)):
        force = sim + 0.01 * s + drift * t / t[-1]
        curve = SimpleNamespace(strain=s, strain_read=s, force=force, cycle=cyc, rate_mm_s=None, source="/lab/c.csv")
        d = force_drift(curve, {"simulated": sim, "keys": keys}, w)
        if expect is None:
            assert d is None
        else:
            assert d["drift_N"] == pytest.approx(expect, rel=1e-9) and d["message"].startswith("c.csv: ")
    pull = SimpleNamespace(strain=up, strain_read=up, force=0.1 + 0.2 * up + 0.006 * (up - 0.1) / 0.5,
                           cycle=np.ones(26, int), rate_mm_s=None, source="p.csv")
    assert force_drift(pull, {"simulated": 0.1 + 0.2 * up, "keys": ["loading_sliding"] * 26}, w[:26]) is None
    # a misfit that grows from cycle to cycle by state (what a knit that shakes down does, and a fit that lacks
    # it misses: 0.02 N x (strain - 0.35) more each cycle, of either sign by state), with the same mean trend over
    # the test as a drift would have: the states' own slopes disagree (chi^2 / dof ~10^5 >> DRIFT_UNIFORMITY):
    # nothing
    force = sim + 0.02 * (cyc - 1) * (s - 0.35) + 0.002 * t / t[-1]
    curve = SimpleNamespace(strain=s, strain_read=s, force=force, cycle=cyc, rate_mm_s=None, source="c.csv")
    assert force_drift(curve, {"simulated": sim, "keys": keys}, w) is None


def test_a_drifting_zero_a_glitch_and_a_grip_slip_in_the_force_are_said_by_the_diagnosis(tmp_path):
    """The blind probe's three artefacts, hand-made on the model's own curves (nothing missing from the model):
    (b) the bundled effect-free cycles (tests/diagnosis/data/README.md) with a zero drifting linearly with the
    strain travelled to 3 % of the peak (0.0052 N) read as a confident `unexplained` (chi2/dof 1.47); (a) a
    pull of the model (E-glass, m 0.20, phi0 0.05, to strain 0.78, 3 mN of noise, numpy) with rows 148-151 of
    its jammed part 25 % low read as a confident `unexplained` (15 % low: chi2/dof 1.86); (c) the same pull
    with its force flat for 3 rows from strain 0.72 and then 3 steps behind, read as yarn_compaction.
    Expected: (b) not confident, the drift named and read within 20 % of 0.0052 N; (a) the rows left out
    (listed with the outliers), the verdict none (nothing is missing); (c) not confident, the stall named."""
    from pathlib import Path

    from knitsim.cell.load_program import piecewise_linear
    from knitsim.diagnosis.measured import read_measured_curve
    base = NOMINAL.replace(m=0.25, phi0=0.0, unloading_rule="dusserre", reload_rule="mirror_unloading",
                           force_cap_N=10.0)
    setup = DiagnosisSetup(base=base, effects=("yarn_compaction", "bending_hysteresis"), pair=False)
    lines = (Path(__file__).parent / "data" / "eglass_3cycles_m0.20_phi0.05_noise2mN.csv").read_text().splitlines()
    rows = [ln.split(",") for ln in lines[1:]]
    s = np.array([float(r[0]) for r in rows])
    f = np.array([float(r[1]) for r in rows])
    t = np.r_[0.0, np.cumsum(np.abs(np.diff(s)))]
    drift = 0.03 * f.max()
    (tmp_path / "drift.csv").write_text("\n".join([lines[0]] + [",".join([r[0], f"{v:.6f}"] + r[2:]) for r, v in
                                                                zip(rows, f + drift * t / t[-1])]) + "\n")
    r = diagnose([read_measured_curve(tmp_path / "drift.csv")], setup).as_dict()
    d = r["curves"][0]["drift"]
    assert d is not None and d["drift_N"] == pytest.approx(drift, rel=0.2)
    assert not r["verdict"]["confident"] and "drifting with time" in r["verdict"]["reason"]

    truth = NOMINAL.replace(phi0=0.05, unloading_rule="dusserre", reload_rule="mirror_unloading", force_cap_N=10.0)
    prog = piecewise_linear([0.0, 0.78], 0.005)
    F = run_batch([truth], prog).values["F"][:, 0] + np.random.default_rng(7).normal(0.0, 0.003, len(prog.strain))
    g = F.copy()
    g[146:150] *= 0.75
    glitch = curve_from_arrays(prog.strain, g, source="glitch.csv")
    assert glitch.glitches == (148, 149, 150, 151)
    r = diagnose([glitch], setup).as_dict()
    assert r["verdict"]["kind"] == "none", r["verdict"]["reason"]
    assert {o["row"] for o in r["baseline"]["outliers"]} >= {148, 149, 150, 151}
    assert "force glitch left out (rows 148-151" in r["verdict"]["reason"]
    k = 143
    sl = F.copy()
    sl[k + 1:k + 4] = F[k] + np.random.default_rng(3).normal(0.0, 0.003, 3)
    sl[k + 4:] = F[k + 1:len(F) - 3]
    slip = curve_from_arrays(prog.strain, sl, source="slip.csv")
    assert slip.stalls == (145,)
    r = diagnose([slip], setup).as_dict()
    assert not r["verdict"]["confident"] and "the force stalls at row 145" in r["verdict"]["reason"]


def test_a_hold_at_the_peak_whose_force_relaxes_is_left_out_and_the_verdict_not_confident(tmp_path):
    """A step-and-hold test: a probe's hold at the first peak of the model's own cycles (the force relaxing by 6 %
    over 20 rows) read as a confident `yarn_extension`.  Hand-made: the model's own single cycle
    (tests/diagnosis/data/README.md: m 0.20, phi0 0.05 rad, 2 mN of noise), 10 rows added after its peak row
    (row 62, strain 0.6, 0.17 N) at that strain, the force relaxing by 15 % (exponentially, 3 rows' time; 12 noise
    sd at the end).  The model keeps one force at one strain: expected, the added rows (63-72) left out and listed
    (JSON hold_rows), nothing else missing (the verdict none, m within 0.005 of its truth), and the verdict not
    confident, saying why (the branches after a hold start from a relaxed knit the model does not know)."""
    from pathlib import Path

    from knitsim.diagnosis.measured import read_measured_curve
    lines = (Path(__file__).parent / "data" / "eglass_1cycle_m0.20_phi0.05_noise2mN.csv").read_text().splitlines()
    s, f = lines[61].split(",")[:2]
    assert s == "0.600000" and f == "0.169945"
    held = [f"{s},{float(f) * (1.0 - 0.15 * (1.0 - np.exp(-t / 3.0))):.6f},1,load" for t in range(1, 11)]
    p = tmp_path / "hold.csv"
    p.write_text("\n".join(lines[:62] + held + lines[62:]) + "\n")
    curve = read_measured_curve(p)
    base = NOMINAL.replace(m=0.25, phi0=0.0, unloading_rule="dusserre", reload_rule="mirror_unloading",
                           force_cap_N=10.0)
    r = diagnose([curve], DiagnosisSetup(base=base, effects=("yarn_extension",), pair=False)).as_dict()
    assert r["verdict"]["kind"] == "none" and not r["verdict"]["confident"], r["verdict"]["reason"]
    assert r["curves"][0]["hold_rows"] == list(range(63, 73))
    assert "hold.csv: the force relaxes at one strain (a hold; 10 row(s) from row 63 left out)" in r["verdict"]["reason"]
    assert abs(r["baseline"]["params"]["m"] - 0.20) < 0.005


def _cycles_file(cell: CellParams, seed: int, source: str):
    """Three cycles 0.1-0.6 at increments of 0.001, read every 0.01 of strain (every 10th row), 2 mN of white noise
    (numpy default_rng(seed)): as a blind probe made its files with `knitsim cell`."""
    prog = cycles(0.1, 0.6, 3, 0.001)
    h = run_batch([cell], prog)
    keep = slice(None, None, 10)
    force = h.values["F"][keep, 0] + np.random.default_rng(seed).normal(0.0, 2e-3, len(prog.strain[keep]))
    return curve_from_arrays(prog.strain[keep], force, prog.cycle[keep], prog.direction[keep], source=source)


def test_the_dahl_candidate_contains_a_hong_baseline_not_a_dusserre_one_and_says_so():
    """A probe read the Dahl candidate's chi2 ~61,500 against the baseline's 314 on an effect-free file (the model's
    own E-glass cycles, m 0.20, phi0 0.05 rad, dusserre unloading, 2 mN) as a nested fit that failed to reach its
    Coulomb limit.  It is no failed search: a Dahl cell holds T through the whole unloading at every sigma, so its
    limit sigma -> inf is Coulomb with Hong's constant-T unloading (at the baseline's m and phi0: Dahl 10^6 94,944.2,
    Coulomb-Hong 94,944.2, Coulomb-dusserre 314), and the candidate contains a `hong_constant_t` baseline only.
    Expected, from that identity: (1) a Hong-made effect-free file against a Hong baseline: the Dahl candidate starts
    at the baseline's m and phi0 and the largest stiffness a cell takes (10^6 / mm), where its chi2 is the baseline's
    up to 0.008 here, and a fit only lowers it: it ends at most 0.1 above the baseline (it ended 9.3 above, 390.1
    against 380.8, at its search's old end 10^3 / mm, where the cell at the baseline's point is 9.9 above), and the
    verdict is `none`; (2) the same file against a dusserre baseline: Dahl is named (it
    carries the unloading the data have), but at the Coulomb end of its stiffness, so the verdict says what it adds
    (Hong's unloading, not a transition) and is not confident (it was confident, with no word of the rule), and the
    candidate's note says it is not nested there; (3) a file made with Dahl friction, sigma 20 / mm (a transition
    of 0.01 mm of slip), against the dusserre baseline: dahl_transition, confident, sigma within the search."""
    hong = NOMINAL.replace(phi0=0.05, unloading_rule="hong_constant_t", reload_rule="mirror_unloading",
                           force_cap_N=10.0)
    dusserre = hong.replace(unloading_rule="dusserre")
    start = {"m": 0.25, "phi0": 0.0}
    curve = _cycles_file(hong, 6, "hong.csv")

    def dahl_of(r):
        return next(c for c in r["candidates"] if c["effect"] == "dahl_transition")
    only_dahl = {"effects": ("dahl_transition",), "pair": False}
    r = diagnose([curve], DiagnosisSetup(base=hong.replace(**start), **only_dahl)).as_dict()
    assert r["verdict"]["kind"] == "none", r["verdict"]["reason"]
    c = dahl_of(r)
    assert c["chi2"] <= r["baseline"]["chi2"] + 0.1, (c["chi2"], r["baseline"]["chi2"], c["params"])
    assert c["note"] == ""
    r = diagnose([curve], DiagnosisSetup(base=dusserre.replace(**start), **only_dahl)).as_dict()
    v, c = r["verdict"], dahl_of(r)
    assert v["effect"] == "dahl_transition" and c["at_bounds"] == {"log10_dahl_sigma": "upper"}
    assert not v["confident"] and 'unloading_rule = "hong_constant_t"' in v["reason"]
    assert "not a gradual stick-slip" in v["reason"] and "not nested in this baseline" in c["note"]
    dahl = dusserre.replace(friction="dahl", dahl_sigma=20.0)
    r = diagnose([_cycles_file(dahl, 7, "dahl.csv")],
                 DiagnosisSetup(base=dusserre.replace(**start), **only_dahl)).as_dict()
    v, c = r["verdict"], dahl_of(r)
    assert v["effect"] == "dahl_transition" and v["confident"], v["reason"]
    assert c["at_bounds"] == {} and 1.0 < c["params"]["log10_dahl_sigma"] < 1.6
