"""``knitsim run --usd`` and ``knitsim usd``: an unwritable USD path and USD options without ``--usd`` are
refused before any work (exit 2, one line, no traceback); a run cut by the force cap says which increments
its USD file leaves out.

Expected values: the operating system's answer (``/proc`` takes no new file on Linux; nothing can be
created under a regular file), knitsim's error contract (exit status 2, one line on stderr; nothing
written: the --out folder is not created), and the run's own curve.csv (``columns_held`` = every column
from the increment that reaches the cap on).
"""
from __future__ import annotations

import csv

import numpy as np

import pytest

pxr = pytest.importorskip("pxr")

from knitsim.cli import main  # noqa: E402
from knitsim.errors import KnitsimInputError  # noqa: E402

SCENE = """title = "uniform E-glass small"
engine = "warp"
device = "cpu"
[patch]
wales = 4
courses = 5
[yarn]
material = "e_glass"
[knit]
material = "e_glass_plain"
[friction]
model = "coulomb"
m = 0.20
[rules]
force_cap_N = 10.0
[load]
type = "cycles"
lower_strain = 0.10
upper_strain = 0.30
cycles = 1
max_increment = 0.05
[output]
checkpoint_every = 0
"""


@pytest.fixture
def scene(tmp_path):
    p = tmp_path / "uni.toml"
    p.write_text(SCENE)
    return p


def _one_line_error(capsys, rc, *needles):
    err = capsys.readouterr().err
    assert rc == 2, err
    lines = [ln for ln in err.strip().splitlines() if "CUDA" not in ln]
    assert len(lines) == 1 and "Traceback" not in err, err
    assert all(n in lines[0] for n in needles), lines[0]


def test_unwritable_usd_path_refused_before_the_solve(tmp_path, scene, capsys, proc_refuses_files):
    rc = main(["run", str(scene), "--out", str(tmp_path / "e2"), "--no-progress", "--usd", "/proc/x.usda"])
    _one_line_error(capsys, rc, "--usd = '/proc/x.usda'", "cannot be written")
    assert not (tmp_path / "e2").exists()                           # nothing solved, nothing written
    (tmp_path / "res").mkdir()                                       # knitsim usd: the path first, then the folder
    rc = main(["usd", str(tmp_path / "res"), "--out", "/proc/x.usda"])
    _one_line_error(capsys, rc, "--out = '/proc/x.usda'", "cannot be written")


def test_usd_path_under_a_file_refused_before_the_solve(tmp_path, scene, capsys):
    (tmp_path / "r1.usda").write_text("#usda 1.0\n")
    rc = main(["run", str(scene), "--out", str(tmp_path / "e3"), "--no-progress",
               "--usd", str(tmp_path / "r1.usda" / "x.usda")])
    _one_line_error(capsys, rc, "--usd = ", "r1.usda is a file, not a folder")
    assert not (tmp_path / "e3").exists()
    (tmp_path / "res").mkdir()
    rc = main(["usd", str(tmp_path / "res"), "--out", str(tmp_path / "r1.usda" / "y.usdc")])
    _one_line_error(capsys, rc, "--out = ", "is a file, not a folder")


def test_a_quicklook_that_cannot_be_written_is_refused_before_the_export(tmp_path, scene, capsys):
    # a blind probe's `knitsim usd RES --out u.usda --quicklook afile/x.png` wrote the USD, then a traceback
    assert main(["run", str(scene), "--out", str(tmp_path / "res"), "--no-progress"]) == 0
    capsys.readouterr()
    (tmp_path / "afile").write_text("")
    rc = main(["usd", str(tmp_path / "res"), "--out", str(tmp_path / "u.usda"),
               "--quicklook", str(tmp_path / "afile" / "x.png")])
    _one_line_error(capsys, rc, "--quicklook = ", "afile is a file, not a folder")
    assert not (tmp_path / "u.usda").exists()
    # a quick-look of another format than the PNG it is (a probe's dahl fit --png fit.txt: matplotlib's traceback
    # "Format 'txt' is not supported" after the work)
    rc = main(["usd", str(tmp_path / "res"), "--out", str(tmp_path / "u.usda"), "--quicklook", str(tmp_path / "q.txt")])
    _one_line_error(capsys, rc, "--quicklook = ", "expected a .png file")
    assert not (tmp_path / "u.usda").exists()
    # a missing folder is created, as the USD file's is (the PNG failed there: FileNotFoundError)
    rc = main(["usd", str(tmp_path / "res"), "--out", str(tmp_path / "u.usda"),
               "--quicklook", str(tmp_path / "new" / "q" / "x.png")])
    assert rc == 0, capsys.readouterr().err
    assert (tmp_path / "new" / "q" / "x.png").stat().st_size > 1000


@pytest.mark.parametrize("opts,flag", [(["--usd-stride", "3"], "--usd-stride"), (["--color-by", "phi"], "--color-by"),
                                       (["--usd-layout", "courses"], "--usd-layout"),
                                       (["--usd-points", "7"], "--usd-points")])
def test_usd_options_without_usd_refused(tmp_path, scene, capsys, opts, flag):
    rc = main(["run", str(scene), "--out", str(tmp_path / "e4"), "--no-progress", *opts])
    _one_line_error(capsys, rc, flag, "without --usd")
    assert not (tmp_path / "e4").exists()


def test_run_cut_by_the_force_cap_says_what_its_usd_leaves_out(tmp_path, scene, capsys):
    out, usd = tmp_path / "cap", tmp_path / "cap.usda"
    rc = main(["run", str(scene), "--set", "rules.force_cap_N=0.09", "--out", str(out), "--no-progress",
               "--usd", str(usd)])
    err = capsys.readouterr().err
    assert rc == 0, err
    with open(out / "curve.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    held = [int(r["increment"]) for r in rows if int(r["columns_held"]) == 4]     # every column from here on
    n = len(rows) - 1
    assert f"increments {held[1]}-{n} of {n} not written" in err
    from knitsim.usd.instanced import read_specimen_usd
    u = read_specimen_usd(usd)
    assert list(u.time_codes) == list(range(0, held[0] + 1))
    assert "program_cut_by_force_cap" in list(u.info["run"]["warning_codes"])
    # knitsim usd of the same folder (its cells.nc holds the rest state): the same time codes, said on stderr
    assert main(["usd", str(out), "--out", str(tmp_path / "again.usda")]) == 0
    err = capsys.readouterr().err
    assert f"increments {held[1]}-{n} of {n} not written" in err and "time code k is increment k + 1" not in err
    assert list(read_specimen_usd(tmp_path / "again.usda").time_codes) == list(range(0, held[0] + 1))
    assert "force_cap_reached" in err                                # the run's own warning, repeated


def test_an_absurd_number_of_usd_points_is_refused_before_any_work(tmp_path, scene, capsys):
    # expectation: the project's rule that an absurd limit is refused before any work; the bound is
    # knitsim.usd.from_results.MAX_POINTS (200 points already draw the elastica within 1e-4 mm, measured); a
    # blind probe's --usd-points 1000000 wrote 8.6 GB in 462 s for a 12-cell patch
    from knitsim.usd.from_results import MAX_POINTS, quarter_centrelines
    rc = main(["run", str(scene), "--out", str(tmp_path / "e5"), "--no-progress", "--usd", str(tmp_path / "p.usda"),
               "--usd-points", str(MAX_POINTS + 1)])
    _one_line_error(capsys, rc, f"--usd-points = {MAX_POINTS + 1}: must be <= {MAX_POINTS}")
    assert not (tmp_path / "e5").exists() and not (tmp_path / "p.usda").exists()
    (tmp_path / "res").mkdir()
    rc = main(["usd", str(tmp_path / "res"), "--out", str(tmp_path / "q.usda"), "--usd-points", "1000000"])
    _one_line_error(capsys, rc, "--usd-points = 1000000: must be <= ")
    with pytest.raises(KnitsimInputError, match=r"n_points = 1001: must be an integer in \[6, 1000\]"):
        quarter_centrelines(np.zeros((1, 5)), 0.31, 0.58, n_points=MAX_POINTS + 1)
