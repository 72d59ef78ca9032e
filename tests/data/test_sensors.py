"""sinslab.data.sensors: an aiding sensor's table read with its units, and the refusals of
a missing unit, a dead or saturated channel and another clock."""
import zipfile

import numpy as np
import pytest

from sinslab.data import sensors as S

MAG = {"mx": ("magnetic_field", None), "my": ("magnetic_field", None), "mz": ("magnetic_field", None)}


def _mag_csv(path, header="t[s],mx[uT],my[uT],mz[uT]", n=200, rows=None):
    rng = np.random.default_rng(0)
    t = 0.02 * np.arange(n)
    m = np.column_stack([20 + rng.normal(size=n), -5 + rng.normal(size=n), 50 + rng.normal(size=n)])
    if rows is not None:
        m = rows(m)
    text = header + "\n" + "\n".join(",".join(f"{v:.4f}" for v in (ti, *mi)) for ti, mi in zip(t, m))
    path.write_text(text.replace("nan", ""))
    return t, m


def test_units_from_the_header_or_the_map_and_empty_rows_counted(tmp_path):
    p = tmp_path / "mag.csv"
    t, m = _mag_csv(p, rows=lambda m: np.where(np.arange(len(m))[:, None] == 7, np.nan, m))
    tab = S.read_sensor_table(p, MAG)
    assert len(tab) == 199 and tab.dropped == 1 and tab.units["mx"] == "uT"
    np.testing.assert_allclose(tab.values["mz"], np.delete(m[:, 2], 7) * 1e-6, atol=1e-10)
    # a map over other names, zipped, in gauss
    q = tmp_path / "raw.csv"
    _mag_csv(q, header="time,mag_x,mag_y,mag_z")
    z = tmp_path / "raw.zip"
    with zipfile.ZipFile(z, "w") as zf:
        zf.write(q, "raw.csv")
    tab = S.read_sensor_table(z, MAG, columns="t=time[s], mx=mag_x[G], my=mag_y[G], mz=mag_z[G]")
    assert tab.path.endswith("raw.zip:raw.csv") and tab.units["my"] == "G"
    assert tab.values["mx"][0] == pytest.approx(float(q.read_text().splitlines()[1].split(",")[1]) * 1e-4)


def test_a_missing_or_wrong_unit_is_one_line(tmp_path):
    p = tmp_path / "mag.csv"
    _mag_csv(p, header="t[s],mx,my[uT],mz[uT]")
    with pytest.raises(ValueError, match=r"mag.csv:1: column 'mx' \(mx\) has no unit"):
        S.read_sensor_table(p, MAG)
    _mag_csv(p, header="t[s],mx[m],my[uT],mz[uT]")
    with pytest.raises(ValueError, match="has unit 'm', not a magnetic field unit"):
        S.read_sensor_table(p, MAG)
    with pytest.raises(ValueError, match="no column 'h'"):
        S.read_sensor_table(p, {"h": ("length", "m")})


def test_a_dead_or_saturated_channel_is_refused(tmp_path):
    p = tmp_path / "mag.csv"
    _mag_csv(p, rows=lambda m: np.column_stack([m[:, 0], np.full(len(m), 3.5), m[:, 2]]))
    with pytest.raises(ValueError, match=r"column 'my\[uT\]' \(my\) is constant over all 200 rows \(3.5 uT\)"):
        S.check_channels(S.read_sensor_table(p, MAG), ("mx", "my", "mz"))
    _mag_csv(p, rows=lambda m: np.column_stack([m[:, 0], m[:, 1], np.minimum(m[:, 2], 50.5)]))
    with pytest.raises(ValueError, match=r"'mz\[uT\]' \(mz\) sits at its largest value 50.5 uT in \d+ of 200 rows"):
        S.check_channels(S.read_sensor_table(p, MAG), ("mx", "my", "mz"))
    S.check_channels(S.read_sensor_table(p, MAG), ("mx", "my"))


def test_another_clock_is_refused(tmp_path):
    p = tmp_path / "mag.csv"
    _mag_csv(p)
    tab = S.read_sensor_table(p, MAG)
    from sinslab.core.stamps import check_time_base
    check_time_base(tab.t, -1.0, 10.0, tab.path)
    with pytest.raises(ValueError, match=r"mag.csv: its times 0.000..3.980 s do not overlap the IMU record "
                                         r"345600.000..345700.000 s \(covered 0%\): a different time base"):
        check_time_base(tab.t, 345600.0, 345700.0, tab.path)


def test_magnetometer_axes_turned_like_the_imus(tmp_path):
    """A forward-right-down sensor's field in sinslab's right-forward-up body axes:
    x_body = y_sensor, y_body = x_sensor, z_body = −z_sensor."""
    p = tmp_path / "mag.csv"
    t, m = _mag_csv(p, header="time,mag_x,mag_y,mag_z")
    tab = S.read_magnetometer(p, "t=time[s], mx=mag_x, my=mag_y, mz=mag_z", unit="uT", frame="frd")
    np.testing.assert_allclose(tab.values["field"], np.column_stack([m[:, 1], m[:, 0], -m[:, 2]]) * 1e-6,
                               atol=1e-10)
    assert tab.units["mx"] == "uT"
