"""Tightly coupled INS/GNSS on simulated raw observations (sinslab.sim.gnss): Monte Carlo
consistency of the filter — the mean over runs of the normalised position error
e² / σ² (NEES, 3 axes) lies inside its chi-square band when the simulated errors are the
ones the filter models (IMU white noise and constant biases drawn from P0, white pseudorange
and Doppler noise by C/N0 and elevation, the two-state receiver clock); and it keeps
navigating with 2 satellites where no single-point fix exists.
"""
import math

import numpy as np
import pytest
from support import assert_doc_quotes

from sinslab.core import attitude as A
from sinslab.core import earth as E
from sinslab.core import units as u
from sinslab.core.records import NavState
from sinslab.estimation.montecarlo import chi2_bounds
from sinslab.fusion.gnss import SatelliteObservations, single_point
from sinslab.fusion.spec import FilterGrid
from sinslab.fusion.tightly_coupled import RawGnss, tc_model, tightly_coupled
from sinslab.sim import gnss as SG
from sinslab.sim import imu as IM
from sinslab.sim import trajectory as tr

ARW, VRW = 0.05 * u.deg / 60, 100 * u.ug       # [rad/√s], [m/s/√s]
SG_B, SA_B = 0.02 * u.deg, 0.02                # bias σ [rad/s], [m/s²]
S_POS, S_VEL, S_ATT = 3.0, 0.2, np.radians([0.3, 0.3, 2.0])
S_CLK = (30.0, 1.0)
ERR = SG.GnssErrors(pseudorange_sigma=1.0, doppler_sigma=0.05, clock_noise=(0.5, 0.5))


@pytest.fixture(scope="module")
def drive():
    segs = [tr.Accelerate(duration=5.0, accel=2.0), tr.Level(duration=20.0), tr.Turn(duration=20.0, rate=9 * u.deg),
            tr.Level(duration=15.0), tr.Turn(duration=10.0, rate=-18 * u.deg), tr.Level(duration=10.0)]
    return tr.generate(segs, tr.Start(lat=math.radians(40.1), lon=math.radians(-105.1), h=1600.0,
                                      heading=math.radians(30)), 0.01)


def _run(g, seed, canyon=(), walker=SG.Walker()):
    rng = np.random.default_rng(seed)
    tru = g.truth
    err = IM.ImuErrors.from_datasheet(
        gyro_bias=[f"{v} deg/s" for v in rng.normal(0, SG_B / u.deg, 3)],
        accel_bias=[f"{v} m/s^2" for v in rng.normal(0, SA_B, 3)],
        gyro_arw=f"{ARW / u.deg} deg/sqrt(s)", accel_vrw=f"{VRW / u.ug} ug/sqrt(Hz)")
    imu = IM.apply(g.imu, err, rng)
    te = np.arange(1.0, tru.t[-1] - 0.5, 1.0)
    k = np.searchsorted(tru.t, te - 1e-9)
    sim = SG.simulate_observations(te, tru.lat[k], tru.lon[k], tru.h[k], tru.vel[k], walker,
                                   SG.GnssErrors(**{**ERR.__dict__, "canyon": canyon}), seed=rng)
    sv = SatelliteObservations(**sim.fields)
    # initial errors drawn from P0
    rm, rn = E.radii(tru.lat[0], tru.h[0])
    dp = rng.normal(0, S_POS, 3)
    phi = rng.normal(0, S_ATT)
    C = A.apply_misalignment(A.euler_to_dcm(tru.att[0]), phi)
    init = NavState(tru.lat[0] + dp[1] / rm, tru.lon[0] + dp[0] / (rn * math.cos(tru.lat[0])), tru.h[0] + dp[2],
                    tru.vel[0] + rng.normal(0, S_VEL, 3), A.dcm_to_euler(C))
    b0, d0 = sim.clock[0]
    # the clock at t = 0 from the first epoch back, plus an error drawn from its σ
    nom = (b0 - d0 * te[0] + rng.normal(0, S_CLK[0]), d0 + rng.normal(0, S_CLK[1]), 0.0, {})
    raw = RawGnss(sv, pseudorange_sigma=1.0, doppler_sigma=0.05, gate=None, nominal=nom, mask=ERR.mask,
                  clock_noise=(0.5, 0.5, 1e-3), clock_sigma0=(S_CLK[0], S_CLK[1], 1.0))
    model = tc_model(ARW, VRW, systems=sv.systems, clock_noise=raw.clock_noise)
    lay = model.layout
    sd = np.r_[S_ATT, np.full(3, S_VEL), S_POS / rm, S_POS / (rn * math.cos(tru.lat[0])), S_POS,
               np.full(3, SG_B), np.full(3, SA_B), raw.clock_sigmas()]
    r = tightly_coupled(imu, init, raw, np.diag(sd ** 2), model, grid=FilterGrid(0.1))
    kt = np.searchsorted(tru.t, r.t - 1e-9)
    e = np.stack([(r.nav[:, 8] - tru.lon[kt]) * rn * math.cos(tru.lat[0]), (r.nav[:, 7] - tru.lat[kt]) * rm,
                  r.nav[:, 9] - tru.h[kt]], -1)
    sp = lay.slice("dp")
    s = np.stack([r.sigma[:, sp.start + 1] * rn * math.cos(tru.lat[0]), r.sigma[:, sp.start] * rm,
                  r.sigma[:, sp.start + 2]], -1)
    return r, e, s, raw, sv


def test_monte_carlo_nees_inside_chi_square_band(drive):
    N = 12
    stats = []
    for seed in range(N):
        r, e, s, raw, _ = _run(drive, 100 + seed)
        j = [int(0.5 * (r.t.size - 1)), r.t.size - 1]
        stats.append(np.sum((e[j] / s[j]) ** 2, axis=1))
    nees = np.mean(stats, 0)                 # at mid-run and at the end
    lo, hi = chi2_bounds(3, N, alpha=0.01)
    assert np.all((nees >= lo) & (nees <= hi)), (nees, lo, hi)
    assert_doc_quotes("docs/raw-gnss.md", "12 Monte Carlo runs of 80 s give a mean position NEES (3 axes) of 2.3 at "
                      "mid-run and 2.9 at the end, inside the 99 % chi-square band 1.49..5.13",
                      [N, 80, 3, *nees, 99, lo, hi])


def test_keeps_navigating_with_two_satellites(drive):
    """20 s with the 2 highest satellites only: no single-point solution exists there,
    the tightly coupled filter still updates on every epoch and stays within 5 σ."""
    r, e, s, raw, sv = _run(drive, 7, canyon=((2, 40.0, 20.0),))
    sp = single_point(sv)
    win = (sv.t_epoch >= 40.0) & (sv.t_epoch < 60.0)
    assert np.all(np.isnan(sp.lat[win]))
    n_used = r.pseudoranges.used_per_epoch()         # the driver's record of every row
    tl = np.array(r.pseudoranges.t)
    assert np.all(n_used[(tl >= 40) & (tl < 60)] == 2)
    m = (r.t >= 40) & (r.t < 60)
    assert np.all(np.abs(e[m]) < 5 * s[m])


def test_real_ephemeris_orbits():
    """Observations simulated on the broadcast orbits of the walk log (GPS, Galileo,
    BeiDou) without noise give the single-point solution the true antenna and clock."""
    from pathlib import Path
    walk = Path(__file__).resolve().parents[3] / "shared" / "data" / "rtklib-walk" / "gnss_1730.ubx"
    if not walk.exists():
        pytest.skip("rtklib-walk not available")
    from sinslab.data.gnss import read_gnss_raw
    g = read_gnss_raw(walk)
    t = np.arange(5.0)
    lat, lon, h = np.full(5, math.radians(40.0967)), np.full(5, math.radians(-105.1471)), np.full(5, 1580.0)
    err = SG.GnssErrors(pseudorange_sigma=0.0, doppler_sigma=0.0, cn0=(35.0, 15.0, 0.0), clock_noise=(0.0, 0.0),
                        isb={"E": 5.0, "C": -3.0})
    sim = SG.simulate_observations(t, lat, lon, h, np.zeros((5, 3)), g.eph, err, seed=1,
                                   t_orbit=float(g.epoch_t[0]))
    sv = SatelliteObservations(**sim.fields)
    assert set(sv.systems) == {"G", "E", "C"} and np.bincount(sv.epoch).min() >= 10
    sp = single_point(sv)
    assert np.max(np.abs(sp.lat - lat)) * 6.4e6 < 1e-3 and np.max(np.abs(sp.h - h)) < 1e-3
    assert np.max(np.abs(sp.clock - sim.clock[:, 0])) < 1e-3
