"""Tables of an aiding sensor beside the IMU (a magnetometer, a barometric altimeter, an
air-speed probe): a time column and a few value columns with their units, read as the IMU
and fix tables are (CSV, delimited text or Parquet, ``.gz``/``.zip``; columns by name or a
column map ``"t=time[s], mx=mag_x[G], ..."``; one-line errors naming file and line).

:func:`read_sensor_table` returns the values in SI with the units they were declared in,
the rows dropped for an empty value counted; a *held* stream (a slow sensor's reading
repeated in every row of a faster log, :func:`sinslab.core.stamps.held_runs`) is
collapsed to its first row per reading. :func:`check_channels` refuses a dead (constant)
or saturated channel (a table on another clock than the IMU's:
:func:`sinslab.core.stamps.check_time_base`).
:func:`read_magnetometer` and :func:`read_barometer` are the readers the magnetometer and
barometer aids use (through the data front door).
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sinslab.core import units
from sinslab.data import columns as _columns
from sinslab.data.increments import check_stamps, where

__all__ = ["SensorTable", "read_sensor_table", "check_channels", "SATURATED_SHARE",
           "read_magnetometer", "read_barometer", "MAG_KEYS"]

#: The quantities of a magnetometer table: time and the field along the sensor's x, y, z.
MAG_KEYS = ("mx", "my", "mz")

#: Share of the rows at a channel's extreme value from which the channel is called saturated.
SATURATED_SHARE = 0.01


@dataclass(frozen=True)
class SensorTable:
    """Samples of one sensor table.

    Attributes
    ----------
    t : ndarray (J,)
        Time stamps [s], strictly increasing.
    values : dict of str -> ndarray (J,)
        Each quantity in SI.
    units : dict of str -> str
        The unit each quantity was declared in (header or map).
    columns : dict of str -> str
        The column each quantity was read from.
    path : str
        The file (an archive's ``NAME.zip:member`` when unpacked), for messages.
    rows : int
        Rows read.
    dropped : int
        Rows dropped for an empty or non-finite value.
    held : tuple (rows, readings) or None
        Held rows collapsed: rows before, readings after.
    """

    t: np.ndarray
    values: dict
    units: dict
    columns: dict
    path: str
    rows: int
    dropped: int = 0
    held: tuple | None = None

    def __len__(self):
        return self.t.size


def read_sensor_table(path, quantities, *, columns=None, option="--columns") -> SensorTable:
    """Read a sensor table.

    Parameters
    ----------
    path : str or Path
        The table (CSV or other delimited text, Parquet; ``.gz`` or a one-table ``.zip``).
    quantities : dict of str -> (kind, default unit or None)
        The keys to read besides ``t`` (always read, default unit s), each with its
        :data:`sinslab.core.units.KINDS` kind and the unit taken when neither the map nor
        the header gives one (None: a unit is required).
    columns : str, dict or TOML path, optional
        A column map over ``t`` and the keys of ``quantities``; unnamed keys are looked up
        by their own name in the header.
    option : str
        The option or config key the map came from, for messages.

    Raises
    ------
    ValueError
        A missing file, column or unit, a unit of the wrong kind, bad stamps, no samples.
    """
    from sinslab.core.stamps import held_runs
    from sinslab.data.archive import plain_file
    from sinslab.data.tables import _fetch_allow_nan, _resolve_map, _source

    keys = ("t",) + tuple(quantities)
    kinds = {"t": ("time", "s"), **quantities}
    cmap = _columns.parse_column_map(columns, keys=keys, option=option)
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such file")
    with contextlib.ExitStack() as stack:
        plain = stack.enter_context(plain_file(path))
        src = _source(plain, cmap)
        cols, hline = src.cols, src.hline
        pick = _resolve_map(cols, src.raw, cmap, path, hline, option)
        names = [c[0] for c in cols]
        for k in keys:
            if k not in pick:
                if names.count(k) != 1:
                    raise ValueError(f"{where(path, hline)}: no column {k!r} among {', '.join(map(str, src.raw))}"
                                     f"; name it with {option} \"{k}=NAME[unit]\"")
                pick[k] = names.index(k)
        order = list(keys)
        a = _fetch_allow_nan(src, [pick[k] for k in order])
        lines = src.lines
        label = str(path) if plain == path else f"{path}:{plain.name}"
    vals, declared = {}, {}
    for j, k in enumerate(order):
        kind, default = kinds[k]
        un = cols[pick[k]][1] or default
        if un is None:
            raise ValueError(f"{where(label, hline)}: column {src.raw[pick[k]]!r} ({k}) has no unit; give it "
                             f"in the header ({k}[unit]) or the map ({option} \"{k}=NAME[unit]\")")
        try:
            vals[k] = a[:, j] * units.unit_scale(un, kind)
        except (ValueError, KeyError):
            raise ValueError(f"{where(label, hline)}: column {src.raw[pick[k]]!r} ({k}) has unit {un!r}, "
                             f"not a {kind.replace('_', ' ')} unit") from None
        declared[k] = un
    n = a.shape[0]
    if n == 0:
        raise ValueError(f"{label}: no samples")
    t = vals.pop("t")
    bad_t = ~np.isfinite(t)
    if bad_t.any():
        raise ValueError(f"{where(label, lines[int(np.argmax(bad_t))])}: time stamp is not a finite number")
    ok = np.all(np.isfinite(np.column_stack([vals[k] for k in quantities])), axis=1)
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        raise ValueError(f"{label}: no row with every value of {', '.join(quantities)}")
    check_stamps(t[idx], label, _Rows(lines, idx))
    held = None
    runs = held_runs(np.column_stack([vals[k][idx] for k in quantities]))
    if runs is not None:
        held = (int(idx.size), int(runs.size))
        idx = idx[runs]
    return SensorTable(t[idx], {k: v[idx] for k, v in vals.items()}, declared,
                       {k: str(src.raw[pick[k]]) for k in order}, label, int(n), int(n - ok.sum()), held)


class _Rows:
    """Line numbers of the kept rows ``idx`` (``lines[idx[i]]``)."""

    def __init__(self, lines, idx):
        self.lines, self.idx = lines, idx

    def __getitem__(self, i):
        return self.lines[int(self.idx[i])]


def check_channels(table: SensorTable, keys, *, share=SATURATED_SHARE):
    """Refuse a dead or saturated channel: one whose every value is the same, or that sits
    at its largest or smallest value in at least ``share`` of the rows (a sensor clipped at
    its range; an honest channel of a few thousand levels meets its extremes a handful of
    times). Raises ValueError naming the file, the column and what is wrong."""
    n = len(table)
    for k in keys:
        x = table.values[k]
        col = table.columns[k]
        if np.all(x == x[0]):
            raise ValueError(f"{table.path}: column {col!r} ({k}) is constant over all {n} rows "
                             f"({x[0] / units.unit_scale(table.units[k]):.6g} {table.units[k]}): a dead or "
                             "unconnected channel")
        for name, v in (("largest", x.max()), ("smallest", x.min())):
            at = int(np.sum(x == v))
            if at >= max(10, share * n):
                raise ValueError(f"{table.path}: column {col!r} ({k}) sits at its {name} value "
                                 f"{v / units.unit_scale(table.units[k]):.6g} {table.units[k]} in {at} of {n} "
                                 f"rows: saturated (clipped at the sensor's range)")


def read_magnetometer(path, columns=None, *, unit=None, frame="rfu", mount=None) -> SensorTable:
    """A three-axis magnetometer's table: ``t`` and the field ``mx my mz`` along the sensor
    axes, turned into the IMU body axes (RFU) by ``frame`` and ``mount`` as the IMU's own
    axes are (:func:`sinslab.data.frames.sensor_to_body`); a dead or saturated channel is
    refused.

    Parameters
    ----------
    path : str or Path
    columns : column map over ``t mx my mz`` (``"t=time[s], mx=mag_x[G], ..."``), optional
    unit : str, optional
        The field unit when neither the map nor the header gives one (``"G"``, ``"uT"``).
    frame, mount
        The sensor axes' convention and mount (as the IMU's ``--frame``/``--mount``).

    Returns
    -------
    SensorTable
        ``values["field"]`` (J, 3): the field in body axes [T]; ``units["mx"]`` the
        declared unit.
    """
    from sinslab.data.frames import sensor_to_body

    C = sensor_to_body(mount, frame)
    tab = read_sensor_table(path, {k: ("magnetic_field", unit) for k in MAG_KEYS}, columns=columns,
                            option="magnetometer.columns")
    check_channels(tab, MAG_KEYS)
    raw = np.column_stack([tab.values[k] for k in MAG_KEYS])
    return SensorTable(tab.t, {"field": raw @ C.T}, tab.units, tab.columns, tab.path, tab.rows, tab.dropped,
                       tab.held)


def read_barometer(path, columns=None, *, unit=None) -> SensorTable:
    """A barometric altimeter's table: ``t`` and the pressure height ``h`` (default unit m);
    a dead or saturated channel is refused. ``values["h"]`` (J,) [m]."""
    tab = read_sensor_table(path, {"h": ("length", unit or "m")}, columns=columns, option="barometer.columns")
    check_channels(tab, ("h",))
    return tab
