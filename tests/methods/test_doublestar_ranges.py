"""Paper 003 beyond the paper: the two measured RDSS paths in the filter
(sinslab.fusion.rdss, sinslab.methods.doublestar_ranges) — H against finite differences of
z, and a small Monte Carlo against the paper's fix-based integration on the same paths.
"""
import math

import numpy as np
import pytest

from sinslab.core import attitude as A
from sinslab.core import units as u
from sinslab.core.earth import radii
from sinslab.core.records import NavState
from sinslab.estimation.montecarlo import chi2_bounds
from sinslab.fusion.measurements import Epoch, NavRow
from sinslab.fusion.rdss import TwoGeoRanges, geo_paths
from sinslab.methods import doublestar as ds
from sinslab.methods.doublestar_ranges import integrate_ranges
from sinslab.sim import imu as IM
from sinslab.sim import trajectory as tr

S1, S2 = math.radians(80.0), math.radians(140.0)      # the paper's satellites
M0, M1, DH = 20.0, 10.0, 50.0


def _model():
    return ds.horizontal_model(0.001 * u.dpsh, 0.1 * u.dph, 3600.0, 100 * u.ug, 1800.0)


def test_H_matches_finite_differences():
    lay = _model().layout
    row = np.r_[A.euler_to_quat(np.array([0.01, 0.02, 0.3])), 200.0, 150.0, 0.0, math.radians(32), math.radians(118), 1000.0]
    paths = geo_paths(row[7], row[8], row[9], S1, S2)[0][None] + [[3.0, -5.0]]
    m = TwoGeoRanges([0.0], paths, S1, S2, 22.0, 50.0)

    def z(x):
        r = row.copy()
        r[7:9] += x[lay.slice("dp")]
        return m.matrices(Epoch(0.0, 0, (NavRow(r, np.zeros(3), np.zeros(3)),), lay, lay.n, 0))[0]

    _, H, R = m.matrices(Epoch(0.0, 0, (NavRow(row, np.zeros(3), np.zeros(3)),), lay, lay.n, 0))
    sp = lay.slice("dp")
    for i in (sp.start, sp.start + 1):
        e = np.zeros(lay.n)
        e[i] = 1e-7
        J = (z(e) - z(-e)) / 2e-7
        assert np.allclose(H[:, i], J, rtol=1e-6, atol=1e-6)
    assert np.count_nonzero(H[:, :sp.start]) == 0 and np.all(np.linalg.eigvalsh(R) > 0)


def test_monte_carlo_against_the_fix_filter():
    """12 runs of 600 s (fixes in 100..400 s every 1 s, 1 s latency, lag-aware): the filter
    on the paths is consistent (mean NEES of the horizontal position at the window end in
    its chi-square band) and ends the window no worse than the paper's filter on the fixes
    solved from the same paths at the same (erroneous) height."""
    g = tr.generate([tr.Level(duration=600.0)], tr.Start(lat=math.radians(32), lon=math.radians(118), h=1000.0,
                                                          speed=300.0, heading=0.0), 0.01)
    truth = g.truth
    model = _model()
    P0 = ds.initial_covariance(model, truth.lat[0], truth.h[0], np.array([100, 100, 200]) * u.arcsec, 1.0,
                               15.0, 0.1 * u.dph, 0.1 * u.dph, 100 * u.ug)
    t = np.arange(100.0, 400.0, 1.0)
    k = np.searchsorted(truth.t, t - 1e-9)
    clean, e = geo_paths(truth.lat[k], truth.lon[k], truth.h[k], S1, S2)
    # ∂paths/∂h along the local vertical
    up = np.stack([np.cos(truth.lat[k]) * np.cos(truth.lon[k]), np.cos(truth.lat[k]) * np.sin(truth.lon[k]),
                   np.sin(truth.lat[k])], -1)
    dr_dh = -np.einsum("jsi,ji->js", e, up)
    g_h = np.stack([2 * dr_dh[:, 0], dr_dh[:, 0] + dr_dh[:, 1]], -1)
    fe = ds.fix_error(truth.lat[k], truth.lon[k], S1, S2, M0, M1, DH)
    end = int(np.argmin(np.abs(truth.t - 400.0)))
    err_r, err_f, sig_r = [], [], []
    rm, rn = radii(truth.lat[0], truth.h[0])
    for seed in range(12):
        rng = np.random.default_rng(seed)
        x0 = rng.standard_normal(16) * np.sqrt(np.diag(P0))
        imu = IM.apply(g.imu, IM.ImuErrors(gyro_bias=x0[7:10], gyro_arw=0.001 * u.dpsh,
                                           gyro_bias_instability=0.1 * u.dph, gyro_corr_time=3600.0,
                                           accel_bias_instability=100 * u.ug, accel_corr_time=1800.0), rng)
        init = NavState(truth.lat[0] + x0[5], truth.lon[0] + x0[6], truth.h[0],
                        truth.vel[0] + np.array([x0[3], x0[4], 0.0]),
                        A.dcm_to_euler(A.apply_misalignment(A.euler_to_dcm(truth.att[0]), x0[:3])), truth.t[0])
        noise = rng.normal(0.0, math.hypot(M0, M1), (t.size, 2))
        dh = rng.normal(0.0, DH, t.size)
        paths = clean + noise
        r = integrate_ranges(imu, init, t, paths + g_h * dh[:, None], model, P0, sat_lon1=S1, sat_lon2=S2,
                             range_sigma=math.hypot(M0, M1), height_sigma=DH, t_arrive=t + 1.0,
                             height=truth.h, kf_dt=1.0)
        sol = np.array([ds.solve_fix(p, truth.h[kk] + d, S1, S2, (truth.lat[kk], truth.lon[kk]))
                        for p, d, kk in zip(paths, dh, k)])
        from sinslab.core.records import Fixes
        fx = Fixes(t, sol[:, 0], sol[:, 1], truth.h[k], np.stack([fe.ns, fe.ew, np.full(t.size, DH)], -1),
                   t_arrive=t + 1.0)
        f = ds.integrate(imu, init, fx, model, P0, height=truth.h, kf_dt=1.0)
        for res, out in ((r, err_r), (f, err_f)):
            j = int(np.argmin(np.abs(res.t - 400.0)))
            out.append([(res.nav[j, 7] - truth.lat[end]) * rm, (res.nav[j, 8] - truth.lon[end]) * rn * math.cos(truth.lat[0])])
        j = int(np.argmin(np.abs(r.t - 400.0)))
        sig_r.append([r.sigma[j, 5] * rm, r.sigma[j, 6] * rn * math.cos(truth.lat[0])])
    rms_r = np.sqrt(np.mean(np.square(err_r), 0))
    rms_f = np.sqrt(np.mean(np.square(err_f), 0))
    nees = float(np.mean(np.sum(np.square(np.array(err_r) / np.array(sig_r)), 1)))
    lo, hi = chi2_bounds(2, len(err_r), alpha=0.01)
    assert lo <= nees <= hi, (nees, lo, hi)
    # same paths, same height errors: no worse than the fix filter beyond Monte Carlo noise
    # (48 runs: 11.5 m against 12.1 m)
    assert np.hypot(*rms_r) <= 1.5 * np.hypot(*rms_f), (rms_r, rms_f)


def test_path_draw_gives_the_newton_fix_of_the_same_paths():
    """plan_paths/PathPlan.draw: the fix it returns is the fix the Newton solver
    (doublestar.solve_fix) finds from the measured paths at the erroneous height, and the
    paths it returns are those of that fix at the true height (both to first order: within 1 cm; the Newton fix lies 2 mm from it for a 200 m error)."""
    from sinslab.core.earth import radii as _radii
    from sinslab.methods.doublestar_ranges import plan_paths

    g = tr.generate([tr.Level(duration=60.0)], tr.Start(lat=math.radians(32), lon=math.radians(118), h=1000.0,
                                                         speed=300.0, heading=0.0), 0.05)
    plan = plan_paths(g.truth, [(10.0, 20.0)], sat_lon1=S1, sat_lon2=S2, m0=M0, m1=M1, dH=DH, latency=1.0)
    assert plan.t.size == 10 and np.allclose(plan.t_arrive - plan.t, 1.0)
    rng = np.random.default_rng(3)
    paths, fixes = plan.draw(rng)
    rng = np.random.default_rng(3)
    e = rng.standard_normal((plan.t.size, 2)) * math.hypot(M0, M1)
    dh = rng.standard_normal(plan.t.size) * DH
    rm, rn = _radii(plan.lat, plan.h)
    for j in range(plan.t.size):
        lat, lon = ds.solve_fix(plan.clean[j] + e[j], plan.h[j] + dh[j], S1, S2, (plan.lat[j], plan.lon[j]))
        assert abs(lat - fixes.lat[j]) * rm[j] < 1e-2 and abs(lon - fixes.lon[j]) * rn[j] < 1e-2
        assert np.allclose(ds.measure_ranges(lat, lon, plan.h[j], S1, S2), paths[j], atol=1e-2, rtol=0)
    # the fix filter is given the paper's σ; the drawn errors are those of the fix
    fe = ds.fix_error(plan.lat, plan.lon, S1, S2, M0, M1, DH, plan.h)
    assert np.array_equal(fixes.sigma[:, 0], fe.ns) and np.array_equal(fixes.sigma[:, 1], fe.ew)
    assert np.allclose(fixes.err[:, 0], (fixes.lat - plan.lat) * rm)
