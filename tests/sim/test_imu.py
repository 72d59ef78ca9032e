"""Oracles for the IMU error model: statistics against theory, exact deterministic terms."""
import math
import tomllib

import numpy as np
import pytest

from sinslab.core import units as u
from sinslab.sim.imu import GM_ALLAN_PEAK, GM_ALLAN_PEAK_TAU, ImuErrors, RecordedNoise, Trend, apply, apply_batch, gm_allan_deviation, gm_sigma_from_allan_floor, noise_increments
from sinslab.core.records import ImuRecord
from sinslab.sim import _rng


def record(n, dt=0.01, dtheta=None, dv=None, t0=0.0):
    t = t0 + dt * np.arange(1, n + 1)
    dth = np.zeros((n, 3)) if dtheta is None else np.broadcast_to(dtheta, (n, 3))
    dvv = np.zeros((n, 3)) if dv is None else np.broadcast_to(dv, (n, 3))
    return ImuRecord(t, dth, dvv, dt)


def allan_dev(y, dt, m):
    """Non-overlapping Allan deviation of a rate sequence y at cluster size m."""
    k = y.shape[0] // m
    means = y[: k * m].reshape(k, m, *y.shape[1:]).mean(axis=1)
    return np.sqrt(0.5 * np.mean(np.diff(means, axis=0) ** 2, axis=0))


# --- the kernel's normal generator -----------------------------------------------------------
def test_kernel_normals_are_standard_normal():
    """xoshiro256++ + ziggurat: moments, equiprobable-bin chi-square, both tails (the tail
    beyond r = 3.654 is the rejection path), no serial correlation."""
    from scipy import stats
    n = 4_000_000
    z = _rng._standard_normals(_rng._kernel_state(np.random.default_rng(5)), n)
    se = 1 / math.sqrt(n)
    assert abs(z.mean()) < 5 * se
    assert abs(z.std() - 1) < 5 * se / math.sqrt(2)
    assert abs(stats.skew(z)) < 5 * math.sqrt(6 / n)
    assert abs(stats.kurtosis(z)) < 5 * math.sqrt(24 / n)
    edges = stats.norm.ppf(np.linspace(0, 1, 401)[1:-1])
    counts = np.bincount(np.searchsorted(edges, z), minlength=400)
    assert stats.chisquare(counts).pvalue > 1e-4
    for x in (2.0, 3.0, 3.6541528853610088, 4.0, 4.5):
        expect = n * 2 * stats.norm.sf(x)
        assert abs((np.abs(z) > x).sum() - expect) < 5 * math.sqrt(expect) + 1, x
    assert abs(np.corrcoef(z[:-1], z[1:])[0, 1]) < 5 * se
    # a state drawn from the same seed gives the same numbers
    again = _rng._standard_normals(_rng._kernel_state(np.random.default_rng(5)), 1000)
    assert again.tobytes() == z[:1000].tobytes()


# --- white noise ------------------------------------------------------------------------------
def test_arw_vrw_sample_sigma_and_allan():
    N = 0.05 * u.dpsh
    V = 50 * u.ugpsHz
    err = ImuErrors.from_datasheet(gyro_arw="0.05 deg/sqrt(h)", accel_vrw="50 ug/sqrt(Hz)")
    assert np.allclose(err.gyro_arw, N) and np.allclose(err.accel_vrw, V)
    dt = 0.01
    dth, dv = noise_increments(400_000, dt, err, 7)
    # σ of Δθ/dt is N/sqrt(dt)
    assert np.allclose(dth.std(0) / dt, N / math.sqrt(dt), rtol=0.01)
    assert np.allclose(dv.std(0) / dt, V / math.sqrt(dt), rtol=0.01)
    assert np.allclose(dth.mean(0), 0, atol=4 * N * math.sqrt(dt) / math.sqrt(400_000))
    # Allan deviation of white rate noise is N/sqrt(τ)
    for m in (10, 100):
        ad = allan_dev(dth / dt, dt, m)
        assert np.allclose(ad, N / math.sqrt(m * dt), rtol=0.04), m


def test_white_noise_scales_with_dt():
    err = ImuErrors(gyro_arw=1e-3)
    for dt in (0.005, 0.1):
        dth, _ = noise_increments(200_000, dt, err, 3)
        assert np.allclose(dth.std(0), 1e-3 * math.sqrt(dt), rtol=0.015)


# --- constant bias, scale factor, misalignment ----------------------------------------------------
def test_constant_bias_exact():
    err = ImuErrors.from_datasheet(gyro_bias="[0.003, -0.002, 0.0005] deg/h",
                                   accel_bias="[2e-5, -4e-5, 1e-4] g")
    dt = 0.02
    out = apply(record(1000, dt), err, 0)
    assert np.allclose(out.dtheta / dt, np.array([0.003, -0.002, 0.0005]) * u.dph, rtol=1e-12, atol=0)
    assert np.allclose(out.dv / dt, np.array([2e-5, -4e-5, 1e-4]) * u.g0, rtol=1e-12, atol=0)


def test_bias_mean_with_noise():
    err = ImuErrors.from_datasheet(gyro_bias="1 deg/h", gyro_arw="0.01 deg/sqrt(h)",
                                   accel_bias="100 ug", accel_vrw="10 ug/sqrt(Hz)")
    dt = 0.01
    n = 200_000
    out = apply(record(n, dt), err, 11)
    se_g = 0.01 * u.dpsh / math.sqrt(n * dt)
    se_a = 10 * u.ugpsHz / math.sqrt(n * dt)
    assert np.all(np.abs(out.dtheta.sum(0) / (n * dt) - u.dph) < 5 * se_g)
    assert np.all(np.abs(out.dv.sum(0) / (n * dt) - 100 * u.ug) < 5 * se_a)


def test_scale_factor_and_misalignment_exact():
    off = [10.0, -5.0, 3.0, 7.0, -2.0, 1.0]            # xy xz yx yz zx zy [arcsec]
    err = ImuErrors.from_datasheet(gyro_scale_factor="[200, -100, 50] ppm",
                                   gyro_misalignment=f"[{', '.join(map(str, off))}] arcsec",
                                   accel_scale_factor="500 ppm",
                                   accel_misalignment=[["0 arcsec", "1 arcmin", "0 arcsec"],
                                                       ["0 arcsec", "0 arcsec", "0 arcsec"],
                                                       ["-2 arcmin", "0 arcsec", "0 arcsec"]])
    M = np.array([[0, off[0], off[1]], [off[2], 0, off[3]], [off[4], off[5], 0]]) * u.arcsec
    Kg = np.eye(3) + np.diag([200e-6, -100e-6, 50e-6]) + M
    Ka = np.eye(3) + 500e-6 * np.eye(3)
    Ka[0, 1] = u.arcmin
    Ka[2, 0] = -2 * u.arcmin
    rng = np.random.default_rng(5)
    n = 500
    dth, dv = rng.normal(size=(n, 3)) * 1e-3, rng.normal(size=(n, 3)) * 0.1
    rec = ImuRecord(0.01 * np.arange(1, n + 1), dth, dv, 0.01)
    out = apply(rec, err, 0)
    assert np.allclose(out.dtheta, dth @ Kg.T, rtol=0, atol=1e-18)
    assert np.allclose(out.dv, dv @ Ka.T, rtol=0, atol=1e-16)
    # the input record is untouched
    assert np.array_equal(rec.dtheta, dth)


def test_error_free_is_identity():
    rng = np.random.default_rng(1)
    rec = ImuRecord(0.01 * np.arange(1, 101), rng.normal(size=(100, 3)), rng.normal(size=(100, 3)))
    out = apply(rec, ImuErrors(), 0)
    assert np.array_equal(out.dtheta, rec.dtheta) and np.array_equal(out.dv, rec.dv)
    assert np.array_equal(out.t, rec.t) and out.dt == rec.dt
    assert ImuErrors().is_deterministic


# --- Gauss-Markov ------------------------------------------------------------------------------
def test_gauss_markov_variance_and_autocorrelation():
    sigma, tau, dt = 0.01 * u.dph, 5.0, 0.05
    err = ImuErrors.from_datasheet(gyro_bias_instability="0.01 deg/h", gyro_corr_time="5 s")
    n = 400_000                                   # 4000 correlation times
    dth, dv = noise_increments(n, dt, err, 21)
    assert not dv.any()
    x = dth / dt                                  # the GM state itself (exact discretisation)
    var = x.var(0)
    # sample variance of a GM sequence: relative s.e. ~ sqrt(2·2τ/T) ≈ 3 %
    assert np.allclose(var, sigma ** 2, rtol=0.1)
    assert np.allclose(var.mean(), sigma ** 2, rtol=0.06)
    lag = int(round(tau / dt))
    xc = x - x.mean(0)
    rho = (xc[lag:] * xc[:-lag]).mean(0) / xc.var(0)
    assert np.allclose(rho, math.exp(-1), atol=0.05)
    assert abs(rho.mean() - math.exp(-1)) < 0.03
    # lag-one coefficient is exactly φ = exp(-dt/τ) in expectation
    rho1 = (xc[1:] * xc[:-1]).mean(0) / xc.var(0)
    assert np.allclose(rho1, math.exp(-dt / tau), atol=2e-3)


def test_gauss_markov_stationary_start():
    """x_0 ~ N(0, σ²): across seeds the first sample has variance σ² (no warm-up)."""
    err = ImuErrors(accel_bias_instability=[1.0, 2.0, 3.0], accel_corr_time=100.0)
    first = np.array([noise_increments(1, 0.01, err, s)[1][0] / 0.01 for s in range(3000)])
    assert np.allclose(first.std(0), [1, 2, 3], rtol=0.06)


def test_gm_allan_curve():
    sigma, tau, dt = 1.0, 2.0, 0.02
    err = ImuErrors(gyro_bias_instability=sigma, gyro_corr_time=tau)
    x = noise_increments(600_000, dt, err, 4)[0] / dt
    for m in (50, 190, 1000):
        ad = allan_dev(x, dt, m).mean()
        assert ad == pytest.approx(float(gm_allan_deviation(m * dt, sigma, tau)), rel=0.08), m
    # the documented peak
    taus = np.linspace(0.5, 5, 2001)
    a = gm_allan_deviation(taus, 1.0, 1.0)
    assert a.max() == pytest.approx(GM_ALLAN_PEAK, rel=1e-6)
    assert taus[a.argmax()] == pytest.approx(GM_ALLAN_PEAK_TAU, abs=3e-3)
    assert gm_sigma_from_allan_floor(1.0, "floor") == pytest.approx(1 / GM_ALLAN_PEAK)
    assert gm_sigma_from_allan_floor(1.0) == pytest.approx(1.0759976, rel=1e-6)
    # small-τ branch continuous with the closed form
    assert float(gm_allan_deviation(0.99e-3, 1, 1)) == pytest.approx(
        float(gm_allan_deviation(1.01e-3, 1, 1)), rel=1e-2)


def test_rate_random_walk_variance_growth():
    K, dt, n = 1e-4, 0.1, 2000
    err = ImuErrors(gyro_rrw=K)
    finals = np.array([noise_increments(n, dt, err, s)[0][-1] / dt for s in range(600)])
    # x_{n-1} = sum of n-1 steps of K sqrt(dt): variance K² (n-1) dt
    assert np.allclose(finals.std(0), K * math.sqrt((n - 1) * dt), rtol=0.1)
    assert np.allclose(noise_increments(1, dt, err, 0)[0], 0)      # x_0 = 0


# --- trend ------------------------------------------------------------------------------------
def test_trend_integrated_exactly():
    tr = Trend.from_dict({"ramp": "0.01 deg/h/h", "exp_amplitude": "0.02 deg/h", "exp_time": "600 s",
                          "sin_amplitude": "[0.005, 0, 0.001] deg/h", "sin_period": "1 h",
                          "sin_phase": "30 deg"}, "gyro")
    assert tr.ramp[0] == pytest.approx(0.01 * u.dph / 3600)
    err = ImuErrors(gyro_trend=tr)
    dt, n = 1.0, 7200
    dth, _ = noise_increments(n, dt, err, 0, t0=100.0)
    # reference: fine quadrature of the trend over each interval (time since record start)
    fine = 200
    s = (np.arange(n * fine) + 0.5) * dt / fine
    ref = tr.evaluate(s).reshape(n, fine, 3).mean(1) * dt
    assert np.allclose(dth, ref, rtol=0, atol=1e-9 * np.abs(ref).max())
    assert np.allclose(np.cumsum(dth, 0)[-1], _trend_integral(tr, n * dt), rtol=1e-9)


def _trend_integral(tr, T):
    w = 2 * np.pi / tr.sin_period
    return (tr.ramp * T ** 2 / 2 + tr.exp_amplitude * (T - tr.exp_time * (1 - np.exp(-T / tr.exp_time)))
            + tr.sin_amplitude / w * (np.cos(tr.sin_phase) - np.cos(w * T + tr.sin_phase)))


def test_accel_trend_units():
    err = ImuErrors.from_datasheet(accel_trend={"ramp": "2 ug/h"})
    assert np.allclose(err.accel_trend.ramp, 2 * u.ug / 3600)
    with pytest.raises(ValueError, match=r"accel_trend\.ramp"):
        ImuErrors.from_datasheet(accel_trend={"ramp": "2 ug"})
    with pytest.raises(ValueError, match=r"accel_trend\.sin_period"):
        ImuErrors.from_datasheet(accel_trend={"sin_amplitude": "2 ug", "sin_period": "2 ug"})
    with pytest.raises(ValueError, match=r"gyro_trend.*'slope'"):
        ImuErrors.from_datasheet(gyro_trend={"slope": "1 deg/h/h"})
    with pytest.raises(ValueError, match="sin_period"):
        ImuErrors.from_datasheet(gyro_trend={"sin_amplitude": "1 deg/h"})


# --- recorded noise ----------------------------------------------------------------------------
def test_recorded_noise_scaled_by_beta_exact():
    rng = np.random.default_rng(9)
    n, dt = 5000, 0.01
    g_rate, a_rate = rng.normal(size=(n, 3)) * 1e-6, rng.normal(size=(n, 3)) * 1e-4
    base = ImuErrors.from_datasheet(gyro_bias="0.01 deg/h", recorded_noise=(g_rate, a_rate))
    rec = record(n, dt)
    out1 = apply(rec, base, 0)
    bias = 0.01 * u.dph * dt
    assert np.allclose(out1.dtheta, bias + g_rate * dt, rtol=0, atol=1e-22)
    assert np.allclose(out1.dv, a_rate * dt, rtol=0, atol=1e-20)
    for beta in (0.8, 0.9, 1.0, 1.1, 1.3, 1.5):
        out = apply(rec, base.with_noise_scale(gyro=beta), 0)
        assert np.allclose(out.dtheta - bias, beta * g_rate * dt, rtol=1e-12, atol=1e-24)
        assert np.array_equal(out.dv, out1.dv)          # β on the gyro only
    # increments instead of rates, with β from the datasheet
    inc = ImuErrors.from_datasheet(recorded_noise=RecordedNoise(g_rate * dt, None, kind="increment"),
                                   gyro_noise_scale=1.1)
    out = apply(rec, inc, 0)
    assert np.allclose(out.dtheta, 1.1 * g_rate * dt, rtol=1e-12)
    assert not out.dv.any()


def test_recorded_noise_length_dt_and_cycle():
    g = np.ones((10, 3))
    with pytest.raises(ValueError, match="10 samples.*20"):
        apply(record(20), ImuErrors(recorded_noise=RecordedNoise(g, None)), 0)
    out = apply(record(25, 0.5), ImuErrors(recorded_noise=RecordedNoise(np.arange(30.).reshape(10, 3), None,
                                                                        kind="increment", cycle=True)), 0)
    assert np.array_equal(out.dtheta[10:20], out.dtheta[:10])
    with pytest.raises(ValueError, match="dt = 0.1"):
        apply(record(5, 0.01), ImuErrors(recorded_noise=RecordedNoise(g, None, dt=0.1)), 0)
    with pytest.raises(ValueError, match="NaN"):
        RecordedNoise(np.full((3, 3), np.nan))
    with pytest.raises(ValueError, match=r"\(K, 3\)"):
        RecordedNoise(np.ones((3, 6)))


def test_recorded_noise_from_file(tmp_path):
    rng = np.random.default_rng(2)
    g, a = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    f = tmp_path / "noise.npz"
    np.savez(f, gyro=g, accel=a)
    err = ImuErrors.from_dict({"recorded_noise": {"source": str(f), "kind": "rate", "dt": "0.1 s"},
                               "gyro_noise_scale": 1.3})
    out = apply(record(50, 0.1), err, 0)
    assert np.allclose(out.dtheta, 1.3 * g * 0.1) and np.allclose(out.dv, a * 0.1)
    d = err.to_dict()
    assert d["recorded_noise"]["source"] == str(f)
    assert ImuErrors.from_dict(d) == err
    csv = tmp_path / "noise.csv"
    np.savetxt(csv, np.hstack([g, a]) / u.dph, delimiter=",")
    err2 = ImuErrors.from_dict({"recorded_noise": {"source": str(csv), "gyro_unit": "deg/h",
                                                   "accel_unit": "deg/h"}})
    assert np.allclose(err2.recorded_noise.gyro, g)
    with pytest.raises(ValueError, match="in memory"):
        ImuErrors.from_dict(ImuErrors(recorded_noise=(g, a)).to_dict())
    with pytest.raises(ValueError, match="does not exist"):
        ImuErrors.from_dict({"recorded_noise": {"source": str(tmp_path / "nope.npz")}})


# --- noise scale β on synthetic noise -------------------------------------------------------------
def test_noise_scale_on_synthetic_terms():
    err = ImuErrors.from_datasheet(gyro_bias="1 deg/h", gyro_arw="0.01 deg/sqrt(h)",
                                   gyro_bias_instability="0.01 deg/h", gyro_corr_time="60 s",
                                   gyro_rrw="0.001 deg/h/sqrt(h)", gyro_trend={"ramp": "1 deg/h/h"})
    a = noise_increments(1000, 0.01, err, 3)[0]
    b = noise_increments(1000, 0.01, err.with_noise_scale(gyro=1.5), 3)[0]
    det = noise_increments(1000, 0.01, err.with_noise_scale(gyro=0.0), 3)[0]
    assert np.allclose(b - det, 1.5 * (a - det), rtol=1e-9, atol=1e-20)
    assert err.with_noise_scale(gyro=0, accel=0).is_deterministic


# --- determinism --------------------------------------------------------------------------------
FULL = dict(gyro_bias="0.01 deg/h", gyro_arw="0.001 deg/sqrt(h)", gyro_bias_instability="0.01 deg/h",
            gyro_corr_time="300 s", gyro_rrw="1e-4 deg/h/sqrt(h)", gyro_scale_factor="200 ppm",
            gyro_misalignment="[1, 2, 3, 4, 5, 6] arcsec",
            gyro_trend={"ramp": "0.001 deg/h/h", "sin_amplitude": "0.002 deg/h", "sin_period": "2 h"},
            accel_bias="100 ug", accel_vrw="10 ug/sqrt(Hz)", accel_bias_instability="20 ug",
            accel_corr_time="[600, 700, 800] s", accel_rrw="1 ug/sqrt(h)", accel_scale_factor="500 ppm",
            accel_misalignment="[-1, -2, -3, -4, -5, -6] arcsec",
            accel_trend={"exp_amplitude": "5 ug", "exp_time": "1 h"}, accel_noise_scale=1.2)


def test_determinism_by_seed():
    err = ImuErrors.from_datasheet(**FULL)
    rng = np.random.default_rng(0)
    n = 70_000                                      # more than one internal chunk
    rec = ImuRecord(0.01 * np.arange(1, n + 1), rng.normal(size=(n, 3)) * 1e-4,
                    rng.normal(size=(n, 3)) * 1e-2)
    a, b = apply(rec, err, 42), apply(rec, err, 42)
    assert a.dtheta.tobytes() == b.dtheta.tobytes() and a.dv.tobytes() == b.dv.tobytes()
    c = apply(rec, err, np.random.default_rng(42))
    assert c.dtheta.tobytes() == a.dtheta.tobytes()
    d = apply(rec, err, 43)
    assert not np.array_equal(d.dtheta, a.dtheta)
    # a Generator is advanced: two draws from one generator differ
    g = np.random.default_rng(1)
    assert not np.array_equal(apply(rec, err, g).dtheta, apply(rec, err, g).dtheta)
    batch = apply_batch(rec, err, [42, 43])
    assert batch[0].dtheta.tobytes() == a.dtheta.tobytes()
    assert batch[1].dv.tobytes() == d.dv.tobytes()


def test_apply_equals_transform_plus_noise_increments():
    err = ImuErrors.from_datasheet(**FULL)
    n, dt = 3000, 0.01
    rng = np.random.default_rng(3)
    rec = ImuRecord(5.0 + dt * np.arange(1, n + 1), rng.normal(size=(n, 3)) * 1e-3,
                    rng.normal(size=(n, 3)) * 0.1, dt)
    out = apply(rec, err, 8)
    nth, ndv = noise_increments(n, dt, err, 8, t0=rec.t0)
    Kg = np.eye(3) + np.diag(err.gyro_scale_factor) + err.gyro_misalignment
    Ka = np.eye(3) + np.diag(err.accel_scale_factor) + err.accel_misalignment
    assert np.allclose(out.dtheta, rec.dtheta @ Kg.T + nth, rtol=1e-12, atol=1e-20)
    assert np.allclose(out.dv, rec.dv @ Ka.T + ndv, rtol=1e-12, atol=1e-18)


# --- datasheet parsing and round trips ---------------------------------------------------------
def test_datasheet_values_in_si():
    e = ImuErrors.from_datasheet(gyro_bias="0.01 deg/h", gyro_arw="0.001 deg/sqrt(h)",
                                 accel_bias="100 ug", accel_vrw="10 ug/sqrt(Hz)",
                                 gyro_scale_factor="200 ppm", accel_scale_factor=5e-4,
                                 gyro_bias_instability="0.01 deg/h", gyro_corr_time="5 min")
    assert np.allclose(e.gyro_bias, 0.01 * math.pi / 180 / 3600)
    assert np.allclose(e.gyro_arw, 0.001 * math.pi / 180 / 60)
    assert np.allclose(e.accel_bias, 100e-6 * 9.80665)
    assert np.allclose(e.accel_vrw, 10e-6 * 9.80665)
    assert np.allclose(e.gyro_scale_factor, 2e-4) and np.allclose(e.accel_scale_factor, 5e-4)
    assert np.allclose(e.gyro_corr_time, 300.0)
    # paper 001 style vectors
    e = ImuErrors.from_datasheet(gyro_bias=["0.003 deg/h", "-0.002 deg/h", "0.0005 deg/h"],
                                 accel_bias="[2e-5, -4e-5, 0] g")
    assert np.allclose(e.gyro_bias / u.dph, [0.003, -0.002, 0.0005])
    assert np.allclose(e.accel_bias / u.g0, [2e-5, -4e-5, 0])


def test_to_dict_from_dict_round_trip():
    e = ImuErrors.from_datasheet(**FULL)
    d = e.to_dict()
    assert all(isinstance(v, (str, float, dict, list)) for v in d.values())
    assert d["gyro_bias"] == "0.01 deg/h"
    assert d["accel_vrw"] == "10 ug/sqrt(Hz)"
    e2 = ImuErrors.from_dict(d)
    for name in ("gyro_bias", "gyro_arw", "accel_corr_time", "gyro_misalignment", "accel_rrw"):
        assert np.allclose(getattr(e2, name), getattr(e, name), rtol=1e-11, atol=0), name
    assert np.allclose(e2.gyro_trend.ramp, e.gyro_trend.ramp, rtol=1e-11)
    assert np.allclose(e2.accel_trend.exp_time, e.accel_trend.exp_time, rtol=1e-11)
    assert e2.to_dict() == d
    # and through TOML text
    text = e.to_toml()
    assert tomllib.loads(text)["imu"]["gyro_arw"] == "0.001 deg/sqrt(h)"
    e3 = ImuErrors.from_toml(text)
    assert e3.to_dict() == d
    e4 = ImuErrors.from_toml(e.to_toml(table="sim.imu"), table="sim.imu")
    assert e4.to_dict() == d
    # the full form lists every key and still round-trips
    full = ImuErrors().to_dict(full=True)
    assert "gyro_rrw" in full and "accel_misalignment" in full
    assert ImuErrors.from_dict(full) == ImuErrors()
    assert ImuErrors.from_toml(ImuErrors().to_toml(table=None), table=None) == ImuErrors()


@pytest.mark.parametrize("key,value,match", [
    ("gyro_bias", 0.01, "gyro_bias.*no unit"),
    ("gyro_bias", "0.01", "gyro_bias.*no unit"),
    ("gyro_bias", "100 ug", "gyro_bias.*expected angular rate"),
    ("gyro_arw", "0.1 deg/h", "gyro_arw.*deg/sqrt\\(h\\)"),
    ("accel_vrw", "10 ug", "accel_vrw.*ug/sqrt\\(Hz\\)"),
    ("accel_bias", "1e-4 gee", "accel_bias.*unknown unit"),
    ("accel_bias", "[1, 2] ug", "accel_bias.*3 values"),
    ("gyro_corr_time", "300", "gyro_corr_time"),
    ("gyro_misalignment", "10 arcsec", "gyro_misalignment.*six"),
    ("gyro_misalignment", "[1, 2, 3, 4, 5, 6] m", "gyro_misalignment"),
    ("gyro_drift", "0.01 deg/h", "'gyro_drift'"),
    ("gyro_noise_scale", "1.1 deg", "gyro_noise_scale"),
])
def test_bad_datasheet_values_name_the_key(key, value, match):
    with pytest.raises(ValueError, match=match):
        ImuErrors.from_datasheet(**{key: value})


def test_bad_values():
    with pytest.raises(ValueError, match="did you mean 'gyro_arw'"):
        ImuErrors.from_dict({"gyro_awr": "0.001 deg/sqrt(h)"})
    with pytest.raises(ValueError, match="gyro_corr_time"):
        ImuErrors.from_datasheet(gyro_bias_instability="0.01 deg/h")
    with pytest.raises(ValueError, match="accel_vrw must be >= 0"):
        ImuErrors(accel_vrw=-1.0)
    with pytest.raises(ValueError, match="gyro_corr_time must be > 0"):
        ImuErrors.from_datasheet(gyro_corr_time="-3 s")
    with pytest.raises(ValueError, match="zero diagonal"):
        ImuErrors(gyro_misalignment=np.eye(3))
    with pytest.raises(ValueError, match="seed"):
        apply(record(3), ImuErrors(gyro_arw=1e-3), 1.5)
    with pytest.raises(ValueError, match="ImuRecord"):
        apply(np.zeros((3, 3)), ImuErrors(), 0)
    with pytest.raises(ValueError, match="n must be"):
        noise_increments(0, 0.01, ImuErrors(), 0)


def test_frozen_and_equality():
    e = ImuErrors.from_datasheet(gyro_bias="0.01 deg/h")
    with pytest.raises(Exception):
        e.gyro_bias = 1.0
    with pytest.raises(ValueError):
        e.gyro_bias[0] = 1.0                       # arrays are read-only
    assert e == ImuErrors.from_datasheet(gyro_bias="0.01 deg/h")
    assert e != ImuErrors.from_datasheet(gyro_bias="0.02 deg/h")


@pytest.mark.parametrize("kw", [
    # bias + white noise on all six channels, no scale factor: the unrolled fast path
    dict(gyro_bias="0.01 deg/h", gyro_arw="0.001 deg/sqrt(h)", accel_bias="50 ug",
         accel_vrw="5 ug/sqrt(Hz)"),
    # white noise on some channels, with scale factor and misalignment: the white-only path
    dict(gyro_arw="[0.001, 0, 0.002] deg/sqrt(h)", gyro_scale_factor="200 ppm",
         accel_misalignment="[10, 0, 0, 5, 0, 0] arcsec", accel_bias="100 ug"),
])
def test_fast_paths_give_the_general_kernels_bytes(kw):
    """apply() has shortcut kernels for bias + white noise; zero recorded noise forces the
    general kernel (it draws no normals), so both must give identical bytes (same seed)."""
    import sinslab.sim.imu as imu_mod
    n = 5000
    t = 0.01 * np.arange(1, n + 1)
    rng = np.random.default_rng(3)
    rec = ImuRecord(t, rng.normal(0, 1e-5, (n, 3)), rng.normal(0, 1e-3, (n, 3)) + [0, 0, 0.098])
    err = ImuErrors.from_datasheet(**kw)
    zero = RecordedNoise(gyro=np.zeros((n, 3)), accel=np.zeros((n, 3)), kind="increment", dt=0.01)
    used = []
    real = imu_mod._kernel

    def spy(*a):
        used.append("general")
        return real(*a)

    fast = apply(rec, err, seed=11)
    import unittest.mock
    with unittest.mock.patch.object(imu_mod, "_kernel", spy):
        general = apply(rec, err.replace(recorded_noise=zero), seed=11)
    assert used == ["general"]                 # the comparison really is fast vs general
    assert fast.dtheta.tobytes() == general.dtheta.tobytes()
    assert fast.dv.tobytes() == general.dv.tobytes()


@pytest.mark.parametrize("kind", ["white", "mixed"])
def test_apply_arrays_shared_gives_each_model_its_bytes(kind):
    """Several error models on one random stream: model j gets exactly what
    ``apply_arrays`` gives it from the same generator state, and the generator ends where
    one such call leaves it. "white": bias + white noise at several β (one draw shared by
    all, the shared kernel); "mixed": a Gauss-Markov model and, last, one without random
    terms among them (applied one after another from the same state)."""
    import unittest.mock

    from sinslab.sim import imu as imu_mod
    from sinslab.sim.imu import apply_arrays, apply_arrays_shared

    base = ImuErrors(gyro_bias=np.full(3, 1e-7), accel_bias=np.full(3, 1e-4), gyro_arw=np.full(3, 1e-6),
                     accel_vrw=np.full(3, 1e-4))
    models = [base.with_noise_scale(gyro=b) for b in (0.8, 1.0, 1.5)] + [base.replace(gyro_bias=np.full(3, -2e-7))]
    if kind == "mixed":
        models.append(base.replace(gyro_bias_instability=np.full(3, 1e-7), gyro_corr_time=np.full(3, 50.0)))
        models.append(base.with_noise_scale(gyro=0.0, accel=0.0))      # no random term (last)
    rng = np.random.default_rng(3)
    dth = rng.standard_normal((1500, 3)) * 1e-4
    dv = rng.standard_normal((1500, 3)) * 1e-2
    dt = 0.01
    t = 2.0 + dt * np.arange(1, 1501)
    used = []
    real = imu_mod._kernel_white_all_shared

    def spy(*a):
        used.append(True)
        return real(*a)

    g = np.random.default_rng(9)
    with unittest.mock.patch.object(imu_mod, "_kernel_white_all_shared", spy):
        out = (np.empty((len(models), 1500, 3)), np.empty((len(models), 1500, 3)))
        got = apply_arrays_shared(dth, dv, t, dt, models, g, out=out)
    assert bool(used) == (kind == "white")
    assert got[0] is out[0] and got[1] is out[1]
    for j, e in enumerate(models):
        ref = apply_arrays(dth, dv, t, dt, e, np.random.default_rng(9))
        assert got[0][j].tobytes() == ref[0].tobytes() and got[1][j].tobytes() == ref[1].tobytes()
    one = np.random.default_rng(9)
    apply_arrays(dth, dv, t, dt, models[0], one)
    assert g.integers(0, 2**63, 4).tolist() == one.integers(0, 2**63, 4).tolist()
    with pytest.raises(ValueError, match="out must be"):
        apply_arrays_shared(dth, dv, t, dt, models, 1, out=(out[0][:, :10], out[1]))
    with pytest.raises(ValueError, match="at least one"):
        apply_arrays_shared(dth, dv, t, dt, [], 1)


def test_trend_skips_axes_without_terms_to_the_bit():
    """Trend.evaluate against the three-axis formula ramp·s + A_e(1 − e^(−s/τ)) +
    A_s sin(2πs/P + φ) evaluated on every axis: equal bytes for random trends with axes
    off (including signed zeros, phases on silent axes, s ≤ 0)."""
    def every_axis(tr, s):
        s = np.asarray(s, dtype=float)[..., None]
        with np.errstate(invalid="ignore", divide="ignore"):
            e = np.where(tr.exp_amplitude != 0, tr.exp_amplitude * -np.expm1(-s / tr.exp_time), 0.0)
            w = np.where(tr.sin_amplitude != 0, 2 * np.pi / tr.sin_period, 0.0)
        return tr.ramp * s + e + tr.sin_amplitude * np.sin(w * s + tr.sin_phase)

    rng = np.random.default_rng(1)
    s = np.r_[-5.0, -0.0, 0.0, rng.uniform(-10, 1e5, 400)]
    for _ in range(200):
        on = rng.random((3, 3)) < 0.4
        tr = Trend(ramp=np.where(on[0], rng.standard_normal(3) * 1e-9, rng.choice([0.0, -0.0], 3)),
                   exp_amplitude=np.where(on[1], rng.standard_normal(3) * 1e-7, 0.0),
                   exp_time=np.where(on[1], rng.uniform(10, 1e4, 3), rng.choice([math.inf, 100.0], 3)),
                   sin_amplitude=np.where(on[2], rng.standard_normal(3) * 1e-7, 0.0),
                   sin_period=np.where(on[2], rng.uniform(10, 1e5, 3), rng.choice([math.inf, 50.0], 3)),
                   sin_phase=rng.choice([0.0, -0.0, 1.0, -2.5], 3))
        assert tr.evaluate(s).tobytes() == every_axis(tr, s).tobytes()
    assert Trend().evaluate(s).shape == (s.size, 3) and not Trend().evaluate(s).any()


@pytest.mark.parametrize("kind", ["white", "full"])
def test_apply_arrays_gives_the_bytes_of_apply(kind):
    """Two entry points of one error model: ``apply_arrays`` on bare arrays equals
    ``apply`` on the record built from them, bit for bit, for the white-noise fast path and
    for the general kernel (scale factor, Gauss-Markov, trend), with a generator continued
    over two chunks."""
    from sinslab.sim.imu import apply_arrays

    e = ImuErrors(gyro_bias=np.full(3, 1e-7), gyro_arw=np.full(3, 1e-6), accel_vrw=np.full(3, 1e-4))
    if kind == "full":
        e = ImuErrors(gyro_bias=np.full(3, 1e-7), gyro_arw=np.full(3, 1e-6), accel_vrw=np.full(3, 1e-4),
                      gyro_scale_factor=np.full(3, 1e-4), gyro_bias_instability=np.full(3, 1e-7),
                      gyro_corr_time=np.full(3, 100.0), gyro_trend=Trend(ramp=np.full(3, 1e-10)))
    rng = np.random.default_rng(3)
    dth = rng.standard_normal((2000, 3)) * 1e-4
    dv = rng.standard_normal((2000, 3)) * 1e-2
    dt = 0.01
    g1, g2 = np.random.default_rng(7), np.random.default_rng(7)
    for a, b in ((0, 1000), (1000, 2000)):
        t = 5.0 + dt * np.arange(a + 1, b + 1)
        ref = apply(ImuRecord(t, dth[a:b], dv[a:b], dt), e, g1)
        got = apply_arrays(dth[a:b], dv[a:b], t, ref.dt, e, g2)
        np.testing.assert_array_equal(got[0], ref.dtheta)
        np.testing.assert_array_equal(got[1], ref.dv)
