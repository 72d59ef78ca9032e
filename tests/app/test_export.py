"""``sinslab export RUN --to kml|geojson``: the written file parsed back (coordinates, the
outage segments, the fixes and their used/withheld marks), and the bad inputs (a folder
that is not a run, a run without a track, an unknown format) as one line, exit 2, nothing
written."""
import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from sinslab.app.commands.runner import Command, Output, Series, run_command
from sinslab.app.export import outage_windows, read_track
from sinslab.cli import app

KML = "{http://www.opengis.net/kml/2.2}"
#: outages of the made-up run: fixes at 1 Hz withheld in [20, 35) and [60, 70) s
OUTAGES = [(20.0, 35.0), (60.0, 70.0)]


def _drive(tmp: Path, with_fixes: bool = True) -> Path:
    """A run folder as ``navigate`` writes one: a 10 Hz solution of a 100 s drive along a
    circle and its 1 Hz fixes with their outage flags."""
    t = np.arange(0.0, 100.0 + 1e-9, 0.1)
    lat = 40.0 + 1e-3 * np.sin(t / 20)
    lon = -105.0 + 1e-3 * np.cos(t / 20)
    h = 1600.0 + 0.1 * t
    tf = np.arange(0.0, 100.0 + 1e-9, 1.0)
    flag = np.zeros(tf.size, int)
    for a, b in OUTAGES:
        flag[(tf >= a) & (tf < b)] = 1
    fixes = {"t_s": tf, "lat_deg": np.interp(tf, t, lat) + 1e-7, "lon_deg": np.interp(tf, t, lon),
             "h_m": np.interp(tf, t, h), "in_outage": flag}
    tables = [Series("solution", {"t_s": t, "lat_deg": lat, "lon_deg": lon, "h_m": h})]
    if with_fixes:
        tables.append(Series("fixes", fixes))
    tables.append(Series("fix_errors", {"t_s": tf, "east_m": tf * 0, "north_m": tf * 0, "up_m": tf * 0,
                                        "in_outage": flag}))
    out = tmp / "drive"
    run_command(Command("navigate", "test drive"), out,
                lambda: Output(config={"imu": "made up"}, metrics={"duration_s": 100.0}, tables=tables),
                echo=lambda s: None)
    return out


def _cli(*args):
    return CliRunner().invoke(app, list(args))


def test_outage_windows_from_flags():
    t = np.arange(10.0)
    assert outage_windows(t, [0, 1, 1, 0, 0, 1, 0, 0, 1, 1]) == [(1.0, 3.0), (5.0, 6.0), (8.0, 9.0)]
    assert outage_windows(t, np.zeros(10)) == []


def test_kml_parses_back_with_track_outages_and_fixes(tmp_path):
    run = _drive(tmp_path)
    r = _cli("export", str(run), "--to", "kml")
    assert r.exit_code == 0, r.output
    path = tmp_path / "drive.kml"
    assert r.output.strip() == str(path.resolve())
    doc = ET.parse(path).getroot().find(f"{KML}Document")
    folders = {f.findtext(f"{KML}name"): f for f in doc.findall(f"{KML}Folder")}
    lines = folders["track"].findall(f"{KML}Placemark")
    kinds = [pm.findtext(f"{KML}styleUrl") for pm in lines]
    assert kinds == ["#track", "#outage", "#track", "#outage", "#track"]
    pts = [np.array([[float(v) for v in c.split(",")] for c in
                     pm.find(f".//{KML}coordinates").text.split()]) for pm in lines]
    # the segments join end to start and together hold every solution epoch once
    for a, b in zip(pts, pts[1:]):
        assert np.array_equal(a[-1], b[0])
    whole = np.vstack([pts[0]] + [p[1:] for p in pts[1:]])
    tr = read_track(run)
    assert whole.shape == (tr.t.size, 3)
    np.testing.assert_allclose(whole[:, 0], tr.lon, atol=1e-9)
    np.testing.assert_allclose(whole[:, 1], tr.lat, atol=1e-9)
    np.testing.assert_allclose(whole[:, 2], tr.h, atol=1e-3)
    # an outage line spans its window: from the first withheld fix's time to the next used fix's
    for pm, (a, b) in zip([pm for pm in lines if pm.findtext(f"{KML}styleUrl") == "#outage"], OUTAGES):
        data = {d.get("name"): float(d.findtext(f"{KML}value")) for d in pm.iter(f"{KML}Data")
                if d.get("name") != "kind"}
        assert data["t_start_s"] == pytest.approx(a) and data["t_end_s"] == pytest.approx(b)
    fixes = folders["GNSS fixes"].findall(f"{KML}Placemark")
    assert len(fixes) == 101
    withheld = [pm for pm in fixes if pm.findtext(f"{KML}styleUrl") == "#fix-withheld"]
    assert len(withheld) == 15 + 10
    lon, lat, h = map(float, fixes[0].find(f".//{KML}coordinates").text.split(","))
    assert (lon, lat) == pytest.approx((tr.fix_lon[0], tr.fix_lat[0]), abs=1e-9)


def test_geojson_parses_back(tmp_path):
    run = _drive(tmp_path)
    out = tmp_path / "maps" / "d.geojson"
    out.parent.mkdir()
    r = _cli("export", str(run), "--to", "geojson", "--out", str(out))
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    assert doc["type"] == "FeatureCollection"
    lines = [f for f in doc["features"] if f["geometry"]["type"] == "LineString"]
    points = [f for f in doc["features"] if f["geometry"]["type"] == "Point"]
    assert [f["properties"]["kind"] for f in lines] == ["track", "outage", "track", "outage", "track"]
    assert doc["properties"]["outages_s"] == [list(o) for o in OUTAGES]
    assert len(points) == 101 and sum(not f["properties"]["used"] for f in points) == 25
    tr = read_track(run)
    first = np.array(lines[0]["geometry"]["coordinates"][0])
    np.testing.assert_allclose(first, [tr.lon[0], tr.lat[0], tr.h[0]], atol=1e-9)


def test_older_run_without_fixes_keeps_its_outages(tmp_path):
    run = _drive(tmp_path, with_fixes=False)
    tr = read_track(run)
    assert tr.fix_t.size == 0 and tr.outages == OUTAGES


def _nothing_written(tmp_path, args, message):
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    r = _cli("export", *args)
    assert r.exit_code == 2, r.output
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("sinslab: error: export:") and message in lines[0], r.output
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


def test_bad_input_one_line_exit_2_nothing_written(tmp_path):
    plain = tmp_path / "plain"
    plain.mkdir()
    (plain / "solution.csv").write_text("t_s,lat_deg,lon_deg\n0,1,2\n")
    _nothing_written(tmp_path, [str(plain), "--to", "kml"], "is not a sinslab run folder")
    _nothing_written(tmp_path, [str(tmp_path / "missing"), "--to", "kml"], "no such folder")
    notrack = tmp_path / "notrack"
    run_command(Command("allan", "no track"), notrack,
                lambda: Output(config={}, metrics={}, tables=[Series("allan", {"tau_s": [1.0, 2.0]})]),
                echo=lambda s: None)
    _nothing_written(tmp_path, [str(notrack), "--to", "geojson"], "has no track")
    run = _drive(tmp_path)
    _nothing_written(tmp_path, [str(run), "--to", "shp"], "unknown format 'shp'")
    _nothing_written(tmp_path, [str(run), "--to", "kml", "--out", str(run / "track.kml")],
                     "inside the run folder")
