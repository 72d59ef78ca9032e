"""Shared test inputs (importable from every test module: pytest puts this folder on
``sys.path`` because it holds the root ``conftest.py``)."""
import numpy as np

from sinslab.core import attitude, earth
from sinslab.core.records import ImuRecord


def static_imu(lat, att, dt, n, h=0.0, gyro_err=(0.0, 0.0, 0.0), accel_err=(0.0, 0.0, 0.0)):
    """Exact output of an IMU at rest, ``n`` samples at ``dt`` [s]: Δθ = (C_n^b ω_ie^n + ε) dt,
    Δv = (C_n^b [0, 0, g] + ∇) dt with constant body-frame errors ε [rad/s], ∇ [m/s²]
    (zero by default), attitude ``att`` = [pitch, roll, yaw] [rad], latitude [rad]."""
    C = attitude.euler_to_dcm(att)
    wb = C.T @ earth.wie_n(lat) + np.asarray(gyro_err, float)
    fb = C.T @ np.array([0.0, 0.0, float(earth.gravity(lat, h))]) + np.asarray(accel_err, float)
    t = dt * np.arange(1, n + 1)
    return ImuRecord(t, np.tile(wb * dt, (n, 1)), np.tile(fb * dt, (n, 1)), dt)


def simulated_car_drive(segments):
    """A car drive near 40.1° N, 105.1° W, 1600 m (heading 30°) along ``segments`` at
    100 Hz with a consumer-MEMS IMU (biases 0.1/−0.05/0.15 °/s, 0.05/−0.03/0.1 m/s²,
    ARW 0.0038 °/√s, VRW 70 µg/√Hz, seed 1) and 4 Hz position + velocity fixes (1 cm,
    2 cm/s noise from ``default_rng(2)``).

    Returns ``(imu, fixes, truth, errors, rng)``; ``rng`` is the generator the fix noise
    came from, to draw any further noise of the same drive from.
    """
    import math

    from sinslab.core.records import Fixes
    from sinslab.sim import imu as IM
    from sinslab.sim import trajectory as tr

    g = tr.generate(segments, tr.Start(lat=math.radians(40.1), lon=math.radians(-105.1), h=1600.0,
                                       heading=math.radians(30)), 0.01)
    err = IM.ImuErrors.from_datasheet(gyro_bias=["0.1 deg/s", "-0.05 deg/s", "0.15 deg/s"],
                                      accel_bias=["0.05 m/s^2", "-0.03 m/s^2", "0.1 m/s^2"],
                                      gyro_arw="0.0038 deg/sqrt(s)", accel_vrw="70 ug/sqrt(Hz)")
    imu = IM.apply(g.imu, err, 1)
    tru = g.truth
    rng = np.random.default_rng(2)
    k = np.arange(0, len(tru.t), 25)[1:]
    fx = Fixes(tru.t[k], tru.lat[k] + rng.normal(0, 0.01, k.size) / 6.37e6, tru.lon[k], tru.h[k],
               np.full((k.size, 3), 0.01), tru.vel[k] + rng.normal(0, 0.02, (k.size, 3)),
               np.full((k.size, 3), 0.05), np.ones(k.size, int))
    return imu, fx, tru, err, rng


# ------------------------------------------------------------------ measurement contract
def turning_drive_segments():
    """A 3-min car drive of six turns (−9 and 12 °/s, 6 s each) between straights, after
    10 s at rest and an acceleration to 10 m/s (:func:`simulated_car_drive` segments)."""
    from sinslab.core import units as u
    from sinslab.sim import trajectory as tr
    segs = [tr.Static(duration=10.0), tr.Accelerate(duration=5.0, accel=2.0)]
    for k in range(6):
        segs += [tr.Level(duration=8.0 + 3 * k), tr.Turn(duration=6.0, rate=(12 if k % 2 else -9) * u.deg,
                                                          coordinated=False)]
    return segs + [tr.Level(duration=30.0)]


def nav_with_errors(row, omega_b, f_b, layout, x, sensor_errors=True):
    """What an INS carrying the error state ``x`` (computed − true) shows, given the true
    navigation row ``[q0..q3, vE, vN, vU, lat, lon, h]`` and true body rate / specific force.

    The conventions of :mod:`sinslab.nav.errstate` (:func:`sinslab.nav.strapdown.with_errors`:
    ``C_b^{n'} = exp(−φ×) C_b^n``, ``v' = v + δv``, ``[lat, lon, h]' = [lat, lon, h] + δp``;
    2-state blocks: east, north / δL, δλ);
    the compensated rate ``ω + δω`` with ``δω = x`` for every block feeding the gyro bias
    compensation (bias, Gauss–Markov) and ``δω = diag(ω) x`` for a gyro scale block, the
    specific force likewise for the accelerometer blocks (:attr:`Block.feeds`, per axis);
    ``sensor_errors=False`` leaves rate and specific force exact, a collection of block
    names applies those blocks only (the blocks of this INS in a two-INS layout).

    Returns ``(row', omega', f')``.
    """
    from sinslab.nav.strapdown import with_errors

    r = with_errors(row, *(x[layout.slice(b)] if b in layout.names else None for b in ("phi", "dv", "dp")))
    w = np.array(omega_b, dtype=float, copy=True)
    f = np.array(f_b, dtype=float, copy=True)
    for b in layout.blocks:
        if b.feeds is None or not sensor_errors or (sensor_errors is not True and b.name not in sensor_errors):
            continue
        sensor, kind = b.feeds.split("_")
        out, true = (w, omega_b) if sensor == "gyro" else (f, f_b)
        s = layout.slice(b.name)
        for i, a in enumerate(b.axes):
            ax = "xyz".index(a)
            out[ax] += x[s.start + i] * (true[ax] if kind == "scale" else 1.0)
    return r, w, f


def fd_steps(layout):
    """Finite-difference step per state: 1e-6 for angles and sensor errors, 1e-4 m/s of
    velocity, 1e-8 rad / 1e-3 m of position, 1e-4 for the states a measurement owns
    (lever arms [m], odometer scale [-]; 1e-10 T for a magnetometer's hard iron)."""
    s = np.full(layout.n, 1e-6)
    for b in layout.blocks:
        sl = layout.slice(b.name)
        if b.name == "dv":
            s[sl] = 1e-4
        elif b.name == "dp":
            s[sl.start:sl.start + 2] = 1e-8
            s[sl.start + 2:sl.stop] = 1e-3
        elif b.name != "phi" and b.feeds is None:
            # 1e-4 of the block's display unit for a field (0.1 nT: a field step of 1e-4 T
            # would be twice the Earth's), 1e-4 SI for the others
            s[sl] = 1e-4 * (1e-6 if "uT" in b.units else 1.0)
    return s


def assert_H_is_jacobian(make, layout, rows, omegas, *, t=0.0, k=1, item=0, stream=0, tol=1e-6,
                         sensor_errors=True):
    """The finite-difference contract of a measurement of :mod:`sinslab.fusion.measurements`:
    its ``H`` is the Jacobian of its own nonlinear ``z`` with respect to the error state.

    ``z(x)`` is ``make(x).matrices(epoch)`` on the navigation of stream ``stream`` carrying
    ``x`` (:func:`nav_with_errors`; the other streams exact; for a layout whose sensor
    blocks belong to several streams, as a difference model's, ``sensor_errors`` names the
    blocks of stream ``stream``, or is False to leave them out, since the layout does not
    say which stream a block feeds); ``make(x)`` builds the
    measurement, so a state the measurement owns (a lever arm, an odometer scale) enters
    through its parameters (``make`` ignores ``x`` when there is none). Central differences
    with :func:`fd_steps`; the error of each element, as the change of ``z`` it makes at
    one step of its state, must stay below ``tol`` of the largest change one step of any
    state makes to that row of ``z``.

    Parameters
    ----------
    make : callable ``x (n,) -> measurement``
    layout : sinslab.nav.errstate.StateLayout
    rows : sequence of ndarray (10,)
        True navigation row of each stream.
    omegas : sequence of ndarray (3,)
        True body rate of each stream [rad/s] (the specific force is taken as gravity).

    Returns
    -------
    z, H, R
        The measurement at ``x = 0``.
    """
    from sinslab.fusion.measurements import Epoch, NavRow

    n = layout.n
    steps = fd_steps(layout)
    f_true = np.array([0.3, -0.2, 9.8])

    def matrices(x):
        navs = []
        for i, (r, w) in enumerate(zip(rows, omegas)):
            if i == stream:
                navs.append(NavRow(*nav_with_errors(r, w, f_true, layout, x, sensor_errors)))
            else:
                navs.append(NavRow(np.asarray(r, float), np.asarray(w, float), f_true))
        return make(x).matrices(Epoch(t, k, tuple(navs), layout, n, item))

    z0, H, R = matrices(np.zeros(n))
    J = np.empty_like(H)
    for i in range(n):
        e = np.zeros(n)
        e[i] = steps[i]
        J[:, i] = (matrices(e)[0] - matrices(-e)[0]) / (2 * steps[i])
    effect = np.abs(H) * steps
    scale = effect.max(1, keepdims=True)
    err = np.abs(H - J) * steps / np.where(scale > 0, scale, 1.0)
    i, j = np.unravel_index(np.argmax(err), err.shape)
    assert err[i, j] < tol, (f"H[{i}, {j}] ({layout.labels[j]}) = {H[i, j]:.6g}, finite "
                             f"differences {J[i, j]:.6g} (relative {err[i, j]:.2e})")
    return z0, H, R


def run_experiment(name, sets=(), quick=True):
    """The :class:`sinslab.experiments.base.Result` of one experiment run in this process
    (``--quick`` configuration unless ``quick=False``, ``--set`` lines ``sets``, Monte Carlo
    serial), without a run folder."""
    import tempfile
    from pathlib import Path

    import sinslab.experiments as E
    from sinslab.app.config import resolve
    from sinslab.experiments.base import RunContext

    exp = E.get(name)
    cfg = resolve(exp.config, quick=exp.quick if quick else None, sets=list(sets))
    with tempfile.TemporaryDirectory() as d:
        return exp.run(cfg, RunContext(name=name, out=Path(d), seed=cfg.seed, runs=cfg.runs, quick=quick,
                                       scheduler="sync"))


def assert_doc_quotes(doc, text, got, tol=0.0):
    """A document (path from the repository root) quotes ``text`` and its numbers are ``got``
    within their rounding (half a unit of the last digit shown) plus ``tol`` (absolute, in
    the text's units; a number or one per value): the figures a test measures and the docs
    quote cannot drift apart."""
    import re
    from pathlib import Path

    body = " ".join((Path(__file__).resolve().parents[1] / doc).read_text(encoding="utf-8").split())
    assert " ".join(text.split()) in body, f"{doc} no longer quotes {text!r}: update the test"
    want = []
    for x, exp in re.findall(r"((?:(?<!\w)[−-])?\d+(?:\.\d+)?)(?:e([−-]?\d+))?", text):
        scale = 10.0 ** int(exp.replace("−", "-")) if exp else 1.0
        want.append((float(x.replace("−", "-")) * scale, 0.5 * 10.0 ** -(len(x.split(".")[1]) if "." in x else 0) * scale))
    got = [float(g) for g in got]
    tols = list(tol) if np.ndim(tol) else [float(tol)] * len(got)
    assert len(want) == len(got), (text, got)
    bad = [(w, g) for (w, r), g, e in zip(want, got, tols) if abs(w - g) > r + e + 1e-12]
    assert not bad, f"{doc}: {text!r} against the measurement: {got} (tolerance {tol})"


def recorded_run(imu, fixes, **kw):
    """:func:`sinslab.fusion.recorded.navigate_recorded` of fixes with the options ``kw`` by
    spec field name and the aids named by these keys: ``zupt`` ("auto" | "flags", with
    ``zaru``, ``rest_flags``), ``estimate_lever`` (the antenna lever arm), ``nhc_sigma``
    (with ``estimate_vehicle``: the mount and lever states; ``vehicle_mount``,
    ``nhc_lever_arm``), as the aid plug-ins of
    :mod:`sinslab.fusion.aids` (registry order)."""
    from sinslab.fusion import recorded as R
    from sinslab.fusion.aids.lever import AntennaLever
    from sinslab.fusion.aids.rest import Zupt
    from sinslab.fusion.aids.vehicle import Nhc

    aids = []
    zupt, zaru, flags = kw.pop("zupt", None), kw.pop("zaru", False), kw.pop("rest_flags", None)
    if zupt is not None:
        aids.append(Zupt(rest=zupt, zaru=zaru, flags=flags))
    if kw.pop("estimate_lever", False):
        aids.append(AntennaLever())
    nhc, est = kw.pop("nhc_sigma", None), kw.pop("estimate_vehicle", False)
    mount, lever = kw.pop("vehicle_mount", None), kw.pop("nhc_lever_arm", (0.0, 0.0, 0.0))
    if nhc is not None:
        aids.append(Nhc(sigma=tuple(nhc), estimate=est, vehicle_mount=mount, lever=tuple(lever)))
    return R.navigate_recorded(imu, fixes, R.NavOptions.of(**kw), aids=aids)


def gate_record(r, aid, label=None):
    """``{"applied", "rejected", "rejected_spans"}`` of an aid's innovation gate in a
    recorded run (its report's metrics and the spans it marks)."""
    rep = r.report(aid)
    label = label or aid
    spans = [list(s) for mk in rep.marks if mk.kind == "bar" for s in mk.spans]
    return {"applied": rep.metrics[f"{label}_updates_applied"], "rejected": rep.metrics[f"{label}_updates_rejected"],
            "rejected_spans": spans}


def rest_intervals_of(r):
    """The rest intervals [s] (K, 2) the zupt aid of a recorded run used."""
    t = next(t for t in r.report("zupt").tables if t.name == "rest_intervals").columns
    return np.stack([t["start_s"], t["end_s"]], -1) if len(t["start_s"]) else np.zeros((0, 2))


# ------------------------------------------------------------------ carrier phase, RTK
def phase_drive(seed, *, canyon=(), code_sigma=0.3, phase=None, systems=2, base_offset=(2000.0, 3000.0, 10.0),
                dt=0.01, duration=None):
    """A simulated car drive with raw GNSS at the antenna and a base station
    (:func:`sinslab.experiments.rtk_outages.simulate_drive`: accelerate and turn near
    35.3° N with an automotive MEMS IMU; 1 Hz GPS (+ Galileo with ``systems=2``) on two
    carriers; the initial state drawn from its σ), ``duration`` [s] (default 170 s)."""
    from sinslab.experiments.rtk_outages import simulate_drive
    return simulate_drive(seed, duration=170.0 if duration is None else duration, canyon=canyon,
                          systems="GE"[:systems], code_sigma=code_sigma, phase=phase, base_offset=base_offset, dt=dt)


def true_double_differences(sim):
    """``f(epoch, satellite, reference, slot)``: the true double-difference integer of a
    simulated rover and base (sinslab.sim.gnss with a base station)."""
    f, b = sim.fields, sim.base.fields

    def table(fl, amb):
        return {(int(e), s): a for e, s, a in zip(fl["epoch"], fl["sat"], amb)}
    tr_, tb = table(f, sim.ambiguity), table(b, sim.base.ambiguity)
    return lambda e, s, q, k: int((tr_[e, s][k] - tb[e, s][k]) - (tr_[e, q][k] - tb[e, q][k]))


def simulated_slips(sim, flagged):
    """{(epoch, satellite, slot)} of the signals of a simulated receiver that slipped
    between two consecutive epochs of their satellite, flagged by the LLI or not."""
    f = sim.fields
    out = set()
    for sat in np.unique(f["sat"]):
        m = np.flatnonzero(f["sat"] == sat)
        nxt = m[1:][np.diff(f["epoch"][m]) == 1]
        hit = sim.slip[nxt] & ((f["signals"].lli[nxt] & 1) == flagged)
        out |= {(int(f["epoch"][nxt[i]]), sat, int(k)) for i, k in zip(*np.nonzero(hit))}
    return out
