"""Tests of the blind study (knitsim.diagnosis.study) and `knitsim diagnose-study`."""
from __future__ import annotations

import json

import numpy as np
import pytest

from knitsim.cli import main
from knitsim.diagnosis import diagnose as diagnose_mod
from knitsim.diagnosis import study
from knitsim.diagnosis import synthetic
from knitsim.diagnosis.measured import MeasuredCurve
from knitsim.errors import KnitsimInputError


def _rec(effect, identifiable, true_stage, v_effect, confident, v_stage=None, shrink=0.0):
    return {"label": {"effect": effect, "identifiable": identifiable, "true_stage": true_stage},
            "verdict": {"effect": v_effect, "confident": confident, "stage": v_stage, "shrink": shrink}}


def test_metrics_on_hand_made_cases():
    recs = [
        _rec("coiling_angle_friction", True, "loading_sliding", "coiling_angle_friction", True, "loading_sliding", 0.5),
        _rec("coiling_angle_friction", True, "loading_sliding", "dahl_transition", True, "loading_sliding", 0.2),
        _rec("dahl_transition", True, "unloading_sliding", "dahl_transition", True, "loading_sliding", 0.3),
        _rec("dahl_transition", True, "unloading_sliding", "dahl_transition", False, "unloading_sliding", 0.9),
        _rec("velocity_friction", False, "loading_sliding", None, True),
        _rec(None, False, None, None, True),
        _rec(None, False, None, "yarn_compaction", True, "loading_jamming", 0.1),
        _rec(None, False, None, "bending_hysteresis", False, "loading_sliding", 0.1),
        {"label": None, "verdict": None, "error": "generator: no specimen"},
    ]
    m = study.study_metrics(recs)
    # counted by hand from the list above
    assert m["n_cases"] == 8 and m["generator_failed"] == 1
    assert m["top1_n"] == 4 and m["top1_correct"] == 2 and m["top1_accuracy"] == pytest.approx(0.5)
    assert m["none_n"] == 3 and m["false_alarm_rate"] == pytest.approx(1 / 3)
    assert m["false_alarm_rate_incl_undecided"] == pytest.approx(2 / 3)
    assert m["stage_n"] == 2 and m["stage_accuracy"] == pytest.approx(0.5)
    assert m["mean_shrink"] == pytest.approx(0.4)
    c = m["confusion"]
    assert c["coiling_angle_friction"] == {"coiling_angle_friction": 1, "dahl_transition": 1}
    assert c["dahl_transition"] == {"dahl_transition": 1, "undecided": 1}
    assert c["velocity_friction"] == {"none": 1}
    assert c["none"] == {"none": 1, "yarn_compaction": 1, "undecided": 1}
    # the matrix holds every case once
    assert sum(sum(r.values()) for r in c.values()) == 8
    assert m["per_effect"]["velocity_friction"] == {"n": 1, "identifiable": 0, "correct": 0,
                                                    "correct_identifiable": 0, "named_none": 1,
                                                    "accuracy_identifiable": None}
    md = study.summary_markdown({"config": {"seed": 0, "noise_rel": 0.013, "noise_how": "x", "scatter_rel": 0.01,
                                            "rates": [0.1, 10.0]}, "metrics": m})
    assert "| coiling_angle_friction | 0 | 1 | 1 |" in md  # row: none, coiling, dahl, (compaction), undecided


def test_metrics_rates_are_none_without_cases():
    m = study.study_metrics([_rec(None, False, None, None, True)])
    assert m["top1_accuracy"] is None and m["stage_accuracy"] is None and m["mean_shrink"] is None
    assert m["false_alarm_rate"] == 0.0


def test_plan_is_deterministic_and_balanced():
    a = study.draw_plan(14, 3, include_none_fraction=0.0)
    assert a == study.draw_plan(14, 3, include_none_fraction=0.0)
    # with no effect-free cases, 14 = 2 rounds of the 7 effects, each shuffled: every effect exactly twice
    effects = [p["effect"] for p in a]
    assert sorted(effects) == sorted(list(study.EFFECT_NAMES) * 2)
    assert all(p["effect"] is None for p in study.draw_plan(5, 3, include_none_fraction=1.0))
    assert all(0 <= p["strength"] <= 1 and p["material"] in ("e_glass", "basalt") for p in a)
    with pytest.raises(KnitsimInputError, match="effects"):
        study.draw_plan(3, 0, effects=["nope"])


def _fake_study(monkeypatch, calls):
    """Replace the generator and the diagnosis by instant fakes that count the diagnosed cases."""

    def fake_diagnose(curves, setup, progress=None):
        # the diagnosis gets measured curves only
        assert all(type(c) is MeasuredCurve for c in curves)
        calls.append(len(curves))

        class Fake:
            def as_dict(self):
                return {"verdict": {"effect": None, "stage": None, "shrink": 0.0, "confident": True, "reason": "fake"},
                        "candidates": [], "indistinguishable": [], "where": [], "noise": {},
                        "baseline": {"rms_N": 0.0}}
        return Fake()

    def fake_case(seed, material, test, effect, strength, **kw):
        s = synthetic.measured_strains("monotonic")[:10]
        c = synthetic.curve_from_arrays(s, np.linspace(0.0, 1.0, 10) + seed % 7)
        return synthetic.SyntheticCase([c], {"effect": effect, "identifiable": effect is not None,
                                             "true_stage": None, "seed": seed})

    def fake_specimen(seed, material, effect, strength, **kw):
        return fake_case(seed, material, synthetic.LAB, effect, strength)

    monkeypatch.setattr(diagnose_mod, "diagnose", fake_diagnose)
    monkeypatch.setattr(synthetic, "make_case", fake_case)
    monkeypatch.setattr(synthetic, "make_specimen", fake_specimen)


def test_interrupted_study_keeps_its_cases_and_says_it_is_partial(tmp_path, monkeypatch):
    """An interrupt after 2 of 5 cases leaves those 2 stored and a summary marked partial (never one that
    looks complete); --summary-only runs nothing; the same call then finishes the other 3 only."""
    calls = []
    _fake_study(monkeypatch, calls)

    def stop_after_two(done, total, eta, rec):
        if done == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        study.run_study(5, 3, tmp_path, progress=stop_after_two)
    assert len(list((tmp_path / "cases").glob("case_*.json"))) == 2
    partial = json.loads((tmp_path / "summary.json").read_text())
    assert partial["complete"] is False and len(partial["cases_missing"]) == 3
    assert partial["metrics"]["n_cases"] == 2
    assert "Partial: 2 of 5" in (tmp_path / "summary.md").read_text()
    s = study.run_study(5, 3, tmp_path, summary_only=True)
    assert len(calls) == 2 and s["complete"] is False
    s = study.run_study(5, 3, tmp_path)
    assert len(calls) == 5 and s["complete"] is True and s["cases_missing"] == [] and s["cases_run"] == 3
    assert "Partial" not in (tmp_path / "summary.md").read_text()


def test_a_resume_into_another_studys_folder_is_refused_where_asked_before_any_case_runs(tmp_path, monkeypatch):
    """`knitsim diagnose-study --resume` (replace_other=False) with another seed or noise than the study in --out: a
    probe's resume with another seed ran every case again and replaced the finished ones without a word (and
    --summary-only overwrote the summary). Refused, naming the case file and what differs; nothing runs, nothing is
    replaced (the library's default, replace_other=True, still reruns: test_resume_skips_finished_cases)."""
    calls = []
    _fake_study(monkeypatch, calls)
    study.run_study(3, 1, tmp_path, specimen="single")
    first = (tmp_path / "cases" / "case_0000.json").read_text()
    with pytest.raises(KnitsimInputError, match=r"case_0000\.json is a case of another study \(.*noise_rel 0\.013\d* there, 0\.05 asked"):
        study.run_study(3, 1, tmp_path, noise_rel=0.05, specimen="single", replace_other=False)
    with pytest.raises(KnitsimInputError, match=r"case_0000\.json is a case of another study \(its plan entry differs"):
        study.run_study(3, 2, tmp_path, specimen="single", replace_other=False)
    with pytest.raises(KnitsimInputError, match=r"another study"):
        study.run_study(3, 2, tmp_path, specimen="single", replace_other=False, summary_only=True)
    assert len(calls) == 3 and (tmp_path / "cases" / "case_0000.json").read_text() == first
    # the same study resumes as before
    assert study.run_study(3, 1, tmp_path, specimen="single", replace_other=False)["cases_resumed"] == 3


def test_resume_skips_finished_cases(tmp_path, monkeypatch):
    calls = []
    _fake_study(monkeypatch, calls)
    seen = []
    s1 = study.run_study(4, 1, tmp_path, progress=lambda d, t, eta, r: seen.append((d, t)), specimen="single")
    assert len(calls) == 4 and s1["cases_run"] == 4 and seen[-1] == (4, 4)
    assert len(list((tmp_path / "cases").glob("case_*.json"))) == 4
    assert (tmp_path / "summary.md").read_text().startswith("# Blind study")
    s2 = study.run_study(4, 1, tmp_path, specimen="single")
    assert len(calls) == 4 and s2["cases_run"] == 0 and s2["cases_resumed"] == 4
    assert s2["metrics"] == s1["metrics"]
    # a study with more cases keeps the first four (same plan prefix: same seed)
    study.run_study(6, 1, tmp_path, specimen="single")
    assert len(calls) == 6
    # a changed configuration or --no-resume reruns
    study.run_study(6, 1, tmp_path, noise_rel=0.05, specimen="single")
    assert len(calls) == 12
    study.run_study(6, 1, tmp_path, noise_rel=0.05, resume=False, specimen="single")
    assert len(calls) == 18
    stored = json.loads((tmp_path / "cases" / "case_0000.json").read_text())
    assert stored["config"]["noise_rel"] == 0.05 and "verdict" in stored


def test_only_runs_the_cases_asked_for_as_in_the_whole_plan(tmp_path, monkeypatch):
    """--only re-runs chosen cases of a plan (the same specimens as in the whole study); the summary is
    of those, marked partial, and the same study without it finishes the rest."""
    calls = []
    _fake_study(monkeypatch, calls)
    s = study.run_study(6, 1, tmp_path, specimen="single", only=[4, 1])
    assert len(calls) == 2 and s["complete"] is False and s["cases_missing"] == [0, 2, 3, 5]
    stored = json.loads((tmp_path / "cases" / "case_0004.json").read_text())
    assert stored["spec"] == study.draw_plan(6, 1)[4]
    s = study.run_study(6, 1, tmp_path, specimen="single")
    assert len(calls) == 6 and s["complete"] is True and s["cases_run"] == 4
    with pytest.raises(KnitsimInputError, match="only"):
        study.run_study(6, 1, tmp_path, specimen="single", only=[6])


def test_plan_prefix_is_stable():
    # resuming a longer study relies on the first cases of a plan not depending on its length
    assert study.draw_plan(6, 1)[:4] == study.draw_plan(4, 1)


@pytest.mark.parametrize("argv", [
    ["--cases", "0"], ["--seed", "-1"], ["--effects", "magic"], ["--effects", ","],
    ["--noise-rel", "-0.1"], ["--free", "E"], ["--scatter-rel", "0.5"], ["--none-fraction", "2"],
    ["--jobs", "0"], ["--only", "40"], ["--only", "x"], ["--only", ","],
])
def test_cli_bad_input_exits_2(argv, tmp_path, capsys):
    assert main(["diagnose-study", "--out", str(tmp_path / "o")] + argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("knitsim: error: --") and "Traceback" not in err


@pytest.mark.parametrize("device", ["tpu", "cuda:7"])
def test_cli_device_that_cannot_run_is_refused_before_any_case(device, tmp_path, capsys):
    """A device Warp cannot run on is refused (exit 2, naming it) before the study starts: before, each case
    failed in its generator on it, stored as a failure that --resume kept, and the study was summarised
    complete, exit 0.  'tpu' is no Warp device anywhere; 'cuda:7' only where CUDA is absent."""
    from knitsim import warp_runtime
    if device.startswith("cuda") and warp_runtime.cuda_available():
        pytest.skip("CUDA present: cuda:7 may run")
    out = tmp_path / "o"
    assert main(["diagnose-study", "--cases", "2", "--device", device, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"knitsim: error: device = {device!r}") and "Traceback" not in err
    assert not (out / "cases").exists() and not (out / "summary.json").exists()


def test_cli_summary_only_of_a_folder_without_a_study_is_refused(tmp_path, capsys):
    """--summary-only summarises the cases in --out: where it holds none (no cases/ folder; a mistyped --out),
    it is refused, exit 2, and no folder is left.  Before, the folder was created with an empty study's
    summary in it, "0 of 2 planned cases", exit 0."""
    out = tmp_path / "mistyped"
    assert main(["diagnose-study", "--cases", "2", "--summary-only", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("knitsim: error: --summary-only:") and "holds no study" in err
    assert not out.exists()
    (tmp_path / "empty").mkdir()
    assert main(["diagnose-study", "--cases", "2", "--summary-only", "--out", str(tmp_path / "empty")]) == 2
    assert list((tmp_path / "empty").iterdir()) == []


def test_cli_non_integer_cases_exits_2(tmp_path):
    with pytest.raises(SystemExit) as exc:
        main(["diagnose-study", "--cases", "many", "--out", str(tmp_path)])
    assert exc.value.code == 2


@pytest.mark.slow
def test_end_to_end_small_study(tmp_path):
    s = study.run_study(3, 0, tmp_path, effects=("bending_hysteresis",), include_none_fraction=0.34)
    assert s["metrics"]["n_cases"] + s["metrics"]["generator_failed"] == 3
    assert (tmp_path / "summary.json").exists()


@pytest.mark.slow
def test_parallel_study_equals_serial(tmp_path):
    # each case is seeded by its plan entry: two worker processes give the records of one, timing aside
    kw = dict(effects=("yarn_extension",), include_none_fraction=0.0, free=("m", "phi0"))
    a = study.run_study(2, 3, tmp_path / "serial", **kw)
    b = study.run_study(2, 3, tmp_path / "parallel", jobs=2, **kw)
    assert a["metrics"] == b["metrics"]
    for i in range(2):
        ra = json.loads((tmp_path / "serial" / "cases" / f"case_{i:04d}.json").read_text())
        rb = json.loads((tmp_path / "parallel" / "cases" / f"case_{i:04d}.json").read_text())
        for k in ("timing_s", "diagnosis_s", "cpu_s"):
            ra.pop(k), rb.pop(k)
        assert ra == rb


def test_lab_plan_alternates_effect_free_and_effect_specimens():
    plan = study.draw_plan(80, 5, study.LAB_EFFECTS, 0.5, specimen="lab")
    assert sum(p["effect"] is None for p in plan) == 40
    assert [p["effect"] is None for p in plan[:4]] == [True, False, True, False]
    assert all(p["test"] == synthetic.LAB for p in plan)
    assert {p["material"] for p in plan} == {"e_glass"}                  # issue 12's specimens
    assert "velocity_friction" not in {p["effect"] for p in plan}        # one test rate in a lab


@pytest.mark.parametrize("n, f, k", [(100, 0.6, 60), (120, 0.5, 60), (7, 0.5, 4), (10, 0.0, 0), (10, 1.0, 10)])
def test_lab_plan_has_exactly_the_share_of_effect_free_cases_asked_for(n, f, k):
    # ceil(n f) of the first n cases, in every prefix: a resumed longer study keeps its first cases
    plan = study.draw_plan(n, 2, study.LAB_EFFECTS, f, specimen="lab")
    assert sum(p["effect"] is None for p in plan) == k
    assert study.draw_plan(n - 3, 2, study.LAB_EFFECTS, f, specimen="lab") == plan[:n - 3]


@pytest.mark.parametrize("k, n", [(0, 40), (2, 40), (20, 40), (40, 40), (3, 100)])
def test_clopper_pearson_interval_inverts_the_binomial_tails(k, n):
    # Clopper and Pearson (1934): the upper end p_u solves P(X <= k | n, p_u) = 0.025, the lower end
    # P(X >= k | n, p_l) = 0.025 (checked with the binomial distribution, not the beta quantiles used);
    # k = 0: p_u = 1 - 0.025^(1/n) in closed form
    from scipy.stats import binom
    lo, hi = study.clopper_pearson_interval(k, n)
    if k < n:
        assert binom.cdf(k, n, hi) == pytest.approx(0.025, abs=1e-9)
    else:
        assert hi == 1.0
    if k > 0:
        assert binom.sf(k - 1, n, lo) == pytest.approx(0.025, abs=1e-9)
    else:
        assert lo == 0.0 and hi == pytest.approx(1 - 0.025 ** (1 / n), rel=1e-9)
    w = study.wilson_interval(k, n)
    assert lo <= w[0] + 0.02 and hi >= w[1] - 0.02   # the exact interval is the wider one, near enough


def test_cases_csv_names_every_case_and_its_time(tmp_path, monkeypatch):
    calls = []
    _fake_study(monkeypatch, calls)
    s = study.run_study(4, 1, tmp_path, include_none_fraction=0.5)
    rows = (tmp_path / "cases.csv").read_text().splitlines()
    assert rows[0].split(",") == list(study.CSV_COLUMNS) and len(rows) == 5
    first = dict(zip(study.CSV_COLUMNS, rows[1].split(",")))
    assert first["index"] == "0" and first["hidden_effect"] == "none" and float(first["case_s"]) >= 0
    assert s["time_per_case"]["case_s"]["n"] == 4
    assert "time per case" in (tmp_path / "summary.md").read_text()


@pytest.mark.parametrize("k, n, lo, hi", [
    (0, 40, 0.0, 0.0876),        # Wilson (1927) 95 % interval, z = 1.96: 0 .. z^2 / (n + z^2)
    (2, 40, 0.0138, 0.1650),
    (20, 40, 0.3520, 0.6480),
])
def test_wilson_interval(k, n, lo, hi):
    a, b = study.wilson_interval(k, n)
    assert a == pytest.approx(lo, abs=2e-4) and b == pytest.approx(hi, abs=2e-4)
