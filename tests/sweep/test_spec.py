"""The [sweep] table: grid and Latin-hypercube sample tables, validation."""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from knitsim.errors import KnitsimInputError
from knitsim.sweep.spec import lhs_unit, parse_sweep, split_scene


def test_grid_is_the_cartesian_product_first_axis_slowest():
    # independent construction: nested loops in the given order (C order)
    spec = parse_sweep({"parameters": {"friction.m": {"values": [0.1, 0.2, 0.3]},
                                       "knit.L": {"min": 13.0, "max": 15.0, "count": 5}}})
    L = np.linspace(13.0, 15.0, 5)          # a min/max/count axis is numpy's linspace
    expected = [(m, l) for m in (0.1, 0.2, 0.3) for l in L]
    assert spec.sample_table() == expected
    assert spec.shape == (3, 5) and spec.samples == 15
    assert spec.keys == ["friction.m", "knit.L"]


def test_grid_keeps_strings_and_order_of_three_axes():
    spec = parse_sweep({"parameters": {"friction.model": {"values": ["coulomb", "dahl"]},
                                       "friction.m": {"values": [0.2, 0.1]},
                                       "rules.force_cap_N": {"values": [5.0]}}})
    assert spec.sample_table() == list(itertools.product(["coulomb", "dahl"], [0.2, 0.1], [5.0]))


@pytest.mark.parametrize("n,seed", [(7, 1), (50, 123)])
def test_lhs_hits_each_stratum_of_each_parameter_exactly_once(n, seed):
    # defining property of a Latin hypercube (McKay, Beckman & Conover 1979): each of the
    # n equal strata of every dimension holds exactly one sample
    spec = parse_sweep({"method": "lhs", "samples": n, "seed": seed,
                        "parameters": {"friction.m": {"min": 0.1, "max": 0.3},
                                       "friction.phi0": {"min": -0.09, "max": 0.09},
                                       "knit.L": {"min": 13.6, "max": 14.6}}})
    x = np.array(spec.sample_table())
    for j, (lo, hi) in enumerate([(0.1, 0.3), (-0.09, 0.09), (13.6, 14.6)]):
        assert np.all((x[:, j] >= lo) & (x[:, j] < hi))
        strata = np.floor((x[:, j] - lo) / (hi - lo) * n).astype(int)
        assert sorted(strata) == list(range(n))


def test_lhs_reproducible_with_the_seed():
    u1, u2, u3 = lhs_unit(3, 20, 5), lhs_unit(3, 20, 5), lhs_unit(3, 20, 6)
    assert np.array_equal(u1, u2)
    assert not np.array_equal(u1, u3)


def test_hash_changes_with_the_spec():
    a = parse_sweep({"parameters": {"friction.m": {"values": [0.1, 0.2]}}})
    b = parse_sweep({"parameters": {"friction.m": {"values": [0.1, 0.25]}}})
    assert a.hash() != b.hash()
    assert a.hash() == parse_sweep({"parameters": {"friction.m": {"values": [0.1, 0.2]}}}).hash()


@pytest.mark.parametrize("table,words", [
    ({"parameters": {"friction.m": {"values": []}}}, ['"friction.m"', "values"]),
    ({"parameters": {"friction.m": {"min": 0.3, "max": 0.3, "count": 3}}}, ['"friction.m"', "min", "< max"]),
    ({"method": "lhs", "samples": 4, "parameters": {"knit.L": {"min": 15.0, "max": 13.0}}}, ['"knit.L"', "min"]),
    ({"parameters": {"friction.m": {"min": 0.1, "max": 0.3}}}, ['"friction.m"', "count"]),
    ({"method": "lhs", "samples": 4, "parameters": {"friction.m": {"values": [0.1]}}}, ['"friction.m"', "range"]),
    ({"method": "lhs", "parameters": {"friction.m": {"min": 0.1, "max": 0.3}}}, ["sweep.samples"]),
    ({"method": "sobol", "parameters": {"friction.m": {"values": [0.1]}}}, ["sweep.method", "sobol"]),
    ({"parameters": {}}, ["sweep.parameters"]),
    ({"chunk_size": 0, "parameters": {"friction.m": {"values": [0.1]}}}, ["sweep.chunk_size"]),
    ({"size": 3, "parameters": {"friction.m": {"values": [0.1]}}}, ["sweep.size", "unknown"]),
    ({"parameters": {"friction.m": {"values": [0.1, 0.1]}}}, ['"friction.m"', "repeat"]),
    # one number written as an int and as a float (both are m = 0: two samples of one, a coordinate that repeats)
    ({"parameters": {"friction.m": {"values": [0, 0.0]}}}, ['"friction.m"', "repeat"]),
    ({"parameters": {"load.cycles": {"values": [2, 3, 2.0]}}}, ['"load.cycles"', "repeat"]),
])
def test_bad_tables_are_refused_naming_the_key(table, words):
    with pytest.raises(KnitsimInputError) as exc:
        parse_sweep(table)
    msg = str(exc.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg


def test_split_scene_needs_a_sweep_table():
    with pytest.raises(KnitsimInputError, match=r"\[sweep\]"):
        split_scene({"load": {"type": "monotonic"}})
    scene, table, src = split_scene({"load": {}, "sweep": {"parameters": {}}})
    assert "sweep" not in scene and table == {"parameters": {}} and src == "scene"


def test_an_unquoted_key_path_is_refused_saying_to_quote_it():
    # a hand-made sweep file's [sweep.parameters] friction.m = { values = [...] } (unquoted) is, by TOML, a table
    # friction holding m: a blind probe was told 'sweep.parameters."friction".m = {...}: unknown key'
    import tomllib
    table = tomllib.loads('[sweep.parameters]\nfriction.m = { values = [0.1, 0.2] }\n'
                          'knit = { L = { min = 13.0, max = 14.0, count = 2 } }\n')["sweep"]
    with pytest.raises(KnitsimInputError, match=r'^sweep.parameters."friction" = .*: a table of friction.m, not a sweep '
                                                r'entry: .* quote it: "friction.m" = \{ ... \}$'):
        parse_sweep(table)
    with pytest.raises(KnitsimInputError, match=r'a table of knit.L, .*"knit.L" = '):
        parse_sweep({"parameters": {"knit": table["parameters"]["knit"]}})
    # quoted: the two axes
    spec = parse_sweep({"parameters": {"friction.m": {"values": [0.1, 0.2]},
                                       "knit.L": {"min": 13.0, "max": 14.0, "count": 2}}})
    assert spec.keys == ["friction.m", "knit.L"] and spec.samples == 4
