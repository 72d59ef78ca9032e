"""The filter's model translated once into GTSAM's: IMU noise and bias random walk as
preintegration parameters, the initial covariance as prior factors, a fix's σ as a noise
model (robust when asked).

What translates exactly
-----------------------
- White gyro and accelerometer noise: the filter's spectral densities ``q = ARW²``,
  ``VRW²`` [rad²/s, m²/s³] are GTSAM's continuous-time gyroscope and accelerometer
  covariances (per axis, diagonal).
- Bias random walks: the densities of the ``eps``/``nabla`` blocks (``rrw²``) are
  ``setBiasOmegaCovariance``/``setBiasAccCovariance``. A random-constant bias (density 0)
  would make the bias chain of ``CombinedImuFactor`` singular: it gets the floor
  :data:`RW_FLOOR` (a wander of 0.03 °/h and 0.3 µg over an hour, far below any bias σ
  a recorded run starts from), and :attr:`GraphImuModel.floored` says so.
- Bias sign: the filter's bias state is ``true − compensation``; GTSAM's bias is the
  compensation (``measured − bias`` is used), so the graph's bias is sinslab's
  ``gyro_bias``/``accel_bias`` compensation and its error is ``−eps``, ``−nabla``.

What the graph cannot take (refused by :meth:`GraphImuModel.from_error_model`): Gauss–Markov
sensor states, scale factors, lever-arm, odometer, barometer or fix-error states, a
horizontal or held vertical channel — ``CombinedImuFactor`` knows a body-frame
random-walk bias of both sensors and nothing else.

Priors: the filter's ``P0`` over ``x = [φ, δv, δp, ε, ∇]`` maps to GTSAM's tangent spaces
by ``δθ_b = −C_n^b φ`` (``R ← R Exp(δθ)`` against ``C ← (I − φ×) C``), ``δt_b = C_w^b δp_w``
(Pose3 translation steps are body-axis), ``δv_w = C_n^w δv``, ``δb = −(ε, ∇)``; the blocks
pose / velocity / bias become three prior factors, exact when ``P0`` has no covariance
between them (the filter's diagonal ``P0`` of every sinslab run).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sinslab.core import earth as E
from sinslab.core.errors import InputError

__all__ = ["GraphImuModel", "RW_FLOOR", "require_gtsam", "pose_prior_covariance", "fix_covariance_w",
           "robust_kernel"]

#: floors of the bias random walks [rad/s/√s], [m/s²/√s] (see the module notes)
RW_FLOOR = (1e-7 * np.pi / 180 * 3.0, 1e-7 * 50.0)
#: GTSAM's integration covariance [m²/s]: the position is the integral of the velocity
#: (no process noise of its own in the filter); 1e-8 m²/s (a wander of 6 mm in an hour) keeps
#: the preintegrated covariance well conditioned for the incremental solver
INTEGRATION_COV = 1e-8


def require_gtsam():
    """The ``gtsam`` module, or one line naming the extra that installs it."""
    try:
        import gtsam
    except ImportError:
        raise InputError("the graph estimator needs GTSAM: pip install 'sinslab[graph]'") from None
    return gtsam


@dataclass(frozen=True)
class GraphImuModel:
    """White noise and bias random walks per axis (body), SI units.

    Attributes
    ----------
    gyro_arw, accel_vrw : ndarray (3,)
        [rad/√s], [m/s/√s].
    gyro_rrw, accel_rrw : ndarray (3,)
        Bias random walks [rad/s/√s], [m/s²/√s] as used (floored).
    floored : tuple of str
        Which random walks were raised to :data:`RW_FLOOR`.
    """

    gyro_arw: np.ndarray
    accel_vrw: np.ndarray
    gyro_rrw: np.ndarray
    accel_rrw: np.ndarray
    floored: tuple = ()

    @classmethod
    def from_error_model(cls, model, clock=False):
        """The filter's :class:`sinslab.nav.errstate.ErrorModel` (full core, body-frame
        gyro and accelerometer bias blocks on all three axes, nothing else; with
        ``clock`` a receiver-clock block too, which the raw GNSS graph makes variables of
        its own, :mod:`sinslab.fusion.graph.raw`)."""
        lay = model.layout
        extra = [n for n in lay.names if n not in ("phi", "dv", "dp")]
        if getattr(model, "core", None) != "full":
            raise InputError(f"the graph estimator needs the full 9-state core, the model has "
                             f"{getattr(model, 'core', type(model).__name__)!r}")
        bias = {}
        other = []
        for s in model.sensor_blocks:
            if s.kind == "bias" and s.frame == "body" and s.axes == "xyz" and s.sensor in ("gyro", "accel"):
                bias[s.sensor] = s
            elif not (clock and s.kind == "clock"):
                other.append(s.name)
        other += [n for n in extra if n not in {b.name for b in model.sensor_blocks}]
        extra = [n for n in extra if n not in {b.name for b in model.sensor_blocks if clock and b.kind == "clock"}]
        if other or set(bias) != {"gyro", "accel"}:
            raise InputError("the graph estimator takes a random-walk gyro and accelerometer bias and "
                             f"nothing else (CombinedImuFactor); the model has {', '.join(extra) or 'no sensor'} states")
        garw, avrw = model.white_noise
        rrw = [np.sqrt(bias["gyro"].q), np.sqrt(bias["accel"].q)]
        floored = []
        for i, (name, fl) in enumerate(zip(("gyro", "accel"), RW_FLOOR)):
            if np.any(rrw[i] < fl):
                floored.append(name)
                rrw[i] = np.maximum(rrw[i], fl)
        if not (np.all(garw > 0) and np.all(avrw > 0)):
            raise InputError("the graph estimator needs white gyro and accelerometer noise on every axis")
        return cls(garw, avrw, rrw[0], rrw[1], tuple(floored))

    def params(self, frame, at=None, centrifugal=True):
        """GTSAM ``PreintegrationCombinedParams`` in the world frame of ``frame``
        (:class:`sinslab.fusion.graph.frame.LocalFrame`): normal gravity at the w point
        ``at`` (None: at the origin, GTSAM's usual constant gravity), less the centrifugal
        term GTSAM adds (``centrifugal``, with ``at``), the Earth rate as the Coriolis rate
        of the frame."""
        gtsam = require_gtsam()
        g = frame.gravity_w(at)
        if at is not None and centrifugal:
            # GTSAM adds the centrifugal term −ω×(ω×p) of the frame's origin-relative
            # position p; normal gravity holds the whole centrifugal part already
            w = frame.earth_rate_w()
            g = g + np.cross(w, np.cross(w, np.asarray(at, dtype=float)))
        p = gtsam.PreintegrationCombinedParams(g)
        p.setGyroscopeCovariance(np.diag(self.gyro_arw ** 2))
        p.setAccelerometerCovariance(np.diag(self.accel_vrw ** 2))
        p.setBiasOmegaCovariance(np.diag(self.gyro_rrw ** 2))
        p.setBiasAccCovariance(np.diag(self.accel_rrw ** 2))
        p.setIntegrationCovariance(INTEGRATION_COV * np.eye(3))
        p.setOmegaCoriolis(frame.earth_rate_w())
        return p


def _metres(lat, h):
    """``diag`` turning ``[δL, δλ, δh]`` [rad, rad, m] into east, north, up [m] (the
    columns reordered: the result's rows are E, N, U)."""
    rm, rn = (float(v) for v in E.radii(lat, h))
    M = np.zeros((3, 3))
    M[0, 1] = rn * np.cos(lat)                 # radii() include the height
    M[1, 0] = rm
    M[2, 2] = 1.0
    return M


def pose_prior_covariance(P0, layout, R_wb, R_wn, lat, h):
    """Prior covariances ``(pose 6×6, velocity 3×3, bias 6×6)`` in GTSAM's tangent
    spaces from the filter's ``P0`` (see the module notes). ``R_wb``, ``R_wn`` at the
    start; ``lat``, ``h`` of the start [rad, m]."""
    P0 = np.asarray(P0, dtype=float)
    n = layout.n
    s = {k: layout.slice(k) for k in ("phi", "dv", "dp", "eps", "nabla")}
    # the rows of J: gtsam tangent [δθ_b, δt_b | δv_w | δb_acc, δb_gyro] from x
    J = np.zeros((15, n))
    R_bn = R_wb.T @ R_wn
    J[0:3, s["phi"]] = -R_bn
    J[3:6, s["dp"]] = R_wb.T @ R_wn @ _metres(lat, h)
    J[6:9, s["dv"]] = R_wn
    J[9:12, s["nabla"]] = -np.eye(3)        # GTSAM's ConstantBias vector is (acc, gyro)
    J[12:15, s["eps"]] = -np.eye(3)
    C = J @ P0 @ J.T
    C = 0.5 * (C + C.T)
    return C[0:6, 0:6], C[6:9, 6:9], C[9:15, 9:15]


def fix_covariance_w(sigma_neu, R_wn):
    """A fix's σ north, east, up [m] (3,) as a w covariance (3, 3)."""
    s = np.asarray(sigma_neu, dtype=float)
    S_n = np.diag([s[1] ** 2, s[0] ** 2, s[2] ** 2])       # ENU
    return R_wn @ S_n @ R_wn.T


def robust_kernel(robust, stage="batch"):
    """GTSAM's m-estimator for a robust weighting (:class:`sinslab.fusion.measurements.
    schedule.RobustWeighting`; None: none). Huber keeps its k0; Chang's whole-fix rule is
    Huber on the Mahalanobis distance with k = √χ²₃(1 − p); IGG-III, which GTSAM lacks, is
    Tukey's biweight with c = k1 (a residual past k1 σ gets no weight) in the batch stage,
    and Huber with k0 in the online pass: a redescending kernel needs a start near the
    answer (the graph whitens by the fix σ alone, not by the state's uncertainty as the
    filter's innovation does), and from the online pass's values it has one."""
    if robust is None:
        return None
    gtsam = require_gtsam()
    me = gtsam.noiseModel.mEstimator
    if robust.kind == "igg3" and stage == "batch":
        return me.Tukey.Create(robust.k1)
    if robust.kind == "chang":
        return me.Huber.Create(float(np.sqrt(robust.limit(3))))
    return me.Huber.Create(robust.k0)
