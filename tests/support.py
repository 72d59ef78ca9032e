"""Shared test inputs (importable from every test module: pytest puts this folder on
``sys.path`` because it holds the root ``conftest.py``)."""
import numpy as np

from sinslab.core import attitude, earth
from sinslab.core.records import ImuRecord


def static_imu(lat, att, dt, n, h=0.0, gyro_err=(0.0, 0.0, 0.0), accel_err=(0.0, 0.0, 0.0)):
    """Exact output of an IMU at rest, ``n`` samples at ``dt`` [s]: Δθ = (C_n^b ω_ie^n + ε) dt,
    Δv = (C_n^b [0, 0, g] + ∇) dt with constant body-frame errors ε [rad/s], ∇ [m/s²]
    (zero by default), attitude ``att`` = [pitch, roll, yaw] [rad], latitude [rad]."""
    C = attitude.euler_to_dcm(att)
    wb = C.T @ earth.wie_n(lat) + np.asarray(gyro_err, float)
    fb = C.T @ np.array([0.0, 0.0, float(earth.gravity(lat, h))]) + np.asarray(accel_err, float)
    t = dt * np.arange(1, n + 1)
    return ImuRecord(t, np.tile(wb * dt, (n, 1)), np.tile(fb * dt, (n, 1)), dt)


def simulated_car_drive(segments):
    """A car drive near 40.1° N, 105.1° W, 1600 m (heading 30°) along ``segments`` at
    100 Hz with a consumer-MEMS IMU (biases 0.1/−0.05/0.15 °/s, 0.05/−0.03/0.1 m/s²,
    ARW 0.0038 °/√s, VRW 70 µg/√Hz, seed 1) and 4 Hz position + velocity fixes (1 cm,
    2 cm/s noise from ``default_rng(2)``).

    Returns ``(imu, fixes, truth, errors, rng)``; ``rng`` is the generator the fix noise
    came from, to draw any further noise of the same drive from.
    """
    import math

    from sinslab.core.records import Fixes
    from sinslab.sim import imu as IM
    from sinslab.sim import trajectory as tr

    g = tr.generate(segments, tr.Start(lat=math.radians(40.1), lon=math.radians(-105.1), h=1600.0,
                                       heading=math.radians(30)), 0.01)
    err = IM.ImuErrors.from_datasheet(gyro_bias=["0.1 deg/s", "-0.05 deg/s", "0.15 deg/s"],
                                      accel_bias=["0.05 m/s^2", "-0.03 m/s^2", "0.1 m/s^2"],
                                      gyro_arw="0.0038 deg/sqrt(s)", accel_vrw="70 ug/sqrt(Hz)")
    imu = IM.apply(g.imu, err, 1)
    tru = g.truth
    rng = np.random.default_rng(2)
    k = np.arange(0, len(tru.t), 25)[1:]
    fx = Fixes(tru.t[k], tru.lat[k] + rng.normal(0, 0.01, k.size) / 6.37e6, tru.lon[k], tru.h[k],
               np.full((k.size, 3), 0.01), tru.vel[k] + rng.normal(0, 0.02, (k.size, 3)),
               np.full((k.size, 3), 0.05), np.ones(k.size, int))
    return imu, fx, tru, err, rng


def run_experiment(name, sets=(), quick=True):
    """The :class:`sinslab.experiments.base.Result` of one experiment run in this process
    (``--quick`` configuration unless ``quick=False``, ``--set`` lines ``sets``, Monte Carlo
    serial), without a run folder."""
    import tempfile
    from pathlib import Path

    import sinslab.experiments as E
    from sinslab.app.config import resolve
    from sinslab.experiments.base import RunContext

    exp = E.get(name)
    cfg = resolve(exp.config, quick=exp.quick if quick else None, sets=list(sets))
    with tempfile.TemporaryDirectory() as d:
        return exp.run(cfg, RunContext(name=name, out=Path(d), seed=cfg.seed, runs=cfg.runs, quick=quick,
                                       scheduler="sync"))
