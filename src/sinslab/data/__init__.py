"""Reading and writing recorded data: one module per file format, frame and mount
matrices, and the front door (``load_imu``, ``read_fixes``). Imports :mod:`sinslab.core`.
"""
