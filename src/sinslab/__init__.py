"""sinslab: strapdown inertial navigation toolkit.

Conventions: navigation frame ENU, body frame RFU, attitude ``[pitch, roll, yaw]`` with
``C_b^n = R_z(yaw) R_x(pitch) R_y(roll)``, SI units inside (see :mod:`sinslab.core.units`).
"""
__version__ = "0.1.0"
