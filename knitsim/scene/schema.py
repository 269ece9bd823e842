"""A small declarative schema for scene files (TOML).

A schema is a :class:`Table` of named :class:`Field` s, nested :class:`Table` s
and :class:`TableArray` s (TOML ``[[name]]``).  :func:`validate` checks a parsed
document against it: unknown keys are refused, types are checked (an integer is
accepted where a float is expected, a bool never is), floats must be finite,
ranges and choices are enforced, and defaults are filled in.  Every error is a
:class:`~knitsim.errors.KnitsimInputError` whose one-line message starts with
the full key path and the value, e.g. ``cells[2].knit.W0 = 2.0: must be > 0``.

:func:`set_value` applies a command-line override ``key.path=value``, converting
the text by the field's type; :func:`dumps` writes a (resolved) document back as
TOML (the subset scenes use: tables, arrays of tables, scalars and flat lists).

Units are part of the key (``force_cap_N``, ``coiling_angle_deg``) or stated in
the field's ``unit`` (N, mm, rad inside; degrees only in ``*_deg`` keys).
"""
from __future__ import annotations

import json
import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from ..errors import KnitsimInputError


class _Sentinel:
    def __init__(self, name: str):
        self.name = name

    def __repr__(self) -> str:
        return self.name


#: default of a field that must be given
REQUIRED = _Sentinel("REQUIRED")
#: default of a field that may be absent (then it is absent from the result)
OPTIONAL = _Sentinel("OPTIONAL")

_TYPE_NAMES = {"float": "a number", "int": "a whole number", "str": "a string", "bool": "true or false",
               "float_list": "a list of numbers", "str_list": "a list of strings"}


@dataclass(frozen=True)
class Field:
    """One scalar (or flat list) key.

    Parameters
    ----------
    types : tuple of str
        Accepted types, tried in order: ``"float"``, ``"int"``, ``"str"``,
        ``"bool"``, ``"float_list"``.
    default : Any
        Value filled in when absent; :data:`REQUIRED` or :data:`OPTIONAL`.
    doc, unit : str
        Description and unit (for messages and :func:`describe`).
    min, max : float, optional
        Bounds of a number; ``min_inclusive`` / ``max_inclusive`` say whether
        the bound itself is allowed.
    choices : tuple of str, optional
        Allowed string values.
    check : callable, optional
        ``check(value) -> str | None``: a further test returning the reason a
        value is refused.
    """

    types: tuple[str, ...]
    default: Any = OPTIONAL
    doc: str = ""
    unit: str = ""
    min: float | None = None
    max: float | None = None
    min_inclusive: bool = True
    max_inclusive: bool = True
    choices: tuple[str, ...] | None = None
    check: Callable[[Any], str | None] | None = None


@dataclass(frozen=True)
class Table:
    """A TOML table: named fields, sub-tables and arrays of tables.

    ``required``: the table must be present (else it is filled from its
    fields' defaults when it is absent).  ``alternatives``: groups of keys
    that state one quantity in different ways (``phi0`` / ``phi0_deg`` /
    ``phi0_fraction``); an override of one (``--set``, a sweep's sample)
    replaces whatever the document said through the others of its groups.
    """

    fields: dict[str, Any]
    doc: str = ""
    required: bool = False
    alternatives: tuple[tuple[tuple[str, ...], ...], ...] = ()
    #: a key whose value chooses which of the table's keys apply, and those keys by value (``load.type``:
    #: ``target_strain`` for ``"monotonic"``, ...): an override of it drops the keys of the other choices
    variants: tuple[str, dict[str, tuple[str, ...]]] | None = None

    def not_of(self, key: str, value: Any) -> tuple[str, ...]:
        """The keys that the choice ``key = value`` leaves out (none where ``key`` chooses nothing)."""
        if self.variants is None or key != self.variants[0]:
            return ()
        keep = self.variants[1].get(value, ())
        return tuple(k for group in self.variants[1].values() for k in group if k not in keep)

    def others_than(self, key: str) -> tuple[str, ...]:
        """The keys that state ``key``'s quantity another way (none where ``key`` is in no group)."""
        return tuple(k for groups in self.alternatives if any(key in g for g in groups)
                     for g in groups if key not in g for k in g)


@dataclass(frozen=True)
class TableArray:
    """A TOML array of tables (``[[name]]``), each checked against ``item``."""

    item: Table
    doc: str = ""
    min_items: int = 0


def join(path: str, key: str) -> str:
    """Key path of ``key`` inside ``path`` (``"a.b"``, or ``"key"`` at the top)."""
    return key if not path else f"{path}.{key}"


def fmt(value: Any) -> str:
    """A value as it appears in error messages (TOML-like)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, dict):
        return "{...}"
    if isinstance(value, list):
        return "[" + ", ".join(fmt(v) for v in value) + "]"
    return repr(value)


def error(path: str, value: Any, why: str) -> KnitsimInputError:
    """The error for a bad value: ``path = value: why``."""
    return KnitsimInputError(f"{path} = {fmt(value)}: {why}")


def _convert(f: Field, value: Any, path: str) -> Any:
    """Check the type of ``value`` against the field; returns the normalised value."""
    for t in f.types:
        if t == "float" and isinstance(value, (int, float)) and not isinstance(value, bool):
            v = float(value)
            if not math.isfinite(v):
                raise error(path, value, "must be a finite number")
            return v
        if t == "int" and isinstance(value, int) and not isinstance(value, bool):
            return int(value)
        if t == "str" and isinstance(value, str):
            return value
        if t == "bool" and isinstance(value, bool):
            return value
        if t == "float_list" and isinstance(value, list):
            out = []
            for i, v in enumerate(value):
                if isinstance(v, bool) or not isinstance(v, (int, float)):
                    raise error(f"{path}[{i}]", v, "expected a number")
                if not math.isfinite(float(v)):
                    raise error(f"{path}[{i}]", v, "must be a finite number")
                out.append(float(v))
            return out
        if t == "str_list" and isinstance(value, list):
            for i, v in enumerate(value):
                if not isinstance(v, str):
                    raise error(f"{path}[{i}]", v, "expected a string")
                if f.choices is not None and v not in f.choices:
                    raise error(f"{path}[{i}]", v, f"expected one of {', '.join(f.choices)}")
            if len(set(value)) != len(value):
                raise error(path, value, "a name is listed twice")
            return list(value)
    want = " or ".join(_TYPE_NAMES[t] for t in f.types)
    raise error(path, value, f"expected {want}")


def _check_field(f: Field, value: Any, path: str) -> Any:
    v = _convert(f, value, path)
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        unit = f" {f.unit}" if f.unit else ""
        if f.min is not None and (v < f.min or (v == f.min and not f.min_inclusive)):
            raise error(path, value, f"must be {'>=' if f.min_inclusive else '>'} {f.min:g}{unit}")
        if f.max is not None and (v > f.max or (v == f.max and not f.max_inclusive)):
            raise error(path, value, f"must be {'<=' if f.max_inclusive else '<'} {f.max:g}{unit}")
    if isinstance(v, str) and f.choices is not None and v not in f.choices:
        raise error(path, value, f"expected one of {', '.join(f.choices)}")
    if f.check is not None:
        why = f.check(v)
        if why:
            raise error(path, value, why)
    return v


def validate(schema: Table, data: Any, path: str = "", fill_defaults: bool = True) -> dict:
    """Check a parsed document (or part of it) against ``schema``.

    Parameters
    ----------
    schema : Table
        The expected layout.
    data : dict
        The parsed TOML (``tomllib`` output) or a plain dict.
    path : str
        Key path of ``data`` (for messages), ``""`` at the top.
    fill_defaults : bool
        Fill in defaults of absent fields and absent sub-tables; with ``False``
        (partial overrides, e.g. one cell of a batch) only given keys are kept
        and nothing is required.

    Returns
    -------
    dict
        A new dict with normalised values (ints promoted to floats where a float
        is expected) and, with ``fill_defaults``, every default present.

    Raises
    ------
    KnitsimInputError
        The first problem, as ``path = value: reason``.
    """
    if not isinstance(data, dict):
        raise error(path or "scene", data, "expected a table")
    unknown = [k for k in data if k not in schema.fields]
    if unknown:
        k = unknown[0]
        raise error(join(path, k), data[k], f"unknown key (expected one of {', '.join(schema.fields)})")
    out: dict = {}
    for key, spec in schema.fields.items():
        p = join(path, key)
        if isinstance(spec, Field):
            if key in data:
                out[key] = _check_field(spec, data[key], p)
            elif fill_defaults:
                if spec.default is REQUIRED:
                    raise KnitsimInputError(f"{p}: missing required key ({spec.doc})" if spec.doc
                                            else f"{p}: missing required key")
                if spec.default is not OPTIONAL:
                    out[key] = spec.default
        elif isinstance(spec, Table):
            if key in data:
                out[key] = validate(spec, data[key], p, fill_defaults)
            elif fill_defaults:
                if spec.required:
                    raise KnitsimInputError(f"{p}: missing required table [{p}] ({spec.doc})" if spec.doc
                                            else f"{p}: missing required table [{p}]")
                out[key] = validate(spec, {}, p, fill_defaults)
        elif isinstance(spec, TableArray):
            if key in data:
                items = data[key]
                if not isinstance(items, list):
                    raise error(p, items, f"expected an array of tables [[{p}]]")
                if len(items) < spec.min_items:
                    raise error(p, items, f"needs at least {spec.min_items} entries")
                out[key] = [validate(spec.item, it, f"{p}[{i}]", fill_defaults) for i, it in enumerate(items)]
        else:  # pragma: no cover - schema construction error
            raise TypeError(f"bad schema entry {p}: {spec!r}")
    return out


# ----------------------------------------------------------------- file input
def load_toml(path: str | Path) -> dict:
    """Parse a TOML file, turning I/O and syntax errors into one-line input errors."""
    path = Path(path)
    if path.is_dir():
        tomls = sorted(p.name for p in path.glob("*.toml"))[:5]
        raise KnitsimInputError(f"{path}: a folder, not a scene file" + (f" (it holds {', '.join(tomls)})" if tomls
                                                                          else ""))
    if not path.is_file():
        raise KnitsimInputError(f"{path}: no such scene file")
    import codecs
    raw = path.read_bytes()
    try:
        # a byte-order mark as editors write one (Notepad's "UTF-8 with BOM", "Unicode"): the text it marks (before,
        # a scene saved so was refused as "not valid TOML (Invalid statement (at line 1, column 1))")
        utf16 = raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE))
        return tomllib.loads(raw.decode("utf-16" if utf16 else "utf-8-sig"))
    except tomllib.TOMLDecodeError as exc:
        raise KnitsimInputError(f"{path}: not valid TOML ({exc})") from None
    except UnicodeDecodeError as exc:
        raise KnitsimInputError(f"{path}: not UTF-8 text ({exc.reason})") from None


# --------------------------------------------------------- command-line --set
_PART = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)\])?$")


def _parse_text(f: Field, text: str, key: str) -> Any:
    """Convert command-line text to a value of the field's type."""
    s = text.strip()
    for t in f.types:
        if t in ("float", "int"):
            try:
                return int(s) if t == "int" else float(s)
            except ValueError:
                continue
        elif t == "bool" and s in ("true", "false"):
            return s == "true"
        elif t in ("float_list", "str_list") and s.startswith("["):
            # a TOML array, as in the scene (before, a str_list had no branch: --set effects.on=["..."] or
            # calibration.per_specimen=[...] was refused whatever was typed); its items are checked by validate
            try:
                return tomllib.loads(f"v = {s}")["v"]
            except tomllib.TOMLDecodeError:
                continue
        elif t == "str":
            if len(s) >= 2 and s[0] == s[-1] and s[0] in "\"'":
                s = s[1:-1]
            return s
    want = " or ".join(_TYPE_NAMES[t] for t in f.types)
    raise KnitsimInputError(f"{key} = {json.dumps(text)}: expected {want}")


def flat_keys(d: Any, prefix: str = "") -> dict:
    """``{"a.b[0].c": value}`` of a nested JSON document (a sweep's or a run's keys, for :func:`key_changes`)."""
    if isinstance(d, dict):
        return {k2: v for k, x in d.items() for k2, v in flat_keys(x, f"{prefix}.{k}" if prefix else str(k)).items()}
    if isinstance(d, list) and any(isinstance(x, (dict, list)) for x in d):
        return {k2: v for i, x in enumerate(d) for k2, v in flat_keys(x, f"{prefix}[{i}]").items()}
    return {prefix: d}


def key_changes(a: dict, b: dict) -> list[str]:
    """``"key old -> new"`` for each key of two flat tables (:func:`flat_keys`) whose values differ (``(none)``
    where absent): what --resume's refusals name."""
    return [f"{k} {a.get(k, '(none)')} -> {b.get(k, '(none)')}" for k in sorted(set(a) | set(b), key=str)
            if a.get(k) != b.get(k)]


def set_value(data: dict, schema: Table, assignment: str) -> dict:
    """Apply one ``key.path=value`` override (``--set``) to a parsed document.

    The key path may index arrays of tables, ``cells[1].friction.m=0.3``; the
    entry must exist.  A key with alternatives (:attr:`Table.alternatives`)
    replaces them: ``friction.phi0_deg=3`` on a scene stating ``phi0 = 0``; a
    choosing key (:attr:`Table.variants`) drops the keys of the other choices:
    ``load.type=cycles`` on a monotonic scene drops its ``target_strain``.  The text is converted by the field's type (so
    ``yarn.B=abc`` is refused naming the key) and range-checked later by
    :func:`validate`.  ``data`` is modified in place and returned.
    """
    if "=" not in assignment:
        raise KnitsimInputError(f"--set {assignment!r}: expected key=value, e.g. yarn.B=0.25")
    key, text = (s.strip() for s in assignment.split("=", 1))
    parts = key.split(".")
    node, spec, where = data, schema, ""
    for depth, part in enumerate(parts):
        m = _PART.match(part)
        if not m:
            raise KnitsimInputError(f"--set {key}: {part!r} is not a key")
        name, index = m.group(1), m.group(2)
        if not isinstance(spec, Table) or name not in spec.fields:
            known = ", ".join(spec.fields) if isinstance(spec, Table) else ""
            raise KnitsimInputError(f"--set {key}: unknown key {join(where, name)!r} (expected one of {known})")
        sub = spec.fields[name]
        where = join(where, name)
        last = depth == len(parts) - 1
        if isinstance(sub, TableArray):
            if index is None:
                raise KnitsimInputError(f"--set {key}: {where} is an array of tables; index it, e.g. {where}[0]")
            items = node.get(name)
            i = int(index)
            if not isinstance(items, list) or i >= len(items):
                n = len(items) if isinstance(items, list) else 0
                raise KnitsimInputError(f"--set {key}: the scene has {n} entries in {where}, no {where}[{i}]")
            if last:
                raise KnitsimInputError(f"--set {key}: {where}[{i}] is a table; set one of its keys")
            node, spec, where = items[i], sub.item, f"{where}[{i}]"
        elif index is not None:
            raise KnitsimInputError(f"--set {key}: {where} is not an array")
        elif isinstance(sub, Table):
            if last:
                raise KnitsimInputError(f"--set {key}: {where} is a table; set one of its keys")
            child = node.setdefault(name, {})
            if not isinstance(child, dict):
                raise error(where, child, "expected a table")
            node, spec = child, sub
        else:
            if not last:
                raise KnitsimInputError(f"--set {key}: {where} is a value, not a table")
            node[name] = _parse_text(sub, text, key)
            for other in spec.others_than(name) + spec.not_of(name, node[name]):
                node.pop(other, None)      # the override states this quantity (or chooses): the document's other way goes
    return data


def field_at(schema: Table, key: str) -> Field | None:
    """The :class:`Field` a key path names (``cells[1].knit.L``: the knit table's ``L``), or None where the path
    names no value of the schema (an unknown key, a table).  What a key path's value is, its unit among it, for
    outputs labelled by key paths (a sweep's axes); :func:`set_value` refuses such paths, naming them."""
    spec: Any = schema
    for part in key.split("."):
        m = _PART.match(part)
        if not m or not isinstance(spec, Table) or m.group(1) not in spec.fields:
            return None
        spec = spec.fields[m.group(1)]
        if isinstance(spec, TableArray):
            spec = spec.item
    return spec if isinstance(spec, Field) else None


# --------------------------------------------------------------- TOML output
_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def _key(k: str) -> str:
    return k if _BARE.match(k) else json.dumps(k)


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} as a TOML value")


def _is_table_array(v: Any) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def _emit(lines: list, data: dict, prefix: str) -> None:
    scalars = [(k, v) for k, v in data.items() if not isinstance(v, dict) and not _is_table_array(v)]
    for k, v in scalars:
        if v is None:
            continue
        lines.append(f"{_key(k)} = {_value(v)}")
    for k, v in data.items():
        name = f"{prefix}.{_key(k)}" if prefix else _key(k)
        if isinstance(v, dict):
            lines.append("")
            lines.append(f"[{name}]")
            _emit(lines, v, name)
        elif _is_table_array(v):
            for item in v:
                lines.append("")
                lines.append(f"[[{name}]]")
                _emit(lines, item, name)


def dumps(data: dict, header: str = "") -> str:
    """Write a document of tables, arrays of tables, scalars and flat lists as TOML.

    ``None`` values are left out (TOML has no null); ``header`` lines become
    comments at the top.  ``tomllib.loads(dumps(d)) == d`` for such documents.
    """
    lines = [f"# {h}" if h else "#" for h in header.splitlines()]
    _emit(lines, data, "")
    return "\n".join(lines).lstrip("\n") + "\n"


def describe(schema: Table, path: str = "") -> list[str]:
    """One line per key of the schema: path, type, unit, default, doc (for help texts)."""
    out = []
    for key, spec in schema.fields.items():
        p = join(path, key)
        if isinstance(spec, Field):
            bits = ["|".join(spec.types)]
            if spec.unit:
                bits.append(f"[{spec.unit}]")
            if spec.choices:
                bits.append("one of " + "/".join(spec.choices))
            if spec.default is REQUIRED:
                bits.append("required")
            elif spec.default is not OPTIONAL:
                bits.append(f"default {fmt(spec.default)}")
            out.append(f"{p}: {' '.join(bits)}" + (f" -- {spec.doc}" if spec.doc else ""))
        elif isinstance(spec, Table):
            out.append(f"[{p}]" + (f" -- {spec.doc}" if spec.doc else ""))
            out += describe(spec, p)
        else:
            out.append(f"[[{p}]]" + (f" -- {spec.doc}" if spec.doc else ""))
            out += describe(spec.item, p + "[i]")
    return out


__all__ = ["REQUIRED", "OPTIONAL", "Field", "Table", "TableArray", "validate", "set_value", "dumps",
           "load_toml", "describe", "error", "fmt", "join"]
