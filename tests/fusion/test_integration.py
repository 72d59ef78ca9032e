"""Oracles for the INS + fix driver, sinslab.fusion.loosely_coupled (simulated data).

The recorded-data front end (levelling, heading from the fix course, rtklib-drive figures)
is tested in test_integration_real.py; paper 003's use of the same driver in
test_doublestar.py.
"""
import numpy as np
import pytest

from sinslab.fusion import loosely_coupled as LC
from sinslab.fusion import recorded as I
from sinslab.fusion.spec import FilterGrid, FixSpec


def _noisy_fixes(tru, idx, sig, rng):
    """Position fixes (lat, lon [rad], h [m]) at the truth samples ``idx`` with white errors
    of σ ``sig`` (north, east, up [m])."""
    from sinslab.core.earth import radii

    rm, rn = radii(tru.lat[idx], tru.h[idx])
    e = rng.normal(size=(idx.size, 3)) * sig
    return np.stack([tru.lat[idx] + e[:, 0] / rm, tru.lon[idx] + e[:, 1] / (rn * np.cos(tru.lat[idx])),
                     tru.h[idx] + e[:, 2]], -1)


def _lc_scenario(duration=300.0, rate=100.0, seed=1):
    from sinslab.sim import imu as imu_mod
    from sinslab.sim import trajectory as tr
    from sinslab.core import units as u
    from sinslab.core.records import NavState
    segs = [tr.Level(duration=60.0), tr.Turn(duration=60.0, rate=1.5 * u.deg),
            tr.Accelerate(duration=30.0, accel=1.0), tr.Climb(duration=60.0, angle=3 * u.deg),
            tr.Level(duration=90.0)]
    start = tr.Start(lat=32 * u.deg, lon=118 * u.deg, h=1000.0, speed=150.0, heading=0.0)
    gen = tr.generate(segs, start, 1.0 / rate, duration=duration)
    err = imu_mod.ImuErrors.from_datasheet(gyro_bias="0.5 deg/h", gyro_arw="0.05 deg/sqrt(h)",
                                           accel_bias="200 ug", accel_vrw="50 ug/sqrt(Hz)")
    meas = imu_mod.apply(gen.imu, err, seed)
    tru = gen.truth
    idx = np.arange(int(rate), tru.t.size, int(rate))
    sig = np.array([3.0, 3.0, 5.0])
    fix = _noisy_fixes(tru, idx, sig, np.random.default_rng(seed + 1))
    att0 = tru.att_imu[0] if tru.att_imu is not None else tru.att[0]
    init = NavState(tru.lat[0], tru.lon[0], tru.h[0], tru.vel[0] + [0.1, -0.1, 0.05],
                    att0 + np.array([1, 1, 5]) * u.arcmin, tru.t[0])
    P0 = np.diag(np.r_[[(2 * u.arcmin) ** 2] * 2, (10 * u.arcmin) ** 2, [0.2 ** 2] * 3,
                       (5 / 6.4e6) ** 2, (5 / 5.4e6) ** 2, 25.0, [(1 * u.dph) ** 2] * 3,
                       [(500 * u.ug) ** 2] * 3])
    kw = dict(model=LC.lc_model(0.05 * u.dpsh, 50 * u.ugpsHz))
    return meas, init, tru.t[idx], fix, sig, P0, kw, tru


def _horiz_err(res, tru, dt):
    from sinslab.core.earth import radii
    k = np.round((res.t - tru.t[0]) / dt).astype(int)
    rm, rn = radii(tru.lat[k], tru.h[k])
    dn = (res.nav[:, 7] - tru.lat[k]) * rm
    de = (res.nav[:, 8] - tru.lon[k]) * rn * np.cos(tru.lat[k])
    sn = res.sigma[:, 6] * rm
    se = res.sigma[:, 7] * rn * np.cos(tru.lat[k])
    return dn, de, sn, se


@pytest.fixture(scope="module")
def lc_case():
    return _lc_scenario()


def test_loosely_coupled_is_consistent_and_beats_free_inertial(lc_case):
    meas, init, ft, fix, sig, P0, kw, tru = lc_case
    res = LC.loosely_coupled(meas, init, FixSpec(ft, fix, sig), P0, progress=False, **kw)
    dn, de, sn, se = _horiz_err(res, tru, meas.dt)
    late = res.t > res.t[0] + 60
    ratio_n = np.sqrt(np.mean(dn[late] ** 2)) / np.sqrt(np.mean(sn[late] ** 2))
    ratio_e = np.sqrt(np.mean(de[late] ** 2)) / np.sqrt(np.mean(se[late] ** 2))
    assert 0.4 < ratio_n < 2.0 and 0.4 < ratio_e < 2.0, (ratio_n, ratio_e)
    assert 1.0 < np.mean(res.nis) < 6.0
    free = LC.loosely_coupled(meas, init, FixSpec(ft[:0], fix[:0], sig), P0, progress=False, **kw)
    fdn, fde, _, _ = _horiz_err(free, tru, meas.dt)
    assert np.hypot(fdn[-1], fde[-1]) > 10 * np.hypot(dn[-1], de[-1])
    # the error model evaluated exactly on the corrected path gives nearly the same result
    exact = LC.loosely_coupled(meas, init, FixSpec(ft, fix, sig), P0, grid=FilterGrid(model_every=0.1),
                               progress=False, **kw)
    edn, ede, _, _ = _horiz_err(exact, tru, meas.dt)
    assert np.max(np.abs(edn - dn)) < 0.05 and np.max(np.abs(ede - de)) < 0.05


def test_loosely_coupled_lagged_fixes_match_on_time(lc_case):
    """Fixes arriving 1 s late, applied at their validity time with the stored INS state,
    give (nearly) the on-time result; ignoring the lag is worse."""
    meas, init, ft, fix, sig, P0, kw, tru = lc_case
    on = LC.loosely_coupled(meas, init, FixSpec(ft, fix, sig), P0, progress=False, **kw)
    lag = LC.loosely_coupled(meas, init, FixSpec(ft, fix, sig, latency=1.0), P0, progress=False, **kw)
    naive = LC.loosely_coupled(meas, init, FixSpec(ft[:-1] + 1.0, fix[:-1], sig), P0, progress=False, **kw)
    e_on = np.hypot(*_horiz_err(on, tru, meas.dt)[:2])
    e_lag = np.hypot(*_horiz_err(lag, tru, meas.dt)[:2])
    e_naive = np.hypot(*_horiz_err(naive, tru, meas.dt)[:2])
    late = on.t > on.t[0] + 60
    rms = lambda e: np.sqrt(np.mean(e[late] ** 2))
    assert rms(e_lag) < 1.3 * rms(e_on)
    assert rms(e_naive) > 3 * rms(e_on)


def test_loosely_coupled_bad_fixes(lc_case):
    meas, init, ft, fix, sig, P0, kw, _ = lc_case
    with pytest.raises(ValueError, match="outside the filter grid"):
        LC.loosely_coupled(meas, init, FixSpec(ft + 1000.0, fix, sig), P0, progress=False, **kw)
    with pytest.raises(ValueError, match="fix_pos"):
        LC.loosely_coupled(meas, init, FixSpec(ft, fix[:, :2], sig), P0, progress=False, **kw)
    with pytest.raises(ValueError, match="multiple"):
        LC.loosely_coupled(meas, init, FixSpec(ft, fix, sig), P0, grid=FilterGrid(0.015), progress=False, **kw)


def test_feed_forward_estimates_the_free_ins_errors(lc_case):
    """Open loop: the INS runs free (same path as without fixes) and ``x`` estimates its
    errors; free INS minus x is about as good as the closed loop."""
    meas, init, ft, fix, sig, P0, kw, tru = lc_case
    ff = LC.loosely_coupled(meas, init, FixSpec(ft[:60], fix[:60], sig), P0, feedback=False, progress=False, **kw)
    free = LC.loosely_coupled(meas, init, FixSpec(ft[:0], fix[:0], sig), P0, progress=False, **kw)
    assert np.array_equal(ff.nav, free.nav)
    from sinslab.core.earth import radii
    k = np.round((ff.t - tru.t[0]) / meas.dt).astype(int)
    rm, _ = radii(tru.lat[k], tru.h[k])
    dn_free = (ff.nav[:, 7] - tru.lat[k]) * rm
    dn_est = (ff.nav[:, 7] - ff.x[:, 6] - tru.lat[k]) * rm
    i = np.searchsorted(ff.t, ft[59])
    assert abs(dn_est[i]) < 3 * ff.sigma[i, 6] * rm[i] + 1.0
    assert abs(dn_est[i]) < abs(dn_free[i]) or abs(dn_free[i]) < 3.0


def test_lever_arm_and_velocity_fixes(lc_case):
    """Antenna fixes 1 m off the IMU with the lever arm given: as accurate as IMU-point fixes;
    adding velocity fixes keeps it consistent (NIS ~ dof 6)."""
    from sinslab.core import attitude as A
    from sinslab.core.earth import radii
    meas, init, ft, fix, sig, P0, kw, tru = lc_case
    lever = np.array([0.5, 1.0, -0.3])
    k = np.round((ft - tru.t[0]) / meas.dt).astype(int)
    att = tru.att_imu if tru.att_imu is not None else tru.att
    C = A.euler_to_dcm(att[k])
    d = C @ lever
    rm, rn = radii(tru.lat[k], tru.h[k])
    ant = fix + np.stack([d[:, 1] / rm, d[:, 0] / (rn * np.cos(tru.lat[k])), d[:, 2]], -1)
    on = LC.loosely_coupled(meas, init, FixSpec(ft, fix, sig), P0, progress=False, **kw)
    lev = LC.loosely_coupled(meas, init, FixSpec(ft, ant, sig, lever_arm=lever), P0, progress=False, **kw)
    rng = np.random.default_rng(7)
    vfix = tru.vel[k] + rng.normal(0, 0.05, (k.size, 3))
    vel = LC.loosely_coupled(meas, init, FixSpec(ft, fix, sig, vel=vfix, vel_sigma=0.05), P0,
                             progress=False, **kw)
    late = on.t > on.t[0] + 60
    rms = lambda r: np.sqrt(np.mean(np.square(np.hypot(*_horiz_err(r, tru, meas.dt)[:2]))[late]))
    assert rms(lev) < 1.3 * rms(on)
    assert vel.innovation.shape[1] == 6 and 2.0 < np.mean(vel.nis) < 12.0
    assert rms(vel) < 1.3 * rms(on)


def test_scale_factor_states_correct_the_stream_they_are_fed_back_to():
    """With gyro and accelerometer scale-factor states (21-state model) the estimates fed
    back must scale the live INS's increments (ω̂ = (I − K̂g)⁻¹…, the stream's compensation):
    a true 2000 ppm z-gyro scale error, seen in the 60 s turn, is estimated within 3σ and the
    filter stays consistent. A stream that drops the fed-back scale (the estimate zeroed in
    the filter, never applied) keeps re-estimating the same error and the NIS explodes."""
    from sinslab.core import units as u
    from sinslab.sim import imu as imu_mod
    from sinslab.sim import trajectory as tr
    from sinslab.core.records import NavState

    segs = [tr.Level(duration=30.0)] + [tr.Turn(duration=60.0, rate=3 * u.deg),
                                        tr.Turn(duration=60.0, rate=-3 * u.deg)] * 3
    start = tr.Start(lat=32 * u.deg, lon=118 * u.deg, h=100.0, speed=20.0, heading=0.0)
    gen = tr.generate(segs, start, 0.01, duration=390.0)
    err = imu_mod.ImuErrors.from_datasheet(gyro_arw="0.05 deg/sqrt(h)", accel_vrw="50 ug/sqrt(Hz)",
                                           gyro_scale_factor="[0, 0, 2000] ppm")
    meas = imu_mod.apply(gen.imu, err, 3)
    tru = gen.truth
    idx = np.arange(100, tru.t.size, 100)
    sig = np.array([0.5, 0.5, 1.0])
    fix = _noisy_fixes(tru, idx, sig, np.random.default_rng(4))
    att0 = tru.att_imu[0] if tru.att_imu is not None else tru.att[0]
    init = NavState(tru.lat[0], tru.lon[0], tru.h[0], tru.vel[0], att0 + np.array([1, 1, 5]) * u.arcmin, tru.t[0])
    P0 = np.diag(np.r_[[(2 * u.arcmin) ** 2] * 2, (10 * u.arcmin) ** 2, [0.1 ** 2] * 3,
                       (1 / 6.4e6) ** 2, (1 / 5.4e6) ** 2, 1.0, [(1 * u.dph) ** 2] * 3,
                       [(100 * u.ug) ** 2] * 3, [3e-3 ** 2] * 6])
    model = LC.lc_model(0.05 * u.dpsh, 50 * u.ugpsHz, scale_factors=True)
    res = LC.loosely_coupled(meas, init, FixSpec(tru.t[idx], fix, sig), P0, model, progress=False)
    kgz, s_kgz = res.scale[-1, 2], res.sigma[-1, model.layout.slice("kg")][2]
    assert abs(kgz - 2000e-6) < 3 * s_kgz and s_kgz < 700e-6, (kgz, s_kgz)
    assert 1.0 < np.mean(res.nis) < 6.0, np.mean(res.nis)
