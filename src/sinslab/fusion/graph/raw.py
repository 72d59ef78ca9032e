"""Raw GNSS in the graph: a pseudorange and a range-rate (Doppler) factor per observation
epoch, and the receiver clock as a variable of every keyframe — the observation model of
the tightly coupled filter (:mod:`sinslab.fusion.gnss`) as factors.

GTSAM's own ``PseudorangeFactor``/``DopplerFactor`` do not fit that model: no clock drift
variable (the Doppler takes the mean drift between two bias variables), one clock per
factor (no inter-system bias) and the Doppler's line of sight frozen where the factor is
made. Here, with the filter's notation (``r_a``, ``v_a`` the antenna in ECEF, ``e`` the
unit line of sight, ``ω_e`` the Earth rate):

- **clock variable** ``C_k = [b, d, b_s...]`` per keyframe (bias [m], drift [m/s], one
  inter-system bias [m] per system after the first, absolute, not errors of a nominal
  clock), joined by the filter's clock process ``ḃ = d + w_b``, ``ḋ = w_d``,
  ``ḃ_s = w_s`` (:class:`sinslab.nav.errstate.ClockBlock`): ``C_k − F C_{k−1}`` with
  ``F = [[1, Δt], [0, 1]] ⊕ I`` and its exact discrete covariance
  ``[[q_b Δt + q_d Δt³/3, q_d Δt²/2], [q_d Δt²/2, q_d Δt]] ⊕ q_s Δt``;
- **pseudoranges** of an epoch (one factor on ``X_k``, ``C_k``):
  ``|r_s − r_a| + ω_e (x_s y_a − y_s x_a)/c + b + b_sys − c δt_s + I + T − P``;
- **range rates** (one factor on ``X_k``, ``V_k``, ``C_k``):
  ``(v_s − v_a)·e + ω_e (v_sy x_a + y_s v_ax − v_sx y_a − x_s v_ay)/c + d − c δṫ_s − ρ̇``,
  ``e`` and the Sagnac terms evaluated at every linearisation (the geometry follows the
  estimate, as the filter's does at every epoch).

The antenna is ``r_a = r_0 + C_e^w (t + R l)``, ``v_a = C_e^w (v + R (ω × l))`` from the pose
``(R, t)`` and velocity ``v`` in the graph's frame (Earth-fixed: its velocity is the ECEF
velocity turned). A keyframe sits at every observation epoch used (outside the outages),
so no clock or position is extrapolated to the epoch. What does not depend on the receiver
state to the metre — the satellites' selection (mask, ephemeris, ``max_satellites``) and
weights (elevation, C/N0), the ionosphere and troposphere — is evaluated once per epoch at
the single-point position, with the measurements' own rules.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from sinslab.core import attitude as A
from sinslab.core import earth as E
from sinslab.core import gnss as G

__all__ = ["ClockChain", "EpochRows", "satellite_factors", "epoch_corrections"]

_W = E.WIE / G.C_LIGHT


@dataclass
class ClockChain:
    """The receiver clock as one vector variable per keyframe (see the module notes).

    Attributes
    ----------
    t : ndarray (K,)
        Keyframe times [s].
    q : ndarray (k,)
        Noise densities of :class:`~sinslab.nav.errstate.ClockBlock` (bias [m²/s], drift
        [m²/s³], inter-system biases [m²/s]).
    start : ndarray (k,)
        The clock at the first keyframe (its prior's mean).
    """

    t: np.ndarray
    q: np.ndarray
    start: np.ndarray

    def key(self, i):
        import gtsam
        return gtsam.symbol_shorthand.C(i)

    def keys(self, i):
        return [self.key(i)]

    def transition(self, dt):
        """``(F, Q)`` over ``dt`` [s]."""
        q = self.q
        F = np.eye(q.size)
        F[0, 1] = dt
        Q = np.diag(q * dt)
        Q[0, 0] += q[1] * dt ** 3 / 3.0
        Q[0, 1] = Q[1, 0] = q[1] * dt ** 2 / 2.0
        return F, Q

    def initial(self, i, prev):
        """The start value of keyframe ``i``: the prior's mean, or the estimate of the
        keyframe before carried by ``F``."""
        if i == 0:
            return [(self.key(0), self.start.copy())]
        F, _ = self.transition(float(self.t[i] - self.t[i - 1]))
        return [(self.key(i), F @ np.asarray(prev[0], float))]

    def process(self, i):
        """The clock process factor between keyframes ``i − 1`` and ``i``."""
        import gtsam
        F, Q = self.transition(float(self.t[i] - self.t[i - 1]))
        k0, k1 = self.key(i - 1), self.key(i)
        eye = np.eye(F.shape[0])
        negF = -F

        def err(this, values, H):
            if H is not None:
                H[0] = negF
                H[1] = eye
            return values.atVector(k1) - F @ values.atVector(k0)

        return [gtsam.CustomFactor(gtsam.noiseModel.Gaussian.Covariance(Q), [k0, k1], err)]

    def prior(self, cov):
        """The prior factor of the first keyframe's clock, covariance ``cov`` (k, k)."""
        import gtsam
        return gtsam.PriorFactorVector(self.key(0), self.start, gtsam.noiseModel.Gaussian.Covariance(cov))


@dataclass(frozen=True)
class EpochRows:
    """The satellites of one observation epoch in the graph: ``epoch`` (index), ``key``
    (keyframe), ``rows`` (observation rows used), per kind (``"pseudorange"``,
    ``"Doppler"``) ``{kind: (rows, σ, factor)}``."""

    epoch: int
    key: int
    used: dict


def epoch_corrections(sv, e, rows, lat, lon, h):
    """Elevation, azimuth [rad] and the ionosphere + troposphere delay [m] of ``rows`` of
    epoch ``e`` at the receiver position ``lat, lon, h`` [rad, rad, m] (the models of the
    tightly coupled filter)."""
    from sinslab.fusion.gnss import F_L1
    el, az = E.elevation_azimuth(sv.sat_pos[rows], lat, lon, h)
    iono = G.klobuchar(sv.t_epoch[e] - sv.t_ref, lat, lon, az, el, sv.iono) * (F_L1 / sv.freq[rows]) ** 2
    return el, az, iono + G.saastamoinen(lat, h, el)


def _clock_rows(systems, row_systems, nc):
    """``(n, nc)``: 1 in the bias column and in each row's inter-system bias column."""
    Hc = np.zeros((row_systems.size, nc))
    Hc[:, 0] = 1.0
    for j, s in enumerate(systems[1:]):
        Hc[row_systems == s, 2 + j] = 1.0
    return Hc


def _pseudorange_factor(gtsam, frame, kx, kc, rs, corr, obs, Hc, lever, noise):
    """Pseudoranges of one epoch (module notes); residual predicted − measured [m]."""
    C_ew, r0 = frame.C_ew, frame.r0
    sag = _W * np.stack([-rs[:, 1], rs[:, 0], np.zeros(rs.shape[0])], -1)
    skl = A.skew(lever)

    def err(this, values, H):
        pose = values.atPose3(kx)
        R = pose.rotation().matrix()
        ra = r0 + C_ew @ (pose.translation() + R @ lever)
        rho, u = G.sagnac_range(rs, ra)
        if H is not None:
            GC = (sag - u) @ C_ew @ R
            H[0] = np.hstack([-GC @ skl, GC])
            H[1] = Hc
        return rho + Hc @ values.atVector(kc) + corr - obs

    return gtsam.CustomFactor(noise, [kx, kc], err)


def _range_rate_factor(gtsam, frame, kx, kv, kc, rs, vs, sat_drift, obs, nc, lever, wl, noise):
    """Range rates of one epoch (module notes); residual predicted − measured [m/s]."""
    C_ew, r0 = frame.C_ew, frame.r0
    n = rs.shape[0]
    zero = np.zeros(n)
    gr_sag = _W * np.stack([vs[:, 1], -vs[:, 0], zero], -1)
    gv_sag = _W * np.stack([rs[:, 1], -rs[:, 0], zero], -1)
    skl, skw = A.skew(lever), A.skew(wl)
    Hd = np.zeros((n, nc))
    Hd[:, 1] = 1.0

    def err(this, values, H):
        pose = values.atPose3(kx)
        R = pose.rotation().matrix()
        ra = r0 + C_ew @ (pose.translation() + R @ lever)
        va = C_ew @ (values.atVector(kv) + R @ wl)
        d = rs - ra
        rho = np.sqrt(np.einsum("ij,ij->i", d, d))
        e = d / rho[:, None]
        dv = vs - va
        de = np.einsum("ij,ij->i", dv, e)
        rate = de + _W * (vs[:, 1] * ra[0] + rs[:, 1] * va[0] - vs[:, 0] * ra[1] - rs[:, 0] * va[1])
        if H is not None:
            gr = -(dv - de[:, None] * e) / rho[:, None] + gr_sag
            GV = (gv_sag - e) @ C_ew
            GRR = gr @ C_ew @ R
            H[0] = np.hstack([-GRR @ skl - GV @ R @ skw, GRR])
            H[1] = GV
            H[2] = Hd
        return rate + values.atVector(kc)[1] - sat_drift - obs

    return gtsam.CustomFactor(noise, [kx, kv, kc], err)


def satellite_factors(gtsam, frame, measurements, plan, seg, positions, systems, gyro_bias):
    """The pseudorange and range-rate factors of the epochs of ``plan`` (``plan.fix_index``
    the epochs, ``plan.fix_key`` their keyframes).

    Parameters
    ----------
    measurements : sequence of :class:`sinslab.fusion.gnss.Pseudoranges` /
        :class:`~sinslab.fusion.gnss.RangeRates`
        What the filter would apply: observations, σ₀, mask, C/N0 reference, satellite
        limits, lever arm.
    positions : ndarray (E, 3)
        ``lat, lon, h`` per epoch [rad, rad, m] where elevations and atmospheric delays
        are evaluated (the single-point solution).
    systems : tuple of str
        The clock's systems (the first the reference).
    gyro_bias : ndarray (3,)
        The start's gyro compensation (the lever arm's rate term, as the filter's).

    Returns ``({keyframe: [factors]}, [EpochRows])``.
    """
    X, V, C = (gtsam.symbol_shorthand.X, gtsam.symbol_shorthand.V, gtsam.symbol_shorthand.C)
    nc = len(systems) + 1
    out, record = {}, []
    for e, k in zip(plan.fix_index, plan.fix_key):
        e, k = int(e), int(k)
        used = {}
        for m in measurements:
            sv = m.sv
            rows = sv.rows(e)
            el, _, corr = epoch_corrections(sv, e, rows, *positions[e])
            keep = m._select(SimpleNamespace(item=e), rows, el)[0]
            if not keep.any():
                continue
            r = rows[keep]
            var = m._weights(r, el[keep])
            noise = gtsam.noiseModel.Diagonal.Variances(var)
            if m.kind == "pseudorange":
                fac = _pseudorange_factor(gtsam, frame, X(k), C(k), sv.sat_pos[r], corr[keep] - sv.sat_clock[r],
                                          sv.pseudorange[r], _clock_rows(systems, sv.system[r], nc), m.lever, noise)
            else:
                s = min(int(np.floor((float(sv.t_epoch[e]) - seg.t0) / seg.dt)), seg.w.shape[0] - 1)
                wl = np.cross(seg.w[max(s, 0)] - gyro_bias, m.lever)
                fac = _range_rate_factor(gtsam, frame, X(k), V(k), C(k), sv.sat_pos[r], sv.sat_vel[r],
                                         sv.sat_drift[r], sv.range_rate[r], nc, m.lever, wl, noise)
            out.setdefault(k, []).append(fac)
            used[m.kind] = (r, np.sqrt(var), fac)
        if used:
            record.append(EpochRows(e, k, used))
    return out, record


# ---------------------------------------------------------------------------- the run ---
def graph_navigate_raw(imu, init, raw, measurements, P0, model, *, ins=None, grid=None, spec=None):
    """INS + pseudoranges and range rates as a factor graph (GTSAM), on the inputs of the
    tightly coupled filter (:func:`sinslab.fusion.tightly_coupled.tightly_coupled`).

    Parameters
    ----------
    imu, init, P0, model, ins, grid
        As for the tightly coupled filter; the model is the 15-state one with bias random
        walks and a receiver-clock block (its noise densities and systems are the clock
        chain's, its part of ``P0`` the first clock's prior).
    raw : sinslab.fusion.tightly_coupled.RawGnss
        Its single-point solution (where elevations and atmospheric delays are evaluated)
        and its nominal clock at the start (the first clock's prior mean).
    measurements : sequence of Pseudoranges / RangeRates
        The filter's measurements of the run (``raw.make(...)``): σ₀, mask, limits, lever
        arm, outages.
    spec : GraphSpec

    Returns
    -------
    GraphRun
        With ``raw`` set: the clock (M, k) and its σ at the output epochs, the post-fit
        residuals of every satellite used.
    """
    from sinslab.fusion.graph.estimator import GraphSpec, run_graph
    from sinslab.fusion.graph.translate import require_gtsam
    from sinslab.fusion.spec import FilterGrid, InsSpec
    gtsam = require_gtsam()
    ins, grid, spec = ins or InsSpec(), grid or FilterGrid(), spec or GraphSpec()
    return run_graph(gtsam, imu, ins, grid, spec,
                     lambda t_end: _raw_problem(gtsam, imu, init, raw, measurements, P0, model, ins, t_end, spec),
                     lambda ctx, vals, covs, t_out, it, err, facts:
                     _raw_result(gtsam, ctx, vals, covs, t_out, facts[0], spec, it, err, facts[1]))


def _positions(raw, init_row):
    """``lat, lon, h`` (E, 3) per epoch: the single-point solution, the nearest one where
    an epoch has none (the start where none has)."""
    sp = raw.single_point()
    p = np.column_stack([sp.lat, sp.lon, sp.h])
    ok = np.flatnonzero(np.all(np.isfinite(p), 1))
    if not ok.size:
        return np.tile(init_row[7:10], (p.shape[0], 1))
    near = ok[np.clip(np.searchsorted(ok, np.arange(p.shape[0])), 0, ok.size - 1)]
    return p[near]


def _raw_problem(gtsam, imu, init, raw, measurements, P0, model, ins, t_end, spec):
    from sinslab.fusion.graph import build
    from sinslab.fusion.graph.estimator import GraphProblem, graph_start
    from sinslab.fusion.graph.translate import GraphImuModel
    imu_model = GraphImuModel.from_error_model(model, clock=True)
    lay = model.layout
    st = graph_start(gtsam, imu, init, P0, lay, ins)
    sv = measurements[0].sv
    epochs = SimpleNamespace(t=sv.t_epoch, outages=tuple(measurements[0].outages), windows=None, arrive=sv.t_epoch)
    plan = build.plan_keyframes(epochs, st.t0, t_end, spec.max_gap)
    block = next(s for s in model.sensor_blocks if s.kind == "clock")
    b0, d0, tn, isb = raw.clock_nominal(st.t0)
    chain = ClockChain(plan.t, np.asarray(block.q, float),
                       np.r_[b0 + d0 * (st.t0 - tn), d0, [isb.get(s, 0.0) for s in block.systems[1:]]])
    sl = lay.find("receiver_clock")
    priors = [*st.priors, chain.prior(np.asarray(P0, float)[sl, sl])]
    fac, record = satellite_factors(gtsam, st.frame, measurements, plan, st.seg, _positions(raw, st.row0),
                                    block.systems, st.gyro_bias)
    notes = tuple(f"{n} bias random walk raised to the graph's floor" for n in imu_model.floored)
    return GraphProblem(st.frame, imu_model, spec.gravity, st.seg, plan, priors, st.pose0, st.vel0, st.bias0, fac,
                        fac, lay, chain), (record, notes)


def _raw_result(gtsam, ctx, vals, covs, t_out, record, spec, it, err, notes):
    from sinslab.fusion.graph.estimator import GraphRun, keyframe_states
    Rwb, pw, vw, key_nav, key_sig, rows, gb, ab, sig = keyframe_states(gtsam, ctx, vals, covs, t_out)
    chain = ctx.extra
    K = ctx.plan.t.size
    kc = np.array([vals.atVector(chain.key(i)) for i in range(K)])
    kcs = np.array([np.sqrt(np.diag(covs[i][3])) for i in range(K)])
    clock = np.column_stack([np.interp(t_out, ctx.plan.t, kc[:, j]) for j in range(kc.shape[1])])
    clock_sd = np.column_stack([np.interp(t_out, ctx.plan.t, kcs[:, j]) for j in range(kc.shape[1])])
    sl = ctx.layout.find("receiver_clock")
    sig[:, sl] = clock_sd
    key_sig[:, sl] = kcs
    res = {}
    for er in record:
        for kind, (r, sd_, fac) in er.used.items():
            res.setdefault(kind, []).append((er.epoch, r, fac.unwhitenedError(vals), sd_))
    residuals = {kind: tuple(np.concatenate(col) for col in (
        [np.full(r.size, e) for e, r, _, _ in lst], [r for _, r, _, _ in lst], [v for _, _, v, _ in lst],
        [s for _, _, _, s in lst])) for kind, lst in res.items()}
    e0 = np.zeros(0)
    return GraphRun(t_out, rows, sig, gb, ab, ctx.layout, ctx.plan.t, key_nav, key_sig, e0, e0.astype(np.int64),
                    np.zeros((0, 3)), spec.kind, spec.lag, it, err, {}, notes, np.zeros((0, 3)), np.zeros((0, 3)),
                    e0, raw={"clock": clock, "clock_sigma": clock_sd, "key_clock": kc, "residuals": residuals})
