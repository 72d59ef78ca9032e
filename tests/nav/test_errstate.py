"""Error-state models: every F against the nonlinear mechanization equations.

Two independent checks, both against a compact reference INS written here (quaternion,
ENU velocity, geodetic position; sinslab.core.earth's WGS-84 radii and normal gravity):

1. exact: central finite differences of the nonlinear error dynamics (computed − true
   derivatives) at x = 0 reproduce F column by column (Maa, Mav, Map, Mva, Mvv, Mvp, Mpv,
   Mpp and each sensor block's coupling);
2. perturbation: small initial-state and sensor errors, nonlinear navigation versus linear
   propagation of F along the truth for 60 s on a manoeuvring trajectory (turns, pitch and
   roll oscillations, accelerations): the responses agree within 2 %.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from scipy.integrate import solve_ivp

from sinslab.estimation.kalman import discretize as kd
from sinslab.methods.rotins import joint_rotation_model
from sinslab.nav import errstate as es
from sinslab.core.attitude import euler_to_dcm, misalignment, rotvec_to_dcm
from sinslab.core.earth import WIE, gravity, radii
from sinslab.core.units import arcmin, dph, ppm, ug

# ------------------------------------------------------------------ reference INS ODE
LAT0, LON0, H0 = 0.6, 2.0, 1000.0
V0 = np.array([120.0, 160.0, 0.0])
ATT0 = np.array([0.05, -0.08, 0.7])


def wb_true(t):
    """Manoeuvre: pitch/roll oscillations (±9°, ±11°) and a varying turn rate [rad/s]."""
    t = np.asarray(t, dtype=float)
    return np.stack([0.05 * np.sin(2 * np.pi * t / 20), 0.06 * np.sin(2 * np.pi * t / 15 + 1.0),
                     0.03 + 0.05 * np.sin(2 * np.pi * t / 25)], -1)


def fb_true(t):
    """Specific force: lateral and forward accelerations plus near-g vertical [m/s²]."""
    t = np.asarray(t, dtype=float)
    return np.stack([1.0 * np.sin(2 * np.pi * t / 30), 2.0 + 1.5 * np.cos(2 * np.pi * t / 12),
                     9.9 + 0.5 * np.sin(2 * np.pi * t / 10)], -1)


def _q2C(q):
    q = q / np.linalg.norm(q)
    q0, q1, q2, q3 = q
    return np.array([[1 - 2 * (q2 * q2 + q3 * q3), 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2)],
                     [2 * (q1 * q2 + q0 * q3), 1 - 2 * (q1 * q1 + q3 * q3), 2 * (q2 * q3 - q0 * q1)],
                     [2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), 1 - 2 * (q1 * q1 + q2 * q2)]])


def _C2q(C):
    from sinslab.core.attitude import dcm_to_quat
    return dcm_to_quat(C)


def _qmul(p, q):
    p0, p1, p2, p3 = p
    q0, q1, q2, q3 = q
    return np.array([p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3, p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
                     p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1, p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0])


def _rates(L, h, v):
    rm, rn = radii(L, h)
    wie = np.array([0.0, WIE * np.cos(L), WIE * np.sin(L)])
    wen = np.array([-v[1] / rm, v[0] / rn, v[0] * np.tan(L) / rn])
    return wie, wen, rm, rn


def nav_rhs(y, wb, fb, hold=False):
    """Nonlinear ENU INS: y = [q0..q3 (C_b^n), vE vN vU, L λ h]."""
    q, v, (L, lam, h) = y[0:4], y[4:7], y[7:10]
    wie, wen, rm, rn = _rates(L, h, v)
    win = wie + wen
    qd = 0.5 * _qmul(q, np.r_[0.0, wb]) - 0.5 * _qmul(np.r_[0.0, win], q)
    C = _q2C(q)
    vd = C @ fb - np.cross(2 * wie + wen, v) + np.array([0.0, 0.0, -float(gravity(L, h))])
    pd = np.array([v[1] / rm, v[0] / (rn * np.cos(L)), v[2]])
    if hold:
        vd[2] = 0.0
        pd[2] = 0.0
    return np.concatenate([qd, vd, pd])


def nav_state(C, v, p):
    return np.concatenate([_C2q(C), v, p])


class SensorErr:
    """Sensor errors of a copy: constant biases, GM initial values (decaying), scale factors."""

    def __init__(self, eps=0, nabla=0, eps_m=0, nabla_m=0, tau_g=1.0, tau_a=1.0, kg=0, ka=0):
        z = np.zeros(3)
        self.eps, self.nabla = z + eps, z + nabla
        self.eps_m, self.nabla_m = z + eps_m, z + nabla_m
        self.tau_g, self.tau_a = tau_g, tau_a
        self.kg, self.ka = z + kg, z + ka

    def apply(self, t, wb, fb):
        em = self.eps_m * np.exp(-t / self.tau_g)
        am = self.nabla_m * np.exp(-t / self.tau_a)
        return wb * (1 + self.kg) + self.eps + em, fb * (1 + self.ka) + self.nabla + am


def run_copies(y0s, errs, T=60.0, hold=False, inputs=None, t_eval=None):
    """Integrate several INS copies jointly (same steps, correlated integration error)."""
    K = len(y0s)
    inputs = inputs or [(wb_true, fb_true)] * K

    def rhs(t, Y):
        Y = Y.reshape(K, 10)
        out = np.empty_like(Y)
        for k in range(K):
            w, f = inputs[k][0](t), inputs[k][1](t)
            if errs[k] is not None:
                w, f = errs[k].apply(t, w, f)
            out[k] = nav_rhs(Y[k], w, f, hold)
        return out.ravel()

    sol = solve_ivp(rhs, (0.0, T), np.concatenate(y0s), method="DOP853", rtol=1e-10, atol=1e-12,
                    dense_output=True, t_eval=t_eval)
    assert sol.success
    return sol


def nav_points(Y, t, wfun=wb_true, ffun=fb_true):
    """NavPoint (vectorised) from truth states Y (M, 10) at times t (M,)."""
    C = np.array([_q2C(y[:4]) for y in Y])
    return es.NavPoint(Y[:, 7], Y[:, 9], Y[:, 4:7], C, ffun(t), wfun(t))


def errors_of(Ytrue, Ycomp):
    """Nonlinear errors computed − true: φ, δv, δp (9,)."""
    phi = misalignment(_q2C(Ytrue[:4]), _q2C(Ycomp[:4]))
    return np.concatenate([phi, Ycomp[4:7] - Ytrue[4:7], Ycomp[7:10] - Ytrue[7:10]])


def transition(Fs, ts):
    """Φ(t_end, t_0) of ẋ = F(t) x given F at the midpoints of the steps of ts (exponential
    midpoint rule, O(dt²))."""
    Phis = scipy.linalg.expm(Fs * np.diff(ts)[:, None, None])
    while len(Phis) > 1:                 # pairwise products: log2(N) vectorised sweeps
        odd = Phis[-1:] if len(Phis) % 2 else Phis[:0]
        even = Phis[: len(Phis) - len(odd)]
        Phis = np.concatenate([even[1::2] @ even[0::2], odd])
    return Phis[0]


def propagate_linear(Fs, ts, x0):
    """x(t_end) for ẋ = F(t) x, x(t_0) = x0."""
    return transition(Fs, ts) @ x0


# -------------------------------------------------------------- exact FD Jacobian test
def _error_rhs(model_layout, nav_y, wb, fb, x, sensors, hold=False):
    """Nonlinear error derivative at error state x (model layout), true nav state nav_y."""
    lab = model_layout.labels
    get = lambda names: np.array([x[lab.index(n)] if n in lab else 0.0 for n in names])
    phi = get(["phiE", "phiN", "phiU"])
    dv = get(["dvE", "dvN", "dvU"])
    dp = get(["dL", "dlam", "dh"])
    C = _q2C(nav_y[:4])
    Cc = rotvec_to_dcm(-phi) @ C
    yc = nav_state(Cc, nav_y[4:7] + dv, nav_y[7:10] + dp)
    # sensor errors
    w, f = wb.copy(), fb.copy()
    xdot_s = {}
    for s in sensors:
        sl = model_layout.slice(s.name)
        xs = x[sl]
        full = np.zeros(3)
        full[[es._AXES[a] for a in s.axes]] = xs
        if s.kind in ("bias", "markov"):
            add = full
        elif s.kind == "scale":
            add = full * (wb if s.sensor == "gyro" else fb)
        else:
            add = np.zeros(3)
        if s.frame == "nav":
            add = C.T @ add
        if s.sensor == "gyro":
            w = w + add
        elif s.sensor == "accel":
            f = f + add
        xdot_s[s.name] = s.dynamics() * xs
    d_true = nav_rhs(nav_y, wb, fb, hold)
    d_comp = nav_rhs(yc, w, f, hold)
    Ct_dot = _qdot_to_Cdot(nav_y[:4], d_true[:4])
    Cc_dot = _qdot_to_Cdot(yc[:4], d_comp[:4])
    E = Cc @ C.T
    Ed = Cc_dot @ C.T + Cc @ Ct_dot.T
    S = -Ed @ E.T
    phid = np.array([S[2, 1], S[0, 2], S[1, 0]])
    full = dict(zip(["phiE", "phiN", "phiU", "dvE", "dvN", "dvU", "dL", "dlam", "dh"],
                    np.concatenate([phid, d_comp[4:7] - d_true[4:7], d_comp[7:10] - d_true[7:10]])))
    out = np.zeros(model_layout.n)
    for i, l in enumerate(lab):
        if l in full:
            out[i] = full[l]
    for s in sensors:
        out[model_layout.slice(s.name)] = xdot_s[s.name]
    return out


def _qdot_to_Cdot(q, qd, h=1.0):
    # C(q) is a quadratic form in q: the central difference is exact for any h (h = 1: no
    # cancellation); q is a unit quaternion and qd ⟂ q, so the raw form is the right one
    def raw(qq):
        q0, q1, q2, q3 = qq
        return np.array([[q0*q0+q1*q1-q2*q2-q3*q3, 2*(q1*q2-q0*q3), 2*(q1*q3+q0*q2)],
                         [2*(q1*q2+q0*q3), q0*q0-q1*q1+q2*q2-q3*q3, 2*(q2*q3-q0*q1)],
                         [2*(q1*q3-q0*q2), 2*(q2*q3+q0*q1), q0*q0-q1*q1-q2*q2+q3*q3]])
    return (raw(q + h * qd) - raw(q - h * qd)) / (2 * h)


_STEP = {"phi": 1e-6, "dv": 1e-4, "dL": 1e-7, "dlam": 1e-7, "dh": 1e-2, "eps": 1e-8, "nabla": 1e-5,
         "eps_m": 1e-8, "nabla_m": 1e-5, "kg": 1e-6, "ka": 1e-6, "lam": 1e-6}


def _steps(layout):
    out = []
    for l in layout.labels:
        for key in ("dlam", "dL", "dh"):
            if l.startswith(key):
                out.append(_STEP[key])
                break
        else:
            out.append(_STEP[[b.name for b in layout.blocks if l in b.labels][0]])
    return np.array(out)


def fd_jacobian(model, sensors, nav_y, wb, fb, hold=False):
    lay = model.layout
    J = np.zeros((lay.n, lay.n))
    for j, hj in enumerate(_steps(lay)):
        e = np.zeros(lay.n)
        e[j] = hj
        J[:, j] = (_error_rhs(lay, nav_y, wb, fb, e, sensors, hold)
                   - _error_rhs(lay, nav_y, wb, fb, -e, sensors, hold)) / (2 * hj)
    return J


SENSORS_ALL = [es.gyro_bias(), es.accel_bias(), es.gyro_markov(50.0, 0.01 * dph),
               es.accel_markov(80.0, 50 * ug), es.gyro_scale(), es.accel_scale(), es.installation()]


@pytest.mark.parametrize("core", ["full", "horizontal", "attvel", "attvel-horizontal", "attitude"])
@pytest.mark.parametrize("tk", [0.0, 17.0])
def test_F_equals_finite_difference_jacobian_of_mechanization(core, tk):
    """Eqs φ̇ = −ω_in×φ + δω_in − C δω_ib, δv̇ = f×φ + C δf − (2ω_ie+ω_en)×δv − (2δω_ie+δω_en)×v + δg,
    δṗ (Mpv, Mpp) and every sensor block's coupling: F is the exact Jacobian (1e-6)."""
    nav_y = nav_state(euler_to_dcm(ATT0 + [0.1, 0.2, -0.3 * tk / 17]), V0 + [3.0, -5.0, 2.0 * (core == "full")],
                      np.array([LAT0, LON0, H0]))
    wb, fb = wb_true(tk), fb_true(tk)
    hold = core in ("horizontal", "attvel-horizontal")
    if hold:
        nav_y[6] = 0.0
    model = es.ErrorModel(core, SENSORS_ALL)
    nav = es.NavPoint(nav_y[7], nav_y[9], nav_y[4:7], _q2C(nav_y[:4]), fb, wb)
    F = model.F(nav)
    J = fd_jacobian(model, SENSORS_ALL, nav_y, wb, fb, hold)
    # position-error columns of the held/attvel cores feed back through states that are
    # not carried; compare only the carried dynamics (rows and columns both carried)
    scale = np.abs(J).max(axis=0) + 1e-300
    err = np.abs(F - J).max(axis=0) / scale
    worst = int(np.argmax(err))
    assert err.max() < 1e-6, f"column {model.layout.labels[worst]}: rel err {err.max():.2e}"


def test_radius_derivatives_only_touch_the_latitude_column():
    """Without dR/dL, ∂g/∂L (PSINS form) F differs only in the δL column: by ~0.3 % in the φ
    rows and ~1.6 % in the δp rows; in the δv rows ∂g/∂L (≈ 0.05 m/s² per rad) dominates."""
    nav = es.NavPoint(LAT0, H0, V0, euler_to_dcm(ATT0), fb_true(0.0), wb_true(0.0))
    m1, m0 = es.ErrorModel("full"), es.ErrorModel("full", radius_derivatives=False)
    F1 = m1.F(nav)
    d = np.abs(F1 - m0.F(nav))
    assert np.all(d[:, [0, 1, 2, 3, 4, 5, 7, 8]] == 0.0)
    rel = lambda s: np.linalg.norm(d[s, 6]) / np.linalg.norm(F1[s, 6])
    assert 0 < rel(slice(0, 3)) < 0.01 and 0 < rel(slice(6, 9)) < 0.03


# --------------------------------------------------------- 60 s perturbation tests
T_END = 60.0
GRID = np.linspace(0.0, T_END, 3001)
MID = 0.5 * (GRID[1:] + GRID[:-1])

# one perturbation group per error term; the name says which equation it exercises
GROUPS = {
    "phi0 (Maa=-(w_in x), Mva=(f^n x))": dict(phi=np.array([2e-3, -1.5e-3, 3e-3])),
    "dv0 (Mav, Mvv, Mpv)": dict(dv=np.array([0.3, -0.2, 0.1])),
    "dp0 (Map, Mvp incl. dg, Mpp)": dict(dp=np.array([2e-6, -3e-6, 20.0])),
    "eps (phi' = -C_b^n eps)": dict(err=SensorErr(eps=np.array([1e-5, -2e-5, 1.5e-5]))),
    "nabla (dv' = C_b^n nabla)": dict(err=SensorErr(nabla=np.array([1e-3, -2e-3, 1.5e-3]))),
    "markov (x' = -x/tau)": dict(err=SensorErr(eps_m=np.array([2e-5, 1e-5, -2e-5]), tau_g=20.0,
                                               nabla_m=np.array([2e-3, -1e-3, 1e-3]), tau_a=30.0)),
    "scale (C diag(w^b) kg, C diag(f^b) ka)": dict(err=SensorErr(kg=np.array([300, -200, 500]) * ppm,
                                                                 ka=np.array([-400, 300, 200]) * ppm)),
}


def _x0_for(model, g):
    lay = model.layout
    x0 = np.zeros(lay.n)
    put = lambda names, vals: [x0.__setitem__(lay.index(n), v) for n, v in zip(names, vals) if n in lay.labels]
    put(["phiE", "phiN", "phiU"], g.get("phi", np.zeros(3)))
    put(["dvE", "dvN", "dvU"], g.get("dv", np.zeros(3)))
    put(["dL", "dlam", "dh"], g.get("dp", np.zeros(3)))
    e = g.get("err")
    if e is not None:
        for blk, val in (("eps", e.eps), ("nabla", e.nabla), ("eps_m", e.eps_m), ("nabla_m", e.nabla_m),
                         ("kg", e.kg), ("ka", e.ka)):
            if blk in lay.names:
                x0[lay.slice(blk)] = val
    return x0


@pytest.fixture(scope="module", params=["full", "horizontal"])
def perturbed_runs(request):
    core = request.param
    hold = core == "horizontal"
    v0 = V0.copy()
    C0 = euler_to_dcm(ATT0)
    p0 = np.array([LAT0, LON0, H0])
    y_true = nav_state(C0, v0, p0)
    y0s, errs = [y_true], [None]
    for g in GROUPS.values():
        phi = g.get("phi", np.zeros(3))
        dv = g.get("dv", np.zeros(3)).copy()
        dp = g.get("dp", np.zeros(3)).copy()
        if hold:
            dv[2] = dp[2] = 0.0
        y0s.append(nav_state(rotvec_to_dcm(-phi) @ C0, v0 + dv, p0 + dp))
        errs.append(g.get("err", SensorErr()))
    sol = run_copies(y0s, errs, T_END, hold=hold)
    Ymid = sol.sol(MID).T.reshape(MID.size, len(y0s), 10)[:, 0, :]
    navs = nav_points(Ymid, MID)
    model = es.ErrorModel(core, [es.gyro_bias(), es.accel_bias(), es.gyro_markov(20.0, 0.0),
                                 es.accel_markov(30.0, 0.0), es.gyro_scale(), es.accel_scale()])
    Phi = transition(model.F(navs), GRID)
    Yend = sol.y[:, -1].reshape(len(y0s), 10)
    return core, model, Phi, Yend


@pytest.mark.parametrize("group", list(GROUPS))
def test_linear_model_matches_nonlinear_60s(perturbed_runs, group):
    """60 s manoeuvring flight: nonlinear error (computed − true) vs Φ-propagated linear error."""
    core, model, Phi, Yend = perturbed_runs
    k = list(GROUPS).index(group) + 1
    g = GROUPS[group]
    x0 = _x0_for(model, g)
    if core == "horizontal":
        pass  # δvU, δh are not states; the nonlinear run holds them at zero
    x_lin = Phi @ x0
    e_nl = errors_of(Yend[0], Yend[k])
    lay = model.layout
    names9 = ["phiE", "phiN", "phiU", "dvE", "dvN", "dvU", "dL", "dlam", "dh"]
    nl = {n: e_nl[i] for i, n in enumerate(names9)}
    for b in ("phi", "dv", "dp"):
        labs = lay.blocks[lay.names.index(b)].labels
        a = np.array([nl[l] for l in labs])
        lin = x_lin[lay.slice(b)]
        if b == "phi":
            a0 = x0[lay.slice(b)]
            a, lin = a - a0, lin - a0       # compare the response, not the initial value
        elif b == "dv":
            a0 = x0[lay.slice(b)]
            a, lin = a - a0, lin - a0
        else:
            a0 = x0[lay.slice(b)]
            a, lin = a - a0, lin - a0
        rel = np.linalg.norm(a - lin) / np.linalg.norm(a)
        assert rel < 0.02, f"{core} {group}: block {b} differs by {100 * rel:.2f} % ({a} vs {lin})"


# -------------------------------------------------------- difference of two INS (001)
OMEGA_MOUNT = np.array([0.03, 0.0, 0.1])       # INS k rotates about its roll and azimuth axes


def _mount(t):
    return rotvec_to_dcm(np.multiply.outer(np.asarray(t, float), OMEGA_MOUNT))   # C_bk^b1


def wbk(t):
    R = _mount(t)
    return np.einsum("...ji,...j->...i", R, wb_true(t)) + OMEGA_MOUNT


def fbk(t):
    return np.einsum("...ji,...j->...i", _mount(t), fb_true(t))


def test_difference_model_matches_two_nonlinear_ins_60s():
    """Paper 001 eqs 3–8 (17-state joint model): INS 1 strapped to the carrier, INS k on a
    rotating mount; both held vertically; the nonlinear difference of their errors agrees
    with the linear joint model within 2 % after 60 s of manoeuvres."""
    C0 = euler_to_dcm(ATT0)
    v0 = V0.copy()
    p0 = np.array([LAT0, LON0, H0])
    phi1, phik = np.array([1e-3, -2e-3, 3e-3]), np.array([-1.5e-3, 1e-3, -2e-3])
    dv1, dvk = np.array([0.2, -0.1, 0.0]), np.array([-0.1, 0.3, 0.0])
    dp1, dpk = np.array([1e-6, -2e-6, 0.0]), np.array([-1e-6, 1e-6, 0.0])
    e1 = SensorErr(eps=np.array([1e-5, -2e-5, 1.5e-5]), nabla=np.array([1e-3, -2e-3, 0.0]))
    ek = SensorErr(eps=np.array([-2e-5, 1e-5, 2e-5]), nabla=np.array([-1.5e-3, 1e-3, 0.0]))
    y0s = [nav_state(C0, v0, p0), nav_state(rotvec_to_dcm(-phi1) @ C0, v0 + dv1, p0 + dp1),
           nav_state(C0, v0, p0), nav_state(rotvec_to_dcm(-phik) @ C0, v0 + dvk, p0 + dpk)]
    inputs = [(wb_true, fb_true)] * 2 + [(wbk, fbk)] * 2
    sol = run_copies(y0s, [None, e1, None, ek], T_END, hold=True, inputs=inputs)
    Ym = sol.sol(MID).T.reshape(MID.size, 4, 10)
    nav1 = nav_points(Ym[:, 0], MID)
    navk = nav_points(Ym[:, 2], MID, wbk, fbk)
    # the truth of INS k is the carrier truth seen through the mount
    assert np.allclose(navk.Cbn, nav1.Cbn @ _mount(MID), atol=1e-9)
    model = joint_rotation_model()
    lay = model.layout
    Fs = model.F(nav1, navk)
    x0 = np.zeros(17)
    x0[lay.slice("dp")] = (dp1 - dpk)[:2]
    x0[lay.slice("dv")] = (dv1 - dvk)[:2]
    x0[lay.slice("phi")] = phi1 - phik
    x0[lay.slice("eps_1")], x0[lay.slice("eps_k")] = e1.eps, ek.eps
    x0[lay.slice("nabla_1")], x0[lay.slice("nabla_k")] = e1.nabla[:2], ek.nabla[:2]
    x_lin = propagate_linear(Fs, GRID, x0)
    Y = sol.y[:, -1].reshape(4, 10)
    d = errors_of(Y[0], Y[1]) - errors_of(Y[2], Y[3])
    for b, idx in (("phi", [0, 1, 2]), ("dv", [3, 4]), ("dp", [6, 7])):
        a = d[idx] - x0[lay.slice(b)]
        lin = x_lin[lay.slice(b)] - x0[lay.slice(b)]
        rel = np.linalg.norm(a - lin) / np.linalg.norm(a)
        assert rel < 0.02, f"block {b}: {100 * rel:.2f} %"


def test_joint_model_is_paper_001_equations_3_to_8():
    """F1..F10 and G of paper 001 typed in from the paper (R_N meridian, R_E prime vertical)."""
    L, h = 0.49, 10.0
    vE, vN = 5.0, -3.0
    C1 = euler_to_dcm([0.01, -0.02, 0.4])
    C2 = euler_to_dcm([0.5, 2.0, -1.1])
    fn = np.array([0.3, -0.2, 9.79])
    nav1 = es.NavPoint(L, h, [vE, vN, 0.0], C1, C1.T @ fn)
    nav2 = nav1.with_attitude(C2)
    model = joint_rotation_model(1.0, 2.0, 3.0, 4.0)
    F, G = model.matrices(nav1, nav2)
    RNm, REm = radii(L, h)                      # paper: R_N meridian, R_E prime vertical
    w = WIE
    sL, cL, tL = np.sin(L), np.cos(L), np.tan(L)
    fE, fN, fU = fn
    F1 = [[0, 0], [vE * tL / (REm * cL), 0]]
    F2 = [[0, 1 / RNm], [1 / (REm * cL), 0]]
    F3 = [[2 * w * vN * cL + vN * vE / (REm * cL ** 2), 0], [-2 * w * vE * cL - vE ** 2 / (REm * cL ** 2), 0]]
    F4 = [[vN * tL / REm, vE * tL / REm + 2 * w * sL], [-2 * w * sL - 2 * vE * tL / REm, 0]]
    F5 = [[0, -fU, fN], [fU, 0, -fE]]
    M = np.eye(3)[:2]
    F6 = np.hstack([M @ C1 @ M.T, -M @ C2 @ M.T])
    F7 = [[0, 0], [-w * sL, 0], [w * cL + vE / (REm * cL ** 2), 0]]
    F8 = [[0, -1 / RNm], [1 / REm, 0], [tL / REm, 0]]
    F9 = [[0, vE * tL / REm + w * sL, -w * cL - vE / REm], [-vE * tL / REm - w * sL, 0, -vN / RNm],
          [w * cL + vE / REm, vN / RNm, 0]]
    F10 = np.hstack([-C1, C2])
    P = np.zeros((17, 17))
    P[0:4, 0:4] = np.block([[np.array(F1), np.array(F2)], [np.array(F3), np.array(F4)]])
    P[2:4, 4:7] = F5
    P[2:4, 13:17] = F6
    P[4:7, 0:2] = F7
    P[4:7, 2:4] = F8
    P[4:7, 4:7] = F9
    P[4:7, 7:13] = F10
    np.testing.assert_allclose(F, P, rtol=1e-12, atol=1e-18)
    # G (eq 8), our noise columns: [w_g1 (3), w_a1 (2), w_gk (3), w_ak (2)]
    Gp = np.zeros((17, 10))
    Gp[2:4, 3:5], Gp[2:4, 8:10] = M @ C1 @ M.T, -M @ C2 @ M.T
    Gp[4:7, 0:3], Gp[4:7, 5:8] = -C1, C2
    np.testing.assert_allclose(G, Gp, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(model.q, [1, 1, 1, 9, 9, 4, 4, 4, 16, 16])


# ------------------------------------------------------------------ discretisation
# (sinslab.estimation.kalman.discretize on errstate's models)
def _test_F(seed=0):
    nav = es.NavPoint(LAT0, H0, V0, euler_to_dcm(ATT0), fb_true(3.0), wb_true(3.0))
    m = es.ErrorModel("full", [es.gyro_bias(rrw=1e-7), es.accel_bias(), es.gyro_markov(30.0, 1e-5),
                               es.accel_scale()], gyro_arw=0.01 * np.pi / 180 / 60,
                      accel_vrw=50 * ug)
    return m, nav


def test_vanloan_matches_ornstein_uhlenbeck_closed_form():
    """Scalar Gauss–Markov: Φ = e^{−T/τ}, Q_k = σ²(1 − e^{−2T/τ})."""
    tau, sigma = 7.0, 3.0
    for T in (0.01, 1.0, 20.0):
        Phi, Q = kd([[-1 / tau]], [2 * sigma ** 2 / tau], T, G=[[1.0]])
        assert Phi[0, 0] == pytest.approx(np.exp(-T / tau), rel=1e-13)
        assert Q[0, 0] == pytest.approx(sigma ** 2 * (1 - np.exp(-2 * T / tau)), rel=1e-12)


def test_vanloan_matches_numerical_integral():
    m, nav = _test_F()
    F, G = m.matrices(nav)
    T = 5.0
    Phi, Q = kd(F, m.q, T, G=G)
    np.testing.assert_allclose(Phi, scipy.linalg.expm(F * T), rtol=1e-12, atol=1e-12 * np.abs(Phi).max())
    s = np.linspace(0, T, 2001)
    Qc = (G * m.q) @ G.T
    E = scipy.linalg.expm(F[None] * s[:, None, None])
    from scipy.integrate import simpson
    Qn = simpson(E @ Qc @ np.swapaxes(E, -1, -2), x=s, axis=0)
    np.testing.assert_allclose(Q, Qn, rtol=1e-8, atol=1e-10 * np.abs(Qn).max())


def test_series_minus_expm_is_third_order_and_bounded():
    """‖Φ_series − expm(FT)‖ ≤ ‖FT‖³/6·e^‖FT‖ (Taylor remainder) and both Φ and Q_k errors
    scale as T³ (halving T divides them by ≈ 8)."""
    m, nav = _test_F()
    F, G = m.matrices(nav)
    Ts = np.array([0.01, 0.02, 0.04, 0.08, 0.16, 0.32])
    dP, dQ, QQ = [], [], []
    for T in Ts:
        P1, Q1 = kd(F, m.q, T, G=G, method="vanloan")
        P2, Q2 = kd(F, m.q, T, G=G, method="series")
        a = np.linalg.norm(F * T, 2)
        d = np.linalg.norm(P2 - P1, 2)
        assert d <= a ** 3 / 6 * np.exp(a)
        dP.append(d)
        dQ.append(np.linalg.norm(Q2 - Q1, 2))
        QQ.append(np.linalg.norm(Q1, 2))
    rP = np.array(dP[1:]) / np.array(dP[:-1])
    rQ = np.array(dQ[1:]) / np.array(dQ[:-1])
    assert np.all((rP > 7.0) & (rP < 9.0)), rP
    assert np.all((rQ > 7.0) & (rQ < 9.0)), rQ
    # relative Q_k error grows as T² (≈ 0.17 T² here: 1.7e-5 at 0.01 s, 1.1e-3 at 0.08 s)
    assert np.all(np.array(dQ) / np.array(QQ) < 0.2 * Ts ** 2)


def test_discretize_vectorised_agrees_with_per_epoch():
    m, _ = _test_F()
    t = np.linspace(0, 50, 7)
    navs = es.NavPoint(LAT0 + 1e-4 * t, H0 + t, V0 + t[:, None], euler_to_dcm(ATT0 + 0.01 * t[:, None]),
                       fb_true(t), wb_true(t))
    F, G = m.matrices(navs)
    for method in ("vanloan", "series"):
        P, Q = kd(F, m.q, 0.5, G=G, method=method)
        for k in range(t.size):
            P1, Q1 = kd(F[k], m.q, 0.5, G=G[k], method=method)
            np.testing.assert_allclose(P[k], P1, rtol=1e-13, atol=1e-16)
            np.testing.assert_allclose(Q[k], Q1, rtol=1e-12, atol=1e-20)


# ---------------------------------------------------------------------- layout, errors
def test_layout_names_units_and_order():
    m = es.ErrorModel("horizontal", [es.gyro_bias(), es.gyro_markov(100.0, 1e-6), es.accel_markov(100.0, 1e-4)],
                      order=["phi", "dv", "dp", "eps", "eps_m", "nabla_m"])
    lay = m.layout
    assert lay.n == 16          # paper 003's 16 states
    assert lay.labels[:7] == ("phiE", "phiN", "phiU", "dvE", "dvN", "dL", "dlam")
    assert lay.slice("eps_m") == slice(10, 13)
    H = lay.selector(["dL", "dlam"])
    x = np.arange(16.0)
    assert np.all(H @ x == [5.0, 6.0])
    assert "arcmin" in lay.format(np.ones(16) * 1e-3)
    np.testing.assert_allclose(lay.to_display(np.r_[np.full(3, 1 * arcmin), np.zeros(13)])[:3], 1.0)
    m2 = es.ErrorModel("attvel", [es.installation(), es.gyro_bias(), es.gyro_scale(), es.accel_bias(),
                                  es.accel_scale()])
    assert m2.n == 21           # paper 002's 21 states
    assert m2.layout.names == ("phi", "dv", "lam", "eps", "kg", "nabla", "ka")


def test_bad_inputs_are_clear_errors():
    with pytest.raises(ValueError, match="core"):
        es.ErrorModel("nope")
    with pytest.raises(ValueError, match="axes"):
        es.gyro_bias("xw")
    with pytest.raises(ValueError, match="correlation time"):
        es.gyro_markov(0.0, 1.0)
    with pytest.raises(ValueError, match="order"):
        es.ErrorModel("full", [es.gyro_bias()], order=["phi", "dv"])
    with pytest.raises(ValueError, match="latitude"):
        es.NavPoint.static(np.pi / 2)
    with pytest.raises(ValueError, match="non-finite"):
        es.NavPoint(np.nan, 0.0, np.zeros(3), np.eye(3), np.zeros(3))
    with pytest.raises(ValueError, match="shape"):
        kd(np.eye(3), [1.0, 1.0], 1.0, G=np.eye(2))
    with pytest.raises(ValueError, match=">= 0"):
        kd(np.eye(2), [1.0, -1.0], 1.0, G=np.eye(2))
    with pytest.raises(ValueError, match="method"):
        kd(np.eye(2), [1.0, 1.0], 1.0, G=np.eye(2), method="euler")


# ------------------------------------- with sinslab's own trajectory + mechanization
def _sinslab_flight():
    from sinslab.sim.trajectory import Accelerate, Climb, Start, Turn, WingRock, generate
    segs = [Accelerate(duration=10.0, accel=3.0), Turn(duration=20.0, rate=np.radians(4.0)),
            Climb(duration=12.0, angle=np.radians(8.0)), WingRock(duration=18.0, amplitude=np.radians(25.0),
                                                                  period=6.0)]
    start = Start(lat=np.radians(34.0), lon=np.radians(108.0), h=1000.0, speed=150.0,
                  heading=np.radians(30.0))
    return generate(segs, start, 0.01)


SINSLAB_GROUPS = {
    "phi0 (Maa, Mva)": dict(phi=np.array([2e-3, -1.5e-3, 3e-3])),
    "dv0 (Mav, Mvv, Mpv)": dict(dv=np.array([0.3, -0.2, 0.1])),
    "dp0 (Map, Mvp, Mpp)": dict(dp=np.array([2e-6, -3e-6, 20.0])),
    "eps, nabla (-C eps, C nabla)": dict(eps=np.array([1e-5, -2e-5, 1.5e-5]), nabla=np.array([1e-3, -2e-3, 1.5e-3])),
    "kg, ka (C diag(w) kg, C diag(f) ka)": dict(kg=np.array([300.0, -200.0, 500.0]) * ppm,
                                               ka=np.array([-400.0, 300.0, 200.0]) * ppm),
}


@pytest.fixture(scope="module")
def sinslab_flight():
    pytest.importorskip("sinslab.nav.strapdown")
    return _sinslab_flight()


@pytest.mark.parametrize("core", ["full", "horizontal"])
def test_linear_model_matches_sinslab_navigate_60s(sinslab_flight, core):
    """Same 2 % criterion with sinslab.sim.trajectory.generate (accelerate, turn, climb, wing rock;
    100 Hz) and sinslab.nav.strapdown.navigate; errors are perturbed − unperturbed navigation."""
    from sinslab.core.records import ImuRecord, NavState
    from sinslab.nav.strapdown import navigate
    gen = sinslab_flight
    truth, imu = gen.truth, gen.imu
    hold = core == "horizontal"
    kw = dict(vertical="hold", height=truth.h) if hold else {}
    init = NavState.from_series(truth, 0)
    base = navigate(imu, init, **kw)
    model = es.ErrorModel(core, [es.gyro_bias(), es.accel_bias(), es.gyro_scale(), es.accel_scale()])
    lay = model.layout
    navs = es.NavPoint.from_series(truth, imu)
    Fk = model.F(navs)
    Phi = transition(0.5 * (Fk[1:] + Fk[:-1]), truth.t)
    C_base = euler_to_dcm(base.att[-1])
    for name, g in SINSLAB_GROUPS.items():
        phi, dv, dp = (g.get(k, np.zeros(3)).copy() for k in ("phi", "dv", "dp"))
        if hold:
            dv[2] = dp[2] = 0.0
        C0 = rotvec_to_dcm(-phi) @ euler_to_dcm(init.att)
        from sinslab.core.attitude import dcm_to_euler
        pinit = NavState(init.lat + dp[0], init.lon + dp[1], init.h + dp[2], init.vel + dv, dcm_to_euler(C0), init.t)
        eps, nab, kg, ka = (g.get(k, np.zeros(3)) for k in ("eps", "nabla", "kg", "ka"))
        pimu = ImuRecord(imu.t, imu.dtheta * (1 + kg) + eps * imu.dt, imu.dv * (1 + ka) + nab * imu.dt, imu.dt)
        nav = navigate(pimu, pinit, **kw)
        e_nl = dict(zip(["phiE", "phiN", "phiU", "dvE", "dvN", "dvU", "dL", "dlam", "dh"], np.concatenate([
            misalignment(C_base, euler_to_dcm(nav.att[-1])), nav.vel[-1] - base.vel[-1],
            [nav.lat[-1] - base.lat[-1], nav.lon[-1] - base.lon[-1], nav.h[-1] - base.h[-1]]])))
        x0 = np.zeros(lay.n)
        for lab, v in zip(["phiE", "phiN", "phiU", "dvE", "dvN", "dvU", "dL", "dlam", "dh"], np.r_[phi, dv, dp]):
            if lab in lay.labels:
                x0[lay.index(lab)] = v
        x0[lay.slice("eps")], x0[lay.slice("nabla")] = eps, nab
        x0[lay.slice("kg")], x0[lay.slice("ka")] = kg, ka
        x_lin = Phi @ x0
        for b in ("phi", "dv", "dp"):
            labs = lay.blocks[lay.names.index(b)].labels
            a = np.array([e_nl[l] for l in labs]) - x0[lay.slice(b)]
            lin = x_lin[lay.slice(b)] - x0[lay.slice(b)]
            rel = np.linalg.norm(a - lin) / np.linalg.norm(a)
            print(f"{core:10s} {name:38s} {b:3s} {100 * rel:.3f} %")
            assert rel < 0.02, f"{core} {name}: block {b} differs by {100 * rel:.2f} %"


def test_receiver_clock_block_dynamics():
    """The clock block: bias integrates drift (Φ = [[1, T], [0, 1]] exactly, the two-state
    clock model), inter-system biases are random walks, nothing couples to the INS."""
    from sinslab.estimation.kalman import discretize
    m = es.ErrorModel("full", [es.gyro_bias(), es.receiver_clock(("G", "E"), bias_noise=0.3,
                                                                    drift_noise=0.2, isb_noise=0.01)],
                      gyro_arw=1e-4, accel_vrw=1e-3)
    lay = m.layout
    sl = lay.slice("clk")
    assert lay.labels[sl] == ("clk_bias", "clk_drift", "clk_isb_E")
    nav = es.NavPoint.static(0.6)
    F, G = m.matrices(nav)
    assert F[sl.start, sl.start + 1] == 1.0 and np.count_nonzero(F[sl, :]) == 1
    assert np.count_nonzero(F[:, sl][:sl.start]) == 0
    T = 2.0
    Phi, Q = discretize(F, (G * m.q) @ G.T, T, method="vanloan")
    assert np.allclose(Phi[sl, sl], [[1, T, 0], [0, 1, 0], [0, 0, 1]], atol=1e-12)
    # Q of the two-state clock: [[qb T + qd T³/3, qd T²/2], [qd T²/2, qd T]]
    qb, qd = 0.3 ** 2, 0.2 ** 2
    assert np.allclose(Q[sl, sl][:2, :2], [[qb * T + qd * T ** 3 / 3, qd * T ** 2 / 2],
                                           [qd * T ** 2 / 2, qd * T]], rtol=1e-9)
    from sinslab.fusion.feedback import FeedbackLayout
    fb = FeedbackLayout.from_model(lay)
    assert not set(range(sl.start, sl.stop)) & set(fb.indices(lay.n).tolist())
