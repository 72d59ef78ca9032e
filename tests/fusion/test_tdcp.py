"""Time-differenced carrier phase (sinslab.fusion.tdcp) in the tightly coupled filter on a
simulated car drive (tests/support.py:phase_drive; 1 m code, slips of which half go
unflagged): beside pseudoranges and Doppler the phase changes make the velocity an order
of magnitude better and the position better; every unflagged slip is found at its epoch;
the filter stays consistent (the errors inside 4σ)."""
import math

import numpy as np
import pytest
from support import phase_drive, simulated_slips

from sinslab.core import earth as E
from sinslab.fusion.spec import FilterGrid
from sinslab.fusion.tdcp import TimeDifferencedPhase
from sinslab.fusion.tightly_coupled import RawGnss, tightly_coupled
from sinslab.nav import errstate as es
from sinslab.sim import gnss as SG


def _run(d, tdcp):
    raw = RawGnss(d["rover"], pseudorange_sigma=1.0, doppler_sigma=0.05, mask=math.radians(10.0))
    sensors = [es.gyro_bias(), es.accel_bias(), raw.clock_block()] + ([es.phase_clones()] if tdcp else [])
    model = es.ErrorModel("full", sensors, gyro_arw=d["arw"], accel_vrw=d["vrw"])
    P0 = np.zeros((model.n, model.n))
    P0[:15, :15] = np.diag(d["sigma0"] ** 2)
    aid = ()
    if tdcp:
        aid = (TimeDifferencedPhase(d["rover"], clock_nominal=raw.clock_nominal(float(d["imu"].t0)),
                                    mask=raw.mask),)
    r = tightly_coupled(d["imu"], d["init"], raw, P0, model, grid=FilterGrid(0.1), aiding=aid)
    tru = d["truth"]
    k = np.searchsorted(tru.t, r.t - 1e-9)
    rm, rn = E.radii(tru.lat[0], tru.h[0])
    ep = np.stack([(r.nav[:, 8] - tru.lon[k]) * rn * math.cos(tru.lat[0]), (r.nav[:, 7] - tru.lat[k]) * rm,
                   r.nav[:, 9] - tru.h[k]], -1)
    ev = r.nav[:, 4:7] - tru.vel[k]
    lay = model.layout
    sp, sv = lay.slice("dp"), lay.slice("dv")
    sd = np.stack([r.sigma[:, sp.start + 1] * rn * math.cos(tru.lat[0]), r.sigma[:, sp.start] * rm,
                   r.sigma[:, sp.start + 2]], -1)
    return r, ep, ev, sd, r.sigma[:, sv], aid


@pytest.fixture(scope="module")
def runs():
    d = phase_drive(4, code_sigma=1.0, phase=SG.PhaseErrors(slip_rate=0.005, slip_flagged=0.5), duration=80.0)
    return d, _run(d, False), _run(d, True)


def test_phase_changes_sharpen_velocity_and_position(runs):
    """After 20 s: horizontal velocity RMS with TDCP ≤ 1/5 of pseudorange + Doppler alone,
    horizontal position RMS smaller too."""
    d, (r0, p0, v0, _, _, _), (r1, p1, v1, _, _, _) = runs
    m = r0.t > 20.0
    rms = lambda e: float(np.sqrt(np.mean(np.sum(e[m, :2] ** 2, 1))))  # noqa: E731
    assert rms(v1) <= 0.2 * rms(v0), (rms(v1), rms(v0))
    assert rms(p1) < rms(p0), (rms(p1), rms(p0))


def test_consistent_and_slips_found(runs):
    """With TDCP the position and velocity errors stay inside 4σ after 10 s, no row is
    rejected by the gate, and every slip the receiver did not flag is cut at its epoch by
    the geometry-free, Doppler or prediction test."""
    d, _, (r1, p1, v1, sp, sv, aid) = runs
    m = r1.t > 10.0
    assert np.all(np.abs(p1[m]) < 4 * sp[m]) and np.all(np.abs(v1[m]) < 4 * sv[m])
    log = aid[0].tdcp
    assert sum(log.rejected) == 0 and sum(log.used) > 1500
    t0 = d["rover"].t_epoch
    caught = {(int(np.flatnonzero(np.isclose(t0, t))[0]), s, k) for t, keys in zip(log.t, log.slipped)
              for s, k in keys}
    hidden = simulated_slips(d["sim"], False)
    assert len(hidden) >= 5 and hidden <= caught, sorted(hidden - caught)
