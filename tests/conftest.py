"""Shared fixtures: every Warp test runs on the CPU, and on CUDA when present."""
from __future__ import annotations

import os

import pytest

from knitsim import warp_runtime

warp_runtime.init()


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_auto_num_workers(config) -> int:
    """``-n auto`` (the README's test command) starts one worker per core this process may use: its CPU
    affinity and its control group's quota (knitsim.warp_runtime.usable_cores), not the host's cores that
    pytest-xdist counts (a 2-core CI container on a 64-core host would start 64 workers)."""
    return warp_runtime.usable_cores()


@pytest.fixture(params=warp_runtime.available_devices())
def device(request) -> str:
    """A Warp device alias: ``"cpu"``, plus ``"cuda:0"`` when a GPU is present."""
    return request.param


@pytest.fixture
def e_glass_calibration():
    """A one-specimen ``knitsim calibrate`` scene as a dict (a fresh one per call), on Dusserre's E-glass yarn
    and knit (Table 1, section 2.2: d = 0.58 mm, B = 0.31 N mm^2; L = 14.1, W0 = 4.4, C0 = 2.7 mm), fitting
    B and m, its curve in ``a.csv`` beside the scene: ``make(title, starts=1, max_nfev=2)``."""
    def make(title: str, starts: int = 1, max_nfev: int = 2) -> dict:
        return {"title": title, "yarn": {"name": "glass", "d": 0.58, "B": 0.31, "in_plane_width": 0.79},
                "friction": {"m": 0.3}, "rules": {"force_cap_N": 200.0},
                "calibration": {"shared": ["B", "m"], "per_specimen": [], "max_increment": 0.02, "row_step": 0.02,
                                "starts": starts, "refine": 1, "max_nfev": max_nfev},
                "specimens": [{"name": "tight", "width": 50.0, "gauge_length": 100.0, "curve": "a.csv",
                               "noise_N": 0.05, "knit": {"L": 14.1, "W0": 4.4, "C0": 2.7}}]}
    return make


@pytest.fixture(scope="session")
def proc_refuses_files() -> str:
    """``/proc``, a folder that exists and takes no new file (Linux, even for root: the permission bits do
    not say so); the test is skipped where there is none."""
    try:
        fd = os.open("/proc/.knitsim-probe", os.O_CREAT | os.O_WRONLY)
    except OSError:
        if os.path.isdir("/proc"):
            return "/proc"
        pytest.skip("needs a /proc that refuses new files (Linux)")
    os.close(fd)
    os.remove("/proc/.knitsim-probe")
    pytest.skip("needs a /proc that refuses new files (Linux)")
