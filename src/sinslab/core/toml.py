"""TOML output: the one writer of sinslab's TOML files (configs, error models, segment
lists). Reading uses the standard library's :mod:`tomllib`."""
from __future__ import annotations

import json
import math
import re
from typing import Mapping

__all__ = ["dump_toml", "toml_value"]

_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def _tkey(k: str) -> str:
    return k if _BARE.match(k) else json.dumps(k, ensure_ascii=False)


def toml_value(v: object) -> str:
    """One TOML value: bool, int, float (``nan``/``inf`` included), string, list/tuple
    (an array) or mapping (an inline table; ``None`` entries omitted)."""
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
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        return "{" + ", ".join(f"{_tkey(k)} = {toml_value(x)}" for k, x in v.items() if x is not None) + "}"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _is_table_array(v) -> bool:
    return isinstance(v, (list, tuple)) and len(v) > 0 and all(isinstance(x, Mapping) for x in v)


def dump_toml(data: Mapping, _prefix: str = "", *, table: str | None = None,
              array_tables: bool = False) -> str:
    """Write a nested dict as TOML (scalars first, then ``[tables]``); ``None`` is omitted.

    Parameters
    ----------
    data : mapping
        Keys are strings; values as :func:`toml_value` takes them, mappings become
        ``[tables]``.
    table : str, optional
        Write ``data`` under this (dotted) table name, ``[table]`` / ``[table.sub]``.
    array_tables : bool
        Write a non-empty list of mappings as an array of tables (``[[name]]`` blocks, in
        order, after the tables) instead of an inline array.
    """
    if table:
        body = dump_toml(data, table + ".", array_tables=array_tables)
        return f"[{table}]" + ("\n" + body if body else "") + "\n"
    lines = []
    tables = []
    arrays = []
    for k, v in data.items():
        if v is None:
            continue
        if isinstance(v, Mapping):
            tables.append((k, v))
        elif array_tables and _is_table_array(v):
            arrays.append((k, v))
        else:
            lines.append(f"{_tkey(k)} = {toml_value(v)}")
    out = "\n".join(lines)
    for k, v in tables:
        name = f"{_prefix}{_tkey(k)}"
        body = dump_toml(v, name + ".", array_tables=array_tables)
        head = f"[{name}]"
        out += ("\n\n" if out else "") + head + ("\n" + body if body else "")
    for k, items in arrays:
        name = f"{_prefix}{_tkey(k)}"
        for item in items:
            body = dump_toml(item, name + ".", array_tables=array_tables)
            out += ("\n\n" if out else "") + f"[[{name}]]" + ("\n" + body if body else "")
    return out + ("\n" if not _prefix and out else "")
