"""The --out folder policy (knitsim.io.output_dir): a folder is knitsim's only as far as knitsim
recorded writing into it; --overwrite removes those outputs and nothing else.

A blind probe's ``knitsim run scene.toml --out . --overwrite`` deleted the scene, its map CSV and its
README (the policy then removed every .csv/.toml/.md file of the folder); a sweep into a folder of 101
scene files removed them all.  The expectations here are the policy's statement, not the code's output:
a user's file survives every command; knitsim's own outputs are replaced.
"""
from __future__ import annotations

import json
import sys

import pytest

from knitsim.cli import main
from knitsim.errors import KnitsimInputError
from knitsim.io.output_dir import (RECORD_NAME, check_output_dir, prepare_output_dir, record_outputs,
                                   recorded_outputs, scene_inputs)

CELL_SCENE = """
engine = "warp"
device = "cpu"
[yarn]
material = "e_glass"
[knit]
material = "e_glass_plain"
[friction]
m = 0.2
phi0 = 0.0
[load]
type = "monotonic"
target_strain = 0.2
max_increment = 0.05
"""

PATCH_SCENE = """
engine = "warp"
device = "cpu"
[patch]
wales = 2
courses = 2
[yarn]
material = "e_glass"
[knit]
material = "e_glass_plain"
[friction]
m = 0.2
[maps.phi0]
type = "file"
path = "phi0_map.csv"
[load]
type = "monotonic"
target_strain = 0.2
max_increment = 0.05
"""

USER_FILES = {"README.md": "my notes\n", "measured.csv": "strain,force_N\n0,0\n0.1,0.5\n",
              "other_scene.toml": "title = 'mine'\n"}


def _user_folder(tmp_path, scene_text, name="scene.toml"):
    d = tmp_path / "work"
    d.mkdir()
    (d / name).write_text(scene_text)
    for k, v in USER_FILES.items():
        (d / k).write_text(v)
    return d


def _user_files_intact(d, scene_name, scene_text, extra=()):
    assert (d / scene_name).read_text() == scene_text
    for k, v in USER_FILES.items():
        assert (d / k).read_text() == v, k
    for k, v in extra:
        assert (d / k).read_text() == v, k


# ------------------------------------------------------------------ the policy itself
def test_a_folder_of_user_files_is_used_and_nothing_in_it_is_removed(tmp_path):
    d = _user_folder(tmp_path, CELL_SCENE)
    before = sorted(p.name for p in d.iterdir())
    for overwrite in (False, True):
        assert prepare_output_dir(d, overwrite=overwrite, writes=("curve.csv", "summary.json")) == d
        assert sorted(p.name for p in d.iterdir()) == before


def test_overwrite_removes_only_the_recorded_names_and_never_an_input(tmp_path):
    d = _user_folder(tmp_path, CELL_SCENE)
    record_outputs(d, ["curve.csv", "materials.toml", "chunks/"])
    (d / "curve.csv").write_text("old\n")
    (d / "materials.toml").write_text("[yarns]\n")          # an earlier calibration's, read by this run
    (d / "chunks").mkdir()
    (d / "chunks" / "chunk_0.npz").write_bytes(b"x")
    with pytest.raises(KnitsimInputError, match=r"already holds results \(curve\.csv, materials\.toml, chunks\)"):
        prepare_output_dir(d, writes=("curve.csv",))
    prepare_output_dir(d, overwrite=True, writes=("curve.csv",), inputs=[d / "materials.toml"])
    assert not (d / "curve.csv").exists() and not (d / "chunks").exists()
    assert (d / "materials.toml").read_text() == "[yarns]\n"
    _user_files_intact(d, "scene.toml", CELL_SCENE)


def test_a_user_file_with_an_output_name_is_refused_even_with_overwrite(tmp_path):
    d = _user_folder(tmp_path, CELL_SCENE)
    (d / "curve.csv").write_text("my own measured curve\n")
    for overwrite in (False, True):
        with pytest.raises(KnitsimInputError, match=r"holds curve\.csv, which knitsim did not write there"):
            prepare_output_dir(d, overwrite=overwrite, writes=("curve.csv", "summary.json"))
    assert (d / "curve.csv").read_text() == "my own measured curve\n"


def test_a_record_naming_paths_outside_the_folder_removes_nothing_there(tmp_path):
    d = tmp_path / "o"
    d.mkdir()
    outside = tmp_path / "precious.txt"
    outside.write_text("keep")
    (d / "curve.csv").write_text("x")
    (d / RECORD_NAME).write_text(json.dumps({"outputs": ["../precious.txt", str(outside), "curve.csv"]}))
    assert recorded_outputs(d) == ["curve.csv"]
    prepare_output_dir(d, overwrite=True)
    assert outside.read_text() == "keep" and not (d / "curve.csv").exists()


def test_an_unwritable_out_is_refused_before_any_work(tmp_path):
    f = tmp_path / "a_file"
    f.write_text("")
    with pytest.raises(KnitsimInputError, match="is not a directory"):
        check_output_dir(f / "sub")
    # /proc refuses new folders whatever the permissions say (os.access said yes to root: the run failed
    # after its whole solve)
    with pytest.raises(KnitsimInputError, match="cannot write there"):
        check_output_dir("/proc/knitsim_nope")
    # the probe leaves nothing behind
    check_output_dir(tmp_path / "x" / "y")
    assert not (tmp_path / "x").exists()


def test_an_unwritable_output_file_is_refused_before_any_work(tmp_path, proc_refuses_files):
    # a single output file (usd --quicklook, diagnose --json / --report, dahl --out): os.access passed a
    # parent that is a file and /proc (root), and the file failed as a traceback after the work (a blind probe)
    from knitsim.io.output_dir import prepare_output_file
    f = tmp_path / "a_file"
    f.write_text("")
    for p in (f / "x.png", f / "sub" / "x.png"):
        with pytest.raises(KnitsimInputError, match=r"^--quicklook = .*: cannot be written: .*a_file is a file, not "
                                                    r"a folder$"):
            prepare_output_file(p, flag="--quicklook")
    with pytest.raises(KnitsimInputError, match=r"^--json = '/proc/x\.json': cannot be written: no file can be "
                                                r"created in /proc "):
        prepare_output_file(f"{proc_refuses_files}/x.json", flag="--json")
    # a folder still missing below a writable one is fine (the writer creates it); the probe leaves nothing
    assert prepare_output_file(tmp_path / "new" / "x.png") == tmp_path / "new" / "x.png"
    assert sorted(q.name for q in tmp_path.iterdir()) == ["a_file"]


def test_scene_inputs_are_the_scene_and_the_files_its_strings_name(tmp_path):
    d = _user_folder(tmp_path, PATCH_SCENE)
    (d / "phi0_map.csv").write_text("0,0\n0,0\n")
    found = {p.resolve() for p in scene_inputs(d / "scene.toml")}
    assert found == {(d / "scene.toml").resolve(), (d / "phi0_map.csv").resolve()}


# ------------------------------------------------------------------ the commands
def test_cell_into_the_scene_folder_twice_with_overwrite_keeps_the_users_files(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")
    d = _user_folder(tmp_path, CELL_SCENE)
    monkeypatch.chdir(d)
    assert main(["cell", "scene.toml", "--out", "."]) == 0
    assert (d / "summary.json").is_file()
    assert main(["cell", "scene.toml", "--out", "."]) == 2
    assert "already holds results" in capsys.readouterr().err
    assert main(["cell", "scene.toml", "--out", ".", "--overwrite"]) == 0
    _user_files_intact(d, "scene.toml", CELL_SCENE)
    assert (d / "curve.csv").is_file() and (d / "plot.png").is_file()


def test_run_into_the_scene_folder_with_overwrite_keeps_the_scene_and_its_map(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")
    d = _user_folder(tmp_path, PATCH_SCENE)
    (d / "phi0_map.csv").write_text("0.1,-0.1\n0.05,0\n")
    monkeypatch.chdir(d)
    for extra in ([], ["--overwrite"], ["--overwrite"]):
        assert main(["run", "scene.toml", "--out", ".", "--no-progress"] + extra) == 0, \
            capsys.readouterr().err
    _user_files_intact(d, "scene.toml", PATCH_SCENE, extra=[("phi0_map.csv", "0.1,-0.1\n0.05,0\n")])
    assert json.loads((d / "summary.json").read_text())


def test_sweep_into_a_folder_of_scene_files_keeps_them(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")
    d = tmp_path / "scenes"
    d.mkdir()
    sweep = '\n[sweep]\n[sweep.parameters]\n"friction.m" = { values = [0.1, 0.2] }\n'
    (d / "s.toml").write_text(CELL_SCENE + sweep)
    others = {f"case_{k:03d}.toml": f"title = 'case {k}'\n" for k in range(12)}
    for k, v in others.items():
        (d / k).write_text(v)
    for extra in ([], ["--overwrite"]):
        assert main(["sweep", str(d / "s.toml"), "--out", str(d), "--workers", "0", "--no-plot"] + extra) == 0, \
            capsys.readouterr().err
    assert (d / "s.toml").read_text() == CELL_SCENE + sweep
    assert all((d / k).read_text() == v for k, v in others.items())
    assert json.loads((d / "summary.json").read_text())["failed"] == []
    rows = (d / "results.csv").read_text().splitlines()
    assert len([r for r in rows if r and not r.startswith("#")]) == 3          # header + the two samples


def test_resume_refuses_a_users_file_and_overwrite_an_edited_output(tmp_path, capsys, monkeypatch):
    """A blind probe: `calibrate --resume` replaced the user's own materials.toml put beside an interrupted run's
    checkpoint (only --resume skipped the check), and `--overwrite` deleted a materials.toml the user had edited
    since knitsim wrote it.  Expected: --resume refuses a file of an output name knitsim did not write, as a
    plain run does; --overwrite refuses to delete an output changed since it was written (size or time), and
    replaces an unchanged one."""
    d = tmp_path / "o"
    record_outputs(d, ["checkpoint.pkl"])
    (d / "checkpoint.pkl").write_bytes(b"x")
    (d / "materials.toml").write_text("[yarns]  # mine\n")
    with pytest.raises(KnitsimInputError, match=r"holds materials\.toml, which knitsim did not write"):
        prepare_output_dir(d, resume=True, writes=("materials.toml", "checkpoint.pkl"))
    assert (d / "materials.toml").read_text() == "[yarns]  # mine\n"
    # a cell run's outputs, then one of them edited by hand
    monkeypatch.chdir(tmp_path)
    (tmp_path / "scene.toml").write_text(CELL_SCENE)
    assert main(["cell", "scene.toml", "--out", "c"]) == 0
    assert main(["cell", "scene.toml", "--out", "c", "--overwrite"]) == 0          # unchanged: replaced
    with open(tmp_path / "c" / "curve.csv", "a") as fh:
        fh.write("# my note\n")
    capsys.readouterr()
    assert main(["cell", "scene.toml", "--out", "c", "--overwrite"]) == 2
    assert "curve.csv changed since knitsim wrote it (edited or added by hand?)" in capsys.readouterr().err
    assert (tmp_path / "c" / "curve.csv").read_text().endswith("# my note\n")


def test_overwrite_keeps_a_users_file_inside_a_recorded_folder(tmp_path):
    """A blind probe's note saved in a sweep's chunks/ went with the folder under --overwrite.  Expected: the
    folder's own files (chunk_*.npz) are knitsim's; another file there is the user's, and --overwrite refuses."""
    d = tmp_path / "o"
    record_outputs(d, ["chunks/", "sweep.json"])
    (d / "chunks").mkdir()
    (d / "chunks" / "chunk_00000.npz").write_bytes(b"x")
    (d / "sweep.json").write_text("{}")
    (d / "chunks" / "my_note.md").write_text("keep")
    with pytest.raises(KnitsimInputError, match=r"chunks/my_note\.md changed since knitsim wrote"):
        prepare_output_dir(d, overwrite=True)
    assert (d / "chunks" / "my_note.md").read_text() == "keep"
    (d / "chunks" / "my_note.md").unlink()
    prepare_output_dir(d, overwrite=True)
    assert not (d / "chunks").exists() and not (d / "sweep.json").exists()


def test_the_record_is_readable_as_the_outputs_beside_it(tmp_path):
    """The record was written by mkstemp with mode 0600 while the outputs beside it follow the umask
    (results.umask_mode): another user of the group could read the results but not what knitsim wrote."""
    import os
    import stat

    from knitsim.io.results import umask_mode
    record_outputs(tmp_path / "o", ["curve.csv"])
    assert stat.S_IMODE(os.stat(tmp_path / "o" / RECORD_NAME).st_mode) == umask_mode()


def test_an_output_lock_refuses_a_second_holder_and_goes_with_its_command(tmp_path):
    import os

    from knitsim.io.output_dir import LOCK_NAME, output_lock
    out = tmp_path / "new"
    with output_lock(out, "sweep") as d:
        assert d == out and (out / LOCK_NAME).read_text().startswith(f"{os.getpid()}\n")
        with pytest.raises(KnitsimInputError, match=rf"knitsim sweep \(pid {os.getpid()}\) is writing into this "
                                                    "folder"):
            with output_lock(out, "sweep"):
                pass
        assert (out / LOCK_NAME).is_file()                 # the refused one took nothing away
    assert not out.exists()                                # created for the lock, left empty: removed
    with pytest.raises(RuntimeError):
        with output_lock(out, "sweep"):
            (out / "kept.txt").write_text("x")
            raise RuntimeError("a command that fails")
    assert sorted(p.name for p in out.iterdir()) == ["kept.txt"]           # lock released, outputs kept


def test_an_output_lock_removes_the_parents_it_made_where_they_are_left_empty(tmp_path):
    # --out a/b/c where none of them exists: a command refused before writing leaves no folder behind; one that
    # wrote into c keeps all three
    from knitsim.io.output_dir import output_lock
    out = tmp_path / "a" / "b" / "c"
    with pytest.raises(KnitsimInputError):
        with output_lock(out, "run"):
            raise KnitsimInputError("a scene refused before any work")
    assert sorted(p.name for p in tmp_path.iterdir()) == []
    (tmp_path / "a").mkdir()
    with output_lock(out, "run"):
        (out / "curve.csv").write_text("x")
    assert (out / "curve.csv").is_file()
    with output_lock(tmp_path / "a" / "d" / "e", "run"):
        pass
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == ["b"]      # a existed: kept; d made, removed


def test_two_commands_taking_over_one_stale_lock_at_once_do_not_both_proceed(tmp_path, monkeypatch):
    """A dead holder's lock found by several commands at the same instant: exactly one takes it over at a time.
    The window (between a command's check that the lock is still the dead holder's and its removal, where
    another command may already have replaced it with its own) is widened here by a slow lock read; without
    the folder's flock two of the four threads held the folder at once."""
    import socket
    import subprocess
    import threading
    import time

    from knitsim.io import output_dir
    from knitsim.errors import KnitsimInputError

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()                                             # a pid that no longer runs: its lock is stale
    out = tmp_path / "o"
    out.mkdir()
    (out / output_dir.LOCK_NAME).write_text(f"{dead.pid}\n{socket.gethostname()}\nknitsim run\n")
    read = output_dir._lock_holder

    def slow_read(path):
        holder = read(path)
        time.sleep(0.05)
        return holder

    monkeypatch.setattr(output_dir, "_lock_holder", slow_read)
    spans, refused, lock = [], [], threading.Lock()

    def command(k):
        time.sleep(0.01 * k)
        try:
            with output_dir.output_lock(out, "run"):
                t0 = time.perf_counter()
                time.sleep(0.3)
                with lock:
                    spans.append((t0, time.perf_counter()))
        except KnitsimInputError:
            with lock:
                refused.append(k)

    threads = [threading.Thread(target=command, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert spans, "no command got the folder"
    spans.sort()
    assert all(a[1] <= b[0] for a, b in zip(spans, spans[1:])), spans     # never two holders at once
    assert len(spans) + len(refused) == 4
