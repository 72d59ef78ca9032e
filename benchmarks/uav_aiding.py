"""Magnetometer and barometer aiding on the UMN UAV flights of ``onavdata`` (THOR): heading
and height error through GNSS outages, with and without each aid, against the unit's own
solution.

Run: ``.venv/bin/python benchmarks/uav_aiding.py [--flights THOR-Flight-75,THOR-Flight-60]
[--out FILE] [--keep DIR]``; ``.venv/bin/python benchmarks/record.py uav_aiding`` runs it
and stores its figures in ``docs/benchmarks.json``, the record docs/aiding.md quotes them
from. Needs the development extra (``onavdata``).

For each flight and each outage schedule (30 s every 90 s, 60 s every 120 s, the first
160 s after the first fix) it runs the command of docs/aiding.md (``sinslab navigate``
with the flight's IMU, fixes and, per variant, ``--aid magnetometer`` or ``--aid
barometer`` with their config keys) and compares the run's solution table with the
unit's own solution (``nav_attitude_data``: heading; ``nav_traj_data``: height): at the
last filter epoch before the GNSS returns ("end") and the largest over the outage
("through"), per outage, with the median and the largest over the outages, and the median
with the fixes (the two solutions' floor). The unit's solution is a GNSS/INS filter of
its own (no magnetometer, no barometer in it): the figures are differences between two
estimates, not errors against a truth.
"""
from __future__ import annotations

import argparse
import io
import json
import os
import sys
import tempfile
import zipfile
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("SINSLAB_QUIET", "1")

import numpy as np  # noqa: E402

#: flights developed on (the others of the package are kept for acceptance)
FLIGHTS = ("THOR-Flight-75", "THOR-Flight-60")
#: outage schedules (length/period@first, seconds from the first fix)
SCHEDULES = ("30/90@160", "60/120@160")
IMU_COLUMNS = ("t=time[s], gx=gyro_x[rad/s], gy=gyro_y[rad/s], gz=gyro_z[rad/s], ax=accel_x[m/s^2], "
               "ay=accel_y[m/s^2], az=accel_z[m/s^2]")
FIX_COLUMNS = "t=time[s], lat=gps_lat[deg], lon=gps_lon[deg], h=gps_alt[m], vn=gps_vn[m/s], ve=gps_ve[m/s], vd=gps_vd[m/s]"
#: the flights' date for the geomagnetic model: the package says 2012 (flight 79: 30 October);
#: the declination moves by a few hundredths of a degree a month there
DATE = "2012-07-01"


def flight_dir(name) -> Path:
    import importlib.util
    spec = importlib.util.find_spec("onavdata")
    if spec is None or spec.origin is None:
        sys.exit("uav_aiding: error: onavdata is not installed (pip install -e '.[dev]')")
    return (Path(spec.origin).parent / "data" / "2014-09-09 UofMN Conservancy 7 UAV Flights"
            / "Processed and Parsed Data" / name)


def command(d: Path, variant: str, outages: str, out: Path) -> list:
    """The ``sinslab navigate`` arguments of one run (docs/aiding.md)."""
    args = ["navigate", "--imu", str(d / "accel_data.txt.zip"), "--imu", str(d / "gyro_data.txt.zip"),
            "--frame", "frd", "--columns", IMU_COLUMNS, "--fixes", str(d / "gps_traj_data.txt.zip"),
            "--fixes", str(d / "gps_velocity_data.txt.zip"), "--fix-columns", FIX_COLUMNS,
            "--outages", outages, "--out", str(out)]
    if variant == "magnetometer":
        args += ["--aid", "magnetometer", "--set", f"magnetometer.file={d / 'mag_data.txt.zip'}",
                 "--set", "magnetometer.columns=t=time[s], mx=mag_x[G], my=mag_y[G], mz=mag_z[G]",
                 "--set", "magnetometer.frame=frd", "--set", f"magnetometer.date={DATE}"]
    elif variant == "barometer":
        args += ["--aid", "barometer", "--set", f"barometer.file={d / 'baroalt_data.txt.zip'}",
                 "--set", "barometer.columns=t=time[s], h=baro_alt[m]"]
    return args


def _table(d: Path, name: str) -> np.ndarray:
    with zipfile.ZipFile(d / f"{name}.txt.zip") as z:
        return np.genfromtxt(io.TextIOWrapper(z.open(z.namelist()[0])), delimiter=",", skip_header=1)


def outage_spans(run: Path):
    """``[(t_first, t_return), ...]`` [s, absolute]: the fixes the run left out (the
    ``in_outage`` rows of its fix table) and the first fix after them."""
    import pandas as pd
    sol = pd.read_parquet(run / "solution.parquet", columns=["t_s", "t_abs_s"])
    t0 = float(sol["t_abs_s"].iloc[0] - sol["t_s"].iloc[0])
    fe = np.genfromtxt(run / "fix_errors.csv", delimiter=",", names=True)
    t, inn = fe["t_s"] + t0, fe["in_outage"] > 0.5
    spans, k = [], 0
    while k < t.size:
        if inn[k]:
            j = k
            while j + 1 < t.size and inn[j + 1]:
                j += 1
            if j + 1 < t.size:
                spans.append((float(t[k - 1]) if k else float(t[k]), float(t[j + 1])))
            k = j + 1
        else:
            k += 1
    return spans


def compare(run: Path, d: Path) -> dict:
    """Heading and height of the run's solution minus the unit's own, through each outage."""
    import pandas as pd
    sol = pd.read_parquet(run / "solution.parquet", columns=["t_abs_s", "heading_deg", "h_m"])
    t = sol["t_abs_s"].to_numpy()
    att, pos = _table(d, "nav_attitude_data"), _table(d, "nav_traj_data")
    ref_h = np.degrees(np.interp(t, att[:, 0], np.unwrap(att[:, 1])))
    dpsi = (sol["heading_deg"].to_numpy() - ref_h + 180.0) % 360.0 - 180.0
    dh = sol["h_m"].to_numpy() - np.interp(t, pos[:, 0], pos[:, 3])
    rows = []
    spans = outage_spans(run)
    for a, b in spans:
        w = np.flatnonzero((t > a) & (t < b))
        e = w[-1]
        rows.append({"start_s": a, "end_s": b, "heading_end_deg": abs(float(dpsi[e])),
                     "heading_through_deg": float(np.max(np.abs(dpsi[w]))),
                     "height_end_m": abs(float(dh[e])), "height_through_m": float(np.max(np.abs(dh[w])))})
    out = np.zeros(t.size, bool)
    for a, b in spans:
        out |= (t > a) & (t < b + 10.0)
    summary = json.loads((run / "summary.json").read_text())["metrics"]
    res = {"outages": rows, "n_outages": len(rows),
           "heading_with_fixes_median_deg": float(np.median(np.abs(dpsi[~out]))),
           "heading_with_fixes_p95_deg": float(np.percentile(np.abs(dpsi[~out]), 95)),
           "height_with_fixes_median_m": float(np.median(np.abs(dh[~out])))}
    for what, unit in (("heading_end", "deg"), ("heading_through", "deg"), ("height_end", "m"),
                       ("height_through", "m")):
        v = np.array([r[f"{what}_{unit}"] for r in rows])
        res[f"{what}_median_{unit}"] = float(np.median(v))
        res[f"{what}_max_{unit}"] = float(np.max(v))
    res["aid_metrics"] = {k: v for k, v in summary.items() if k.startswith(("magnetometer_", "barometer_"))}
    return res


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--flights", default=",".join(FLIGHTS))
    p.add_argument("--out", default=None, help="write the figures as JSON")
    p.add_argument("--keep", default=None, help="keep the run folders here")
    a = p.parse_args(argv)
    from typer.testing import CliRunner

    from sinslab.cli import app
    runner = CliRunner()
    figures = {"date": DATE, "schedules": list(SCHEDULES)}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(a.keep or tmp)
        for fl in a.flights.split(","):
            d = flight_dir(fl)
            fk = "thor" + fl.rsplit("-", 1)[-1] if fl.startswith("THOR-Flight-") else fl
            figures[fk] = {}
            for sched in SCHEDULES:
                for variant in ("none", "magnetometer", "barometer"):
                    out = root / f"{fl}-{sched.split('/')[0]}s-{variant}"
                    r = runner.invoke(app, command(d, variant, sched, out))
                    if r.exit_code != 0:
                        sys.exit(f"uav_aiding: {fl} {sched} {variant} failed:\n{r.output}")
                    res = compare(out, d)
                    figures[fk].setdefault("s" + sched.split("/")[0], {})[variant] = res
                    print(f"{fl} {sched:>11s} {variant:>12s}: heading end {res['heading_end_median_deg']:5.2f}° "
                          f"(max {res['heading_end_max_deg']:5.2f}°), through max {res['heading_through_max_deg']:5.2f}°"
                          f" | height end {res['height_end_median_m']:6.2f} m (max {res['height_end_max_m']:6.2f} m), "
                          f"through max {res['height_through_max_m']:6.2f} m | with fixes "
                          f"{res['heading_with_fixes_median_deg']:.2f}°, {res['height_with_fixes_median_m']:.2f} m"
                          f" | {len(res['outages'])} outages", flush=True)
    if a.out:
        Path(a.out).write_text(json.dumps(figures, indent=1))


if __name__ == "__main__":
    main()
