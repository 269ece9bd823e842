"""``knitsim run``: what a run says of itself where the user looks, and work that is never lost.

Where the expected outcomes come from:

- cells past the model's domain (strain 0.6, ``knitsim.cell.domain.DOMAIN``) while the grip stays inside it:
  a specimen pretensioned by p has its knit at rest over ``gauge / (1 + p)`` (``PatchModel.pretension``),
  so at grip strain g (displacement / gauge from the pretensioned origin) a uniform knit is at strain
  ``(1 + p)(1 + g) - 1`` (construction: 0.8 for p = 0.5, g = 0.2); two cells of equal C0 in series between
  rigid grips have elongations that add up to the grip displacement, so their strains add up to twice the
  grip strain while the column carries load (identity);
- increments: ``cycles(0.1, 0.3, 1, 0.05)`` has 6 loading and 4 unloading increments, ``monotonic`` its
  target over the increment (``knitsim.cell.load_program``, counted here from the program itself);
- the 1 x 1 patch reproduces its cell bit for bit (README, "Patches"), so its residual strain and first
  jamming are compared with ``knitsim cell``'s located events (events.csv), the tolerance of the first
  jamming from the cell's own curve (the secant's error, bound below).
"""
from __future__ import annotations

import csv
import json
import re
import shlex
import sys
from pathlib import Path

import numpy as np
import pytest

from knitsim.cell.load_program import cycles, monotonic
from knitsim.cli import main
from knitsim.io.output_dir import RECORD_NAME

PATCH = """
title = "tiny"
[patch]
wales = 2
courses = 2
[yarn]
material = "e_glass"
[knit]
material = "e_glass_plain"
[friction]
m = 0.2
phi0 = 0.0
[load]
type = "cycles"
lower_strain = 0.1
upper_strain = 0.3
cycles = 1
max_increment = 0.05
[output]
checkpoint_every = 1
"""
N_PATCH = len(cycles(0.1, 0.3, 1, 0.05))           # 10 increments


def _scene(tmp_path, text=PATCH, name="s.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def _interrupt_after(monkeypatch, k):
    """knitsim run's solve stopped after k increments (checkpoint written), as a Ctrl-C there would."""
    import knitsim.patch.runner as runner
    real = runner.run_patch

    def interrupted(*a, **kw):
        try:
            return real(*a, stop_after=k, **kw)
        except runner.PatchInterrupted:
            raise KeyboardInterrupt from None

    monkeypatch.setattr(runner, "run_patch", interrupted)
    return lambda: monkeypatch.setattr(runner, "run_patch", real)


def _argv(monkeypatch, argv):
    monkeypatch.setattr(sys, "argv", ["knitsim"] + argv)     # the resume command is the command line as typed
    return argv


# ----------------------------------------------------------------------------------------- 1: the domain


def test_a_pretensioned_specimen_past_the_domain_is_warned_though_its_grip_strain_is_inside(tmp_path, capsys,
                                                                                          monkeypatch):
    scene = _scene(tmp_path, """
[specimen]
width = 50.0
gauge_length = 100.0
pretension = 0.5
[yarn]
material = "e_glass"
[knit]
material = "e_glass_plain"
[friction]
model = "coulomb"
m = 0.2
[load]
type = "monotonic"
target_strain = 0.2
max_increment = 0.05
""")
    import knitsim.io.patch_results as pr
    shown = {}
    real_plot = pr.plot_force_strain

    def plot(h, title="", layout=None, warnings=None, force_cap=None):
        shown["warnings"] = warnings
        return real_plot(h, title, layout, warnings, force_cap)

    monkeypatch.setattr(pr, "plot_force_strain", plot)
    rc = main(["run", str(scene), "--out", str(tmp_path / "o"), "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 0, err
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    (w,) = [w for w in s["warnings"] if w["code"] == "cells_outside_domain"]   # before: none (grip program 0.2)
    p, g = 0.5, 0.2
    knit = (1 + p) * (1 + g) - 1                                            # 0.8 (construction)
    assert f"up to {knit:.4g} at band 0 strip 0" in w["message"], w["message"]
    assert "while the grip strain stays within it (at most 0.2)" in w["message"]
    assert "specimen.pretension = 0.5" in w["message"]
    # from the first row whose knit strain (1 + p)(1 + g) - 1 passes 0.6
    with open(tmp_path / "o" / "curve.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))[1:]
    first = next(r for r in rows if (1 + p) * (1 + float(r["grip_strain"])) - 1 > 0.6 + 1e-9)
    assert f"past 0.6 from grip strain {float(first['grip_strain']):.4g} (increment {first['increment']})" \
        in w["message"]
    # where the user looks: the console and the plot, as the pre-run domain warnings are
    assert "knitsim run: warning: " + w["message"] in err
    assert w in shown["warnings"]


def test_zones_in_series_past_the_domain_are_named_and_the_overlap_says_grip_strain(tmp_path, capsys):
    scene = _scene(tmp_path, """
[patch]
wales = 1
courses = 2
[yarn]
material = "e_glass"
[knit]
material = "e_glass_plain"
[friction]
model = "coulomb"
phi0 = 0.0
[[zones]]
label = "basalt"
courses = [1, 2]
yarn = { material = "basalt" }
knit = { material = "basalt_plain" }
[load]
type = "monotonic"
target_strain = 0.55
max_increment = 0.05
""")
    assert main(["run", str(scene), "--out", str(tmp_path / "o"), "--no-progress"]) == 0
    err = capsys.readouterr().err
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    (w,) = [w for w in s["warnings"] if w["code"] == "cells_outside_domain"]   # before: none (grip 0.55 < 0.6)
    import xarray as xr
    with xr.open_dataset(tmp_path / "o" / "cells.nc", engine="h5netcdf") as ds:
        C0 = ds["C0"].values[:, 0]
        basalt_end = float(ds["strain"].values[-1, 1, 0])
    assert C0[0] == C0[1]
    e_glass_end = 2 * 0.55 - basalt_end               # identity: equal rest lengths, elongations add up to u
    assert e_glass_end > 0.6
    assert f"up to {e_glass_end:.4g} at course 0 wale 0 (base knit) at grip strain 0.55" in w["message"]
    assert "1 of 2 cell(s)" in w["message"] and "by zone: base knit: 1 cell(s)" in w["message"]
    assert "knitsim run: warning: " + w["message"] in err
    # the overlap warning's strains are the grip's, and it says so, with the cells' own beside them
    (o,) = [w for w in s["warnings"] if w["code"] == "heads_interpenetrate"]
    assert " at grip strains " in o["message"] and "(cell strains " in o["message"]
    assert f"to {e_glass_end:.4g})" in o["message"]


def test_overlapping_zones_are_warned_before_the_run_naming_the_cells(tmp_path, capsys):
    # Zones do not stack (the scene schema: later ones on top, each the base scene with its own keys): a zone
    # giving only knit.L over a basalt zone makes E-glass cells there.  The overlap of courses [0, 3) and [2, 4)
    # on wales [0, 2) is course 2 of both wales: 2 cells; adjacent zones (courses [3, 4) after [0, 3)) do not.
    body = """
[patch]
wales = 2
courses = 4
[yarn]
material = "e_glass"
[knit]
material = "e_glass_plain"
[[zones]]
label = "a"
courses = [0, 3]
yarn = { material = "basalt" }
knit = { material = "basalt_plain" }
[[zones]]
label = "b"
courses = [%s, 4]
knit = { L = 13.5 }
[load]
type = "monotonic"
target_strain = 0.1
max_increment = 0.05
"""
    assert main(["run", str(_scene(tmp_path, body % 2)), "--out", str(tmp_path / "o"), "--no-progress"]) == 0
    err = capsys.readouterr().err
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    (w,) = [w for w in s["warnings"] if w["code"] == "zones_overlap"]
    assert "zone 'a' and zone 'b' overlap on courses [2, 3) x wales [0, 2) (2 cells)" in w["message"]
    assert err.count("knitsim run: warning: " + w["message"]) == 1          # before the run only (it was twice)
    (tmp_path / "p").mkdir()
    assert main(["run", str(_scene(tmp_path / "p", body % 3)), "--out", str(tmp_path / "o2"), "--no-progress"]) == 0
    capsys.readouterr()
    s = json.loads((tmp_path / "o2" / "summary.json").read_text())
    assert not [w for w in s["warnings"] if w["code"] == "zones_overlap"]


def test_two_zones_of_one_label_that_overlap_are_warned_of(tmp_path, capsys):
    # Two zones both labelled "x" on courses [0, 2) and [1, 3) of a 3 x 2 patch share course 1 (2 cells, hand-
    # counted): the later one's keys alone hold there, as for zones of two labels.  Before, zones were told apart by
    # their label, so the two read as one grade's elements (which tile without overlap) and nothing was said.
    body = """
[patch]
wales = 2
courses = 3
[yarn]
material = "e_glass"
[knit]
material = "e_glass_plain"
[[zones]]
label = "x"
courses = [0, 2]
friction = { phi0 = 0.1 }
[[zones]]
label = "x"
courses = [1, 3]
knit = { L = 14.0 }
[load]
type = "monotonic"
target_strain = 0.1
max_increment = 0.05
"""
    assert main(["run", str(_scene(tmp_path, body)), "--out", str(tmp_path / "o"), "--no-progress"]) == 0
    capsys.readouterr()
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    (w,) = [w for w in s["warnings"] if w["code"] == "zones_overlap"]
    assert w["message"].startswith("zone 'x' on courses [0, 2) x wales [0, 2) and zone 'x' on courses [1, 3) x wales "
                                   "[0, 2) overlap on courses [1, 2) x wales [0, 2) (2 cells): there the cells are the "
                                   "base scene with the keys of zone 'x' on courses [1, 3) x wales [0, 2) alone"), w


def test_a_zone_over_a_grade_is_one_warning_said_once(tmp_path, capsys):
    # A grade along the courses of a 4-course patch is 4 elements (one per course) in the resolved scene; a zone
    # on courses [1, 3) of both wales overlaps 2 of them, 4 cells in all (hand-counted).  One warning names the
    # grade and the zone (before: one per element, each printed before the run and again after it).
    body = """
[patch]
wales = 2
courses = 4
[yarn]
material = "e_glass"
[knit]
material = "e_glass_plain"
[[grades]]
label = "g"
from = "e_glass_plain"
to = "e_glass_plain"
axis = "courses"
[[zones]]
label = "z"
courses = [1, 3]
knit = { L = 13.8 }
[load]
type = "monotonic"
target_strain = 0.1
max_increment = 0.05
"""
    assert main(["run", str(_scene(tmp_path, body)), "--out", str(tmp_path / "o"), "--no-progress"]) == 0
    err = capsys.readouterr().err
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    (w,) = [w for w in s["warnings"] if w["code"] == "zones_overlap"]
    assert w["message"].startswith("grade 'g' and zone 'z' overlap on courses [1, 3) x wales [0, 2) (4 cells): "
                                   "there the cells are the base scene with the keys of zone 'z' alone, not those of "
                                   "grade 'g' ")
    assert "''s" not in w["message"]             # a quoted name with a possessive read zone 'z''s
    assert err.count("overlap on courses") == 1 and err.count("knitsim run: warning: " + w["message"]) == 1
    # the resolved scene (grade elements written as zones) run as it is: the same one warning
    out2 = tmp_path / "o2"
    assert main(["run", str(tmp_path / "o" / "scene.resolved.toml"), "--out", str(out2), "--no-progress"]) == 0
    capsys.readouterr()
    s2 = json.loads((out2 / "summary.json").read_text())
    assert [x["message"] for x in s2["warnings"] if x["code"] == "zones_overlap"] == [w["message"]]


# ----------------------------------------------------------------------------------- 2: --usd on --resume


def test_resume_never_replaces_a_usd_file_it_was_not_given(tmp_path, capsys, monkeypatch):
    scene = _scene(tmp_path)
    out = tmp_path / "o"
    precious = tmp_path / "precious.usda"
    precious.write_text("x\n")
    restore = _interrupt_after(monkeypatch, 2)
    assert main(_argv(monkeypatch, ["run", str(scene), "--out", str(out), "--no-progress"])) == 130
    restore()
    capsys.readouterr()
    # resumed with --usd naming a file that was there before and that the run was never given: refused
    # before any work (before: replaced without a word)
    rc = main(_argv(monkeypatch, ["run", str(scene), "--out", str(out), "--no-progress", "--resume",
                                  "--usd", str(precious)]))
    err = capsys.readouterr().err
    assert rc == 2 and "exists" in err and "without consent" in err, err
    assert precious.read_text() == "x\n" and (out / "checkpoint.pkl").is_file() and not (out / "summary.json").exists()
    # a file that is not there is this run's to write
    fresh = tmp_path / "fresh.usda"
    assert main(_argv(monkeypatch, ["run", str(scene), "--out", str(out), "--no-progress", "--resume",
                                    "--usd", str(fresh)])) == 0
    assert fresh.read_text().startswith("#usda")
    # the console says where it resumed (a blind probe found it only in summary.json's resumed_from)
    done = json.loads((out / "summary.json").read_text())["solver"]["resumed_from"]
    assert re.search(rf"resuming from .*checkpoint\.pkl: {done} of \d+ increments done", capsys.readouterr().err)

    # consent given when the run started (--overwrite) holds for its resume, which cannot repeat --overwrite
    given = tmp_path / "given.usda"
    given.write_text("old\n")
    restore = _interrupt_after(monkeypatch, 2)
    argv = _argv(monkeypatch, ["run", str(scene), "--out", str(tmp_path / "o2"), "--no-progress", "--usd",
                               str(given), "--overwrite"])
    assert main(argv) == 130
    restore()
    cmd = capsys.readouterr().err.split("continue with: ")[1].strip().splitlines()[0]
    assert "--overwrite" not in cmd
    assert main(_argv(monkeypatch, shlex.split(cmd)[1:])) == 0
    assert given.read_text().startswith("#usda")


# ------------------------------------------------------------------------- 3: Ctrl-C while writing outputs


def test_ctrl_c_while_the_outputs_are_written_keeps_the_solve_and_the_resume_writes_them(tmp_path, capsys,
                                                                                        monkeypatch):
    import knitsim.io.patch_results as pr
    from knitsim.patch import coupling
    scene = _scene(tmp_path)
    full = tmp_path / "full"
    assert main(["run", str(scene), "--out", str(full), "--no-progress"]) == 0
    out = tmp_path / "o"
    real_write = pr.write_patch_results

    def ctrl_c(*a, **kw):
        raise KeyboardInterrupt

    monkeypatch.setattr(pr, "write_patch_results", ctrl_c)
    argv = _argv(monkeypatch, ["run", str(scene), "--out", str(out), "--no-progress"])
    assert main(argv) == 130
    err = capsys.readouterr().err
    # before: "knitsim: interrupted" alone, and the checkpoint held the last periodic one (done < total)
    assert f"the solve is finished and kept: {N_PATCH}/{N_PATCH} increment(s) in the checkpoint" in err, err
    cmd = err.split("without solving again, with: ")[1].strip().splitlines()[0]
    assert cmd.endswith(" --resume")
    # nothing that looks complete: the checkpoint alone, its pickle and the chunks of its rows (summary.json,
    # written last, marks a complete set)
    assert sorted(p.name for p in out.iterdir()) == [RECORD_NAME, "checkpoint.pkl", "checkpoint_rows"]
    monkeypatch.setattr(pr, "write_patch_results", real_write)

    def no_solving(*a, **kw):
        raise AssertionError("the finished solve was solved again")

    monkeypatch.setattr(coupling.PatchSolver, "step", no_solving)
    assert main(_argv(monkeypatch, shlex.split(cmd)[1:])) == 0
    assert "holds the finished solve" in capsys.readouterr().err
    assert not (out / "checkpoint.pkl").exists() and not (out / "checkpoint_rows").exists()
    for name in ("curve.csv", "columns.csv"):                # the uninterrupted run's, bit for bit
        assert (out / name).read_bytes() == (full / name).read_bytes(), name


def test_a_disk_that_fills_while_the_outputs_are_written_keeps_the_solve_and_says_how_to_write_them(
        tmp_path, capsys, monkeypatch):
    # writing the outputs failed with an OSError (a full disk) after the solve: before, a traceback, the
    # checkpoint kept without a word of it; now one line that says the solve is kept and the command that
    # writes the outputs, exit 1, and that command writes what the uninterrupted run writes
    import errno

    import knitsim.io.patch_results as pr
    scene = _scene(tmp_path)
    full = tmp_path / "full"
    assert main(["run", str(scene), "--out", str(full), "--no-progress"]) == 0
    out = tmp_path / "o"
    real_write = pr.write_patch_results

    def disk_full(out_dir, *a, **kw):
        # (write_result_set writes into a hidden sibling folder first: nothing of it in --out)
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(pr, "write_patch_results", disk_full)
    argv = _argv(monkeypatch, ["run", str(scene), "--out", str(out), "--no-progress"])
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert (f"knitsim run: writing the outputs failed ([Errno 28] No space left on device); the solve is finished "
            f"and kept: {N_PATCH}/{N_PATCH} increment(s) in the checkpoint") in err, err
    assert not (out / "summary.json").exists()
    cmd = err.split("without solving again, with: ")[1].strip().splitlines()[0]
    monkeypatch.setattr(pr, "write_patch_results", real_write)
    assert main(_argv(monkeypatch, shlex.split(cmd)[1:])) == 0
    for name in ("curve.csv", "columns.csv"):                # the uninterrupted run's, bit for bit
        assert (out / name).read_bytes() == (full / name).read_bytes(), name


@pytest.mark.parametrize("signame", ["SIGTERM", "SIGHUP"])
def test_sigterm_checkpoints_says_how_to_resume_and_the_resume_equals_the_uninterrupted_run(tmp_path, capsys,
                                                                                          monkeypatch, signame):
    # SIGTERM (a batch scheduler's time limit, kill, timeout) and SIGHUP (the terminal closed, an ssh session
    # dropped) are taken as a Ctrl-C: before, the process died at once with no message, keeping only the last
    # periodic checkpoint (none here: checkpoint_every is past the program's end). Sent to a real process once
    # its progress says 10% of the increments are done.
    import signal
    import subprocess

    sig = getattr(signal, signame)

    text = PATCH.replace("max_increment = 0.05", "max_increment = 0.002").replace(
        "checkpoint_every = 1", "checkpoint_every = 100000")
    scene = _scene(tmp_path, text)
    total = len(cycles(0.1, 0.3, 1, 0.002))
    full = tmp_path / "full"
    assert main(["run", str(scene), "--out", str(full), "--no-progress"]) == 0
    out = tmp_path / "o"
    # the knitsim this interpreter imports (installed, or editable): not the source tree on PYTHONPATH, whose
    # knitsim.kernels exists only as installed (setup.py maps kernels/ to it)
    # the child's disposition the default: a test run under nohup (or a CI runner that ignores SIGHUP) passes
    # an ignored SIGHUP on to its children, which knitsim then rightly leaves ignored
    p = subprocess.Popen([sys.executable, "-m", "knitsim", "run", str(scene), "--out", str(out)], cwd=tmp_path,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: signal.signal(sig, signal.SIG_DFL))
    before = []
    for line in p.stderr:
        before.append(line)
        if "knitsim run: increments: " in line:        # the first progress line (10%): a few increments in
            p.send_signal(sig)
            break
    err = p.stderr.read()
    p.stdout.read()
    assert any("knitsim run: increments: " in line for line in before), "".join(before)
    # 143 = 128 + SIGTERM, 129 = 128 + SIGHUP, as before and as a shell or scheduler reads it (Ctrl-C: 130)
    assert p.wait() == 128 + int(sig), err
    m = re.search(r"interrupted; (\d+)/(\d+) increment\(s\) kept in the checkpoint .*; continue with: (.*)", err)
    assert m, err
    done = int(m.group(1))
    assert int(m.group(2)) == total and 0 < done < total
    assert (out / "checkpoint.pkl").is_file() and not (out / "summary.json").exists()
    cmd = shlex.split(m.group(3).strip())
    assert cmd[:2] == ["knitsim", "run"] and cmd[-1] == "--resume"
    assert main(_argv(monkeypatch, cmd[1:] + ["--no-progress"])) == 0
    assert f"resuming from {out / 'checkpoint.pkl'}: {done} of {total}" in capsys.readouterr().err
    for name in ("curve.csv", "columns.csv"):                # the uninterrupted run's, bit for bit
        assert (out / name).read_bytes() == (full / name).read_bytes(), name


@pytest.mark.parametrize("signame", ["SIGTERM", "SIGHUP"])
def test_sigterm_as_ctrl_c_restores_the_handler_and_keeps_an_ignored_sigterm_ignored(signame):
    import os
    import signal

    from knitsim.cli.common import sigterm_as_ctrl_c
    sig = getattr(signal, signame)
    inherited = signal.signal(sig, signal.SIG_DFL)           # (a test run under nohup inherits SIGHUP ignored)
    try:
        before = signal.getsignal(sig)
        with sigterm_as_ctrl_c() as got, pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), sig)
            for _ in range(1000):                            # (delivered at the next bytecode)
                pass
        assert got == [sig] and signal.getsignal(sig) is before
        signal.signal(sig, signal.SIG_IGN)                   # (nohup ignores SIGHUP: it stays ignored)
        with sigterm_as_ctrl_c() as got:
            os.kill(os.getpid(), sig)                        # ignored: nothing raised
        assert got == []
    finally:
        signal.signal(sig, inherited)


def test_an_interrupted_usd_export_leaves_no_file_that_looks_whole(tmp_path, capsys, monkeypatch):
    import knitsim.usd.from_results as fr
    scene = _scene(tmp_path)
    out, usd = tmp_path / "o", tmp_path / "y.usda"

    def half_then_ctrl_c(h, params, out_path, **kw):
        Path(out_path).write_text("#usda 1.0\n(\n")             # a USD file cut off where the Ctrl-C came
        raise KeyboardInterrupt

    monkeypatch.setattr(fr, "export_history", half_then_ctrl_c)
    assert main(_argv(monkeypatch, ["run", str(scene), "--out", str(out), "--no-progress", "--usd", str(usd)])) == 130
    assert "the solve is finished and kept" in capsys.readouterr().err
    assert not usd.exists() and not [p for p in tmp_path.iterdir() if "partial" in p.name]
    assert not (out / "summary.json").exists() and (out / "checkpoint.pkl").is_file()


# ------------------------------------------------------------------------------- 4: see test_force_cap_outputs
# ------------------------------------------------------------------------- 5: knitsim usd of an unfinished run


def test_knitsim_usd_of_an_unfinished_run_says_so_and_how_to_finish_it(tmp_path, capsys, monkeypatch):
    scene = _scene(tmp_path)
    out = tmp_path / "o"
    restore = _interrupt_after(monkeypatch, 3)
    assert main(_argv(monkeypatch, ["run", str(scene), "--out", str(out), "--no-progress"])) == 130
    restore()
    capsys.readouterr()
    rc = main(["usd", str(out), "--out", str(tmp_path / "y.usda")])
    err = capsys.readouterr().err
    # before: "no cells.nc (was the run made with output.cell_fields = false?)"
    assert rc == 2 and "the run is unfinished" in err and f"holds 3/{N_PATCH} solved increment(s)" in err, err
    cmd = err.split("finish it with (in ")[1].split("): ", 1)[1].split("; then run knitsim usd")[0]
    assert cmd.startswith("knitsim run ") and cmd.endswith(" --resume")
    assert main(_argv(monkeypatch, shlex.split(cmd)[1:])) == 0
    assert main(["usd", str(out), "--out", str(tmp_path / "y.usda")]) == 0


# -------------------------------------------------------------- 6: residual strain and first jamming, located

CELL = """
title = "E-glass, m = 0.45"
[yarn]
material = "e_glass"
in_plane_width = 0.79
[knit]
material = "e_glass_plain"
[friction]
model = "coulomb"
m = 0.45
phi0 = 0.0
[rules]
force_cap_N = 50.0
[load]
type = "cycles"
lower_strain = 0.1
upper_strain = 0.6
cycles = 1
max_increment = 0.01
"""


def test_a_1x1_patch_locates_residual_strain_and_first_jamming_as_its_cell_does(tmp_path, capsys):
    cell_scene = _scene(tmp_path, CELL, "cell.toml")
    patch_scene = _scene(tmp_path, CELL.replace("[yarn]", "[patch]\nwales = 1\ncourses = 1\n[yarn]"), "patch.toml")
    assert main(["cell", str(cell_scene), "--out", str(tmp_path / "c")]) == 0
    assert main(["run", str(patch_scene), "--out", str(tmp_path / "r"), "--no-progress"]) == 0
    capsys.readouterr()
    with open(tmp_path / "c" / "events.csv", newline="") as fh:
        events = list(csv.DictReader(fh))
    slack = float(next(e for e in events if e["kind"] == "slack")["event_strain"])
    jam = float(next(e for e in events if e["kind"] == "jam")["event_strain"])
    with open(tmp_path / "c" / "curve.csv", newline="") as fh:
        curve = [r for r in csv.DictReader(fh)]
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    (c1,) = s["cycles"]

    # the residual: the slack length the cell located (the patch's cell is the cell, bit for bit), read
    # through the column's slack length: equal to the rounding of (u + slack) / C0 against C / C0 - 1
    assert c1["residual_grip_strain"] == pytest.approx(slack, abs=1e-12)
    assert abs(0.15 - slack) > 1e-3                    # the row value reported before (0.15) is not it
    assert c1["residual_grip_strain_from"] == "slack_lengths"

    # the first jamming: the secant of q = W - 4 w through the two unjammed rows before the first jammed
    # one, extrapolated to 0 at t past the last, errs by |q''| t (t + h) / (2 |q'|) <= |q''| h^2 / |q'|;
    # q' and q'' from the cell's own rows (finite differences)
    h = 0.01
    b = next(k for k, r in enumerate(curve) if r["stage"] == "jamming")
    q = np.array([float(curve[k]["W"]) - 4 * 0.79 for k in (b - 3, b - 2, b - 1)])
    dq, d2q = (q[2] - q[1]) / h, (q[2] - 2 * q[1] + q[0]) / h ** 2
    bound = abs(d2q) * h ** 2 / abs(dq)
    assert abs(s["grip_strain_at_first_jamming"] - jam) <= bound, (s["grip_strain_at_first_jamming"], jam, bound)
    row = float(curve[b]["strain"])                    # what was reported before: the first jammed row
    assert abs(row - jam) > bound
    assert s["grip_strain_at_first_jamming_from"].startswith("located between rows")


HELD_SERIES = """
title = "series 1x3: a tight stitch between loose ones, held from rest"
[patch]
wales = 1
courses = 3
dedup = false
[yarn]
material = "e_glass"
[knit]
material = "e_glass_plain"
[friction]
m = 0.148
[rules]
force_cap_N = 20.0
[load]
type = "piecewise"
waypoints = [0.296, 0.182, 0.314]
max_increment = 0.01
[[zones]]
courses = [0, 1]
knit = { C0 = 2.9603, W0 = 3.6983, L = 13.5663 }
friction = { phi0 = 0.0532 }
[[zones]]
label = "tight"
courses = [1, 2]
knit = { C0 = 2.4927, W0 = 4.1334, L = 11.1565 }
friction = { phi0 = -0.0624 }
[[zones]]
courses = [2, 3]
knit = { C0 = 2.9500, W0 = 4.3284, L = 15.6725 }
friction = { phi0 = 0.1183 }
"""


def test_rows_after_a_held_column_are_not_reported_as_the_knits(tmp_path, capsys):
    """Cells in series between rigid grips: where the column carries load, their elongations add up to the grip
    displacement, sum C0 (C/C0 - 1) = u (identity).  This column (a tight stitch, 10.4 N per wale at rest, between
    two loose ones) finds no balance near rest: held (not converged) from its first increments, through the
    unloading from 0.296 to 0.182 (the grip above its cells' lengths), until it balances on the reload.  A blind
    probe's column that jammed and could not follow the grip from 0.55 to 0.6 (held at 9.705 N, below its cap),
    the scene this test had, now stops at its cap (the grip displacement of the cap located: tests/patch/
    test_coupling.py); before, unloading from it, the cells were kept at the held lengths by the direction of the
    increment, their forces agreed, and the rows at grip 0.59 to 0.56 were reported ok (1 trial, columns_held 0)
    with the lengths 0.057 to 0.228 mm short of the grips.  Every row reported the knit's must close, the others
    are held, and the summary says that the cycle figures include held rows."""
    out = tmp_path / "o"
    rc = main(["run", str(_scene(tmp_path, HELD_SERIES)), "--out", str(out), "--no-progress", "--json"])
    s = json.loads(capsys.readouterr().out)
    assert rc == 1
    import xarray as xr
    with xr.open_dataset(out / "cells.nc") as ds:
        e, C0, g = ds.strain.values[:, :, 0], ds.C0.values[:, 0], ds.grip_strain.values
    with open(out / "curve.csv") as f:
        held = np.array([int(r["columns_held"]) for r in csv.DictReader(f)][1:])      # row 0: the rest state
    gap = np.abs((C0 * e).sum(axis=1) - g * C0.sum())
    knit = held == 0
    assert knit.sum() > 10 and gap[knit].max() <= 1e-9 * C0.sum()
    assert np.all(held[gap > 1e-6] > 0) and (gap > 1e-3).sum() == 43         # 0.01 .. 0.296 .. 0.182, 0.191
    (w,) = [w for w in s["warnings"] if w["code"] == "cycle_figures_include_held_rows"]
    assert "cycle(s) 1 (42 row(s), grip strains 0.009867 to 0.296), 2 (1 row(s)" in w["message"]
    assert [c.get("held_rows") for c in s["cycles"]] == [42, 1]


def test_the_force_cap_cut_counts_the_columns_stopped_at_the_strain_it_names(tmp_path):
    """A blind probe: wale 0 of a 3-wale E-glass patch has in-plane width 1.0 mm (its heads meet first) and
    reaches the 0.5 N cap long before the others; the warning said "3 of 3 stopped at grip strain 0.33" where
    columns.csv showed one.  The count must be columns.csv's at that row, and the later stops said."""
    import csv
    import json
    from knitsim.cli import main
    scene = tmp_path / "cap.toml"
    scene.write_text('[yarn]\nmaterial = "e_glass"\n[knit]\nmaterial = "e_glass_plain"\n[friction]\nm = 0.20\n'
                     '[rules]\nforce_cap_N = 0.5\n[patch]\nwales = 3\ncourses = 2\n'
                     '[[zones]]\nwales = [0, 1]\nyarn = { in_plane_width = 1.0 }\n'
                     '[load]\ntype = "cycles"\nlower_strain = 0.10\nupper_strain = 0.9\ncycles = 2\n'
                     'max_increment = 0.02\n')
    out = tmp_path / "o"
    main(["run", str(scene), "--out", str(out)])
    cut = next(w for w in json.loads((out / "summary.json").read_text())["warnings"]
               if w["code"] == "program_cut_by_force_cap")["message"]
    rows = list(csv.DictReader((out / "columns.csv").open()))
    first = min(int(r["increment"]) for r in rows if r["status"] != "ok")
    stopped = {r["column"] for r in rows if int(r["increment"]) == first and r["status"] != "ok"}
    assert cut.startswith(f"{len(stopped)} of 3 wale column(s) stopped at the force cap"), cut
    assert len(stopped) < 3 and "stop at the cap later" in cut


def test_a_patch_unloading_from_rest_peaks_at_the_rest_state(tmp_path):
    """The same for a patch (a blind probe: "peak 0 N per wale at grip strain -0.005"): the peak is the rest
    state's force, curve.csv's row 0, at grip strain 0."""
    import csv
    import json
    from knitsim.cli import main
    scene = tmp_path / "u.toml"
    scene.write_text('[yarn]\nmaterial = "e_glass"\n[knit]\nmaterial = "e_glass_plain"\n[friction]\nm = 0.2\n'
                     '[patch]\nwales = 2\ncourses = 2\n[load]\ntype = "piecewise"\nwaypoints = [-0.05]\n'
                     'max_increment = 0.01\n')
    main(["run", str(scene), "--out", str(tmp_path / "o")])
    cyc = json.loads((tmp_path / "o" / "summary.json").read_text())["cycles"][0]
    row0 = next(csv.DictReader((tmp_path / "o" / "curve.csv").open()))
    assert float(row0["grip_strain"]) == 0.0 and cyc["grip_strain_at_peak"] == 0.0
    assert cyc["peak_force_per_wale_N"] == pytest.approx(float(row0["force_per_wale_N"]), rel=1e-12)
    assert cyc["peak_force_per_wale_N"] > 0.01
    # no loop: the unloading's work, and a warning where the user looks
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert "unloading_work_N_mm" in cyc and "work_N_mm" not in cyc and "hysteresis_energy_N_mm" not in cyc
    assert [w["code"] for w in summary["warnings"]].count("cycle_without_loading") == 1


P2Z = """
title = "two zones beyond reach"
[patch]
wales = 2
courses = 4
[yarn]
material = "e_glass"
[knit]
material = "e_glass_plain"
[friction]
m = 0.2
[rules]
force_cap_N = 1e6
[[zones]]
courses = [2, 4]
yarn = { material = "basalt" }
knit = { material = "basalt_plain" }
[load]
type = "monotonic"
target_strain = 1.2
max_increment = 0.01
"""


def test_columns_that_keep_failing_while_loading_hold_without_being_tried_again(tmp_path, capsys):
    """A blind probe's patch (E-glass over basalt, pulled to grip strain 1.2 under a 1e6 N cap): from 0.78 its
    two columns find no balance (jammed, the force diverges) and held to the end, but each of the last 42
    increments tried them again (~50 trials, 2.4 s each).  Expected (coupling.HELD_RETRIES): tried in 3 loading
    increments in a row, then held without trying (iterations 0) at the same force to the end, and the warning
    says so; the rows before, where the columns converged, are untouched (their iterations > 0)."""
    from knitsim.patch.coupling import HELD_RETRIES
    out = tmp_path / "o"
    assert main(["run", str(_scene(tmp_path, P2Z)), "--out", str(out), "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert f"a column that failed in {HELD_RETRIES} loading increments in a row is not tried again" in err
    with open(out / "columns.csv") as f:
        rows = [r for r in csv.DictReader(f) if r["column"] == "0"]
    first = next(i for i, r in enumerate(rows) if r["status"] != "ok")
    tried, held = rows[first:first + HELD_RETRIES], rows[first + HELD_RETRIES:]
    assert len(held) > 30 and all(r["status"] == "not_converged" for r in rows[first:])
    assert all(int(r["iterations"]) > 0 for r in rows[:first] + tried)
    assert all(int(r["iterations"]) == 0 for r in held)
    assert len({r["force_N"] for r in held}) == 1


def test_a_resume_of_a_changed_scene_is_refused_before_it_says_it_resumes(tmp_path, capsys, monkeypatch):
    # a blind probe: `knitsim run --resume` after editing the scene printed "resuming from ... 601 of 1700
    # increments done" and only then refused.  Expected: refused (exit 2) naming the way out, nothing said of
    # resuming, the checkpoint kept; the unchanged scene resumes
    scene = _scene(tmp_path)
    out = tmp_path / "o"
    restore = _interrupt_after(monkeypatch, 2)
    assert main(_argv(monkeypatch, ["run", str(scene), "--out", str(out), "--no-progress"])) == 130
    restore()
    capsys.readouterr()
    rc = main(_argv(monkeypatch, ["run", str(scene), "--out", str(out), "--no-progress", "--resume",
                                  "--set", "friction.m=0.25"]))
    err = capsys.readouterr().err
    assert rc == 2 and "belongs to another scene" in err and "--overwrite" in err, err
    # what changed, named (the scene's m = 0.2; before: "another scene, program or engine" and no more)
    assert "(changed since it was written: friction.m 0.2 -> 0.25)" in err, err
    assert "resuming from" not in err and "Traceback" not in err
    assert (out / "checkpoint.pkl").is_file() and not (out / "summary.json").exists()
    # a key of [output] may change on --resume: not a change of the run, neither refused nor named
    assert main(_argv(monkeypatch, ["run", str(scene), "--out", str(out), "--no-progress", "--resume",
                                    "--set", "output.checkpoint_every=3"])) == 0
    assert "resuming from" in capsys.readouterr().err


def test_a_resume_on_another_engine_is_refused_before_the_domain_check(tmp_path, capsys, monkeypatch):
    # a blind probe: `--resume --engine reference` of a warp run's checkpoint (12 x 12 random patch) was refused
    # only after the reference engine's rest-state check of its 144 cells, 51 s.  Expected (the project's rule:
    # refused before any work): the refusal, with nothing of the domain check run, the checkpoint kept
    import knitsim.cli.run as cli_run
    scene = _scene(tmp_path)
    out = tmp_path / "o"
    restore = _interrupt_after(monkeypatch, 2)
    assert main(_argv(monkeypatch, ["run", str(scene), "--out", str(out), "--no-progress"])) == 130
    restore()
    capsys.readouterr()

    def no_domain_check(*a, **kw):
        raise AssertionError("the domain check ran before the resume was refused")

    monkeypatch.setattr(cli_run, "check_patch_domain", no_domain_check)
    rc = main(_argv(monkeypatch, ["run", str(scene), "--out", str(out), "--no-progress", "--resume",
                                  "--engine", "reference"]))
    err = capsys.readouterr().err
    assert rc == 2 and "was computed by the warp engine, this run uses reference" in err, err
    assert (out / "checkpoint.pkl").is_file() and "Traceback" not in err
    rc = main(_argv(monkeypatch, ["run", str(scene), "--out", str(tmp_path / "none"), "--no-progress", "--resume"]))
    assert rc == 2 and "no checkpoint" in capsys.readouterr().err and not (tmp_path / "none").exists()


# ------------------------------------------------------------------------ one command at a time in a folder


@pytest.mark.parametrize("command", ["run", "calibrate", "diagnose-study"])
def test_a_second_command_into_a_folder_in_use_is_refused_before_any_work(tmp_path, capsys, monkeypatch, command):
    # an interrupted run in o/, then its folder's lock held by a process that runs (a child sleeping: hand-made,
    # as a first `knitsim run --resume` would hold it); a second command into o/ is refused, naming the holder,
    # the folder and its checkpoint untouched; with the holder gone, the resume takes the stale lock over
    import socket
    import subprocess

    from knitsim.io.output_dir import LOCK_NAME
    monkeypatch.setenv("MPLBACKEND", "Agg")
    scene = _scene(tmp_path)
    out = tmp_path / "o"
    restore = _interrupt_after(monkeypatch, 2)
    assert main(["run", str(scene), "--out", str(out), "--no-progress"]) == 130
    restore()
    assert not (out / LOCK_NAME).exists()                   # the interrupted run let its lock go
    before = sorted(p.name for p in out.iterdir())
    capsys.readouterr()
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])
    try:
        held = f"{other.pid}\n{socket.gethostname()}\nknitsim run\n"
        (out / LOCK_NAME).write_text(held)
        argv = {"run": ["run", str(scene), "--out", str(out), "--no-progress", "--resume"],
                "calibrate": ["calibrate", str(scene), "--out", str(out)],
                "diagnose-study": ["diagnose-study", "--cases", "1", "--out", str(out)]}[command]
        rc = main(argv)
        err = capsys.readouterr().err
        assert rc == 2 and "Traceback" not in err
        assert f"--out = {str(out)!r}: knitsim run (pid {other.pid}) is writing into this folder" in err
        assert (out / LOCK_NAME).read_text() == held                        # the other's lock, untouched
        assert sorted(p.name for p in out.iterdir()) == sorted(before + [LOCK_NAME])
    finally:
        other.kill()
        other.wait()
    if command == "run":
        assert main(["run", str(scene), "--out", str(out), "--no-progress", "--resume"]) == 0
        assert "which no longer runs (killed or crashed): taking it over" in capsys.readouterr().err
        assert not (out / LOCK_NAME).exists()


# --------------------------------------------------------- the checkpoint's rows in chunk files (checkpoint_rows/)


def test_overwrite_replaces_an_interrupted_run_with_its_chunks_and_keeps_a_users_file(tmp_path, capsys, monkeypatch):
    """An interrupted run leaves checkpoint.pkl and checkpoint_rows/ (one chunk per checkpoint: every increment
    here); both are knitsim's (recorded), so --overwrite removes them, and the finished run leaves neither. A
    user's file inside checkpoint_rows/ is refused by --overwrite, as one in a sweep's chunks/; a folder of that
    name that knitsim did not write is refused, --overwrite or not."""
    scene = _scene(tmp_path)
    out = tmp_path / "o"
    restore = _interrupt_after(monkeypatch, 3)
    assert main(_argv(monkeypatch, ["run", str(scene), "--out", str(out), "--no-progress"])) == 130
    restore()
    assert sorted(p.name for p in (out / "checkpoint_rows").iterdir()) == [
        "000000-000001.npz", "000001-000002.npz", "000002-000003.npz"]
    (out / "checkpoint_rows" / "my_note.md").write_text("keep")
    capsys.readouterr()
    assert main(["run", str(scene), "--out", str(out), "--no-progress", "--overwrite"]) == 2
    assert "checkpoint_rows/my_note.md changed since knitsim wrote" in capsys.readouterr().err
    assert (out / "checkpoint_rows" / "my_note.md").read_text() == "keep" and (out / "checkpoint.pkl").is_file()
    (out / "checkpoint_rows" / "my_note.md").unlink()
    assert main(["run", str(scene), "--out", str(out), "--no-progress", "--overwrite"]) == 0
    assert not (out / "checkpoint.pkl").exists() and not (out / "checkpoint_rows").exists()
    assert (out / "summary.json").is_file()
    # a folder named checkpoint_rows that knitsim did not write there
    mine = tmp_path / "mine"
    (mine / "checkpoint_rows").mkdir(parents=True)
    capsys.readouterr()
    for extra in ([], ["--overwrite"]):
        assert main(["run", str(scene), "--out", str(mine), "--no-progress", *extra]) == 2
        assert "holds checkpoint_rows, which knitsim did not write there" in capsys.readouterr().err
    assert (mine / "checkpoint_rows").is_dir() and not (mine / "summary.json").exists()


def test_a_resume_with_a_chunk_missing_is_refused_naming_it_before_it_says_it_resumes(tmp_path, capsys,
                                                                                      monkeypatch):
    scene = _scene(tmp_path)
    out = tmp_path / "o"
    restore = _interrupt_after(monkeypatch, 4)
    assert main(_argv(monkeypatch, ["run", str(scene), "--out", str(out), "--no-progress"])) == 130
    restore()
    capsys.readouterr()
    chunk = out / "checkpoint_rows" / "000001-000002.npz"
    kept = chunk.read_bytes()
    chunk.unlink()
    rc = main(["run", str(scene), "--out", str(out), "--no-progress", "--resume"])
    err = capsys.readouterr().err
    assert rc == 2 and f"--resume: {chunk} is missing: it holds increment 2 of the checkpoint" in err, err
    assert "resuming from" not in err and "Traceback" not in err
    chunk.write_bytes(kept[:-10])
    assert main(["run", str(scene), "--out", str(out), "--no-progress", "--resume"]) == 2
    assert f"--resume: {chunk} holds {len(kept) - 10} bytes" in capsys.readouterr().err
    chunk.write_bytes(kept)
    assert main(["run", str(scene), "--out", str(out), "--no-progress", "--resume"]) == 0
    assert not (out / "checkpoint_rows").exists()
