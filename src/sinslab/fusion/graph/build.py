"""The factor graph of an INS/GNSS record: keyframes, preintegrated IMU between them,
fix factors and priors (GTSAM objects; ``gtsam`` imported by the caller's
:func:`~sinslab.fusion.graph.translate.require_gtsam`).

Keyframes
---------
A keyframe (pose ``X``, velocity ``V``, bias ``B``) sits at the start, at the validity
time of every fix used and, where fixes are further apart than ``max_gap`` (an outage),
every ``max_gap`` seconds between them; the end of the filter grid closes the record. The
IMU sample that straddles a keyframe time is split there (GTSAM holds the rate constant
over a sample, so the split is exact in its model): a fix is compared with the state at
its own validity time, where the filter extrapolates it to its epoch with the INS
velocity. One ``CombinedImuFactor`` joins consecutive keyframes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sinslab.core import attitude as A
from sinslab.fusion.graph.translate import fix_covariance_w, pose_prior_covariance, robust_kernel

__all__ = ["Plan", "plan_keyframes", "Segments", "integrate", "fix_factors", "prior_factors"]


@dataclass(frozen=True)
class Plan:
    """Keyframe times and the fixes at them.

    Attributes
    ----------
    t : ndarray (K,)
        Keyframe times [s], strictly increasing; ``t[0]`` the start, ``t[-1]`` the end.
    fix_key : ndarray of int (J,)
        The keyframe of each fix used.
    fix_index : ndarray of int (J,)
        Rows of the used fixes in the fix arrays.
    """

    t: np.ndarray
    fix_key: np.ndarray
    fix_index: np.ndarray


def _used_fixes(fixes, t0, t1):
    """Rows of the fixes valid inside ``(t0, t1]``, outside the outages and, with
    windows, arriving inside one."""
    t = fixes.t
    keep = (t > t0 + 1e-9) & (t <= t1 + 1e-9)
    for s, ln in fixes.outages:
        keep &= ~((t >= s) & (t < s + ln))
    if fixes.windows is not None:
        w = np.asarray(fixes.windows, dtype=float).reshape(-1, 2)
        ta = fixes.arrive
        keep &= ((ta[:, None] >= w[:, 0] - 1e-9) & (ta[:, None] <= w[:, 1] + 1e-9)).any(1)
    return np.flatnonzero(keep)


def plan_keyframes(fixes, t0, t1, max_gap):
    """The :class:`Plan` of a run from ``t0`` to ``t1`` [s] (see the module notes)."""
    idx = _used_fixes(fixes, t0, t1)
    anchors = np.concatenate([[t0], fixes.t[idx], [t1]]) if idx.size == 0 or fixes.t[idx[-1]] < t1 - 1e-9 \
        else np.concatenate([[t0], fixes.t[idx]])
    ts = [anchors[:1]]
    for a, b in zip(anchors[:-1], anchors[1:]):
        m = int(np.ceil((b - a) / max_gap - 1e-9))
        ts.append(a + (b - a) * np.arange(1, m + 1) / m)
    t = np.concatenate(ts)
    key = np.searchsorted(t, fixes.t[idx] - 1e-9)
    return Plan(t, key.astype(np.int64), idx.astype(np.int64))


class Segments:
    """The IMU record cut at the keyframes: for every sample the rates and, per keyframe
    interval, the pieces ``(sample, duration)`` that make it (a sample split at a
    keyframe gives two pieces).

    GTSAM steps the velocity with the rotation at the start of each sample
    (``Δv_nav = R_k a dt``), where the increments sinslab reads are integrals over a
    rotating body: the accelerometer rate given to it is ``(Δv + ½ Δθ × Δv)/dt`` (the
    rotation term of the strapdown velocity update), which its Euler step then integrates
    to the increment's first order. Without it the error-free car of benchmarks/graph.py
    coasts 2.5 m off in 200 s, with it 0.34 m.

    Parameters
    ----------
    imu : ImuRecord
    start : int
        First sample used (the run starts at the end of sample ``start − 1``).
    t0 : float
        Start time [s].
    rotation_term : bool
        Add ``½ Δθ × Δv`` (False: the increments divided by dt, for the measurement of
        what the term does).
    """

    def __init__(self, imu, start, t0, rotation_term=True):
        self.dt = float(imu.dt)
        self.w = np.ascontiguousarray(imu.dtheta[start:] / self.dt)
        dth, dv = imu.dtheta[start:], imu.dv[start:]
        self.a = np.ascontiguousarray(((dv + 0.5 * np.cross(dth, dv)) if rotation_term else dv) / self.dt)
        self.t0 = float(t0)

    def pieces(self, ta, tb):
        """``[(sample, duration), ...]`` covering ``(ta, tb]``."""
        dt = self.dt
        ja = (ta - self.t0) / dt
        jb = (tb - self.t0) / dt
        out = []
        j = int(np.floor(ja + 1e-9))
        while j < jb - 1e-9:
            lo = max(ja, j)
            hi = min(jb, j + 1)
            if hi - lo > 1e-9:
                out.append((min(j, self.w.shape[0] - 1), (hi - lo) * dt))
            j += 1
        return out


def integrate(gtsam, params, seg, ta, tb, bias, marks=(), on_mark=None):
    """Preintegrate ``(ta, tb]`` from the bias estimate ``bias`` (ConstantBias); at each
    of ``marks`` (increasing times inside it) ``on_mark(pim)`` is called with the
    preintegration up to that time. Returns ``(pim, [on_mark results])``."""
    pim = gtsam.PreintegratedCombinedMeasurements(params, bias)
    got = []
    marks = [m for m in marks if m > ta + 1e-12]
    tcur = ta
    for j, d in seg.pieces(ta, tb):
        while marks and marks[0] <= tcur + d + 1e-9:
            # a mark inside the piece: split it there
            d1 = marks.pop(0) - tcur
            if d1 > 1e-12:
                pim.integrateMeasurement(seg.a[j], seg.w[j], d1)
                tcur += d1
                d -= d1
            got.append(on_mark(pim))
        if d > 1e-12:
            pim.integrateMeasurement(seg.a[j], seg.w[j], d)
            tcur += d
    got += [on_mark(pim) for _ in marks]
    return pim, got


def _velocity_factor(gtsam, kx, kv, v_fix, wl, noise):
    """Antenna velocity ``v + R (ω × l)`` against a fix (w axes): ``wl = ω × l`` (body)."""
    skew = -A.skew(wl)
    eye = np.eye(3)

    def err(this, values, H):
        # GTSAM calls this back at every linearisation: no temporaries beyond the needed
        R = values.atPose3(kx).rotation().matrix()
        if H is not None:
            J = np.zeros((3, 6))
            np.matmul(R, skew, out=J[:, :3])
            H[0] = J
            H[1] = eye
        return values.atVector(kv) + R @ wl - v_fix

    return gtsam.CustomFactor(noise, [kx, kv], err)


def fix_factors(gtsam, frame, fixes, plan, seg, lever, robust, keys, stage="batch", gyro_bias=np.zeros(3)):
    """Position (``GPSFactorArm``: ``t + R l`` against the fix) and velocity factors of the
    used fixes, robust when ``robust`` is set (the kernel of ``stage``:
    :func:`~sinslab.fusion.graph.translate.robust_kernel`); returns ``{keyframe: [factors]}``.
    The lever arm's rate term uses the gyro rate of the fix's sample less ``gyro_bias``
    (the start's compensation)."""
    nm = gtsam.noiseModel
    kern = robust_kernel(robust, stage)
    X, V = keys
    idx = plan.fix_index
    pw = frame.to_w(fixes.pos[idx, 0], fixes.pos[idx, 1], fixes.pos[idx, 2])
    Rwn = frame.R_wn(fixes.pos[idx, 0], fixes.pos[idx, 1])
    out = {}
    for m, (j, k) in enumerate(zip(idx, plan.fix_key)):
        g = nm.Gaussian.Covariance(fix_covariance_w(fixes.sigma[j], Rwn[m]))
        fs = [gtsam.GPSFactorArm(X(k), pw[m], lever, g if kern is None else nm.Robust.Create(kern, g))]
        if fixes.vel is not None:
            S = Rwn[m] @ np.diag(fixes.vel_sigma[j] ** 2) @ Rwn[m].T
            gv = nm.Gaussian.Covariance(S)
            gv = gv if kern is None else nm.Robust.Create(kern, gv)
            vw = Rwn[m] @ fixes.vel[j]
            s = min(int(np.floor((fixes.t[j] - seg.t0) / seg.dt)), seg.w.shape[0] - 1)
            wl = np.cross(seg.w[s] - gyro_bias, lever)
            if np.any(lever):
                fs.append(_velocity_factor(gtsam, X(k), V(k), vw, wl, gv))
            else:
                fs.append(gtsam.PriorFactorVector(V(k), vw, gv))
        out.setdefault(int(k), []).extend(fs)
    return out


def prior_factors(gtsam, frame, init_row, bias0, P0, layout, keys):
    """Priors on the first keyframe from the initial state, its compensation and ``P0``."""
    X, V, B = keys
    Rwb, v, p = (a[0] for a in frame.rows_to_w(init_row))
    Rwn = frame.R_wn(init_row[7], init_row[8])
    Cx, Cv, Cb = pose_prior_covariance(P0, layout, Rwb, Rwn, init_row[7], init_row[9])
    nm = gtsam.noiseModel
    pose = gtsam.Pose3(gtsam.Rot3(Rwb), p)
    return [gtsam.PriorFactorPose3(X(0), pose, nm.Gaussian.Covariance(Cx)),
            gtsam.PriorFactorVector(V(0), v, nm.Gaussian.Covariance(Cv)),
            gtsam.PriorFactorConstantBias(B(0), bias0, nm.Gaussian.Covariance(Cb))], pose, v
