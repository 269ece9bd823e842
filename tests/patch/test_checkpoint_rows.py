"""A patch run's checkpoint keeps its rows in chunk files written once (knitsim.patch.records).

Where the expected outcomes come from: an uninterrupted run of the same model and program (a resumed run
restores the solver's state bit for bit, so every array of its history equals that run's, dtype included); the
chunks' ranges are the save points of the run (``checkpoint_every``, ``stop_after``, the end); a chunk file cut
short, removed, altered or of another run is refused naming the file; a checkpoint of the format before (the
rows in its pickle, written here as that knitsim wrote it: a header of format 2 and a body ``{"solver",
"rows"}`` of per-increment rows) still resumes.
"""
from __future__ import annotations

import dataclasses
import pickle
import shutil

import numpy as np
import pytest

from knitsim.cell.load_program import cycles
from knitsim.cell.material import CellParams
from knitsim.errors import KnitsimInputError
from knitsim.patch import records, runner
from knitsim.patch.model import PatchModel
from knitsim.patch.runner import PatchInterrupted, read_checkpoint_header, resume_refusal, run_patch

P = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, force_cap_N=10.0)   # Table 1, section 2.2
PROG = cycles(0.10, 0.40, 1, 0.05)                                                # 14 increments


def _model():
    rng = np.random.default_rng(3)
    cells = [[P.replace(phi0=float(rng.uniform(-1, 1) * np.arctan(0.2)), L=float(13.6 + 0.5 * rng.random()))
              for _ in range(3)] for _ in range(2)]
    return PatchModel.from_cells(cells)


@pytest.fixture(scope="module")
def full():
    """The uninterrupted run (no checkpoint)."""
    return run_patch(_model(), PROG)


def _assert_same_history(h, ref, geometry=True):
    """Every array of the history equal to the reference's, bit for bit and of the same dtype (not the solving
    time, nor ``info``'s ``resumed_from``)."""
    for f in dataclasses.fields(ref):
        a, b = getattr(h, f.name), getattr(ref, f.name)
        if f.name in ("wall_s", "info"):
            continue
        if isinstance(b, dict):
            # (without the geometry rows, the groups hold the others: C, F, phi, label, status)
            keys = set(a) if f.name == "groups" and not geometry else set(b)
            assert keys <= set(b) and set(a) == keys, f.name
            for k in keys:
                assert np.asarray(a[k]).dtype == np.asarray(b[k]).dtype, (f.name, k)
                assert np.array_equal(a[k], b[k]), (f.name, k)
        elif isinstance(b, np.ndarray):
            assert a.dtype == b.dtype and np.array_equal(a, b), f.name
        else:
            assert a == b, f.name
    assert h.info["trial_steps"] == ref.info["trial_steps"]


def _stop(ck, k, every=2):
    with pytest.raises(PatchInterrupted):
        run_patch(_model(), PROG, checkpoint=ck, checkpoint_every=every, stop_after=k, resume=ck.is_file())
    return read_checkpoint_header(ck)


def test_a_run_stopped_twice_and_resumed_equals_the_uninterrupted_one(tmp_path, full):
    ck = tmp_path / "checkpoint.pkl"
    head = _stop(ck, 5)
    # saves at 2 and 4 (checkpoint_every), at 5 (stop_after): each interval's rows written once, beside the pickle
    assert [(c["start"], c["stop"]) for c in head["chunks"]] == [(0, 2), (2, 4), (4, 5)]
    assert sorted(p.name for p in (tmp_path / "checkpoint_rows").iterdir()) == [
        "000000-000002.npz", "000002-000004.npz", "000004-000005.npz"]
    first = (tmp_path / "checkpoint_rows" / "000000-000002.npz").stat().st_mtime_ns
    # the body holds the solver's state and no rows
    with open(ck, "rb") as fh:
        pickle.load(fh)
        assert set(pickle.load(fh)) == {"solver"}
    head = _stop(ck, 9, every=3)
    assert head["done"] == 9
    assert [(c["start"], c["stop"]) for c in head["chunks"]] == [(0, 2), (2, 4), (4, 5), (5, 6), (6, 9)]
    assert (tmp_path / "checkpoint_rows" / "000000-000002.npz").stat().st_mtime_ns == first     # not written again
    h = run_patch(_model(), PROG, checkpoint=ck, checkpoint_every=3, resume=True)
    assert h.info["resumed_from"] == 9
    _assert_same_history(h, full)
    # the finished solve is checkpointed, its rows with it: a resume of it gives the history without solving
    assert read_checkpoint_header(ck)["chunks"][-1]["stop"] == len(PROG)
    again = run_patch(_model(), PROG, checkpoint=ck, resume=True)
    assert again.info["resumed_from"] == len(PROG)
    _assert_same_history(again, full)
    runner.remove_checkpoint(ck)
    assert not ck.exists() and not (tmp_path / "checkpoint_rows").exists()


def test_a_chunk_missing_cut_short_altered_or_of_another_run_is_refused_naming_it(tmp_path, full):
    ck = tmp_path / "checkpoint.pkl"
    head = _stop(ck, 5)
    rows = tmp_path / "checkpoint_rows"
    kept = tmp_path / "kept"
    shutil.copytree(rows, kept)
    chunk = rows / "000002-000004.npz"

    def refused(match):
        # before any work (knitsim run asks resume_refusal first) where the sizes tell, and by run_patch
        with pytest.raises(KnitsimInputError, match=match):
            run_patch(_model(), PROG, checkpoint=ck, resume=True)
        return resume_refusal(ck, read_checkpoint_header(ck), _model(), PROG, engine="warp", device="cpu")

    def restore():
        shutil.rmtree(rows)
        shutil.copytree(kept, rows)

    chunk.unlink()
    why = refused(rf"{chunk} is missing: it holds increments 3\.\.4 of the checkpoint .*without --resume")
    assert str(chunk) in why
    restore()
    data = chunk.read_bytes()
    chunk.write_bytes(data[: len(data) // 2])
    why = refused(rf"{chunk} holds {len(data) // 2} bytes, the checkpoint .* wrote {len(data)}: truncated")
    assert str(chunk) in why
    # altered in place, its size kept: the archive's CRC-32 (checked as it is read)
    restore()
    bad = bytearray(data)
    bad[len(bad) // 2] ^= 0xFF
    chunk.write_bytes(bytes(bad))
    assert refused(rf"{chunk} is not a readable chunk of the checkpoint .*CRC") == ""   # (its size tells nothing)
    # another run's chunk of the same rows and size (another fingerprint)
    restore()
    other = records.RunRecords(5)
    records.read_chunks(ck, head["chunks"], 5, head["fingerprint"], other)
    records.write_chunk(tmp_path / "other", other, 2, 4, "f" * 64)
    shutil.copy(tmp_path / "other" / chunk.name, chunk)
    assert chunk.stat().st_size == len(data)
    refused(rf"{chunk} is not a chunk of the checkpoint .*another run")
    # restored, it resumes
    restore()
    _assert_same_history(run_patch(_model(), PROG, checkpoint=ck, resume=True), full)


def _as_format_2(ck, geometry=True):
    """Rewrite the checkpoint ``ck`` as knitsim wrote it before its rows went into chunks (format 2): the header
    without ``chunks``, the body ``{"solver", "rows"}`` with the rows as lists of per-increment rows (floats for
    the grip forces); ``geometry=False``: without the geometry rows (a checkpoint that predates them)."""
    head = read_checkpoint_header(ck)
    with open(ck, "rb") as fh:
        pickle.load(fh)
        body = pickle.load(fh)
    rows = records.RunRecords(head["done"])
    records.read_chunks(ck, head["chunks"], head["done"], head["fingerprint"], rows)
    lists = {k: (a.tolist() if a.ndim == 1 else [r.copy() for r in a]) for k, a in rows.arrays.items()
             if geometry or k not in runner._GEOMETRY_KEYS}
    old_head = {k: v for k, v in head.items() if k != "chunks"}
    old_head["format"] = 2
    runner.remove_checkpoint(ck)
    with open(ck, "wb") as fh:
        pickle.dump(old_head, fh)
        pickle.dump({"solver": body["solver"], "rows": lists}, fh)


@pytest.mark.parametrize("geometry", [True, False])
def test_a_checkpoint_of_the_format_before_still_resumes(tmp_path, full, geometry):
    """Decided: a checkpoint whose rows are inside its pickle resumes (its next save writes them into chunks);
    one without the geometry rows gives a history without them, as before."""
    ck = tmp_path / "checkpoint.pkl"
    _stop(ck, 5)
    _as_format_2(ck, geometry)
    assert "chunks" not in read_checkpoint_header(ck) and not (tmp_path / "checkpoint_rows").exists()
    assert resume_refusal(ck, read_checkpoint_header(ck), _model(), PROG, engine="warp", device="cpu") == ""
    head = _stop(ck, 7)
    # its rows and the new ones, in chunks now
    assert head["format"] == runner.CHECKPOINT_FORMAT and [(c["start"], c["stop"]) for c in head["chunks"]] == [
        (0, 6), (6, 7)]
    h = run_patch(_model(), PROG, checkpoint=ck, resume=True)
    _assert_same_history(h, full, geometry)
    assert ("x" in h.groups) == geometry


def test_the_rows_are_the_history_arrays_without_a_stacking_copy():
    """The rows are written in place into one array per key: the history's group arrays are those arrays (one
    base each), not copies stacked from lists at the end."""
    h = run_patch(_model(), PROG)
    for k in ("C", "F", "phi", "label", "status", "x", "W", "s_AB"):
        assert h.groups[k].shape[0] == len(PROG) and h.groups[k].flags.owndata, k
    rec = records.RunRecords(3)
    rec.put(0, "a", 1.0)
    rec.put(1, "a", np.float64(2.5))
    rec.put(0, "b", np.array([1, 2], np.int8))
    rec.put(1, "b", np.array([300, 2], np.int16))            # a wider row promotes, as np.asarray of the rows
    assert rec.arrays["a"].dtype == np.float64 and rec.arrays["b"].dtype == np.int16
    assert rec.arrays["b"][1].tolist() == [300, 2] and rec.arrays["b"][0].tolist() == [1, 2]


def test_a_chunk_without_a_key_the_others_hold_is_refused(tmp_path):
    """Every chunk of a run holds the same keys: one without the geometry rows among chunks with them (rows of
    another knitsim, or put there by hand, its CRC-32s rewritten into the header) would leave rows unwritten."""
    ck = tmp_path / "checkpoint.pkl"
    head = _stop(ck, 5)
    rows = records.RunRecords(5)
    records.read_chunks(ck, head["chunks"], 5, head["fingerprint"], rows)
    rows.drop(["g_x"])
    head["chunks"][1] = records.write_chunk(tmp_path / "checkpoint_rows", rows, 2, 4, head["fingerprint"])
    with pytest.raises(KnitsimInputError, match=r"000002-000004\.npz holds other rows than the chunks before it "
                                                r"\(g_x\)"):
        records.read_chunks(ck, head["chunks"], 5, head["fingerprint"], records.RunRecords(5))
