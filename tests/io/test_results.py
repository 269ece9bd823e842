"""Result writers on a hand-built BatchHistory (no engine): columns, rows, summary numbers, atomic writes."""
from __future__ import annotations

import csv
import io
import json
import tomllib

import numpy as np
import pytest

from knitsim.cell.history import HISTORY_QUANTITIES, BatchHistory
from knitsim.cell.material import CellParams
from knitsim.cell.stages import Stage
from knitsim.io import results
from knitsim.io.results import CURVE_COLUMNS, curve_csv, events_csv, summarise, write_cell_results

C0 = 2.7
STRAIN = np.array([0.1, 0.2, 0.3, 0.2, 0.1])
P = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=C0, m=0.2, force_cap_N=3.0)


def history() -> BatchHistory:
    """Three cells on one program: load 0 -> 0.3, unload -> 0.1.

    cell 0: F = 1, 2, 3, 1, 0; goes slack at strain 0.15 (event), C stays there;
    cell 1: reaches the force cap (3 N) at row 2, later rows repeat its state;
    cell 2: F = 1, 2, 3, 1, 0 without a slack event, jams at strain 0.25 (event);
    cell 3: no convergence at row 3, whose row (and the next) repeat row 2.
    """
    n, k = len(STRAIN), 4
    C = np.repeat((C0 * (1 + STRAIN))[:, None], k, axis=1)
    F = np.array([[1, 1, 1, 1], [2, 2, 2, 2], [3, 3, 3, 3], [1, 3, 1, 3], [0, 3, 0, 3]], float)
    C[4, 0] = C0 * 1.15
    C[3:, 1] = C[2, 1]
    C[3:, 3] = C[2, 3]
    stage = np.full((n, k), int(Stage.S_LOAD))
    stage[3, :], stage[4, :] = int(Stage.S_UNLOAD), int(Stage.S_UNLOAD)
    stage[4, 0] = int(Stage.SLACK)
    stage[3:, 1] = int(Stage.S_LOAD)
    stage[3:, 3] = int(Stage.S_LOAD)
    jammed = np.zeros((n, k), np.int32)
    jammed[2:, 2] = 1
    status = np.zeros((n, k), np.int32)
    status[2:, 1] = 2          # force_cap
    status[3:, 3] = 1          # no_convergence
    values = {q: np.full((n, k), 0.5) for q in HISTORY_QUANTITIES}
    values["F"], values["C"] = F, C
    events = [{"cell": 0, "increment": 4, "kind": "slack", "C": C0 * 1.15, "from": "sliding", "to": "slack"},
              {"cell": 1, "increment": 2, "kind": "force_cap", "C": C0 * 1.3},
              {"cell": 1, "increment": 2, "kind": "flag", "reason": "force per wale reached force_cap_N",
               "status": "force_cap"},
              {"cell": 2, "increment": 2, "kind": "jam", "C": C0 * 1.25, "from": "sliding", "to": "jamming"},
              {"cell": 3, "increment": 3, "kind": "flag", "reason": "no convergence, x", "status": "no_convergence"}]
    return BatchHistory(STRAIN, np.ones(n, np.int32), np.array([1, 1, 1, -1, -1]), stage, jammed, status,
                        values, events, [P, P, P.replace(unloading_rule="hong_constant_t"), P])


def read(text):
    return list(csv.DictReader(io.StringIO(text)))


def test_curve_columns_rows_and_labels():
    h = history()
    text = curve_csv(h)
    assert text.splitlines()[0] == ("cell,cycle,direction,stage,strain,force_per_wale_N,alpha,beta,gamma,phi,"
                                    "P,W,C,s_BC,status")
    rows = read(text)
    assert len(rows) == 5 * 4                             # increments x cells
    assert [r["cell"] for r in rows] == ["0"] * 5 + ["1"] * 5 + ["2"] * 5 + ["3"] * 5
    assert [r["direction"] for r in rows[:5]] == ["load"] * 3 + ["unload"] * 2
    assert [r["stage"] for r in rows[:5]] == ["sliding"] * 4 + ["slack"]
    assert [r["stage"] for r in rows[10:15]] == ["sliding", "sliding", "jamming", "jamming", "jamming"]
    assert [r["status"] for r in rows[15:]] == ["ok", "ok", "ok", "no_convergence", "no_convergence"]
    assert [r["status"] for r in rows[5:10]] == ["ok", "ok", "force_cap", "force_cap", "force_cap"]
    assert float(rows[4]["C"]) == C0 * 1.15 and float(rows[2]["force_per_wale_N"]) == 3.0
    assert float(rows[3]["strain"]) == 0.2                 # full precision


def test_events_csv():
    rows = read(events_csv(history()))
    assert [r["kind"] for r in rows] == ["slack", "force_cap", "flag", "jam", "flag"]
    assert float(rows[0]["event_strain"]) == pytest.approx(0.15, abs=1e-15)
    assert rows[4]["reason"] == "no convergence, x"       # quoted comma survives


def test_summary_numbers_by_hand():
    s = summarise(history(), ["a", "b", "c", "d"])
    c0, c1, c2, c3 = s["cells"]
    # cell 0: residual strain from the slack event, C/C0 - 1 = 0.15
    assert c0["cycles"][0]["residual_strain"] == pytest.approx(0.15, abs=1e-15)
    assert c0["cycles"][0]["residual_strain_from"] == "event"
    # loop (0.1,1) (0.2,2) (0.3,3) (0.2,1) (0.15,0), trapezoids: 0.15 + 0.25 - 0.2 - 0.025 = 0.175
    assert c0["cycles"][0]["energy_N_per_strain"] == pytest.approx(0.175, abs=1e-14)
    assert c0["cycles"][0]["energy_N_mm"] == pytest.approx(0.175 * C0, abs=1e-14)
    assert c0["cycles"][0]["peak_force_per_wale_N"] == 3.0 and c0["cycles"][0]["strain_at_peak"] == 0.3
    assert c0["end"] == "completed the load program" and c0["expected_end"]
    assert c0["strain_at_first_jamming"] is None
    # cell 1: stopped at the cap (a stop, not a failure); rows after the stop ignored; the program's
    # unloading after the stop was never run, which its end and a warning say
    assert c1["final_status"] == "force_cap" and c1["expected_end"]
    assert "force cap" in c1["end"] and "later cycles not run" in c1["end"]
    assert [w["code"] for w in c1["warnings"]][:1] == ["program_cut_by_force_cap"]
    assert c1["stopped_at_strain"] == 0.3
    assert c1["status_counts"] == {"ok": 2, "force_cap": 3}
    assert c1["cycles"][0]["energy_N_per_strain"] == pytest.approx(0.15 + 0.25, abs=1e-14)
    assert c1["cycles"][0]["residual_strain"] is None
    # cell 2: no slack event: F reaches 0 between rows (0.2, 1) and (0.1, 0) -> 0.1
    assert c2["cycles"][0]["residual_strain"] == pytest.approx(0.1, abs=1e-15)
    assert c2["cycles"][0]["residual_strain_from"] == "interpolated"
    assert c2["strain_at_first_jamming"] == pytest.approx(0.25, abs=1e-15)
    # cell 3: failed at row 3; its repeated rows are not part of the curve's numbers
    assert c3["expected_end"] is False and c3["end"] == "FAILED (no_convergence): no convergence, x"
    assert c3["stopped_at_strain"] == 0.2 and c3["final_force_per_wale_N"] == 3.0
    assert c3["cycles"][0]["energy_N_per_strain"] == pytest.approx(0.15 + 0.25, abs=1e-14)
    assert c3["cycles"][0]["residual_strain"] is None
    assert c2["rules"]["unloading_rule"]["value"] == "hong_constant_t"
    assert "Hong" in c2["rules"]["unloading_rule"]["meaning"]
    assert s["all_expected_end"] is False and s["n_cells"] == 4 and s["n_increments"] == 5


def test_write_set_is_complete_and_replaces_stale_files(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / "plot.png").write_text("stale")
    results.record_outputs(out, ["plot.png"])            # an earlier run's plot: replaced by no plot
    h = history()
    files = write_cell_results(out, h, summarise(h), 'title = "x"\n', plot=False)
    assert sorted(p.name for p in out.iterdir()) == [results.RECORD_NAME, "curve.csv", "events.csv",
                                                     "scene.resolved.toml", "summary.json"]
    assert set(files) == {"curve.csv", "events.csv", "scene.resolved.toml", "summary.json"}
    assert json.loads((out / "summary.json").read_text())["n_cells"] == 4
    assert tomllib.loads((out / "scene.resolved.toml").read_text()) == {"title": "x"}
    assert list(tmp_path.iterdir()) == [out]              # no temporary sibling left
    # a plot.png knitsim did not write (no record of it) is the user's: left alone
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "plot.png").write_text("my figure")
    write_cell_results(mine, h, summarise(h), 'title = "x"\n', plot=False)
    assert (mine / "plot.png").read_text() == "my figure"


def test_plot_is_a_png(tmp_path):
    h = history()
    data = results.plot_png(h, ["a", "b", "c", "d"], "t")
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 1000


def test_error_while_writing_leaves_nothing(tmp_path, monkeypatch):
    out = tmp_path / "run"

    def boom(*a, **k):
        raise RuntimeError("disk full")

    monkeypatch.setattr(results, "plot_png", boom)
    h = history()
    with pytest.raises(RuntimeError):
        write_cell_results(out, h, summarise(h), "", plot=True)
    assert list(tmp_path.iterdir()) == []


def test_atomic_write_text(tmp_path):
    p = results.atomic_write_text(tmp_path / "a.txt", "hello")
    assert p.read_text() == "hello" and [x.name for x in tmp_path.iterdir()] == ["a.txt"]


def test_output_dir_that_is_a_file_is_refused(tmp_path):
    f = tmp_path / "f"
    f.write_text("")
    with pytest.raises(results.KnitsimInputError, match=r"^--out = .*: exists and is not a directory$"):
        results.check_output_dir(f)


def _failed_inside_an_increment() -> BatchHistory:
    """One cell loaded 0.1 .. 0.5; the increment to 0.4 fails after converging up to strain 0.37 (F = 4 N,
    the state its flagged row holds), the next row repeats it."""
    strain = np.array([0.1, 0.2, 0.3, 0.4, 0.5])
    n = len(strain)
    C = (C0 * (1 + strain))[:, None].copy()
    C[3:, 0] = C0 * 1.37
    F = np.array([[1.0], [2.0], [3.0], [4.0], [4.0]])
    stage = np.full((n, 1), int(Stage.S_LOAD))
    status = np.zeros((n, 1), np.int32)
    status[3:, 0] = 1
    values = {q: np.full((n, 1), 0.5) for q in HISTORY_QUANTITIES}
    values["F"], values["C"] = F, C
    events = [{"cell": 0, "increment": 3, "kind": "flag", "reason": "no convergence, y", "status": "no_convergence"}]
    return BatchHistory(strain, np.ones(n, np.int32), np.ones(n, np.int32), stage, np.zeros((n, 1), np.int32),
                        status, values, events, [P.replace(force_cap_N=100.0)])


def test_a_failed_cell_reports_one_final_state_and_no_values_it_never_reached(monkeypatch):
    # found by a blind probe: the summary's final force (the last finished increment) disagreed with the
    # force of the state the cell stopped in, the peak left that state out, and curve.csv carried the held
    # state at strains the cell never reached
    h = _failed_inside_an_increment()
    c = summarise(h, ["x"])["cells"][0]
    assert c["final_force_per_wale_N"] == c["last_converged_force_per_wale_N"] == 4.0
    assert c["cycles"][0]["peak_force_per_wale_N"] == 4.0
    assert c["cycles"][0]["strain_at_peak"] == pytest.approx(0.37, abs=1e-15)   # the cell's own strain there
    assert c["stopped_at_strain"] == 0.4 and c["last_converged_strain"] == pytest.approx(0.37, abs=1e-15)
    rows = read(curve_csv(h))
    assert float(rows[3]["force_per_wale_N"]) == 4.0 and float(rows[3]["C"]) == C0 * 1.37
    assert rows[4]["status"] == "no_convergence" and float(rows[4]["strain"]) == 0.5
    assert all(rows[4][k] == "nan" for k in CURVE_COLUMNS if k not in ("cell", "cycle", "direction", "stage",
                                                                          "strain", "status"))
    # the capped cell of history(): its cap row kept, the later rows empty
    rows = read(curve_csv(history()))
    assert float(rows[7]["force_per_wale_N"]) == 3.0 and rows[8]["force_per_wale_N"] == "nan"
    # the plot says so in its title, and marks where
    titles, markers = [], []
    from matplotlib.axes import Axes
    real_title, real_scatter = Axes.set_title, Axes.scatter
    monkeypatch.setattr(Axes, "set_title", lambda self, t, **k: (titles.append((t, k.get("color"))),
                                                                  real_title(self, t, **k))[1])
    monkeypatch.setattr(Axes, "scatter", lambda self, *a, **k: (markers.append(k.get("marker")),
                                                                 real_scatter(self, *a, **k))[1])
    results.plot_png(h, ["x"], title="t")
    assert "FAILED" in titles[-1][0] and "0.37" in titles[-1][0] and titles[-1][1] is not None
    assert "X" in markers
    titles.clear()
    results.plot_png(history(), ["a", "b", "c", "d"], title="t")
    assert "FAILED: d stopped" in titles[-1][0]


def test_a_first_cycle_that_unloads_from_rest_peaks_at_the_rest_state():
    # a blind probe's unloading-only program reported a peak of 0 N at strain -0.005: the cycle starts at the
    # rest state, whose force per wale (Table 4's initial state) is its largest
    from knitsim.cell.batch import run_batch
    from knitsim.cell.load_program import piecewise_linear
    h = run_batch([P], piecewise_linear([-0.05], 0.01))
    cell = summarise(h)["cells"][0]
    c = cell["cycles"][0]
    assert c["peak_force_per_wale_N"] == h.rest["F"][0] > 0.01 and c["strain_at_peak"] == 0.0
    # and it says that this cycle never loads (a later probe: the rest force read as a peak, and a negative
    # energy, with no remark): no loop, its energy the unloading's work, by trapezoids from the rest state
    assert c["energy_kind"] == "unloading_work" and not c["closed"]
    F, s = np.r_[h.rest["F"][0], h.force_per_wale[:, 0]], np.r_[0.0, h.values["C"][:, 0] / P.C0 - 1]
    assert c["energy_N_per_strain"] == pytest.approx(float(np.sum(0.5 * (F[1:] + F[:-1]) * np.diff(s))), rel=1e-12)
    assert c["energy_N_per_strain"] < 0
    warned = [w for w in cell["warnings"] if w["code"] == "cycle_without_loading"]
    assert len(warned) == 1 and warned[0]["message"].startswith("cycle 1 only unloads (strain down to -0.05")


def test_a_cycle_that_loads_after_an_unloading_from_rest_is_no_unloading_work():
    # the identity of cycle_work's kinds on hand-made paths: the rest state, down, then up and down again
    from knitsim.io.checks import cycle_work, unloading_only_cycles
    s, f = np.array([0.0, -0.1, -0.2]), np.array([0.02, 0.0, 0.0])
    assert cycle_work(s, f, unloads=True, loads=False)["kind"] == "unloading_work"
    assert cycle_work(s, f, unloads=True, loads=True)["kind"] == "work"
    assert cycle_work(s[::-1], f[::-1], unloads=False)["kind"] == "loading_work"
    loop = np.array([0.1, 0.3, 0.1])
    assert cycle_work(loop, np.array([0.0, 1.0, 0.0]), unloads=True)["kind"] == "hysteresis"
    # rows: cycle 1 only unloads, cycle 2 loads and unloads: one warning, for cycle 1
    w = unloading_only_cycles([-0.05, -0.1, 0.2, 0.1], [1, 1, 2, 2], [-1, -1, 1, -1])
    assert [x.code for x in w] == ["cycle_without_loading"] and "cycle 1 only unloads" in w[0].message
    assert unloading_only_cycles([0.1, 0.2, 0.1], [1, 1, 1], [1, 1, -1]) == []


def test_the_cell_plot_legend_ties_every_rule_set_to_its_cells_and_gives_dahl_only_the_rules_it_uses(monkeypatch):
    """A blind probe's five rule sets: the legend showed three, tied to no curve, and labelled the Dahl cell with an
    unloading and a reload rule that Dahl does not use (rule_meaning says so in the summary).  Expected: one line
    per rule set naming its cells; the Dahl line without them."""
    import matplotlib.axes

    from knitsim.cell.batch import run_batch
    from knitsim.cell.load_program import cycles
    from knitsim.io.results import plot_png
    base = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.3, force_cap_N=20.0)
    cells = [base, base.replace(unloading_rule="hong_constant_t"), base.replace(reload_rule="freeze_rn"),
             base.replace(jamming_criterion="head_gap", in_plane_width=0.7), base.replace(friction="dahl", dahl_sigma=50.0)]
    seen = []
    real = matplotlib.axes.Axes.legend

    def legend(self, *args, handles=None, **kw):
        seen.extend(h.get_label().replace("\n", " ") for h in handles or [])   # (long labels wrapped)
        return real(self, *args, handles=handles, **kw)
    monkeypatch.setattr(matplotlib.axes.Axes, "legend", legend)
    plot_png(run_batch(cells, cycles(0.1, 0.3, 1, 0.05)), labels=["a", "b", "c", "d", "e"])
    rules = [s for s in seen if ", cap 20 N" in s]
    assert len(rules) == 5 and [r.split(":")[0] for r in rules] == ["a", "b", "c", "d", "e"]
    assert rules[4] == "e: dahl, w_4d, cap 20 N"
    assert rules[1] == "b: coulomb, unload hong_constant_t, reload mirror_unloading, w_4d, cap 20 N"


def test_the_cell_plot_prints_the_summarys_warnings_under_it(tmp_path, monkeypatch):
    """The paper's E-glass cell cycled 0.1-0.6 (Table 1, section 2.3; README 'the reload pocket'): its cycles 2
    and 3 peak at 8 % of cycle 1, and summary.json warns zero_force_cycle; the cell plot showed the curve
    without a word (the patch plot prints its warnings).  Expected: each warning of the summary under the
    axes, as the patch plot does."""
    import matplotlib.figure

    from knitsim.cell.batch import run_batch
    from knitsim.cell.load_program import cycles
    texts = []
    real = matplotlib.figure.Figure.text

    def text(self, x, y, s, *a, **k):
        texts.append(s)
        return real(self, x, y, s, *a, **k)
    monkeypatch.setattr(matplotlib.figure.Figure, "text", text)
    h = run_batch([CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, force_cap_N=10.0)],
                  cycles(0.1, 0.6, 3, 0.01))
    s = summarise(h)
    codes = [w["code"] for w in s["warnings"]]
    assert codes.count("zero_force_cycle") == 2
    write_cell_results(tmp_path / "o", h, s, "", plot=True)
    shown = " ".join(t.replace("\n", " ") for t in texts)
    assert shown.count("warning: cycle") == 2 and "8.0% of cycle 1" in shown
