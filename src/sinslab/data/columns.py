"""Column headers and column maps of IMU tables.

A header cell is ``NAME`` or ``NAME[unit]`` / ``NAME (unit)``; ``NAME`` may carry integer
indices, ``DeltaTheta[0]`` (a name, not a unit "0"), so ``DeltaTheta[0][rad]`` is the
column ``deltatheta[0]`` in radians. Cells that follow neither form (``Gyro X (deg/s)``
with a space, vendor status words) are kept as raw names: they matter only when a column
map asks for them.

A column map says which column of the file is which quantity of sinslab's table, and in
which unit: ``"t=Time[s], dtheta_x=DeltaTheta[0] [rad], ..., dv_z=DeltaVel[2] [m/s]"``, a
``dict`` of the same, or a TOML file with those keys (top level or a ``[columns]`` table;
values a string ``"NAME [unit]"``, a table ``{name = "NAME", unit = "rad"}`` or a 1-based
column position for a file without a header).
"""
from __future__ import annotations

import re
from pathlib import Path

__all__ = ["parse_header_cell", "parse_column_map", "CANONICAL", "RATE_KEYS", "INC_KEYS", "FIX_KEYS"]

#: the quantities a map may name: time, rates or increments, and a rest flag
RATE_KEYS = ("gx", "gy", "gz", "ax", "ay", "az")
INC_KEYS = ("dtheta_x", "dtheta_y", "dtheta_z", "dv_x", "dv_y", "dv_z")
CANONICAL = ("t",) + RATE_KEYS + INC_KEYS + ("stationary",)
#: the quantities a map of a fix table may name (``--fix-columns``): validity time, arrival
#: time, position, its σ north/east/up, velocity east/north/up or north/east/down (``vd``)
#: with σ, and a solution quality/mode column
FIX_KEYS = ("t", "t_arrive", "lat", "lon", "h", "sd_n", "sd_e", "sd_u", "ve", "vn", "vu", "vd",
            "sd_ve", "sd_vn", "sd_vu", "sd_vd", "quality")

_NAME = r"[A-Za-z_][A-Za-z0-9_.\-]*(?:\[\s*\d+\s*\])*"
_CELL = re.compile(rf"^\s*({_NAME})\s*(?:[\[(]\s*([^\])]*?)\s*[\])])?\s*$")


def _norm(name: str) -> str:
    return re.sub(r"\s+", "", name).lower()


def parse_header_cell(cell) -> tuple:
    """``(name, unit or None, ok)``: ``name`` lower case without blanks; ``ok`` False for a
    cell that is neither ``NAME`` nor ``NAME[unit]`` (its whole text is the name)."""
    s = str(cell).strip().strip("\"'")
    m = _CELL.match(s)
    if not m:
        return _norm(s), None, False
    unit = (m.group(2) or "").strip() or None
    return _norm(m.group(1)), unit, True


def _split_top(text: str):
    """Split at commas outside brackets/parentheses."""
    out, depth, cur = [], 0, []
    for ch in text:
        if ch in "[(":
            depth += 1
        elif ch in "])":
            depth -= 1
        if ch == "," and depth == 0:
            out.append("".join(cur))
            cur = []
        else:
            cur.append(ch)
    out.append("".join(cur))
    return [s for s in (x.strip() for x in out) if s]


def _entry(key, val, src):
    """(source name or 1-based position, unit or None) of one map entry."""
    if isinstance(val, bool):
        raise ValueError(f"{src}: column map entry {key!r}: give a column name or position, got {val!r}")
    if isinstance(val, int):
        if val < 1:
            raise ValueError(f"{src}: column map entry {key!r}: positions count from 1, got {val}")
        return val, None
    if isinstance(val, dict):
        extra = set(val) - {"name", "unit", "column"}
        if extra or not ({"name", "column"} & set(val)):
            raise ValueError(f"{src}: column map entry {key!r}: use {{name = \"...\", unit = \"...\"}} "
                             f"or {{column = N, unit = \"...\"}}, got {val!r}")
        pos = val.get("column")
        name = pos if pos is not None else _norm(str(val["name"]))
        if pos is not None:
            name, _ = _entry(key, pos, src)
        return name, (str(val["unit"]).strip() or None) if "unit" in val else None
    s = str(val).strip()
    if s.isdigit():
        return _entry(key, int(s), src)
    # "NAME [unit]" / "NAME[unit]" / "NAME (unit)" / "NAME" / "#N [unit]"
    pos = re.match(r"^#?(\d+)\s*(?:[\[(]\s*([^\])]*?)\s*[\])])?$", s)
    if pos:
        return _entry(key, int(pos.group(1)), src)[0], (pos.group(2) or None)
    name, unit, ok = parse_header_cell(s)
    if not ok:
        raise ValueError(f"{src}: column map entry {key}={s!r}: write NAME or NAME[unit], "
                         "e.g. DeltaTheta[0][rad]")
    return name, unit


def parse_column_map(spec, *, keys=CANONICAL, option="--columns") -> dict:
    """A column map from a string ``"key=NAME[unit],..."``, a dict, or a TOML file path.

    Returns ``{key: (name or 1-based position, unit or None)}`` with keys from ``keys``
    (:data:`CANONICAL` for IMU tables, :data:`FIX_KEYS` for fix tables; ``option`` names
    the command-line option in messages). Raises ValueError naming the offending entry: an
    unknown key, a key given twice, an entry that is not ``key=value``, an IMU map mixing
    rates and increments, or one without the time column.
    """
    if spec is None:
        return {}
    src = option
    if isinstance(spec, (str, Path)) and str(spec).strip().lower().endswith(".toml") \
            and "=" not in str(spec):
        import tomllib
        p = Path(spec)
        if not p.is_file():
            raise ValueError(f"{p}: no such column-map file")
        try:
            d = tomllib.loads(p.read_text())
        except Exception as e:       # noqa: BLE001 - any TOML syntax error
            raise ValueError(f"{p}: not a TOML column map ({e})") from None
        spec = d.get("columns", d)
        src = str(p)
    if isinstance(spec, dict):
        items = list(spec.items())
    else:
        items = []
        for tok in _split_top(str(spec)):
            k, sep, v = tok.partition("=")
            if not sep or not k.strip() or not v.strip():
                raise ValueError(f"{src}: cannot read {tok!r}; use key=COLUMN[unit], e.g. "
                                 "dtheta_x=DeltaTheta[0][rad]")
            items.append((k, v))
    out = {}
    for k, v in items:
        key = str(k).strip().lower()
        if key not in keys:
            raise ValueError(f"{src}: unknown column key {key!r}; use {', '.join(keys)}")
        if key in out:
            raise ValueError(f"{src}: column key {key!r} given twice")
        out[key] = _entry(key, v, src)
    if keys is not CANONICAL:
        return out
    has_rate = any(k in out for k in RATE_KEYS)
    has_inc = any(k in out for k in INC_KEYS)
    if has_rate and has_inc:
        raise ValueError(f"{src}: the map mixes rates (gx.., ax..) and increments (dtheta_x.., dv_x..); "
                         "use one kind")
    if not (has_rate or has_inc):
        return out               # only the time and/or the rest flag: sensors found by name
    want = RATE_KEYS if has_rate else INC_KEYS
    miss = [k for k in ("t",) + want if k not in out]
    if miss:
        raise ValueError(f"{src}: the column map lacks {', '.join(miss)}")
    return out
