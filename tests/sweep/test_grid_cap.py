"""A grid sweep is capped at 10^7 samples like a Latin hypercube, before any axis is built.

Expected outcomes from parse_sweep's own cap: ``method = "lhs", samples = 10**9`` is refused with
``more than 10^7 samples; split the sweep``; a grid's sample count is the product of its axis lengths
(the module docstring of knitsim.sweep.spec), so a grid over 10^7 gets the same refusal, naming the
counts, and a grid of exactly 10^7 is accepted.
"""
from __future__ import annotations

import time
import tracemalloc

import pytest

from knitsim.errors import KnitsimInputError
from knitsim.sweep.spec import MAX_SAMPLES, parse_sweep


def test_a_huge_grid_count_is_refused_before_its_axis_is_built():
    tracemalloc.start()
    t0 = time.perf_counter()
    with pytest.raises(KnitsimInputError) as exc:
        parse_sweep({"parameters": {"friction.m": {"min": 0.10, "max": 0.30, "count": 1_000_000_000}}})
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    msg = str(exc.value)
    assert "more than 10^7 samples; split the sweep" in msg
    assert '"friction.m" count = 1000000000' in msg and "a grid of 1000000000 samples" in msg
    assert peak < 50 * 2**20 and time.perf_counter() - t0 < 5.0   # no 8 GB linspace


def test_a_grid_over_the_cap_by_its_product_names_every_axis():
    with pytest.raises(KnitsimInputError) as exc:
        parse_sweep({"parameters": {"friction.m": {"min": 0.1, "max": 0.3, "count": 4000},
                                    "knit.L": {"values": [13.0, 14.0, 15.0]},
                                    "knit.C0": {"min": 2.5, "max": 2.9, "count": 1000}}})
    msg = str(exc.value)
    assert "a grid of 12000000 samples" in msg
    assert '"friction.m" count = 4000 x "knit.L" 3 values x "knit.C0" count = 1000' in msg
    # the LHS refusal says the same
    with pytest.raises(KnitsimInputError, match="more than 10\\^7 samples; split the sweep"):
        parse_sweep({"method": "lhs", "samples": 1_000_000_000, "parameters": {"friction.m": {"min": 0.1, "max": 0.3}}})


def test_a_grid_of_exactly_the_cap_is_accepted():
    spec = parse_sweep({"parameters": {"friction.m": {"min": 0.1, "max": 0.3, "count": 1000},
                                       "knit.L": {"min": 13.0, "max": 15.0, "count": 10_000}}})
    assert spec.samples == MAX_SAMPLES == 10_000_000
