"""Reading and writing recorded data: one module per file format (:mod:`.psins`,
:mod:`.tables`, :mod:`.rtklib`, :mod:`.matlab`; other tools' files: :mod:`.navego`, :mod:`.kfgins`,
:mod:`.rosbag`), column maps (:mod:`.columns`), body-frame and mount matrices
(:mod:`.frames`), raw stamps -> uniform increments (:mod:`.increments`), and the front door
re-exported here (:mod:`.load`): ``load_imu``, ``read_imu``, ``read_fixes``, ``write_imu``,
``write_fixes``. Imports :mod:`sinslab.core`.
"""
from sinslab.core.records import Fixes
from sinslab.data.increments import ImuData
from sinslab.data.load import (FIX_FORMATS, IMU_FORMATS, guess_fix_format, guess_imu_format, load_fixes,
                               load_imu, read_fixes, read_imu, read_truth, write_fixes, write_imu)

__all__ = ["Fixes", "ImuData", "FIX_FORMATS", "IMU_FORMATS", "guess_fix_format", "guess_imu_format",
           "load_imu", "load_fixes", "read_fixes", "read_imu", "read_truth", "write_fixes", "write_imu"]
