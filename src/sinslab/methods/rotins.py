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

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from sinslab.core import attitude as A
from sinslab.core import earth
from sinslab.estimation import observability as obs
from sinslab.estimation.kalman import discretize
from sinslab.estimation.kernels import gain_correct, predicted_dense
from sinslab.estimation.linear import error_budget, propagate_covariance
from sinslab.nav.errstate import DifferenceModel, NavPoint, accel_bias, gyro_bias

__all__ = ["joint_rotation_model", "windowed_std", "joint_subsystem", "ScheduleObservability",
           "schedule_observability", "difference_sigma", "joint_P0", "joint_filter",
           "joint_transitions", "schedule_transitions", "joint_filter_linear", "difference_measurements",
           "noise_share", "sigma_settle_time", "band_settle_time", "NOISE_GROUPS", "CAMPAIGN_PARTS", "campaign_setup",
           "campaign_batch", "fractions", "campaign_sums", "campaign_statistics"]

#: Noise sources of the joint model's noise vector (:func:`joint_rotation_model`): INS 1's
#: gyros and accelerometers, INS k's gyros, INS k's accelerometers.
NOISE_GROUPS = {"ins1": range(0, 5), "gyro_k": range(5, 8), "accel_k": range(8, 10)}


def joint_rotation_model(gyro_arw1=0.0, gyro_arwk=0.0, accel_vrw1=0.0, accel_vrwk=0.0,
                         radius_derivatives=False, drift_rw1=0.0, drift_rwk=0.0) -> DifferenceModel:
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

    Optionally the gyro drifts are random walks instead of random constants
    (``drift_rw1``, ``drift_rwk``): a drift that wanders (temperature) can then be
    followed, at the price of a noisier estimate. The paper's model has none (default);
    with a non-zero density the three driving noises of that INS's drift block are
    appended to the noise vector (``w_eps_x_1 … w_eps_z_1``, then ``w_eps_x_k …``), and
    F is unchanged.

    Parameters
    ----------
    gyro_arw1, gyro_arwk : float or (3,)
        Gyro white noise (ARW) of INS 1 / INS k [rad/√s].
    accel_vrw1, accel_vrwk : float or (2,)
        Horizontal accelerometer white noise (VRW) of INS 1 / INS k [m/s/√s].
    radius_derivatives : bool
        Keep the dR/dL and ∂g/∂L terms (exact Jacobian) instead of the paper's F.
    drift_rw1, drift_rwk : float or (3,)
        Rate random walk of the gyro drifts of INS 1 / INS k [rad/s/√s] (0: random
        constant, the paper's model).

    Returns
    -------
    DifferenceModel
        ``F(nav1, navk)`` of shape ``S + (17, 17)``; block names ``dp dv phi eps_1 eps_k
        nabla_1 nabla_k``.
    """
    for v, nm in ((drift_rw1, "drift_rw1"), (drift_rwk, "drift_rwk")):
        a = np.asarray(v, float)
        if a.shape not in ((), (3,)) or not np.all(np.isfinite(a)) or np.any(a < 0):
            raise ValueError(f"joint_rotation_model: {nm} must be a finite value >= 0 or three of them [rad/s/√s], "
                             f"got {v!r}")
    return DifferenceModel(
        "horizontal", [gyro_bias(rrw=drift_rw1, name="eps"), accel_bias("xy", name="nabla")],
        [gyro_bias(rrw=drift_rwk, name="eps"), accel_bias("xy", name="nabla")],
        gyro_arw1, gyro_arwk, accel_vrw1, accel_vrwk, accel_vrw_axes="xy",
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


# ----------------------------------------------------------------------- the joint filter
def difference_sigma(lat, pos=1e-3, vel=1e-5, h=0.0):
    """Measurement σ of :class:`sinslab.fusion.measurements.InsDifference` for the nearly
    noise-free difference of two INS on one carrier (paper: R = 0).

    The difference of two navigation outputs carries no measurement noise of its own;
    R = 0 would make the update singular (S = H P Hᵀ → 0 once the differences are known).
    A floor far below the INS errors changes nothing the filter estimates and keeps every
    update well conditioned; the updates are sequential scalar Joseph updates (symmetrised),
    so P stays symmetric positive definite.

    Parameters
    ----------
    lat : float
        Latitude [rad] (converts the position floor to radians).
    pos : float
        Position floor [m] (default 1 mm).
    vel : float
        Velocity floor [m/s] (default 1e-5 m/s).
    h : float
        Height [m].

    Returns
    -------
    ndarray (4,)
        ``[σ_L, σ_λ, σ_vE, σ_vN]`` [rad, rad, m/s, m/s].
    """
    pos, vel = float(pos), float(vel)
    if not (pos > 0 and vel > 0 and np.isfinite(pos) and np.isfinite(vel)):
        raise ValueError(f"difference_sigma: the floors must be > 0, got pos={pos}, vel={vel}")
    rm, rn = earth.radii(float(lat), float(h))
    return np.array([pos / float(rm), pos / (float(rn) * np.cos(lat)), vel, vel])


def joint_P0(model: DifferenceModel, lat, *, pos=0.0, vel=0.0, att=(0.0, 0.0, 0.0), gyro1=0.0,
             gyrok=0.0, accel1=0.0, accelk=0.0, h=0.0):
    """Diagonal initial covariance of the joint model (σ per block, SI).

    Parameters
    ----------
    model : DifferenceModel
        :func:`joint_rotation_model`.
    lat : float
        Latitude [rad].
    pos, vel : float
        σ of the initial position [m] and velocity [m/s] difference (0: the INS start
        from one position fix; a tiny floor is kept so P0 stays definite).
    att : (3,)
        σ of the initial attitude difference φ_1k [rad] (E, N, U).
    gyro1, gyrok : float or (3,)
        σ of the gyro drifts of INS 1 / INS k [rad/s].
    accel1, accelk : float or (2,)
        σ of the horizontal accelerometer biases [m/s²].

    Returns
    -------
    ndarray (n, n)
    """
    lay = model.layout
    rm, rn = earth.radii(float(lat), float(h))
    pos = max(float(pos), 1e-4)
    vel = max(float(vel), 1e-6)
    sd = np.zeros(lay.n)
    sp, sv = lay.slice("dp"), lay.slice("dv")
    sd[sp.start] = pos / float(rm)
    sd[sp.start + 1] = pos / (float(rn) * np.cos(lat))
    sd[sv] = vel
    sd[lay.slice("phi")] = np.broadcast_to(np.asarray(att, float), (3,))
    sd[lay.slice("eps_1")] = gyro1
    sd[lay.slice("eps_k")] = gyrok
    sd[lay.slice("nabla_1")] = accel1
    sd[lay.slice("nabla_k")] = accelk
    if not np.all(np.isfinite(sd)) or np.any(sd <= 0):
        raise ValueError("joint_P0: every σ must be finite and > 0")
    return np.diag(sd ** 2)


def joint_filter(stream1, streamk, model: DifferenceModel, P0, *, kf_dt, meas_every=1, sigma=None,
                 lever_arm=None, model_every=None, discretization="series", progress=False,
                 label="joint filter"):
    """Joint error filter of INS 1 and INS k run by the fusion driver on their outputs.

    Both INS navigate on their own; their outputs at the filter epochs come in as
    :class:`sinslab.fusion.driver.PrecomputedStream` (feed-forward: the filter estimates
    the joint error state and corrects neither INS, so one navigation of INS 1 serves the
    filters of every INS k). At every epoch after the first the measurement is
    :class:`sinslab.fusion.measurements.InsDifference`
    ``z = [L1−Lk, λ1−λk, vE1−vEk, vN1−vNk]`` with the lever arm (IMU 1 → IMU k, IMU-1
    body axes) removed.

    Parameters
    ----------
    stream1, streamk : PrecomputedStream or LiveStream
        INS 1 (single-axis) and INS k on one filter grid.
    model : DifferenceModel
        :func:`joint_rotation_model` with the nominal noise densities.
    P0 : array (n, n)
        Initial covariance (e.g. :func:`joint_P0`).
    kf_dt : float
        Step of the streams and of the model [s] (the mechanisms turn by up to 180° in a
        few seconds: keep it short against the moves, e.g. 1 s).
    meas_every : int
        One measurement every that many steps (the epochs in between are predictions,
        compiled, so the cost is per measurement).
    sigma : array (4,) or (J, 4), optional
        Measurement σ [rad, rad, m/s, m/s]; default :func:`difference_sigma` at the
        latitude of stream 1 (the R ≈ 0 floor).
    lever_arm : array (3,), optional
        IMU 1 → IMU k in IMU-1 body axes [m] (None: co-located).
    model_every : float, optional
        Length [s] of the model stretches evaluated at once (vectorised). For precomputed
        streams the look-ahead rows are the streams' own rows, so any length gives the
        same matrices as an evaluation epoch by epoch; default 1 h.
    discretization : {"series", "vanloan"}

    Returns
    -------
    sinslab.fusion.driver.DriverResult
        ``x`` and ``sigma`` per epoch; ε_z1 is column ``model.layout.index(["eps_z_1"])``.
    """
    from sinslab.fusion import driver
    from sinslab.fusion.spec import FilterGrid
    from sinslab.fusion.measurements import InsDifference

    T, t0, n_ep = streamk.bind(kf_dt)
    T1, t01, n1 = stream1.bind(kf_dt)
    if abs(t0 - t01) > 1e-6 * T or n1 != n_ep:
        raise ValueError(f"joint_filter: the two streams must share the filter grid (t0 {t01} vs {t0} s, "
                         f"{n1} vs {n_ep} epochs)")
    me = int(meas_every)
    if me < 1:
        raise ValueError(f"joint_filter: meas_every must be >= 1, got {meas_every}")
    t = t0 + T * np.arange(me, n_ep + 1, me)
    if sigma is None:
        sigma = difference_sigma(stream1.row0()[0][7])
    meas = InsDifference(t, sigma, lever_arm=lever_arm, streams=(0, 1))
    every = 3600.0 if model_every is None else float(model_every)
    grid = FilterGrid(kf_dt, max_block=max(kf_dt * me, kf_dt), model_every=every, discretization=discretization)
    return driver.run([stream1, streamk], model, P0, [meas], grid=grid, progress=progress, label=label)


def joint_transitions(model: DifferenceModel, T, rows1, rowsk, rates1, ratesk, noise_groups=None,
                      method="series", substeps=1, chunk=2048, inputs=False):
    """Transition matrices and discrete process noise of the joint model along two
    navigation outputs, the noise split by source.

    The model is evaluated on the grid of the rows (step ``T``); with ``substeps = m``
    those transitions are chained into steps of ``m·T``: ``Φ = Φ_m ⋯ Φ_1``,
    ``Q ← Φ_j Q Φ_jᵀ + Q_j``. Rotations of the indexing mechanisms last seconds, so a
    filter step of several seconds needs its transition chained from short sub-steps: the
    sensor states enter through ``C_b^n``, which turns by up to 180° within such a step.

    Parameters
    ----------
    model : DifferenceModel
    T : float
        Step of the rows [s].
    rows1, rowsk : array (K·m, 10)
        ``[q, v, L, λ, h]`` of INS 1 / INS k at the sub-epochs 0..K·m−1 (the step
        i → i+1 uses row i, as the fusion driver does).
    rates1, ratesk : tuple (omega_b, f_b), arrays (K·m, 3)
        Mean compensated rate [rad/s] and specific force [m/s²] of each sub-step.
    noise_groups : dict {name: list of noise-column indices}, optional
        Columns of G (``[w_g1 (3), w_a1 (2), w_gk (3), w_ak (2)]``, then the drift random
        walks if the model has them, ``model.noise_labels``) per source; default one group
        ``"all"``.
    method : {"series", "vanloan"}
    substeps : int
        Sub-steps m per returned step.
    chunk : int
        Returned steps evaluated at once (memory).
    inputs : bool
        Also return the input matrices ``Γ`` of each group: the state increment over a step
        caused by a noise held constant over that step is ``Γ u`` (``u`` in the noise's own
        units: rad/s, m/s²). Chained like Φ (``Γ ← Φ_j Γ + Γ_j``, with ``Γ_j = ∫Φ(s)G ds``
        by the same rule as ``Q``), so that ``Q − Γ (q / (m·T)) Γᵀ`` — the part of the
        step's noise not explained by its step mean ``u ~ N(0, q/(m·T))`` — is a covariance.
        That split lets a simulation change the slow part of a white noise (e.g. remove its
        mean over blocks of steps) and keep the rest exact.

    Returns
    -------
    Phi : ndarray (K, n, n)
    Q : dict {name: ndarray (K, n, n)}
    Gam : dict {name: ndarray (K, n, p_name)}
        Only with ``inputs=True``; columns in the order of the group's noise columns.
    """
    m = int(substeps)
    rows1 = np.asarray(rows1, float)
    rowsk = np.asarray(rowsk, float)
    if m < 1 or rows1.shape[0] % m or rows1.shape != rowsk.shape:
        raise ValueError(f"joint_transitions: rows must be K·substeps long and alike, got {rows1.shape}, "
                         f"{rowsk.shape}, substeps={substeps}")
    K = rows1.shape[0] // m
    q = np.asarray(model.q, float)
    groups = {"all": list(range(q.size))} if noise_groups is None else {k: list(v) for k, v in noise_groups.items()}
    n = model.n
    Phi = np.empty((K, n, n))
    Q = {g: np.empty((K, n, n)) for g in groups}
    Gam = {g: np.empty((K, n, len(c))) for g, c in groups.items()} if inputs else None
    if inputs and method not in ("series", "vanloan"):
        raise ValueError(f"joint_transitions: unknown method {method!r}")

    def pt(rows, rates, a, b):
        return NavPoint(rows[a:b, 7], rows[a:b, 9], rows[a:b, 4:7], A.quat_to_dcm(rows[a:b, :4]),
                        np.asarray(rates[1][a:b], float), np.asarray(rates[0][a:b], float))

    for k0 in range(0, K, int(chunk)):
        k1 = min(K, k0 + int(chunk))
        a, b = k0 * m, k1 * m
        F, G = model.matrices(pt(rows1, rates1, a, b), pt(rowsk, ratesk, a, b))
        parts = {}
        Ps = None
        for name, cols in groups.items():
            qq = np.zeros_like(q)
            qq[cols] = q[cols]
            P_, Q_ = discretize(F, qq, T, G=G, method=method)
            Ps = P_ if Ps is None else Ps
            parts[name] = Q_.reshape(k1 - k0, m, n, n)
        Ps = Ps.reshape(k1 - k0, m, n, n)
        gin = {}
        if inputs:
            for name, cols in groups.items():
                Gc = G[..., list(cols)]
                if method == "series":
                    # the trapezoid of ∫Φ(s)G ds, as Q's trapezoid of ∫Φ(s)Q̄Φ(s)ᵀ ds
                    Gj = 0.5 * T * (Gc + Ps.reshape(-1, n, n) @ Gc)
                else:
                    from scipy.linalg import expm

                    p = Gc.shape[-1]
                    aug = np.zeros(Gc.shape[:-2] + (n + p, n + p))
                    aug[..., :n, :n] = F * T
                    aug[..., :n, n:] = Gc * T
                    Gj = expm(aug)[..., :n, n:]
                gin[name] = Gj.reshape(k1 - k0, m, n, Gc.shape[-1])
        acc = Ps[:, 0].copy()
        qacc = {g: parts[g][:, 0].copy() for g in groups}
        gacc = {g: gin[g][:, 0].copy() for g in gin}
        for j in range(1, m):
            Pj = Ps[:, j]
            acc = Pj @ acc
            for g in groups:
                qacc[g] = Pj @ qacc[g] @ np.swapaxes(Pj, -1, -2) + parts[g][:, j]
            for g in gin:
                gacc[g] = Pj @ gacc[g] + gin[g][:, j]
        Phi[k0:k1] = acc
        for g in groups:
            Q[g][k0:k1] = 0.5 * (qacc[g] + np.swapaxes(qacc[g], -1, -2))
        for g in gin:
            Gam[g][k0:k1] = gacc[g]
    if inputs:
        return Phi, Q, Gam
    return Phi, Q


def schedule_transitions(model: DifferenceModel, T, t, key, truth, substeps, noise_groups=None,
                         inputs=False):
    """Step transitions of the joint model along a known schedule, computed once per
    distinct filter step (mounts that dwell most of the time give few distinct steps).

    Parameters
    ----------
    model : DifferenceModel
    T : float
        Model step [s]; ``substeps`` of them are chained per filter step.
    t : array (K·substeps,)
        Start time of every model step [s].
    key : array (K·substeps, m)
        What makes a step differ (the mount angles of both INS at ``t`` [rad]); filter
        steps whose keys agree to 1e-9 share a table entry.
    truth : callable
        ``truth(epochs) -> (rows1, rates1, rowsk, ratesk)``: the error-free outputs of both
        INS at ``epochs`` (S,) and their rates over the S − 1 steps, as
        :func:`joint_transitions` takes them.
    substeps : int
    noise_groups, inputs
        As in :func:`joint_transitions`.

    Returns
    -------
    Phi : ndarray (U, n, n)
    Q : dict {group: ndarray (U, n, n)}
    index : int ndarray (K,)
        Table entry of each of the K filter steps.
    Gam : dict {group: ndarray (U, n, p)}
        Only with ``inputs=True``: the input matrices of :func:`joint_transitions`.
    """
    me = int(substeps)
    t = np.asarray(t, float)
    key = np.asarray(key, float)
    K = t.size // me
    key = np.round(key.reshape(K, me * key.shape[-1]), 9)
    _, first, index = np.unique(key, axis=0, return_index=True, return_inverse=True)
    sub = (first[:, None] * me + np.arange(me)[None, :]).ravel()
    r1, rates1, rk, ratesk = truth(np.r_[t[sub], 0.0])
    out = joint_transitions(model, T, r1[:-1], rk[:-1], rates1, ratesk, noise_groups=noise_groups,
                            substeps=me, inputs=inputs)
    return (*out[:2], np.asarray(index, dtype=np.int64).reshape(K), *out[2:])


def _metre_scale(model, sigma):
    """State scale d putting the two position differences in metres (other states as
    they are) and the position measurement with them; R then spans (1 mm)² to
    (1e-5 m/s)² instead of 1e-20 rad² to 1e-10 (m/s)²."""
    sp = model.layout.slice("dp")
    sigma = np.asarray(sigma, float)
    d = np.ones(model.n)
    d[sp.start] = 1e-3 / sigma[0]
    d[sp.start + 1] = 1e-3 / sigma[1]
    return d


def _difference_H(model):
    lay = model.layout
    sp, sv = lay.slice("dp"), lay.slice("dv")
    H = np.zeros((4, lay.n))
    H[0, sp.start] = H[1, sp.start + 1] = 1.0
    H[2, sv.start] = H[3, sv.start + 1] = 1.0
    return H


def joint_filter_linear(z, Phi, Q, model: DifferenceModel, P0, *, sigma, index=None):
    """The joint filter linearised along a known schedule, in one compiled loop
    (:func:`sinslab.estimation.linear.run_linear`).

    When both IMUs follow known indexing schedules on a moored carrier, the model matrices
    along the true schedule equal those along the navigation outputs up to the INS errors
    (µrad): one table of step transitions (:func:`joint_transitions`, typically with
    sub-steps and only the distinct steps of the schedule) then serves every filter of
    every INS k and every seed. Same measurement, floor and Joseph updates as
    :func:`joint_filter` (cross-checked against it in the tests).

    Parameters
    ----------
    z : array (K, 4)
        ``[L1−Lk, λ1−λk, vE1−vEk, vN1−vNk]`` at the filter epochs 1..K [rad, rad, m/s, m/s].
    Phi, Q : array (L, n, n)
        Step transitions and process noise (per step, or a table with ``index``).
    model : DifferenceModel
    P0 : array (n, n)
    sigma : array (4,)
        Measurement σ (:func:`difference_sigma`).
    index : int array (K,), optional
        Table entry of each step.

    Returns
    -------
    x, sigma : ndarray (K + 1, n)
        Estimate and σ at the filter epochs (SI; positions in rad).
    """
    from sinslab.estimation.linear import run_linear

    sigma = np.asarray(sigma, float)
    d = _metre_scale(model, sigma)
    sp = model.layout.slice("dp")
    zs = np.array(z, dtype=float)
    zs[:, 0] *= d[sp.start]
    zs[:, 1] *= d[sp.start + 1]
    rs = sigma * np.r_[d[sp.start], d[sp.start + 1], 1.0, 1.0]
    Ds = d[:, None] * d[None, :]
    res = run_linear(np.zeros(model.n), np.asarray(P0, float) * Ds, np.asarray(Phi, float) * (d[:, None] / d[None, :]),
                     np.asarray(Q, float) * Ds, _difference_H(model), np.diag(rs ** 2), zs,
                     Phi_index=index, Q_index=index, check=False)
    return res.x / d, res.sigma / d


def difference_measurements(rows1, rowsk):
    """``z = [L1−Lk, λ1−λk, vE1−vEk, vN1−vNk]`` of two navigation outputs (K, 10), co-located
    IMUs (longitude difference wrapped to ±π)."""
    r1 = np.asarray(rows1, float)
    rk = np.asarray(rowsk, float)
    return np.stack([r1[:, 7] - rk[:, 7], A.wrap_pi(r1[:, 8] - rk[:, 8]),
                     r1[:, 4] - rk[:, 4], r1[:, 5] - rk[:, 5]], -1)


def noise_share(model: DifferenceModel, P0, Phi, Q_parts, sigma, *, index=None, history_every=0):
    """Split the covariance of the joint filter into noise sources with the filter's own
    gains (the covariance side of paper eqs 16–20).

    With the gains of the nominal filter fixed, the error covariance is linear in the
    process noise: if the true noise of source j is ``(1 + α_j) Q_j`` instead of ``Q_j``,
    the actual error variance is ``P + Σ_j α_j P_j`` where ``P_j`` is the variance
    propagated from ``Q_j`` alone. Paper eq 20 (ΔP = α P) is the special case where every
    source is scaled alike.

    Parameters
    ----------
    model : DifferenceModel
    P0 : array (n, n)
    Phi : array (K, n, n)
    Q_parts : dict {name: array (K, n, n)}
        (or tables (L, n, n) with ``index``).
    sigma : array (4,)
        Measurement σ [rad, rad, m/s, m/s].
    index : int array (K,), optional
        Table entry of each step.
    history_every : int
        Also return the per-source variances every that many steps.

    Returns
    -------
    sinslab.estimation.linear.Budget
        Sources ``"P0"``, the names of ``Q_parts``, ``"R"``.
    """
    sp = model.layout.slice("dp")
    sigma = np.asarray(sigma, float)
    d = _metre_scale(model, sigma)
    H = _difference_H(model)
    r = (sigma * np.r_[d[sp.start], d[sp.start + 1], 1.0, 1.0]) ** 2
    D = d[:, None] * d[None, :]
    Phi_s = np.asarray(Phi, float) * (d[:, None] / d[None, :])
    names = list(Q_parts)
    Qp = np.stack([np.asarray(Q_parts[k], float) * D for k in names])
    n_steps = None if index is None else len(index)
    return error_budget((np.asarray(P0, float) * D)[None], Phi_s, Qp, H, r[None], Phi_index=index,
                        Q_index=index, n_steps=n_steps, names=["P0", *names, "R"], history_every=history_every)


def sigma_settle_time(t, sigma, level):
    """First time the filter σ of a state falls to ``level`` — one reading of "the estimate
    is stable after ..." that does not depend on how long the record goes on (the σ at a
    time is causal).

    Parameters
    ----------
    t : array (M,)
        Times [s].
    sigma : array (M,)
        Filter σ of the state at ``t``.
    level : float
        Level, same unit as ``sigma`` (e.g. the magnitude of the drift being estimated:
        from then on the estimate tells the drift from zero at 1σ).

    Returns
    -------
    float
        Time [s]; NaN if σ never reaches ``level``.
    """
    t = np.asarray(t, float)
    s = np.asarray(sigma, float)
    hit = np.flatnonzero(s <= float(level))
    return float(t[hit[0]]) if hit.size else float("nan")


def band_settle_time(t, x, truth, band):
    """Time after which an estimate stays within ± ``band`` of the true value to the end of
    the record — the second reading of "stable after ...": unlike a band around the final
    value or the final σ, the band is fixed, so a longer record can only move the time by an
    excursion that really happens later.

    Parameters
    ----------
    t, x : array (M,)
        Times [s] and the estimate.
    truth : float or array (M,)
        True value at ``t`` (same unit as ``x``).
    band : float
        Half-width of the band, > 0.

    Returns
    -------
    float
        Time [s] of the first sample of the final run inside the band (``t[0]`` if every
        sample is inside); NaN if the last sample is outside.
    """
    t = np.asarray(t, float)
    out = np.abs(np.asarray(x, float) - np.asarray(truth, float)) > float(band)
    if not out.any():
        return float(t[0])
    last = int(np.flatnonzero(out)[-1])
    return float(t[last + 1]) if last + 1 < t.size else float("nan")


# ---------------------------------------------------------------- linear-domain campaign -------
#: parts of the linear-domain run: which noise drives each (None: no noise) —
#: INS 1 + initial state, INS 2 accel, INS 2 gyro, INS B accel, INS B gyro, INS 3 accel,
#: INS 3 gyro, INS 4 accel, INS 4 gyro, INS 1's drift trend, INS 1's noise block means
CAMPAIGN_PARTS = ("ins1", "accel_k", "gyro_k", "accel_k", "gyro_k", "accel_k", "gyro_k", "accel_k", "gyro_k",
          None, "blocks")


def campaign_setup(spec):
    """The campaign's fixed part, made once in the main process from its transition table:
    transitions, noise square roots and the nominal filter's gains, positions in metres.

    INS 1's step noise is split into its step mean ``u ~ N(0, q/T)`` acting through ``Γ``
    (:func:`sinslab.methods.rotins.joint_transitions` with ``inputs=True``) and the rest,
    independent of ``u``: removing the block means of ``u`` is then removing those of INS 1's
    noise, and the white case is the same numbers with nothing removed."""
    model = joint_rotation_model()
    model.q[:] = spec["q"]
    K, T = spec["n_steps"], spec["kf_dt"]
    Phi, Qg, Gam, index = spec["Phi"].copy(), {g: v.copy() for g, v in spec["Q"].items()}, spec["Gam"], spec["index"]
    n = model.n
    sig = spec["sig"]
    d = _metre_scale(model, sig)
    Phi *= d[:, None] / d[None, :]
    q1 = spec["q"][list(NOISE_GROUPS["ins1"])]
    G1 = Gam["ins1"] * d[None, :, None] * np.sqrt(q1 / T)[None, None, :]
    roots = {}
    for g, Qk in Qg.items():
        Qk *= d[:, None] * d[None, :]
        if g == "ins1":
            Qk = Qk - G1 @ np.swapaxes(G1, -1, -2)
        w, V = np.linalg.eigh(Qk)
        roots[g] = V * np.sqrt(np.maximum(w, 0.0))[:, None, :]
    Q = sum(Qg.values())
    P0 = spec["P0"] * (d[:, None] * d[None, :])
    Rv = (sig * np.r_[d[0], d[1], 1.0, 1.0]) ** 2
    iz = model.layout.index(["eps_z_1"])[0]
    jk = model.layout.index(["eps_x_k"])[0]
    # the nominal filter's covariance does not depend on the data: its gains, computed
    # once, are the filter of every run (campaign_batch)
    nominal = propagate_covariance(P0, Phi, Q, _difference_H(model), np.diag(Rv), n_steps=K,
                                   Phi_index=index, Q_index=index, keep_gain=True, check=False)
    return dict(Phi=np.ascontiguousarray(Phi), index=index, roots=roots, G1=np.ascontiguousarray(G1),
                gains=nominal.gain, Rv=Rv, d=d, iz=iz, jk=jk, P0=P0, t=T * np.arange(K + 1),
                sig_z=nominal.sigma[:, iz])


def campaign_batch(seeds, spec, setup):
    """Linear-domain runs of analyses one and two (campaign function of
    :func:`sinslab.estimation.montecarlo.run_campaign`).

    Per seed, the true joint error state and the nominal filter's estimate are propagated
    in parts (``CAMPAIGN_PARTS``) that the filters share or not: the filter is linear with fixed
    gains, so each filter's ε̂_z1 is a sum of parts, a rescaled noise record a scaled part
    (ε̂_z1(β) = ε̂(rest) + β ε̂(gyro 2)), INS 1's noise without its block means the INS 1 part
    minus the block-mean part, and the drift trend a part of its own. Vectorised over seeds
    and parts. INS B, #3 and #4 share INS #2's initial state (its effect is gone long before
    the first window).

    A trend in the gyro noise of INS #2, B, #3 and #4 (their records keep one):
    ``spec["ktrend_steps"]`` (K,) holds the steps of its shape, a unit trend [rad/s], which
    each of those INS has on each gyro axis times a factor drawn per seed (standard normal,
    from a stream of its own, so the process and measurement draws are those without the
    trend); it enters the INS's gyro part, so a record rescaled by β has its trend rescaled
    too. Absent or all zero: no trend.

    Returns
    -------
    dict
        ``wstd`` (B, len(betas)) mean windowed std of ε̂_z1 per β [rad/s]; ``wstd_sep``
        (B, 2): INS A (β = 1), INS B (ratio ``sep``); ``wstd_two`` (B, 3): filters 2, 3, 4
        of analysis two; ``final`` (B,) ε̂_z1 − ε_z1 at the end (β = 1); ``settle_band``
        (B,) the band reading of the settling time [s] (β = 1); ``trend_corr`` (B, 3): the
        correlation of filters 2, 3, 4's ε̂_z1 with the drift's trend after ``start``.
    """
    S = setup
    Phi, index, roots, gains, iz, G1 = S["Phi"], S["index"], S["roots"], S["gains"], S["iz"], S["G1"]
    K, n = gains.shape[:2]
    B = len(seeds)
    P_ = len(CAMPAIGN_PARTS)
    p1 = G1.shape[-1]
    nb = spec["block_steps"]
    L0 = np.linalg.cholesky(S["P0"])
    rngs = [np.random.default_rng(s) for s in seeds]
    X = np.zeros((B, P_, n))
    for b, g in enumerate(rngs):
        X[b, 0] = L0 @ g.standard_normal(n)
    x0z = X[:, 0, iz].copy()
    Xh = np.zeros((B, P_, n))
    noisy = [j for j, s in enumerate(CAMPAIGN_PARTS) if s in ("ins1", "accel_k", "gyro_k")]
    # per source: its parts and their columns among the noisy parts' draws
    groups = [(g, np.array([j for j, s in enumerate(CAMPAIGN_PARTS) if s == g]),
               np.array([noisy.index(j) for j, s in enumerate(CAMPAIGN_PARTS) if s == g]))
              for g in ("ins1", "accel_k", "gyro_k")]
    j_tr, j_bl = CAMPAIGN_PARTS.index(None), CAMPAIGN_PARTS.index("blocks")
    tr = spec["trend_steps"] * S["d"][iz]
    jk = S["jk"]
    ktr = np.asarray(spec.get("ktrend_steps", np.zeros(K)), float)
    kfac = np.zeros((B, P_, 3))
    if np.any(ktr):
        gyro_parts = [j for j, s in enumerate(CAMPAIGN_PARTS) if s == "gyro_k"]
        for b, sd in enumerate(seeds):
            kfac[b, gyro_parts] = _trend_stream(sd).standard_normal((len(gyro_parts), 3)) * S["d"][jk:jk + 3]
    sv = np.sqrt(S["Rv"])
    ez = np.empty((B, P_, K + 1))
    ez[:, :, 0] = 0.0
    # A seed's generator gives per step, in this order, the process normals of the noisy
    # parts, INS 1's step means and the measurement normals; drawn for a block of steps at
    # once they are the same numbers in the same order. The blocks hold whole noise blocks.
    per = len(noisy) * n + p1 + 4
    chunk = 2048 if nb < 1 else nb * max(1, 2048 // nb)
    # per part: the noise source driving it (index into roots, -1: none) and its column
    # among the noisy parts' draws
    src = np.full(P_, -1, dtype=np.int64)
    col = np.zeros(P_, dtype=np.int64)
    for gi, (gname, js, cols) in enumerate(groups):
        src[js], col[js] = gi, cols
    root = np.stack([roots[g] for g, _, _ in groups])
    index = np.ascontiguousarray(index, dtype=np.int64)
    for k in range(0, K, chunk):
        m = min(chunk, K - k)
        draws = np.stack([g.standard_normal((m, per)) for g in rngs])
        xis = np.ascontiguousarray(draws[:, :, :len(noisy) * n].reshape(B, m, len(noisy), n))
        us = np.ascontiguousarray(draws[:, :, len(noisy) * n:len(noisy) * n + p1])
        vs = np.ascontiguousarray(draws[:, :, len(noisy) * n + p1:])
        ubar = np.zeros_like(us)
        if nb >= 1:
            for a in range(0, m, nb):
                ubar[:, a:a + nb] = us[:, a:a + nb].mean(1, keepdims=True)
        _campaign_steps(X, Xh, ez, Phi, index, root, src, col, G1, xis, us, ubar, vs, sv, gains, tr, iz, j_tr, j_bl,
                        ktr, kfac, jk, k, m)
    t = S["t"]
    betas, scales = spec["betas"], spec["scales"]
    st, win = spec["start"], spec["window"]

    def ws(x):
        return windowed_std(t, x, st, win)[1].mean()

    out = np.empty((B, len(betas)))
    sep = np.empty((B, 2))
    two = np.empty((B, 3))
    corr = np.empty((B, 3))
    settle = np.empty(B)
    # the true drift's trend at the epochs (the seed's constant drift does not change a correlation)
    trend = np.r_[0.0, np.cumsum(spec["trend_steps"])]
    after = t >= st
    for b in range(B):
        e = ez[b]
        one1 = e[0] - e[j_bl] if nb >= 1 else e[0]
        base = one1 + e[1]
        for i, be in enumerate(betas):
            out[b, i] = ws(base + be * e[2])
        sep[b, 0] = out[b, betas.index(1.0)]
        sep[b, 1] = ws(one1 + e[3] + spec["sep"] * e[4])
        white = e[0] + e[j_tr]
        ests = (white + e[1] + scales[0] * e[2], white + e[5] + scales[1] * e[6], white + e[7] + scales[2] * e[8])
        two[b] = [ws(x) for x in ests]
        corr[b] = [np.corrcoef(x[after], trend[after])[0, 1] for x in ests]
        settle[b] = band_settle_time(t, base + e[2], x0z[b], spec["band"])
    final = (ez[:, 0, -1] - (ez[:, j_bl, -1] if nb >= 1 else 0.0) + ez[:, 1, -1] + ez[:, 2, -1]) - x0z
    return {"wstd": out, "wstd_sep": sep, "wstd_two": two, "final": final, "settle_band": settle,
            "trend_corr": corr}


def _trend_stream(seed) -> np.random.Generator:
    """The generator of a seed's trend factors: a stream of its own beside the seed's."""
    if isinstance(seed, np.random.SeedSequence):
        return np.random.default_rng(np.random.SeedSequence(seed.entropy, spawn_key=(*seed.spawn_key, 97)))
    return np.random.default_rng([int(seed), 97])


@njit(cache=True)
def _campaign_steps(X, Xh, ez, Phi, index, root, src, col, G1, xis, us, ubar, vs, sv, gains, tr, iz, j_tr, j_bl,
                    ktr, kfac, jk, k0, m):
    """Steps ``k0 .. k0+m−1`` of :func:`campaign_batch`, seed by seed (so a seed's numbers do
    not depend on the seeds stacked with it), in place on the true parts ``X`` and the
    estimates ``Xh`` (B, parts, n), the estimates of ε_z1 written to ``ez`` (B, parts, K+1).

    Per step k (transition ``Phi[index[k]]``): the drift trend's step ``tr[k]`` enters its
    part, the gyro trend of INS k ``ktr[k] · kfac[b, p]`` the drifts of INS k (states
    ``jk..jk+2``) of part p, every part is propagated, the noisy parts get their process noise
    ``root[src[p]][u] ξ`` (draws ``xis[:, c, col[p]]``), INS 1's part its step mean through
    ``G1[u]`` (``us``) and the block-mean part that of its block (``ubar``); the filter
    predicts, and updates every part with the gain ``gains[k]`` (n, 4) from its four
    measured components (measurement noise ``vs · sv`` in INS 1's part only). The filter
    steps with estimation's dense prediction and fixed-gain update
    (:mod:`sinslab.estimation.kernels`); the true parts' propagation is fused with their
    noise terms here."""
    B, P_, n = X.shape
    p1 = G1.shape[2]
    t = np.empty(n)
    nu = np.empty(4)
    for b in range(B):
        for c in range(m):
            k = k0 + c
            u = index[k]
            X[b, j_tr, iz] += tr[k]
            if ktr[k] != 0.0:
                for p in range(P_):
                    for a in range(3):
                        X[b, p, jk + a] += ktr[k] * kfac[b, p, a]
            for p in range(P_):
                for i in range(n):
                    acc = 0.0
                    for j in range(n):
                        acc += Phi[u, i, j] * X[b, p, j]
                    t[i] = acc
                if src[p] >= 0:
                    g, q = src[p], col[p]
                    for i in range(n):
                        acc = 0.0
                        for j in range(n):
                            acc += root[g, u, i, j] * xis[b, c, q, j]
                        t[i] += acc
                if p == 0 or p == j_bl:
                    w = us if p == 0 else ubar
                    for i in range(n):
                        acc = 0.0
                        for j in range(p1):
                            acc += G1[u, i, j] * w[b, c, j]
                        t[i] += acc
                for i in range(n):
                    X[b, p, i] = t[i]
                # the nominal filter: estimation's prediction and fixed-gain update, the
                # innovation the measured differences (truth + noise) minus the prediction
                xh = Xh[b, p]
                predicted_dense(xh, Phi[u], t)
                for i in range(4):
                    nu[i] = X[b, p, i] - t[i]
                    if p == 0:
                        nu[i] += vs[b, c, i] * sv[i]
                gain_correct(t, gains[k], nu)
                for i in range(n):
                    xh[i] = t[i]
                ez[b, p, k + 1] = t[iz]


def _orderings(wstd, wstd_sep, betas, sep_ratio):
    """Per seed: std monotone in β; β = 1.1 above β = 1.0; separate INS ordered (bool each)."""
    order = np.argsort(betas)
    mono = np.all(np.diff(wstd[:, order], axis=1) > 0, axis=1)
    d11 = wstd[:, betas.index(1.1)] > wstd[:, betas.index(1.0)]
    dsep = (wstd_sep[:, 1] > wstd_sep[:, 0]) if sep_ratio > 1 else (wstd_sep[:, 1] < wstd_sep[:, 0])
    return mono, d11, dsep


def fractions(wstd, wstd_sep, betas, sep_ratio):
    """Fractions of seeds: std monotone in β; β = 1.1 above β = 1.0; separate INS ordered."""
    return tuple(float(v.mean()) for v in _orderings(wstd, wstd_sep, betas, sep_ratio))


def campaign_sums(out, betas, sep_ratio, scales, shift):
    """What :func:`campaign_statistics` needs of each seed of :func:`campaign_batch`, to be
    summed over the seeds where they are computed (a campaign's ``reduce``).

    ``shift`` (dict: ``wstd`` (len(betas),), ``wstd_sep`` (2,) [rad/s], ``ratio``) holds
    values near the means (e.g. a single run's), subtracted before the squares are summed so
    that the spread keeps its digits. Returns per seed: a count ``n``, the three orderings
    of :func:`fractions`, whether analysis two ranks the filters as their noise scales
    (``right``), eq 20's ratio at β = 1.1 and the windowed stds, each shifted, with their
    squares, and the trend correlations.
    """
    w, ws = out["wstd"], out["wstd_sep"]
    mono, d11, dsep = _orderings(w, ws, betas, sep_ratio)
    ratio = w[:, betas.index(1.1)] / w[:, betas.index(1.0)] - shift["ratio"]
    right = np.all(np.argsort(out["wstd_two"], axis=1) == np.argsort(np.asarray(scales, float)), axis=1)
    dw, dws = w - shift["wstd"], ws - shift["wstd_sep"]
    return {"n": np.ones(len(w)), "monotone": mono, "distinguish": d11, "separate": dsep, "right": right,
            "ratio": ratio, "ratio2": ratio ** 2, "wstd": dw, "wstd2": dw ** 2, "wstd_sep": dws, "wstd_sep2": dws ** 2,
            "trend_corr": out["trend_corr"]}


def campaign_statistics(sums, shift):
    """The campaign's statistics from the sums of :func:`campaign_sums` over its seeds: the
    fractions, eq 20's σ ratio at β = 1.1 (mean over seeds, 95 % Student-t interval), the
    probability that the windowed stds of analysis two rank INS #2..#4 as their noise
    scales (95 % Wilson interval), the mean and standard deviation (over seeds, ddof 0) of
    the windowed stds per β and of the separate INS A, B [rad/s], the mean trend
    correlation of filters 2, 3, 4."""
    from sinslab.estimation.montecarlo import mean_ci95_sums, wilson_ci95

    N = int(sums["n"])
    rm, rci = mean_ci95_sums(N, sums["ratio"], sums["ratio2"], shift["ratio"])

    def moments(k):
        m = sums[k] / N
        return shift[k] + m, np.sqrt(np.maximum(sums[f"{k}2"] / N - m * m, 0.0))

    w_mean, w_sd = moments("wstd")
    s_mean, s_sd = moments("wstd_sep")
    right = int(sums["right"])
    return dict(p_monotone=float(sums["monotone"] / N), p_distinguish=float(sums["distinguish"] / N),
                p_separate=float(sums["separate"] / N), eq20_ratio_mean=rm, eq20_ratio_ci95=rci,
                ranking_probability=right / N, ranking_probability_ci95=wilson_ci95(right, N),
                wstd_mean=w_mean, wstd_sd=w_sd, wstd_sep_mean=s_mean, wstd_sep_sd=s_sd,
                trend_corr_mean=sums["trend_corr"] / N)
