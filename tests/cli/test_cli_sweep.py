"""``knitsim sweep``: exit codes, one-line errors, JSON, interruption and resume."""
from __future__ import annotations

import json
import sys

import pytest

from knitsim.cli import main
from knitsim.sweep import runner

SCENE = """
engine = "warp"
[yarn]
material = "e_glass"          # Table 1: d = 0.58 mm
[knit]
material = "e_glass_plain"    # section 2.2: W0 = 4.4 mm
[friction]
m = 0.2
[load]
type = "cycles"
lower_strain = 0.1
upper_strain = 0.4
cycles = 2
max_increment = 0.1
"""
SWEEP = """
[sweep]
chunk_size = 2
[sweep.parameters]
"friction.m" = { values = [0.1, 0.2, 0.3] }
"""


def _files(tmp_path, sweep=SWEEP, separate=False):
    scene = tmp_path / "s.toml"
    if separate:
        scene.write_text(SCENE)
        (tmp_path / "w.toml").write_text(sweep)
    else:
        scene.write_text(SCENE + sweep)
    return scene


def test_sweep_runs_and_prints_json(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")
    scene = _files(tmp_path, separate=True)
    out = tmp_path / "o"
    rc = main(["sweep", str(scene), "--sweep", str(tmp_path / "w.toml"), "--out", str(out), "--workers", "0",
               "--json"])
    assert rc == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["samples"] == 3 and doc["chunks"] == 2 and doc["parameters"] == ["friction.m"]
    for f in ("sweep.json", "results.nc", "results.csv", "plot_sweep.png", "summary.json"):
        assert (out / f).is_file()


@pytest.mark.parametrize("sweep,words", [
    ('[sweep.parameters]\n"friction.mm" = { values = [0.1] }\n', ['"friction.mm"', "unknown key"]),
    ('[sweep.parameters]\n"knit.W0" = { values = [4.4, 2.0] }\n', ["knit.W0 = 2.0", ">= 4 d", "sample 1"]),
    ('[sweep.parameters]\n"friction.m" = { values = [] }\n', ['"friction.m"', "values"]),
    ('[sweep.parameters]\n"knit.L" = { min = 15.0, max = 13.0, count = 3 }\n', ['"knit.L"', "min", "max"]),
    ('[sweep.parameters]\n"friction.m" = { values = [-0.1] }\n', ["friction.m = -0.1", "sample 0"]),
])
def test_bad_input_exits_2_with_one_line_naming_the_key(tmp_path, capsys, sweep, words):
    scene = _files(tmp_path, "[sweep]\n" + sweep if not sweep.startswith("[sweep]") else sweep)
    rc = main(["sweep", str(scene), "--out", str(tmp_path / "o"), "--workers", "0"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    line = [e for e in err if e.startswith("knitsim: error:")]
    assert len(line) == 1
    for w in words:
        assert w in line[0]
    assert not (tmp_path / "o").exists()          # refused before anything was written


def _second_chunk_does(tmp_path, monkeypatch, action):
    """A two-chunk sweep scene whose chunk 1 first runs ``action`` (an interrupt, a signal, a full disk):
    (scene, out, the real run_chunk)."""
    monkeypatch.setenv("MPLBACKEND", "Agg")
    real = runner.run_chunk

    def chunk(task):
        if task["chunk"] == 1:
            action()
        return real(task)

    monkeypatch.setattr(runner, "run_chunk", chunk)
    return _files(tmp_path), tmp_path / "o", real


def test_interrupt_keeps_finished_chunks_and_tells_how_to_resume(tmp_path, capsys, monkeypatch):
    def interrupt():
        raise KeyboardInterrupt

    scene, out, real = _second_chunk_does(tmp_path, monkeypatch, interrupt)
    # run with --overwrite, as typed (sys.argv): a blind probe was told to finish with "--overwrite --resume",
    # which is refused; the command it is given must run as printed
    argv = ["sweep", str(scene), "--out", str(out), "--workers", "0", "--overwrite"]
    monkeypatch.setattr(sys, "argv", ["knitsim"] + argv)
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 130 and "--resume" in err and "1/2" in err
    assert [p.name for p in (out / "chunks").iterdir()] == ["chunk_00000.npz"]
    cmd = err.split("finish with: ", 1)[1].strip()
    assert "--overwrite" not in cmd and cmd.endswith("--resume")
    monkeypatch.setattr(runner, "run_chunk", real)
    rc = main(cmd.split()[1:] + ["--json"])
    doc = json.loads(capsys.readouterr().out)
    assert rc == 0 and doc["computed_chunks"] == 1 and doc["skipped_chunks"] == 1


def test_sigterm_is_taken_as_a_ctrl_c_keeping_the_finished_chunks(tmp_path, capsys, monkeypatch):
    # a batch scheduler's time limit (SIGTERM) while chunk 1 of 2 runs: before, the process died at once
    # without a word; now as a Ctrl-C (the finished chunk kept, the command that finishes it said), exit 143
    import os
    import signal

    scene, out, real = _second_chunk_does(tmp_path, monkeypatch, lambda: os.kill(os.getpid(), signal.SIGTERM))

    def not_taken(signum, frame):                   # (the old code's fate, without killing the test process)
        raise AssertionError("SIGTERM reached the handler in force before knitsim: not taken as a Ctrl-C")

    before = signal.signal(signal.SIGTERM, not_taken)
    argv = ["sweep", str(scene), "--out", str(out), "--workers", "0"]
    monkeypatch.setattr(sys, "argv", ["knitsim"] + argv)
    try:
        rc = main(argv)
        assert signal.getsignal(signal.SIGTERM) is not_taken         # the handler given back
    finally:
        signal.signal(signal.SIGTERM, before)
    err = capsys.readouterr().err
    assert rc == 143 and "interrupted; 1/2 finished chunk(s) kept" in err and err.rstrip().endswith("--resume")
    assert [p.name for p in (out / "chunks").iterdir()] == ["chunk_00000.npz"]


def test_a_disk_that_fills_keeps_the_finished_chunks_and_says_how_to_finish(tmp_path, capsys, monkeypatch):
    # chunk 1 of 2 cannot be written (a full disk): before, a traceback; now one line with the error, the chunks
    # kept and the command that finishes the sweep, exit 1; that command finishes it, reusing chunk 0
    import errno

    def disk_full():
        raise OSError(errno.ENOSPC, "No space left on device")

    scene, out, real = _second_chunk_does(tmp_path, monkeypatch, disk_full)
    argv = ["sweep", str(scene), "--out", str(out), "--workers", "0"]
    monkeypatch.setattr(sys, "argv", ["knitsim"] + argv)
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert ("knitsim sweep: a file could not be written or read ([Errno 28] No space left on device); 1/2 "
            "finished chunk(s) kept; after fixing the cause, finish with: ") in err, err
    assert not (out / "summary.json").exists()
    monkeypatch.setattr(runner, "run_chunk", real)
    cmd = err.split("finish with: ", 1)[1].strip()
    assert main(cmd.split()[1:] + ["--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["computed_chunks"] == 1 and doc["skipped_chunks"] == 1


def test_a_second_sweep_into_a_folder_in_use_is_refused_and_a_dead_ones_lock_taken_over(tmp_path, capsys,
                                                                                          monkeypatch):
    # an interrupted sweep (chunk 1 of 2 not run), then its folder's lock held by another process that runs
    # (a child sleeping: hand-made), then by one that has ended (the child, killed: a stale lock)
    import socket
    import subprocess

    from knitsim.io.output_dir import LOCK_NAME
    monkeypatch.setenv("MPLBACKEND", "Agg")
    scene = _files(tmp_path)
    out = tmp_path / "o"
    real = runner.run_chunk
    monkeypatch.setattr(runner, "run_chunk",
                        lambda task: (_ for _ in ()).throw(KeyboardInterrupt) if task["chunk"] == 1 else real(task))
    assert main(["sweep", str(scene), "--out", str(out), "--workers", "0"]) == 130
    monkeypatch.setattr(runner, "run_chunk", real)
    assert not (out / LOCK_NAME).exists()                  # the interrupted command let its lock go
    capsys.readouterr()
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])
    try:
        held = f"{other.pid}\n{socket.gethostname()}\nknitsim sweep\n"
        (out / LOCK_NAME).write_text(held)
        rc = main(["sweep", str(scene), "--out", str(out), "--workers", "0", "--resume"])
        err = capsys.readouterr().err
        assert rc == 2 and "Traceback" not in err
        (line,) = err.strip().splitlines()
        assert line.startswith(f"knitsim: error: --out = {str(out)!r}: knitsim sweep (pid {other.pid}) is writing "
                               "into this folder")
        assert (out / LOCK_NAME).read_text() == held                        # the other's lock, untouched
        assert [p.name for p in (out / "chunks").iterdir()] == ["chunk_00000.npz"]   # and its folder
    finally:
        other.kill()
        other.wait()
    rc = main(["sweep", str(scene), "--out", str(out), "--workers", "0", "--resume", "--json"])
    cap = capsys.readouterr()
    assert rc == 0 and json.loads(cap.out)["computed_chunks"] == 1
    assert f"(pid {other.pid}), which no longer runs (killed or crashed): taking it over" in cap.err
    assert not (out / LOCK_NAME).exists()


def test_resume_without_a_sweep_and_rerun_over_one_exit_2(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")
    scene = _files(tmp_path)
    assert main(["sweep", str(scene), "--out", str(tmp_path / "o"), "--workers", "0", "--resume"]) == 2
    assert "nothing to resume" in capsys.readouterr().err
    assert main(["sweep", str(scene), "--out", str(tmp_path / "o"), "--workers", "0", "--no-plot"]) == 0
    assert main(["sweep", str(scene), "--out", str(tmp_path / "o"), "--workers", "0"]) == 2
    err = capsys.readouterr().err
    assert "already holds results (sweep.json, chunks, results.nc" in err and "or --resume to continue it" in err
    # a folder of a cell run holds no sweep to resume: --resume is not offered (it then failed: sweep.json not found)
    (tmp_path / "cell.toml").write_text(SCENE)
    assert main(["cell", str(tmp_path / "cell.toml"), "--out", str(tmp_path / "c")]) == 0
    capsys.readouterr()
    assert main(["sweep", str(scene), "--out", str(tmp_path / "c"), "--workers", "0"]) == 2
    err = capsys.readouterr().err
    assert "already holds results" in err and "--resume" not in err
    (tmp_path / "s.toml").write_text(SCENE + SWEEP.replace("0.3]", "0.25]"))
    assert main(["sweep", str(scene), "--out", str(tmp_path / "o"), "--workers", "0", "--resume"]) == 2
    assert "different sweep" in capsys.readouterr().err


def test_a_sweep_whose_samples_fail_exits_1_and_lists_them(tmp_path, capsys):
    # E-glass (Table 1) pulled to strain 1.0 under a 1e12 N cap fails up its jammed branch whatever m
    # (tests/cell/test_batch.py: the jammed branch's force diverges): every sample is a missing result,
    # listed, and the exit status says so, as knitsim cell and run do for a failed cell (before: 0)
    scene = tmp_path / "s.toml"
    scene.write_text('engine = "warp"\ndevice = "cpu"\n[yarn]\nmaterial = "e_glass"\n[knit]\n'
                     'material = "e_glass_plain"\n[friction]\nm = 0.2\nphi0 = 0.0\n[rules]\nforce_cap_N = 1e12\n'
                     '[load]\ntype = "monotonic"\ntarget_strain = 1.0\nmax_increment = 0.02\n[sweep]\n'
                     'method = "grid"\n[sweep.parameters]\n"friction.m" = { min = 0.1, max = 0.3, count = 3 }\n')
    rc = main(["sweep", str(scene), "--out", str(tmp_path / "o"), "--workers", "0", "--json", "--no-plot"])
    s = json.loads(capsys.readouterr().out)
    assert rc == 1 and [f["sample"] for f in s["failed"]] == [0, 1, 2]
    # each says where it stopped: the increment it could not finish and its last converged state, the
    # numbers knitsim cell's summary gives for the same cell (knitsim.io.results.cell_summary)
    from knitsim.cell.batch import run_batch
    from knitsim.cell.load_program import monotonic
    from knitsim.cell.material import CellParams
    from knitsim.io.results import cell_summary
    cell = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, phi0=0.0, force_cap_N=1e12)
    one = cell_summary(run_batch([cell], monotonic(1.0, 0.02)), 0)
    assert (f"no converged solution on the increment to strain {one['stopped_at_strain']:.4g}; stopped at strain "
            f"{one['last_converged_strain']:.4g} (force per wale {one['last_converged_force_per_wale_N']:.4g} N)"
            in s["failed"][1]["reason"])
    # no judgement of a failed sample's cycles: its flags are -1 (empty in results.csv), as the variables'
    # descriptions say (a blind probe read 0 / 1 judged on the rows before the failure); its rest state is
    # judged (before any solve)
    import csv
    rows = list(csv.DictReader((tmp_path / "o" / "results.csv").open()))
    for k in ("loop_creates_energy", "heads_interpenetrate", "zero_force_cycle", "reload_below_earlier_loading",
              "reload_loss_continues", "reload_above_first_loading"):
        assert [r[k] for r in rows] == ["", "", ""], k
    assert [r["rest_state_compressive"] for r in rows] == ["0", "0", "0"]


def test_no_plot_writes_no_plot(tmp_path, capsys, monkeypatch):
    # a blind probe: --no-plot wrote plot_sweep.png and said so
    monkeypatch.setenv("MPLBACKEND", "Agg")
    scene = _files(tmp_path)
    out = tmp_path / "o"
    assert main(["sweep", str(scene), "--out", str(out), "--workers", "0", "--no-plot"]) == 0
    assert not list(out.glob("*.png")) and (out / "results.csv").is_file()
    assert "plot_sweep.png" not in capsys.readouterr().out


@pytest.mark.parametrize("bad", ['"friction.mu" = { values = [0.1, 0.2] }', '"knit.W0" = { values = [2.0, 4.4] }'])
def test_overwrite_keeps_the_earlier_results_when_the_new_sweep_is_refused(tmp_path, capsys, monkeypatch, bad):
    # a blind probe: `--overwrite` emptied the folder, then the typo'd key (or the sample with W0 < 4 d) was refused
    monkeypatch.setenv("MPLBACKEND", "Agg")
    scene = _files(tmp_path)
    out = tmp_path / "o"
    assert main(["sweep", str(scene), "--out", str(out), "--workers", "0", "--no-plot"]) == 0
    before = sorted(p.name for p in out.iterdir())
    (tmp_path / "bad.toml").write_text(SCENE + "\n[sweep]\n[sweep.parameters]\n" + bad + "\n")
    assert main(["sweep", str(tmp_path / "bad.toml"), "--out", str(out), "--workers", "0", "--overwrite"]) == 2
    assert sorted(p.name for p in out.iterdir()) == before and "results.csv" in before


def test_a_sweep_on_a_flagged_calibrations_materials_says_so_in_its_summary(tmp_path, capsys):
    """As knitsim cell does (tests/cli/test_cli_cell.py): a sweep whose base scene names the bundled flagged
    calibration's materials (NOT A CALIBRATION YOU CAN USE) carries from_unusable_calibration in summary.json
    and on the console; before, the console only."""
    from pathlib import Path
    lib = Path(__file__).resolve().parents[2] / "scenes" / "calibration" / "do2020" / "calibrated" / "materials.toml"
    (tmp_path / "lib.toml").write_text(lib.read_text())
    scene = tmp_path / "s.toml"
    scene.write_text('materials = "lib.toml"\n[knit]\nmaterial = "jersey_4p5"\n[load]\ntype = "monotonic"\n'
                     'target_strain = 0.1\nmax_increment = 0.02\n[sweep]\n[sweep.parameters]\n'
                     '"friction.phi0" = { values = [0.0, 0.1] }\n')
    main(["sweep", str(scene), "--out", str(tmp_path / "o"), "--workers", "0", "--no-plot"])
    assert "NOT ONE YOU CAN USE" in capsys.readouterr().err
    codes = [w["code"] for w in json.loads((tmp_path / "o" / "summary.json").read_text())["warnings"]]
    assert codes == ["from_unusable_calibration"]


def test_a_long_listing_of_flagged_samples_is_cut_in_summary_json_and_counted_whole(tmp_path, capsys, monkeypatch):
    # expectation: a 50,000-sample sweep's summary.json listed every flagged sample with its reason (46 MB); it lists
    # the first SUMMARY_LISTED of each kind (here 2 of the 3 failing samples of the test above: E-glass pulled to
    # strain 1.0 under a 1e12 N cap fails up its jammed branch whatever m), counts all of them, says where every
    # sample's flag is, and the console counts all three and points there too
    from knitsim.sweep import runner
    monkeypatch.setattr(runner, "SUMMARY_LISTED", 2)
    scene = tmp_path / "s.toml"
    scene.write_text('engine = "warp"\ndevice = "cpu"\n[yarn]\nmaterial = "e_glass"\n[knit]\n'
                     'material = "e_glass_plain"\n[friction]\nm = 0.2\nphi0 = 0.0\n[rules]\nforce_cap_N = 1e12\n'
                     '[load]\ntype = "monotonic"\ntarget_strain = 1.0\nmax_increment = 0.02\n[sweep]\n'
                     'method = "grid"\n[sweep.parameters]\n"friction.m" = { min = 0.1, max = 0.3, count = 3 }\n')
    assert main(["sweep", str(scene), "--out", str(tmp_path / "o"), "--workers", "0", "--no-plot"]) == 1
    err = capsys.readouterr().err
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["failed_count"] == 3 and [f["sample"] for f in s["failed"]] == [0, 1, 2][:2]
    assert s["failed_listed"] == ("the first 2 of 3; every sample's flag is in results.csv and results.nc "
                                  "(final_status and expected_end)")
    assert s["no_rest_state_count"] == 0 and "no_rest_state_listed" not in s
    assert "warning: 3 of 3 sample cell(s) failed (100 %" in err       # the fraction, of the 3 x 1 sample cells


def test_the_failed_samples_are_said_as_a_fraction_of_the_sweeps_sample_cells(tmp_path, capsys):
    # a blind probe: "7 sample cell(s) failed" did not say of how many; E-glass (Table 1, section 2.2) with m = 3,
    # outside the domain, fails in its unloading (no converged solution at strain 0.46), m = 0.2 runs the program:
    # 1 of the 2 x 2 sample cells fails, one cell of sample 1
    scene = tmp_path / "s.toml"
    scene.write_text('[yarn]\nmaterial = "e_glass"\n[knit]\nmaterial = "e_glass_plain"\n[friction]\nm = 0.2\n'
                     'phi0 = 0.0\n[rules]\nforce_cap_N = 10.0\n[load]\ntype = "cycles"\nlower_strain = 0.1\n'
                     'upper_strain = 0.5\ncycles = 1\nmax_increment = 0.02\n[[cells]]\nlabel = "a"\n[[cells]]\n'
                     'label = "b"\nfriction = { m = 0.25 }\n[sweep]\n[sweep.parameters]\n'
                     '"cells[1].friction.m" = { values = [0.2, 3.0] }\n')
    assert main(["sweep", str(scene), "--out", str(tmp_path / "o"), "--workers", "0", "--no-plot"]) == 1
    err = capsys.readouterr().err
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["failed_count"] == 1 and s["samples"] * s["cells_per_sample"] == 4
    assert "warning: 1 of 4 sample cell(s) failed (25 %; no results" in err
