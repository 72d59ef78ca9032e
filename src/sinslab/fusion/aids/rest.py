"""Rest: zero-velocity (ZUPT) and zero angular-rate (ZARU) updates on the stationary
intervals of a recorded run.

Where the vehicle stands still its velocity is zero and its body turns with the Earth
only. The intervals come from the log's rest column (``rest = "flags"``) or from the IMU
detector (:func:`sinslab.fusion.stationarity.detect`, ``"auto"``) with thresholds
calibrated on the run's initial rest, and are cut wherever a GNSS fix says the vehicle
moves (a detector cannot tell rest from steady driving on a smooth road; a fix can).
ZUPT (:class:`~sinslab.fusion.measurements.ZeroVelocity`) applies every ``interval``
inside them, ZARU (:class:`~sinslab.fusion.measurements.ZeroRate`, ``zaru = true`` or
``--aid zaru``) at every epoch; each behind an innovation gate, so that a "rest" in
motion is refused and counted.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sinslab.fusion.aids.base import (GATE_DESCRIPTIONS, Aid, AidRun, Mark, Plan, Report, Setup, Table, every,
                                     gated, setting)

__all__ = ["Zupt", "rest_intervals", "moving_spans", "subtract_spans"]


@dataclass(frozen=True)
class Zupt(Aid):
    """ZUPT (and ZARU) on the rest intervals of the run (see the module notes)."""

    name = "zupt"
    summary = "zero-velocity updates (and zero angular rate: zaru) where the vehicle stands still"
    aliases = {"zaru": {"zaru": True}}

    rest: str = setting("choice", "either", "where rest is found: auto (IMU detector), flags (the log's rest "
                        "column) or either (the flags when the IMU table has them, else the detector)",
                        choices=("either", "auto", "flags"), flag="--rest")
    sigma: float = setting("velocity", "0.02 m/s", "σ of a zero-velocity update", gt="0 m/s", le="10 m/s")
    zaru: bool = setting("flag", False, "zero angular-rate updates on the same intervals (--aid zaru)")
    zaru_sigma: float | None = setting("angular_rate", "auto", "σ of a zero angular-rate update (auto: twice "
                                       "the gyro white noise over one filter step)", none="auto", gt="0 deg/h")
    min_duration: float = setting("time", "2 s", "shortest rest interval used", gt="0 s", le="1 h")
    interval: float = setting("time", "0.1 s", "a ZUPT every this inside the intervals", gt="0 s", le="60 s")
    gate: float | None = setting("probability", 1e-6, "false-rejection probability of the innovation gate "
                                 "of each update (none: no gate)", none="none", gt=0.0, lt=1.0)
    #: the log's rest flags ``(t, flags)`` when the intervals come from them (read by :meth:`load`)
    flags: tuple | None = None

    def load(self, inputs):
        """The source of the intervals settled: the flags of the IMU table, if asked for or
        (``either``) if it has them."""
        import dataclasses
        have = inputs.rest_flags is not None
        if self.rest == "flags" and not have:
            raise ValueError("--rest flags: the IMU table has no rest-flag column (name it in --columns "
                             "as stationary=COLUMN)")
        source = "flags" if self.rest == "flags" or (self.rest == "either" and have) else "auto"
        return dataclasses.replace(self, rest=source, flags=inputs.rest_flags if source == "flags" else None)

    def plan(self, setup: Setup) -> Plan:
        from sinslab.fusion.measurements import ZeroRate, ZeroVelocity
        st = setup.start
        rest = None if st.rest is None else (st.rest.k0, st.rest.k1)
        iv = rest_intervals(setup.imu, "flags" if self.rest == "flags" else "auto", setup.lat, rest,
                            st.gyro_bias, fixes=setup.fixes_used, start=setup.start_spec, rest_flags=self.flags,
                            min_duration=self.min_duration)
        iv = iv[iv[:, 1] > st.t] if iv.size else iv
        ms = []
        zs = None
        if len(iv):
            ms.append(("zupt", ZeroVelocity(iv, self.sigma, every=every(self.interval, setup.T), gate=self.gate)))
            if self.zaru:
                zs = self.zaru_sigma if self.zaru_sigma is not None else \
                    2.0 * float(np.max(setup.gyro_noise)) / math.sqrt(setup.T)
                # every epoch: each holds the rate of its own step, thinning discards them
                ms.append(("zaru", ZeroRate(iv, zs, every=1, gate=self.gate)))
        return Plan(tuple(ms), {"intervals": iv.tolist(), "zaru_sigma": zs})

    def report(self, plan: Plan, run: AidRun) -> Report:
        iv = plan.facts["intervals"]
        metrics = {"rest_intervals": len(iv), "rest_total_s": float(sum(b - a for a, b in iv))}
        lines, marks = [], [Mark("band", tuple(tuple(x) for x in iv), "rest (ZUPT/ZARU)")] if iv else []
        for label, m in plan.measurements:
            if m.gate is None:
                continue
            mt, ln, mk = gated(label, run.gates[label], 2.5 * run.T * m.every, run.t_ref)
            metrics.update(mt)
            lines += ln
            marks += [mk] if mk else []
        note = (f"ZUPT{'/ZARU' if self.zaru else ''} on {metrics['rest_intervals']} rest interval(s), "
                f"{metrics['rest_total_s']:.0f} s in all ({self.rest} detection).")
        arr = np.asarray(iv, dtype=float).reshape(-1, 2)
        table = Table("rest_intervals", {"start_s": arr[:, 0], "end_s": arr[:, 1]},
                      "rest intervals the zero-velocity updates were applied in (absolute times)")
        return Report(self.name, "zero-velocity updates", metrics=metrics, tables=(table,), notes=(note,),
                      lines=tuple(lines), marks=tuple(marks), descriptions=(
                          (r"^rest_intervals$", "rest intervals used for zero-velocity updates"),
                          (r"^rest_total_s$", "total time at rest used for zero-velocity updates"),
                          *GATE_DESCRIPTIONS))


def rest_intervals(imu, source, lat, rest=None, gyro_bias=None, fixes=None, *, start=None, rest_flags=None,
                   min_duration=2.0):
    """Stationary intervals for ZUPT/ZARU [s], shape (K, 2): from the log's rest flags
    (``source="flags"``, ``rest_flags = (t, flags)``) or the IMU detector
    (:func:`sinslab.fusion.stationarity.detect`) with thresholds calibrated on the initial
    rest ``rest = (k0, k1)`` (the scatter of specific force and rate and the mean rate of
    the engine-on car at rest, ×1.5; the gyro bias measured there removed), trimmed by
    0.5 s at both ends and at least ``min_duration`` long; then cut wherever one of
    ``fixes`` (those the filter uses) says the vehicle moves (:func:`moving_spans`, with
    the thresholds of ``start``, a :class:`~sinslab.fusion.recorded_spec.StartSpec`)."""
    from sinslab.fusion.recorded_spec import StartSpec
    iv = _rest_candidates(imu, source, lat, rest, gyro_bias, rest_flags, min_duration)
    if fixes is not None and len(fixes) > 1 and iv.size:
        iv = subtract_spans(iv, moving_spans(fixes, start or StartSpec()))
    return iv[(iv[:, 1] - iv[:, 0]) >= max(min_duration - 1.0, 0.1)] if iv.size else iv


def moving_spans(fixes, start):
    """Time spans [s] (K, 2) in which fixes say the vehicle moves: one fix interval either
    side of every fix faster than
    :func:`~sinslab.fusion.recorded_start.moving_speed_threshold`."""
    from sinslab.core.stamps import stamp_step
    from sinslab.fusion.recorded_start import fix_speed, moving_speed_threshold
    fdt, _ = stamp_step(fixes.t)
    mv = fix_speed(fixes) > moving_speed_threshold(fixes, start)
    return np.stack([fixes.t[mv] - fdt, fixes.t[mv] + fdt], -1)


def subtract_spans(iv, spans):
    """Intervals ``iv`` (K, 2) minus the union of ``spans`` (L, 2), both [s]."""
    out = []
    spans = np.asarray(spans, dtype=float).reshape(-1, 2)
    spans = spans[np.argsort(spans[:, 0])] if spans.size else spans
    for a, b in np.asarray(iv, dtype=float).reshape(-1, 2):
        hit = spans[(spans[:, 1] > a) & (spans[:, 0] < b)]
        cur = a
        for sa, sb in hit:
            if sa > cur:
                out.append((cur, min(sa, b)))
            cur = max(cur, sb)
            if cur >= b:
                break
        if cur < b:
            out.append((cur, b))
    return np.array(out, dtype=float).reshape(-1, 2)


def _rest_candidates(imu, source, lat, rest, gyro_bias, rest_flags, min_duration):
    from sinslab.core import earth as E
    from sinslab.fusion import stationarity as st
    if source == "flags":
        t, fl = rest_flags
        iv = st.from_flags(t, fl, min_duration=min_duration)
    else:
        gb = np.zeros(3) if gyro_bias is None else np.asarray(gyro_bias, float)
        kw = {}
        if rest is not None:
            k0, k1 = rest
            k = max(1, int(round(1.0 / imu.dt)))
            m = (k1 - k0) // k
            if m >= 1:
                f = (imu.dv[k0:k0 + m * k] / imu.dt).reshape(m, k, 3)
                w = ((imu.dtheta[k0:k0 + m * k] - gb * imu.dt) / imu.dt).reshape(m, k, 3)
                g = float(E.gravity(lat, 0.0))
                kw = dict(f_std=max(1.5 * float(np.linalg.norm(f.std(1), axis=1).max()), 0.02),
                          f_tol=max(1.5 * float(np.abs(np.linalg.norm(f.mean(1), axis=1) - g).max()), 0.05),
                          w_max=max(1.5 * float(np.linalg.norm(w.mean(1), axis=1).max()), 0.002),
                          w_std=max(1.5 * float(np.linalg.norm(w.std(1), axis=1).max()), 1e-4))
        iv = st.detect(imu, lat, min_duration=min_duration, gyro_bias=gb, **kw)
    iv = np.asarray(iv, dtype=float).reshape(-1, 2)
    return np.stack([iv[:, 0] + 0.5, iv[:, 1] - 0.5], -1) if iv.size else iv
