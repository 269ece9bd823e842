"""Per-cell maps: each map type gives the array its definition states (knitsim.patch.maps docstring)."""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.errors import KnitsimInputError
from knitsim.patch.maps import build_map, gradient

SHAPE = (4, 3)   # (courses, wales)


def test_uniform_and_regions():
    assert np.all(build_map({"type": "uniform", "value": 0.5}, SHAPE, 1.0, "maps.d") == 0.5)
    spec = {"type": "regions", "regions": [{"courses": [1, 3], "wales": [0, 2], "value": 2.0},
                                           {"courses": [2, 4], "value": 3.0}]}
    expected = np.array([[1, 1, 1], [2, 2, 1], [3, 3, 3], [3, 3, 3]], float)   # later regions on top
    assert np.array_equal(build_map(spec, SHAPE, 1.0, "maps.d"), expected)
    spec["default"] = 9.0
    assert build_map(spec, SHAPE, 1.0, "maps.d")[0, 0] == 9.0


def test_region_out_of_range_names_key():
    spec = {"type": "regions", "regions": [{"courses": [0, 5], "value": 2.0}]}
    with pytest.raises(KnitsimInputError, match=r"maps\.d\.regions\[0\]\.courses = \[0, 5\].*4 courses"):
        build_map(spec, SHAPE, 1.0, "maps.d")


@pytest.mark.parametrize("axis", ["courses", "wales"])
def test_linear_gradient(axis):
    a = build_map({"type": "gradient", "axis": axis, "start": 1.0, "end": 2.0}, SHAPE, 0.0, "maps.L")
    n = SHAPE[0] if axis == "courses" else SHAPE[1]
    line = a[:, 0] if axis == "courses" else a[0, :]
    # endpoints are start and end; equal spacing (end - start) / (n - 1)
    assert line[0] == 1.0 and line[-1] == 2.0
    assert np.allclose(np.diff(line), 1.0 / (n - 1), rtol=0, atol=1e-15)
    # constant along the other axis
    assert np.all(a == (a[:, :1] if axis == "courses" else a[:1, :]))


def test_step_gradient_bands():
    # 4 courses in 2 bands: [0, 1] at start, [2, 3] at end
    a = build_map({"type": "gradient", "axis": "courses", "start": 1.0, "end": 3.0, "profile": "step", "steps": 2},
                  SHAPE, 0.0, "maps.L")
    assert np.array_equal(a[:, 0], [1.0, 1.0, 3.0, 3.0])
    # 3 wales in 3 bands: start, midpoint, end
    assert np.array_equal(gradient(3, 0.0, 1.0, "step", 3), [0.0, 0.5, 1.0])


def test_file_npy_csv_and_shape_check(tmp_path):
    arr = np.arange(12, dtype=float).reshape(SHAPE)
    np.save(tmp_path / "a.npy", arr)
    (tmp_path / "a.csv").write_text("\n".join(",".join(str(v) for v in row) for row in arr) + "\n")
    for name in ("a.npy", "a.csv"):
        got = build_map({"type": "file", "path": name}, SHAPE, 0.0, "maps.phi0", base_dir=tmp_path)
        assert np.array_equal(got, arr)
    np.save(tmp_path / "b.npy", arr.T)
    with pytest.raises(KnitsimInputError, match=r"maps\.phi0\.path = .*shape \(3, 4\), expected .*\(4, 3\)"):
        build_map({"type": "file", "path": "b.npy"}, SHAPE, 0.0, "maps.phi0", base_dir=tmp_path)


def test_random_reproducible_and_bounded():
    spec = {"type": "random", "low": -1.0, "high": 1.0, "seed": 7, "scale": "phimax"}
    phimax = np.full(SHAPE, np.arctan(0.2))
    a = build_map(spec, (40, 30), 0.0, "maps.phi0", phimax=np.full((40, 30), np.arctan(0.2)), name="phi0")
    b = build_map(spec, (40, 30), 0.0, "maps.phi0", phimax=np.full((40, 30), np.arctan(0.2)), name="phi0")
    assert np.array_equal(a, b)                       # same seed, same field
    assert np.all(np.abs(a) <= np.arctan(0.2))        # within [-phimax, phimax]
    assert a.std() > 0.3 * np.arctan(0.2)             # uniform on [-1, 1] x phimax: std = phimax / sqrt(3)
    c = build_map(dict(spec, seed=8), SHAPE, 0.0, "maps.phi0", phimax=phimax, name="phi0")
    assert not np.array_equal(c, a[:4, :3])
    with pytest.raises(KnitsimInputError, match=r"maps\.d\.scale = \"phimax\""):
        build_map(dict(spec), SHAPE, 0.0, "maps.d", phimax=phimax, name="d")


def test_a_phimax_scaled_range_beyond_the_cone_names_low_or_high():
    # low and high are fractions of phimax: a blind probe's low = -30, high = 30 was refused at a drawn cell,
    # "maps.phi0 = -5.46 ... -5.46 looks like degrees", a value in no file and a wrong hint
    phimax = np.full(SHAPE, np.arctan(0.2))
    spec = {"type": "random", "low": -30.0, "high": 30.0, "seed": 7, "scale": "phimax"}
    with pytest.raises(KnitsimInputError, match=r'^maps\.phi0\.low = -30\.0: with scale = "phimax", low and high '
                                                r"are fractions of each cell's phimax = atan m, within \[-1, 1\]"):
        build_map(spec, SHAPE, 0.0, "maps.phi0", phimax=phimax, name="phi0")
    with pytest.raises(KnitsimInputError, match=r"^maps\.phi0\.high = 1\.5: "):
        build_map(dict(spec, low=0.0, high=1.5), SHAPE, 0.0, "maps.phi0", phimax=phimax, name="phi0")
    # the cone's own edges, [-1, 1], stay allowed (the limit case)
    got = build_map(dict(spec, low=-1.0, high=1.0), SHAPE, 0.0, "maps.phi0", phimax=phimax, name="phi0")
    assert np.all(np.abs(got) <= phimax)


@pytest.mark.parametrize("axis, shape", [("wales", (4, 1)), ("courses", (1, 3))])
def test_a_gradient_along_one_cell_is_refused(axis, shape):
    # start on the first cell and end on the last cannot both hold with one cell: a blind probe's end = -3 on
    # a 1 x 1 patch ran with L = start, where the same map on 3 wales refused the negative L
    with pytest.raises(KnitsimInputError, match=rf"maps\.L\.axis = .{axis}.: a gradient needs at least 2 {axis}"):
        build_map({"type": "gradient", "axis": axis, "start": 14.0, "end": -3.0}, shape, 0.0, "maps.L")


def test_an_unknown_rule_of_a_patch_model_is_refused():
    # a blind probe's PatchModel(rules={"unload_rule": ...}) ran with the default rule without a word
    from knitsim.cell.material import CellParams
    from knitsim.patch.model import PatchModel
    base = PatchModel.uniform(CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2), 2, 2)
    with pytest.raises(KnitsimInputError, match=r"^rules\.unload_rule: unknown rule \(expected one of .*unloading_rule"):
        PatchModel(2, 2, base.fields, {"unload_rule": "hong_constant_t"})


def test_map_csv_files_as_spreadsheets_write_them(tmp_path):
    """Hand-written files (not knitsim's): the 4 x 3 array 0.1 k - 0.05 j as Excel saves it in a decimal-comma
    locale (BOM, ';', decimal commas, CRLF, a row of labels, a trailing ';', a blank line), as "Unicode Text"
    (UTF-16, tabs), and plainly; all read as that array.  An empty cell and a word are refused by row and
    column (a blind probe's Excel map was refused as "row 1 is not a list of numbers")."""
    arr = np.array([[0.1 * k - 0.05 * j for j in range(3)] for k in range(4)])
    excel = "\ufeffwale 0;wale 1;wale 2;\r\n" + "".join(
        ";".join(f"{v:.2f}".replace(".", ",") for v in row) + ";\r\n" for row in arr) + "\r\n"
    (tmp_path / "excel.csv").write_bytes(excel.encode("utf-8"))
    utf16 = "\r\n".join("\t".join(f"{v:g}" for v in row) for row in arr) + "\r\n"
    (tmp_path / "unicode.csv").write_bytes(utf16.encode("utf-16"))
    (tmp_path / "plain.csv").write_text("\n".join(",".join(f"{v:g}" for v in row) for row in arr) + "\n")
    for name in ("excel.csv", "unicode.csv", "plain.csv"):
        got = build_map({"type": "file", "path": name}, SHAPE, 0.0, "maps.phi0", base_dir=tmp_path)
        assert np.allclose(got, arr, atol=1e-12), name
    (tmp_path / "hole.csv").write_text("0.1,,0.2\n0,0,0\n0,0,0\n0,0,0\n")
    with pytest.raises(KnitsimInputError, match=r"hole\.csv.*row 1, column 2: empty"):
        build_map({"type": "file", "path": "hole.csv"}, SHAPE, 0.0, "maps.phi0", base_dir=tmp_path)
    (tmp_path / "word.csv").write_text("0,0,0\n0,abc,0\n0,0,0\n0,0,0\n")
    with pytest.raises(KnitsimInputError, match=r"word\.csv.*row 2, column 2: 'abc' is not a number"):
        build_map({"type": "file", "path": "word.csv"}, SHAPE, 0.0, "maps.phi0", base_dir=tmp_path)


def test_map_csv_quoted_cells_ragged_rows_and_a_specimens_axes(tmp_path):
    """Hand-written files: the 4 x 3 array 0.1 k - 0.05 j with every cell quoted (a script's QUOTE_ALL with ';';
    LibreOffice's decimal-comma export with ',' between quoted cells) reads as that array: before, the quoted
    first row was skipped as a row of labels and the map refused as "shape (3, 3)".  A row one number short is
    refused naming it and the first row's length (before: "expected a rectangular table", no row named).  A
    specimen's map of the wrong shape names bands and strips, and a transposed one says it may be."""
    arr = np.array([[0.1 * k - 0.05 * j for j in range(3)] for k in range(4)])
    semi = "".join(";".join(f'"{v:.2f}"'.replace(".", ",") for v in row) + "\r\n" for row in arr)
    (tmp_path / "semi.csv").write_text(semi)
    comma = "".join(",".join(f'"{v:.2f}"'.replace(".", ",") for v in row) + "\n" for row in arr)
    (tmp_path / "comma.csv").write_text(comma)
    for name in ("semi.csv", "comma.csv"):
        got = build_map({"type": "file", "path": name}, SHAPE, 0.0, "maps.phi0", base_dir=tmp_path)
        assert np.allclose(got, arr, atol=1e-12), name
    (tmp_path / "ragged.csv").write_text("0;0;0\n0;0;0\n0;0\n0;0;0\n")
    with pytest.raises(KnitsimInputError, match=r"ragged\.csv.*row 3 holds 2 number\(s\), row 1 3"):
        build_map({"type": "file", "path": "ragged.csv"}, SHAPE, 0.0, "maps.phi0", base_dir=tmp_path)
    (tmp_path / "t.csv").write_text("\n".join(",".join(f"{v:g}" for v in row) for row in arr.T) + "\n")
    with pytest.raises(KnitsimInputError, match=r"shape \(3, 4\), expected \(bands, strips\) = \(4, 3\) "
                                                r"\(the file may hold the map transposed"):
        build_map({"type": "file", "path": "t.csv"}, SHAPE, 0.0, "maps.phi0", base_dir=tmp_path,
                  counted=("bands", "strips"))


def test_a_map_csv_of_the_wrong_shape_names_the_row_it_skipped_as_labels(tmp_path):
    # hand-made: 4 rows of 3 cells for a 4 x 3 patch, the first a row of words (a spreadsheet's column names):
    # skipped as labels, the map holds 3 rows, and the error says which row was not read as numbers
    (tmp_path / "named.csv").write_text("w0,w1,w2\n0.1,0.0,-0.1\n0.05,0.0,-0.05\n0.0,0.0,0.0\n")
    with pytest.raises(KnitsimInputError, match=r"named\.csv.*shape \(3, 3\), expected \(courses, wales\) = "
                                                r"\(4, 3\); row 1 \('w0', 'w1', 'w2'\) was read as a row of "
                                                r"labels and skipped"):
        build_map({"type": "file", "path": "named.csv"}, SHAPE, 0.0, "maps.phi0", base_dir=tmp_path)
    # the same labels over 4 rows of numbers: the map, the labels skipped without a word (as before)
    (tmp_path / "ok.csv").write_text("w0,w1,w2\n1,2,3\n4,5,6\n7,8,9\n10,11,12\n")
    a = build_map({"type": "file", "path": "ok.csv"}, SHAPE, 0.0, "maps.phi0", base_dir=tmp_path)
    assert a.tolist() == [[1, 2, 3], [4, 5, 6], [7, 8, 9], [10, 11, 12]]
    # a wrong shape without a row of labels says nothing of one
    (tmp_path / "short.csv").write_text("1,2,3\n4,5,6\n")
    with pytest.raises(KnitsimInputError, match=r"shape \(2, 3\), expected \(courses, wales\) = \(4, 3\)$"):
        build_map({"type": "file", "path": "short.csv"}, SHAPE, 0.0, "maps.phi0", base_dir=tmp_path)


def test_a_map_file_with_a_nan_names_the_cell(tmp_path):
    """A NaN (or inf) in a map file is refused naming where it is: a .npy by its cell (course and wale; a specimen's
    band and strip) and index, a CSV by its row and column as its other bad cells are.  Before: "the array must hold
    finite numbers only", no cell named, among every cell of the map."""
    a = np.full(SHAPE, 14.1)
    a[2, 1] = np.nan
    a[3, 0] = np.inf
    np.save(tmp_path / "L.npy", a)
    with pytest.raises(KnitsimInputError, match=r"nan at cell \[course 2, wale 1\] \(index \[2, 1\]\) \(2 cells in all\): "
                                                r"the map must hold finite numbers only"):
        build_map({"type": "file", "path": "L.npy"}, SHAPE, 1.0, "maps.L", base_dir=tmp_path)
    with pytest.raises(KnitsimInputError, match=r"nan at block \[band 2, strip 1\]"):
        build_map({"type": "file", "path": "L.npy"}, SHAPE, 1.0, "maps.L", base_dir=tmp_path,
                  counted=("bands", "strips"))
    rows = [";".join("14,1" for _ in range(3))] * 4
    rows[2] = "14,1;NaN;14,1"
    (tmp_path / "L.csv").write_text("course;a;b\n" + "\n".join(rows) + "\n")       # a row of labels first: row 4
    with pytest.raises(KnitsimInputError, match=r"row 4, column 2: 'NaN' is not a finite number"):
        build_map({"type": "file", "path": "L.csv"}, SHAPE, 1.0, "maps.L", base_dir=tmp_path)
