"""Error-behaviour oracles of the mechanization.

The nonlinear navigation of ideal static IMU data with an injected sensor error must show
the textbook error dynamics: the Schuler oscillation of an accelerometer bias and the
24 h / Foucault-modulated response to a gyro drift (linear ENU φ-angle static model).
"""
import numpy as np
import pytest
from scipy.linalg import expm
from scipy.optimize import curve_fit

from sinslab.core import attitude, earth
from sinslab.core.records import ImuRecord, NavState
from sinslab.nav.strapdown import navigate
from support import static_imu

DPH = np.radians(1.0) / 3600.0
G0 = 9.80665


def nav_errors(nav, lat, lon, att):
    """Columns φE φN φU δvE δvN δL δλ of a static navigation against its truth."""
    C = attitude.euler_to_dcm(att)
    phi = attitude.misalignment(np.broadcast_to(C, (len(nav), 3, 3)), attitude.euler_to_dcm(nav.att))
    return np.column_stack([phi, nav.vel[:, 0], nav.vel[:, 1], nav.lat - lat, nav.lon - lon])


def static_error_model(lat, h=0.0):
    """Continuous F of the static ENU φ-angle error model, x = [φE φN φU δvE δvN δL δλ]
    augmented with constant ε^n (3) and ∇^n (2): 12 states (textbook, e.g. Qin Yongyuan,
    *Inertial Navigation*, ch. 7; Titterton & Weston §12.3 in ENU form):

        φ̇  = φ × ω_ie + [−δvN/RM, δvE/RN − ω sinL δL, δvE tanL/RN + ω cosL δL] − ε
        δv̇E = −g φN + 2ω sinL δvN + ∇E,    δv̇N = g φE − 2ω sinL δvE + ∇N
        δL̇ = δvN/RM,   δλ̇ = δvE/(RN cos L)
    """
    W, sL, cL = earth.WIE, np.sin(lat), np.cos(lat)
    rm, rn = (float(x) for x in earth.radii(lat, h))
    g = float(earth.gravity(lat, h))
    F = np.zeros((12, 12))
    # φ × ω_ie, ω_ie = [0, W cL, W sL]
    F[0, 1], F[0, 2] = W * sL, -W * cL
    F[1, 0] = -W * sL
    F[2, 0] = W * cL
    F[0, 4] = -1 / rm
    F[1, 3], F[1, 5] = 1 / rn, -W * sL
    F[2, 3], F[2, 5] = np.tan(lat) / rn, W * cL
    F[0:3, 7:10] = -np.eye(3)
    F[3, 1], F[3, 4], F[3, 10] = -g, 2 * W * sL, 1.0
    F[4, 0], F[4, 3], F[4, 11] = g, -2 * W * sL, 1.0
    F[5, 4] = 1 / rm
    F[6, 3] = 1 / (rn * cL)
    return F


def propagate(F, x0, dt, n):
    Phi = expm(F * dt)
    out = np.empty((n + 1, x0.size))
    out[0] = x0
    for k in range(n):
        out[k + 1] = Phi @ out[k]
    return out


def _fit_oscillation(t, y, w0):
    """Fit A sin(ωt) + B cos(ωt) + quadratic trend; returns (ω, amplitude)."""
    model = lambda t, w, a, b, c0, c1, c2: (a * np.sin(w * t) + b * np.cos(w * t)
                                            + c0 + c1 * t + c2 * t * t)
    s = np.abs(y).max()
    p, _ = curve_fit(model, t, y / s, p0=[w0 * 1.02, 1.0, 0.0, 0.0, 0.0, 0.0], maxfev=20000)
    return abs(p[0]), s * p[1], s * p[2]


@pytest.mark.parametrize("lat_deg,axis", [(0.0, "north"), (34.246, "north"), (45.0, "east"),
                                          (-60.0, "east")])
def test_accel_bias_schuler_oscillation(lat_deg, axis):
    """Constant accel bias b (north or east), vertical held: the horizontal velocity error
    oscillates at 2π sqrt(R/g) with amplitude b/ω_s. The Foucault rotation of the error
    vector (ω_ie sin L) is removed before fitting, z = (δvE + i δvN)·exp(i ω_ie sin L t)."""
    lat = np.radians(lat_deg)
    att = np.radians([2.0, -1.0, 57.0])
    b = 1e-4 * G0
    dt, dur = 0.1, 3.0 * float(earth.schuler_period(lat))
    n = int(dur / dt) // 2 * 2
    b_n = np.array([0.0, b, 0.0]) if axis == "north" else np.array([b, 0.0, 0.0])
    C = attitude.euler_to_dcm(att)
    imu = static_imu(lat, att, dt, n, accel_err=C.T @ b_n)
    nav = navigate(imu, NavState(lat, 0.3, 0.0, np.zeros(3), att), nsub=2, vertical="hold",
                   height=0.0, out_every=50, progress=False)
    z = (nav.vel[:, 0] + 1j * nav.vel[:, 1]) * np.exp(1j * earth.foucault_frequency(lat) * nav.t)
    y = z.imag if axis == "north" else z.real
    ws = float(earth.schuler_frequency(lat))
    w, a_sin, a_cos = _fit_oscillation(nav.t, y, ws)
    period = 2 * np.pi / w
    amp = np.hypot(a_sin, a_cos)
    print(f"\n{lat_deg} {axis}: period {period / float(earth.schuler_period(lat)) - 1:+.2e}, "
          f"amplitude {amp / (b / ws) - 1:+.2e}, phase {np.degrees(np.arctan2(a_cos, a_sin)):.2f} deg")
    assert period == pytest.approx(float(earth.schuler_period(lat)), rel=0.005)
    assert amp == pytest.approx(b / ws, rel=0.02)
    # and the oscillation is (b/ω_s) sin(ω_s t): in phase with the sine, sign of the bias
    assert a_sin > 0 and abs(a_cos) < 0.05 * amp


@pytest.mark.parametrize("lat_deg,att_deg", [(34.246, (1.0, -2.0, 30.0)), (-50.0, (0.0, 3.0, -120.0))])
def test_gyro_drift_matches_linear_static_model_24h(lat_deg, att_deg):
    """Constant gyro drift at rest, vertical held: the nonlinear navigation follows the
    linear static error model (24 h, Schuler, Foucault modulation) within 2 % of each
    channel's peak error over 24 h."""
    lat = np.radians(lat_deg)
    att = np.radians(att_deg)
    eps_b = np.array([0.01, -0.02, 0.015]) * DPH
    dt, step = 0.1, 10.0
    n = int(24 * 3600 / dt)
    imu = static_imu(lat, att, dt, n, gyro_err=eps_b)
    nav = navigate(imu, NavState(lat, 0.0, 0.0, np.zeros(3), att), nsub=2, vertical="hold",
                   height=0.0, out_every=int(round(step / (2 * dt))), progress=False)
    err = nav_errors(nav, lat, 0.0, att)
    x0 = np.zeros(12)
    x0[7:10] = attitude.euler_to_dcm(att) @ eps_b
    lin = propagate(static_error_model(lat), x0, step, len(nav) - 1)[:, :7]
    assert np.allclose(nav.t, np.arange(len(nav)) * step)
    names = ["phiE", "phiN", "phiU", "dvE", "dvN", "dL", "dlon"]
    for j, name in enumerate(names):
        peak = np.abs(lin[:, j]).max()
        dev = np.abs(err[:, j] - lin[:, j]).max()
        print(f"{name}: peak {peak:.3e} dev/peak {dev / peak:.2e}")
        assert dev < 0.02 * peak, (name, dev / peak)
    # the response really contains the 24 h and Schuler terms (not just a ramp)
    dvN = err[:, 4]
    spec = np.abs(np.fft.rfft(dvN - dvN.mean()))
    f = np.fft.rfftfreq(dvN.size, step)
    f_s = 1 / float(earth.schuler_period(lat))
    near = lambda f0: spec[np.argmin(np.abs(f - f0))]
    assert near(f_s) > 5 * np.median(spec)


def test_row_errors_of_stacked_runs_are_each_runs_nav_errors():
    """Three solutions stacked along the rows against the truth once: every error of every
    run is, byte for byte, what nav_errors gives for that run alone; rows that are not
    whole runs are refused. nav_errors_many (one matching, one truth conversion) gives each
    solution its nav_errors bytes, also when one solution has other epochs."""
    import pytest

    from sinslab.core.records import NavSeries
    from sinslab.nav import compare

    rng = np.random.default_rng(4)
    M = 7
    t = np.arange(M) * 1.0
    att = rng.normal(size=(M, 3)) * [0.1, 0.1, 2.0]
    truth = NavSeries(t, 0.6 + 1e-4 * rng.normal(size=M), 2.0 + 1e-4 * rng.normal(size=M),
                      100 + rng.normal(size=M), rng.normal(size=(M, 3)), att)
    runs = [NavSeries(t, truth.lat + 1e-6 * rng.normal(size=M), truth.lon + 1e-6 * rng.normal(size=M),
                      truth.h + rng.normal(size=M), truth.vel + 0.1 * rng.normal(size=(M, 3)),
                      att + 1e-3 * rng.normal(size=(M, 3))) for _ in range(3)]
    cat = lambda f: np.concatenate([getattr(r, f) for r in runs])  # noqa: E731
    stacked = NavSeries(np.tile(t, 3), cat("lat"), cat("lon"), cat("h"), cat("vel"), cat("att"))
    e = compare.row_errors(stacked, truth)
    for k, r in enumerate(runs):
        one = compare.nav_errors(r, truth)
        for name in ("vE", "vN", "vU", "phiE", "phiN", "phiU", "pitch", "roll", "yaw", "north", "east"):
            assert np.array_equal(e[name][k * M:(k + 1) * M], one[name]), name
    with pytest.raises(ValueError, match="whole runs"):
        compare.row_errors(stacked, truth.at(slice(0, 5)))
    # several solutions against one denser truth, matched once: each one's nav_errors bytes
    dense = NavSeries(np.arange(2 * M) * 0.5, np.repeat(truth.lat, 2), np.repeat(truth.lon, 2),
                      np.repeat(truth.h, 2), np.repeat(truth.vel, 2, 0), np.repeat(att, 2, 0))
    other = NavSeries(t[:4] + 0.5, runs[0].lat[:4], runs[0].lon[:4], runs[0].h[:4], runs[0].vel[:4],
                      runs[0].att[:4])
    for navs in (runs, runs[:2] + [other]):
        many = compare.nav_errors_many(navs, dense)
        for r, got in zip(navs, many):
            one = compare.nav_errors(r, dense)
            assert all(got[k].tobytes() == one[k].tobytes() for k in one)
