"""HTML report of a diagnosis.

Sources: the result layout of issue 6 (/tmp/diag_format.md, built here by
hand), the PNG signature (PNG spec, section 5.2: bytes 137 80 78 71 13 10 26 10),
the figure size promised by the module (inches x DPI), HTML escaping rules
(html.escape: ``<`` -> ``&lt;``), and the shrink definition 1 - rms_after/rms_before
shown in percent.
"""
from __future__ import annotations

import base64
import copy
import io
import math
import re
from html.parser import HTMLParser

import pytest

from knitsim.diagnosis import report
from knitsim.errors import KnitsimInputError

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
VOID = {"meta", "img", "br", "hr", "link", "input"}
EVIL = "<script>alert(1)</script>"


def _stages(rms):
    return {"loading_sliding": {"n": 6, "rms_N": rms[0], "max_abs_N": 2 * rms[0], "share": 0.6},
            "unloading_sliding": {"n": 4, "rms_N": rms[1], "max_abs_N": 2 * rms[1], "share": 0.3},
            "reloading_jamming": {"n": 2, "rms_N": rms[2], "max_abs_N": 2 * rms[2], "share": 0.1}}


def _curve(source, n=6):
    s = [0.02 * i for i in range(n)] + [0.02 * (n - 2 - i) for i in range(n - 1)]
    meas = [x * 3.0 for x in s]
    return {"source": source, "strain": s, "measured": meas, "baseline": [x * 2.5 for x in s],
            "best": [x * 2.9 for x in s], "pair": [x * 2.95 for x in s],
            "keys": ["loading_sliding"] * n + ["unloading_sliding"] * (n - 1),
            "cycle": [1] * len(s), "direction": [1] * n + [-1] * (n - 1)}


@pytest.fixture
def result():
    return {
        "scene": "E-glass specimen", "inputs": ["a.csv", "b.csv"],
        "noise": {"sigma_N": 0.0213, "method": "residual of a smoothing spline"},
        "baseline": {"params": {"m": 0.123456, "phi0": -0.2}, "std_errors": {"m": 0.004, "phi0": 0.05},
                     "rms_N": 0.0876543, "bic": -321.0, "stages": _stages([0.1, 0.07, 0.03])},
        "where": ["loading_sliding", "unloading_sliding", "reloading_jamming"],
        "candidates": [
            {"effect": "dahl_transition", "params": {"sigma": 250.0}, "std_errors": {"sigma": 12.0},
             "rms_N": 0.03, "stages": _stages([0.03, 0.03, 0.02]), "shrink": 0.4567, "score": 41.5,
             "significant": True, "identifiable": True, "note": ""},
            {"effect": "velocity_friction", "params": {"p": 0.1}, "std_errors": {"p": 0.5},
             "rms_N": 0.08, "stages": _stages([0.09, 0.07, 0.03]), "shrink": 0.05, "score": -3.0,
             "significant": False, "identifiable": False, "note": "needs tests at several rates"}],
        "pair": {"effects": ["dahl_transition", "yarn_compaction"], "params": {"sigma": 240.0, "k": 1.0},
                 "rms_N": 0.025, "stages": _stages([0.025, 0.025, 0.02]), "shrink": 0.7, "score": 44.0},
        "indistinguishable": [["velocity_friction", "normal_load_friction"]],
        "verdict": {"effect": "dahl_transition", "stage": "loading_sliding", "shrink": 0.4567,
                    "confident": True, "reason": "score well above the noise penalty"},
        "curves": [_curve("data/a.csv"), _curve("data/b.csv")],
        "timing_s": 12.3,
    }


class _Checker(HTMLParser):
    """Records tags; fails on a close without a matching open."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.stack, self.errors, self.imgs, self.tags = [], [], [], []

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        if tag == "img":
            self.imgs.append(dict(attrs))
        if tag not in VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag):
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> closes {self.stack[-1:] or 'nothing'}")
        else:
            self.stack.pop()


def _parse(text):
    p = _Checker()
    p.feed(text)
    p.close()
    assert p.errors == []
    assert p.stack == []  # every element closed, nested properly
    return p


def _png_dims(png):
    import matplotlib.image as mpimg

    assert png[:8] == PNG_SIGNATURE
    arr = mpimg.imread(io.BytesIO(png), format="png")
    return arr.shape[1], arr.shape[0]


def test_figures_are_png_of_the_promised_size(result):
    w, h = _png_dims(report.figure_curves(result))
    # two curves -> two panels side by side (MAX_COLUMNS = 2), each PANEL_SIZE_IN at DPI
    assert (w, h) == (round(2 * report.PANEL_SIZE_IN[0] * report.DPI), round(report.PANEL_SIZE_IN[1] * report.DPI))
    result["curves"].append(_curve("c.csv"))
    w3, h3 = _png_dims(report.figure_curves(result))
    assert (w3, h3) == (w, 2 * h)  # a third curve opens a second row
    wb, hb = _png_dims(report.figure_stage_bars(result))
    assert (wb, hb) == (round(report.BARS_SIZE_IN[0] * report.DPI), round(report.BARS_SIZE_IN[1] * report.DPI))


def test_bar_stages_follow_where(result):
    result["where"] = ["reloading_jamming", "loading_sliding", "unloading_sliding"]
    keys, series = report._stage_bar_data(result)
    assert keys == result["where"]
    labels = [s[0] for s in series]
    assert len(series) == 3 and "dahl_transition" in labels[1] and "yarn_compaction" in labels[2]
    # baseline bar of the first key is that stage's baseline RMS
    assert series[0][1][0] == result["baseline"]["stages"]["reloading_jamming"]["rms_N"]


def test_html_is_well_formed_and_self_contained(result):
    text = report.render_report(result)
    p = _parse(text)
    assert text.startswith("<!DOCTYPE html>")
    assert "script" not in p.tags and "link" not in p.tags
    assert not re.search(r"(src|href)\s*=\s*\"(https?:|//)", text)
    assert len(p.imgs) == 2
    for img in p.imgs:
        src = img["src"]
        assert src.startswith("data:image/png;base64,")
        w, h = _png_dims(base64.b64decode(src.split(",", 1)[1]))
        assert w > 0 and h > 0
    for key in result["where"]:
        assert key in text
    for name in ["dahl_transition", "velocity_friction", "yarn_compaction", "normal_load_friction"]:
        assert name in text
    # 4 significant digits for numbers, 3 for percentages (shrink 0.4567 -> 45.7 %)
    assert "0.1235" in text and "0.08765" in text and "45.7 %" in text and "0.0213" in text
    # the where table lists the stages in the order of result["where"]
    where_table = text[text.index('class="where"'):]
    pos = [where_table.index(f"<td>{k}</td>") for k in result["where"]]
    assert pos == sorted(pos)


def test_strings_are_escaped(result):
    result["scene"] = EVIL
    result["candidates"][1]["note"] = EVIL
    result["verdict"]["reason"] = EVIL
    result["curves"][0]["source"] = EVIL
    result["inputs"] = [EVIL]
    result["where"][0] = EVIL
    result["pair"]["at_bounds_note"] = EVIL
    result["baseline"]["stages"][EVIL] = result["baseline"]["stages"].pop("loading_sliding")
    text = report.render_report(result)
    assert "<script" not in text.lower()
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in text
    p = _parse(text)
    assert "script" not in p.tags


def test_pair_line_says_where_its_fit_sits_at_a_bound(result):
    result["pair"].update(significant=True, gain_over_best=12.5,
                          at_bounds_note="dahl_transition + yarn_compaction fit: k = 1 at its upper bound")
    text = report.render_report(result)
    assert "best pair: dahl_transition + yarn_compaction: a significant gain" in text
    assert "at the bounds of its search (values not estimated): dahl_transition + yarn_compaction fit: k = 1 at its" \
        " upper bound" in text
    del result["pair"]["at_bounds_note"]
    assert "bounds of its search" not in report.render_report(result)


def test_tolerates_missing_best_pair_and_nan(result):
    result["candidates"] = []
    result["pair"] = None
    result["indistinguishable"] = []
    result["verdict"] = {"effect": None, "stage": "loading_sliding", "shrink": 0.0, "confident": False,
                         "reason": "no score above the noise penalty"}
    for st in result["baseline"]["stages"].values():
        st["share"] = math.nan
    for c in result["curves"]:
        c["best"] = None
        c["pair"] = None
    text = report.render_report(result)
    _parse(text)
    sentence = report.verdict_sentence(result)
    assert "no effect" in sentence.lower() and "loading_sliding" in sentence
    assert "no effect explains the gap" in text.lower()
    visible = re.sub(r"data:image/png;base64,[A-Za-z0-9+/=]*", "", text)
    assert "nan" not in visible.lower()  # NaN share shown as n/a
    assert visible.count("<td>n/a</td>") >= 3
    _png_dims(report.figure_curves(result))
    _png_dims(report.figure_stage_bars(result))


def test_verdict_sentence_names_effect_and_shrink(result):
    s = report.verdict_sentence(result)
    assert "dahl_transition" in s and "loading_sliding" in s and "45.7 %" in s and "confident" in s
    assert "not confident" not in s
    result["verdict"]["confident"] = False
    assert "not confident" in report.verdict_sentence(result)


def _candidate_rows(text):
    """{effect: [cell texts]} of the candidates table."""
    table = text[text.index("Which: candidate effects"):]
    table = table[:table.index("</table>")]
    rows = {}
    for tr in re.findall(r"<tr>(.*?)</tr>", table, re.S):
        cells = [re.sub(r"<[^>]+>", "", c) for c in re.findall(r"<td[^>]*>(.*?)</td>", tr, re.S)]
        if cells:
            rows[cells[0]] = cells
    return rows


def test_only_the_verdicts_effect_is_named(result):
    """A verdict names one effect; a rival that passes the same tests is marked as passing them, not as
    named (a probe read three "named" candidates beside a verdict naming one).  The candidates' own
    fitted zero offsets are shown with their parameters."""
    result["candidates"][0]["practical"] = True
    rival = copy.deepcopy(result["candidates"][0])
    rival.update(effect="yarn_compaction", score=40.0, offsets_N={"data/a.csv": 0.0123})
    result["candidates"].insert(1, rival)
    rows = _candidate_rows(report.render_report(result))
    assert "named" in rows["dahl_transition"] and "passes" in rows["yarn_compaction"]
    assert "no" in rows["velocity_friction"]
    assert "zero offset a.csv 0.0123 N" in rows["yarn_compaction"][1]
    result["verdict"].update(kind="unexplained", effect=None)
    rows = _candidate_rows(report.render_report(result))
    assert "named" not in rows["dahl_transition"] and "passes" in rows["dahl_transition"]


def test_indicators_rendered_when_present(result):
    ind = {"cycles": [{"cycle": 1, "peak_force_N": 0.314159, "strain_at_peak": 0.1, "residual_strain": None,
                       "energy_N_per_strain": 0.002718}], "strain_at_first_jamming": None}
    result["curves"][0]["indicators"] = {"measured": ind, "baseline": ind}
    text = report.render_report(result)
    _parse(text)
    assert "Indicators per curve" in text and "0.3142" in text and "0.002718" in text
    assert "Indicators per curve" not in report.render_report(
        {**result, "curves": [_curve("a.csv"), _curve("b.csv")]})


@pytest.mark.parametrize("drop, named", [
    (("baseline",), "result['baseline']"),
    (("verdict",), "result['verdict']"),
    (("curves",), "result['curves']"),
    (("baseline", "stages"), "result['baseline']['stages']"),
    (("curves", 1, "measured"), "result['curves'][1]['measured']"),
])
def test_missing_key_is_named(result, drop, named):
    r = copy.deepcopy(result)
    target = r
    for k in drop[:-1]:
        target = target[k]
    del target[drop[-1]]
    for fn in (report.render_report, report.figure_curves, report.figure_stage_bars):
        with pytest.raises(KnitsimInputError) as exc:
            fn(r)
        assert named in str(exc.value) and "missing" in str(exc.value)


def test_write_report_is_atomic(result, tmp_path, monkeypatch):
    out = tmp_path / "report.html"
    got = report.write_report(result, out)
    assert got == out
    assert [p.name for p in tmp_path.iterdir()] == ["report.html"]  # no temp sibling left
    _parse(out.read_text(encoding="utf-8"))

    def boom(_result):
        raise RuntimeError("render failed")

    monkeypatch.setattr(report, "render_report", boom)
    fresh = tmp_path / "fresh.html"
    with pytest.raises(RuntimeError):
        report.write_report(result, fresh)
    assert not fresh.exists()
    before = out.read_bytes()
    with pytest.raises(RuntimeError):
        report.write_report(result, out)
    assert out.read_bytes() == before  # an older report stays intact
    assert [p.name for p in tmp_path.iterdir()] == ["report.html"]


def test_the_plots_say_a_verdict_is_not_confident():
    # a blind probe's fit plot read "best model: yarn_compaction" for a verdict that was not confident
    from knitsim.diagnosis.report import _best_label
    assert _best_label({"verdict": {"effect": "yarn_compaction", "confident": False}}) == \
        "best model: yarn_compaction (not confident)"
    assert _best_label({"verdict": {"effect": "yarn_compaction", "confident": True}}) == "best model: yarn_compaction"


def test_how_the_files_were_read_is_said_in_the_report(result):
    # expectation: the reader's notes (a lab's column taken for ours, a cycle column from 0, a log that starts by
    # unloading) go where the verdict is read, the report, not only on the console's read line; escaped like
    # every string from a user's file; no section where no file needed a note
    assert "How the files were read" not in report.render_report(result)
    result["curves"][0]["read_notes"] = ["column 'Force per wale [N/wale]' read as force_per_wale_N", EVIL]
    result["curves"][1]["read_notes"] = []
    text = report.render_report(result)
    assert "How the files were read" in text
    assert "<li><code>a.csv</code>: column &#x27;Force per wale [N/wale]&#x27; read as force_per_wale_N</li>" in text
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in text and "<script" not in text.lower()


def test_a_baseline_within_the_noise_has_no_gap_to_share_out(result):
    """The stage table of a baseline within its noise shares out the noise's own chi2 excess: said above it, so
    that a `none` verdict's "unloading_sliding 82 %" is not read as a gap (the console says the same,
    tests/diagnosis/test_diagnose.py)."""
    said = "The baseline fits within the noise: there is no gap beyond it"
    assert said not in report.render_report(result)
    result["noise"]["baseline_within_noise"] = True
    assert said in report.render_report(result)
