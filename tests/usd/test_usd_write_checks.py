"""The USD writers check what they are given before any work: a path that cannot be written, a playback
rate that is not a finite positive number; a failure while writing is knitsim's error, naming the path.

Expected values: the operating system's own answer (``/proc`` takes no new file on Linux; a path under
a regular file cannot be created), and knitsim's error contract (:class:`knitsim.errors.KnitsimInputError`,
message naming the path).
"""
from __future__ import annotations

import os

import numpy as np
import pytest

pxr = pytest.importorskip("pxr")

from knitsim.errors import KnitsimInputError  # noqa: E402
from knitsim.usd import export as ex  # noqa: E402
from knitsim.usd import write_patch_usd  # noqa: E402
from knitsim.usd.instanced import write_specimen_usd  # noqa: E402

import importlib.util  # noqa: E402
import pathlib  # noqa: E402

_spec = importlib.util.spec_from_file_location("_usd_export_tests", pathlib.Path(__file__).with_name("test_export.py"))
_export_tests = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_export_tests)
make_frames = _export_tests.make_frames


def test_unwritable_folder_refused_before_any_work(proc_refuses_files):
    frames = make_frames(2, courses=2, wales=3, n=5)
    with pytest.raises(KnitsimInputError, match=r"path='/proc/x\.usda': cannot be written: no file can be created"):
        write_patch_usd("/proc/x.usda", frames, 0.3)
    with pytest.raises(KnitsimInputError, match=r"path='/proc/x\.usdc'"):
        write_specimen_usd("/proc/x.usdc", [], np.ones(1), np.zeros((1, 1), int), np.ones((1, 1)), np.ones((1, 1)))


def test_parent_that_is_a_file_refused(tmp_path):
    (tmp_path / "r1.usda").write_text("#usda 1.0\n")
    frames = make_frames(2, courses=2, wales=3, n=5)
    with pytest.raises(KnitsimInputError, match=r"r1\.usda is a file, not a folder"):
        write_patch_usd(tmp_path / "r1.usda" / "x.usda", frames, 0.3)
    (tmp_path / "d.usda").mkdir()
    with pytest.raises(KnitsimInputError, match="is a folder"):
        write_patch_usd(tmp_path / "d.usda", frames, 0.3)
    # a missing folder is created (as before)
    assert write_patch_usd(tmp_path / "new" / "deeper" / "x.usda", frames, 0.3).file_bytes > 0


def test_a_pxr_failure_is_knitsims_error_naming_the_path(monkeypatch, proc_refuses_files):
    """Past the check (bypassed here), pxr's own error while writing comes back as KnitsimInputError."""
    monkeypatch.setattr(ex, "check_usd_path", lambda path, flag=None: os.fspath(path))
    frames = make_frames(2, courses=2, wales=3, n=5)
    with pytest.raises(KnitsimInputError, match=r"path='/proc/y\.usda': the USD file cannot be written"):
        write_patch_usd("/proc/y.usda", frames, 0.3)


@pytest.mark.parametrize("rate", [0, -24.0, float("nan"), float("inf"), True, "24"])
def test_time_codes_per_second_must_be_finite_and_positive(tmp_path, rate):
    frames = make_frames(2, courses=2, wales=3, n=5)
    with pytest.raises(KnitsimInputError, match="time_codes_per_second"):
        write_patch_usd(tmp_path / "x.usda", frames, 0.3, time_codes_per_second=rate)
    assert not (tmp_path / "x.usda").exists()
    with pytest.raises(KnitsimInputError, match="time_codes_per_second"):
        write_specimen_usd(tmp_path / "y.usda", [{"quarter_xy": np.zeros((1, 5, 2))}], np.ones(1),
                           np.zeros((1, 1), int), np.ones((1, 1)), np.ones((1, 1)), time_codes_per_second=rate)


def test_layer_metadata_names_what_it_counts(tmp_path):
    """customLayerData: the time samples written and the frames passed (no ambiguous frames_in_input)."""
    frames = make_frames(6, courses=2, wales=3, n=5)
    res = write_patch_usd(tmp_path / "x.usda", frames, 0.3, stride=2)
    from pxr import Usd
    stage = Usd.Stage.Open(res.path)
    info = stage.GetRootLayer().customLayerData["knitsim"]
    assert "frames_in_input" not in info
    assert info["timeline"]["time_samples"] == 4 and info["timeline"]["frames_passed"] == 6      # 0, 2, 4, 5
    assert info["timeline"]["stride"] == 2
