"""Reading measured tables as laboratories write them (CSV from a test machine, from Excel).

:func:`read_csv_columns` accepts what a lab produces and refuses only what is
wrong, naming the file, the row (the file's own line number, as a spreadsheet
shows it), the column and the value, and what to do:

- a UTF-8 byte-order mark (Excel's "CSV UTF-8"), UTF-16 with its byte-order
  mark (Excel's "Unicode Text", tab-separated) or without one (a machine's
  export or a BOM lost in a copy: recognised by its zero bytes), or
  Windows-1252 text;
- CRLF or LF line ends, blank lines, spaces around cells, quoted cells;
- ``,`` ``;`` or tab as the delimiter, found from the header line (the one
  that splits it into the most fields);
- decimal commas where the delimiter is ``;`` or a tab (``0,125``), and in quoted cells of a
  comma-separated file (``"0,125"``) when at least one of its numbers reads only that way (``1,250``
  alone could be 1250: such a file is refused); thousands separators with a decimal point
  (``"1,234.5"``; ``1.234,5`` in a ``;`` or tab file), and thousands grouped by a space (``1 234,5``: a French or
  Nordic spreadsheet's formatted value, with a no-break or narrow no-break space) or an apostrophe (``1'234.5``:
  a Swiss one) in any file;
- header names matched after trimming spaces and quotes, in any case
  (``Strain``, `` FORCE_PER_WALE_N ``); the keys returned are the names asked for;
- a unit after a header name, in brackets (``strain [-]``, ``force_per_wale_N (N)``,
  ``V_mm_s [mm/s]``), when it is the unit the name implies (``_N``: N, ``_per_wale_N``: N or N/wale,
  ``_mm``: mm, ``_mm_s``: mm/s, ``_1_mm``: 1/mm; others dimensionless: ``-``, ``1``, ``mm/mm``);
  a dimensionless column (a strain) stated in per cent (``Strain [%]``, ``strain (%)``, ``strain %``,
  ``percent``, ``pct``) is read divided by 100 and said so (:attr:`Columns.notes`); another unit
  (``F0_N [kN]``, ``force_per_wale_N [%]``) is refused naming the header cell;
- lines starting with ``#`` (comments), anywhere; but not a row whose first cell is a
  spreadsheet's error value (``#DIV/0!``, ``#N/A``, ``#VALUE!``): that is a data row, and
  it is refused as text in a number column, naming its row, not dropped as a comment;
- a preamble above the header (``Specimen: A3``, ``Test date;2026-03-01``): the
  header is the first line that holds every required column (and, when none is
  required, at least one of the optional ones); the lines above it are skipped;
- a units row directly under the header (``-,N,-,-``, ``[mm],[N],(-),mm/s``):
  the first data row is skipped when none of its non-empty cells is a number; the unit
  under each column read is checked as one in its header cell (``%`` under ``strain``: read in
  per cent; ``kN`` under ``force_per_wale_N``: refused naming the row and the column; a header cell and
  a units row that disagree, ``strain [-]`` over ``%``, are refused).
  Text in a number column further down is refused as before;
- a test machine's own names for a column, where the caller gives them (``aliases``: ``Tensile strain (%)``
  for ``strain``, ``Load (N)`` for ``load_N``, ``Force per wale [N/wale]`` and ``force [N/wale]`` for
  ``force_per_wale_N``; :data:`LAB_ALIASES`, where a name written with a unit stands for the column only with
  that unit: ``Force (N)`` is no force per wale): taken only with a unit that is the
  column's (or per cent, for a strain), in brackets or in a units row under the header (``"Load"`` over
  ``"(N)"``), and only where the column's own name is absent; said so in the notes (``column 'Load (N)'
  read as load_N``).  Without a unit, or with another, it is not taken (``Load`` could be kN): a missing
  column's refusal says why (:attr:`Columns.not_read` for a caller's own refusal); two cells that would
  both be one column are refused as a column named twice.  So is a column asked for with a unit ending
  (``force_per_wale_N``, ``rate_mm_s``) written as its name in words with that unit (``Force per wale (N)``,
  ``Rate [mm/s]``; spaces, hyphens or underscores), where no cell is another column asked for by its own name;
- refused: a value in a row beyond the header's columns (a shifted or merged row), and a
  column read that is named twice (which one is meant is not said).
"""
from __future__ import annotations

import codecs
import csv
import functools
import hashlib
import math
import re
from decimal import Decimal
from pathlib import Path
from typing import Iterable

import numpy as np

from ..errors import KnitsimInputError

_DELIMITERS = (",", ";", "\t")
#: bad cells a refusal lists (the count of the others follows)
BAD_CELLS_LISTED = 10
#: test machines' names of the columns the package reads (any case; with the column's unit, in brackets or a units row):
#: Instron Bluehill's "Tensile strain (%)" and "Load (N)", Zwick testXpert's "Standard force (N)"
#: and a lab's own names of the force per wale ("Force per wale (N)", "Force per wale [N/wale]").  A name written with
#: a unit (``"force [N/wale]"``) stands for the column only with that unit: ``Force [N/wale]`` is a force per wale,
#: ``Force (N)`` a total force
LAB_ALIASES = {"strain": ("tensile strain", "engineering strain"),
               "load_N": ("load", "tensile load"),
               "force_N": ("force", "tensile force", "standard force"),
               "force_per_wale_N": ("force per wale", "force_per_wale", "force/wale", "load per wale", "load_per_wale",
                                    "load/wale", "force [N/wale]", "load [N/wale]", "tensile force [N/wale]",
                                    "tensile load [N/wale]", "standard force [N/wale]")}
#: a column read in per cent whose values all lie within this (as fractions: 2 %) is said to look like fractions:
#: a knit is tested to tens of per cent, and 0.6 or 1.2 under a ``%`` header is far likelier 60 % or 120 % than
#: 0.6 % or 1.2 % (a note, not a refusal: a test that small is told, and read as written)
PER_CENT_LOOKS_FRACTION = 0.02


class Columns(dict):
    """The columns :func:`read_csv_columns` read: a ``dict`` of column name to array (and ``"_row"``), with
    ``notes``, a tuple of what the reader did that the user must be told (a strain column read in per cent
    and divided by 100: ``strain column 'Strain [%]' read in per cent (divided by 100)``).  Its keys are the
    columns only, so code that iterates them is unchanged; :func:`notes_of` reads the notes of any dict."""

    def __init__(self, *args, notes: Iterable[str] = (), **kwargs):
        super().__init__(*args, **kwargs)
        self.notes: tuple[str, ...] = tuple(notes)
        #: why a test machine's name for a column was not read (no unit stated, or another unit), for a caller's
        #: refusal when it then lacks that column
        self.not_read: tuple[str, ...] = ()


def notes_of(cols) -> tuple[str, ...]:
    """The notes of columns read by :func:`read_csv_columns` (``()`` for a plain dict)."""
    return tuple(getattr(cols, "notes", ()))
_NAMES = {",": "comma", ";": "semicolon", "\t": "tab"}


#: the first bytes of a workbook: Office Open XML (.xlsx, .xlsm: a zip archive; so is an OpenDocument .ods) and
#: the legacy binary Excel format (.xls: an OLE2 compound file)
_ZIP_MAGIC, _OLE2_MAGIC = b"PK\x03\x04", b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1"


def _text(path: Path) -> str:
    return _text_and_note(path)[0]


def _text_and_note(path: Path) -> tuple[str, str | None]:
    """The file's text, and what its reading must tell the user (a workbook's sheet read; else None)."""
    path = Path(path)
    raw = path.read_bytes()
    if raw.startswith((_ZIP_MAGIC, _OLE2_MAGIC)):
        # one command reads a file's header several times (dahl fit: its columns, their units, the table): a
        # workbook is parsed once for the same bytes
        return _workbook_text(str(path), hashlib.sha256(raw).digest())
    if raw.startswith((codecs.BOM_UTF32_LE, codecs.BOM_UTF32_BE)):
        return raw.decode("utf-32", errors="replace"), None
    if raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        return raw.decode("utf-16", errors="replace"), None   # Excel's "Unicode Text"; the BOM is dropped
    utf16 = _utf16_without_bom(raw)
    if utf16:
        return raw.decode(utf16, errors="replace"), None
    try:
        return raw.decode("utf-8-sig"), None       # strips Excel's byte-order mark
    except UnicodeDecodeError:
        return raw.decode("cp1252", errors="replace"), None


class _PerCent(float):
    """A workbook cell formatted as a percentage: its text is the per cent it shows, every digit kept
    (``0.125`` -> ``12.5%``: the decimal point of its shortest repr shifted by two places, exactly)."""

    def __str__(self) -> str:
        return f"{Decimal(repr(float(self))).scaleb(2).normalize():f}%"


def _numeric_row(cells: tuple) -> bool:
    return sum(isinstance(c, (int, float)) and not isinstance(c, bool) for c in cells) >= 2


@functools.lru_cache(maxsize=8)
def _workbook_text(path: str, digest: bytes) -> tuple[str, str]:
    """An Excel workbook (.xlsx, .xlsm) as tab-separated text, one line per row of its sheet, so that a line
    number is the spreadsheet's row number and the rest of the reading (preamble, header, units row, aliases)
    is the CSV's.

    The sheet read is the active one (the sheet Excel's "Save as CSV" writes), or, where that holds no row of
    two numbers and another does, the first such (a workbook whose active sheet is a chart or a summary); which
    one, of how many, is said in :attr:`Columns.notes`.  Cells hold the values Excel last computed
    (a formula's cached result; a file written by a program that never computed its formulas has none: those
    cells read as the formula said never computed, ``=B3/2 (a formula never computed)``, and are refused as text,
    naming the row: :func:`_formulas_never_computed`).  Numbers keep every digit (no rounding to the
    cells' display format).  Legacy .xls and OpenDocument sheets are refused, saying how to save them."""
    path = Path(path)
    with open(path, "rb") as f:
        legacy = f.read(len(_OLE2_MAGIC)) == _OLE2_MAGIC
    if legacy:
        raise KnitsimInputError(f"{path}: an Excel 97-2003 workbook (.xls), which knitsim does not read: open it and "
                                "save it as an Excel workbook (.xlsx) or as CSV")
    import zipfile
    try:
        with zipfile.ZipFile(path) as z:
            names = set(z.namelist())
    except zipfile.BadZipFile:
        raise KnitsimInputError(f"{path}: starts as a zip archive (an .xlsx workbook?) but is not a readable one "
                                "(truncated or damaged): save the sheet again, or as CSV") from None
    if "xl/workbook.xml" not in names:
        what = ("an OpenDocument spreadsheet (.ods)" if "mimetype" in names and "content.xml" in names
                else "a zip archive, not an Excel workbook")
        raise KnitsimInputError(f"{path}: {what}, which knitsim does not read: save the sheet as an Excel workbook "
                                "(.xlsx) or as CSV")
    import warnings

    import openpyxl
    try:
        with warnings.catch_warnings():
            # (openpyxl warns of the parts it drops, data validation or conditional formats of Excel's own
            # extensions, and of a workbook without a default style: nothing a sheet's numbers depend on)
            warnings.simplefilter("ignore", UserWarning)
            book = openpyxl.load_workbook(path, read_only=True, data_only=True)
    except Exception as exc:  # noqa: BLE001 - a damaged workbook is the user's file, said as such
        raise KnitsimInputError(f"{path}: not a readable Excel workbook ({type(exc).__name__}: {exc}): save the "
                                "sheet again, or as CSV") from None
    try:
        sheets = [ws for ws in book.worksheets if hasattr(ws, "iter_rows")]
        if not sheets:
            raise KnitsimInputError(f"{path}: the workbook holds no worksheet (only charts?)")
        rows_of = {}

        def value(c):
            v = getattr(c, "value", None)
            if (isinstance(v, (int, float)) and not isinstance(v, bool)
                    and "%" in str(getattr(c, "number_format", "") or "")):
                # a cell formatted as a percentage holds the fraction (0.125 shown as 12.5%): written as the per
                # cent it shows, the decimal point shifted exactly, as Excel's CSV writes it (read as that per cent)
                return _PerCent(float(v))          # (1 shown as 100% is stored as the integer 1)
            return v

        def rows(ws):
            if ws.title not in rows_of:
                rows_of[ws.title] = [tuple(value(c) for c in r) for r in ws.iter_rows(min_row=1)]
            return rows_of[ws.title]

        active = book.active if book.active in sheets else sheets[0]
        ws = active
        if not any(_numeric_row(r) for r in rows(active)):
            ws = next((w for w in sheets if w is not active and any(_numeric_row(r) for r in rows(w))), active)
        if any(v is None for r in rows(ws) for v in r):
            _formulas_never_computed(path, ws.title, rows_of[ws.title])
        import io
        buf = io.StringIO()
        out = csv.writer(buf, delimiter="\t", lineterminator="\n")
        for r in rows(ws):
            out.writerow(["" if c is None else str(c) if isinstance(c, _PerCent) else repr(float(c))
                          if isinstance(c, float) else c.isoformat(" ") if hasattr(c, "isoformat") else str(c)
                          for c in r])
        listed = ", ".join(repr(w.title) for w in sheets)
        why = ("the active one" if ws is active else
               f"the first with rows of numbers; the active one, {active.title!r}, has none")
        return buf.getvalue(), (f"an Excel workbook: read its sheet {ws.title!r} ({why}"
                                + (f"; sheets: {listed}" if len(sheets) > 1 else "") + ")")
    finally:
        book.close()


def _formulas_never_computed(path: Path, title: str, rows: list[tuple]) -> None:
    """Write a formula whose value was never computed (a workbook written by a program, not saved by a spreadsheet:
    its cells hold no cached value) into its empty cell of ``rows`` (the sheet ``title`` as read), as
    ``=C2/23 (a formula never computed)``, so that a refusal says why the cell is empty (a probe's workbook
    of formulas written with openpyxl was refused as ``'' is not a number``, row after row, the formulas unnamed)."""
    import warnings

    import openpyxl
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        book = openpyxl.load_workbook(path, read_only=True, data_only=False)
    try:
        for i, r in enumerate(book[title].iter_rows(min_row=1)):
            if i >= len(rows):
                break
            cells = list(rows[i])
            for j, c in enumerate(r):
                f = getattr(c, "value", None)
                if j < len(cells) and cells[j] is None and isinstance(f, str) and f.startswith("="):
                    cells[j] = f"{f} (a formula never computed)"
            rows[i] = tuple(cells)
    finally:
        book.close()


def _utf16_without_bom(raw: bytes) -> str | None:
    """"utf-16-le" / "utf-16-be" for UTF-16 text without a byte-order mark, else None.

    A table is mostly ASCII, whose UTF-16 has a zero byte in every other place: in the odd places for
    little-endian, the even ones for big-endian.  Text in UTF-8 or Windows-1252 has no zero bytes."""
    head = raw[:4096]
    if len(head) < 4 or len(head) % 2:
        return None
    half = len(head) // 2
    odd, even = head[1::2].count(0), head[0::2].count(0)
    if odd >= 0.9 * half and even == 0:
        return "utf-16-le"
    if even >= 0.9 * half and odd == 0:
        return "utf-16-be"
    return None


def _delimiter(header_line: str) -> str:
    counts = {d: header_line.count(d) for d in _DELIMITERS}
    best = max(_DELIMITERS, key=lambda d: counts[d])
    return best if counts[best] > 0 else ","


#: a number written with a decimal comma and no other separator (``0,125``, ``-12,5``, ``1,5e-3``)
_DECIMAL_COMMA = re.compile(r"[+-]?\d*,\d+(?:[eE][+-]?\d+)?")
#: thousands grouped with commas and a decimal point (``1,234.5``: an en-US spreadsheet's formatted value)
_GROUPED_POINT = re.compile(r"[+-]?\d{1,3}(?:,\d{3})+\.\d*")
#: thousands grouped with points and a decimal comma (``1.234,5``: a German spreadsheet's formatted value)
_GROUPED_COMMA = re.compile(r"[+-]?\d{1,3}(?:\.\d{3})+,\d+")
#: thousands grouped with a space (plain, no-break U+00A0, narrow no-break U+202F, thin U+2009: a French, Nordic or
#: SI-style spreadsheet's formatted value, ``1 234,5``) or an apostrophe (``1'234.5``, Swiss): no decimal mark, so
#: read the same under either decimal convention
_GROUPED_SPACE = re.compile(r"[+-]?[1-9]\d{0,2}([ \u00a0\u202f\u2009'\u2019])\d{3}(?:\1\d{3})*(?:[.,]\d*)?")


def _ungrouped(cell: str) -> str:
    """``cell`` without the spaces or apostrophes that group its thousands (:data:`_GROUPED_SPACE`), else as is."""
    m = _GROUPED_SPACE.fullmatch(cell)
    return cell.replace(m.group(1), "") if m else cell


def _number(cell: str, decimal_comma: bool, per_cent: bool = False) -> float:
    """A cell's number; ``per_cent``: divided by 100, exactly (the decimal number written, shifted by two
    places, then rounded once: ``5.123`` in per cent reads as ``0.05123`` does)."""
    c = _ungrouped(cell.strip().replace("\u2212", "-"))       # (a typographic minus sign)
    if decimal_comma and "," in c and "." not in c:
        c = c.replace(",", ".")
    elif decimal_comma and _GROUPED_COMMA.fullmatch(c):
        c = c.replace(".", "").replace(",", ".")
    elif not decimal_comma and _GROUPED_POINT.fullmatch(c):
        c = c.replace(",", "")
    v = float(c)                          # raises ValueError on what is not a number
    if per_cent and math.isfinite(v):
        return float(Decimal(c.strip()).scaleb(-2))
    return v


def _ambiguous_comma(cell: str) -> bool:
    """``1,250``: three digits after the comma and a non-zero integer part read as 1.25 (a decimal comma) or
    as 1250 (a thousands separator) alike; ``0,125``, ``12,5`` and ``1,2500`` read one way only."""
    c = cell.strip().lstrip("+-").split("e")[0].split("E")[0]
    whole, _, frac = c.partition(",")
    return len(frac) == 3 and whole.strip("0") != ""


def _comma_file_decimal_comma(path: Path, rows: list[list[str]], numbers: list[int], columns: list[int],
                              names: list[str]) -> bool:
    """Whether a comma-separated file writes its numbers with decimal commas, in quoted cells (``"0,125"``:
    LibreOffice and Google Sheets in a decimal-comma locale).  A comma inside a cell of a comma file is
    either that or a thousands separator; the file is read with decimal commas when every such cell is a
    plain decimal-comma number and at least one of them reads only that way (:func:`_ambiguous_comma`);
    when every one reads both ways the file is refused, naming the first."""
    # (a per-cent cell's sign is not part of its number: "12,5%")
    cells = [(line, name, _ungrouped(row[j].strip().removesuffix("%").rstrip())) for line, row in zip(numbers, rows)
             for j, name in zip(columns, names) if j < len(row) and "," in row[j]]
    if not cells or not all(_DECIMAL_COMMA.fullmatch(c) for _, _, c in cells):
        return False
    if all(_ambiguous_comma(c) for _, _, c in cells):
        line, name, c = cells[0]
        raise KnitsimInputError(
            f"{path}: row {line}, column {name}: {c!r} in a comma-separated file reads as a decimal comma "
            f"({_number(c, True):g}) or as a thousands separator ({_number(c.replace(',', ''), False):g}), and so "
            "does every comma number of the file; save it with ';' as the delimiter, or with decimal points")
    return True


def _is_number(cell: str, decimal_comma: bool) -> bool:
    try:
        _number(cell, decimal_comma)
    except ValueError:
        return False
    return True


def _trim(name: str) -> str:
    return name.strip().strip('"').strip()


def _key(name: str) -> str:
    """A column's key: its name without a unit in brackets, any case (``x [mm]`` -> ``x``)."""
    return _name_and_unit(name)[0]


#: a header cell with its unit: ``strain [-]``, ``force_per_wale_N (N)``, ``V_mm_s [mm/s]``
_WITH_UNIT = re.compile(r"^(.*?\S)\s*[\[(]\s*([^\])]*?)\s*[\])]$")
#: the units a column's name implies, by the end of its name (casefold, no spaces); else dimensionless
#: (a force per wale: N, or N/wale, the unit a lab writes for it: ``force_per_wale_N [N/wale]``)
_UNITS = (("_1_mm", ("1/mm", "mm^-1", "mm-1")), ("_n_mm_per_mm", ("nmm/mm", "n.mm/mm", "n*mm/mm")),
          ("_mm_per_mm", ("mm/mm", "-", "1", "")), ("_mm_s", ("mm/s",)),
          ("_per_wale_n", ("n", "n/wale", "n/wales", "nperwale")), ("_n", ("n",)), ("_mm", ("mm",)))
_DIMENSIONLESS = ("-", "1", "", "mm/mm", "m/m")


_PER_CENT_SIGN = re.compile(r"^(.*?\S)\s*%$")
#: a unit that says per cent (casefold, no spaces)
_PER_CENT = ("%", "percent", "pct")


def split_unit(cell: str) -> tuple[str, str | None]:
    """A header cell's name, as written, and the unit written after it in brackets (or a bare ``%``), if any:
    ``'K [1/cm]'`` -> ``('K', '1/cm')``, ``'Strain %'`` -> ``('Strain', '%')``, ``'x_mm'`` -> ``('x_mm', None)``."""
    text = _trim(cell)
    m = _WITH_UNIT.match(text) or _PER_CENT_SIGN.match(text)
    return (m.group(1), m.group(2) if m.re is _WITH_UNIT else "%") if m else (text, None)


def _name_and_unit(cell: str) -> tuple[str, str | None]:
    """A header cell's name (its key: case folded) and its unit (:func:`split_unit`)."""
    name, unit = split_unit(cell)
    return name.casefold(), unit


def _is_per_cent(unit: str | None) -> bool:
    return unit is not None and unit.casefold().replace(" ", "") in _PER_CENT


def _dimensionless(name: str) -> bool:
    """Whether the column asked for as ``name`` is dimensionless (a strain): the unit it states in brackets,
    else the one its ending implies, else none."""
    return any(_unit_fits(name, u) for u in _DIMENSIONLESS)


def _unit_fits(name: str, unit: str) -> bool:
    """Whether ``unit`` is that of the column asked for as ``name``: the unit the name states in brackets
    (``x [mm]``: a blind probe's ``--columns "x [mm],F [N]"`` was told the columns it named were missing),
    else the one its ending implies (``_N``, ``_mm``, ...), else dimensionless."""
    u = unit.casefold().replace(" ", "")
    key, asked = _name_and_unit(name)
    if asked is not None:
        return u == asked.casefold().replace(" ", "")
    for end, units in _UNITS:
        if key.endswith(end):
            return u in units
    return u in _DIMENSIONLESS


def _implied_unit(name: str) -> str:
    """The unit of the column asked for as ``name``, as a header would write it: the one it states in brackets,
    else the first its ending implies (``V_mm_s``: mm/s; ``F0_N``: N), else N (a force, the columns read)."""
    key, asked = _name_and_unit(name)
    if asked is not None:
        return asked
    for end, units in _UNITS:
        if key.endswith(end):
            return {"_n": "N", "_per_wale_n": "N", "_n_mm_per_mm": "N.mm/mm"}.get(end, units[0])
    return "N"


#: a spreadsheet's error value in a cell (Excel: #DIV/0!, #N/A, #VALUE!, #REF!, #NAME?, #NUM!, #NULL!, ...)
_SHEET_ERROR = re.compile(r"#(N/A|[A-Z][A-Z0-9/_]*[!?])")


def _is_comment(line: str) -> bool:
    text = line.lstrip().lstrip('"')
    if not text.startswith("#"):
        return False
    first = re.split(r"[,;\t\"]", text, maxsplit=1)[0].strip()
    return _SHEET_ERROR.fullmatch(first) is None   # a row starting with #DIV/0! is data, not a comment


#: a cell that marks a missing value (casefold), not a label: a row starting with one is a data row
_MISSING_MARKERS = ("n/a", "na", "n.a.", "-", "--", "?", "null", "none", "missing")


def _is_label(cell: str, decimal_comma: bool) -> bool:
    """Whether ``cell`` is a label (``Max force``), as a spreadsheet's footer starts: text with a letter, neither a
    number, a spreadsheet's error value (``#DIV/0!``) nor a missing-value marker (``N/A``)."""
    c = _trim(cell)
    return (any(ch.isalpha() for ch in c) and not _is_number(c, decimal_comma) and _SHEET_ERROR.fullmatch(c) is None
            and c.casefold() not in _MISSING_MARKERS)


def _split(line: str, delim: str) -> list[str]:
    return next(csv.reader([line], delimiter=delim), [])


def _unit_cells(cells: list[str], decimal_comma: bool) -> list[str] | None:
    """A units row's units (``s;N;%``, ``(s),(N),(%)``: none of its non-empty cells a number), brackets removed;
    None where a cell is a number (a data row)."""
    cells = [_trim(c) for c in cells]
    if any(_is_number(c, decimal_comma) or _is_number(c, True) for c in cells if c):
        return None
    return [m.group(1) if (m := re.fullmatch(r"[\[(]\s*(.*?)\s*[\])]", c)) else c for c in cells]


def _units_row(lines: list[str], h: int, delim: str) -> list[str] | None:
    """The units of the units row under header line h (the first record after it that is not blank or a comment,
    as the data rows are read), else None."""
    nxt = next((ln for ln in lines[h + 1:] if ln.strip() and not _is_comment(ln)), None)
    return None if nxt is None else _unit_cells(_split(nxt, delim), delim != ",")


def _alias_unit(cells: list[str], unit_cells: list[str] | None, j: int) -> str | None:
    """The unit of header cell j: in brackets after its name, else in the units row under it (if any)."""
    unit = _name_and_unit(cells[j])[1]
    if unit is None and unit_cells is not None and j < len(unit_cells) and unit_cells[j]:
        unit = unit_cells[j]
    return unit


def _aliased(cells: list[str], names: list[str], aliases: dict, unit_cells: list[str] | None = None,
             strict: bool = True) -> tuple[list[str], dict[int, str], list[str]]:
    """The keys of a header line's ``cells``, where a cell that is an alias of a column asked for (``names``) stands
    for it: its unit (in brackets, or in the units row ``unit_cells`` under it) fits the column's (or says per
    cent, for a dimensionless column), and the column's own name is absent.  Every such cell takes the column's
    key (two of them are then refused as a column named twice).  An alias written with a unit (``"force [N/wale]"``)
    stands for the column only with that unit, and says nothing of a cell with another (``Force (N)``: a total force,
    not a force per wale).  ``strict=False`` takes any other alias whatever its unit
    (to find the header line, whose refusal then says why).  Returns (keys, {index: the column it was read as},
    the reasons the aliases present were not taken)."""
    keys = [_name_and_unit(c)[0] for c in cells]
    own = {_key(n) for n in names}
    taken, why_not = {}, []
    for name in names:
        # besides the machines' names, the column's own name written out with its unit: "Force per wale (N)" for
        # force_per_wale_N, "Rate [mm/s]" for rate_mm_s (a blind probe's hand-made header was refused as missing);
        # never a cell that is another column asked for by its own name ("Strain [%]" is strain, not strain_mm_per_mm)
        stem = _unit_stem(name)
        if _key(name) in keys or (name not in aliases and stem is None):
            continue
        for j, cell in enumerate(cells):
            if j in taken:
                continue
            spelled = keys[j] not in own and re.sub(r"[\s_-]+", "_", keys[j]) == stem
            with_unit = [split_unit(a)[1] for a in aliases.get(name, ()) if _key(a) == keys[j]]
            if not (with_unit or spelled):
                continue
            unit = _alias_unit(cells, unit_cells, j)
            bare = re.sub(r"\s*([\[(].*|%)$", "", _trim(cell))     # the cell's name without its unit
            if with_unit and None not in with_unit:
                # a name that stands for the column only with its unit (force [N/wale]: Force (N) is a total force,
                # no force per wale): taken with it, else not this column (nothing to say)
                if unit is not None and _unit_norm(unit) in {_unit_norm(u) for u in with_unit}:
                    keys[j] = _key(name)
                    taken[j] = name
                elif unit is not None and _per_wale(unit):
                    # a force per wale in another unit (Force [kN/wale]): said as this column's, converted to its own
                    why_not.append((j, f"{cell!r} is not read as {name}: {unit!r} is not its unit (convert the column: "
                                       f"{bare + ' [' + with_unit[0] + ']'!r})"))
                continue
            fits = unit is not None and (_unit_fits(name, unit) or (_is_per_cent(unit) and _dimensionless(name)))
            if fits or not strict:
                keys[j] = _key(name)
                taken[j] = name
            elif unit is not None and _per_wale(unit) and not _per_wale_column(name):
                # (a per-wale unit on a total force's name: the conversion to that total would mislead; a force per
                # wale's own names say it)
                continue
            else:
                stated = " or ".join(repr(f"{bare} ({u})") for u in (("%", "-") if _dimensionless(name) else
                                                                     (_implied_unit(name),)))
                why_not.append((j, f"{cell!r} is read as {name} with its unit stated ({stated})" if unit is None else
                                f"{cell!r} is not read as {name}: {unit!r} is not its unit"
                                + (f", {PER_WIDTH_HINT}" if _per_width(unit) and _knit_force_column(name) else "")
                                + f" (convert the column: {stated})"))
    # (a cell not read as one column may be another's: Force [N/wale] is no force_N, and is force_per_wale_N)
    return keys, taken, [why for j, why in why_not if j not in taken]


def _per_wale(unit: str) -> bool:
    """Whether ``unit`` is per wale (``N/wale``, ``kN / wale``, ``N per wale``)."""
    u = _unit_norm(unit)
    return u.endswith("/wale") or u.endswith("/wales") or u.endswith("perwale")


def _per_width(unit: str) -> bool:
    """Whether ``unit`` is a force per length (``N/mm``, ``kN/m``, ``N/cm``): a lab's load per specimen width."""
    return re.fullmatch(r"[mk]?n/(mm|cm|m)", _unit_norm(unit)) is not None


#: what a force per width is (a probe's 'Load [N/mm]' was told to convert the column to 'Load (N)', not how)
PER_WIDTH_HINT = ("a force per width: times the specimen's width (in that length unit) it is the total force, times "
                  "the wale spacing W0 the force per wale")


def _knit_force_column(name: str) -> bool:
    """Whether the column asked for as ``name`` is a knit's force (``load_N``, ``force_N``, ``force_per_wale_N``),
    which a force per width converts to (:data:`PER_WIDTH_HINT`)."""
    return _key(name) in ("load_n", "force_n") or _per_wale_column(name)


def _per_wale_column(name: str) -> bool:
    """Whether the column asked for as ``name`` is a force per wale (``force_per_wale_N``)."""
    return _key(name).endswith("_per_wale_n")


def _unit_norm(unit: str) -> str:
    """A unit as units are compared: case folded, without spaces (``N / wale`` is ``n/wale``)."""
    return unit.casefold().replace(" ", "")


def _unit_stem(name: str) -> str | None:
    """The name of a column asked for without the unit its ending implies (``force_per_wale_N`` ->
    ``force_per_wale``, ``rate_mm_s`` -> ``rate``), or None where it implies none."""
    key = _key(name)
    for end, _ in _UNITS:
        if key.endswith(end) and len(key) > len(end):
            # (the per-wale ending names the quantity as well as its unit: force_per_wale_N's stem is force_per_wale,
            # never force, which would take a total force's "Force (N)" for a force per wale)
            return key[:-len("_n" if end == "_per_wale_n" else end)]
    return None


def _find_header(lines: list[str], required: list[str], optional: list[str], aliases: dict | None = None) -> int | None:
    """Index of the header line: the first line holding every required name (and one wanted name), a machine's
    name for one standing for it whatever its unit (the reading then takes it or says why not).

    ``#`` lines are looked at only when no other line qualifies (a first column named ``#``).
    """
    want_all = {_key(c) for c in required}
    want_any = want_all | {_key(c) for c in optional}
    for comments in (False, True):
        for i, ln in enumerate(lines):
            if not ln.strip() or _is_comment(ln) != comments:
                continue
            cells = set(_aliased(_split(ln, _delimiter(ln)), required + optional, aliases or {}, strict=False)[0])
            if want_all <= cells and (not want_any or want_any & cells):
                return i
    return None


#: lines a refusal's header search looks at (:func:`_likeliest_header`)
HEADER_SCAN_LINES = 200


def _likeliest_header(lines: list[str], names: list[str], aliases: dict) -> int | None:
    """Where no line names every required column: the first non-comment line naming most of ``names`` or of the
    machines' names (``aliases``, whatever their units), else, above the first row of two numbers, the first line
    of the most labels (a header in the lab's own words: ``Zeit;Dehnung;Standardkraft`` under a preamble's
    ``Test report``, which a probe's refusal listed as the header found), else the first non-comment line, so that
    the refusal shows the header the file has (a blind probe's Bluehill export was refused as having found its
    preamble's ``Results Table 1``), or None for a file of blank lines and comments."""
    known = {_key(c) for c in names} | {_key(a) for alts in aliases.values() for a in alts}
    best, best_n = None, 0
    labelled, labels_n = None, 0
    # (a header is near the top: the first HEADER_SCAN_LINES lines, not a 200,000-row file's every row)
    for i, ln in enumerate(lines[:HEADER_SCAN_LINES]):
        if not ln.strip() or _is_comment(ln):
            continue
        if best is None:
            best = i
        delim = _delimiter(ln)
        cells = _split(ln, delim)
        n = sum(_name_and_unit(c)[0] in known for c in cells)
        if n > best_n:
            best, best_n = i, n
        if best_n == 0 and sum(_is_number(_trim(c), delim != ",") for c in cells) >= 2:
            break      # the data begin: the header is above
        k = sum(_is_label(c, delim != ",") for c in cells)
        if k > labels_n:
            labelled, labels_n = i, k
    return best if best_n > 0 or labelled is None else labelled


def _existing_file(path: str | Path) -> Path:
    """``path`` as a Path, refused where it is no file: a folder is said to be one (a probe's ``dahl fit .`` was
    told "no such file")."""
    path = Path(path)
    if not path.is_file():
        raise KnitsimInputError(f"{path}: is a folder, not a file" if path.is_dir() else f"{path}: no such file")
    return path


def has_columns(path: str | Path, names: Iterable[str]) -> bool:
    """Whether a line of the file names every column of ``names``, as :func:`read_csv_columns` finds its
    header (any case, after a preamble or ``#`` comments, in any of the encodings it reads)."""
    path = _existing_file(path)
    return _find_header(_text(path).splitlines(), list(names), []) is not None


def stated_units(path: str | Path, names: Iterable[str]) -> dict[str, tuple[str, str | None]]:
    """The unit each column of ``names`` states, where :func:`read_csv_columns` finds the header.

    Parameters
    ----------
    path : path-like
        The CSV file.
    names : iterable of str
        Columns asked for (any case; a unit in brackets after a name, ``K [1/cm]``, is ignored in finding it).

    Returns
    -------
    dict of str to (str, str or None)
        For each column found: its header cell and the unit stated for it, in brackets after its name
        (``K [1/cm]``), else in a units row under the header, else in brackets after the name asked for,
        else None.  Columns not found are left out (reading them then refuses them as missing).
    """
    path = _existing_file(path)
    lines = _text(path).splitlines()
    names = list(names)
    h = _find_header(lines, names, [])
    if h is None:
        return {}
    delim = _delimiter(lines[h])
    cells = [_trim(c) for c in _split(lines[h], delim)]
    keys = [_key(c) for c in cells]
    unit_cells = _units_row(lines, h, delim)
    out = {}
    for n in names:
        if _key(n) in keys:
            j = keys.index(_key(n))
            unit = _alias_unit(cells, unit_cells, j)
            out[n] = (cells[j], unit if unit is not None else _name_and_unit(n)[1])
    return out


def header_candidates(path: str | Path) -> list[tuple[int, list[str], list[str | None]]]:
    """The lines near the top of a file that may be its header, for a caller that finds its columns by their
    units rather than their names: each line (of the first :data:`HEADER_SCAN_LINES`, not blank nor a comment)
    as its 1-based line number, its cells and the unit each states (in brackets after its name, or in a units
    row under it; None where none is stated)."""
    path = _existing_file(path)
    lines = _text(path).splitlines()
    out = []
    for i, ln in enumerate(lines[:HEADER_SCAN_LINES]):
        if not ln.strip() or _is_comment(ln):
            continue
        delim = _delimiter(ln)
        cells = [_trim(c) for c in _split(ln, delim)]
        unit_cells = _units_row(lines, i, delim)
        out.append((i + 1, cells, [_alias_unit(cells, unit_cells, j) for j in range(len(cells))]))
    return out


def read_csv_columns(path: str | Path, required: Iterable[str], optional: Iterable[str] = (),
                     numeric: Iterable[str] | None = None, aliases: dict | None = None,
                     labels: Iterable[str] = ()) -> Columns:
    """Read named columns of a CSV file (see the module docstring).

    Parameters
    ----------
    path : path-like
        The CSV file; its header line names the columns (with units, e.g. ``F0_N``):
        the first line that holds every required column (lines above it and
        ``#`` lines are skipped), matched after trimming, in any case.
    required, optional : iterable of str
        Column names that must / may be present.
    numeric : iterable of str, optional
        Columns to parse as finite floats (default: all required and optional
        columns present).  A NaN, an empty cell or text there is an error naming
        the row and the column.  A units row directly under the header (none of
        its non-empty cells a number) is skipped.
    aliases : dict of str to tuple of str, optional
        Other names of the columns asked for (e.g. :data:`LAB_ALIASES`), taken only with a unit that is the
        column's (or per cent, for a strain), in brackets or in a units row, and only where the column's own
        name is absent; noted (``column 'Load (N)' read as load_N``); why one was not taken is in the
        result's ``not_read``.
    labels : iterable of str, optional
        Text columns read where the header holds exactly one of each (``specimen``, ``run``), as str arrays:
        never used to find the header line nor required, so a preamble's ``Sample;A3`` is not taken for it.

    Returns
    -------
    Columns
        A ``dict``: float arrays for numeric columns, arrays of str otherwise, keyed
        by the names asked for; the key ``"_row"`` holds the file's line number (the
        spreadsheet row) of each data row.  Its ``notes`` (a tuple of str, empty for
        most files) say what the user must be told: a dimensionless column stated in
        per cent (its header cell or the units row) is read divided by 100, and
        noted as ``strain column 'Strain [%]' read in per cent (divided by 100)``.
    """
    path = _existing_file(path)
    text, book_note = _text_and_note(path)
    lines = text.splitlines()
    if not any(ln.strip() for ln in lines):
        raise KnitsimInputError(f"{path}: the file is empty")
    required, optional = list(required), list(optional)
    aliases = aliases or {}
    h = _find_header(lines, required, optional, aliases)
    if h is None:      # no line names the columns: the line naming most of them (or any machine's) is the header
        h = _likeliest_header(lines, required + optional, aliases)
        if h is None:
            raise KnitsimInputError(f"{path}: no header line (only blank lines and # comments)")
    delim = _delimiter(lines[h])
    decimal_comma = delim != ","
    header = [_trim(c) for c in _split(lines[h], delim)]
    units = [_name_and_unit(c)[1] for c in header]
    # a machine's name is taken with its unit in brackets or in a units row under the header (Bluehill's raw data)
    keys, read_as, not_taken = _aliased(header, required + optional, aliases, _units_row(lines, h, delim))
    asked_strain = [c for c in required + optional if _key(c).startswith("strain")]
    if asked_strain and not any(_key(c) in keys for c in asked_strain):
        # an extension in mm where a strain is wanted (a blind probe's Extension [mm] was refused as "no strain
        # column", the gauge length it needed unnamed): said here and, through not_read, by a caller that asks
        # for its strain as optional (calibrate: a probe's Extension (mm) file was refused without it)
        ext = [c for c in header if re.search(r"exten|elong|displac|travel|position", c, re.I)]
        if ext:
            not_taken.append(f"{ext[0]!r} is a length, not a strain: write strain = extension / gauge length (both "
                             f"in mm) in a column named {asked_strain[0]}")
    missing = [c for c in required if _key(c) not in keys]
    for c in missing:
        # a column named for another unit of force than the one asked for (load_kN where load_N is read: a probe's
        # file was refused as "missing load_N" without a word of its unit)
        if c.endswith("_N"):
            other = re.compile(rf"^{re.escape(_key(c)[:-2])}_(kn|dan|cn|mn|lbf|kgf|gf)$")
            for cell in header:
                m = other.match(_key(cell))
                if m:
                    unit = split_unit(cell)[0][len(c) - 1:]
                    not_taken.append(f"{cell!r} is a force in {unit}, not in N: convert it to N and name the "
                                     f"column {c}")
    if missing:
        # a machine's name without its unit, or with another, is not taken (Load could be kN): say why
        raise KnitsimInputError(f"{path}: missing column(s) {', '.join(missing)} (found: {', '.join(header)}; "
                                f"read as {_NAMES[delim]}-separated){'; ' + '; '.join(not_taken) if not_taken else ''}")
    present = required + [c for c in optional if _key(c) in keys]
    # (a label named twice is not read: it is checked, not fitted, and the columns asked for are refused so)
    labels = [c for c in labels if keys.count(_key(c)) == 1 and c not in present]
    for name in present:
        at = [j for j, k in enumerate(keys) if k == _key(name)]
        if len(at) > 1:
            # which one is meant is not said by the file (a blind probe's second force column, twice the
            # first, was read as the first without a word)
            if any(j in read_as for j in at):
                # a machine's names (Load (N) twice, or Load (N) and Tensile load (N)): both would be this column
                raise KnitsimInputError(f"{path}: row {h + 1}: the columns {at[0] + 1} and {at[1] + 1} "
                                        f"({header[at[0]]!r}, {header[at[1]]!r}) would both be read as {name}: "
                                        "rename or delete one")
            raise KnitsimInputError(f"{path}: row {h + 1}: the columns {at[0] + 1} and {at[1] + 1} are both named "
                                    f"{header[at[1]]!r}: rename or delete one")

    #: the columns read in per cent (a dimensionless column whose unit says so): name -> where it says so
    per_cent: dict[str, str] = {}

    def refuse_unit(name: str, unit: str, line: int, cell: str) -> None:
        """Check ``unit``, stated for column ``name`` in header cell ``cell`` (``line`` h + 1) or in the units
        row (``line`` below it); a dimensionless column stated in per cent is noted in ``per_cent``."""
        pct = not _unit_fits(name, unit) and _is_per_cent(unit) and _dimensionless(name)
        if not pct and not _unit_fits(name, unit):
            # (a per-wale unit on a total force's name: the column is most likely a force per wale, named wrong)
            what = ("name the column force_per_wale_N if it holds a force per wale, else convert it to the total "
                    "force in N" if _per_wale(unit) and not _per_wale_column(name) else
                    f"{PER_WIDTH_HINT}: convert the column and write the unit its name implies, or none"
                    if _per_width(unit) and _knit_force_column(name) else
                    "convert the column and write the unit its name implies, or none")
            raise KnitsimInputError(f"{path}: row {line}, column {cell!r}: the unit {unit!r} is not that of {name} "
                                    f"(its name says its unit); {what}.")
        stated = units[keys.index(_key(name))] if line != h + 1 else None     # the header cell's, under it
        if stated is not None and stated.strip() and unit.strip() and pct != (name in per_cent):
            # one says per cent, the other a fraction: which one is meant is not said
            raise KnitsimInputError(f"{path}: row {line}, column {cell!r}: the units row says {unit!r} and the "
                                    f"header cell {stated!r}: which one is meant is not said; keep one")
        if pct and name not in per_cent:
            per_cent[name] = f"{cell!r}" if line == h + 1 else f"{cell!r} (units row {line}: {unit!r})"

    for name in present:
        unit = units[keys.index(_key(name))]
        if unit is not None:
            refuse_unit(name, unit, h + 1, header[keys.index(_key(name))])
    rows, numbers = [], []
    first_data = True                     # the row that may be a units row
    reader = csv.reader(lines[h + 1:], delimiter=delim)
    while True:
        line = h + 1 + reader.line_num + 1  # the file's line number (1-based) where the next record begins
        try:
            r = next(reader)
        except StopIteration:
            break
        if _is_comment(lines[line - 1]) or not any(c.strip() for c in r):
            continue
        if first_data:
            first_data = False
            row_units = _unit_cells(r, decimal_comma)
            if row_units is not None:
                # units under the header (-, N, [mm], mm/s): no cell is a number.  Each read column's unit is
                # checked as one in its header cell is (a blind probe's "%" and "kN" rows were skipped unread,
                # the numbers taken as a fraction and as N)
                for name in present:
                    j = keys.index(_key(name))
                    # a blank cell (or one an export left off the row's end) states no unit: the header's holds (a
                    # probe's ',,,,turns' under F0_N was refused: "the unit '' is not that of F0_N")
                    if j < len(row_units) and row_units[j].strip():
                        refuse_unit(name, row_units[j], line, header[j])
                continue
        extra = [j for j in range(len(header), len(r)) if r[j].strip()]
        if extra:
            # a value where the header names no column: a row shifted or merged, not a measurement to guess at
            raise KnitsimInputError(f"{path}: row {line}, column {extra[0] + 1}: {r[extra[0]].strip()!r} lies beyond "
                                    f"the header's {len(header)} columns (a shifted or merged row?): fix or delete "
                                    "the row")
        rows.append(r)
        numbers.append(line)
    if not rows:
        raise KnitsimInputError(f"{path}: no data rows")
    numeric = set(present if numeric is None else numeric)
    if delim == ",":
        numeric_present = [c for c in present if c in numeric]
        decimal_comma = _comma_file_decimal_comma(path, rows, numbers, [keys.index(_key(c)) for c in numeric_present],
                                                  numeric_present)
    out = Columns()
    bad = []                              # (row, column, text) of every cell that is not a finite number
    signed: dict[str, int] = {}          # dimensionless columns' cells written with a % sign, counted
    numeric -= set(labels)
    for name in present + labels:
        j = keys.index(_key(name))
        cells = []
        for line, row in zip(numbers, rows):
            cell = row[j].strip() if j < len(row) else ""
            if name in numeric:
                # a per-cent cell (Excel writes a cell formatted as a percentage so in its CSV: 12.5%) of a
                # dimensionless column is that per cent, under any header: divided by 100 once
                signed_cell = cell.endswith("%") and _dimensionless(name)
                try:
                    v = _number(cell[:-1] if signed_cell else cell, decimal_comma, signed_cell or name in per_cent)
                    if signed_cell:
                        signed[name] = signed.get(name, 0) + 1
                except ValueError:
                    bad.append((line, name, f"{cell!r} is not a number"))
                    v = math.nan
                else:
                    if not math.isfinite(v):
                        bad.append((line, name, f"{cell!r} is not finite"))
                cells.append(v)
            else:
                cells.append(cell)
        out[name] = np.asarray(cells, dtype=float if name in numeric else object)
    notes = [f"column {header[j]!r} read as {name}" for j, name in sorted(read_as.items())
             if name in present]
    out.not_read = tuple(not_taken)
    for name, n in signed.items():
        notes.append(f"{name}: {n} cell(s) written with a % sign read in per cent (divided by 100)"
                     + (", the header's per cent not applied to them again" if name in per_cent else ""))
    for name, where in per_cent.items():
        # (a column whose every cell carries its % sign was read by the cells' signs alone, said above)
        if name in numeric and signed.get(name, 0) < int(np.sum(np.isfinite(out[name]))):
            note = f"{name} column {where} read in per cent (divided by 100)"
            top = float(np.nanmax(np.abs(out[name]))) if len(out[name]) else math.nan
            if top <= PER_CENT_LOOKS_FRACTION:
                # (a blind probe's fractions under a % header were refused later as a test too short, the header
                # never named)
                where_unit = "in its units row as -" if "units row" in where else "as [-], or none"
                note += (f"; its largest value is {100.0 * top:g} %: if the column holds fractions (0.6 for 60 %), "
                         f"state its unit {where_unit}")
            notes.append(note)
    # a spreadsheet's footer (Max force;;8,55;;): rows after the data that fail to read and start with a label,
    # not a number, are no measurement: skipped and said (a blind probe's export was refused at its footer
    # as "'' is not a number")
    # A row whose first cell is a spreadsheet's error value or a missing-value marker (#DIV/0!, #N/A, N/A) is a
    # data row with a bad cell, not a label: refused as mid-file (a probe's last row "#DIV/0!;0,85" was skipped
    # as a footer, the curve's last reading lost with a note, where the same row mid-file is refused)
    bad_rows = {b[0] for b in bad}
    footer = []
    for line, row in reversed(list(zip(numbers, rows))):
        first = next((c.strip() for c in row if c.strip()), "")
        if line not in bad_rows or not _is_label(first, decimal_comma):
            break
        footer.append(line)
    if footer and len(footer) < len(rows):
        keep = np.asarray([line not in footer for line in numbers])
        for name in present + labels:
            out[name] = out[name][keep]
        numbers = [line for line in numbers if line not in footer]
        bad = [b for b in bad if b[0] not in footer]
        notes.append(f"row{'s' if len(footer) > 1 else ''} {', '.join(map(str, sorted(footer)))} after the data "
                     f"read as a footer (starting with a label, not a number: "
                     f"{next(c.strip() for c in rows[len(numbers)] if c.strip())!r}): skipped")
    out.notes = tuple(([book_note] if book_note else []) + notes)
    read_cols = [keys.index(_key(c)) for c in present]
    again = [line for line, r in zip(numbers, rows) if line in {b[0] for b in bad}
             and all(j < len(r) and _trim(r[j]) == header[j] for j in read_cols)]
    if again:
        # a second table under the first (a machine's export of a test series: each specimen's header and rows one
        # under the other): said as such, not as the header's names refused as numbers (a probe's two tests in one
        # file read "row 8, column strain: 'strain' is not a number")
        raise KnitsimInputError(f"{path}: row {again[0]} repeats the header of row {h + 1}"
                                + (f" (and rows {', '.join(map(str, again[1:4]))}{', ...' if len(again) > 4 else ''})"
                                   if len(again) > 1 else "")
                                + ": several tests one under the other? Give each test its own file")
    if bad:
        # every bad cell at once, in row order (a blind probe fixed one, ran again and met the next)
        bad.sort(key=lambda b: b[0])
        first = "; ".join(f"row {line}, column {name}: {what}" for line, name, what in bad[:BAD_CELLS_LISTED])
        more = f"; and {len(bad) - BAD_CELLS_LISTED} more" if len(bad) > BAD_CELLS_LISTED else ""
        raise KnitsimInputError(f"{path}: {first}{more} (fix or delete the row{'s' if len(bad) > 1 else ''})")
    out["_row"] = np.asarray(numbers, dtype=np.int64)
    return out
