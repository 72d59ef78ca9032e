"""Reading and writing recorded data: one module per file format (:mod:`.psins`,
:mod:`.tables`, :mod:`.rtklib`, :mod:`.matlab`; other tools' files: :mod:`.navego`, :mod:`.kfgins`,
:mod:`.rosbag`), column maps (:mod:`.columns`), body-frame and mount matrices
(:mod:`.frames`), raw stamps -> uniform increments (:mod:`.increments`), and the front door
re-exported here (:mod:`.load`): ``load_imu``, ``read_imu``, ``read_fixes``, ``write_imu``,
``write_fixes``, and the readers of aids' own inputs (``read_odometer``, ``read_magnetometer``,
``read_barometer``; an aid of
:mod:`sinslab.fusion.aids` reads through these ``read_*`` names). Imports :mod:`sinslab.core`.
"""
from sinslab.core.records import Fixes
from sinslab.data.increments import ImuData
from sinslab.data.load import (FIX_FORMATS, IMU_FORMATS, guess_fix_format, guess_imu_format, load_fixes,
                               load_imu, read_fixes, read_imu, read_truth, write_fixes, write_imu)
from sinslab.data.odometer import read_odometer
from sinslab.data.sensors import read_barometer, read_magnetometer

__all__ = ["Fixes", "ImuData", "FIX_FORMATS", "IMU_FORMATS", "guess_fix_format", "guess_imu_format",
           "load_imu", "load_fixes", "read_fixes", "read_imu", "read_truth", "write_fixes", "write_imu",
           "read_odometer", "read_magnetometer", "read_barometer"]
