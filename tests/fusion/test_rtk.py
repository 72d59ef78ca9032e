"""RTK without an INS (sinslab.fusion.gnss_alone.rtk_solve on sinslab.fusion.rtk) on
simulated rover + base observations with known integers (sinslab.sim.gnss): every integer
fixed is the true double-difference ambiguity, the fixed position is millimetres from the
truth, the float and fixed solutions are consistent (NEES over 20 runs inside the χ²
band of 3 × 20 degrees of freedom), slips are found and do not produce wrong fixes; and
on the real static pair (cssrlib-static-rtk): fixed from the first epoch, every epoch
fixed, within 1 cm of the reference coordinates."""
import math
from pathlib import Path

import numpy as np
import pytest

from sinslab.core import earth as E
from sinslab.estimation.montecarlo import chi2_bounds
from sinslab.fusion.gnss import SatelliteObservations
from sinslab.fusion.gnss_alone import rtk_solve
from sinslab.fusion.rtk import RtkBase, RtkOptions
from sinslab.sim import gnss as SG
from support import assert_doc_quotes, simulated_slips, true_double_differences

LAT, LON, H = math.radians(35.3), math.radians(139.5), 50.0
WALKERS = [SG.Walker(), SG.Walker(planes=3, per_plane=8, system="E", raan0=0.4, radius=29_600e3)]
ERR = SG.GnssErrors(pseudorange_sigma=0.3, doppler_sigma=0.05)
OPT = RtkOptions(mask=math.radians(10.0), ar_mask=math.radians(10.0), iono="broadcast")
STATIC = Path(__file__).resolve().parents[3] / "shared" / "data" / "cssrlib-static-rtk"


def simulate(seed, n=60, phase=SG.PhaseErrors(), offset=(3000.0, 4000.0, 20.0), err=ERR, t0=0.0):
    """A static rover and a base ``offset`` (ENU [m]) away: (rover, base, truth ECEF, sim)."""
    t = t0 + np.arange(float(n))
    r0 = E.geodetic_to_ecef(LAT, LON, H)
    rb = r0 + E.enu_to_ecef_matrix(LAT, LON) @ np.asarray(offset)
    sim = SG.simulate_observations(t, np.full(n, LAT), np.full(n, LON), np.full(n, H), np.zeros((n, 3)), WALKERS,
                                   err, seed=seed, phase=phase, base=SG.BaseStation(position=tuple(rb)))
    return (SatelliteObservations(**sim.fields), RtkBase(SatelliteObservations(**sim.base.fields), rb), r0, sim)


def _nees(err, cov):
    return np.einsum("ei,eij,ej->e", err, np.linalg.inv(cov), err)


def test_known_integers_fixed_and_position():
    """Static, 60 epochs, GPS + Galileo on two carriers, base 5 km away: fixed within 3
    epochs and at every epoch after, every fixed double-difference integer the simulator's,
    the fixed position inside the 99.9 % ellipsoid of its covariance at every fixed epoch
    and within 5 mm (3-D) of the truth from the tenth."""
    rov, base, r0, sim = simulate(1)
    sol = rtk_solve(rov, base, OPT, start_position=r0 + 5.0)
    dd = true_double_differences(sim)
    n_checked = 0
    for e, (pairs, ints) in enumerate(sol.fixed_dd):
        for (s, q, k), v in zip(pairs, ints):
            assert v == dd(e, s, q, k), (e, s, q, k)
            n_checked += 1
    assert n_checked > 1000
    ep, _ = sol.time_to_first_fix()
    assert ep <= 3 and sol.fixed[ep - 1:].all()
    # a partial first fix is centimetres off, inside its covariance; then millimetres
    fx = sol.fixed
    assert np.all(_nees(sol.fixed_pos[fx] - r0, sol.fixed_cov[fx]) < 16.3)      # χ²₃ 99.9 %
    assert np.max(np.linalg.norm(sol.fixed_pos[10:] - r0, axis=1)) < 0.005


def test_nees_inside_chi_square_band():
    """20 runs of 20 s (start 10 m off, drawn from its σ): the position NEES of the float
    solution (no integers) and of the fixed solution (fix and hold, integers right)
    averaged over the runs lies in the 99 % χ² band at epochs 5, 12 and 19."""
    N = 20
    at = [5, 12, 19]
    rows = {"off": [], "hold": []}
    for seed in range(N):
        rov, base, r0, sim = simulate(100 + seed, n=20)
        start = r0 + np.random.default_rng(seed).normal(0, 10.0, 3)
        for ar, which in (("off", "float"), ("hold", "fixed")):
            sol = rtk_solve(rov, base, RtkOptions(**{**OPT.__dict__, "ar": ar}), pos_sigma0=10.0,
                            start_position=start)
            pos, cov = getattr(sol, f"{which}_pos"), getattr(sol, f"{which}_cov")
            assert np.all(np.isfinite(pos[at])), (seed, ar, sol.status)
            rows[ar].append(_nees(pos[at] - r0, cov[at]))
    lo, hi = chi2_bounds(3, N, alpha=0.01)
    for ar, v in rows.items():
        nees = np.mean(v, 0)
        assert np.all((nees > lo) & (nees < hi)), (ar, nees, lo, hi)


def test_slips_found_no_wrong_fix():
    """Slips of 1–5 cycles at 1 per 200 s per signal on rover and base, half of them without
    the LLI flag, 120 epochs: every slip the receivers did not flag restarts its ambiguity at
    its epoch (geometry-free, Doppler and prediction tests), every fixed integer is the
    truth, and the solution is fixed at ≥ 90 % of the epochs within 1 cm."""
    rov, base, r0, sim = simulate(7, n=120, phase=SG.PhaseErrors(slip_rate=0.005, slip_flagged=0.5))
    sol = rtk_solve(rov, base, OPT, start_position=r0 + 5.0)
    dd = true_double_differences(sim)
    for e, (pairs, ints) in enumerate(sol.fixed_dd):
        for (s, q, k), v in zip(pairs, ints):
            assert v == dd(e, s, q, k), (e, s, q, k)
    hidden = simulated_slips(sim, False) | simulated_slips(sim.base, False)
    assert len(hidden) > 10
    caught = {(e, s, k) for e, keys in enumerate(sol.restarted) for s, k in keys}
    assert hidden <= caught, sorted(hidden - caught)
    assert sol.fixed.mean() >= 0.9
    assert np.max(np.linalg.norm(sol.fixed_pos[sol.fixed] - r0, axis=1)) < 0.01


@pytest.mark.skipif(not STATIC.exists(), reason="cssrlib-static-rtk not available")
def test_static_pair_gnss_only():
    """The real static pair, GNSS only, static: fixed at the first epoch, all 60 epochs
    fixed (the base's loss-of-lock flags at 12:00:18 restart every ambiguity; they are
    fixed again at once), fixed positions within 1 cm horizontally and 2 cm vertically of
    the reference."""
    from sinslab.data.gnss import read_gnss_raw
    from sinslab.fusion.gnss import prepare
    rov = prepare(read_gnss_raw(STATIC / "SEPT078M1.21O", STATIC / "SEPT078M.21P"))
    bas = prepare(read_gnss_raw(STATIC / "3034078M1.21O", STATIC / "SEPT078M.21P"))
    ref = np.array([-3962108.673, 3381309.574, 3668678.638])
    sol = rtk_solve(rov, RtkBase(bas, np.array([-3959400.631, 3385704.533, 3667523.111])))
    assert sol.time_to_first_fix() == (1, 0.0) and sol.fixed.all()
    assert_doc_quotes("docs/raw-gnss.md", "a partial fix of 17 of the 50 double-difference ambiguities",
                      [sol.n_fixed[0], sol.n_amb[0]])
    enu = sol.enu_errors(ref)
    assert np.max(np.hypot(enu[:, 0], enu[:, 1])) < 0.01 and np.max(np.abs(enu[:, 2])) < 0.02
    assert sol.slips["base_lli"] > 50 and sol.n_slip[18] > 50
    m, tab = sol.summary(), sol.table()
    assert m["rtk_first_fix_epochs"] == 1 and m["rtk_fixed_fraction"] == 1.0 and m["restarts_base_lli"] > 50
    assert np.all(tab["status"] == 2) and np.all(tab["sigma_u_m"] < 0.02) and abs(tab["lat_deg"][0] - 35.339) < 1e-3


def test_bad_pairs_one_line_each():
    """A base from another day, base epochs 60 s apart, a base position 3 km off, a base
    without phase, every rover phase flagged as a slip, no carrier in common: one line
    naming the file and the cause each; the good pair passes without warning."""
    import dataclasses

    from sinslab.core.errors import InputError
    from sinslab.core.gnss import Signals
    from sinslab.fusion.rtk import check_pair
    rov, base, r0, _ = simulate(3, n=130)
    b = RtkBase(base.sv, base.position, "base.obs")
    assert check_pair(rov, b, "rover.obs") == []

    def refused(bb, match, r=rov):
        with pytest.raises(InputError, match=match):
            check_pair(r, bb, "rover.obs")
    sv = base.sv
    refused(RtkBase(dataclasses.replace(sv, t_epoch=sv.t_epoch + 86400.0), base.position, "base.obs"),
            r"^base.obs: its epochs .* do not overlap the rover's")
    keep = np.isin(sv.epoch, [0, 60, 120])
    sparse = dataclasses.replace(sv, t_epoch=sv.t_epoch, epoch=sv.epoch[keep], **{
        k: getattr(sv, k)[keep] for k in ("sat", "system", "pseudorange", "range_rate", "freq", "cn0", "sat_pos",
                                          "sat_vel", "sat_clock", "sat_drift", "usable")}, signals=sv.signals[keep])
    sparse = dataclasses.replace(sparse, t_epoch=sv.t_epoch[[0, 60, 120]],
                                 epoch=np.searchsorted([0, 60, 120], sparse.epoch))
    refused(RtkBase(sparse, base.position, "base.obs"), r"^base.obs: base epochs every 60 s, further apart")
    refused(RtkBase(sv, base.position + np.array([3000.0, 0.0, 0.0]), "base.obs"),
            r"^base.obs: the base position given is 3 km from the base observations' own single-point")
    refused(RtkBase(dataclasses.replace(sv, signals=None), base.position, "base.obs"),
            r"^base.obs: no carrier phase in the observations")
    S = rov.signals
    flagged = dataclasses.replace(rov, signals=Signals(S.code, S.pseudorange, S.phase, S.doppler, S.cn0, S.freq,
                                                       S.lli | 1))
    refused(b, r"^rover.obs: every carrier-phase observation is flagged as a cycle slip", r=flagged)
    Sb = sv.signals
    other = dataclasses.replace(sv, signals=Signals(Sb.code, Sb.pseudorange, Sb.phase, Sb.doppler, Sb.cn0,
                                                    Sb.freq * 0 + 1176.45e6, Sb.lli))
    refused(RtkBase(other, base.position, "base.obs"), r"^base.obs: no carrier in common with the rover \(rover.obs: ")
