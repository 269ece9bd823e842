"""Shared fixtures: every Warp test runs on the CPU, and on CUDA when present."""
from __future__ import annotations

import pytest

from knitsim import warp_runtime

warp_runtime.init()


@pytest.fixture(params=warp_runtime.available_devices())
def device(request) -> str:
    """A Warp device alias: ``"cpu"``, plus ``"cuda:0"`` when a GPU is present."""
    return request.param
