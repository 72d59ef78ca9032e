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
# numpy asks the kernel for transparent huge pages on every array of 4 MB or more; where
# the kernel compacts memory to find them on demand (its default THP "defrag" setting),
# the first touch of such an array costs ~2 ms of system time per 2 MB — 0.28 s for a
# 120 MB history on the development machine against 0.05 s with ordinary pages, ~0.5 s of
# a 1 h full-rate navigate. The long arrays here are streamed through once, where huge
# pages save little. Off unless the user chose otherwise; applies as the thread setting.
_os.environ.setdefault("NUMPY_MADVISE_HUGEPAGE", "0")

__version__ = "0.1.0"
