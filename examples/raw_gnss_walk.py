"""Tightly coupled INS/GNSS on the rtklib-walk log, beside loosely coupled filters and the
GNSS-only single-point solution, against the RTK-fixed epochs of the reference solution.

    python examples/raw_gnss_walk.py DATA_DIR [FIGURE.png]

DATA_DIR holds imu_1730.csv(.tag), gnss_1730.ubx and gnss_1730_sf.pos (the shared
rtklib-walk data). Prints the tables of docs/raw-gnss.md. The options are those of the
documented command (``sinslab navigate --gnss-raw``): the same reader, mount, heading from
the course above 1 m/s with a 10° spread, and defaults otherwise.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from sinslab.core import units as u
from sinslab.data import load_imu, read_fixes
from sinslab.data.gnss import read_gnss_raw, read_ubx_pvt
from sinslab.fusion.gnss import prepare
from sinslab.fusion.recorded import NavOptions, fix_errors, navigate_recorded
from sinslab.fusion.tightly_coupled import RawGnss, RawSource


def main(data, figure=None):
    data = Path(data)
    imu = load_imu(data / "imu_1730.csv", "rtklib-imu", mount="rpy:180,0,-90", frame="frd").imu
    ref = read_fixes(data / "gnss_1730_sf.pos")
    pvt = read_ubx_pvt(data / "gnss_1730.ubx")
    obs = read_gnss_raw(data / "gnss_1730.ubx")
    start = dict(move_speed=1.0, heading_straight=10 * u.deg)

    def tc(**kw):                 # the raw observations as the GNSS source: tightly coupled
        raw = RawGnss(prepare(obs), **kw)
        return navigate_recorded(imu, RawSource(raw), NavOptions.of(**start)), raw

    res_tc, raw = tc()
    res_tdcp, _ = tc(phase="tdcp")               # and the phase change of every signal between epochs
    spp = raw.fixes()
    res_lc_pvt = navigate_recorded(imu, pvt, NavOptions.of(**start))
    res_lc_spp = navigate_recorded(imu, spp, NavOptions.of(**start))
    t0 = float(obs.t_abs[0])
    fixed = ref.select(ref.quality == 1)
    t_lo = res_tc.t[0]                                   # compare where every filter runs
    fixed = fixed.select(fixed.t >= max(t_lo, res_lc_pvt.t[0]))

    def err_of(res):
        t, e, _ = fix_errors(res, fixed)
        return t, e

    def err_spp(fx):
        from sinslab.core import earth as E
        j = np.searchsorted(fx.t, fixed.t - 0.01)
        j = np.clip(j, 0, len(fx) - 1)
        ok = np.abs(fx.t[j] - fixed.t) < 0.01
        rm, rn = E.radii(fixed.lat[ok], fixed.h[ok])
        e = np.stack([(fx.lon[j[ok]] - fixed.lon[ok]) * rn * np.cos(fixed.lat[ok]),
                      (fx.lat[j[ok]] - fixed.lat[ok]) * rm, fx.h[j[ok]] - fixed.h[ok]], -1)
        return fixed.t[ok], e

    rows = [("tightly coupled (pseudorange + Doppler)", *err_of(res_tc)),
            ("tightly coupled + time-differenced phase", *err_of(res_tdcp)),
            ("loosely coupled on the receiver's NAV-PVT", *err_of(res_lc_pvt)),
            ("loosely coupled on the single-point fixes", *err_of(res_lc_spp)),
            ("GNSS-only single-point solution", *err_spp(spp))]
    print(f"RTK-fixed epochs compared: {len(fixed)} ({fixed.t[0] - t0:.1f}..{fixed.t[-1] - t0:.1f} s "
          "after the first GNSS epoch)\n")
    print("| solution | offset E, N, U [m] | horizontal RMS / max [m] | vertical RMS / max [m] |")
    print("| --- | --- | --- | --- |")
    offsets = {}
    for name, t, e in rows:
        off = e.mean(0)
        offsets[name] = off
        d = e - off
        hz = np.hypot(d[:, 0], d[:, 1])
        print(f"| {name} | {off[0]:.2f}, {off[1]:.2f}, {off[2]:.2f} | {np.sqrt(np.mean(hz ** 2)):.3f} / "
              f"{hz.max():.3f} | {np.sqrt(np.mean(d[:, 2] ** 2)):.3f} / {np.abs(d[:, 2]).max():.3f} |")

    curves = [(name, t - t0, np.hypot(*(e - offsets[name])[:, :2].T)) for name, t, e in rows]
    # a window with at most K satellites: no fix for the loosely coupled filter
    print("\n| window | solution | horizontal RMS / max in the window [m] | at its end [m] |")
    print("| --- | --- | --- | --- |")
    for k, (ws, wd) in ((3, (60.0, 20.0)), (2, (60.0, 20.0))):
        res_w, raw_w = tc(max_satellites=((k, t0 + ws, wd),))
        log = res_w.source.rows["pseudoranges"]          # the driver's record of every row
        n_used, tl = log.used_per_epoch(), np.array(log.t)
        assert np.all(n_used[(tl >= t0 + ws) & (tl < t0 + ws + wd)] <= k)
        res_lo = navigate_recorded(imu, pvt, NavOptions.of(outages=((t0 + ws, wd),), **start))
        for name, res, key in ((f"tightly coupled, {k} satellites", res_w, rows[0][0]),
                               ("loosely coupled on NAV-PVT, no fix", res_lo, rows[2][0])):
            t, e = err_of(res)
            d = e - offsets[key]
            m = (t >= t0 + ws) & (t < t0 + ws + wd)
            hz = np.hypot(d[m, 0], d[m, 1])
            print(f"| {ws:g}..{ws + wd:g} s, ≤ {k} sat | {name} | {np.sqrt(np.mean(hz ** 2)):.2f} / "
                  f"{hz.max():.2f} | {hz[-1]:.2f} |")
            if k == 3 or res is res_w:        # the loosely coupled run once
                window = (ws, wd)
                curves.append((f"{name} (window)", t - t0, np.hypot(d[:, 0], d[:, 1])))
    if figure is not None:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True, layout="constrained")
        for name, t, hz in curves[:5]:
            axes[0].plot(t, hz, lw=1, label=name)
        axes[0].set_ylabel("horizontal error [m]")
        axes[0].set_yscale("log")
        axes[0].legend(fontsize=8)
        axes[0].set_title("against the RTK-fixed epochs (each solution's mean offset removed)")
        for name, t, hz in curves[5:]:
            axes[1].plot(t, hz, lw=1, label=name)
        axes[1].axvspan(window[0], window[0] + window[1], color="0.9", lw=0)
        axes[1].set_yscale("log")
        axes[1].set_ylabel("horizontal error [m]")
        axes[1].set_xlabel("time after the first GNSS epoch [s]")
        axes[1].legend(fontsize=8)
        axes[1].set_title("at most 3 or 2 satellites from 60 to 80 s (grey): no fix for the loosely coupled filter")
        fig.savefig(figure, dpi=110)
    c = res_tc.source.rows["pseudoranges"].counts()
    clock = res_tc.source.clock[0]
    print(f"\npseudoranges used {c['used']}, rejected by the gate {c['rejected']}, observations "
          f"without ephemeris {c['no_ephemeris']}; clock drift {clock[0, 1]:.1f} -> "
          f"{clock[-1, 1]:.1f} m/s")
    m = res_tdcp.source.metrics
    restarts = sum(v for k, v in m.items() if k.startswith("tdcp_restarts_"))
    print(f"time-differenced phase: {m['tdcp_rows_used']} rows used, {m['tdcp_rows_rejected']} rejected, "
          f"{restarts} ambiguity restarts, mean NIS {m['tdcp_nis_mean']:.2f}")


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3):
        sys.exit("usage: python examples/raw_gnss_walk.py DATA_DIR [FIGURE.png]")
    main(*sys.argv[1:])
