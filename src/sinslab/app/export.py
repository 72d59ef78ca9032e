"""A run's track for map tools: KML (Google Earth) and GeoJSON (QGIS, web maps).

The track is the run's navigation solution (a ``navigate`` run's ``solution`` series) or,
for an experiment, its truth or solution series: any series of the run with ``t_s``,
``lat_deg`` and ``lon_deg`` columns (and ``h_m`` when it has one). A ``navigate`` run's
``fixes`` series adds the GNSS fixes, each marked used or withheld in an outage; the outage
windows mark the parts of the track navigated without fixes. A run folder from before
the ``fixes`` series (``fix_errors`` only) still gives its outages.

Both files are written through the standard library (``xml.etree`` and ``json``):

- KML 2.2: a document with the track split into GNSS-aided and outage lines, one point
  per fix in its own folder, styles by kind. Coordinates are ``lon,lat,h``; the heights are
  ellipsoidal (WGS-84), so the lines are drawn clamped to the ground.
- GeoJSON (RFC 7946): a FeatureCollection of ``LineString`` features (``kind`` "track" or
  "outage", ``t_start_s``, ``t_end_s``) and ``Point`` features (``kind`` "fix", ``t_s``,
  ``used``), positions ``[lon, lat, h]`` in degrees and metres.
"""
from __future__ import annotations

import json
import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sinslab.app.errors import CliError
from sinslab.app.outputs import MARKER, is_run_dir
from sinslab.core.atomic import atomic_write

__all__ = ["FORMATS", "Track", "read_track", "outage_windows", "kml_text", "geojson_text", "export_run"]

#: export formats and their file suffixes
FORMATS = {"kml": ".kml", "geojson": ".geojson"}

_KML_NS = "http://www.opengis.net/kml/2.2"


@dataclass
class Track:
    """A run's track, its fixes and its outage windows, in degrees, metres and seconds.

    ``t`` [s] run time, ``lat``/``lon`` [deg], ``h`` [m] ellipsoidal (NaN where unknown);
    ``fix_*`` the GNSS fixes (empty when the run has none), ``fix_used`` False for a fix
    withheld in an outage; ``outages`` ``[(start, end)]`` [s]; ``name`` the run's name and
    ``source`` the series the track was read from.
    """

    name: str
    source: str
    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    fix_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    fix_lat: np.ndarray = field(default_factory=lambda: np.zeros(0))
    fix_lon: np.ndarray = field(default_factory=lambda: np.zeros(0))
    fix_h: np.ndarray = field(default_factory=lambda: np.zeros(0))
    fix_used: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    outages: list[tuple[float, float]] = field(default_factory=list)

    def segments(self) -> list[tuple[str, slice]]:
        """``[(kind, index slice)]`` of the track split at the outage windows: kind
        ``"track"`` (aided) or ``"outage"``; neighbouring segments share their boundary
        point, so the drawn line has no gaps."""
        edges = []
        for a, b in self.outages:
            # from the last epoch at or before the window's start to the first at or after its end
            i = max(int(np.searchsorted(self.t, a, side="right")) - 1, 0)
            j = min(int(np.searchsorted(self.t, b, side="left")), self.t.size - 1)
            if j > i:
                edges.append((i, j))
        out, k = [], 0
        for i, j in edges:
            if i > k:
                out.append(("track", slice(k, i + 1)))
            out.append(("outage", slice(i, j + 1)))
            k = j
        if k < self.t.size - 1 or not out:
            out.append(("track", slice(k, self.t.size)))
        return out


def outage_windows(t_fix: np.ndarray, in_outage: np.ndarray) -> list[tuple[float, float]]:
    """Outage windows ``[(start, end)]`` [s] from the fix times and their outage flags: an
    outage starts at the first withheld fix of a run of them and ends at the next fix that
    is used (the last withheld fix when none follows)."""
    t_fix = np.asarray(t_fix, dtype=float)
    flag = np.asarray(in_outage).astype(bool)
    out, k = [], 0
    while k < flag.size:
        if not flag[k]:
            k += 1
            continue
        j = k
        while j + 1 < flag.size and flag[j + 1]:
            j += 1
        end = t_fix[j + 1] if j + 1 < flag.size else t_fix[j]
        out.append((float(t_fix[k]), float(end)))
        k = j + 1
    return out


def _series(summary: dict) -> dict[str, dict]:
    return {s["name"]: s for s in summary.get("series") or [] if isinstance(s, dict) and "name" in s}


def _read_table(run: Path, info: dict):
    import pandas as pd

    name = info.get("parquet") if info.get("parquet") and (run / info["parquet"]).is_file() else info.get("csv")
    if not name or not (run / name).is_file():
        raise CliError(f"export: {run}: the series {info['name']!r} has no file in the run folder")
    try:
        return pd.read_parquet(run / name) if name.endswith(".parquet") else pd.read_csv(run / name)
    except (OSError, ValueError) as e:
        raise CliError(f"export: {run / name}: unreadable ({e})") from None


def _track_series(series: dict[str, dict]) -> dict | None:
    """The series to draw: ``solution``, then ``truth``, then any with a time and a
    position column."""
    def is_track(s: dict) -> bool:
        return {"t_s", "lat_deg", "lon_deg"} <= set(s.get("columns") or [])

    for name in ("solution", "truth"):
        if name in series and is_track(series[name]):
            return series[name]
    return next((s for s in series.values() if is_track(s)), None)


def read_track(run: str | os.PathLike) -> Track:
    """The track of the run folder ``run`` (see the module's docstring).

    Raises :class:`~sinslab.app.errors.CliError` naming the problem for a folder that is not
    a sinslab run and for a run without a track.
    """
    run = Path(run)
    if not run.is_dir():
        raise CliError(f"export: {run}: no such folder" if not run.exists() else f"export: {run} is a file, "
                       f"not a run folder")
    summary_file = run / "summary.json"
    if not is_run_dir(run) or not summary_file.is_file():
        raise CliError(f"export: {run} is not a sinslab run folder (no {MARKER} marker and summary.json)")
    try:
        summary = json.loads(summary_file.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise CliError(f"export: {summary_file}: unreadable ({e})") from None
    series = _series(summary)
    info = _track_series(series)
    if info is None:
        what = summary.get("experiment") or "this run"
        raise CliError(f"export: {run}: the run ({what}) has no track (no series with t_s, lat_deg and "
                       f"lon_deg columns)")
    df = _read_table(run, info).sort_values("t_s")
    t = df["t_s"].to_numpy(float)
    h = df["h_m"].to_numpy(float) if "h_m" in df else np.full(t.size, np.nan)
    tr = Track(run.resolve().name, info["name"], t, df["lat_deg"].to_numpy(float), df["lon_deg"].to_numpy(float), h)
    if "fixes" in series:
        fx = _read_table(run, series["fixes"]).sort_values("t_s")
        tr.fix_t = fx["t_s"].to_numpy(float)
        tr.fix_lat, tr.fix_lon = fx["lat_deg"].to_numpy(float), fx["lon_deg"].to_numpy(float)
        tr.fix_h = fx["h_m"].to_numpy(float) if "h_m" in fx else np.full(tr.fix_t.size, np.nan)
        flags = fx["in_outage"].to_numpy() if "in_outage" in fx else np.zeros(tr.fix_t.size)
        tr.fix_used = ~flags.astype(bool)
        tr.outages = outage_windows(tr.fix_t, flags)
    elif "fix_errors" in series and "in_outage" in (series["fix_errors"].get("columns") or []):
        fe = _read_table(run, series["fix_errors"]).sort_values("t_s")
        tr.outages = outage_windows(fe["t_s"].to_numpy(float), fe["in_outage"].to_numpy())
    return tr


def _coords(lon: np.ndarray, lat: np.ndarray, h: np.ndarray) -> list[list[float]]:
    return [[round(float(x), 9), round(float(y), 9)] + ([round(float(z), 3)] if math.isfinite(z) else [])
            for x, y, z in zip(lon, lat, h)]


def _kml_coords(lon: np.ndarray, lat: np.ndarray, h: np.ndarray) -> str:
    return " ".join(",".join(repr(v) for v in c) for c in _coords(lon, lat, h))


def _sub(parent: ET.Element, tag: str, text: str | None = None, **attrib: str) -> ET.Element:
    el = ET.SubElement(parent, f"{{{_KML_NS}}}{tag}", attrib)
    if text is not None:
        el.text = text
    return el


def _kml_style(doc: ET.Element, sid: str, line: str | None = None, width: float = 3.0,
               icon_color: str | None = None, scale: float = 0.4) -> None:
    st = _sub(doc, "Style", id=sid)
    if line:
        ls = _sub(st, "LineStyle")
        _sub(ls, "color", line)
        _sub(ls, "width", f"{width:g}")
    if icon_color:
        ic = _sub(st, "IconStyle")
        _sub(ic, "color", icon_color)
        _sub(ic, "scale", f"{scale:g}")
        icon = _sub(ic, "Icon")
        _sub(icon, "href", "http://maps.google.com/mapfiles/kml/shapes/shaded_dot.png")
        _sub(_sub(st, "LabelStyle"), "scale", "0")


def kml_text(track: Track) -> str:
    """The track as a KML 2.2 document (see the module's docstring)."""
    ET.register_namespace("", _KML_NS)
    root = ET.Element(f"{{{_KML_NS}}}kml")
    doc = _sub(root, "Document")
    _sub(doc, "name", f"sinslab {track.name}")
    _sub(doc, "description", f"{track.source} of the run {track.name}: {track.t.size} points, "
                             f"{track.fix_t.size} GNSS fixes, {len(track.outages)} outages; heights are "
                             f"ellipsoidal (WGS-84), lines clamped to the ground")
    # KML colours are aabbggrr
    _kml_style(doc, "track", line="ffff7f00")
    _kml_style(doc, "outage", line="ff0000ff", width=4.0)
    _kml_style(doc, "fix", icon_color="ff00c000")
    _kml_style(doc, "fix-withheld", icon_color="ff9e9e9e")
    lines = _sub(doc, "Folder")
    _sub(lines, "name", "track")
    for kind, sl in track.segments():
        pm = _sub(lines, "Placemark")
        t0, t1 = float(track.t[sl][0]), float(track.t[sl][-1])
        _sub(pm, "name", f"{'outage' if kind == 'outage' else 'aided'} {t0:.1f}–{t1:.1f} s")
        _sub(pm, "styleUrl", f"#{kind}")
        ext = _sub(pm, "ExtendedData")
        for key, value in (("kind", kind), ("t_start_s", f"{t0:.3f}"), ("t_end_s", f"{t1:.3f}")):
            _sub(_sub(ext, "Data", name=key), "value", value)
        ls = _sub(pm, "LineString")
        _sub(ls, "tessellate", "1")
        _sub(ls, "altitudeMode", "clampToGround")
        _sub(ls, "coordinates", _kml_coords(track.lon[sl], track.lat[sl], track.h[sl]))
    if track.fix_t.size:
        fixes = _sub(doc, "Folder")
        _sub(fixes, "name", "GNSS fixes")
        for k in range(track.fix_t.size):
            pm = _sub(fixes, "Placemark")
            used = bool(track.fix_used[k])
            _sub(pm, "name", f"fix {track.fix_t[k]:.2f} s{'' if used else ' (withheld: outage)'}")
            _sub(pm, "styleUrl", "#fix" if used else "#fix-withheld")
            ext = _sub(pm, "ExtendedData")
            for key, value in (("kind", "fix"), ("t_s", f"{track.fix_t[k]:.3f}"), ("used", str(used).lower())):
                _sub(_sub(ext, "Data", name=key), "value", value)
            pt = _sub(pm, "Point")
            _sub(pt, "coordinates", _kml_coords(track.fix_lon[k:k + 1], track.fix_lat[k:k + 1],
                                                track.fix_h[k:k + 1]))
    ET.indent(root, space=" ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def geojson_text(track: Track) -> str:
    """The track as a GeoJSON FeatureCollection (see the module's docstring)."""
    feats = []
    for kind, sl in track.segments():
        feats.append({"type": "Feature",
                      "geometry": {"type": "LineString",
                                   "coordinates": _coords(track.lon[sl], track.lat[sl], track.h[sl])},
                      "properties": {"kind": kind, "t_start_s": float(track.t[sl][0]),
                                     "t_end_s": float(track.t[sl][-1])}})
    for k in range(track.fix_t.size):
        feats.append({"type": "Feature",
                      "geometry": {"type": "Point",
                                   "coordinates": _coords(track.fix_lon[k:k + 1], track.fix_lat[k:k + 1],
                                                          track.fix_h[k:k + 1])[0]},
                      "properties": {"kind": "fix", "t_s": float(track.fix_t[k]),
                                     "used": bool(track.fix_used[k])}})
    doc = {"type": "FeatureCollection", "name": f"sinslab {track.name}",
           "properties": {"source": track.source, "outages_s": [list(o) for o in track.outages],
                          "height": "ellipsoidal (WGS-84) [m]"},
           "features": feats}
    return json.dumps(doc, separators=(",", ":")) + "\n"


def export_run(run: str | os.PathLike, to: str, out: str | os.PathLike | None = None) -> Path:
    """Write the track of the run folder ``run`` as ``to`` (``"kml"`` or ``"geojson"``) to
    ``out`` (default: beside the run folder, ``RUN.kml`` / ``RUN.geojson``); return the path.

    Everything is checked before anything is written, and the file is written atomically:
    a bad input (:class:`~sinslab.app.errors.CliError`) leaves no file behind.
    """
    fmt = str(to).lower()
    if fmt not in FORMATS:
        raise CliError(f"export: unknown format {to!r}: choose one of {', '.join(FORMATS)}")
    run = Path(run)
    track = read_track(run)
    path = Path(out) if out is not None else run.resolve().with_suffix(FORMATS[fmt])
    if path.is_dir():
        raise CliError(f"export: --out {path} is a folder; give a file name")
    if not path.parent.is_dir():
        raise CliError(f"export: --out {path}: the folder {path.parent} does not exist")
    for anc in path.resolve().parents:
        if is_run_dir(anc):
            raise CliError(f"export: --out {path} is inside the run folder {anc}: a run folder holds "
                           f"what its run wrote; write the file beside it")
    text = kml_text(track) if fmt == "kml" else geojson_text(track)
    try:
        atomic_write(path, text)
    except OSError as e:
        raise CliError(f"export: cannot write {path} ({e.strerror or e})") from None
    return path
