"""The aid plug-ins of a recorded run (sinslab.fusion.aids): every registered aid declares
its settings whole (unit kind, default in SI equal to the text, a config section the app
builds from them), its aliases, and its blocks; a new aid is one class and one registry
entry — the barometer of docs/architecture.md ("A new sensor is one file"), built here
through the plug-in API only, estimates its bias within its σ on a simulated drive and
gets its config section, its keys refused while it is not enabled, and its report."""
import math
from dataclasses import dataclass, fields, replace

import numpy as np
import pytest

from sinslab.core import units as u
from sinslab.fusion import aids as AI
from sinslab.fusion.aids.base import (Aid, Estimate, Line, Panel, PanelFigure, Plan, Report, State, settings_of,
                                      setting)
from sinslab.sim import trajectory as tr
from support import simulated_car_drive


def test_registry_declares_every_aid_whole():
    from sinslab.app.config import settings_section
    types = AI.aid_types()
    assert list(types) == ["zupt", "lever", "nhc", "odometer", "magnetometer", "barometer"]  # the order they enter a run
    flags = []
    for name, t in types.items():
        assert t.name == name and t.summary and issubclass(t, Aid)
        st = settings_of(t)
        defaults = {f.name: f.default for f in fields(t)}
        for key, s in st.items():
            # the dataclass default is the config default in SI
            want = s.si(s.text) if s.kind != "mount" else None
            assert defaults[key] == (pytest.approx(want) if isinstance(want, (float, tuple)) else want), (name, key)
            flags += [s.flag] if s.flag else []
        sec = settings_section(f"S_{name}", st)
        back = sec.model_validate(sec().model_dump(mode="json"))        # the defaults round-trip
        assert t(**{k: getattr(back, k) for k in st}) == t()
        for alias, kv in t.aliases.items():
            assert set(kv) <= set(st) and alias not in types
    assert len(flags) == len(set(flags))                               # one option, one key


def test_tokens_resolve_in_registry_order_with_aliases():
    assert AI.resolve_tokens(["nhc", "zaru", "lever"]) == {"zupt": {"zaru": True}, "lever": {}, "nhc": {}}
    assert AI.resolve_tokens([]) == {}
    with pytest.raises(ValueError, match="unknown wings"):
        AI.resolve_tokens(["zupt", "wings"])


def test_row_log_records_what_the_driver_decided():
    """The driver's row record (RowLog): every candidate per epoch, the rows formed with
    their innovation and σ, used or refused, the candidates left out counted by cause."""
    from sinslab.fusion.measurements import Rows
    from sinslab.fusion.observer import RowLog
    log = RowLog()
    rows = Rows(np.array([1.0, 2.0]), np.eye(2), np.array([4.0, 9.0]), np.array([True, False, True]),
                {"sat": np.array(["G01", "G02", "G03"])}, {"below_mask": 1})
    log.add(10.0, rows, np.array([False, True]), np.array([0.5, 0.7]), np.array([0.1, 9.0]))
    assert log.t == [10.0] and list(log.meta["sat"][0]) == ["G01", "G02", "G03"]
    assert np.array_equal(log.used[0], [True, False, False]) and np.array_equal(log.rejected[0], [False, False, True])
    np.testing.assert_array_equal(log.sigma[0], [2.0, np.nan, 3.0])
    assert log.counts() == {"used": 1, "rejected": 1, "below_mask": 1}
    assert log.used_per_epoch().tolist() == [1]


# ------------------------------------------------- a new aid: the recipe of the docs ---
@dataclass(frozen=True)
class Baro(Aid):
    """Barometric height with a Gauss–Markov bias state (docs/architecture.md)."""

    name = "baro"
    summary = "barometric height with a bias state"
    file: str = setting("file", "", "heights: FILE (t, height columns)", flag="--baro")
    sigma: float = setting("length", "0.5 m", "white noise of a reading", gt="0 m")
    bias_sigma: float = setting("length", "10 m", "prior σ of the bias", gt="0 m")
    tau: float = setting("time", "300 s", "correlation time of the bias", gt="0 s")
    series: object = None

    def load(self, inputs):
        t, h = inputs.read("read_baro", self.file)
        return replace(self, series=(inputs.clock(t), h))

    def states(self):
        from sinslab.nav import errstate as es
        return (State(es.barometer_bias(tau=self.tau, sigma=self.bias_sigma), self.bias_sigma),)

    def plan(self, setup):
        from sinslab.fusion.measurements import Barometer
        t, h = self.series
        return Plan((("baro", Barometer(t, h, self.sigma)),))

    def report(self, plan, run):
        sl = run.layout.find("baro_bias")
        b, s = -run.x[-1, sl][0], run.sigma[-1, sl][0]          # δb = b_used − b_true, b_used = 0
        return Report(self.name, "barometer", estimates=(Estimate("baro_bias", (b,), (s,), "m"),),
                      metrics={"baro_bias_m": b, "baro_bias_sigma_m": s},
                      figures=(PanelFigure("baro", "Barometer bias ± 1σ.", (Panel("bias [m]", (
                          Line(run.t - run.t[0], -run.x[:, sl][:, 0], band=run.sigma[:, sl][:, 0]),)),)),))


class _Inputs:
    """The app's side of Aid.load, for the test: the data front door replaced by a dict."""

    imu_path, rest_flags = None, None

    def __init__(self, files):
        self.files = files

    def read(self, reader, path):
        assert reader == "read_baro"
        return self.files[path]

    def clock(self, t):
        return t


@pytest.fixture(scope="module")
def baro_drive():
    segs = [tr.Static(duration=20.0), tr.Accelerate(duration=10.0, accel=2.0),
            tr.Climb(duration=40.0, angle=2 * u.deg), tr.Turn(duration=15.0, rate=6 * u.deg, coordinated=False),
            tr.Climb(duration=40.0, angle=-2 * u.deg), tr.Level(duration=30.0)]
    imu, fx, tru, _, rng = simulated_car_drive(segs)
    k = np.arange(0, tru.t.size, 10)                                  # 10 Hz readings, bias 7 m
    return imu, fx, tru, (tru.t[k], tru.h[k] + 7.0 + 0.3 * rng.standard_normal(k.size))


def test_a_new_aid_through_the_plug_in_api(baro_drive, monkeypatch):
    from sinslab.fusion import recorded as R
    imu, fx, tru, series = baro_drive
    aid = Baro(file="baro.csv", sigma=0.3).load(_Inputs({"baro.csv": series}))
    outs = [(fx.t[0] + 60.0, 40.0)]                                   # no GNSS through the climb
    r = R.navigate_recorded(imu, fx, R.NavOptions.of(outages=outs, kf_dt=0.1), aids=[aid])
    rep = r.report("baro")
    b, s = rep.metrics["baro_bias_m"], rep.metrics["baro_bias_sigma_m"]
    assert abs(b - 7.0) < 3 * s and s < 1.0, (b, s)                   # the bias, within its σ
    assert "baro" in r.layout.names and rep.estimates[0].text() == f"{b:.3f} ± {s:.3f}"
    # one line in the registry: the command line and the configuration follow
    AI.aid_types()
    monkeypatch.setitem(AI._TYPES, "baro", Baro)
    from sinslab.app.commands import navigate_config as NC
    from sinslab.app.config import ConfigError
    monkeypatch.setattr(NC, "_SECTIONS", {})
    cfg = NC.resolve_navigate(given={"--imu": ["i.csv"], "--fixes": ["f.pos"], "--baro": "baro.csv"},
                              sets=["baro.sigma=30 cm"])
    assert cfg.aid == ["baro"] and cfg.baro.sigma == pytest.approx(0.3)
    (built,) = NC.aids_of(cfg)
    assert built == Baro(file="baro.csv", sigma=0.3)
    for sets, msg in ((["baro.sigma=0.3"], "config key baro.sigma (--set baro.sigma=0.3): 0.3 has no unit"),
                      (["baro.sigmaa=1 m"], "unknown config key baro.sigmaa"),
                      (["baro.tau=-1 s"], "must be > 0 s")):
        with pytest.raises(ConfigError, match=msg.replace("(", r"\(").replace(")", r"\)")):
            NC.resolve_navigate(given={"--imu": ["i.csv"], "--aid": "baro"}, sets=sets)
    with pytest.raises(ConfigError, match="the baro aid is not enabled: add --aid baro"):
        NC.resolve_navigate(given={"--imu": ["i.csv"]}, sets=["baro.sigma=1 m"])
    assert "# [baro]" in NC.default_toml("x") and 'sigma = "0.5 m"' in NC.default_toml("x")
    assert math.isfinite(b)
