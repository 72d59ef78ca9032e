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
