"""read_csv_columns on lab files as a test machine or Excel writes them, typed by hand here.

Each file below imitates a lab practice named in its test; none is produced by knitsim.
Expected values are the numbers typed into the files: a file with a units row, a preamble,
comments, capitalised headers or UTF-16 text reads as the same numbers as its plain twin,
and what is wrong is refused naming the file, its own line number, the column and the value.
"""
from __future__ import annotations

import codecs
import re

import numpy as np
import pytest

from knitsim.errors import KnitsimInputError
from knitsim.io.table_input import read_csv_columns

REQ = ("strain", "force_per_wale_N")
OPT = ("direction", "cycle", "rate_mm_s")
NUM = ("strain", "force_per_wale_N", "cycle", "rate_mm_s")

# the plain twin: header, then four rows typed by hand (a load cell reading -0.002 N at rest)
PLAIN = ("strain,force_per_wale_N,direction,cycle\n"
         "0.0,-0.002,load,1\n"
         "0.1,0.053,load,1\n"
         "0.2,0.098,load,1\n"
         "0.1,0.018,unload,1\n")


def _write(tmp_path, text: str, name="m.csv", encoding="utf-8"):
    p = tmp_path / name
    p.write_bytes(text.encode(encoding))
    return p


def _read(path):
    return read_csv_columns(path, REQ, OPT, numeric=NUM)


def _same_values(a, b):
    assert set(a) == set(b)
    for k in a:
        if k != "_row":
            np.testing.assert_array_equal(a[k], b[k])


@pytest.fixture
def plain(tmp_path):
    return _read(_write(tmp_path, PLAIN, "plain.csv"))


def test_the_plain_twin_reads_as_typed(plain):
    np.testing.assert_array_equal(plain["strain"], [0.0, 0.1, 0.2, 0.1])
    np.testing.assert_array_equal(plain["force_per_wale_N"], [-0.002, 0.053, 0.098, 0.018])
    assert list(plain["direction"]) == ["load", "load", "load", "unload"]
    assert list(plain["_row"]) == [2, 3, 4, 5]


@pytest.mark.parametrize("units", [
    "-,N,-,-",                       # a test machine's units line
    "[-],[N],(-),",                  # bracketed units, an empty cell
    "mm/mm,N,,",                     # a strain as mm/mm, empty cells mixed in
    '"(-)","[N]","",""',             # quoted by Excel
    "-,,-,-",                        # no unit under the force: its name's (force_per_wale_N) holds
    "mm/mm",                         # the row ends after its first unit (an export drops trailing empty cells)
])
def test_a_units_row_under_the_header_is_skipped(tmp_path, plain, units):
    # Lab practice: exports from tensile testers write the units on the line under the names (each the
    # unit of its column: another one is refused, test_a_units_row_is_read_and_a_unit_that_is_not_...)
    lines = PLAIN.split("\n")
    lines.insert(1, units)
    cols = _read(_write(tmp_path, "\n".join(lines)))
    _same_values(cols, plain)
    assert list(cols["_row"]) == [3, 4, 5, 6]       # the file's own line numbers


def test_a_units_row_on_a_semicolon_decimal_comma_file(tmp_path, plain):
    # Lab practice: a German-locale Excel export, units row, decimal commas.
    text = ("strain;force_per_wale_N;direction;cycle\r\n"
            "-;N;-;-\r\n"
            "0,0;-0,002;load;1\r\n0,1;0,053;load;1\r\n0,2;0,098;load;1\r\n0,1;0,018;unload;1\r\n")
    _same_values(_read(_write(tmp_path, text)), plain)


def test_quoted_decimal_commas_in_a_comma_file_read_as_the_plain_twin(tmp_path, plain):
    # Lab practice: LibreOffice / Google Sheets in a German locale, saved as comma-separated: every number
    # with a decimal comma is quoted.  "0,053" reads only as 0.053 (no thousands separator follows a 0),
    # so the file's commas are decimal commas; the first row is data, not a units row.
    text = ('strain,force_per_wale_N,direction,cycle\n'
            '"0,0","-0,002",load,1\n"0,1","0,053",load,1\n"0,2","0,098",load,1\n"0,1","0,018",unload,1\n')
    cols = _read(_write(tmp_path, text))
    _same_values(cols, plain)
    assert list(cols["_row"]) == [2, 3, 4, 5]


def test_comma_numbers_that_read_two_ways_are_refused_naming_both_readings(tmp_path):
    # "1,250" is 1.25 with a decimal comma and 1250 with a thousands separator; a file where every comma
    # number reads both ways cannot be read without guessing
    text = 'strain,force_per_wale_N\n0.1,"1,250"\n0.2,"2,500"\n'
    with pytest.raises(KnitsimInputError, match=r"row 2, column force_per_wale_N: '1,250'.*1\.25.*1250"):
        read_csv_columns(_write(tmp_path, text), REQ)


@pytest.mark.parametrize("text", [
    'strain,force_per_wale_N\n0.1,"1,234.5"\n0.2,"2,000.25"\n',      # en-US formatted values, quoted
    "strain;force_per_wale_N\n0,1;1.234,5\n0,2;2.000,25\n",           # German formatted values
    # French Excel's formatted values: thousands grouped by a no-break space (older) or a narrow no-break space
    # (Windows 10+), a decimal comma; before, refused as "'1\xa0234,5' is not a number"
    "strain;force_per_wale_N\n0,1;1\u00a0234,5\n0,2;2\u00a0000,25\n",
    "strain;force_per_wale_N\n0,1;1\u202f234,5\n0,2;2\u202f000,25\n",
    "strain\tforce_per_wale_N\n0,1\t1 234,5\n0,2\t2 000,25\n",         # a plain space, tab-separated
    'strain,force_per_wale_N\n0.1,"1 234,5"\n0.2,"2 000,25"\n',          # LibreOffice fr, comma-separated
    "strain,force_per_wale_N\n0.1,1'234.5\n0.2,2\u2019000.25\n",         # Swiss: an apostrophe, a decimal point
])
def test_thousands_separators_with_a_decimal_mark_are_read(tmp_path, text):
    cols = read_csv_columns(_write(tmp_path, text), REQ)
    np.testing.assert_array_equal(cols["force_per_wale_N"], [1234.5, 2000.25])
    np.testing.assert_array_equal(cols["strain"], [0.1, 0.2])


@pytest.mark.parametrize("cell", ["0 125", "1 23", "1 234 56", "1 234\u00a0567"])
def test_a_space_that_groups_no_thousands_is_not_read_as_one(tmp_path, cell):
    # (a leading 0, a group of two digits, or two different separators group no thousands: refused as text)
    with pytest.raises(KnitsimInputError, match="row 3, column force_per_wale_N"):
        read_csv_columns(_write(tmp_path, f"strain;force_per_wale_N\n0,1;0,5\n0,2;{cell}\n"), REQ)


def test_a_units_row_with_a_number_in_it_is_data_and_refused(tmp_path):
    # Lab practice gone wrong: a units line with "1" for a dimensionless column is not skipped,
    # its text cell is then refused like any text in a number column, with its line number.
    lines = PLAIN.split("\n")
    lines.insert(1, "1,N,-,-")
    p = _write(tmp_path, "\n".join(lines))
    with pytest.raises(KnitsimInputError) as e:
        _read(p)
    msg = str(e.value)
    assert str(p) in msg and "row 2, column force_per_wale_N: 'N' is not a number" in msg


def test_text_further_down_is_refused_with_its_real_line_number(tmp_path):
    # Lab practice gone wrong: an operator typed "n/a" into a force cell of the 3rd data row;
    # a units row, a comment and a blank line come before it, and the line number stays the file's.
    text = ("# exported 2026-03-01\n"
            "strain,force_per_wale_N,direction,cycle\n"
            "-,N,-,-\n"
            "0.0,-0.002,load,1\n"
            "\n"
            "0.1,0.053,load,1\n"
            "0.2,n/a,load,1\n")
    p = _write(tmp_path, text)
    with pytest.raises(KnitsimInputError) as e:
        _read(p)
    assert f"{p}: row 7, column force_per_wale_N: 'n/a' is not a number" in str(e.value)


def test_a_second_text_row_after_a_units_row_is_refused(tmp_path):
    # Only the first data row may be units: a second line of text is refused.
    lines = PLAIN.split("\n")
    lines[1:1] = ["-,N,-,-", "mm,kN,-,-"]
    p = _write(tmp_path, "\n".join(lines))
    with pytest.raises(KnitsimInputError, match=r"row 3, column strain: 'mm' is not a number"):
        _read(p)


def test_comments_and_a_two_line_preamble_are_skipped(tmp_path, plain):
    # Lab practice: a test machine writes specimen and date above the table (with ; and :),
    # and the analyst adds # comments, some of them between the rows.
    text = ("Specimen: A3; operator: JB\n"
            "Test date;2026-03-01\n"
            "# Prüfung µm, 20 °C\n"
            "strain,force_per_wale_N,direction,cycle\n"
            "0.0,-0.002,load,1\n"
            "# the extensometer was re-clipped here\n"
            "0.1,0.053,load,1\n"
            "0.2,0.098,load,1\n"
            "0.1,0.018,unload,1\n"
            "# end of test\n")
    for enc in ("utf-8", "cp1252"):
        cols = _read(_write(tmp_path, text, encoding=enc))
        _same_values(cols, plain)
        assert list(cols["_row"]) == [5, 7, 8, 9]


def test_preamble_comment_and_units_row_together(tmp_path, plain):
    # Lab practice: an Excel sheet with a title line, a comment, the names, then the units.
    text = ('"Knit tensile test, wale direction";;;\n'
            "# analyst JB\n"
            '"Strain";"Force_per_wale_N";"Direction";"Cycle"\n'
            '"[-]";"[N]";"";""\n'
            "0;-0,002;load;1\n0,1;0,053;load;1\n0,2;0,098;load;1\n0,1;0,018;unload;1\n")
    cols = _read(_write(tmp_path, text))
    _same_values(cols, plain)
    assert list(cols["_row"]) == [5, 6, 7, 8]


def test_capitalised_and_padded_headers_are_read_under_the_names_asked_for(tmp_path, plain):
    # Lab practice: a spreadsheet user capitalises the names and leaves spaces around them.
    text = PLAIN.replace("strain,force_per_wale_N,direction,cycle",
                         'Strain, FORCE_PER_WALE_N ," Direction ",CYCLE')
    cols = _read(_write(tmp_path, text))
    _same_values(cols, plain)                        # keys: strain, force_per_wale_N, direction, cycle


def test_a_column_named_hash_is_a_header_not_a_comment(tmp_path):
    # Lab practice: a test machine numbers its samples in a first column named "#".
    text = "#,strain,force_per_wale_N\n1,0.0,-0.002\n2,0.1,0.053\n"
    cols = read_csv_columns(_write(tmp_path, text), REQ)
    np.testing.assert_array_equal(cols["force_per_wale_N"], [-0.002, 0.053])


@pytest.mark.parametrize("bom, enc", [(codecs.BOM_UTF16_LE, "utf-16-le"), (codecs.BOM_UTF16_BE, "utf-16-be"),
                                     (b"", "utf-16-le"), (b"", "utf-16-be")])
def test_utf16_unicode_text_is_read_as_its_utf8_twin(tmp_path, plain, bom, enc):
    # Lab practice: Excel's "Unicode Text" export: UTF-16 LE with a byte-order mark, tab-separated,
    # CRLF line ends (BE tested too), with a non-ASCII comment and a units row; also without the mark
    # (a machine's UTF-16 export, or the mark lost in a copy), both byte orders.
    text = ("# Prüfung µm\r\n"
            "strain\tforce_per_wale_N\tdirection\tcycle\r\n"
            "-\tN\t-\t-\r\n"
            "0,0\t-0,002\tload\t1\r\n0,1\t0,053\tload\t1\r\n0,2\t0,098\tload\t1\r\n0,1\t0,018\tunload\t1\r\n")
    p16 = tmp_path / "unicode.txt"
    p16.write_bytes(bom + text.encode(enc))
    assert p16.read_bytes()[:2] == (bom or text.encode(enc)[:2])
    p8 = _write(tmp_path, text, "utf8.txt")
    c16, c8 = _read(p16), _read(p8)
    _same_values(c16, c8)
    np.testing.assert_array_equal(c16["_row"], c8["_row"])
    _same_values(c16, plain)


def test_utf16_text_in_a_number_cell_is_refused_with_the_row(tmp_path):
    text = "strain\tforce_per_wale_N\r\n0\t0,1\r\n0,1\tx\r\n"
    p = tmp_path / "u.txt"
    p.write_bytes(codecs.BOM_UTF16_LE + text.encode("utf-16-le"))
    with pytest.raises(KnitsimInputError, match=r"row 3, column force_per_wale_N: 'x' is not a number"):
        read_csv_columns(p, REQ)


def test_a_file_without_the_columns_is_refused_listing_what_was_found(tmp_path):
    # Lab practice gone wrong: the export named the columns otherwise; the comment line is not listed.
    text = "# exported by the machine\nDehnung;Kraft\n0,0;0,1\n"
    p = _write(tmp_path, text)
    with pytest.raises(KnitsimInputError) as e:
        _read(p)
    assert str(e.value) == (f"{p}: missing column(s) strain, force_per_wale_N (found: Dehnung, Kraft; "
                            "read as semicolon-separated)")


def test_a_preamble_without_the_columns_lists_the_line_naming_most_of_them(tmp_path):
    # No line holds both names: the line naming most of them is read as the header and listed (a blind probe's
    # Bluehill export was refused as having found its preamble's first line); with none named, the line of the most
    # labels above the data (a probe's German export, below, was refused as having found "Test report, , , ")
    text = "Specimen: A3\nstrain,force\n0,0.1\n"
    p = _write(tmp_path, text)
    with pytest.raises(KnitsimInputError, match=r"missing column\(s\) force_per_wale_N \(found: strain, force; "
                                                r"read as comma-separated\)"):
        read_csv_columns(p, REQ)
    p = _write(tmp_path, "Specimen: A3\neps,F\n0,0.1\n", "none.csv")
    with pytest.raises(KnitsimInputError, match=r"missing column\(s\) strain, force_per_wale_N \(found: eps, F; "):
        read_csv_columns(p, REQ)
    # hand-made: a title, a specimen and a date line, a blank line, the header in German, a units row, two rows
    text = ("Test report;;\r\nSpecimen;E-glass A3;\r\nDate;29.11.2026;\r\n;;\r\nZeit;Dehnung;Standardkraft\r\n"
            "s;%;N\r\n0,0;0,0;0,01\r\n0,5;1,0;0,07\r\n")
    p = _write(tmp_path, text, "de.csv")
    with pytest.raises(KnitsimInputError, match=r"missing column\(s\) strain, force_per_wale_N \(found: Zeit, Dehnung, "
                                                r"Standardkraft; read as semicolon-separated\)"):
        read_csv_columns(p, REQ)
    # a file of numbers only: no line of labels above them, the first line is listed
    p = _write(tmp_path, "0,0.1\n1,0.2\n", "bare.csv")
    with pytest.raises(KnitsimInputError, match=r"\(found: 0, 0.1; read as comma-separated\)"):
        read_csv_columns(p, REQ)


def test_only_optional_columns_find_the_header_below_a_preamble(tmp_path):
    # The specimen reader asks for no required column, only optional ones: the header is then
    # the first line holding one of them.
    text = "Specimen: A3\nTest date;2026-03-01\nstrain,force_N\n-,N\n0.0,0.0\n0.1,2.5\n"
    cols = read_csv_columns(_write(tmp_path, text), (), ("strain", "force_N", "force_per_wale_N"))
    assert set(cols) == {"strain", "force_N", "_row"}
    np.testing.assert_array_equal(cols["force_N"], [0.0, 2.5])
    assert list(cols["_row"]) == [5, 6]


def test_only_comments_or_only_a_units_row(tmp_path):
    with pytest.raises(KnitsimInputError, match=r"the file is empty"):
        _read(_write(tmp_path, "\n\n \n", "blank.csv"))
    with pytest.raises(KnitsimInputError, match=r"no header line"):
        _read(_write(tmp_path, "# nothing\n# here\n", "comments.csv"))
    with pytest.raises(KnitsimInputError, match=r"no data rows"):
        _read(_write(tmp_path, "strain,force_per_wale_N\n-,N\n", "units.csv"))


def test_a_nan_or_empty_cell_is_still_refused(tmp_path):
    with pytest.raises(KnitsimInputError, match=r"row 3, column strain: 'nan' is not finite"):
        read_csv_columns(_write(tmp_path, "strain,force_per_wale_N\n0,0\nnan,0.1\n"), REQ)
    with pytest.raises(KnitsimInputError, match=r"row 2, column force_per_wale_N: '' is not a number"):
        read_csv_columns(_write(tmp_path, "strain,force_per_wale_N\n0,\n0.1,0.1\n", "e.csv"), REQ)


@pytest.mark.parametrize("error", ["#DIV/0!", "#N/A", "#VALUE!", "#NAME?"])
@pytest.mark.parametrize("delim", [",", ";", "\t"])
def test_a_spreadsheet_error_in_the_first_cell_is_a_data_row_refused(tmp_path, error, delim):
    # Lab practice gone wrong: a strain computed in Excel (=B4/C4) over an empty cell exports as
    # #DIV/0! in the first column. It is a data row (refused with its row), not a "# comment" that
    # would drop the row without a word; a real comment above it is still skipped.
    text = "\n".join(delim.join(r) for r in [["# exported 2026-03-01"], ["strain", "force_per_wale_N"],
                                               ["0.0", "0.01"], [error, "0.05"], ["0.2", "0.1"]]) + "\n"
    p = _write(tmp_path, text)
    with pytest.raises(KnitsimInputError) as e:
        read_csv_columns(p, REQ)
    assert f"{p}: row 4, column strain: {error!r} is not a number" in str(e.value)


def test_units_after_the_header_names_are_read_when_they_are_the_names_units(tmp_path, plain):
    # Lab practice: a test machine writes the unit after each column name, "strain [-]", "(N)". The file
    # reads as its plain twin; a unit that is not the one the name implies (a force in per cent, kN) is
    # refused naming the header cell (row 1), never read as if it were (a strain in per cent is read:
    # test_a_strain_in_per_cent_reads_as_its_fraction_twin_and_says_so).
    text = PLAIN.replace("strain,force_per_wale_N,direction,cycle",
                         "Strain [-],force_per_wale_N (N),direction,cycle [ - ]")
    _same_values(_read(_write(tmp_path, text, "units.csv")), plain)
    for header, unit in (("strain,force_per_wale_N [%]", "'%'"), ("strain,force_per_wale_N [kN]", "'kN'")):
        p = _write(tmp_path, header + "\n0,0\n1,0.1\n2,0.2\n3,0.3\n", "bad_unit.csv")
        with pytest.raises(KnitsimInputError) as e:
            read_csv_columns(p, REQ)
        assert f"{p}: row 1, column" in str(e.value) and f"the unit {unit} is not that of" in str(e.value)


def test_has_columns_finds_the_header_as_the_reader_does(tmp_path):
    # a test machine's export: UTF-8 BOM, a comment, a preamble line, capitalised names, ';' and
    # decimal commas: the x_mm / F_N pair is found, the KES pair is not (knitsim dahl fit chooses by it)
    from knitsim.io.table_input import has_columns
    p = tmp_path / "loop.csv"
    p.write_bytes("\ufeff# KES bending, specimen 3\nOperator;JB\nX_MM;F_N\n-1,0;-0,5\n1,0;0,5\n".encode("utf-8"))
    assert has_columns(p, ["x_mm", "F_N"])
    assert not has_columns(p, ["kappa_1_mm", "M_N_mm_per_mm"])


def test_dahl_fit_picks_the_x_f_columns_of_such_a_file(tmp_path):
    from pathlib import Path

    from knitsim.cli.dahl import _choose_columns
    p = tmp_path / "loop.csv"
    p.write_text("# pull-out loop\nX_mm,F_N\n0,0\n")
    assert _choose_columns(Path(p), None) == ("x_mm", "F_N")


@pytest.mark.parametrize("units, column, unit", [("-,%", "force_per_wale_N", "%"), ("-,kN", "force_per_wale_N", "kN"),
                                                  ("[-],[mN]", "force_per_wale_N", "mN"), ("mm,N", "strain", "mm")])
def test_a_units_row_is_read_and_a_unit_that_is_not_the_columns_refused(tmp_path, units, column, unit):
    # a blind probe's units rows were skipped unread: "%" read as a fraction (100 x), "kN" as N (1000 x),
    # an extension in mm as a strain (a strain in per cent is now read divided by 100, below; a force in per
    # cent is refused)
    p = tmp_path / "u.csv"
    p.write_text(f"strain,force_per_wale_N\n{units}\n0.0,0.0\n0.1,0.05\n0.2,0.1\n")
    with pytest.raises(KnitsimInputError) as e:
        read_csv_columns(p, ["strain", "force_per_wale_N"])
    assert f"row 2, column '{column}': the unit '{unit}' is not that of {column}" in str(e.value)


@pytest.mark.parametrize("units", ["-,N", "mm/mm,N", "[-],(N)", ",N", "m/m;N"])
def test_a_units_row_of_the_columns_units_is_skipped(tmp_path, units):
    p = tmp_path / "u.csv"
    sep = ";" if ";" in units else ","
    p.write_text(f"strain{sep}force_per_wale_N\n{units}\n0.0{sep}0.0\n0.1{sep}0.05\n")
    out = read_csv_columns(p, ["strain", "force_per_wale_N"])
    np.testing.assert_array_equal(out["strain"], [0.0, 0.1])
    np.testing.assert_array_equal(out["_row"], [3, 4])


def test_a_value_beyond_the_header_and_a_column_named_twice_are_refused(tmp_path):
    p = tmp_path / "long.csv"
    p.write_text("strain,force_per_wale_N\n0.0,0.0\n0.1,0.05,0.3\n0.2,0.1\n")
    with pytest.raises(KnitsimInputError, match=r"row 3, column 3: '0.3' lies beyond the header's 2 columns"):
        read_csv_columns(p, ["strain", "force_per_wale_N"])
    # trailing empty cells (a spreadsheet's export) are no values
    p.write_text("strain,force_per_wale_N\n0.0,0.0,,\n0.1,0.05,,\n")
    assert len(read_csv_columns(p, ["strain", "force_per_wale_N"])["strain"]) == 2
    p.write_text("strain,force_per_wale_N,force_per_wale_N\n0.0,0.0,0.0\n0.1,0.05,0.1\n")
    with pytest.raises(KnitsimInputError, match=r"columns 2 and 3 are both named 'force_per_wale_N'"):
        read_csv_columns(p, ["strain", "force_per_wale_N"])


def test_a_column_asked_for_with_its_unit_matches_the_header_with_that_unit(tmp_path):
    # a blind probe's `dahl fit --columns "x [mm],F [N]"` on a file headed `x [mm];F [N]` was told the columns
    # it named were missing ("found: x [mm], F [N]"); a header in another unit is refused naming both
    p = tmp_path / "xf.csv"
    p.write_bytes("\ufeffx [mm];F [N]\r\n0,0;0,0\r\n0,5;0,25\r\n".encode())
    out = read_csv_columns(p, ["x [mm]", "F [N]"])
    np.testing.assert_array_equal(out["x [mm]"], [0.0, 0.5])
    np.testing.assert_array_equal(out["F [N]"], [0.0, 0.25])
    p.write_text("x [cm];F [N]\n0,0;0,0\n0,5;0,25\n")
    with pytest.raises(KnitsimInputError, match=r"column 'x \[cm\]': the unit 'cm' is not that of x \[mm\]"):
        read_csv_columns(p, ["x [mm]", "F [N]"])


# a strain in per cent, stated: the twin of FRACTION_ROWS with each strain written x 100 (typed by hand: 0.0512
# is 5.12 %, 0.1234 is 12.34 %); the expected strains are the fractions typed in FRACTION_ROWS
FRACTION_ROWS = [("0.0", "-0.002"), ("0.0512", "0.031"), ("0.1234", "0.062"), ("0.2", "0.098"), ("0.1", "0.018")]
PER_CENT_ROWS = [("0.0", "-0.002"), ("5.12", "0.031"), ("12.34", "0.062"), ("20", "0.098"), ("10.0", "0.018")]


def _table(header, rows, units=None, sep=",", dec=".", eol="\n"):
    lines = [sep.join(header)] + ([sep.join(units)] if units else [])
    lines += [sep.join(c.replace(".", dec) for c in row) for row in rows]
    return eol.join(lines) + eol


@pytest.mark.parametrize("header, units, note", [
    (["Strain [%]", "force_per_wale_N"], None, "strain column 'Strain [%]' read in per cent (divided by 100)"),
    (["strain (%)", "force_per_wale_N (N)"], None, "strain column 'strain (%)' read in per cent"),
    (["strain %", "force_per_wale_N"], None, "strain column 'strain %' read in per cent"),
    (["strain [percent]", "force_per_wale_N"], None, "strain column 'strain [percent]' read in per cent"),
    (["Strain", "force_per_wale_N"], ["%", "N"], "strain column 'Strain' (units row 2: '%') read in per cent"),
    (["Strain", "force_per_wale_N"], ["[%]", "[N]"], "strain column 'Strain' (units row 2: '%') read in per cent"),
    (["Strain", "force_per_wale_N"], ["PCT", "N"], "strain column 'Strain' (units row 2: 'PCT') read in per cent"),
    (["Strain [%]", "force_per_wale_N"], ["%", "N"], "strain column 'Strain [%]' read in per cent"),
    (["Strain [%]", "force_per_wale_N"], ["", "N"], "strain column 'Strain [%]' read in per cent"),
])
def test_a_strain_in_per_cent_reads_as_its_fraction_twin_and_says_so(tmp_path, header, units, note):
    # A lab's export states its strain in per cent, in the header cell or in a units row: the column is read
    # divided by 100 (before, it was refused) and the reader says so in the returned columns' notes.
    # Expected: the same file written with fractions (FRACTION_ROWS), to 1e-15 relative.
    frac = read_csv_columns(_write(tmp_path, _table(["strain", "force_per_wale_N"], FRACTION_ROWS), "f.csv"), REQ)
    pct = read_csv_columns(_write(tmp_path, _table(header, PER_CENT_ROWS, units), "p.csv"), REQ)
    np.testing.assert_allclose(pct["strain"], frac["strain"], rtol=1e-15, atol=0)
    np.testing.assert_array_equal(pct["force_per_wale_N"], frac["force_per_wale_N"])   # the force is not scaled
    np.testing.assert_array_equal(pct["_row"], frac["_row"] + (1 if units else 0))
    assert len(pct.notes) == 1 and pct.notes[0].startswith(note), pct.notes
    assert frac.notes == ()
    assert set(pct) == {"strain", "force_per_wale_N", "_row"}     # the note is not a column


def test_an_excel_per_cent_file_reads_as_its_fraction_twin(tmp_path):
    # Excel in a decimal-comma locale: UTF-8 BOM, ';', decimal commas, CRLF, a preamble, a units row with '%';
    # expected: the comma-separated fraction twin (FRACTION_ROWS), to 1e-15 relative
    frac = read_csv_columns(_write(tmp_path, _table(["strain", "force_per_wale_N"], FRACTION_ROWS), "f.csv"), REQ)
    text = _table(["Strain [%]", "force_per_wale_N", "cycle"], [r + ("1",) for r in PER_CENT_ROWS],
                  units=["%", "N", "-"], sep=";", dec=",", eol="\r\n")
    p = _write(tmp_path, "\ufeffSpecimen: EG-3;Operator: JB;\r\n" + text, "excel.csv")
    assert p.read_bytes().startswith(codecs.BOM_UTF8) and b"5,12;0,031;1\r\n" in p.read_bytes()
    pct = read_csv_columns(p, REQ, ("cycle",))
    np.testing.assert_allclose(pct["strain"], frac["strain"], rtol=1e-15, atol=0)
    np.testing.assert_array_equal(pct["force_per_wale_N"], frac["force_per_wale_N"])
    np.testing.assert_array_equal(pct["cycle"], np.ones(5))                     # a dimensionless "-": not scaled
    assert pct.notes == ("strain column 'Strain [%]' read in per cent (divided by 100)",)


def test_the_note_survives_drop_copied_rows_and_reaches_the_curve_and_the_table(tmp_path):
    # a row copied (row 4 = row 3) is dropped; the note is kept.  MeasuredCurve (knitsim diagnose) and
    # MeasuredTable (knitsim calibrate) carry it; their strains are the fraction twin's
    from knitsim.calibration.specimen import read_table
    from knitsim.diagnosis.measured import drop_copied_rows
    rows = PER_CENT_ROWS[:3] + PER_CENT_ROWS[2:3] + PER_CENT_ROWS[3:4]
    p = _write(tmp_path, _table(["strain [%]", "force_per_wale_N"], rows))
    cols = drop_copied_rows(read_csv_columns(p, REQ))
    assert list(cols["_row"]) == [2, 3, 4, 6]
    # and a note names the copy left out (line 5 of the file)
    assert cols.notes == ("strain column 'strain [%]' read in per cent (divided by 100)",
                          "1 row(s) that repeat the row above in every column left out as copies (row(s) 5)")
    total = _write(tmp_path, _table(["Strain [%]", "load_N"], PER_CENT_ROWS[:4]), "total.csv")
    t = read_table(total)
    np.testing.assert_allclose(t.strain, [0.0, 0.0512, 0.1234, 0.2], rtol=1e-15, atol=0)
    assert t.notes == ("strain column 'Strain [%]' read in per cent (divided by 100)",)
    assert read_table(_write(tmp_path, _table(["strain", "load_N"], FRACTION_ROWS[:4]), "frac.csv")).notes == ()


@pytest.mark.parametrize("header, units, match", [
    # a force in per cent (of what?) is not a force: refused as any other unit
    (["strain", "force_per_wale_N [%]"], None, r"row 1, column 'force_per_wale_N \[%\]': the unit '%' is not that "
                                               r"of force_per_wale_N"),
    (["strain", "force_per_wale_N"], ["-", "%"], r"row 2, column 'force_per_wale_N': the unit '%' is not that of "
                                                 r"force_per_wale_N"),
    # an unknown unit on the strain stays refused
    (["strain [permille]", "force_per_wale_N"], None, r"row 1, column 'strain \[permille\]': the unit 'permille' "
                                                      r"is not that of strain"),
    (["strain", "force_per_wale_N"], ["mm", "N"], r"row 2, column 'strain': the unit 'mm' is not that of strain"),
    # a header cell and a units row that disagree: which one is meant is not said
    (["strain [-]", "force_per_wale_N"], ["%", "N"], r"row 2, column 'strain \[-\]': the units row says '%' and "
                                                     r"the header cell '-'"),
    (["strain [%]", "force_per_wale_N"], ["mm/mm", "N"], r"row 2, column 'strain \[%\]': the units row says "
                                                         r"'mm/mm' and the header cell '%'"),
])
def test_a_force_in_per_cent_and_an_unknown_strain_unit_are_still_refused(tmp_path, header, units, match):
    p = _write(tmp_path, _table(header, PER_CENT_ROWS, units))
    with pytest.raises(KnitsimInputError, match=match):
        read_csv_columns(p, REQ)


def test_every_bad_cell_is_named_at_once_in_row_order(tmp_path):
    """Hand-made: an empty force cell (file row 4), a NaN (row 5) and an empty strain cell (row 8).  Expected:
    one refusal naming all three, by row (a blind probe met them one run at a time, the strain column's
    first); one bad cell keeps its single message; beyond BAD_CELLS_LISTED the rest are counted."""
    from knitsim.io.table_input import BAD_CELLS_LISTED
    rows = ["strain,force_per_wale_N", "0.0,0.0", "0.1,0.1", "0.2,", "0.3,NaN", "0.4,0.4", "0.5,0.5", ",0.6"]
    p = _write(tmp_path, "\n".join(rows) + "\n")
    with pytest.raises(KnitsimInputError) as e:
        read_csv_columns(p, ["strain", "force_per_wale_N"])
    msg = str(e.value)
    assert msg.index("row 4, column force_per_wale_N: '' is not a number") < msg.index("row 5, column "
                                                                                        "force_per_wale_N: 'NaN'")
    assert msg.index("row 5,") < msg.index("row 8, column strain: '' is not a number") and "fix or delete the rows" in msg
    many = ["strain,force_per_wale_N"] + [f"{0.01 * i},x" for i in range(BAD_CELLS_LISTED + 3)]
    with pytest.raises(KnitsimInputError, match=r"and 3 more \(fix or delete the rows\)"):
        read_csv_columns(_write(tmp_path, "\n".join(many) + "\n", name="many.csv"), ["strain", "force_per_wale_N"])
    one = ["strain,force_per_wale_N", "0.0,0.0", "0.1,abc", "0.2,0.2"]
    with pytest.raises(KnitsimInputError, match=r"row 3, column force_per_wale_N: 'abc' is not a number \(fix or "
                                                r"delete the row\)$"):
        read_csv_columns(_write(tmp_path, "\n".join(one) + "\n", name="one.csv"), ["strain", "force_per_wale_N"])


def test_fractions_under_a_per_cent_header_are_read_in_per_cent_and_said_to_look_like_fractions(tmp_path):
    # FRACTION_ROWS (strain to 0.2) under a "Strain [%]" header: the header is followed (divided by 100: the
    # strain ends at 0.002, exactly), and the note adds that every value lies within 2 % (a knit is tested to
    # tens of per cent) and how to state fractions.  PER_CENT_ROWS (to 20 %) under it get the plain note.
    pct = read_csv_columns(_write(tmp_path, _table(["Strain [%]", "force_per_wale_N"], FRACTION_ROWS)), REQ)
    assert pct["strain"].max() == 0.002
    assert pct.notes == ("strain column 'Strain [%]' read in per cent (divided by 100); its largest value is "
                         "0.2 %: if the column holds fractions (0.6 for 60 %), state its unit as [-], or none",)
    plain = read_csv_columns(_write(tmp_path, _table(["Strain [%]", "force_per_wale_N"], PER_CENT_ROWS), "p.csv"), REQ)
    assert plain.notes == ("strain column 'Strain [%]' read in per cent (divided by 100)",)


def test_a_test_machines_names_with_their_units_read_as_the_columns_and_say_so(tmp_path):
    # An Instron Bluehill-like export (hand-made): a preamble, "Load (N)" and "Tensile strain (%)" beside columns
    # not read.  Expected: the twin file with the package's names (strain as fractions, load_N), exactly, and a
    # note for each column read under another name; with LAB_ALIASES only (without them: no column found).
    from knitsim.io.table_input import LAB_ALIASES
    text = ("Sample: knit A3\n"
            "Time (s),Extension (mm),Load (N),Tensile strain (%)\n"
            "0.0,0.000,-0.004,0.00\n1.0,0.135,0.812,2.50\n2.0,0.270,1.634,5.00\n")
    twin = "strain,load_N\n0.0,-0.004\n0.025,0.812\n0.05,1.634\n"
    names = ("strain", "strain_mm_per_mm", "load_N", "force_N")
    lab = read_csv_columns(_write(tmp_path, text, "lab.csv"), (), names, aliases=LAB_ALIASES)
    ref = read_csv_columns(_write(tmp_path, twin, "ref.csv"), (), names)
    np.testing.assert_allclose(lab["strain"], ref["strain"], rtol=1e-15, atol=0)
    np.testing.assert_array_equal(lab["load_N"], ref["load_N"])
    assert set(lab) == {"strain", "load_N", "_row"}
    assert lab.notes == ("column 'Load (N)' read as load_N", "column 'Tensile strain (%)' read as strain",
                         "strain column 'Tensile strain (%)' read in per cent (divided by 100)")
    with pytest.raises(KnitsimInputError, match="missing column"):
        read_csv_columns(_write(tmp_path, text, "lab.csv"), ("strain",), names)     # no aliases given
    # another unit, or none, is not taken; a required column's refusal says why and how to state it
    for header, why in (("Load (kN),Tensile strain (%)", "'Load (kN)' is not read as load_N: 'kN' is not its unit "
                                                         "(convert the column: 'Load (N)')"),
                        ("Load,Tensile strain (%)", "'Load' is read as load_N with its unit stated ('Load (N)')")):
        p = _write(tmp_path, header + "\n0,0\n1,2.5\n", "bad.csv")
        assert "load_N" not in read_csv_columns(p, (), names, aliases=LAB_ALIASES)
        with pytest.raises(KnitsimInputError) as e:
            read_csv_columns(p, ("load_N",), names, aliases=LAB_ALIASES)
        assert why in str(e.value), str(e.value)
    # the package's own name wins over a machine's (no column is read twice)
    both = read_csv_columns(_write(tmp_path, "strain,Tensile strain (%),load_N\n0.1,5,1\n0.2,10,2\n", "both.csv"),
                            (), names, aliases=LAB_ALIASES)
    np.testing.assert_array_equal(both["strain"], [0.1, 0.2])
    assert both.notes == ()


def test_a_machines_names_twice_a_units_row_and_a_preamble(tmp_path):
    # Found by a blind probe (hand-made files).  Expected, from the reading rules (module docstring): a column
    # named twice is refused, also when two of a machine's names would both be it; a machine's unit in a units row
    # under its header (Bluehill's raw data) is its stated unit; a preamble above a header whose machine name lacks
    # its unit still finds that header, and the refusal says what to state.
    from knitsim.io.table_input import LAB_ALIASES
    names = ("strain", "load_N", "force_N")
    for header in ("Load (N),Load (N),Tensile strain (%)", "Load (N),Tensile load (N),Tensile strain (%)"):
        p = _write(tmp_path, header + "\n0,0,0\n0.5,1,2.5\n", "dup.csv")
        with pytest.raises(KnitsimInputError, match=r"columns 1 and 2 \(.*\) would both be read as load_N"):
            read_csv_columns(p, (), names, aliases=LAB_ALIASES)
    raw = _write(tmp_path, '"Time","Load","Tensile strain"\n"(s)","(N)","(%)"\n0,0,0\n1,0.5,2.5\n2,1.0,5.0\n', "raw.csv")
    c = read_csv_columns(raw, (), names, aliases=LAB_ALIASES)
    np.testing.assert_allclose(c["strain"], [0.0, 0.025, 0.05], rtol=1e-15)
    np.testing.assert_array_equal(c["load_N"], [0.0, 0.5, 1.0])
    assert "column 'Load' read as load_N" in c.notes and "column 'Tensile strain' read as strain" in c.notes
    kn = _write(tmp_path, "Time;Load;Tensile strain\ns;kN;%\n0;0;0\n1;0,5;2,5\n", "kn.csv")
    c = read_csv_columns(kn, (), names, aliases=LAB_ALIASES)
    assert "load_N" not in c and c.not_read == ("'Load' is not read as load_N: 'kN' is not its unit (convert the "
                                                "column: 'Load (N)')",)
    pre = _write(tmp_path, "Machine: Instron 5965\nTensile strain,force_per_wale_N\n0,0\n1,2\n", "pre.csv")
    with pytest.raises(KnitsimInputError) as e:
        read_csv_columns(pre, ("strain", "force_per_wale_N"), aliases=LAB_ALIASES)
    assert "(found: Tensile strain, force_per_wale_N;" in str(e.value)
    assert "'Tensile strain' is read as strain with its unit stated ('Tensile strain (%)' or " in str(e.value)
    # fractions under a % stated in a units row: the advice is to change the units row
    fr = read_csv_columns(_write(tmp_path, "strain,force_per_wale_N\n%,N\n0,0\n0.3,1\n", "fr.csv"), REQ)
    assert fr.notes[0].endswith("state its unit in its units row as -"), fr.notes


def test_the_fractions_note_reaches_values_to_two_per_cent_and_not_beyond(tmp_path):
    # PER_CENT_LOOKS_FRACTION = 0.02 (a blind probe: 0..1.2 under "%", fractions of a knit at 120 %, got no note):
    # a largest value of 1.2 (read as 1.2 %) is said to look like fractions; 2.5 (2.5 %) is not.
    for top, said in ((1.2, True), (2.5, False)):
        p = _write(tmp_path, f"Strain [%],force_per_wale_N\n0,0\n{top / 2},1\n{top},2\n", f"t{top}.csv")
        note = read_csv_columns(p, REQ).notes[0]
        assert ("its largest value is" in note) == said, note


def test_a_machines_units_row_after_a_blank_line_is_its_stated_unit(tmp_path):
    # A review's case: the data rows skip blank lines before the units row, so the machine's unit is found there
    # too (before, only the line right under the header was looked at, and "state its unit" was asked).
    from knitsim.io.table_input import LAB_ALIASES
    p = _write(tmp_path, "Time,Load,Tensile strain\n\n(s),(N),(%)\n0,0,0\n1,0.5,2.5\n", "blank.csv")
    c = read_csv_columns(p, ("strain", "load_N"), aliases=LAB_ALIASES)
    np.testing.assert_allclose(c["strain"], [0.0, 0.025], rtol=1e-15)
    np.testing.assert_array_equal(c["load_N"], [0.0, 0.5])


def test_a_spreadsheet_footer_is_skipped_and_said_and_a_label_mid_file_is_not(tmp_path):
    """A blind probe's Excel export ended with a footer line (Max force;;8,55;;) and was refused as "row 166,
    column strain: '' is not a number".  Hand-made: a ';' file with decimal commas, 5 data rows and a footer
    starting with a label (Max force;0,55): the rows read, the footer skipped and said with its row.  The same line
    between data rows is no footer: refused, naming it."""
    body = "strain;force_per_wale_N\n" + "".join(f"0,{k}0;0,{k}5\n" for k in range(1, 6))
    p = tmp_path / "f.csv"
    p.write_text(body + "Max force;0,55\n")
    cols = read_csv_columns(p, ["strain", "force_per_wale_N"])
    assert len(cols["strain"]) == 5 and cols["force_per_wale_N"][-1] == pytest.approx(0.55)
    assert any("row 7 after the data read as a footer" in n and "'Max force'" in n for n in cols.notes)
    q = tmp_path / "g.csv"
    lines = body.splitlines()
    q.write_text("\n".join(lines[:3] + ["Max force;0,55"] + lines[3:]) + "\n")
    with pytest.raises(KnitsimInputError, match=r"row 4, column strain: 'Max force' is not a number"):
        read_csv_columns(q, ["strain", "force_per_wale_N"])


@pytest.mark.parametrize("first", ["#DIV/0!", "#N/A", "N/A", "-"])
def test_a_last_row_starting_with_an_error_value_is_refused_not_skipped_as_a_footer(tmp_path, first):
    """A probe's Excel export whose last row's strain was an error value ("#DIV/0!;0,85") read as a footer: the
    curve's last reading skipped (with a note), where the same row mid-file is refused.  Hand-made: 5 ';' rows
    with decimal commas, the last one's strain replaced by a spreadsheet's error value or a missing-value marker.
    Expected (the README: such a row "is a data row, refused with its row and column"): refused naming row 6."""
    rows = "".join(f"0,{k}0;0,{k}5\n" for k in range(1, 5))
    p = tmp_path / "e.csv"
    p.write_text("strain;force_per_wale_N\n" + rows + f"{first};0,55\n")
    with pytest.raises(KnitsimInputError, match=rf"row 6, column strain: '{re.escape(first)}' is not a number"):
        read_csv_columns(p, ["strain", "force_per_wale_N"])


def test_an_extension_in_mm_is_named_as_a_length_not_a_strain(tmp_path):
    """A probe's file with Extension [mm] in place of a strain was refused as missing a strain, with no word of
    what to do.  Expected: the refusal names the column and the conversion (strain = extension / gauge length)."""
    p = tmp_path / "e.csv"
    p.write_text("Extension [mm],force_per_wale_N\n0,0.1\n1,0.2\n2,0.3\n3,0.4\n")
    with pytest.raises(KnitsimInputError, match=r"'Extension \[mm\]' is a length, not a strain: write strain = "
                                                r"extension / gauge length"):
        read_csv_columns(p, ["strain", "force_per_wale_N"])


def test_an_extension_in_mm_is_named_where_the_strain_is_asked_for_as_optional(tmp_path):
    """calibrate asks for its strain as optional (strain or strain_mm_per_mm): a probe's file with Extension (mm)
    and Load (N) was refused as "no strain column" without the conversion diagnose names.  Expected: the hint in
    the columns' not_read, and so in calibrate's refusal."""
    from knitsim.calibration.specimen import read_table
    p = tmp_path / "e.csv"
    p.write_text("Extension (mm),load_N\n0,0.1\n1,0.2\n2,0.3\n3,0.4\n")
    cols = read_csv_columns(p, (), ("strain", "strain_mm_per_mm", "load_N"))
    assert any("'Extension (mm)' is a length, not a strain: write strain = extension / gauge length" in w
               for w in cols.not_read)
    with pytest.raises(KnitsimInputError, match=r"no strain column .*'Extension \(mm\)' is a length, not a strain"):
        read_table(p)


@pytest.mark.parametrize("header", ["strain", "Strain [%]"])
def test_cells_written_with_a_per_cent_sign_read_as_that_per_cent_once(tmp_path, plain, header):
    # Excel's CSV of a strain column formatted as a percentage writes 10% for 0.1: read as 0.1 under a plain
    # header and under a per-cent one alike (the sign is the cell's own unit: not divided twice)
    text = PLAIN.replace("strain,", f"{header},").replace("0.0,-0.002", "0%,-0.002").replace(
        "0.1,0.053", "10%,0.053").replace("0.2,0.098", "20%,0.098").replace("0.1,0.018", "10%,0.018")
    got = _read(_write(tmp_path, text))
    _same_values(got, plain)
    assert "strain: 4 cell(s) written with a % sign read in per cent (divided by 100)" in got.notes[0]


def test_a_per_cent_sign_in_a_force_column_is_refused_naming_its_row(tmp_path):
    text = PLAIN.replace("0.1,0.053", "0.1,5%")
    with pytest.raises(KnitsimInputError, match=r"row 3.*force_per_wale_N.*'5%' is not a number"):
        _read(_write(tmp_path, text))


@pytest.mark.parametrize("text", [
    "Strain [%];force_per_wale_N\r\n0%;0,01\r\n12,5%;0,05\r\n25%;0,1\r\n",        # ';' and decimal commas
    'strain,force_per_wale_N\n"0%","0,01"\n"12,5%","0,05"\n"25%","0,1"\n',       # quoted decimal commas
])
def test_per_cent_cells_with_decimal_commas(tmp_path, text):
    got = read_csv_columns(_write(tmp_path, text), REQ, numeric=REQ)
    np.testing.assert_array_equal(got["strain"], [0.0, 0.125, 0.25])
    np.testing.assert_array_equal(got["force_per_wale_N"], [0.01, 0.05, 0.1])
    assert len(got.notes) == 1 and got.notes[0].startswith("strain: 3 cell(s) written with a % sign")


def test_a_column_named_in_words_with_its_unit_is_read_as_that_column(tmp_path):
    # Found by a blind probe (hand-made lab files): "Force per wale [N]" was refused as a missing force_per_wale_N.
    # Expected, from the reading rules (module docstring): a column asked for with a unit ending (_N, _mm_s) may be
    # written as its name in words (spaces, hyphens or underscores) with that unit in brackets, taken and noted as
    # a machine's name is; without its unit, or with another, it is not taken, and the refusal says what to write;
    # a cell that is another column by its own name is never taken for this one.
    names = ("force_per_wale_N", "rate_mm_s")
    c = read_csv_columns(_write(tmp_path, "Strain;Force per wale (N);Rate [mm/s]\n0;0,001;1\n0,1;0,03;1\n", "a.csv"),
                         ("strain",) + names[:1], names[1:])
    np.testing.assert_array_equal(c["force_per_wale_N"], [0.001, 0.03])
    np.testing.assert_array_equal(c["rate_mm_s"], [1.0, 1.0])
    assert c.notes == ("column 'Force per wale (N)' read as force_per_wale_N", "column 'Rate [mm/s]' read as rate_mm_s")
    c = read_csv_columns(_write(tmp_path, "strain,Force-per_wale [N]\n0,0.001\n0.1,0.03\n", "b.csv"),
                         ("strain", "force_per_wale_N"))
    np.testing.assert_array_equal(c["force_per_wale_N"], [0.001, 0.03])
    for header, why in (("strain,Force per wale", "'Force per wale' is read as force_per_wale_N with its unit "
                                                  "stated ('Force per wale (N)')"),
                        ("strain,Force per wale [kN]", "'Force per wale [kN]' is not read as force_per_wale_N: 'kN' "
                                                       "is not its unit (convert the column: 'Force per wale (N)')")):
        with pytest.raises(KnitsimInputError) as e:
            read_csv_columns(_write(tmp_path, header + "\n0,0.001\n0.1,0.03\n", "c.csv"), ("strain", "force_per_wale_N"))
        assert why in str(e.value), str(e.value)
    # "Strain [%]" is the strain asked for by its name, not the strain_mm_per_mm asked for beside it
    c = read_csv_columns(_write(tmp_path, "Strain [%],force_per_wale_N\n0,0.001\n10,0.03\n", "d.csv"), (),
                         ("strain", "strain_mm_per_mm", "force_per_wale_N"))
    assert "strain_mm_per_mm" not in c
    np.testing.assert_allclose(c["strain"], [0.0, 0.1], rtol=1e-15)


@pytest.mark.parametrize("header, units, note", [
    # the package's name with the unit a lab writes for a force per wale: no other name, nothing to say
    ("force_per_wale_N [N/wale]", None, None),
    ("force_per_wale_N", "N/wale", None),
    # a lab's own name of the force per wale, with N or N/wale (in brackets or in a units row)
    ("Force per wale [N/wale]", None, "column 'Force per wale [N/wale]' read as force_per_wale_N"),
    ("Force per wale (N)", None, "column 'Force per wale (N)' read as force_per_wale_N"),
    ("Force per wale", "N/wale", "column 'Force per wale' read as force_per_wale_N"),
    # a force whose unit says per wale
    ("force [N/wale]", None, "column 'force [N/wale]' read as force_per_wale_N"),
    ("Load (N / wale)", None, "column 'Load (N / wale)' read as force_per_wale_N"),
])
def test_a_force_per_wale_stated_in_N_per_wale_reads_as_force_per_wale_N(tmp_path, header, units, note):
    """A blind probe's force_per_wale_N [N/wale], Force per wale [N/wale] and force [N/wale] were refused (N/wale
    was not the unit of force_per_wale_N, and no other name was read for it).  Expected: the numbers of the plain
    twin (typed the same), and a note naming the cell where it is not the package's own name."""
    from knitsim.io.table_input import LAB_ALIASES
    rows = [("0.0", "-0.002"), ("0.1", "0.053"), ("0.2", "0.098"), ("0.1", "0.018")]
    p = _write(tmp_path, _table(["strain", header], rows, units=["-", units] if units else None))
    c = read_csv_columns(p, REQ, aliases=LAB_ALIASES)
    twin = read_csv_columns(_write(tmp_path, _table(list(REQ), rows), "twin.csv"), REQ)
    np.testing.assert_array_equal(c["force_per_wale_N"], twin["force_per_wale_N"])
    np.testing.assert_array_equal(c["strain"], twin["strain"])
    assert c.notes == ((note,) if note else ()), c.notes


def test_a_total_force_is_not_read_as_a_force_per_wale_and_a_per_wale_unit_on_a_total_is_refused(tmp_path):
    """Force (N) is a total force: a force per wale only with its unit N/wale (the names of a total force stand for
    the force per wale with that unit only), so diagnose's columns do not take it (calibrate reads it as force_N);
    Force per wale without a unit, or in kN, is not read, and the refusal says why; a total force's own name with a
    per-wale unit (load_N [N/wale]) says two things, and is refused naming the header cell."""
    from knitsim.io.table_input import LAB_ALIASES
    body = "0.0,-0.002\n0.1,0.053\n0.2,0.098\n"
    total = _write(tmp_path, "strain,Force (N)\n" + body, "total.csv")
    with pytest.raises(KnitsimInputError, match=r"missing column\(s\) force_per_wale_N"):
        read_csv_columns(total, REQ, aliases=LAB_ALIASES)
    c = read_csv_columns(total, (), ("strain", "load_N", "force_N", "force_per_wale_N"), aliases=LAB_ALIASES)
    assert "force_N" in c and "force_per_wale_N" not in c and c.notes == ("column 'Force (N)' read as force_N",)
    for header, why in (("Force per wale", "'Force per wale' is read as force_per_wale_N with its unit stated "
                                           "('Force per wale (N)')"),
                        ("Force per wale [kN]", "'Force per wale [kN]' is not read as force_per_wale_N: 'kN' is not "
                                                "its unit")):
        with pytest.raises(KnitsimInputError) as e:
            read_csv_columns(_write(tmp_path, f"strain,{header}\n" + body, "bad.csv"), REQ, aliases=LAB_ALIASES)
        assert why in str(e.value), str(e.value)
    with pytest.raises(KnitsimInputError, match=r"row 1, column 'load_N \[N/wale\]': the unit 'N/wale' is not that "
                                                r"of load_N"):
        read_csv_columns(_write(tmp_path, "strain,load_N [N/wale]\n" + body, "load.csv"), ("strain", "load_N"))


def test_a_force_per_wale_in_another_unit_is_told_to_convert_to_N_per_wale_not_to_a_total_force(tmp_path):
    # expectation (the reading rules: a name written with a unit stands for the column only with that unit): a
    # helper's probe found 'Force [kN/wale]' told to convert to 'Force (N)' (calibrate), a total force, and diagnose
    # said nothing of it; it is a force per wale in kN, so both refusals name force_per_wale_N and its unit, N/wale,
    # and neither suggests the total
    from knitsim.calibration.specimen import read_table
    from knitsim.io.table_input import LAB_ALIASES
    path = _write(tmp_path, "strain,Force [kN/wale]\n0.0,0.0\n0.1,0.0001\n0.2,0.0003\n0.3,0.0008\n0.2,0.0002\n",
                  "kn.csv")
    for read in (lambda: read_csv_columns(path, REQ, aliases=LAB_ALIASES), lambda: read_table(path)):
        with pytest.raises(KnitsimInputError) as e:
            read()
        msg = str(e.value)
        assert ("'Force [kN/wale]' is not read as force_per_wale_N: 'kN/wale' is not its unit (convert the column: "
                "'Force [N/wale]')") in msg, msg
        assert "'Force (N)'" not in msg, msg


def test_a_second_table_under_the_first_is_refused_as_several_tests(tmp_path):
    from knitsim.io.table_input import LAB_ALIASES
    # A machine's export of a test series: each test's header (and units row) and rows one under the other.  A probe's
    # two tests in one file were refused as "row 8, column strain: 'strain' is not a number".  Hand-made: the
    # header at row 2 (under a title), a units row, 3 rows, a blank line, the same header at row 8 and its rows.
    text = ('Results\n"Strain [%]";"Standard force [N/wale]"\n"%";"N/wale"\n0;0,01\n5;0,12\n10;0,23\n\n'
            '"Strain [%]";"Standard force [N/wale]"\n"%";"N/wale"\n0;0,02\n5;0,13\n10;0,25\n')
    p = _write(tmp_path, text, "series.csv")
    with pytest.raises(KnitsimInputError, match=r"series\.csv: row 8 repeats the header of row 2: several tests one "
                                                r"under the other\? Give each test its own file$"):
        read_csv_columns(p, REQ, aliases=LAB_ALIASES)
    # a header's name in one cell of a data row is text in a number cell, as before
    p = _write(tmp_path, "strain,force_per_wale_N\n0,0.01\nstrain,0.12\n0.1,0.23\n", "one.csv")
    with pytest.raises(KnitsimInputError, match=r"row 3, column strain: 'strain' is not a number"):
        read_csv_columns(p, REQ)


@pytest.mark.parametrize("cell, unit", [("load_kN", "kN"), ("Load_lbf", "lbf"), ("load_daN", "daN")])
def test_a_force_column_named_for_another_unit_is_said_as_such(tmp_path, cell, unit):
    """A probe's calibration file headed `load_kN` where `load_N` is read was refused as "missing column
    load_N" without a word of its unit (a `force [kN]` header was already told): the refusal names the unit and
    what to write."""
    f = tmp_path / "t.csv"
    f.write_text(f"strain,{cell}\n0,0\n0.1,0.001\n0.2,0.002\n0.3,0.003\n")
    with pytest.raises(KnitsimInputError, match=rf"missing column\(s\) load_N .*'{cell}' is a force in {unit}, not "
                                                 r"in N: convert it to N and name the column load_N$"):
        read_csv_columns(f, ["strain", "load_N"])


def test_a_force_per_width_is_refused_saying_what_it_is(tmp_path):
    # Found by a probe (hand-made lab files): 'Load [N/mm]', a load per specimen width, was refused with "convert the
    # column: 'Load (N)'", as kN is, without saying how (a width is no factor of a unit).  Expected, from the reading
    # rules: still refused (a force per width is neither a total force nor a force per wale), naming the header
    # cell and saying that the width, or the wale spacing, converts it; a unit in kN keeps its own advice.
    from knitsim.io.table_input import LAB_ALIASES, PER_WIDTH_HINT
    names = ("strain", "load_N", "force_N", "force_per_wale_N")
    for header in ("strain,Load [N/mm]", "strain,Load (kN/m)"):
        p = _write(tmp_path, header + "\n0,0\n0.1,1\n0.2,2\n0.3,3\n", "w.csv")
        with pytest.raises(KnitsimInputError) as e:
            read_csv_columns(p, ("load_N",), names, aliases=LAB_ALIASES)
        assert f"'{header.split(',')[1]}' is not read as load_N" in str(e.value) and PER_WIDTH_HINT in str(e.value)
    for header, cell in (("strain,load_N [N/mm]\n", "'load_N [N/mm]'"), ("strain,force_per_wale_N\n-,N/mm\n",
                                                                         "'force_per_wale_N'")):
        p = _write(tmp_path, header + "0,0\n0.1,1\n0.2,2\n0.3,3\n", "w2.csv")
        with pytest.raises(KnitsimInputError) as e:
            read_csv_columns(p, ("strain",), names, aliases=LAB_ALIASES)
        assert f"column {cell}: the unit 'N/mm' is not that of" in str(e.value) and PER_WIDTH_HINT in str(e.value)
    p = _write(tmp_path, "strain,Load [kN]\n0,0\n0.1,1\n", "k.csv")
    with pytest.raises(KnitsimInputError) as e:
        read_csv_columns(p, ("load_N",), names, aliases=LAB_ALIASES)
    assert PER_WIDTH_HINT not in str(e.value) and "'kN' is not its unit (convert the column: 'Load (N)')" in str(e.value)


def test_a_folder_given_as_the_file_is_said_to_be_a_folder(tmp_path):
    # the reader's four entry points share one check: a folder is named as one (a probe's `knitsim dahl fit .`
    # was told "no such file"), a missing path is still "no such file"
    from knitsim.io.table_input import has_columns, header_candidates, stated_units
    for read in (lambda p: read_csv_columns(p, ["a"]), lambda p: has_columns(p, ["a"]),
                 lambda p: stated_units(p, ["a"]), lambda p: list(header_candidates(p))):
        with pytest.raises(KnitsimInputError, match=r": is a folder, not a file$"):
            read(tmp_path)
        with pytest.raises(KnitsimInputError, match=r"nope\.csv: no such file$"):
            read(tmp_path / "nope.csv")
