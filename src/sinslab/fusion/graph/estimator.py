"""The factor-graph estimator on the inputs of the loosely coupled filter
(:func:`graph_navigate`): the same IMU record, start, fixes (lever arm, outages, σ,
robust weighting), IMU noise and bias model, and the same filter epochs for its output.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from sinslab.core import attitude as A
from sinslab.core.errors import InputError
from sinslab.fusion.graph import build
from sinslab.fusion.graph.frame import LocalFrame
from sinslab.fusion.graph.solve import batch_solve, dense_solution, key_sigma, online_pass
from sinslab.fusion.graph.translate import GraphImuModel, require_gtsam
from sinslab.fusion.spec import FilterGrid, FixSpec, InsSpec
from sinslab.nav import strapdown as sd

__all__ = ["GraphSpec", "GraphRun", "graph_navigate", "parse_estimator"]

#: estimator names of the recorded front end
ESTIMATORS = ("filter", "graph", "fixed-lag:SECONDS")


@dataclass(frozen=True)
class GraphSpec:
    """How the graph is solved.

    Attributes
    ----------
    kind : {"batch", "fixed-lag"}
        Levenberg–Marquardt over the whole record (started from the online pass), or the
        incremental fixed-lag smoother alone.
    lag : float
        Window of the online pass [s] (for ``"batch"`` only its start values).
    max_gap : float
        Longest interval [s] between keyframes (outages get one every ``max_gap``).
    gravity : {"local", "origin"}
        ``"local"``: each keyframe interval is integrated with the normal gravity at the
        position it starts from (the estimate of the online pass), as a w vector — the
        filter's gravity, in the graph's fixed frame; ``"origin"``: the constant gravity of
        the origin for the whole record (GTSAM's usual set-up; its error grows with the
        distance from the origin, docs/methods/graph.md).
    """

    kind: str = "batch"
    lag: float = 5.0
    max_gap: float = 1.0
    gravity: str = "local"

    def __post_init__(self):
        if self.kind not in ("batch", "fixed-lag"):
            raise ValueError(f"graph kind must be 'batch' or 'fixed-lag', got {self.kind!r}")
        if self.gravity not in ("local", "origin"):
            raise ValueError(f"graph gravity must be 'local' or 'origin', got {self.gravity!r}")
        for nm in ("lag", "max_gap"):
            v = float(getattr(self, nm))
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"graph {nm} must be > 0 s, got {v}")
            object.__setattr__(self, nm, v)

    def check_fix_interval(self, fix_t):
        """Refuse a fixed-lag window shorter than the fix interval (median spacing)."""
        if self.kind == "fixed-lag" and np.size(fix_t) > 1:
            step = float(np.median(np.diff(fix_t)))
            if self.lag < step:
                raise InputError(f"fixed-lag window {self.lag:g} s is shorter than the fix interval "
                                 f"{step:g} s: the window must hold at least two fixes")


def parse_estimator(text):
    """``"filter"`` (None), ``"graph"`` or ``"fixed-lag:SECONDS"`` as a :class:`GraphSpec`;
    anything else one line naming the choices."""
    s = str(text).strip().lower()
    if s in ("filter", "kalman", ""):
        return None
    if s in ("graph", "batch"):
        return GraphSpec("batch")
    if s.startswith("fixed-lag:"):
        try:
            lag = float(s.split(":", 1)[1].removesuffix("s"))
        except ValueError:
            lag = float("nan")
        if not (math.isfinite(lag) and lag > 0):
            raise InputError(f"estimator {text!r}: the fixed-lag window must be a number of seconds > 0")
        return GraphSpec("fixed-lag", lag)
    raise InputError(f"unknown estimator {text!r}: choose filter, graph or fixed-lag:SECONDS")


@dataclass(frozen=True)
class GraphRun:
    """Output of :func:`graph_navigate` at the filter epochs (the fields a
    :class:`~sinslab.fusion.loosely_coupled.LooselyCoupled` run has for its solution).

    Attributes
    ----------
    t : ndarray (M,)
        Filter epochs [s].
    nav : ndarray (M, 10)
        ``[q0..q3, vE, vN, vU, lat, lon, h]``.
    sigma : ndarray (M, n)
        σ in the filter's layout (interpolated between keyframes; NaN for states the graph
        does not have).
    gyro_bias, accel_bias : ndarray (M, 3)
        Bias compensation [rad/s], [m/s²].
    layout : StateLayout
    key_t, key_nav, key_sigma : ndarray (K,), (K, 10), (K, n)
        The keyframes.
    fix_t, fix_index : ndarray (J,)
        The fixes used and their rows.
    residual : ndarray (J, 3) or (J, 6)
        Post-fit antenna minus fix: position north, east, up [m], then (velocity fixes)
        velocity east, north, up [m/s].
    kind : str
    lag : float
    iterations : int
        Levenberg–Marquardt iterations (0 for fixed-lag).
    error : float
        Final graph error (½ Σ whitened squares; batch only, else NaN).
    cpu : dict
        CPU time [s] of the stages.
    notes : tuple of str
    fix_sigma : ndarray (J, 3) or (J, 6)
        The σ of the fixes used, in the order of ``residual`` [m, m/s].
    """

    t: np.ndarray
    nav: np.ndarray
    sigma: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    layout: object
    key_t: np.ndarray
    key_nav: np.ndarray
    key_sigma: np.ndarray
    fix_t: np.ndarray
    fix_index: np.ndarray
    residual: np.ndarray
    kind: str
    lag: float
    iterations: int
    error: float
    cpu: dict
    notes: tuple = ()
    fix_sigma: np.ndarray | None = None


    def as_driver_result(self):
        """The solution as a :class:`sinslab.fusion.driver.DriverResult` of one stream
        (what the recorded front end and the outputs read): ``x`` zero (the graph's solution
        is the navigation itself, nothing is left to feed back), σ, the bias compensation,
        and as the applied records the fixes used with their post-fit residuals and
        ``Σ (r/σ_fix)²`` in place of innovations and NIS (σ: the fixes' own)."""
        from sinslab.fusion.driver import Applied, DriverResult
        J = self.fix_t.size
        comp = {"gyro_bias": self.gyro_bias, "accel_bias": self.accel_bias}
        r = self.residual
        sd = self.fix_sigma if self.fix_sigma is not None else np.ones_like(r)
        applied = Applied(np.zeros(J, dtype=np.int64), self.fix_index.astype(np.int64), self.fix_t, self.fix_t,
                          list(r), np.sum((r / sd) ** 2, axis=1), list(sd))
        return DriverResult(self.t, (self.nav,), np.zeros_like(self.sigma), self.sigma, (comp,), applied,
                            self.layout, None)


@dataclass
class GraphProblem:
    """What the solvers share: frame, preintegration parameters, the IMU cut at the
    keyframes, the plan, priors, the start values and the fix factors per keyframe (those
    of the online pass and of the batch: they differ in their robust kernel only)."""

    frame: LocalFrame
    imu_model: GraphImuModel
    gravity: str
    seg: build.Segments
    plan: build.Plan
    priors: list
    pose0: object
    vel0: np.ndarray
    bias0: object
    fixes_at: dict
    fixes_batch: dict
    layout: object

    def params(self, p_w):
        """Preintegration parameters of an interval that starts at the w point ``p_w``."""
        return self.imu_model.params(self.frame, p_w if self.gravity == "local" else None)


def _problem(gtsam, imu, init, fixes: FixSpec, P0, model, ins: InsSpec, t_end, spec: GraphSpec):
    imu_model = GraphImuModel.from_error_model(model)
    if ins.vertical != "free":
        raise InputError("the graph estimator integrates a free vertical channel (vertical='free')")
    if fixes.n_pos != 3:
        raise InputError("the graph estimator needs 3-D fixes (a height with each)")
    row0 = sd.initial_state_array(init)[:10]
    frame = LocalFrame(row0[7], row0[8], row0[9])
    start = int(ins.start)
    t0 = float(ins.t_start) if ins.t_start is not None else (float(imu.t[start - 1]) if start > 0 else imu.t0)
    seg = build.Segments(imu, start, t0)
    plan = build.plan_keyframes(fixes, t0, t_end, spec.max_gap)
    keys = (gtsam.symbol_shorthand.X, gtsam.symbol_shorthand.V, gtsam.symbol_shorthand.B)
    gb = np.zeros(3) if ins.gyro_bias is None else np.asarray(ins.gyro_bias, dtype=float)
    ab = np.zeros(3) if ins.accel_bias is None else np.asarray(ins.accel_bias, dtype=float)
    bias0 = gtsam.imuBias.ConstantBias(ab, gb)
    priors, pose0, vel0 = build.prior_factors(gtsam, frame, row0, bias0, P0, model.layout, keys)
    fixes_at = build.fix_factors(gtsam, frame, fixes, plan, seg, fixes.lever_arm, fixes.robust, keys[:2], "online", gb)
    fixes_batch = fixes_at if fixes.robust is None or fixes.robust.kind != "igg3" else \
        build.fix_factors(gtsam, frame, fixes, plan, seg, fixes.lever_arm, fixes.robust, keys[:2], "batch", gb)
    notes = tuple(f"{n} bias random walk raised to the graph's floor" for n in imu_model.floored)
    return GraphProblem(frame, imu_model, spec.gravity, seg, plan, priors, pose0, vel0, bias0, fixes_at,
                        fixes_batch, model.layout), notes


def graph_navigate(imu, init, fixes: FixSpec, P0, model, *, ins: InsSpec = InsSpec(),
                   grid: FilterGrid = FilterGrid(), spec: GraphSpec = GraphSpec()) -> GraphRun:
    """INS + position(/velocity) fixes as a factor graph (GTSAM), on the inputs of
    :func:`sinslab.fusion.loosely_coupled.loosely_coupled`.

    Parameters
    ----------
    imu, init, fixes, P0, model, ins, grid
        As for the loosely coupled filter; the model must be the 15-state one with bias
        random walks (:class:`~sinslab.fusion.graph.translate.GraphImuModel`), the fixes
        3-D; ``grid.kf_dt`` gives the output epochs.
    spec : GraphSpec
        Batch or fixed-lag, the window, the keyframe spacing.

    Returns
    -------
    GraphRun
    """
    gtsam = require_gtsam()
    spec.check_fix_interval(fixes.t)
    cpu = {}
    c = time.process_time()
    start = int(ins.start)
    T = grid.kf_dt
    k_kf = int(round(T / imu.dt))
    if k_kf < 1 or abs(k_kf * imu.dt - T) > 1e-6 * T:
        raise ValueError(f"kf_dt={T} s must be a multiple of the IMU interval {imu.dt} s")
    n_ep = (len(imu) - start) // k_kf
    t0 = float(ins.t_start) if ins.t_start is not None else (float(imu.t[start - 1]) if start > 0 else imu.t0)
    t_out = t0 + T * np.arange(n_ep + 1)
    ctx, notes = _problem(gtsam, imu, init, fixes, P0, model, ins, float(t_out[-1]), spec)
    cpu["build"] = time.process_time() - c
    c = time.process_time()
    vals, covs, imu_f = online_pass(gtsam, ctx, spec.lag, want_sigma=spec.kind == "fixed-lag")
    cpu["online"] = time.process_time() - c
    it, err = 0, float("nan")
    if spec.kind == "batch":
        c = time.process_time()
        vals, covs, it, err = batch_solve(gtsam, ctx, vals, imu_f)
        cpu["batch"] = time.process_time() - c
    c = time.process_time()
    run = _result(gtsam, ctx, vals, covs, t_out, fixes, spec, it, err, notes)
    cpu["output"] = time.process_time() - c
    run.cpu.update(cpu)
    return run


def _result(gtsam, ctx, vals, covs, t_out, fixes, spec, it, err, notes):
    X, V, B = gtsam.symbol_shorthand.X, gtsam.symbol_shorthand.V, gtsam.symbol_shorthand.B
    K = ctx.plan.t.size
    Rwb = np.array([vals.atPose3(X(i)).rotation().matrix() for i in range(K)])
    pw = np.array([vals.atPose3(X(i)).translation() for i in range(K)])
    vw = np.array([vals.atVector(V(i)) for i in range(K)])
    key_nav = ctx.frame.rows_from_w(Rwb, vw, pw)
    lay = ctx.layout
    key_sig = np.array([key_sigma(ctx.frame, lay, Rwb[i], *key_nav[i, 7:10], covs[i]) for i in range(K)])
    rows, gb, ab = dense_solution(gtsam, ctx, vals, t_out)
    sig = np.column_stack([np.interp(t_out, ctx.plan.t, key_sig[:, j]) for j in range(lay.n)])
    res = _residuals(ctx, fixes, Rwb, pw, vw, vals, gtsam)
    idx = ctx.plan.fix_index
    sd = fixes.sigma[idx][:, :3] if fixes.vel is None else np.column_stack([fixes.sigma[idx][:, :3], fixes.vel_sigma[idx]])
    return GraphRun(t_out, rows, sig, gb, ab, lay, ctx.plan.t, key_nav, key_sig, fixes.t[idx], idx, res,
                    spec.kind, spec.lag, it, err, {}, notes, sd)


def _residuals(ctx, fixes, Rwb, pw, vw, vals, gtsam):
    """Post-fit residuals of the fixes used (antenna minus fix): position north, east, up
    [m] and, with velocity fixes, velocity east, north, up [m/s]."""
    idx = ctx.plan.fix_index
    kf = ctx.plan.fix_key
    ant_w = pw[kf] + np.einsum("kij,j->ki", Rwb[kf], fixes.lever_arm)
    fix_w = ctx.frame.to_w(fixes.pos[idx, 0], fixes.pos[idx, 1], fixes.pos[idx, 2])
    Rnw = np.swapaxes(ctx.frame.R_wn(fixes.pos[idx, 0], fixes.pos[idx, 1]), -1, -2)
    res = np.einsum("kij,kj->ki", Rnw, ant_w - fix_w)[:, [1, 0, 2]]
    if fixes.vel is None:
        return res
    seg = ctx.seg
    s = np.minimum(np.floor((fixes.t[idx] - seg.t0) / seg.dt).astype(int), seg.w.shape[0] - 1)
    B = gtsam.symbol_shorthand.B
    gb = np.array([vals.atConstantBias(B(int(k))).gyroscope() for k in kf])
    wl = np.cross(seg.w[s] - gb, fixes.lever_arm)
    v_ant = vw[kf] + np.einsum("kij,kj->ki", Rwb[kf], wl)
    dv = np.einsum("kij,kj->ki", Rnw, v_ant) - fixes.vel[idx]
    return np.column_stack([res, dv])
