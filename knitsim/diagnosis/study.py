"""Blind study of the diagnosis: synthetic curves whose effect is withheld (issue 6).

:func:`run_study` draws ``n_cases`` cases from one seed (material, test,
hidden effect or none, strength), makes each with the generator
(:func:`knitsim.diagnosis.synthetic.make_case`), hands *only its curves* to
:func:`knitsim.diagnosis.diagnose.diagnose`, and compares the verdict with the
label afterwards.  The diagnosis starts from the paper's nominal material (not
the drawn specimen) and considers every effect of
:data:`knitsim.cell.effects.EFFECT_NAMES`, whichever are hidden in the study.

Each finished case is one JSON file in ``out_dir/cases/`` (written
atomically), so an interrupted study resumes where it stopped: a case file
whose stored plan entry and configuration equal the current ones is not run
again.  The summary (:func:`study_metrics`) goes to ``summary.json`` and
``summary.md``:

- confusion matrix: rows the true effect (``none`` for effect-free curves),
  columns the verdict: the named effect when the verdict is confident,
  ``undecided`` when it names an effect without confidence, ``none`` when it
  names none (``error`` when the diagnosis raised);
- top-1 accuracy over identifiable effect cases (a correct *confident* verdict);
  identifiable is the generator's oracle label
  (:func:`knitsim.diagnosis.synthetic.oracle_evidence`: what the best baseline
  refit of the noise-free curves leaves is evidence enough, with high
  probability); also the accuracy over all effect cases, and how many
  identifiable effects were named first but without confidence;
- false-alarm rate over effect-free cases: a confident verdict naming an
  effect (also given counting ``undecided`` as an alarm);
- stage localisation: ``verdict.stage == label.true_stage`` over the
  correctly identified cases; mean ``verdict.shrink`` over the same cases;
- per hidden effect: cases, identifiable cases, correct verdicts.
"""
from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..cell.effects import EFFECT_NAMES
from ..errors import KnitsimInputError
from ..io.jsonable import json_text
from ..io.results import atomic_write_bytes, record_outputs
from . import synthetic
from .effects import DEFAULT_STUDY_FREE

NONE = "none"
UNDECIDED = "undecided"
#: every name a study writes into its --out (recorded there: --overwrite removes these and nothing else)
STUDY_OUTPUTS = ("cases/", "summary.json", "summary.md", "cases.csv")
ERROR = "error"

#: test rates of every case [mm/s]: two rates two decades apart, so that velocity_friction is identifiable
#: (Table 2 spans 0.2 .. 10 mm/s); every case gets the same rates, so the number of curves tells nothing
STUDY_RATES = (0.1, 10.0)


#: effects a lab specimen may hide: all but velocity_friction (both tests run at one rate, as a lab's do)
LAB_EFFECTS = tuple(e for e in EFFECT_NAMES if e != "velocity_friction")
#: kinds of specimen: "lab" (two tests, lab-like files: synthetic.make_specimen) or "single" (one test)
SPECIMENS = ("lab", "single")


def draw_plan(n_cases: int, seed: int, effects: Sequence[str] = EFFECT_NAMES,
              include_none_fraction: float = 0.25, specimen: str = "single",
              materials: Sequence[str] | None = None) -> list[dict]:
    """The cases of a study: index, case seed, material, test, hidden effect (None) and strength.

    ``single``: effect-free cases are drawn with probability ``include_none_fraction``.
    ``lab``: exactly ``ceil(n f)`` of the first ``n`` cases are effect-free (``f`` =
    ``include_none_fraction``, spread evenly: case ``i`` is effect-free when
    ``ceil((i + 1) f) > ceil(i f)``; f = 0.5 alternates, starting effect-free), so that a study
    reports both rates on the numbers asked for, and any prefix of a plan keeps them.
    The effect of the others cycles through ``effects`` in an order shuffled per
    round, so that every effect is about equally represented.  ``materials`` (default: both of
    :data:`knitsim.diagnosis.synthetic.MATERIALS` for ``single``, the E-glass knit for ``lab``, the
    specimen of the paper and of issue 12) are drawn uniformly.
    """
    _check_plan_args(n_cases, seed, effects, include_none_fraction)
    if specimen not in SPECIMENS:
        raise KnitsimInputError(f"specimen = {specimen!r}: expected one of {', '.join(SPECIMENS)}")
    materials = _materials(materials, specimen)
    rng = np.random.default_rng(int(seed))
    effects = list(effects)
    f = float(include_none_fraction)
    plan, queue = [], []
    for i in range(int(n_cases)):
        if specimen == "lab":
            none = math.ceil((i + 1) * f - 1e-9) > math.ceil(i * f - 1e-9) or not effects
            rng.random()  # keep one draw per case, as the single plan
        else:
            none = bool(rng.random() < include_none_fraction) if effects else True
        if not none and not queue:
            queue = [effects[j] for j in rng.permutation(len(effects))]
        effect = None if none else queue.pop()
        entry = {"index": i, "seed": int(rng.integers(0, 2**31 - 1)),
                 "material": materials[int(rng.integers(len(materials)))],
                 "test": synthetic.TESTS[int(rng.integers(len(synthetic.TESTS)))],
                 "effect": effect, "strength": float(rng.uniform(0.0, 1.0))}
        if specimen == "lab":
            entry["test"] = synthetic.LAB
        plan.append(entry)
    return plan


#: materials of a lab study by default: the E-glass knit (the paper's specimen, issue 12's blind specimens)
LAB_MATERIALS = ("e_glass",)


def _materials(materials, specimen: str) -> tuple:
    if materials is None:
        return LAB_MATERIALS if specimen == "lab" else tuple(synthetic.MATERIALS)
    if isinstance(materials, str) or not materials:
        raise KnitsimInputError(f"materials = {materials!r}: expected a list of some of "
                                f"{', '.join(synthetic.MATERIALS)}")
    for m in materials:
        if m not in synthetic.MATERIALS:
            raise KnitsimInputError(f"materials: unknown material {m!r}; expected some of "
                                    f"{', '.join(synthetic.MATERIALS)}")
    return tuple(materials)


def _check_plan_args(n_cases, seed, effects, include_none_fraction) -> None:
    if not (isinstance(n_cases, (int, np.integer)) and not isinstance(n_cases, bool) and n_cases >= 1):
        raise KnitsimInputError(f"cases = {n_cases!r}: expected a whole number >= 1")
    if not (isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and seed >= 0):
        raise KnitsimInputError(f"seed = {seed!r}: expected a whole number >= 0")
    if isinstance(effects, str):
        raise KnitsimInputError(f"effects = {effects!r}: expected a list of effect names")
    for e in effects:
        if e not in EFFECT_NAMES:
            raise KnitsimInputError(f"effects: unknown effect {e!r}; expected some of {', '.join(EFFECT_NAMES)}")
    if not (isinstance(include_none_fraction, (int, float)) and 0.0 <= include_none_fraction <= 1.0):
        raise KnitsimInputError(f"include_none_fraction = {include_none_fraction!r}: expected a number in [0, 1]")


UNEXPLAINED = "unexplained"


def verdict_class(verdict: dict | None) -> str:
    """Column of the confusion matrix for a verdict (module docstring)."""
    if verdict is None:
        return ERROR
    eff = verdict.get("effect")
    if eff is None:
        return UNEXPLAINED if verdict.get("kind") == UNEXPLAINED else NONE
    return str(eff) if verdict.get("confident") else UNDECIDED


def wilson_interval(k: int, n: int, z: float = 1.96) -> tuple[float, float] | None:
    """95 % Wilson score interval of a rate k / n (Wilson 1927); None for n = 0."""
    if n <= 0:
        return None
    p = k / n
    den = 1.0 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (max(0.0, mid - half), min(1.0, mid + half))


def clopper_pearson_interval(k: int, n: int, level: float = 0.95) -> tuple[float, float] | None:
    """Exact (Clopper and Pearson 1934) interval of a rate k / n: the beta quantiles
    ``B(a/2; k, n-k+1)`` .. ``B(1-a/2; k+1, n-k)``, 0 and 1 at the ends; None for n = 0."""
    if n <= 0:
        return None
    from scipy.stats import beta
    a = 1.0 - level
    lo = 0.0 if k <= 0 else float(beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k >= n else float(beta.ppf(1 - a / 2, k + 1, n - k))
    return (lo, hi)


def _ratio(num: int, den: int) -> float | None:
    return num / den if den else None


def study_metrics(records: Sequence[dict]) -> dict:
    """Confusion matrix and scores of finished cases.

    Parameters
    ----------
    records : sequence of dict
        Each with ``label`` (``effect`` name or None, ``identifiable``,
        ``true_stage``) and ``verdict`` (``effect``, ``stage``, ``shrink``,
        ``confident``; None when the diagnosis failed).  Records with an
        ``error`` from the generator (no ``label``) are counted apart.

    Returns
    -------
    dict
        ``confusion`` {true: {predicted: count}}, ``rows``, ``columns``,
        ``n_cases``, ``generator_failed``, ``top1_accuracy`` (and ``top1_n``,
        ``top1_correct``), ``false_alarm_rate`` (confident effect named on
        effect-free curves; ``false_alarm_rate_incl_undecided``),
        ``stage_accuracy``, ``mean_shrink``, ``per_effect``.  A rate over no
        case is None.
    """
    recs = [r for r in records if r.get("label") is not None]
    failed = len(records) - len(recs)
    rows, cols = [], []
    confusion: dict[str, dict[str, int]] = {}
    per_effect: dict[str, dict] = {}
    top1_n = top1_ok = none_n = alarms = alarms_any = unexplained_none = dahl_wrong = 0
    all_n = all_ok = named_n = 0
    stage_n = stage_ok = 0
    shrinks = []
    for r in recs:
        lab, ver = r["label"], r.get("verdict")
        true = lab.get("effect") or NONE
        pred = verdict_class(ver)
        confusion.setdefault(true, {})
        confusion[true][pred] = confusion[true].get(pred, 0) + 1
        if true not in rows:
            rows.append(true)
        if pred not in cols:
            cols.append(pred)
        if true == NONE:
            none_n += 1
            alarms += pred not in (NONE, UNDECIDED, ERROR, UNEXPLAINED)
            alarms_any += pred not in (NONE, ERROR, UNEXPLAINED)
            unexplained_none += pred == UNEXPLAINED
            continue
        if true == "dahl_transition":
            # misattributed: another effect named (confidently or not)
            dahl_wrong += bool(ver) and ver.get("effect") not in (None, true)
        pe = per_effect.setdefault(true, {"n": 0, "identifiable": 0, "correct": 0, "correct_identifiable": 0,
                                          "named_none": 0})
        pe["n"] += 1
        pe["named_none"] += pred == NONE
        ok = pred == true
        pe["correct"] += ok
        all_n += 1
        all_ok += ok
        if lab.get("identifiable"):
            pe["identifiable"] += 1
            pe["correct_identifiable"] += ok
            top1_n += 1
            top1_ok += ok
            # named first but not confidently (a rival within the BIC margin, or flagged increments)
            named_n += bool(ver) and pred == UNDECIDED and ver.get("effect") == true
        if ok:
            stage_n += 1
            stage_ok += ver.get("stage") == lab.get("true_stage")
            s = ver.get("shrink")
            if s is not None and math.isfinite(float(s)):
                shrinks.append(float(s))
    for pe in per_effect.values():
        pe["accuracy_identifiable"] = _ratio(pe["correct_identifiable"], pe["identifiable"])
    order_r = [NONE] + [e for e in EFFECT_NAMES if e in rows] + sorted(set(rows) - set(EFFECT_NAMES) - {NONE})
    order_c = [NONE] + [e for e in EFFECT_NAMES if e in cols] + [c for c in (UNDECIDED, ERROR) if c in cols]
    order_c += sorted(set(cols) - set(order_c))
    return {
        "n_cases": len(recs), "generator_failed": failed,
        "rows": [r for r in order_r if r in rows], "columns": [c for c in order_c if c in cols or c == NONE],
        "confusion": confusion,
        "top1_accuracy": _ratio(top1_ok, top1_n), "top1_n": top1_n, "top1_correct": top1_ok,
        "top1_named_undecided": named_n,
        "accuracy_all_effects": _ratio(all_ok, all_n), "effect_n": all_n,
        "false_alarm_rate": _ratio(alarms, none_n), "false_alarm_rate_incl_undecided": _ratio(alarms_any, none_n),
        "false_alarm_wilson95": wilson_interval(alarms, none_n),
        "false_alarm_clopper_pearson95": clopper_pearson_interval(alarms, none_n),
        "false_alarm_incl_undecided_wilson95": wilson_interval(alarms_any, none_n),
        "unexplained_on_effect_free": unexplained_none,
        "none_n": none_n, "false_alarms": alarms,
        "dahl_misattributed": dahl_wrong,
        "stage_accuracy": _ratio(stage_ok, stage_n), "stage_n": stage_n,
        "mean_shrink": float(np.mean(shrinks)) if shrinks else None,
        "per_effect": per_effect,
    }


def time_per_case(records: Sequence[dict]) -> dict:
    """Seconds per case (generation + diagnosis), of the diagnosis alone (both wall) and CPU seconds per
    case: mean, median, max."""
    out = {}
    for key, get in (("case_s", lambda r: r.get("timing_s")), ("diagnosis_s", lambda r: r.get("diagnosis_s")),
                     ("case_cpu_s", lambda r: r.get("cpu_s"))):
        t = [float(get(r)) for r in records if get(r) is not None]
        out[key] = ({"n": len(t), "mean": float(np.mean(t)), "median": float(np.median(t)), "max": float(np.max(t))}
                    if t else None)
    return out


def summary_markdown(summary: dict) -> str:
    """The summary as a markdown page: scores, confusion matrix, per-effect table."""
    m = summary["metrics"]

    def pct(x):
        return "n/a" if x is None else f"{100.0 * x:.1f} %"

    lines = [f"# Blind study of the diagnosis ({m['n_cases']} cases, seed {summary['config']['seed']})", ""]
    if summary.get("complete") is False:
        missing = summary.get("cases_missing", [])
        lines += [f"**Partial: {m['n_cases']} of {summary.get('cases_planned', '?')} planned cases finished** "
                  f"(not yet: {', '.join(str(i) for i in missing)}); run the same command with `--resume` to finish it.", ""]
    def ci(x, how="Wilson"):
        return "" if not x else f" (95 % {how} {100 * x[0]:.1f} .. {100 * x[1]:.1f} %)"

    def secs(t):
        return "n/a" if not t else f"{t['mean']:.1f} s mean, {t['median']:.1f} s median, {t['max']:.1f} s max"

    lines += [
             f"- specimens: {summary['config'].get('specimen', 'single')}",
             f"- noise: {summary['config']['noise_rel']:.4g} x peak force ({summary['config']['noise_how']})",
             f"- specimen scatter of L, W0, C0, d: {summary['config']['scatter_rel']:.4g}; "
             f"test rates {summary['config']['rates']} mm/s", "",
             "| score | value | over |", "|---|---|---|",
             f"| top-1 accuracy (identifiable effects) | {pct(m['top1_accuracy'])} | {m['top1_n']} cases |",
             f"| identifiable effects named first, not confidently | {m.get('top1_named_undecided', 0)} "
             f"| {m['top1_n']} cases |",
             f"| accuracy over all effect cases (identifiable or not) | {pct(m.get('accuracy_all_effects'))} "
             f"| {m.get('effect_n', 0)} cases |",
             f"| false alarms (effect-free, confident) | {m['false_alarms']} = {pct(m['false_alarm_rate'])}"
             f"{ci(m.get('false_alarm_wilson95'))}{ci(m.get('false_alarm_clopper_pearson95'), 'Clopper-Pearson')} "
             f"| {m['none_n']} cases |",
             f"| false alarms incl. undecided | {pct(m['false_alarm_rate_incl_undecided'])}"
             f"{ci(m.get('false_alarm_incl_undecided_wilson95'))} | {m['none_n']} cases |",
             f"| effect-free specimens called unexplained | {m.get('unexplained_on_effect_free', 0)} | {m['none_n']} cases |",
             f"| Dahl cases with another effect named | {m.get('dahl_misattributed', 0)} "
             f"| {m['per_effect'].get('dahl_transition', {}).get('n', 0)} cases |",
             f"| stage localisation (correct verdicts) | {pct(m['stage_accuracy'])} | {m['stage_n']} cases |",
             "| mean shrink (correct verdicts) | "
             + ("n/a" if m["mean_shrink"] is None else f"{m['mean_shrink']:.3f}") + f" | {m['stage_n']} cases |",
             f"| generator failures (not diagnosed) | {m['generator_failed']} | |",
             f"| time per case (generation, oracle, diagnosis) | {secs(summary.get('time_per_case', {}).get('case_s'))} "
             f"| {m['n_cases']} cases |",
             f"| time per diagnosis | {secs(summary.get('time_per_case', {}).get('diagnosis_s'))} | {m['n_cases']} cases |",
             f"| CPU time per case (one core) | {secs(summary.get('time_per_case', {}).get('case_cpu_s'))} "
             f"| {m['n_cases']} cases |", "",
             "## Confusion matrix (rows: hidden effect; columns: verdict)", ""]
    cols = m["columns"]
    lines.append("| true \\ verdict | " + " | ".join(cols) + " |")
    lines.append("|---" * (len(cols) + 1) + "|")
    for r in m["rows"]:
        lines.append(f"| {r} | " + " | ".join(str(m["confusion"].get(r, {}).get(c, 0)) for c in cols) + " |")
    lines += ["", "## Per hidden effect", "", "| effect | cases | identifiable | correct | correct (identifiable) "
              "| named none |", "|---|---|---|---|---|---|"]
    for e, pe in m["per_effect"].items():
        lines.append(f"| {e} | {pe['n']} | {pe['identifiable']} | {pe['correct']} | {pe['correct_identifiable']} "
                     f"| {pe['named_none']} |")
    return "\n".join(lines) + "\n"


#: columns of ``cases.csv``
CSV_COLUMNS = ("index", "seed", "material", "hidden_effect", "strength", "identifiable", "verdict_kind",
               "verdict_effect", "confident", "column", "correct", "p_none", "p_verdict_effect", "best_candidate",
               "best_score", "best_share_of_excess", "baseline_chi2_per_dof", "baseline_within_noise",
               "case_s", "diagnosis_s", "cpu_s", "error")


def cases_csv(records: Sequence[dict]) -> str:
    """One CSV row per finished case (:data:`CSV_COLUMNS`); ``column`` is the verdict's column of the
    confusion matrix (:func:`verdict_class`), ``correct`` whether it is the hidden effect (``none``
    for an effect-free specimen); empty fields where a value does not exist."""
    import csv
    import io

    def fmt(v):
        if v is None:
            return ""
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, float):
            return f"{v:.6g}"
        return str(v)

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for r in sorted(records, key=lambda r: r["spec"]["index"]):
        spec, lab, ver = r["spec"], r.get("label") or {}, r.get("verdict")
        col = verdict_class(ver) if lab else ERROR
        probs = (ver or {}).get("probabilities") or {}
        cands = [c for c in r.get("candidates") or [] if c.get("score") is not None]
        best = max(cands, key=lambda c: c["score"]) if cands else {}
        true = spec.get("effect") or NONE
        w.writerow([fmt(v) for v in (
            spec["index"], spec["seed"], spec["material"], true, spec["strength"], lab.get("identifiable"),
            (ver or {}).get("kind"), (ver or {}).get("effect"), (ver or {}).get("confident"), col,
            (col == true) if ver else None, probs.get(NONE), probs.get((ver or {}).get("effect")),
            best.get("effect"), best.get("score"), best.get("share_of_excess"), r.get("baseline_chi2_per_dof"),
            r.get("baseline_within_noise"), r.get("timing_s"), r.get("diagnosis_s"), r.get("cpu_s"),
            r.get("error"))])
    return buf.getvalue()


def _json_bytes(obj) -> bytes:
    return json_text(obj, indent=1).encode("utf-8")


def _case_record(spec: dict, config: dict, case, result: dict | None, error: str | None, timing: float) -> dict:
    rec = {"spec": spec, "config": config, "timing_s": timing, "diagnosis_s": None}
    if case is None:
        rec.update({"label": None, "verdict": None, "error": error})
        return rec
    rec["label"] = case.label
    if result is None:
        rec.update({"verdict": None, "error": error})
        return rec
    rec["verdict"] = result.get("verdict")
    rec["diagnosis_s"] = result.get("timing_s")
    rec["baseline_chi2_per_dof"] = (result.get("noise") or {}).get("baseline_chi2_per_dof")
    rec["baseline_within_noise"] = (result.get("noise") or {}).get("baseline_within_noise")
    rec["candidates"] = [{k: c.get(k) for k in ("effect", "shrink", "score", "significant", "practical",
                                                "share_of_excess", "probability", "identifiable", "note")}
                         for c in result.get("candidates", [])]
    rec["indistinguishable"] = result.get("indistinguishable")
    rec["where"] = result.get("where")
    rec["noise"] = result.get("noise")
    rec["baseline_rms_N"] = (result.get("baseline") or {}).get("rms_N")
    return rec


def _run_case(spec: dict, key_config: dict, path: Path, args: dict) -> dict:
    """Generate one case, diagnose its curves (never its label), write its record atomically."""
    from .diagnose import DiagnosisSetup, diagnose

    tc, cpu0 = time.perf_counter(), time.process_time()
    case, result, error = None, None, None
    try:
        if spec["test"] == synthetic.LAB:
            case = synthetic.make_specimen(spec["seed"], spec["material"], spec["effect"], spec["strength"],
                                           scatter_rel=args["scatter_rel"], device=args["device"],
                                           oracle_free=args["free"], oracle_increment=args["max_increment"])
        else:
            case = synthetic.make_case(spec["seed"], spec["material"], spec["test"], spec["effect"],
                                       spec["strength"], noise_rel=args["noise_rel"], scatter_rel=args["scatter_rel"],
                                       rates=args["rates"], device=args["device"], oracle_free=args["free"],
                                       oracle_increment=args["max_increment"])
    except (RuntimeError, KnitsimInputError) as exc:  # no specimen runs with this effect, or made no valid file
        error = f"generator: {exc}"
    if case is not None:
        setup = DiagnosisSetup(base=synthetic.material_params(spec["material"]), free=args["free"],
                               effects=args["candidate_effects"], max_increment=args["max_increment"],
                               noise_N=None, device=args["device"])
        try:
            # the diagnosis sees the curves only, never case.label
            result = diagnose(list(case.curves), setup).as_dict()
        except (RuntimeError, ValueError, FloatingPointError, KnitsimInputError) as exc:
            error = f"diagnosis: {type(exc).__name__}: {exc}"
    rec = _case_record(spec, key_config, case, result, error, time.perf_counter() - tc)
    # CPU seconds of the case's process (one core: Warp's CPU kernels are serial): on a shared machine the
    # wall time grows with the load, this much less
    rec["cpu_s"] = time.process_time() - cpu0
    atomic_write_bytes(path, _json_bytes(rec))
    return json.loads(_json_bytes(rec))


def _differs(old: dict, spec: dict, key_config: dict) -> str:
    """What differs between a stored case and the plan entry and configuration asked for, in words."""
    def short(v) -> str:
        t = repr(v)
        return t if len(t) <= 40 else t[:37] + "..."

    have, want = dict(old.get("config") or {}), key_config
    keys = [k for k in sorted(set(have) | set(want)) if have.get(k) != want.get(k)]
    if keys:
        return "; ".join(f"{k} {short(have.get(k))} there, {short(want.get(k))} asked" for k in keys[:3])
    a, b = dict(old.get("spec") or {}), spec
    keys = [k for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
    return "its plan entry differs (another seed?): " + "; ".join(
        f"{k} {short(a.get(k))} there, {short(b.get(k))} asked" for k in keys[:3])


def run_study(n_cases: int, seed: int, out_dir, effects: Sequence[str] | None = None,
              include_none_fraction: float | None = None, noise_rel: float | None = None,
              scatter_rel: float | None = None, device: str = "cpu", progress: Callable | None = None, resume: bool = True,
              rates: Sequence[float] = STUDY_RATES, max_increment: float = 0.01,
              candidate_effects: Sequence[str] = EFFECT_NAMES, free: Sequence[str] = None, jobs: int = 1,
              summary_only: bool = False, specimen: str = "lab", materials: Sequence[str] | None = None,
              only: Sequence[int] | None = None, replace_other: bool = True) -> dict:
    """Run (or resume) a blind study and write its summary.

    Parameters
    ----------
    n_cases, seed : int
        Number of cases and the seed of the plan (:func:`draw_plan`).
    specimen : {"lab", "single"}
        ``lab`` (default): every specimen has two tests with their own noise and the flaws of real
        files (:func:`knitsim.diagnosis.synthetic.make_specimen`), a share
        ``include_none_fraction`` of the specimens (exactly, :func:`draw_plan`) is effect-free, hidden
        effects default to :data:`LAB_EFFECTS`, the material to :data:`LAB_MATERIALS`, scatter to
        0.5 %, and ``noise_rel`` / ``rates`` are those of the lab model.  ``single``: one test per case
        (:func:`~knitsim.diagnosis.synthetic.make_case`).
    out_dir : path-like
        Output folder: ``cases/case_NNNN.json``, ``summary.json``, ``summary.md`` and ``cases.csv``
        (one row per finished case: label, verdict, probabilities, seconds), all rewritten after
        every case, so that a study killed at any moment keeps every finished case.
    effects : sequence of str
        Effects that may be hidden.
    include_none_fraction : float, optional
        Share of the cases with no hidden effect (``single``: the probability of one); default 0.5
        for ``lab``, 0.25 for ``single``.
    materials : sequence of str, optional
        Materials drawn (:func:`draw_plan`).
    noise_rel : float, optional
        Force noise as a fraction of each curve's peak (default: the paper's
        capstan scatter, :func:`knitsim.diagnosis.synthetic.paper_noise_rel`).
    scatter_rel : float
        Specimen scatter of L, W0, C0, d.
    device : str
        Warp device of the generator and the diagnosis.
    progress : callable, optional
        ``progress(done, total, eta_s, record)`` after each case (``eta_s`` None until one case ran here).
    resume : bool
        Keep finished case files whose plan entry and configuration match.
    replace_other : bool
        With ``resume``: a finished case file of another plan entry or configuration (a study run with another
        seed, noise or candidate list into this folder) is run again and replaced (the default); False: refused
        before any case runs, naming the file and what differs (``knitsim diagnose-study --resume``: a probe's
        resume with another seed replaced every finished case without a word).
    rates : sequence of float
        Test rates of every case [mm/s] (one curve each).
    max_increment : float
        Strain increment of the diagnosis' simulations.
    candidate_effects : sequence of str
        Effects the diagnosis tries (all by default; it is not told which are hidden).
    free : sequence of str, optional
        Baseline parameters the diagnosis calibrates (from the paper's nominal
        material); default :data:`DEFAULT_STUDY_FREE`.  With ("m", "phi0") only,
        the specimen scatter of L, W0, C0, d is left to the effects to explain:
        1 % scatter moves the curve by 2 to 60 noise sd, and an effect that
        absorbs it is a false alarm.
    jobs : int
        Cases run at once, one process each (Warp's CPU kernels use one core).
        The results do not depend on it: each case is seeded by its plan entry.
    summary_only : bool
        Run nothing: summarise the cases already stored in ``out_dir``.
    only : sequence of int, optional
        Run only the cases of these plan indices (0-based, the ``index`` column of ``cases.csv``);
        the plan is still that of ``n_cases`` and ``seed``, so that a case is the same specimen as in
        the whole study, and the summary is that of the cases finished (marked partial).

    Returns
    -------
    dict
        ``config``, ``metrics`` (:func:`study_metrics`), ``timing_s``, ``complete`` and
        ``cases_missing`` (plan indices not finished); also written to ``summary.json``.
        When interrupted (KeyboardInterrupt), the finished cases stay stored, a summary of
        them is written with ``complete = false``, and the interrupt is raised again: the
        same call resumes.
    """
    free = DEFAULT_STUDY_FREE if free is None else tuple(free)
    lab = specimen == "lab"
    if effects is None:
        effects = LAB_EFFECTS if lab else EFFECT_NAMES
    if scatter_rel is None:
        scatter_rel = synthetic.LAB_SCATTER_REL if lab else 0.01
    if include_none_fraction is None:
        include_none_fraction = 0.5 if lab else 0.25
    if not (isinstance(jobs, (int, np.integer)) and not isinstance(jobs, bool) and jobs >= 1):
        raise KnitsimInputError(f"jobs = {jobs!r}: expected a whole number >= 1")
    _check_plan_args(n_cases, seed, effects, include_none_fraction)
    how = synthetic.paper_noise_rel()[1] if noise_rel is None else "given"
    noise_rel = synthetic.DEFAULT_NOISE_REL if noise_rel is None else noise_rel
    if not (isinstance(noise_rel, (int, float)) and math.isfinite(noise_rel) and noise_rel >= 0):
        raise KnitsimInputError(f"noise_rel = {noise_rel!r}: expected a number >= 0")
    if not (isinstance(scatter_rel, (int, float)) and math.isfinite(scatter_rel) and 0 <= scatter_rel < 0.2):
        raise KnitsimInputError(f"scatter_rel = {scatter_rel!r}: expected a number in [0, 0.2)")
    out = Path(out_dir)
    cases_dir = out / "cases"
    record_outputs(out, STUDY_OUTPUTS)
    cases_dir.mkdir(parents=True, exist_ok=True)
    plan = draw_plan(n_cases, seed, effects, include_none_fraction, specimen, materials)
    if only is not None:
        only = sorted({int(i) for i in only})
        bad = [i for i in only if not 0 <= i < len(plan)]
        if bad or not only:
            raise KnitsimInputError(f"only = {bad or only}: expected case indices in 0 .. {len(plan) - 1}")
    if lab:
        how = (f"lab: each test {synthetic.LAB_NOISE_REL:g} x its peak + {synthetic.LAB_NOISE_ABS:g} N, offsets "
               f"+-{synthetic.LAB_OFFSET_N:g} N, strain jitter {synthetic.LAB_STRAIN_JITTER:g}, an outlier with "
               f"probability {synthetic.LAB_OUTLIER_PROB:g}")
        noise_rel, rates = synthetic.LAB_NOISE_REL, (synthetic.PAPER_RATE_MM_S,)
    config = {"seed": int(seed), "specimen": specimen, "noise_rel": float(noise_rel), "noise_how": how,
              "scatter_rel": float(scatter_rel),
              "rates": [float(r) for r in rates], "max_increment": float(max_increment),
              "generator_max_increment": 0.0025, "candidate_effects": list(candidate_effects),
              "include_none_fraction": float(include_none_fraction), "hidden_effects": list(effects),
              "materials": list(_materials(materials, specimen)),
              "free": list(free), "identifiable_by": "oracle refit (synthetic.oracle_evidence)"}
    # what makes a stored case reusable: its plan entry and everything that shapes its data or its diagnosis
    key_config = {k: v for k, v in config.items()
                  if k not in ("seed", "include_none_fraction", "hidden_effects", "materials")}
    t0 = time.perf_counter()
    args = {"noise_rel": noise_rel, "scatter_rel": scatter_rel, "rates": tuple(rates), "device": device,
            "free": tuple(free), "candidate_effects": tuple(candidate_effects), "max_increment": max_increment}
    done: dict[int, dict] = {}
    todo = []
    for spec in plan:
        path = cases_dir / f"case_{spec['index']:04d}.json"
        rec = None
        if resume and path.exists():
            try:
                old = json.loads(path.read_text())
            except (OSError, ValueError):
                old = None              # (a file cut short by a kill: run again)
            if isinstance(old, dict) and old.get("spec") == spec and old.get("config") == key_config:
                rec = old
            elif isinstance(old, dict) and not replace_other:
                raise KnitsimInputError(
                    f"--resume: {path} is a case of another study ({_differs(old, spec, key_config)}): resuming "
                    "would replace it; give the first study's settings, or --overwrite, or another --out")
        if rec is None:
            if only is None or spec["index"] in only:
                todo.append((spec, path))
        else:
            done[spec["index"]] = rec
    ran, ran_time = 0, 0.0

    def finished(rec):
        nonlocal ran, ran_time
        done[rec["spec"]["index"]] = rec
        ran += 1
        ran_time += rec["timing_s"]
        write_summary()  # after every case: what a kill leaves behind is up to date (marked partial)
        if progress is not None:
            left = len(plan) - len(done)
            eta = ran_time / ran * left / max(1, min(jobs, left))  # cases run jobs at a time
            progress(len(done), len(plan), eta, rec)

    if progress is not None:
        for k, (_, rec) in enumerate(sorted(done.items()), start=1):  # resumed cases: no time estimate
            progress(k, len(plan), None, rec)

    def write_summary() -> dict:
        records = [done[spec["index"]] for spec in plan if spec["index"] in done]
        missing = [spec["index"] for spec in plan if spec["index"] not in done]
        summary = {"config": config, "metrics": study_metrics(records), "timing_s": time.perf_counter() - t0,
                   "time_per_case": time_per_case(records),
                   "cases_run": ran, "cases_resumed": len(records) - ran, "cases_planned": len(plan),
                   "complete": not missing, "cases_missing": missing}
        atomic_write_bytes(out / "summary.json", _json_bytes(summary))
        atomic_write_bytes(out / "summary.md", summary_markdown(summary).encode("utf-8"))
        atomic_write_bytes(out / "cases.csv", cases_csv(records).encode("utf-8"))
        return summary

    try:
        if not summary_only:
            _run_cases(todo, key_config, args, jobs, finished)
    except KeyboardInterrupt:
        write_summary()  # of the finished cases, marked incomplete; they are kept for the resume
        raise
    return write_summary()


def _run_cases(todo, key_config: dict, args: dict, jobs: int, finished: Callable) -> None:
    """Run the cases of ``todo`` (serially, or in ``jobs`` processes), handing each record to ``finished``."""
    if jobs <= 1 or len(todo) <= 1:
        for spec, path in todo:
            finished(_run_case(spec, key_config, path, args))
    else:
        # one process per core: Warp's CPU kernels are serial; each case is written by its worker as it ends
        import concurrent.futures as cf
        import multiprocessing as mp

        with cf.ProcessPoolExecutor(max_workers=int(jobs), mp_context=mp.get_context("spawn")) as pool:
            futures = [pool.submit(_run_case, spec, key_config, path, args) for spec, path in todo]
            try:
                for fut in cf.as_completed(futures):
                    finished(fut.result())
            except BaseException:
                for fut in futures:
                    fut.cancel()
                raise
