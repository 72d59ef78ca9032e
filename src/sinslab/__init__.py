"""sinslab: strapdown inertial navigation toolkit.

Conventions: navigation frame ENU, body frame RFU, attitude ``[pitch, roll, yaw]`` with
``C_b^n = R_z(yaw) R_x(pitch) R_y(roll)``, SI units inside (see :mod:`sinslab.core.units`).
"""
import os as _os

# sinslab's matrices are small (tens of states, Van Loan blocks of twice that): a
# multi-threaded BLAS spends more on hand-offs between threads than on the arithmetic
# (a 32×32 expm: ~10× the CPU time on a 2-core machine) and oversubscribes the cores
# Monte Carlo workers already use. One BLAS thread unless the user chose otherwise; it
# applies when sinslab is imported before numpy (the CLI) and to the worker processes.
for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")
del _var

__version__ = "0.1.0"
