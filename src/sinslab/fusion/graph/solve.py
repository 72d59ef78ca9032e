"""Solving the graph: the online pass (an incremental fixed-lag smoother, GTSAM's
``IncrementalFixedLagSmoother`` on ISAM2) and the batch Levenberg–Marquardt over the whole
record started from it; σ from GTSAM's marginals; the solution at the filter epochs.

The online pass adds one keyframe at a time, its initial value the IMU prediction from
the latest estimate. A keyframe's fixed-lag estimate is the one it has when it leaves the
window (``lag`` seconds of later data seen), its σ the smoother's marginal then. The
batch optimises every keyframe at once from those values, and its σ are the marginals of
the whole problem (``gtsam.Marginals``).

Between keyframes the solution at the filter epochs is the IMU prediction from the
keyframe before (its pose, velocity and bias), with the gap to the next keyframe's
estimate closed linearly in time (rotation: a body-axis rotation vector), and σ
interpolated linearly — the way the RTS smoother's correction is interpolated between
its stored epochs.
"""
from __future__ import annotations

import numpy as np

from sinslab.fusion.graph.build import integrate

__all__ = ["online_pass", "batch_solve", "dense_solution", "key_sigma"]


def _keys(gtsam):
    s = gtsam.symbol_shorthand
    return s.X, s.V, s.B


def _isam_params(gtsam):
    # QR: the bias chain's information (1/(rrw² Δt), 1e12 for a tactical gyro) next to
    # a metre-level position makes the normal equations of Cholesky indeterminate
    p = gtsam.ISAM2Params()
    p.setFactorization("QR")
    p.setRelinearizeThreshold(1e-3)
    p.relinearizeSkip = 1
    return p


def online_pass(gtsam, ctx, lag, *, want_sigma=True):
    """The fixed-lag smoother over the keyframes of ``ctx`` (:class:`GraphProblem`).

    Returns ``(values, covariances, process_factors)``: every keyframe's estimate as it
    left the window (``gtsam.Values``), its marginal covariances ``(pose, vel, bias[,
    extra...])`` per keyframe (None without ``want_sigma``), and the factors between
    consecutive keyframes (the ``CombinedImuFactor`` of every interval and the extra
    variables' process factors, for the batch)."""
    X, V, B = _keys(gtsam)
    t = ctx.plan.t
    ex = ctx.extra
    sm = gtsam.IncrementalFixedLagSmoother(float(lag), _isam_params(gtsam))
    f, v, ts = gtsam.NonlinearFactorGraph(), gtsam.Values(), gtsam.FixedLagSmootherKeyTimestampMap()
    for fac in ctx.priors:
        f.add(fac)
    start = [(X(0), ctx.pose0), (V(0), ctx.vel0), (B(0), ctx.bias0), *(ex.initial(0, None) if ex else ())]
    for k, val in start:
        v.insert(k, val)
        ts.insert((k, float(t[0])))
    for fac in ctx.fixes_at.get(0, ()):
        f.add(fac)
    sm.update(f, v, ts)
    nav = gtsam.NavState(ctx.pose0, ctx.vel0)
    bias = ctx.bias0
    out = gtsam.Values()
    covs = [None] * t.size
    process = []
    done = 0
    for i in range(1, t.size):
        pim, _ = integrate(gtsam, ctx.params(nav.position()), ctx.seg, t[i - 1], t[i], bias)
        between = [gtsam.CombinedImuFactor(X(i - 1), V(i - 1), X(i), V(i), B(i - 1), B(i), pim),
                   *(ex.process(i) if ex else ())]
        process += between
        pred = pim.predict(nav, bias)
        f, v, ts = gtsam.NonlinearFactorGraph(), gtsam.Values(), gtsam.FixedLagSmootherKeyTimestampMap()
        for fac in (*between, *ctx.fixes_at.get(i, ())):
            f.add(fac)
        new = [(X(i), pred.pose()), (V(i), pred.velocity()), (B(i), bias),
               *(ex.initial(i, [sm.calculateEstimateVector(k) for k in ex.keys(i - 1)]) if ex else ())]
        for k, val in new:
            v.insert(k, val)
            ts.insert((k, float(t[i])))
        while done < i and t[done] < t[i] - lag:          # leaves the window in this update
            _record(sm, done, out, covs, want_sigma, ctx)
            done += 1
        sm.update(f, v, ts)
        nav = gtsam.NavState(sm.calculateEstimatePose3(X(i)), sm.calculateEstimateVector(V(i)))
        bias = sm.calculateEstimateConstantBias(B(i))
    while done < t.size:
        _record(sm, done, out, covs, want_sigma, ctx)
        done += 1
    return out, (covs if want_sigma else None), process


def _record(sm, i, out, covs, want_sigma, ctx):
    import gtsam
    X, V, B = _keys(gtsam)
    out.insert(X(i), sm.calculateEstimatePose3(X(i)))
    out.insert(V(i), sm.calculateEstimateVector(V(i)))
    out.insert(B(i), sm.calculateEstimateConstantBias(B(i)))
    extra = ctx.extra.keys(i) if ctx.extra else ()
    for k in extra:
        out.insert(k, sm.calculateEstimateVector(k))
    if want_sigma:
        covs[i] = tuple(sm.marginalCovariance(k) for k in (X(i), V(i), B(i), *extra))


def batch_solve(gtsam, ctx, init, process_factors, *, max_iterations=100):
    """Levenberg–Marquardt over the whole record from ``init`` (gtsam.Values); returns
    ``(values, covariances, iterations, final error)``."""
    X, V, B = _keys(gtsam)
    g = gtsam.NonlinearFactorGraph()
    for fac in ctx.priors:
        g.add(fac)
    for fac in process_factors:
        g.add(fac)
    for fs in ctx.fixes_batch.values():
        for fac in fs:
            g.add(fac)
    p = gtsam.LevenbergMarquardtParams()
    p.setMaxIterations(int(max_iterations))
    p.setRelativeErrorTol(1e-12)
    p.setAbsoluteErrorTol(1e-12)
    p.setLinearSolverType("MULTIFRONTAL_QR")
    opt = gtsam.LevenbergMarquardtOptimizer(g, init, p)
    res = opt.optimize()
    # the marginals from a QR elimination of the whole problem at the optimum (ISAM2's batch
    # step: gtsam.Marginals factors by Cholesky, indeterminate for the same reason as above)
    marg = gtsam.ISAM2(_isam_params(gtsam))
    marg.update(g, res)
    covs = [tuple(marg.marginalCovariance(k) for k in (X(i), V(i), B(i), *(ctx.extra.keys(i) if ctx.extra else ())))
            for i in range(ctx.plan.t.size)]
    return res, covs, int(opt.iterations()), float(g.error(res))


def key_sigma(frame, layout, Rwb, lat, lon, h, cov):
    """The filter's σ (n,) of a keyframe from GTSAM's marginals ``(pose 6×6, vel 3×3,
    bias 6×6)``: attitude and position turned from body to the local level axes,
    position in ``[δL, δλ, δh]``; states the graph does not have are NaN."""
    from sinslab.core import earth as E
    Cx, Cv, Cb = cov[:3]
    Rnw = frame.R_wn(lat, lon).T
    Rnb = Rnw @ Rwb
    sig = np.full(layout.n, np.nan)
    sig[layout.slice("phi")] = np.sqrt(np.diag(Rnb @ Cx[:3, :3] @ Rnb.T))
    sig[layout.slice("dv")] = np.sqrt(np.diag(Rnw @ Cv @ Rnw.T))
    sp = np.sqrt(np.diag(Rnb @ Cx[3:, 3:] @ Rnb.T))               # E, N, U [m]
    rm, rn = (float(x) for x in E.radii(lat, h))
    sig[layout.slice("dp")] = [sp[1] / rm, sp[0] / (rn * np.cos(lat)), sp[2]]
    sb = np.sqrt(np.diag(Cb))
    sig[layout.slice("nabla")] = sb[:3]
    sig[layout.slice("eps")] = sb[3:]
    return sig


def dense_solution(gtsam, ctx, values, t_out):
    """Rows ``(M, 10)`` and the bias compensation ``(M, 3)``, ``(M, 3)`` at the times
    ``t_out`` (see the module notes)."""
    X, V, B = _keys(gtsam)
    t = ctx.plan.t
    M = t_out.size
    Rwb = np.empty((M, 3, 3))
    vw = np.empty((M, 3))
    pw = np.empty((M, 3))
    gb = np.empty((M, 3))
    ab = np.empty((M, 3))
    at_key = np.searchsorted(t, t_out - 1e-9)              # the keyframe at or after each time
    for i in range(t.size):
        sel = np.flatnonzero(at_key == i)
        b = values.atConstantBias(B(max(i - 1, 0)))
        if i == 0 or sel.size == 0:
            for m in sel:
                _put(m, values.atPose3(X(i)), values.atVector(V(i)), values.atConstantBias(B(i)),
                     Rwb, vw, pw, gb, ab)
            continue
        nav0 = gtsam.NavState(values.atPose3(X(i - 1)), values.atVector(V(i - 1)))
        pim, preds = integrate(gtsam, ctx.params(nav0.position()), ctx.seg, t[i - 1], t[i], b, marks=t_out[sel],
                               on_mark=lambda p: p.predict(nav0, b))
        end = pim.predict(nav0, b)
        pose1 = values.atPose3(X(i))
        dth = gtsam.Rot3.Logmap(end.pose().rotation().between(pose1.rotation()))
        dv = values.atVector(V(i)) - end.velocity()
        dp = pose1.translation() - end.pose().translation()
        for m, nv in zip(sel, preds):
            fr = (t_out[m] - t[i - 1]) / (t[i] - t[i - 1])
            R = nv.pose().rotation().compose(gtsam.Rot3.Expmap(fr * dth))
            _put(m, gtsam.Pose3(R, nv.pose().translation() + fr * dp), nv.velocity() + fr * dv, b,
                 Rwb, vw, pw, gb, ab)
    return ctx.frame.rows_from_w(Rwb, vw, pw), gb, ab


def _put(m, pose, v, b, Rwb, vw, pw, gb, ab):
    Rwb[m] = pose.rotation().matrix()
    pw[m] = pose.translation()
    vw[m] = v
    gb[m] = b.gyroscope()
    ab[m] = b.accelerometer()
