"""A log in another vendor's style, for the "bringing your own unit" tests and docs.

Semicolon-delimited text with a preamble of comment lines, indexed column names without
units (``DeltaTheta[0]`` rad, ``DeltaVel[0]`` m/s, in the *sensor* axes), GPS time of
week in seconds, a temperature, a text status word and a 0/1 zero-velocity flag; the
sensor is mounted in a forward-right-down vehicle frame with a rotation given as a
quaternion. The column map and mount that read it are :data:`COLUMNS` and :data:`MOUNT`.
"""
import numpy as np

from sinslab.core import attitude as A
from sinslab.data import frames

#: sensor -> vehicle (FRD) rotation: a unit quaternion, scalar first (about 90° yaw, 2° roll)
MOUNT_EULER_DEG = (2.0, 0.0, 90.0)          # pitch, roll, yaw in sinslab's convention
MOUNT = "quat:" + ",".join(f"{x:.12f}" for x in A.dcm_to_quat(A.euler_to_dcm(np.radians(MOUNT_EULER_DEG))))
FRAME = "frd"
COLUMNS = ("t=GPSTimeOfWeek[s], dtheta_x=DeltaTheta[0][rad], dtheta_y=DeltaTheta[1][rad], "
           "dtheta_z=DeltaTheta[2][rad], dv_x=DeltaVel[0][m/s], dv_y=DeltaVel[1][m/s], "
           "dv_z=DeltaVel[2][m/s], stationary=ZeroVelFlag")
HEADER = ("GPSTimeOfWeek;DeltaTheta[0];DeltaTheta[1];DeltaTheta[2];DeltaVel[0];DeltaVel[1];"
          "DeltaVel[2];Temperature (degC);Status;ZeroVelFlag")


def write_foreign_log(path, imu, flags=None, week_seconds=345600.0):
    """Write ``imu`` (increments in sinslab's RFU body axes) as the vendor's log: rotated
    into the sensor axes of :data:`MOUNT` in the :data:`FRAME` vehicle frame, times shifted
    to GPS seconds of week. ``flags`` (N,) bool: the zero-velocity column."""
    R = frames.sensor_to_body(MOUNT, FRAME)            # sensor -> RFU
    dth = imu.dtheta @ R                              # RFU -> sensor (R orthogonal)
    dv = imu.dv @ R
    n = len(imu)
    flags = np.zeros(n, bool) if flags is None else np.asarray(flags, bool)
    import pandas as pd
    cols = HEADER.split(";")
    df = pd.DataFrame({cols[0]: imu.t + week_seconds, **{c: dth[:, i] for i, c in enumerate(cols[1:4])},
                       **{c: dv[:, i] for i, c in enumerate(cols[4:7])},
                       cols[7]: np.round(21.5 + 0.01 * np.arange(n), 2),
                       cols[8]: np.where(flags, "STILL", "NAV"), cols[9]: flags.astype(int)})
    with open(path, "w") as fh:
        fh.write("% ACME NAV-200 export v3.1\n% serial 0042, firmware 7.2\n")
        df.to_csv(fh, sep=";", index=False, float_format="%.17g")
    return path


# ------------------------------------------------------------- a foreign unit's fixes ---
#: a commercial INS/GNSS unit's export of its receiver's solution: dotted names, ``time``,
#: NED velocity, a solution-mode column (4 RTK fixed, 2 DGNSS, 1 single, 0 none), the
#: 1 Hz fixes held and repeated in every row of its 50 Hz log
FIX_HEADER = ("time,InsGnssBIT.InsMode,GnssPosition.Latitude,GnssPosition.Longitude,"
              "GnssPosition.AltitudeHAE,GnssVelocity.North,GnssVelocity.East,GnssVelocity.Down,"
              "GnssPosition.StdDevN,GnssPosition.StdDevE,GnssPosition.StdDevU,GnssSolution.Mode")
FIX_COLUMNS = ("t=time[s], lat=GnssPosition.Latitude[deg], lon=GnssPosition.Longitude[deg], "
               "h=GnssPosition.AltitudeHAE[m], vn=GnssVelocity.North[m/s], ve=GnssVelocity.East[m/s], "
               "vd=GnssVelocity.Down[m/s], sd_n=GnssPosition.StdDevN[m], sd_e=GnssPosition.StdDevE[m], "
               "sd_u=GnssPosition.StdDevU[m], quality=GnssSolution.Mode")


def jittered_stamps(t0, t1, step=1.000019, jitter=0.0, rng=None):
    """Stamps from ``t0`` to ``t1`` every ``step`` s (a receiver 19 ppm off the logger's
    clock), each moved by a uniform ±``jitter`` s."""
    t = np.arange(t0, t1, step)
    if jitter:
        t = t + (rng or np.random.default_rng(5)).uniform(-jitter, jitter, t.size)
    return t


def fixes_at(truth, t, rng, pos_sigma=0.02, vel_sigma=0.02, lever=None, imu=None):
    """Fixes of the truth at any times ``t`` (linear interpolation between its samples),
    with white noise of ``pos_sigma`` [m] and ``vel_sigma`` [m/s]; with ``lever`` (IMU ->
    antenna, body RFU [m]) and the ``imu`` record (for the body rate) those of the antenna."""
    from sinslab.core.earth import radii
    from sinslab.core.records import Fixes
    lat, lon, h = (np.interp(t, truth.t, x) for x in (truth.lat, truth.lon, truth.h))
    vel = np.stack([np.interp(t, truth.t, truth.vel[:, i]) for i in range(3)], -1)
    rm, rn = radii(lat, h)
    if lever is not None:
        i = np.clip(np.rint((t - truth.t[0]) / (truth.t[1] - truth.t[0])).astype(int), 0, truth.t.size - 1)
        C = A.euler_to_dcm(truth.att[i])
        d = C @ np.asarray(lever, float)
        w = np.stack([np.interp(t, imu.t - imu.dt / 2, imu.dtheta[:, k] / imu.dt) for k in range(3)], -1)
        vel = vel + np.einsum("kij,kj->ki", C, np.cross(w, lever))
        lat, lon, h = lat + d[:, 1] / rm, lon + d[:, 0] / (rn * np.cos(lat)), h + d[:, 2]
    e = rng.normal(0, pos_sigma, (t.size, 3))
    return Fixes(t, lat + e[:, 0] / rm, lon + e[:, 1] / (rn * np.cos(lat)), h + e[:, 2],
                 np.full((t.size, 3), pos_sigma), vel + rng.normal(0, vel_sigma, (t.size, 3)),
                 np.full((t.size, 3), max(vel_sigma, 0.01)), np.full(t.size, 4))


def write_foreign_fixes(path, fx, rows_t=None, mode=None, compress=None):
    """Write ``fx`` in the unit's layout (:data:`FIX_HEADER`): one row per ``rows_t`` stamp
    (default: one per fix) holding the latest fix at or before it (rows before the first
    fix are left out); ``mode`` (J,) the solution mode per fix (default 4); ``compress``
    None, ``"gz"`` or ``"zip"`` (the CSV inside the archive). Returns the path written."""
    import gzip
    import io
    import zipfile
    rows_t = fx.t if rows_t is None else np.asarray(rows_t, float)
    j = np.searchsorted(fx.t, rows_t + 1e-12, side="right") - 1
    keep = j >= 0
    rows_t, j = rows_t[keep], j[keep]
    mode = np.full(len(fx), 4) if mode is None else np.asarray(mode)
    cols = [rows_t, np.full(j.size, 3), np.degrees(fx.lat[j]), np.degrees(fx.lon[j]), fx.h[j],
            fx.vel[j, 1], fx.vel[j, 0], -fx.vel[j, 2], fx.sigma[j, 0], fx.sigma[j, 1], fx.sigma[j, 2],
            mode[j]]
    buf = io.StringIO()
    buf.write(FIX_HEADER + "\n")
    np.savetxt(buf, np.column_stack(cols), delimiter=",", fmt="%.12f")
    text = buf.getvalue()
    if compress is None:
        open(path, "w").write(text)
    elif compress == "gz":
        with gzip.open(path, "wt") as fh:
            fh.write(text)
    elif compress == "zip":
        with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr("gnss_export.csv", text)
    else:
        raise ValueError(compress)
    return path
