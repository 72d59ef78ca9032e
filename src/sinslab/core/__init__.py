"""Foundations every layer uses: units, the WGS-84 Earth model, the attitude convention,
data records (IMU increments, navigation series, states, fixes), progress reporting and
small validators. Imports numpy/scipy/numba only.
"""
