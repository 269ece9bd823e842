"""``knitsim run`` refuses, before any work, a run whose per-cell records would not fit in memory.

Where the expected values come from: the bytes a run keeps per group and increment are counted from a real
checkpoint's rows (the run's own records, read back from its chunk files, each array's ``nbytes``),
independently of the constant that the estimate uses; the refusal is driven by a stated free memory (``available``) below the estimate, the estimate's
arithmetic being the product of its factors (an identity).
"""
from __future__ import annotations

import pytest

from knitsim.cell.load_program import cycles
from knitsim.cli import main
from knitsim.patch import runner
from knitsim.patch.records import RunRecords, read_chunks
from knitsim.patch.runner import CELL_FIELDS_COPIES, RECORD_BYTES_PER_GROUP, RECORD_COPIES, record_memory_bytes

PATCH = """
title = "memory"
[patch]
wales = 3
courses = 4
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


def test_the_records_per_group_and_increment_are_those_a_run_keeps(tmp_path):
    from knitsim.cell.material import CellParams
    from knitsim.patch.model import PatchModel
    cell = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.20, force_cap_N=10.0)   # Table 1, section 2.2
    prog = cycles(0.1, 0.3, 1, 0.05)
    ck = tmp_path / "checkpoint.pkl"
    runner.run_patch(PatchModel.uniform(cell, 4, 3), prog, dedup=False, checkpoint=ck, checkpoint_every=4)
    # the rows as the checkpoint keeps them (in chunk files beside it) and a resume reads them back
    head = runner.read_checkpoint_header(ck)
    rows = RunRecords(head["done"])
    read_chunks(ck, head["chunks"], head["done"], head["fingerprint"], rows)
    n = len(rows.arrays["force_N"])
    assert n == len(prog) == 10
    kept = sum(a.nbytes for k, a in rows.arrays.items() if k.startswith("g_"))
    n_groups = rows.arrays["g_C"].shape[1]
    assert n_groups == 12
    assert kept == RECORD_BYTES_PER_GROUP * n_groups * n
    assert record_memory_bytes(n_groups, n) == (RECORD_COPIES + CELL_FIELDS_COPIES) * kept
    assert record_memory_bytes(n_groups, n, cell_fields=False) == RECORD_COPIES * kept


def test_a_run_that_would_not_fit_in_memory_is_refused_before_any_work(tmp_path, monkeypatch, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text(PATCH)
    # 12 cells, dedup off (every cell its own group): 12 x 10 increments x 90 bytes x 3 = 32,400 bytes (the rows,
    # what the summary and plots derive, and cells.nc's per-cell fields); 2 copies without cells.nc
    need = record_memory_bytes(12, len(cycles(0.1, 0.3, 1, 0.05)))
    assert need == 3 * 90 * 12 * 10
    assert record_memory_bytes(12, len(cycles(0.1, 0.3, 1, 0.05)), cell_fields=False) == 2 * 90 * 12 * 10
    monkeypatch.setattr(runner, "available_memory_bytes", lambda: need - 1)
    out = tmp_path / "out"
    rc = main(["run", str(scene), "--out", str(out), "--no-progress", "--set", "patch.dedup=false"])
    err = capsys.readouterr().err
    assert rc != 0 and "per-cell records" in err and "turn dedup on" in err, err
    assert "3 copies at its peak" in err and "write no cells.nc (output.cell_fields = false" in err, err
    assert "Traceback" not in err
    assert not out.exists()                     # refused before any output was touched
    # without cells.nc the same memory holds the run
    assert main(["run", str(scene), "--out", str(out), "--no-progress", "--set", "patch.dedup=false",
                 "--set", "output.cell_fields=false"]) == 0
    assert not (out / "cells.nc").exists()
    out = tmp_path / "out2"
    monkeypatch.setattr(runner, "available_memory_bytes", lambda: need)
    assert main(["run", str(scene), "--out", str(out), "--no-progress", "--set", "patch.dedup=false"]) == 0


@pytest.mark.parametrize("n_groups, n_inc, gb, cell_fields", [(10 ** 6, 620, 167.4, True), (10 ** 6, 620, 111.6, False),
                                                             (2530, 620, 0.4235, True)])
def test_the_estimate_of_the_docstring(n_groups, n_inc, gb, cell_fields):
    # record_memory_bytes' docstring: a 1000 x 1000 random patch through the paper's 620 increments (with and
    # without cells.nc), and the paper's specimen (23 x 110) with random phi0
    assert record_memory_bytes(n_groups, n_inc, cell_fields) / 1e9 == pytest.approx(gb, rel=1e-3)


def test_cells_nc_at_a_stride_is_counted_at_its_increments(tmp_path, monkeypatch, capsys):
    """output.cells_stride = 5 on the 10 increments of cycles(0.1, 0.3, 1, 0.05) (up 0.05 .. 0.3 in 6, down to
    0.1 in 4): cells.nc holds increments 5 and 10 (multiples) and 6 (the peak), 3 of 10, so the run keeps
    (2 x 10 + 1 x 3) rows x 90 bytes x 12 groups = 24,840 bytes at its peak, not the 32,400 of every increment:
    the memory one byte short of the full estimate holds it; one byte short of its own is refused, saying so."""
    scene = tmp_path / "s.toml"
    scene.write_text(PATCH)
    n = len(cycles(0.1, 0.3, 1, 0.05))
    assert record_memory_bytes(12, n, cells_increments=3) == (2 * 10 + 3) * 90 * 12 == 24840
    monkeypatch.setattr(runner, "available_memory_bytes", lambda: record_memory_bytes(12, n) - 1)
    sets = ["--no-progress", "--set", "patch.dedup=false", "--set", "output.cells_stride=5"]
    assert main(["run", str(scene), "--out", str(tmp_path / "a"), *sets]) == 0
    monkeypatch.setattr(runner, "available_memory_bytes", lambda: 24840 - 1)
    capsys.readouterr()
    assert main(["run", str(scene), "--out", str(tmp_path / "b"), *sets]) == 2
    err = capsys.readouterr().err
    assert "per-cell records" in err and "(3 of the increments)" in err and "2.3 copies" in err, err
    assert not (tmp_path / "b").exists()
