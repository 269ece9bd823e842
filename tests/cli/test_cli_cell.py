"""``knitsim cell`` in-process: paper scenes run small (NumPy reference), bad input refused, outputs checked."""
from __future__ import annotations

import csv
import importlib.util
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from knitsim.cli import main
from knitsim.io.output_dir import RECORD_NAME
from knitsim.io.results import CURVE_COLUMNS

REPO = Path(__file__).resolve().parents[2]
PAPER = REPO / "scenes" / "paper"
FILES = {"curve.csv", "events.csv", "scene.resolved.toml", "plot.png", "summary.json"}

# small runs: coarse increments (and fewer cycles) keep each scene to a few seconds
SMALL = {
    "e_glass_monotonic": ["load.max_increment=0.025"],
    "basalt_monotonic": ["load.max_increment=0.025"],
    "e_glass_cyclic": ["load.max_increment=0.025", "load.cycles=1"],
    "e_glass_cyclic_constant_t": ["load.max_increment=0.025", "load.cycles=2"],
}


def run(capsys, scene, out, *extra):
    argv = ["cell", str(scene), "--out", str(out), "--engine", "reference", "--json", *extra]
    rc = main(argv)
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def read_curve(path):
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    return rows


def col(rows, name, cell=0):
    return np.array([float(r[name]) for r in rows if int(r["cell"]) == cell])


@pytest.mark.parametrize("name", sorted(SMALL))
def test_paper_scene_runs_small(capsys, tmp_path, name):
    sets = [a for s in SMALL[name] for a in ("--set", s)]
    rc, out, err = run(capsys, PAPER / f"{name}.toml", tmp_path / "o", *sets)
    summary = json.loads(out)
    assert {p.name for p in (tmp_path / "o").iterdir()} == FILES | {RECORD_NAME}
    assert "engine reference" in err and "done in" in err
    rows = read_curve(tmp_path / "o" / "curve.csv")
    with open(tmp_path / "o" / "curve.csv") as fh:
        assert tuple(fh.readline().strip().split(",")) == CURVE_COLUMNS
    # the rest state (strain 0, Table 4's initialisation) first, then one row per increment
    assert len(rows) == (summary["n_increments"] + 1) * summary["n_cells"]
    assert float(rows[0]["strain"]) == 0.0
    assert float(rows[0]["C"]) == pytest.approx(summary["cells"][0]["params"]["C0"], rel=1e-12)
    cell = summary["cells"][0]
    assert rc == (0 if cell["expected_end"] else 1)
    F, C, strain = col(rows, "force_per_wale_N"), col(rows, "C"), col(rows, "strain")
    with open(tmp_path / "o" / "events.csv", newline="") as fh:
        events = list(csv.DictReader(fh))
    C0 = cell["params"]["C0"]
    cyc = col(rows, "cycle")
    unloading = np.array([r["direction"] == "unload" for r in rows])
    stage = [r["stage"] for r in rows]
    for entry in cell["cycles"]:
        k = entry["cycle"]
        idx = np.nonzero(cyc == k)[0]
        idx = idx[idx > 0]                                  # row 0 is the rest state
        idx = idx[np.isfinite(F[idx])]                      # after a stop the rows hold no values (not solved)
        assert entry["peak_force_per_wale_N"] == F[idx].max()
        # residual strain: where F reached 0 unloading; the slack cell keeps C there, so the
        # first slack row of the cycle's unloading carries it as C/C0 - 1
        slack = [i for i in idx if unloading[i] and stage[i] == "slack"]
        if entry["residual_strain"] is not None:
            assert entry["residual_strain"] == pytest.approx(C[slack[0]] / C0 - 1, abs=1e-12)
        else:
            assert not slack
        # energy: trapezoids of F over the cell's strain C/C0 - 1 (numpy's trapezoid, from the last row of
        # the previous cycle; the first cycle from the rest state, row 0), through the located events of
        # events.csv between the rows of their increments (curve.csv row r + 1 is increment r)
        path = np.concatenate([[idx[0] - 1], idx])
        xs, ys = [], []
        for r in path:
            for ev in events:
                if int(ev["increment"]) + 1 == r and r != path[0] and ev["force_per_wale_N"]:
                    xs.append(float(ev["event_strain"]))
                    ys.append(float(ev["force_per_wale_N"]))
            xs.append(C[r] / C0 - 1)
            ys.append(F[r])
        e = np.trapezoid(ys, xs) if hasattr(np, "trapezoid") else np.trapz(ys, xs)
        assert entry["energy_N_per_strain"] == pytest.approx(e, rel=1e-12, abs=1e-15)
    if "monotonic" in name:
        # from rest through jamming to the 10 N cap: the cap is the expected end (section 4.1 runs)
        assert cell["final_status"] == "force_cap" and cell["expected_end"]
        assert "expected end" in cell["end"]
        assert np.nanmax(F) == pytest.approx(10.0, rel=1e-9)
        # the rows after the cap's hold no values: the cell never reached their strains
        capped = [i for i, r in enumerate(rows) if r["status"] == "force_cap"]
        assert F[capped[0]] == pytest.approx(10.0, rel=1e-9) and np.all(np.isnan(F[capped[1:]]))
        jam = cell["strain_at_first_jamming"]
        first = stage.index("jamming")
        assert C[first - 1] / C0 - 1 < jam <= C[first] / C0 - 1 + 1e-12
        # W = 4 d at and after jamming (Hong 2002), d = 0.58 / 0.56 mm (Table 1)
        assert col(rows, "W")[first] == pytest.approx(4 * cell["params"]["d"], rel=1e-9)
    else:
        # section 2.3: cycles up to 0.60; the loop dissipates (second law) and stays below jamming
        assert strain.max() == pytest.approx(0.6) and cell["strain_at_first_jamming"] is None
        assert cell["cycles"][0]["residual_strain"] is not None
        assert cell["cycles"][0]["energy_N_per_strain"] > 0


def test_batch_scene_and_text_output(capsys, tmp_path):
    scene = tmp_path / "batch.toml"
    scene.write_text((PAPER / "basalt_monotonic.toml").read_text() + """
[[cells]]
label = "m = 0.17"

[[cells]]
label = "stiffer"
yarn = { B = 0.25 }
""")
    rc = main(["cell", str(scene), "--out", str(tmp_path / "o"), "--engine", "reference",
               "--set", "load.max_increment=0.025", "--set", "load.target_strain=0.3"])
    cap = capsys.readouterr()
    assert rc == 0
    assert cap.out.count("completed the load program") == 2
    rows = read_curve(tmp_path / "o" / "curve.csv")
    n = math.ceil(0.3 / 0.025 - 1e-12)
    assert len(rows) == (n + 1) * 2                      # the rest state, then n increments, per cell
    # eqs 8-9: lengths scale with sqrt(B/P), so a stiffer yarn needs a larger P for the same
    # shape: at every imposed strain before jamming the stiffer cell carries more force
    F0, F1 = col(rows, "force_per_wale_N", 0), col(rows, "force_per_wale_N", 1)
    assert np.all(F1 > F0)


BAD = [
    ("no_load", lambda t: t.split("[load]")[0], r"^knitsim: error: load: missing required table \[load\]"),
    ("unknown_key", lambda t: t.replace("[yarn]", "[yarn]\ncolour = \"red\""),
     r'^knitsim: error: yarn\.colour = "red": unknown key'),
    ("wrong_type", lambda t: t.replace("\nm = 0.20", '\nm = "high"'), r'^knitsim: error: friction\.m = "high": expected a number$'),
    ("negative_B", lambda t: t.replace('material = "e_glass"   ', 'B = -0.31\nmaterial = "e_glass" '),
     r"^knitsim: error: yarn\.B = -0\.31: must be > 0 N mm\^2$"),
    ("nan_B", lambda t: t.replace('material = "e_glass"   ', 'B = nan\nmaterial = "e_glass" '),
     r"^knitsim: error: yarn\.B = nan: must be a finite number$"),
    ("narrow", lambda t: t.replace("[knit]", "[knit]\nW0 = 2.0"),
     r"^knitsim: error: knit\.W0 = 2\.0: must be >= 4 d = 2\.32 mm"),
    ("short", lambda t: t.replace("[knit]", "[knit]\nL = 7.0"),
     r"^knitsim: error: knit\.L = 7\.0: too short to close a loop"),
    ("material", lambda t: t.replace('material = "e_glass_plain"', 'material = "e_glass_rib"'),
     r"^knitsim: error: knit\.material = 'e_glass_rib': unknown knit \(known: basalt_plain, e_glass_plain\)$"),
    ("lower_upper", lambda t: t.replace("lower_strain = 0.10", "lower_strain = 0.70"),
     r"^knitsim: error: load\.lower_strain = 0\.7: must be < load\.upper_strain = 0\.6$"),
    ("syntax", lambda t: t.replace("[load]", "[load"), r"^knitsim: error: .*bad\.toml: not valid TOML"),
    # an increment as large as half the cycle's range: every branch one increment, a cycle of two rows
    # (its trapezoid "hysteresis" 0 by construction, before reported as a result)
    ("one_increment_branches", lambda t: t.replace("max_increment = 0.005", "max_increment = 0.05").replace(
        "lower_strain = 0.10", "lower_strain = 0.55"),
     r"^knitsim: error: load\.max_increment = 0\.05: the branches between load\.lower_strain = 0\.55 and "
     r"load\.upper_strain = 0\.6 would be one increment each .*use at most 0\.025$"),
    # two cells under one label: the outputs name cells by label
    ("same_label", lambda t: t + '\n[[cells]]\nlabel = "a"\n[[cells]]\nlabel = "a"\n',
     r'^knitsim: error: cells\[1\]\.label = "a": the label of cells\[0\] too'),
    # a cap below the force per wale at rest (E-glass, about 0.02 N): no program can load the cell
    ("cap_below_rest", lambda t: t.replace("force_cap_N = 10.0", "force_cap_N = 0.015"),
     r"^knitsim: error: cell .*: its force per wale at rest, 0\.02\d* N, is already at or above force_cap_N = "
     r"0\.015 N: no load program can start from it"),
]


@pytest.mark.parametrize("case, edit, match", BAD, ids=[b[0] for b in BAD])
def test_bad_scene_exit_2_one_line_nothing_written(capsys, tmp_path, case, edit, match):
    bad = tmp_path / "bad.toml"
    bad.write_text(edit((PAPER / "e_glass_cyclic.toml").read_text()))
    rc = main(["cell", str(bad), "--out", str(tmp_path / "o"), "--engine", "reference"])
    err = capsys.readouterr().err
    assert rc == 2
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    import re
    if case != "syntax":
        # the scene's own errors name its file first (the syntax error always did; the cap, checked later by the
        # domain check, now too)
        match = match.replace("^knitsim: error: ", f"^knitsim: error: {re.escape(str(bad))}: ", 1)
    assert re.match(match, err.strip()), err
    assert not (tmp_path / "o").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]


@pytest.mark.parametrize("sets, match", [
    (["yarn.B=abc"], r'yarn\.B = "abc": expected a number$'),
    (["yarn.B=-1"], r"yarn\.B = -1\.0: must be > 0 N mm\^2$"),
    (["knit.W0=nan"], r"knit\.W0 = nan: must be a finite number$"),
    (["load.upper_strain=2.0"], r"load\.upper_strain = 2\.0: strain 2 cannot be reached"),
    (["friction.phi0=1.0"], r"friction\.phi0 = 1\.0: must lie in \[-phimax, phimax\]"),
    (["yarn.Bee=1"], r"--set yarn\.Bee: unknown key 'yarn\.Bee'"),
])
def test_bad_set_exit_2(capsys, tmp_path, sets, match):
    argv = ["cell", str(PAPER / "e_glass_cyclic.toml"), "--out", str(tmp_path / "o"), "--engine", "reference"]
    for s in sets:
        argv += ["--set", s]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    import re
    assert re.search(match, err), err
    assert not (tmp_path / "o").exists()


def test_missing_scene_and_bad_out(capsys, tmp_path):
    assert main(["cell", str(tmp_path / "none.toml"), "--engine", "reference"]) == 2
    assert "none.toml: no such scene file" in capsys.readouterr().err
    f = tmp_path / "file"
    f.write_text("")
    assert main(["cell", str(PAPER / "e_glass_cyclic.toml"), "--out", str(f), "--engine", "reference"]) == 2
    assert "exists and is not a directory" in capsys.readouterr().err


def test_warp_engine_missing_is_a_clear_error(capsys, tmp_path, monkeypatch):
    # None in sys.modules makes the lazy import fail as if knitsim.cell.batch were absent
    monkeypatch.setitem(sys.modules, "knitsim.cell.batch", None)
    rc = main(["cell", str(PAPER / "e_glass_cyclic.toml"), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and "engine 'warp' is not available" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


@pytest.mark.skipif(importlib.util.find_spec("knitsim.cell.batch") is None, reason="no Warp batch engine")
def test_warp_and_reference_agree_on_basalt_monotonic(capsys, tmp_path):
    # the two engines are independent solvers of the same cell (section 4.1 data): the located
    # jamming strain and the dissipated energy to the cap agree
    sets = ["--set", "load.max_increment=0.025"]
    rc_r, out_r, _ = run(capsys, PAPER / "basalt_monotonic.toml", tmp_path / "r", *sets)
    rc_w = main(["cell", str(PAPER / "basalt_monotonic.toml"), "--out", str(tmp_path / "w"), "--json", *sets])
    out_w = capsys.readouterr().out
    r, w = json.loads(out_r)["cells"][0], json.loads(out_w)["cells"][0]     # stdout is pure JSON
    assert rc_r == rc_w == 0 and r["final_status"] == w["final_status"] == "force_cap"
    assert w["strain_at_first_jamming"] == pytest.approx(r["strain_at_first_jamming"], abs=1e-8)
    assert w["cycles"][0]["energy_N_per_strain"] == pytest.approx(r["cycles"][0]["energy_N_per_strain"], rel=1e-6)


def test_a_scene_from_a_flagged_calibration_says_so_in_every_result(tmp_path, capsys):
    """A blind probe ran the bundled calibration's cell scene and a scene naming its library's materials (the
    calibration: NOT A CALIBRATION YOU CAN USE, 5 flags) and read "completed the load program", nothing in
    the console or summary.json.  Expected: the warning from_unusable_calibration, naming where the values come
    from and the first flag, in summary.json and on the console; a library without flags gives none."""
    cal = REPO / "scenes" / "calibration" / "do2020" / "calibrated"
    main(["cell", str(cal / "jersey_4p5.cell.toml"), "--out", str(tmp_path / "a")])
    err = capsys.readouterr().err
    w = [x for x in json.loads((tmp_path / "a" / "summary.json").read_text())["warnings"]
         if x["code"] == "from_unusable_calibration"]
    assert len(w) == 1 and "NOT ONE YOU CAN USE (5 flag(s): d = 0.29 mm is at its high bound" in w[0]["message"]
    assert "NOT ONE YOU CAN USE" in err
    lib = (cal / "materials.toml").read_text()
    (tmp_path / "lib.toml").write_text(lib)
    scene = ('materials = "lib.toml"\n[knit]\nmaterial = "jersey_4p5"\n[load]\ntype = "monotonic"\n'
             'target_strain = 0.1\nmax_increment = 0.02\n')
    (tmp_path / "s.toml").write_text(scene)
    main(["cell", str(tmp_path / "s.toml"), "--out", str(tmp_path / "b")])
    w = [x["message"] for x in json.loads((tmp_path / "b" / "summary.json").read_text())["warnings"]
         if x["code"] == "from_unusable_calibration"]
    assert len(w) == 1 and "yarn 'do2020_yarn'" in w[0] and "knit 'jersey_4p5'" in w[0]
    (tmp_path / "lib.toml").write_text("\n".join(ln for ln in lib.splitlines() if not ln.startswith("flags = ")))
    main(["cell", str(tmp_path / "s.toml"), "--out", str(tmp_path / "c")])
    assert not any(x["code"] == "from_unusable_calibration"
                   for x in json.loads((tmp_path / "c" / "summary.json").read_text())["warnings"])


TIGHT_CELL = """title = "tight corner cell"
engine = "{engine}"
device = "cpu"
[yarn]
B = 10.0
d = 0.1
[knit]
W0 = 0.55
C0 = 0.4
L = 1.68625
[friction]
model = "coulomb"
m = 0.05
[load]
type = "monotonic"
target_strain = 0.05
max_increment = 0.01
[output]
plot = false
"""


def test_a_tight_cell_the_warp_engine_solves_is_not_refused_for_the_reference_s_rest_state(tmp_path, capsys):
    """A blind probe's corner cell (d = 0.1, B = 10, W0 = 5.5 d, C0 = 4 d, L ratio 1.775, inside the domain's
    box): its rest state exists (alpha - gamma = 4.4e-4, a pushing contact; rest force 23681.63909 N per wale by
    an independent shooting solver of the elastica ODE, scipy's solve_ivp + root, to 10 digits), but the float64
    reference's continuation in L stops at ratio 1.78.  With the Warp engine the cell runs, from that rest force;
    with the reference engine it is refused, saying where its continuation stopped (not that the loop cannot
    exist)."""
    import json

    path = tmp_path / "tight.toml"
    path.write_text(TIGHT_CELL.format(engine="warp"))
    assert main(["cell", str(path), "--out", str(tmp_path / "w")]) == 0
    rows = (tmp_path / "w" / "curve.csv").read_text().splitlines()
    head = rows[0].split(",")
    rest = dict(zip(head, rows[1].split(",")))
    assert float(rest["force_per_wale_N"]) == pytest.approx(23681.63909, rel=1e-9)
    assert json.loads((tmp_path / "w" / "summary.json").read_text())["all_expected_end"] is True
    path.write_text(TIGHT_CELL.format(engine="reference"))
    assert main(["cell", str(path), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert "no rest state found" in err and "was followed down to 1.78" in err and 'engine = "warp"' in err


def test_a_tight_cell_the_warp_engine_cannot_start_is_refused_without_suggesting_that_engine(tmp_path, capsys):
    """The same corner cell tighter, L ratio 1.70 (L = 1.615 mm), below where the Warp engine's rest-state solve
    reaches (a blind probe: the refusal of an engine = "warp" cell suggested the Warp engine "may reach tighter
    loops").  Expected: refused before any work (exit 2), saying down to which ratio the Warp engine, the one
    asked for, finds the loop: between the asked 1.70 and 1.775, where an independent shooting solver has the
    rest state and that engine runs the cell (test above).  The ratio is that engine's own search (before: the
    reference's continuation in L, ~20 s to word a refusal of a cell at ratio 1.2 on the CPU)."""
    import re

    path = tmp_path / "tighter.toml"
    path.write_text(TIGHT_CELL.format(engine="warp").replace("L = 1.68625", "L = 1.615"))
    assert main(["cell", str(path), "--out", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    found = re.search(r"no rest state found: the Warp engine's rest-state solve finds the quarter loop at C0 = 0\.4, "
                      r"W0 = 0\.55 mm, phi0 = 0 rad down to L / \(2 C0 \+ W0 - 4 d\) = ([0-9.]+) \(L = [0-9.]+ mm\), "
                      r"L = 1\.615 mm asks for 1\.7 ", err)
    assert found and 1.70 < float(found.group(1)) <= 1.775, err
    assert "may reach tighter loops" not in err
    assert not (tmp_path / "w" / "summary.json").exists()


def test_a_set_that_a_cell_states_itself_is_warned_of(tmp_path, capsys):
    """--set friction.m=0.3 on a scene whose second cell states its own m (or phi0 as phi0_deg) does not reach that
    cell: a cell's own keys replace the base's; the summary's params showed it, nothing else (a blind probe)."""
    scene = tmp_path / "s.toml"
    scene.write_text('[yarn]\nmaterial = "e_glass"\n[knit]\nmaterial = "e_glass_plain"\n[friction]\nm = 0.2\n'
                     'phi0 = 0.0\n[rules]\nforce_cap_N = 10.0\n[load]\ntype = "monotonic"\ntarget_strain = 0.2\n'
                     'max_increment = 0.1\n[[cells]]\nlabel = "a"\n[[cells]]\nlabel = "b"\n'
                     'friction = { m = 0.4, phi0_deg = 1.0 }\n')
    assert main(["cell", str(scene), "--set", "friction.m=0.3", "--set", "friction.phi0=0.05",
                 "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    assert ("--set friction.m=0.3: 1 of the scene's 2 cell(s) (b) set friction.m themselves (e.g. cells[1].friction.m "
            "= 0.4): their own value wins") in err
    assert "--set friction.phi0=0.05: 1 of the scene's 2 cell(s) (b) set friction.phi0 themselves (e.g. " \
           "cells[1].friction.phi0_deg = 1" in err
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert [c["params"]["m"] for c in s["cells"]] == [0.3, 0.4]                # what the warning says
    assert [w["code"] for w in s["warnings"]].count("set_key_set_by_cell") == 2
    # a --set of a key no cell states: nothing said
    assert main(["cell", str(scene), "--set", "knit.L=14.0", "--out", str(tmp_path / "p")]) == 0
    assert "set_key_set_by_cell" not in (tmp_path / "p" / "summary.json").read_text()


def test_a_parameter_of_an_effect_that_is_off_is_warned_of(tmp_path, capsys):
    """--set effects.bend_h=0.5 without bending_hysteresis in effects.on runs bit for bit as without it (the kernels
    read an effect's parameters only where it is on: checked here on curve.csv), and was not said (a blind probe):
    warned on the console and in summary.json; with the effect on, it changes the curve and nothing is said."""
    scene = Path(__file__).resolve().parents[2] / "scenes" / "paper" / "e_glass_cyclic.toml"
    args = ["cell", str(scene), "--set", "load.max_increment=0.05"]
    assert main(args + ["--out", str(tmp_path / "plain")]) == 0
    assert main(args + ["--set", "effects.bend_h=0.5", "--out", str(tmp_path / "off")]) == 0
    err = capsys.readouterr().err
    assert ("effects.bend_h = 0.5 is a parameter of the effect bending_hysteresis, which is off (effects.on): it "
            "changes nothing") in err
    codes = [w["code"] for w in json.loads((tmp_path / "off" / "summary.json").read_text())["warnings"]]
    assert "effect_parameter_unused" in codes
    curve = {d: (tmp_path / d / "curve.csv").read_text() for d in ("plain", "off")}
    assert curve["plain"] == curve["off"]
    assert main(args + ["--set", "effects.bend_h=0.5", "--set", 'effects.on=["bending_hysteresis"]',
                        "--out", str(tmp_path / "on")]) == 0
    assert "changes nothing" not in capsys.readouterr().err
    assert (tmp_path / "on" / "curve.csv").read_text() != curve["plain"]


def test_the_readme_s_effect_example_at_the_default_strength_is_warned_of(tmp_path, capsys):
    """The README's --set 'effects.on=["yarn_compaction"]' with compaction_k at its default 0 runs bit for bit as
    without the effect (the law's own limit, a rigid yarn): said on the console and in summary.json (a blind
    probe: nothing was said); with a strength given, nothing is."""
    scene = Path(__file__).resolve().parents[2] / "scenes" / "paper" / "e_glass_monotonic.toml"
    args = ["cell", str(scene), "--set", 'effects.on=["yarn_compaction"]', "--set", "load.max_increment=0.1"]
    assert main(args + ["--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert "effect yarn_compaction is on at effects.compaction_k = 0, where it changes nothing" in err
    codes = [w["code"] for w in json.loads((tmp_path / "a" / "summary.json").read_text())["warnings"]]
    assert "effect_without_strength" in codes
    assert main(args + ["--set", "effects.compaction_k=5", "--out", str(tmp_path / "b")]) == 0
    assert "changes nothing" not in capsys.readouterr().err
