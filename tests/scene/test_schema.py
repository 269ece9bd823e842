"""The declarative scene schema: types, ranges, defaults, unknown keys, key paths, --set, TOML output."""
from __future__ import annotations

import math
import tomllib

import pytest

from knitsim.errors import KnitsimInputError
from knitsim.scene.schema import OPTIONAL, REQUIRED, Field, Table, TableArray, describe, dumps, set_value, validate

KNIT = Table({
    "L": Field(("float",), REQUIRED, "stitch length", "mm", min=0.0, min_inclusive=False),
    "W0": Field(("float",), 4.4, "wale width", "mm", min=0.0, min_inclusive=False),
    "label": Field(("str",), OPTIONAL),
})
SCHEMA = Table({
    "engine": Field(("str",), "warp", choices=("warp", "reference")),
    "n": Field(("int",), 3, min=1),
    "flag": Field(("bool",), False),
    "phi0": Field(("float", "str"), 0.0, check=lambda v: None if not isinstance(v, str) or v == "phimax"
                  else 'expected a number or "phimax"'),
    "waypoints": Field(("float_list",), OPTIONAL),
    "on": Field(("str_list",), OPTIONAL, choices=("a", "b")),
    "knit": KNIT,
    "cells": TableArray(Table({"knit": KNIT}), min_items=1),
})


def err(data, match, **kw):
    with pytest.raises(KnitsimInputError, match=match) as info:
        validate(SCHEMA, data, **kw)
    assert "\n" not in str(info.value)          # one line
    return str(info.value)


def test_defaults_filled_and_ints_promoted():
    out = validate(SCHEMA, {"knit": {"L": 14}})
    assert out == {"engine": "warp", "n": 3, "flag": False, "phi0": 0.0, "knit": {"L": 14.0, "W0": 4.4}}
    assert isinstance(out["knit"]["L"], float)
    # optional keys stay absent; partial validation fills nothing
    assert validate(SCHEMA, {"knit": {"W0": 5}}, fill_defaults=False) == {"knit": {"W0": 5.0}}


def test_unknown_key_names_path_and_known_keys():
    msg = err({"knit": {"L": 14.1, "W": 4.4}}, r"^knit\.W = 4\.4: unknown key \(expected one of L, W0, label\)$")
    assert msg.startswith("knit.W")
    err({"knit": {"L": 1.0}, "devise": "cpu"}, r'^devise = "cpu": unknown key')


def test_missing_required():
    err({"knit": {}}, r"^knit\.L: missing required key \(stitch length\)$")
    err({}, r"^knit\.L: missing required key")          # absent table filled from defaults


def test_wrong_types():
    err({"knit": {"L": "long"}}, r'^knit\.L = "long": expected a number$')
    err({"knit": {"L": True}}, r"^knit\.L = true: expected a number$")     # bool is not a number
    err({"knit": {"L": 1.0}, "n": 2.5}, r"^n = 2\.5: expected a whole number$")
    err({"knit": {"L": 1.0}, "knit2": 1}, r"^knit2 = 1: unknown key")
    err({"knit": 3}, r"^knit = 3: expected a table$")
    err({"knit": {"L": 1.0}, "waypoints": [0.1, "x"]}, r'^waypoints\[1\] = "x": expected a number$')


def test_nan_and_inf_refused():
    err({"knit": {"L": math.nan}}, r"^knit\.L = nan: must be a finite number$")
    err({"knit": {"L": 1.0}, "waypoints": [0.1, math.inf]}, r"^waypoints\[1\] = inf: must be a finite number$")


def test_ranges_and_choices():
    err({"knit": {"L": 0.0}}, r"^knit\.L = 0\.0: must be > 0 mm$")
    err({"knit": {"L": -2.0}}, r"^knit\.L = -2\.0: must be > 0 mm$")
    err({"knit": {"L": 1.0}, "n": 0}, r"^n = 0: must be >= 1$")
    err({"knit": {"L": 1.0}, "engine": "gpu"}, r'^engine = "gpu": expected one of warp, reference$')
    err({"knit": {"L": 1.0}, "phi0": "max"}, r'^phi0 = "max": expected a number or "phimax"$')
    assert validate(SCHEMA, {"knit": {"L": 1.0}, "phi0": "phimax"})["phi0"] == "phimax"


def test_table_array_paths():
    cells = [{"knit": {"L": 14.1}}, {"knit": {"L": 14.1}}, {"knit": {"L": 14.1, "W0": -2.0}}]
    err({"knit": {"L": 1.0}, "cells": cells}, r"^cells\[2\]\.knit\.W0 = -2\.0: must be > 0 mm$")
    err({"knit": {"L": 1.0}, "cells": []}, r"^cells = \[\]: needs at least 1 entries$")
    err({"knit": {"L": 1.0}, "cells": {"knit": {}}}, r"^cells = \{\.\.\.\}: expected an array of tables")


def test_set_value_converts_by_type():
    data = {"knit": {"L": 14.1}, "cells": [{"knit": {"L": 1.0}}]}
    set_value(data, SCHEMA, "knit.W0=5")
    set_value(data, SCHEMA, "n = 4")
    set_value(data, SCHEMA, "flag=true")
    set_value(data, SCHEMA, "engine=reference")
    set_value(data, SCHEMA, 'knit.label="a, b"')
    set_value(data, SCHEMA, "phi0=phimax")
    set_value(data, SCHEMA, "waypoints=[0.1, 0.5, 0.2]")
    set_value(data, SCHEMA, "cells[0].knit.L=12.5")
    assert data == {"knit": {"L": 14.1, "W0": 5.0, "label": "a, b"}, "n": 4, "flag": True, "engine": "reference",
                    "phi0": "phimax", "waypoints": [0.1, 0.5, 0.2], "cells": [{"knit": {"L": 12.5}}]}
    assert validate(SCHEMA, data)["cells"][0]["knit"] == {"L": 12.5, "W0": 4.4}


@pytest.mark.parametrize("assignment, match", [
    ("knit.L=abc", r'^knit\.L = "abc": expected a number$'),
    ("n=1.5", r'^n = "1\.5": expected a whole number$'),
    ("knit.Lx=1", r"unknown key 'knit\.Lx' \(expected one of L, W0, label\)"),
    ("knit=1", r"knit is a table; set one of its keys"),
    ("cells[3].knit.L=1", r"the scene has 1 entries in cells, no cells\[3\]"),
    ("cells.knit.L=1", r"cells is an array of tables; index it"),
    ("knit.L", r"expected key=value"),
    ("n.x=1", r"n is a value, not a table"),
])
def test_set_value_errors(assignment, match):
    with pytest.raises(KnitsimInputError, match=match):
        set_value({"cells": [{}]}, SCHEMA, assignment)


def test_set_value_takes_a_list_of_strings_as_a_toml_array():
    """--set effects.on=["yarn_compaction"] or calibration.per_specimen=["phi0", "W0"]: a list of strings was
    refused whatever was typed ("expected a list of strings"); now read as the scene writes it (a TOML array),
    its items checked by validate (choices, repeats) as a scene's are."""
    data = set_value({}, SCHEMA, 'on=["a", "b"]')
    doc = {"knit": {"L": 14.1}, "cells": [{"knit": {"L": 1.0}}]}
    assert data == {"on": ["a", "b"]} and validate(SCHEMA, {**doc, **data})["on"] == ["a", "b"]
    assert set_value({}, SCHEMA, "on=[]") == {"on": []}
    err(set_value(doc, SCHEMA, 'on=["a", "c"]'), r'^on\[1\] = "c": expected one of a, b$')
    with pytest.raises(KnitsimInputError, match=r'^on = "a": expected a list of strings$'):
        set_value({}, SCHEMA, "on=a")


def test_set_value_nan_is_refused_by_validation():
    data = set_value({}, SCHEMA, "knit.L=nan")
    err(data, r"^knit\.L = nan: must be a finite number$")


def test_dumps_round_trips_through_tomllib():
    # tomllib (the standard library's parser) is the independent reader
    doc = {"title": 'E-glass "plain", 3 cycles', "n": 3, "x": 0.1, "big": 1e-300, "on": True,
           "waypoints": [0.0, 0.6, 0.1], "load": {"type": "cycles", "upper_strain": 0.6},
           "cells": [{"label": "a", "yarn": {"d": 0.58}, "friction": {"m": 0.2}},
                     {"label": "b", "yarn": {"d": 0.56}}],
           "odd key": {"a.b": 1}}
    text = dumps(doc, header="resolved\nsecond line")
    assert text.startswith("# resolved\n# second line\n")
    assert tomllib.loads(text) == doc


def test_describe_lists_every_key():
    lines = describe(SCHEMA)
    assert "knit.L: float [mm] required -- stitch length" in lines
    assert any(line.startswith("[[cells]]") for line in lines)
    assert "cells[i].knit.W0: float [mm] default 4.4 -- wale width" in lines


def test_a_folder_given_as_the_scene_is_said_to_be_one(tmp_path):
    # a blind probe's `knitsim run FOLDER` was told "no such scene file" of a folder that exists; expected: it is
    # named a folder, with the scenes it holds
    from knitsim.scene.schema import load_toml
    (tmp_path / "a.toml").write_text("title = 'a'\n")
    with pytest.raises(KnitsimInputError, match=r": a folder, not a scene file \(it holds a\.toml\)$"):
        load_toml(tmp_path)
    with pytest.raises(KnitsimInputError, match=r"none\.toml: no such scene file$"):
        load_toml(tmp_path / "none.toml")


def test_a_scene_saved_with_a_byte_order_mark_reads_as_its_text(tmp_path):
    # a blind probe's scene saved by an editor as "UTF-8 with BOM" was refused as "not valid TOML (Invalid
    # statement (at line 1, column 1))", a line that reads right in the editor; expected: the same document as
    # the file without the mark (the mark is no character of the text), of UTF-16 ("Unicode") too
    import codecs

    from knitsim.scene.schema import load_toml
    text = 'title = "Maschenware für Glas"\n[load]\ntype = "monotonic"\ntarget_strain = 0.2\n'
    plain = tmp_path / "plain.toml"
    plain.write_text(text, encoding="utf-8")
    for name, raw in (("bom8.toml", codecs.BOM_UTF8 + text.encode("utf-8")),
                      ("bom16.toml", codecs.BOM_UTF16_LE + text.encode("utf-16-le"))):
        (tmp_path / name).write_bytes(raw)
        assert load_toml(tmp_path / name) == load_toml(plain), name
    # text of no byte-order mark that is not UTF-8 is refused as before, naming the encoding it needs
    (tmp_path / "latin1.toml").write_bytes(text.encode("latin-1"))
    with pytest.raises(KnitsimInputError, match=r"latin1\.toml: not UTF-8 text"):
        load_toml(tmp_path / "latin1.toml")
