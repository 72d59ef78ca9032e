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
from sinslab.fusion.graph.translate import GraphImuModel, fix_covariance_w, require_gtsam
from sinslab.fusion.spec import FilterGrid, FixSpec, InsSpec
from sinslab.nav import strapdown as sd

__all__ = ["GraphSpec", "GraphRun", "GraphEstimator", "graph_navigate"]

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
    residual_sigma : ndarray (J, 3) or (J, 6)
        σ of each post-fit residual, ``√diag(R − H P Hᵀ)`` (P the marginal of the
        keyframe the fix is at): the residual of a consistent graph over it is N(0, 1).
    residual_chi2 : ndarray (J,)
        The studentised post-fit residual of each fix, ``rᵀ (R − H P Hᵀ)⁻¹ r`` (position
        and velocity blocks apart): its mean is the fix dimension for a consistent graph,
        as the filter's NIS is.
    raw : dict or None
        Raw GNSS (:func:`sinslab.fusion.graph.raw.graph_navigate_raw`): ``clock`` and
        ``clock_sigma`` (M, k) at the epochs (bias [m], drift [m/s], inter-system biases
        [m]), ``key_clock`` (K, k), ``residuals`` ``{kind: (epoch, row, post-fit residual
        predicted − measured, σ)}`` of every satellite used.
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
    residual_sigma: np.ndarray | None = None
    residual_chi2: np.ndarray | None = None
    raw: dict | None = None

    def as_driver_result(self):
        """The solution as a :class:`sinslab.fusion.driver.DriverResult` of one stream
        (what the recorded front end and the outputs read): ``x`` zero (the graph's solution
        is the navigation itself, nothing is left to feed back), σ, the bias compensation,
        and as the applied records the fixes used with their post-fit residuals, their σ
        and their studentised χ² in place of innovations, innovation σ and NIS."""
        from sinslab.fusion.driver import Applied, DriverResult
        J = self.fix_t.size
        comp = {"gyro_bias": self.gyro_bias, "accel_bias": self.accel_bias}
        r = self.residual
        applied = Applied(np.zeros(J, dtype=np.int64), self.fix_index.astype(np.int64), self.fix_t, self.fix_t,
                          list(r), self.residual_chi2, list(self.residual_sigma))
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
    #: variables of each keyframe beside pose, velocity and bias (the receiver clock of raw
    #: GNSS, :class:`sinslab.fusion.graph.raw.ClockChain`), or None
    extra: object = None

    def params(self, p_w):
        """Preintegration parameters of an interval that starts at the w point ``p_w``."""
        return self.imu_model.params(self.frame, p_w if self.gravity == "local" else None)


@dataclass(frozen=True)
class GraphStart:
    """What every graph of a run starts from: the first row ``[q, v, lat, lon, h]``, the
    frame at it, the start time, the IMU cut from it, the start's gyro compensation, the
    first bias value and the priors on the first pose, velocity and bias."""

    row0: np.ndarray
    frame: LocalFrame
    t0: float
    seg: build.Segments
    gyro_bias: np.ndarray
    bias0: object
    priors: list
    pose0: object
    vel0: np.ndarray


def graph_start(gtsam, imu, init, P0, layout, ins: InsSpec) -> GraphStart:
    """The :class:`GraphStart` of a run (the filter's start, compensation and ``P0``)."""
    if ins.vertical != "free":
        raise InputError("the graph estimator integrates a free vertical channel (vertical='free')")
    row0 = sd.initial_state_array(init)[:10]
    frame = LocalFrame(row0[7], row0[8], row0[9])
    start = int(ins.start)
    t0 = float(ins.t_start) if ins.t_start is not None else (float(imu.t[start - 1]) if start > 0 else imu.t0)
    keys = (gtsam.symbol_shorthand.X, gtsam.symbol_shorthand.V, gtsam.symbol_shorthand.B)
    gb = np.zeros(3) if ins.gyro_bias is None else np.asarray(ins.gyro_bias, dtype=float)
    ab = np.zeros(3) if ins.accel_bias is None else np.asarray(ins.accel_bias, dtype=float)
    bias0 = gtsam.imuBias.ConstantBias(ab, gb)
    priors, pose0, vel0 = build.prior_factors(gtsam, frame, row0, bias0, P0, layout, keys)
    return GraphStart(row0, frame, t0, build.Segments(imu, start, t0), gb, bias0, priors, pose0, vel0)


def _problem(gtsam, imu, init, fixes: FixSpec, P0, model, ins: InsSpec, t_end, spec: GraphSpec):
    imu_model = GraphImuModel.from_error_model(model)
    if fixes.n_pos != 3:
        raise InputError("the graph estimator needs 3-D fixes (a height with each)")
    st = graph_start(gtsam, imu, init, P0, model.layout, ins)
    frame, seg, gb = st.frame, st.seg, st.gyro_bias
    plan = build.plan_keyframes(fixes, st.t0, t_end, spec.max_gap)
    keys = (gtsam.symbol_shorthand.X, gtsam.symbol_shorthand.V, gtsam.symbol_shorthand.B)
    fixes_at = build.fix_factors(gtsam, frame, fixes, plan, seg, fixes.lever_arm, fixes.robust, keys[:2], "online", gb)
    fixes_batch = fixes_at if fixes.robust is None or fixes.robust.kind != "igg3" else \
        build.fix_factors(gtsam, frame, fixes, plan, seg, fixes.lever_arm, fixes.robust, keys[:2], "batch", gb)
    notes = tuple(f"{n} bias random walk raised to the graph's floor" for n in imu_model.floored)
    return GraphProblem(frame, imu_model, spec.gravity, seg, plan, st.priors, st.pose0, st.vel0, st.bias0, fixes_at,
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
    return run_graph(gtsam, imu, ins, grid, spec,
                     lambda t_end: _problem(gtsam, imu, init, fixes, P0, model, ins, t_end, spec),
                     lambda ctx, vals, covs, t_out, it, err, notes:
                     _result(gtsam, ctx, vals, covs, t_out, fixes, spec, it, err, notes))


def run_graph(gtsam, imu, ins, grid, spec, make, finish) -> GraphRun:
    """Build (``make(t_end) -> (GraphProblem, facts)``), solve and read out
    (``finish(ctx, values, covariances, t_out, iterations, error, facts) -> GraphRun``) a
    graph over the output epochs of the run, the CPU time of each stage in ``cpu``."""
    c = time.process_time()
    t_out = output_epochs(imu, ins, grid)
    ctx, facts = make(float(t_out[-1]))
    cpu = {"build": time.process_time() - c}
    vals, covs, it, err = solve(gtsam, ctx, spec, cpu)
    c = time.process_time()
    run = finish(ctx, vals, covs, t_out, it, err, facts)
    cpu["output"] = time.process_time() - c
    run.cpu.update(cpu)
    return run


def output_epochs(imu, ins: InsSpec, grid: FilterGrid):
    """The filter epochs [s] of a run: every ``grid.kf_dt`` from the start while IMU
    samples last (whole steps)."""
    start = int(ins.start)
    T = grid.kf_dt
    k_kf = int(round(T / imu.dt))
    if k_kf < 1 or abs(k_kf * imu.dt - T) > 1e-6 * T:
        raise ValueError(f"kf_dt={T} s must be a multiple of the IMU interval {imu.dt} s")
    n_ep = (len(imu) - start) // k_kf
    t0 = float(ins.t_start) if ins.t_start is not None else (float(imu.t[start - 1]) if start > 0 else imu.t0)
    return t0 + T * np.arange(n_ep + 1)


def solve(gtsam, ctx, spec: GraphSpec, cpu: dict):
    """The online pass, then (batch) Levenberg–Marquardt from it: ``(values, covariances,
    iterations, final error)``; CPU times into ``cpu``."""
    c = time.process_time()
    vals, covs, process = online_pass(gtsam, ctx, spec.lag, want_sigma=spec.kind == "fixed-lag")
    cpu["online"] = time.process_time() - c
    it, err = 0, float("nan")
    if spec.kind == "batch":
        c = time.process_time()
        vals, covs, it, err = batch_solve(gtsam, ctx, vals, process)
        cpu["batch"] = time.process_time() - c
    return vals, covs, it, err


def keyframe_states(gtsam, ctx, vals, covs, t_out):
    """The solution at the keyframes and at the output epochs: ``(Rwb, pw, vw, key_nav,
    key_sigma, rows, gyro_bias, accel_bias, sigma)``."""
    X, V = gtsam.symbol_shorthand.X, gtsam.symbol_shorthand.V
    K = ctx.plan.t.size
    Rwb = np.array([vals.atPose3(X(i)).rotation().matrix() for i in range(K)])
    pw = np.array([vals.atPose3(X(i)).translation() for i in range(K)])
    vw = np.array([vals.atVector(V(i)) for i in range(K)])
    key_nav = ctx.frame.rows_from_w(Rwb, vw, pw)
    lay = ctx.layout
    key_sig = np.array([key_sigma(ctx.frame, lay, Rwb[i], *key_nav[i, 7:10], covs[i]) for i in range(K)])
    rows, gb, ab = dense_solution(gtsam, ctx, vals, t_out)
    sig = np.column_stack([np.interp(t_out, ctx.plan.t, key_sig[:, j]) for j in range(lay.n)])
    return Rwb, pw, vw, key_nav, key_sig, rows, gb, ab, sig


def _result(gtsam, ctx, vals, covs, t_out, fixes, spec, it, err, notes):
    Rwb, pw, vw, key_nav, key_sig, rows, gb, ab, sig = keyframe_states(gtsam, ctx, vals, covs, t_out)
    lay = ctx.layout
    res = _residuals(ctx, fixes, Rwb, pw, vw, vals, gtsam)
    idx = ctx.plan.fix_index
    sd = fixes.sigma[idx][:, :3] if fixes.vel is None else np.column_stack([fixes.sigma[idx][:, :3], fixes.vel_sigma[idx]])
    rsd, chi2 = _studentised(ctx, fixes, Rwb, covs, res)
    return GraphRun(t_out, rows, sig, gb, ab, lay, ctx.plan.t, key_nav, key_sig, fixes.t[idx], idx, res,
                    spec.kind, spec.lag, it, err, {}, notes, sd, rsd, chi2)


def _studentised(ctx, fixes, Rwb, covs, res):
    """σ and χ² of the post-fit residuals (:class:`GraphRun`): ``S = R − H P Hᵀ`` with
    ``H = [−R_wb [l×], R_wb]`` on the keyframe's pose marginal for the position (GTSAM's
    tangent: rotation, then body-axis translation) and the velocity marginal for the
    velocity (its lever-arm term, ``ω × l``, left out: mm/s against the fix σ)."""
    idx, kf = ctx.plan.fix_index, ctx.plan.fix_key
    lever = np.asarray(fixes.lever_arm, dtype=float)
    Rwn = ctx.frame.R_wn(fixes.pos[idx, 0], fixes.pos[idx, 1])
    sd = np.empty_like(res)
    chi2 = np.zeros(idx.size)
    for m, (j, k) in enumerate(zip(idx, kf)):
        Cx, Cv = covs[k][:2]
        R = Rwb[k]
        H = np.hstack([-R @ A.skew(lever), R])
        blocks = [(slice(0, 3), fix_covariance_w(fixes.sigma[j], Rwn[m]) - H @ Cx @ H.T, [1, 0, 2])]
        if fixes.vel is not None:
            blocks.append((slice(3, 6), Rwn[m] @ np.diag(fixes.vel_sigma[j] ** 2) @ Rwn[m].T - Cv, [0, 1, 2]))
        for sl, S_w, order in blocks:
            S_n = Rwn[m].T @ S_w @ Rwn[m]                     # ENU
            S_n = 0.5 * (S_n + S_n.T)
            w, V = np.linalg.eigh(S_n)
            w = np.maximum(w, 1e-6 * max(float(w.max()), 1e-30))     # a fix the graph follows exactly
            r_n = res[m, sl][np.argsort(order)]              # back to E, N, U
            chi2[m] += float(np.sum((V.T @ r_n) ** 2 / w))
            sd[m, sl] = np.sqrt(np.diag(S_n))[order]
    return sd, chi2


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


# ------------------------------------------------------------- the recorded front end ---
@dataclass(frozen=True)
class GraphEstimator:
    """The factor graph as the estimator of a recorded run
    (:class:`sinslab.fusion.estimators.Estimator`): the GNSS fix source's fixes (σ, lever
    arm, outages, robust weighting), the start, the IMU error model and its prior, solved
    by :func:`graph_navigate`; what the graph cannot take is refused in one line."""

    spec: GraphSpec = GraphSpec()

    @property
    def name(self):
        return "graph" if self.spec.kind == "batch" else "fixed-lag"

    def label(self):
        return ("factor graph (batch Levenberg–Marquardt)" if self.spec.kind == "batch"
                else f"factor graph (fixed-lag smoother, {self.spec.lag:g} s window)")

    def ready(self):
        """GTSAM importable (one line naming the extra otherwise)."""
        require_gtsam()

    def check(self, smooth, source, aids) -> None:
        self.ready()
        if smooth:
            raise InputError(f"the {self.name} estimator smooths already: --smooth (filter.smooth) goes with "
                             "the filter estimator")
        if source != "fixes":
            raise InputError(f"the {self.name} estimator takes position/velocity fixes (--fixes); raw "
                             "observations go through the filter estimator")
        if aids:
            raise InputError(f"the {self.name} estimator takes the IMU and the GNSS fixes only: drop --aid "
                             + ",".join(aids) + " (or use the filter estimator)")

    def estimate(self, e) -> tuple:
        plan = e.plans[0]
        fixes = plan.facts["spec"]
        run = graph_navigate(e.imu, e.start.nav_state, fixes, e.P0, e.model, ins=e.ins, grid=e.grid,
                             spec=self.spec)
        return run.as_driver_result(), None, self.report(run)

    def report(self, run: GraphRun):
        """The graph's own report (:class:`sinslab.fusion.aids.base.Report`)."""
        from sinslab.fusion.aids.base import Report
        cpu = float(sum(run.cpu.values()))
        m = {"estimator": self.name, "graph_keyframes": int(run.key_t.size), "graph_fixes_used": int(run.fix_t.size),
             "graph_iterations": int(run.iterations), "graph_cpu_s": cpu,
             "graph_residual_chi2_mean": float(np.mean(run.residual_chi2)) if run.fix_t.size else None}
        if self.spec.kind == "fixed-lag":
            m["graph_lag_s"] = float(self.spec.lag)
        else:
            m["graph_final_error"] = float(run.error)
        solved = (f"{run.iterations} Levenberg–Marquardt iterations from the fixed-lag pass"
                  if self.spec.kind == "batch" else "each keyframe as it left the window")
        notes = (f"Estimator: {self.label()} with GTSAM over {run.key_t.size} keyframes (the fixes' own times, "
                 f"one a second in outages), {solved}; σ from the marginals. The fix records are post-fit "
                 "residuals (antenna − fix), their NIS the studentised residual rᵀ(R − H P Hᵀ)⁻¹r, whose "
                 "mean is the fix dimension for a consistent graph.", *run.notes)
        lines = (f"  {self.label()}: {run.key_t.size} keyframes, {run.fix_t.size} fixes, "
                 + (f"{run.iterations} iterations, " if self.spec.kind == "batch" else "")
                 + f"CPU {cpu:.2f} s",)
        desc = (("^estimator$", "the estimator: filter, graph (batch) or fixed-lag"),
                ("^graph_residual_chi2_mean$", "mean studentised post-fit χ² of the fixes (their dimension "
                                               "for a consistent graph)"),
                ("^graph_", "the factor graph's solution: keyframes, fixes, iterations, CPU [s]"))
        return Report("graph", self.label(), metrics=m, notes=notes, lines=lines, descriptions=desc)
