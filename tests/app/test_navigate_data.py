"""A navigate run's results as data: ``RecordedNav.to_pandas()`` against the run folder's
``solution``/``smoothed`` tables (two writers of the same columns), and ``--kml`` (the
track, the fixes and the outages beside the run folder) parsed back against the fixes
file and the outage windows. One simulated car drive, navigated once."""
import dataclasses
import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd
import pytest

from sinslab.core import units as u
from sinslab.data import write_fixes
from sinslab.sim import trajectory as tr
from support import simulated_car_drive

KML = "{http://www.opengis.net/kml/2.2}"
OUTAGE = (45.0, 10.0)           # [s] after the first fix, length


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    from sinslab.app.commands.navigate import navigate_config, navigate_files

    d = tmp_path_factory.mktemp("drive")
    segs = [tr.Static(duration=20.0), tr.Accelerate(duration=5.0, accel=2.0), tr.Level(duration=15.0),
            tr.Turn(duration=10.0, rate=9 * u.deg, coordinated=False), tr.Level(duration=25.0)]
    imu, fx, _, _, _ = simulated_car_drive(segs)
    write_fixes(d / "fixes.csv", fx)
    a = np.column_stack([imu.t, imu.dtheta, imu.dv])
    np.savetxt(d / "imu.csv", a, delimiter=",", comments="", fmt="%.17g",
               header="t[s],dtheta_x[rad],dtheta_y[rad],dtheta_z[rad],dv_x[m/s],dv_y[m/s],dv_z[m/s]")
    cfg = navigate_config(imu=[d / "imu.csv"], fixes=[d / "fixes.csv"], outages=f"{OUTAGE[0]:g}:{OUTAGE[1]:g}",
                          smooth=True, kml=True)
    summary, res, ref = navigate_files(cfg, out=d / "run", echo=lambda line: None)
    return d, res, ref


def test_to_pandas_is_the_solution_table(drive):
    d, res, _ = drive
    df = res.to_pandas()
    sol = pd.read_parquet(d / "run" / "solution.parquet")
    assert list(df.columns) == list(sol.columns)
    assert len(df) == len(res.t) == len(sol)
    np.testing.assert_allclose(df.to_numpy(), sol.to_numpy(), rtol=1e-12, atol=1e-9)
    # the heading (clockwise from north, 0-360) and σ in display units
    assert df.heading_deg.between(0, 360).all()
    i = list(res.labels).index("phiU")
    np.testing.assert_allclose(df.sigma_phiU_arcmin * u.arcmin, res.sigma[:, i], rtol=1e-12)


def test_to_pandas_smoothed_is_the_smoothed_table(drive):
    d, res, _ = drive
    df = res.to_pandas(smoothed=True)
    smo = pd.read_parquet(d / "run" / "smoothed.parquet")
    for c in ("lat_deg", "lon_deg", "h_m", "vE_mps", "pitch_deg", "heading_deg", "sigma_phiU_arcmin"):
        np.testing.assert_allclose(df[c], smo[f"smo_{c}"], rtol=1e-12, atol=1e-9, err_msg=c)
    with pytest.raises(ValueError, match="not smoothed"):
        dataclasses.replace(res, smoothed=None).to_pandas(smoothed=True)


def test_kml_beside_the_run_has_the_track_the_fixes_and_the_outage(drive):
    d, res, ref = drive
    root = ET.parse(d / "run.kml").getroot()
    marks = root.iter(f"{KML}Placemark")
    kinds = {}
    for pm in marks:
        data = {e.get("name"): e.find(f"{KML}value").text for e in pm.iter(f"{KML}Data")}
        kinds.setdefault(data["kind"], []).append((pm, data))
    assert [d_["kind"] for _, d_ in kinds["outage"]] == ["outage"]          # one outage window
    _, od = kinds["outage"][0]
    t_first = ref.t[0] - res.t[0]                     # run times are from the solution's first epoch
    assert float(od["t_start_s"]) == pytest.approx(t_first + OUTAGE[0], abs=0.1)
    assert float(od["t_end_s"]) == pytest.approx(t_first + OUTAGE[0] + OUTAGE[1], abs=0.1)
    # every fix inside the solution's span, withheld exactly inside the outage, at its position
    inside = (ref.t >= res.t[0]) & (ref.t <= res.t[-1])
    fixes = kinds["fix"]
    assert len(fixes) == inside.sum()
    t_fix = np.array([float(d_["t_s"]) for _, d_ in fixes]) + res.t[0]
    used = np.array([d_["used"] == "true" for _, d_ in fixes])
    t_out = ref.t[0] + OUTAGE[0]
    np.testing.assert_array_equal(~used, (t_fix >= t_out) & (t_fix < t_out + OUTAGE[1]))
    lon_lat = np.array([[float(v) for v in pm.find(f".//{KML}coordinates").text.split(",")[:2]] for pm, _ in fixes])
    np.testing.assert_allclose(lon_lat[:, 1], np.degrees(ref.lat[inside]), atol=1e-9)
    np.testing.assert_allclose(lon_lat[:, 0], np.degrees(ref.lon[inside]), atol=1e-9)


def test_kml_option_is_a_key_of_the_configuration():
    from sinslab.app.commands.navigate import navigate_config

    assert navigate_config(imu=["i.csv"], fixes=["f.csv"], kml=True).output.kml
    assert not navigate_config(imu=["i.csv"], fixes=["f.csv"]).output.kml
