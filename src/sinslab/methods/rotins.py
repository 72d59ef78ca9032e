"""Joint error model of two rotation-modulated INS on one carrier, its online evaluation
index and its observability along a rotate-stop schedule.

Wang, Wu et al. (2018), online evaluation of a dual-axis rotation-modulated INS against a
single-axis one on the same ship: both INS navigate on their own; a joint Kalman filter of
the pair (INS 1, INS k) uses the difference of their horizontal positions and velocities
as measurement and estimates, among others, INS 1's azimuth gyro drift ε_z1. The
scatter of that estimate over a sliding window is the evaluation index of INS k's random
error.

Frames and units as in :mod:`sinslab.nav.errstate` (ENU navigation frame, RFU body
frames, errors computed minus true, SI inside).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sinslab.estimation import observability as obs
from sinslab.nav.errstate import DifferenceModel, NavPoint, accel_bias, gyro_bias

__all__ = ["joint_rotation_model", "windowed_std", "joint_subsystem", "ScheduleObservability",
           "schedule_observability"]


def joint_rotation_model(gyro_noise1=0.0, gyro_noisek=0.0, accel_noise1=0.0, accel_noisek=0.0,
                         radius_derivatives=False) -> DifferenceModel:
    """The 17-state joint error model of INS 1 (single-axis) and INS k (dual-axis)
    (Wang, Wu et al. 2018, eqs 1–8).

    State order (paper eq 1)::

        x1 = [δL δλ δvE δvN]_1k                      (differences, 1 − k)
        x2 = [φE φN φU]_1k, ε_1 (x y z, body 1), ε_k (x y z, body k),
             ∇_1 (x y, body 1), ∇_k (x y, body k)

    Horizontal core (vertical channel damped by a depth gauge), random-constant drifts
    and biases; the noise vector is ``[w_g1 (3), w_a1 (x,y), w_gk (3), w_ak (x,y)]``
    (paper eq 7 orders gyros first; only the column order differs). With
    ``radius_derivatives=False`` F equals the paper's eqs 3–6 (tested).

    Parameters
    ----------
    gyro_noise1, gyro_noisek : float or (3,)
        Gyro white noise (ARW) of INS 1 / INS k [rad/√s].
    accel_noise1, accel_noisek : float or (2,)
        Horizontal accelerometer white noise (VRW) of INS 1 / INS k [m/s/√s].
    radius_derivatives : bool
        Keep the dR/dL and ∂g/∂L terms (exact Jacobian) instead of the paper's F.

    Returns
    -------
    DifferenceModel
        ``F(nav1, navk)`` of shape ``S + (17, 17)``; block names ``dp dv phi eps_1 eps_k
        nabla_1 nabla_k``.
    """
    return DifferenceModel(
        "horizontal", [gyro_bias(name="eps"), accel_bias("xy", name="nabla")],
        [gyro_bias(name="eps"), accel_bias("xy", name="nabla")],
        gyro_noise1, gyro_noisek, accel_noise1, accel_noisek, accel_noise_axes="xy",
        order=["dp", "dv", "phi", "eps_1", "eps_k", "nabla_1", "nabla_k"],
        radius_derivatives=radius_derivatives)


def windowed_std(t, x, start, window):
    """Online evaluation index: standard deviation of an estimate over consecutive windows
    (Wang, Wu et al. 2018, eq 21).

    Window j covers ``start + j·window ≤ t < start + (j+1)·window``; only windows inside
    ``[t[0], t[-1]]`` are evaluated. Inside a window of N samples the index is the
    population deviation ``sqrt(1/N Σ (x_i − μ)²)`` (1/N as in eq 21).

    Parameters
    ----------
    t : array (M,)
        Sample times [s], strictly increasing.
    x : array (M,) or (M, k)
        The estimate (e.g. ε_z1 [rad/s]) at ``t``; columns are evaluated separately.
    start : float
        Start of the first window [s] (same time origin as ``t``); before ``t[-1]``.
    window : float
        Window length [s], > 0 and at most ``t[-1] − max(start, t[0])``.

    Returns
    -------
    t_end : ndarray (J,)
        End time of each window [s].
    std : ndarray (J,) or (J, k)
        Deviation per window, in the units of ``x``.

    Raises
    ------
    ValueError
        One line naming the problem (bad window, start, span, shapes or empty window).
    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"windowed_std: t must be 1-D with at least 2 samples, got shape {t.shape}")
    if x.shape[:1] != t.shape:
        raise ValueError(f"windowed_std: x must have {t.size} rows like t, got shape {x.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)):
        raise ValueError("windowed_std: t must be finite and strictly increasing")
    if not np.all(np.isfinite(x)):
        raise ValueError("windowed_std: x has non-finite values")
    start, window = float(start), float(window)
    if not (np.isfinite(window) and window > 0):
        raise ValueError(f"windowed_std: window must be > 0 s, got {window}")
    if not (np.isfinite(start) and start < t[-1]):
        raise ValueError(f"windowed_std: start {start} s is not before the last sample {t[-1]} s")
    span = t[-1] - max(start, t[0])
    if window > span:
        raise ValueError(f"windowed_std: window {window} s is longer than the {span} s from start to the end")
    first = max(start, t[0])
    # windows are counted from ``start``; one that would begin before the record is skipped
    j0 = int(np.ceil((first - start) / window - 1e-12))
    J = int(np.floor((t[-1] - start) / window + 1e-12)) - j0
    if J < 1:
        raise ValueError(f"windowed_std: no full {window} s window counted from {start} s lies inside "
                         f"[{t[0]}, {t[-1]}] s")
    edges = start + window * np.arange(j0, j0 + J + 1)
    idx = np.searchsorted(t, edges, side="left")
    out = []
    for a, b in zip(idx[:-1], idx[1:]):
        if b == a:
            raise ValueError(f"windowed_std: a {window} s window holds no sample; the sampling is too sparse")
        seg = x[a:b]
        out.append(np.sqrt(np.mean((seg - seg.mean(axis=0)) ** 2, axis=0)))
    return edges[1:], np.array(out)


# ----------------------------------------------------------------------- observability
def _measured_blocks(model):
    lay = model.layout
    x1 = np.concatenate([np.arange(lay.slice(b).start, lay.slice(b).stop) for b in ("dp", "dv")])
    x2 = np.setdiff1d(np.arange(lay.n), x1)
    return x1, x2


def joint_subsystem(model: DifferenceModel, C1n, Ckn, lat, h=0.0):
    """The unmeasured subsystem ``(A, C) = (F22, F12)`` of the joint model at one stop.

    The measurement gives the difference states x1 = [δL δλ δvE δvN]_1k directly, so
    (F, H) is observable exactly when ``ẋ2 = F22 x2``, ``y = F12 x2`` is (Wang, Wu et al.
    2018, eqs 11–13); x2 = [φ_1k, ε_1, ε_k, ∇_1, ∇_k] (13 states).

    Parameters
    ----------
    model : DifferenceModel
        Must have core blocks ``dp`` and ``dv`` (e.g. :func:`joint_rotation_model`).
    C1n, Ckn : array (3, 3)
        ``C_b^n`` of IMU 1 and IMU k during the stop.
    lat : float
        Latitude [rad] of the stationary carrier.
    h : float
        Height [m].

    Returns
    -------
    A : ndarray (n2, n2)
    C : ndarray (n1, n2)
    """
    x1, x2 = _measured_blocks(model)
    F = model.F(NavPoint.static(lat, np.asarray(C1n, float), h), NavPoint.static(lat, np.asarray(Ckn, float), h))
    return F[np.ix_(x2, x2)], F[np.ix_(x1, x2)]


@dataclass(frozen=True)
class ScheduleObservability:
    """Observability of the joint model along a sequence of stops.

    Attributes
    ----------
    labels : tuple of str
        The x2 states, in order.
    rank_static : int
        Rank of the first stop alone.
    segment_ranks : list of int
        Rank of each stop alone.
    ranks : list of int
        Rank of the stacked matrix after stops 1, 2, …, m (time order).
    degree : ndarray (n2,)
        Per-state SVD degree of observability of all m stops
        (:class:`sinslab.estimation.observability.ObservabilityResult`).
    result : ObservabilityResult
        Full analysis of the m stops (singular values, null space, scale).
    method : str
        ``"som"`` or ``"tom"``.
    """

    labels: tuple
    rank_static: int
    segment_ranks: list
    ranks: list
    degree: np.ndarray
    result: obs.ObservabilityResult
    method: str

    @property
    def n(self):
        return len(self.labels)

    @property
    def observable(self) -> bool:
        return self.ranks[-1] == self.n


def schedule_observability(model: DifferenceModel, C1c, Ckc, lat, h=0.0, Ccn=None, durations=None,
                           method="som", scale=None, rtol=obs.DEFAULT_RTOL) -> ScheduleObservability:
    """Rank and degree of observability of the joint model along a rotate-stop schedule.

    The carrier is stationary; during stop j the IMUs sit at ``C_b1^c[j]`` and
    ``C_bk^c[j]`` in the carrier frame, so ``C_bi^n = C_c^n C_bi^c[j]``. Each stop is one
    time-invariant segment of the piecewise-constant system (Wang, Wu et al. 2018,
    eq 15: the stacked ``[Ō_1; …; Ō_m]``); the rotations between stops are not segments.

    Parameters
    ----------
    model : DifferenceModel
        E.g. :func:`joint_rotation_model`.
    C1c, Ckc : array (m, 3, 3)
        IMU-to-carrier DCMs of INS 1 and INS k per stop, in time order.
    lat : float
        Latitude [rad].
    h : float
        Height [m].
    Ccn : array (3, 3), optional
        Carrier attitude ``C_c^n`` (default identity: carrier axes = ENU).
    durations : array (m,), optional
        Stop durations [s]; needed by ``method="tom"``.
    method : {"som", "tom"}
        Stripped (paper eq 15) or total observability matrix.
    scale : array (n2,), optional
        State magnitudes for the numerical rank and the degrees (default automatic).
    rtol : float
        Relative singular-value tolerance of the ranks.

    Returns
    -------
    ScheduleObservability
    """
    C1c = np.asarray(C1c, dtype=float)
    Ckc = np.asarray(Ckc, dtype=float)
    if C1c.ndim != 3 or C1c.shape[1:] != (3, 3) or C1c.shape != Ckc.shape or C1c.shape[0] == 0:
        raise ValueError(f"schedule_observability: C1c and Ckc must both have shape (m, 3, 3), m >= 1, "
                         f"got {C1c.shape} and {Ckc.shape}")
    m = C1c.shape[0]
    Ccn = np.eye(3) if Ccn is None else np.asarray(Ccn, dtype=float)
    if Ccn.shape != (3, 3):
        raise ValueError(f"schedule_observability: Ccn must be (3, 3), got {Ccn.shape}")
    if durations is None:
        if method == "tom":
            raise ValueError("schedule_observability: method='tom' needs the stop durations")
        T = [None] * m
    else:
        T = np.asarray(durations, dtype=float)
        if T.shape != (m,) or not np.all(np.isfinite(T) & (T > 0)):
            raise ValueError(f"schedule_observability: durations must be {m} positive numbers")
    segs = []
    for j in range(m):
        A, C = joint_subsystem(model, Ccn @ C1c[j], Ccn @ Ckc[j], lat, h)
        segs.append((A, C) if T[j] is None else (A, C, T[j]))
    pw = obs.piecewise(segs, method, scale, rtol)
    own = [obs.rank(s[0], s[1], scale, rtol) for s in segs]
    _, x2 = _measured_blocks(model)
    labels = tuple(model.layout.labels[i] for i in x2)
    return ScheduleObservability(labels, own[0], own, pw.ranks, pw.result.degree, pw.result, method)
