"""Excel workbooks (.xlsx) read as their sheet's table, typed cell by cell here.

A lab saves a test machine's export as a workbook as often as a CSV.  Each workbook below is typed cell by cell
(openpyxl writes the file, as Excel would, with the sheet's own row numbers); the expected values are the numbers
typed: the sheet reads as its CSV twin, rows are named by the spreadsheet's row numbers, and what cannot be read
(a legacy .xls, an OpenDocument sheet, a damaged file) is refused saying what to save it as.
"""
from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest

from knitsim.errors import KnitsimInputError
from knitsim.io.table_input import read_csv_columns

openpyxl = pytest.importorskip("openpyxl")

REQ = ("strain", "force_per_wale_N")
NUM = ("strain", "force_per_wale_N", "cycle")
ROWS = [(0.0, -0.002, "load", 1), (0.1, 0.053, "load", 1), (0.2, 0.098, "load", 1), (0.1, 0.018, "unload", 1)]


def _book(path, sheets):
    """A workbook of ``sheets``: (title, {cell: value}) pairs, the first one active."""
    wb = openpyxl.Workbook()
    wb.remove(wb.active)
    for title, cells in sheets:
        ws = wb.create_sheet(title)
        for ref, v in cells.items():
            ws[ref] = v
    wb.active = 0
    wb.save(path)
    return path


def _data_sheet(first_row=1, preamble=True):
    cells = {"A1": "Specimen: A3", "A2": "Operator: JD"} if preamble else {}
    h = first_row
    cells.update({f"A{h}": "Strain", f"B{h}": "force_per_wale_N [N]", f"C{h}": "direction", f"D{h}": "cycle"})
    for k, (e, f, d, c) in enumerate(ROWS):
        r = h + 2 + k if k >= 2 else h + 1 + k          # a blank row inside the data, as a sheet often has
        cells.update({f"A{r}": e, f"B{r}": f, f"C{r}": d, f"D{r}": c})
    return cells


def test_a_sheet_with_a_preamble_reads_as_its_csv_twin_with_the_spreadsheet_row_numbers(tmp_path):
    p = _book(tmp_path / "m.xlsx", [("Test 1", _data_sheet(first_row=4))])
    got = read_csv_columns(p, REQ, ("direction", "cycle"), numeric=NUM)
    np.testing.assert_array_equal(got["strain"], [r[0] for r in ROWS])
    np.testing.assert_array_equal(got["force_per_wale_N"], [r[1] for r in ROWS])     # -0.002 N kept as typed
    assert list(got["direction"]) == [r[2] for r in ROWS]
    np.testing.assert_array_equal(got["_row"], [5, 6, 8, 9])        # the header in row 4, a blank row 7
    assert got.notes[0] == "an Excel workbook: read its sheet 'Test 1' (the active one)"


def test_the_data_sheet_is_found_behind_a_summary_sheet_and_said(tmp_path):
    summary = {"A1": "Summary", "A2": "Max load", "B2": "see sheet Raw"}
    p = _book(tmp_path / "m.xlsx", [("Summary", summary), ("Raw", _data_sheet(preamble=False))])
    got = read_csv_columns(p, REQ, numeric=REQ)
    np.testing.assert_array_equal(got["strain"], [r[0] for r in ROWS])
    assert got.notes[0] == ("an Excel workbook: read its sheet 'Raw' (the first with rows of numbers; the active "
                            "one, 'Summary', has none; sheets: 'Summary', 'Raw')")


def test_a_formula_keeps_the_value_excel_computed_and_one_never_computed_is_refused_by_its_row(tmp_path):
    cells = _data_sheet(preamble=False)
    cells["B2"] = "=B3/2"                       # a formula (row 2 of the data)
    p = _book(tmp_path / "m.xlsx", [("Data", cells)])
    # as written by a program that never computed it: no cached value, refused naming the row, the column and the
    # formula, said never computed (a probe's workbook of such formulas was refused as "'' is not a number")
    with pytest.raises(KnitsimInputError, match=r"m\.xlsx: row 2, column force_per_wale_N: '=B3/2 \(a formula never "
                                                r"computed\)' is not a number"):
        read_csv_columns(p, REQ, numeric=REQ)
    # as Excel saves it: the formula with its last computed value (<v>), which is read
    with zipfile.ZipFile(p) as z:
        parts = {n: z.read(n) for n in z.namelist()}
    sheet = parts["xl/worksheets/sheet1.xml"].decode()
    assert "<f>B3/2</f><v />" in sheet
    parts["xl/worksheets/sheet1.xml"] = sheet.replace("<f>B3/2</f><v />", "<f>B3/2</f><v>0.0265</v>").encode()
    q = tmp_path / "excel.xlsx"
    with zipfile.ZipFile(q, "w") as z:
        for n, b in parts.items():
            z.writestr(n, b)
    got = read_csv_columns(q, REQ, numeric=REQ)
    assert got["force_per_wale_N"][0] == 0.0265


@pytest.mark.parametrize("what, content, says", [
    ("xls", b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1" + bytes(504), "an Excel 97-2003 workbook (.xls)"),
    ("ods", None, "an OpenDocument spreadsheet (.ods)"),
    ("damaged", b"PK\x03\x04" + bytes(40), "not a readable one"),
])
def test_what_is_not_an_xlsx_is_refused_saying_what_to_save_it_as(tmp_path, what, content, says):
    p = tmp_path / f"m.{what}"
    if content is None:
        with zipfile.ZipFile(p, "w") as z:           # an OpenDocument file's first entries
            z.writestr("mimetype", "application/vnd.oasis.opendocument.spreadsheet")
            z.writestr("content.xml", "<office:document-content/>")
    else:
        p.write_bytes(content)
    with pytest.raises(KnitsimInputError) as e:
        read_csv_columns(p, REQ, numeric=REQ)
    assert str(e.value).startswith(f"{p}: ") and says in str(e.value) and "CSV" in str(e.value)


def test_capstan_fit_of_a_workbook_is_the_fit_of_its_csv(tmp_path, capsys):
    # Table 2's e-glass records (scenes/capstan/e_glass_table2.csv) typed into a sheet: the same fit
    import csv
    from pathlib import Path

    from knitsim.cli import main
    src = Path(__file__).resolve().parents[2] / "scenes" / "capstan" / "e_glass_table2.csv"
    rows = [r for r in csv.reader(src.read_text().splitlines()) if r and not r[0].startswith("#")]
    cells = {}
    for i, r in enumerate(rows, start=1):
        for j, v in enumerate(r):
            try:
                val = float(v)
            except ValueError:
                val = v
            cells[f"{'ABCDEFGH'[j]}{i}"] = val
    p = _book(tmp_path / "t2.xlsx", [("records", cells)])
    fits = []
    for f in (src, p):
        assert main(["capstan", "fit", str(f), "--json"]) in (0, 1)
        fits.append(json.loads(capsys.readouterr().out))
    for k in ("b", "p", "n"):
        assert fits[1][k] == fits[0][k]


def test_a_patch_map_in_a_workbook_reads_as_its_csv_and_a_gap_is_named_by_its_row(tmp_path):
    # a phi0 map typed into a sheet: a row of wale labels, two courses of three wales
    from knitsim.patch.maps import read_array_file
    cells = {"A1": "w0", "B1": "w1", "C1": "w2", "A2": 0.1, "B2": 0.0, "C2": -0.1, "A3": 0.2, "B3": 0.1, "C3": 0.0}
    p = _book(tmp_path / "phi0.xlsx", [("map", cells)])
    np.testing.assert_array_equal(read_array_file(p, (2, 3), "fields.phi0"), [[0.1, 0.0, -0.1], [0.2, 0.1, 0.0]])
    del cells["B3"]
    q = _book(tmp_path / "gap.xlsx", [("map", cells)])
    with pytest.raises(KnitsimInputError, match=r"row 3, column 2: empty"):
        read_array_file(q, (2, 3), "fields.phi0")


def test_diagnose_json_says_which_sheet_of_a_workbook_was_read(tmp_path):
    # a loading typed into a workbook's second sheet, behind a summary: the curve's read notes say which sheet,
    # and they reach the diagnosis JSON (curves[i].read_notes), as the console's read line says them
    from knitsim.diagnosis.diagnose import _curves_out
    from knitsim.diagnosis.measured import read_measured_curve
    strain = np.round(np.linspace(0.0, 0.3, 16), 4)
    force = np.round(0.02 + 0.5 * strain + 4.0 * strain ** 3, 5)          # a knit's loading, typed as numbers
    cells = {"A1": "strain", "B1": "force_per_wale_N"}
    for k, (e, f) in enumerate(zip(strain, force), start=2):
        cells.update({f"A{k}": float(e), f"B{k}": float(f)})
    p = _book(tmp_path / "m.xlsx", [("Summary", {"A1": "see Raw"}), ("Raw", cells)])
    curve = read_measured_curve(p)
    np.testing.assert_array_equal(curve.force, force)
    assert curve.notes[0].startswith("an Excel workbook: read its sheet 'Raw'")
    fit = {"curves": [{"simulated": curve.force, "keys": [], "labels": np.array(["sliding"] * len(force))}]}
    (entry,) = _curves_out([curve], fit, None, None)
    assert entry["read_notes"] == list(curve.notes)


def test_a_strain_column_formatted_as_a_percentage_reads_as_the_fractions_it_holds(tmp_path):
    # a sheet whose strain cells hold 0.1 shown as 10% (a percentage format) under 'Strain [%]': read as 0.1,
    # not 0.001 (the cell's fraction is the per cent it shows)
    cells = {"A1": "Strain [%]", "B1": "force_per_wale_N"}
    fractions = [0.0, 0.125, 0.25, 0.123456789012, 1.0]          # (1.0, 100 %, is stored as the integer 1)
    for k, e in enumerate(fractions, start=2):
        cells.update({f"A{k}": e, f"B{k}": 0.01 * k})
    p = _book(tmp_path / "m.xlsx", [("Data", cells)])
    wb = openpyxl.load_workbook(p)
    for k in range(2, 2 + len(fractions)):
        wb["Data"][f"A{k}"].number_format = "0.00%"
    wb.save(p)
    got = read_csv_columns(p, REQ, numeric=REQ)
    np.testing.assert_array_equal(got["strain"], fractions)
