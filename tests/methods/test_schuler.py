"""sinslab.methods.schuler: delayed-alignment suppression on one IMU stream — principle (antiphase
of T_s/2-shifted Schuler errors), both modes, real alignments, one pass, bad input."""
import math

import numpy as np
import pytest

from sinslab.nav import compare
from sinslab.core import earth, units as u
from sinslab.sim import indexing
from sinslab.methods import schuler
from sinslab.sim import imu as imu_
from sinslab.methods import oscillation as osc
from sinslab.sim import trajectory as tj
from sinslab.core.records import ImuRecord, NavState

LAT, LON = 45.75 * u.deg, 126.6 * u.deg
DT = 0.1
T1 = 1800.0


def test_half_schuler_delay_and_principle():
    d = schuler.half_schuler_delay(LAT)
    assert d == pytest.approx(0.5 * float(earth.schuler_period(LAT)))
    assert d / 60 == pytest.approx(42.2, abs=0.1)
    # eq 6-8: a Schuler sinusoid and its T/2-delayed copy cancel; a 24 h term stays
    t = np.linspace(0, 86400, 5000)
    ws = 2 * math.pi / (2 * d)
    f = lambda tt: 0.3 * np.sin(ws * tt + 0.2) + 0.1 * np.sin(earth.WIE * tt)  # noqa: E731
    m = 0.5 * (f(t) + f(t - d))
    assert np.max(np.abs(m - 0.1 * math.cos(earth.WIE * d / 2) * np.sin(earth.WIE * (t - d / 2)))) < 1e-12
    assert math.cos(earth.WIE * d / 2) > 0.99


def test_foucault_residual_is_sin_of_a_quarter_schuler_period():
    """The mean of a Foucault-modulated Schuler term ``A cos(ω_f t) sin(ω_s t)`` and its
    T_s/2-delayed copy is ``−A sin(ω_f T_s/4) sin(ω_f (t − T_s/4)) sin(ω_s t)`` (derived
    with sum-to-product): a residual sin(ω_f T_s/4) ≈ 0.066 at 45.75°, a ceiling of ≈ 15×
    on the band's suppression — not the 1 − cos(ω_f T_s/2) ≈ 0.008 once written here.
    ``mean_factors`` gives the same per line."""
    lat = math.radians(45.75)
    d = schuler.half_schuler_delay(lat)
    ws, wf = float(earth.schuler_frequency(lat)), abs(float(earth.foucault_frequency(lat)))
    t = np.linspace(0, 3 * 86400, 20001)
    f = lambda tt: np.cos(wf * tt) * np.sin(ws * tt)  # noqa: E731
    m = 0.5 * (f(t) + f(t - d))
    closed = -math.sin(wf * d / 2) * np.sin(wf * (t - d / 2)) * np.sin(ws * t)
    assert np.max(np.abs(m - closed)) < 1e-12
    fac = schuler.mean_factors(lat)
    assert fac["schuler"] < 1e-12 and fac["earth"] == pytest.approx(math.cos(earth.WIE * d / 2), abs=1e-15)
    assert fac["schuler_minus"] == pytest.approx(math.sin(wf * d / 2), rel=1e-12)
    assert fac["schuler_plus"] == pytest.approx(math.sin(wf * d / 2), rel=1e-12)
    assert 1 / fac["schuler_plus"] == pytest.approx(15.1, abs=0.05)
    # another delay: each line's mean with its delayed copy, numerically, against the factor
    fac = schuler.mean_factors(lat, 1234.0)
    for name, w in (("schuler", ws), ("schuler_plus", ws + wf), ("earth", earth.WIE)):
        mm = 0.5 * (np.cos(w * t) + np.cos(w * (t - 1234.0)))
        assert np.max(np.abs(mm)) == pytest.approx(fac[name], rel=1e-4), name


def test_check_delay():
    assert schuler.check_delay("42.2 min") == pytest.approx(2532.0)
    assert schuler.check_delay(100) == 100.0
    for bad in (0, -5.0, float("nan"), float("inf"), "10 m", "abc", None, True, "-3 min"):
        with pytest.raises(ValueError, match="positive duration"):
            schuler.check_delay(bad)


@pytest.fixture(scope="module")
def swaying_site():
    """A moored, swaying base for t2 + 3 h at 10 Hz with constant biases."""
    d = schuler.half_schuler_delay(LAT)
    total = T1 + d + 3 * 3600.0
    segs = [tj.Ship(total, pitch_amplitude=2 * u.deg, roll_amplitude=4 * u.deg,
                    yaw_amplitude=1 * u.deg, heave_amplitude=0.3)]
    g = tj.generate(segs, tj.Start(lat=LAT, lon=LON, heading=30 * u.deg), DT, out_every=10)
    err = imu_.ImuErrors.from_datasheet(gyro_bias="0.01 deg/h", accel_bias="100 ug")
    return g, imu_.apply(g.imu, err, 0)


@pytest.fixture(scope="module")
def aligned(swaying_site):
    g, m = swaying_site
    opt = schuler.AlignmentOptions(coarse_time=120.0, gyro_arw=5e-4 * u.dpsh, accel_vrw=5 * u.ugpsHz)
    return schuler.delayed_alignment(m, LAT, LON, 0.0, T1, options=opt, out_every=5, progress=False)


def test_aligned_mode_real_alignments(aligned, swaying_site):
    g, m = swaying_site
    r = aligned
    assert r.mode == "aligned"
    assert r.t1 == pytest.approx(T1)
    assert r.delay == pytest.approx(schuler.half_schuler_delay(LAT), abs=1.0)
    assert r.t2 == pytest.approx(r.t1 + r.delay)
    # two separate alignments on prefixes of the same stream, ending at t1 and t2
    assert r.align1.t[-1] == pytest.approx(r.t1) and r.align2.t[-1] == pytest.approx(r.t2)
    assert len(r.align2.t) > len(r.align1.t)
    n1 = len(r.align1.x)
    assert np.allclose(r.align1.z, r.align2.z[:n1 - 1], rtol=0, atol=1e-12)   # same data
    # the filter is causal: solution 2's alignment passes through solution 1's estimate at t1
    assert np.allclose(r.align1.x, r.align2.x[:n1], rtol=0, atol=1e-12)
    # both alignments reach the bias-limited accuracy: φE = −∇N/g, φN = ∇E/g (heading 30°)
    for s in (r.sol1, r.sol2):
        e = compare.nav_errors(s.at(slice(0, 1)), g.truth)
        dE = math.cos(30 * u.deg) * 100 * u.ug + math.sin(30 * u.deg) * 100 * u.ug   # ∇E
        dN = -math.sin(30 * u.deg) * 100 * u.ug + math.cos(30 * u.deg) * 100 * u.ug  # ∇N
        gg = float(earth.gravity(LAT))
        assert e["phiE"][0] == pytest.approx(-dN / gg, abs=0.03 * u.arcmin)
        assert e["phiN"][0] == pytest.approx(dE / gg, abs=0.03 * u.arcmin)
    # solution 2 starts from its own alignment, not from solution 1 at t2
    k = int(np.searchsorted(r.sol1.t, r.t2 - 1e-9))
    assert not np.allclose(r.sol1.att[k], r.init2.att, atol=1e-7)
    assert r.init1.t == pytest.approx(r.t1) and r.init2.t == pytest.approx(r.t2)
    assert np.all(r.init1.vel == 0) and r.init1.lat == LAT


def test_outputs_on_common_grid_and_mean(aligned):
    r = aligned
    s1 = r.sol1_from_t2
    assert len(s1) == len(r.sol2) == len(r.mean)
    assert np.allclose(s1.t, r.mean.t) and np.allclose(r.sol2.t, r.mean.t)
    assert r.mean.t[0] == pytest.approx(r.t2)
    assert np.allclose(r.mean.vel, 0.5 * (s1.vel + r.sol2.vel))
    assert np.allclose(r.mean.lat, 0.5 * (s1.lat + r.sol2.lat))
    # attitude mean: halfway rotation, i.e. within ~1e-12 of the mean of small differences
    d = (s1.att - r.sol2.att)
    assert np.allclose(r.mean.att, r.sol2.att + 0.5 * d, atol=1e-9)


def test_moored_schuler_suppressed_24h_kept(aligned, swaying_site):
    """Static (moored) base: the time-shift argument is exact, the mean cancels the
    Schuler oscillation started by the alignment errors."""
    g, _ = swaying_site
    r = aligned
    e1 = compare.nav_errors(r.sol1_from_t2, g.truth)
    em = compare.nav_errors(r.mean, g.truth)
    for ch in ("vE", "vN", "phiE", "phiN"):
        a1 = osc.fit_components(e1["t"], e1[ch], lat=LAT).schuler
        am = osc.fit_components(em["t"], em[ch], lat=LAT).schuler
        assert a1 / am > 4, ch


def test_one_pass_equals_separate_navigation(aligned, swaying_site):
    """navigate_pair steps both solutions through one sweep: identical to running each
    with strapdown.navigate from its start."""
    from sinslab.nav import strapdown

    _, m = swaying_site
    r = aligned
    e2 = int(round((r.t2 - m.t0) / m.dt))
    sub = ImuRecord(m.t[e2:], m.dtheta[e2:], m.dv[e2:], m.dt)
    ref = strapdown.navigate(sub, r.init2, nsub=2, vertical="hold", height=0.0, out_every=5,
                             progress=False)
    n = min(len(ref), len(r.sol2))
    assert np.allclose(ref.vel[:n], r.sol2.vel[:n], atol=1e-9)
    assert np.allclose(ref.lat[:n], r.sol2.lat[:n], atol=1e-13)


def test_injected_mode_same_errors_at_t1_and_t2(swaying_site):
    g, m = swaying_site
    err = schuler.InitialErrors(att=(0.61 * u.arcmin, 0.58 * u.arcmin, 6.9 * u.arcmin),
                                vel=(0.12, 0.1, 0.0), pos=(2.1 * u.arcsec, 2.1 * u.arcsec, 0.0))
    r = schuler.delayed_injected(m, g.truth, T1, err, out_every=5, progress=False)
    assert r.mode == "injected" and r.align1 is None
    for s, t in ((r.init1, r.t1), (r.init2, r.t2)):
        k = int(np.argmin(np.abs(g.truth.t - t)))
        assert s.lat - g.truth.lat[k] == pytest.approx(2.1 * u.arcsec)
        assert s.vel[0] - g.truth.vel[k, 0] == pytest.approx(0.12)
        assert s.att[2] - g.truth.att[k, 2] == pytest.approx(6.9 * u.arcmin)
    e1 = compare.nav_errors(r.sol1_from_t2, g.truth)
    em = compare.nav_errors(r.mean, g.truth)
    a1 = osc.fit_components(e1["t"], e1["vN"], lat=LAT).schuler
    am = osc.fit_components(em["t"], em["vN"], lat=LAT).schuler
    assert a1 > 0.3 and a1 / am > 5
    # a pair of NavStates works too
    s1 = NavState.from_series(g.truth, int(np.argmin(np.abs(g.truth.t - r.t1))))
    s2 = NavState.from_series(g.truth, int(np.argmin(np.abs(g.truth.t - r.t2))))
    r2 = schuler.delayed_injected(m, (s1, s2), T1, err, out_every=5, progress=False)
    assert np.allclose(r2.mean.vel, r.mean.vel)


def test_turntable_mount_outputs_carrier_attitude():
    d = schuler.half_schuler_delay(LAT)
    total = 600 + d + schuler.half_schuler_delay(LAT) * 2 + 60
    g = tj.generate([tj.Static(total)], tj.Start(lat=LAT, lon=LON), DT, out_every=10,
                    mount=indexing.Swing(axis="pitch", amplitude=5 * u.deg, period=40.0))
    opt = schuler.AlignmentOptions(coarse_time=120.0, gyro_arw=5e-4 * u.dpsh, accel_vrw=5 * u.ugpsHz)
    r = schuler.delayed_alignment(g.imu, LAT, LON, 0.0, 600.0, options=opt, out_every=5,
                                  mount=g.mount, progress=False)
    e = compare.nav_errors(r.mean, g.truth)
    assert r.mean.att_imu is not None
    # error-free IMU: only the alignment filter's residual (arcsec level)
    assert np.max(np.abs(e["phiE"])) < 5 * u.arcsec and np.max(np.abs(e["vN"])) < 0.01
    # carrier attitude is the static carrier's (mount removed), IMU attitude swings
    assert np.ptp(r.mean.att[:, 0]) < 1e-3 and np.ptp(r.mean.att_imu[:, 0]) > 9 * u.deg


def test_bad_input(swaying_site):
    g, m = swaying_site
    opt = schuler.AlignmentOptions(coarse_time=120.0, gyro_arw=5e-4 * u.dpsh, accel_vrw=5 * u.ugpsHz)
    T = len(m) * m.dt
    with pytest.raises(ValueError, match="beyond the end"):
        schuler.delayed_alignment(m, LAT, LON, 0.0, T - 600.0, options=opt, progress=False)
    with pytest.raises(ValueError, match="beyond the end"):
        schuler.delayed_alignment(m, LAT, LON, 0.0, T1, delay="20 h", options=opt, progress=False)
    for bad in (0.0, -60.0, "0 s", "5 m", float("nan")):
        with pytest.raises(ValueError, match="positive duration"):
            schuler.delayed_alignment(m, LAT, LON, 0.0, T1, delay=bad, options=opt, progress=False)
    short = ImuRecord(m.t[:30000], m.dtheta[:30000], m.dv[:30000], m.dt)      # 50 min
    with pytest.raises(ValueError, match="shorter than one Schuler period"):
        schuler.delayed_alignment(short, LAT, LON, 0.0, 600.0, options=opt, progress=False)
    with pytest.raises(ValueError, match="shorter than one Schuler period"):
        schuler.delayed_injected(short, g.truth, 600.0, schuler.InitialErrors(), progress=False)
    with pytest.raises(ValueError, match="no time for fine alignment"):
        schuler.delayed_alignment(m, LAT, LON, 0.0, 100.0, options=opt, progress=False)
    with pytest.raises(ValueError, match="t1"):
        schuler.delayed_alignment(m, LAT, LON, 0.0, float("nan"), options=opt, progress=False)
    with pytest.raises(ValueError, match="beyond the end"):
        schuler.delayed_injected(m, g.truth, T + 10, schuler.InitialErrors(), progress=False)
    with pytest.raises(ValueError, match="no epoch"):
        schuler.delayed_injected(m, g.truth, T1 + 0.3, schuler.InitialErrors(), progress=False)
    with pytest.raises(ValueError, match="InitialErrors"):
        schuler.delayed_injected(m, g.truth, T1, (0, 0, 0), progress=False)
    with pytest.raises(ValueError, match="3 finite"):
        schuler.InitialErrors(att=(1, 2))
    with pytest.raises(ValueError, match="coarse"):
        schuler.AlignmentOptions(coarse="magic")
    with pytest.raises(ValueError, match="coarse_time"):
        schuler.AlignmentOptions(coarse_time=-1.0)
