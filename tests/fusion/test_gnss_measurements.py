"""Raw GNSS measurements (sinslab.fusion.gnss): each H against central finite differences
of its own z with respect to the error state (computed − true: C_b^n' = (I − φ×) C_b^n,
δv, δp, the gyro bias in the lever-arm velocity, the receiver clock as the error of the
nominal clock), the gate, the satellite limit and the single-point solution.
"""
import dataclasses
import math

import numpy as np
import pytest

from sinslab.core import attitude as A
from sinslab.core import earth as E
from sinslab.core import gnss as G
from sinslab.fusion import gnss as FG
from sinslab.fusion.measurements import Epoch, NavRow
from sinslab.nav import errstate as es

LAT, LON, H = 0.70, -1.83, 1600.0


def _sky(n=8, seed=4, t0=1000.0, epochs=1):
    """Satellites on a half-sphere of radius 26 600 km around the Earth's centre above
    the receiver, with orbital velocities, for ``epochs`` epochs 1 s apart; observations
    generated from a known receiver and clock, so that z = 0 at the truth."""
    rng = np.random.default_rng(seed)
    r_rx = E.geodetic_to_ecef(LAT, LON, H)
    Cne = E.enu_to_ecef_matrix(LAT, LON)
    el = rng.uniform(0.2, 1.4, n)
    az = rng.uniform(0, 2 * math.pi, n)
    d = Cne @ np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])
    rs = []
    for k in range(n):
        # the point at 26 600 km from the centre along the line of sight
        u = d[:, k]
        b = 2 * r_rx @ u
        c = r_rx @ r_rx - 2.66e7 ** 2
        rs.append(r_rx + u * (-b + math.sqrt(b * b - 4 * c)) / 2)
    rs = np.array(rs)
    vs = np.cross(rng.normal(size=(n, 3)), rs)
    vs *= 3870.0 / np.linalg.norm(vs, axis=1)[:, None]
    systems = np.array(["G", "E", "C", "G", "E", "C", "G", "G"][:n])
    sat = np.array([f"{s}{i + 1:02d}" for i, s in enumerate(systems)])
    M = n * epochs
    return FG.SatelliteObservations(
        0, t0 + np.arange(epochs, dtype=float), np.repeat(np.arange(epochs), n), np.tile(sat, epochs),
        np.tile(systems, epochs), np.full(M, 2.2e7), np.zeros(M), np.full(M, 1575.42e6),
        np.tile(rng.uniform(30, 50, n), epochs), np.tile(rs, (epochs, 1)), np.tile(vs, (epochs, 1)),
        np.tile(rng.normal(scale=3e4, size=n), epochs), np.tile(rng.normal(scale=0.3, size=n), epochs),
        np.zeros(8), np.ones(M, bool))


def _model():
    return es.ErrorModel("full", [es.gyro_bias(), es.accel_bias(), es.receiver_clock(("G", "E", "C"))],
                         gyro_arw=1e-4, accel_vrw=1e-3)


def _perturb(row, omega, lay, x):
    r = row.copy()
    r[:4] = A.dcm_to_quat(A.apply_misalignment(A.quat_to_dcm(row[:4]), x[lay.slice("phi")]))
    r[4:7] += x[lay.slice("dv")]
    r[7:10] += x[lay.slice("dp")]
    return r, omega + x[lay.slice("eps")]


def _fd(cls, sv, lever, t_ep, **kw):
    lay = _model().layout
    n = lay.n
    row = np.r_[A.euler_to_quat(np.array([0.05, -0.1, 0.7])), 1.3, -0.8, 0.1, LAT, LON, H]
    w = np.array([0.2, -0.3, 0.5])
    sc = lay.slice("clk")
    b0, d0, t0 = 1.5e5, -60.0, 990.0

    def z(x):
        r, ww = _perturb(row, w, lay, x)
        xb, xd = x[sc.start], x[sc.start + 1]
        nom = (b0 + xb + xd * (t0 - t_ep), d0 + xd, t0,
               {"E": 20.0 + x[sc.start + 2], "C": -7.0 + x[sc.start + 3]})
        m = cls(sv, lever_arm=lever, clock_nominal=nom, gate=None, mask=0.0, **kw)
        return m.matrices(Epoch(t_ep, 1, (NavRow(r, ww, np.zeros(3)),), lay, n, 0))[0]

    # steps large enough that rounding of z (ranges of 2e7 m) stays below 1e-8 of H
    steps = np.full(n, 1e-4)
    steps[lay.slice("phi")] = 3e-3
    steps[lay.slice("eps")] = 1e-2
    steps[lay.slice("dv")] = 1e-1
    sp = lay.slice("dp")
    steps[sp.start:sp.start + 2] = 1e-7
    steps[sp.start + 2] = 1e-1
    steps[sc] = 1.0
    J = np.empty((z(np.zeros(n)).size, n))
    for i in range(n):
        e = np.zeros(n)
        e[i] = steps[i]
        J[:, i] = (z(e) - z(-e)) / (2 * steps[i])
    m = cls(sv, lever_arm=lever, clock_nominal=(b0, d0, t0, {"E": 20.0, "C": -7.0}), gate=None, mask=0.0, **kw)
    _, Hm, R, *_ = m.matrices(Epoch(t_ep, 1, (NavRow(row, w, np.zeros(3)),), lay, n, 0))
    return Hm, J, lay


@pytest.mark.parametrize("cls", [FG.Pseudoranges, FG.RangeRates])
@pytest.mark.parametrize("lever", [None, (0.3, -0.2, 0.9)])
def test_H_matches_finite_differences(cls, lever):
    """Rows of H per state scale against ∂z/∂x by central differences; the 0.015 s between
    the observation and the filter epoch exercises the extrapolation terms. Left out of H
    by design: the change of the elevation and of the ionosphere's pierce point with
    position (below 1e-5 m per metre)."""
    sv = _sky()
    Hm, J, lay = _fd(cls, sv, lever, 1000.015)
    for b in lay.blocks:
        sl = lay.slice(b.name)
        scale = max(np.abs(Hm[:, sl]).max(), np.abs(J[:, sl]).max(), 1e-300)
        err = np.abs(Hm[:, sl] - J[:, sl]).max()
        assert err <= 2e-5 * scale + 1e-6, (b.name, err, scale)


def test_z_vanishes_at_the_truth():
    """Observations made from the geometry (range with Sagnac, clocks, Klobuchar and
    Saastamoinen) give z = 0 at the true receiver: the model closes on itself."""
    sv = _sky()
    r = E.geodetic_to_ecef(LAT, LON, H)
    rho, u = G.sagnac_range(sv.sat_pos, r)
    el, az = E.elevation_azimuth(sv.sat_pos, LAT, LON, H)
    isb = np.array([{"G": 0.0, "E": 20.0, "C": -7.0}[s] for s in sv.system])
    b = 1.5e5
    P = rho + b + isb - sv.sat_clock + G.klobuchar(sv.t_epoch[0], LAT, LON, az, el) + G.saastamoinen(LAT, H, el)
    v = np.zeros(3)
    rate = np.sum(sv.sat_vel * u, 1) + E.WIE / G.C_LIGHT * (sv.sat_vel[:, 1] * r[0] - sv.sat_vel[:, 0] * r[1])
    rr = rate - 60.0 - sv.sat_drift
    sv2 = dataclasses.replace(sv, pseudorange=P, range_rate=rr)
    lay = _model().layout
    row = np.r_[1.0, 0, 0, 0, v, LAT, LON, H]
    ep = Epoch(1000.0, 1, (NavRow(row, np.zeros(3), np.zeros(3)),), lay, lay.n, 0)
    nom = (b, -60.0, 1000.0, {"E": 20.0, "C": -7.0})
    for cls in (FG.Pseudoranges, FG.RangeRates):
        z = cls(sv2, clock_nominal=nom, mask=0.0).matrices(ep)[0]
        assert np.max(np.abs(z)) < 1e-6, cls
    # the single-point solution recovers the receiver
    sp = FG.single_point(sv2, mask=0.0)
    assert abs(sp.lat[0] - LAT) * 6.4e6 < 1e-3 and abs(sp.h[0] - H) < 1e-3
    assert abs(sp.clock[0] - b) < 1e-3 and np.max(np.abs(sp.vel[0])) < 1e-4 and abs(sp.drift[0] + 60.0) < 1e-4


def test_gate_rejects_one_satellite_and_limit_keeps_highest():
    sv = _sky()
    lay = _model().layout
    n = lay.n
    row = np.r_[1.0, 0, 0, 0, 0, 0, 0, LAT, LON, H]
    ep0 = Epoch(1000.0, 1, (NavRow(row, np.zeros(3), np.zeros(3)),), lay, n, 0)
    m = FG.Pseudoranges(sv, mask=0.0, gate=None)
    z0 = m.matrices(ep0)[0]
    P = sv.pseudorange.copy()
    P[2] += 2000.0                                  # one outlier (the measured range too long)
    sv2 = dataclasses.replace(sv, pseudorange=P + z0)   # z = 0 elsewhere
    # 1 m of position, 100 m of clock bias, 1 m of inter-system biases
    sd = np.r_[np.full(3, 1e-3), np.full(3, 0.1), 1 / 6.4e6, 1 / 4.9e6, 1.0, np.full(6, 1e-4), 100.0, 1.0, 1.0, 1.0]
    prior = (np.zeros(n), np.diag(sd ** 2))
    ep = Epoch(1000.0, 1, (NavRow(row, np.zeros(3), np.zeros(3)),), lay, n, 0, prior)
    m = FG.Pseudoranges(sv2, mask=0.0, gate=5.0)
    rows = m.matrices(ep)                         # every candidate: the driver gates them
    rej, nu, nis, streak = m.row_gate.decide(rows, prior)
    assert rows.z.size == 8 and rej.sum() == 1 and rej[2] and streak == 0
    assert nis[2] > 25.0 and np.all(nis[~rej] < 1e-6)
    el = rows.meta["el"]
    m = FG.Pseudoranges(sv, mask=0.0, gate=None, max_satellites=[(3, 999.0, 5.0)])
    rows = m.matrices(ep0)
    assert set(np.flatnonzero(rows.formed)) == set(np.argsort(-el)[:3])
    assert rows.skipped["over_limit"] == 5


def test_row_gate_opens_after_every_row_was_refused():
    """RowGate: after ``reset`` epochs whose every row was refused, one epoch goes through
    whole (the filter, not all satellites, is then wrong); a lagged update (no prior) is
    not gated."""
    from sinslab.fusion.measurements import RowGate, Rows
    g = RowGate(3.0, reset=2)
    rows = Rows(np.full(2, 10.0), np.eye(2), np.ones(2), np.ones(2, bool), {}, {})
    prior = (np.zeros(2), np.eye(2))                        # ν²/S = 50 > 9 for both rows
    streak, seen = 0, []
    for _ in range(4):
        rej, _, _, streak = g.decide(rows, prior, streak)
        seen.append(bool(rej.all()))
    assert seen == [True, True, False, True]
    rej, nu, nis, s = g.decide(rows, None, 1)
    assert not rej.any() and np.isnan(nu).all() and s == 1
