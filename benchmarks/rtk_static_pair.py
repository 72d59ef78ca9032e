"""RTK on the real rover + base pair ``cssrlib-static-rtk`` from the command line: fix
rate, time to first fix, ratio, integers fixed and the error of the float and the fixed
antenna against the rover's reference coordinates, GNSS alone and RTK/INS.

Run: ``.venv/bin/python benchmarks/rtk_static_pair.py [--data DIR] [--out FILE] [--keep DIR]``;
``.venv/bin/python benchmarks/record.py rtk_static_pair`` runs it and stores its figures in
``docs/benchmarks.json``, the record docs/raw-gnss.md quotes them from.

Every run is the ``sinslab navigate`` command of docs/raw-gnss.md (in process): the rover
(a Septentrio receiver, 60 epochs at 1 Hz) against the GSI base 3034 at the coordinates
of the set's README, GNSS alone (no ``--imu``) with the constant-velocity motion model
(the default) and the static one, and RTK/INS with a synthesised consumer MEMS IMU at rest
on the rover's antenna (real observations, synthetic inertial data: 100 Hz, gyro bias
0.1 °/s and ARW 0.6 °/√h, accelerometer bias 40 mg and VRW 150 µg/√Hz, drawn with seed 1
by ``examples/rtk_static_pair.py``; the heading given 5° off), each with integer resolution
(fix and hold) and float only (``gnss.raw.ar=off``). The errors are the run's baseline
columns (antenna minus base, east/north/up at the base) minus the reference baseline; the
fixed figures are over the fixed epochs, the float ones over every epoch and at the
first, 10th and last epoch. CPU time is of the whole command (reading, filter, run folder).
The cross-check: RTKLIB's own RTK (``postpos`` of pyrtklib5, kinematic, fix and hold, the
same mask, carriers and base position, :data:`RTKLIB_CONF`) on the same files, its fixed
antenna against the reference and against sinslab's at the epochs both fixed.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("SINSLAB_QUIET", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "cssrlib-static-rtk"
#: reference coordinates of the set's README (ECEF [m])
BASE = np.array([-3959400.631, 3385704.533, 3667523.111])
ROVER = np.array([-3962108.673, 3381309.574, 3668678.638])
BASE_TEXT = "-3959400.631,3385704.533,3667523.111 m"
#: the heading given to the RTK/INS start (the IMU's true heading is 40°)
HEADING = "heading=45 deg"


def command(data: Path, variant: str, out: Path, imu: Path | None = None) -> list:
    """The ``sinslab navigate`` arguments of one run (docs/raw-gnss.md)."""
    args = ["navigate", "--gnss-raw", str(data / "SEPT078M1.21O"), "--gnss-nav", str(data / "SEPT078M.21P"),
            "--gnss-base", str(data / "3034078M1.21O"), "--base-position", BASE_TEXT]
    if imu is not None:
        args += ["--imu", str(imu), "--init", HEADING]
    if "static" in variant:
        args += ["--set", "gnss.raw.dynamics=static"]
    if "float" in variant:
        args += ["--set", "gnss.raw.ar=off"]
    return args + ["--out", str(out)]


def write_imu(data: Path, path: Path):
    """The synthesised IMU at rest on the rover's antenna as a CSV of increments on the
    observations' time axis (GPS time)."""
    import pandas as pd
    sys.path.insert(0, str(ROOT / "examples"))
    from rtk_static_pair import consumer_imu_at_rest, read
    rover, _ = read(data)
    imu = consumer_imu_at_rest(rover)[0]
    cols = {"t": imu.t}
    for k, c in enumerate("xyz"):
        cols[f"dtheta_{c}"] = imu.dtheta[:, k]
    for k, c in enumerate("xyz"):
        cols[f"dv_{c}"] = imu.dv[:, k]
    pd.DataFrame(cols).to_csv(path, index=False, float_format="%.17g")


#: RTKLIB's options for the cross-check (postpos through pyrtklib5): the rover's three
#: carriers of GPS, Galileo and QZSS above 10°, broadcast ionosphere, Saastamoinen, fix
#: and hold with the ratio test at 3, the base at the README's coordinates; the rest its defaults
RTKLIB_CONF = """pos1-posmode=kinematic
pos1-frequency=l1+l2+l5
pos1-soltype=forward
pos1-elmask=10
pos1-ionoopt=brdc
pos1-tropopt=saas
pos1-sateph=brdc
pos1-navsys=13
pos2-armode=fix-and-hold
pos2-arthres=3
out-solformat=xyz
ant2-postype=xyz
ant2-pos1={0}
ant2-pos2={1}
ant2-pos3={2}
"""


def rtklib(data: Path, root: Path) -> dict:
    """RTKLIB's RTK solution of the pair (``postpos``, kinematic): per epoch its status
    (1 fixed), ratio and the baseline east/north/up at the base [m]."""
    import pyrtklib5 as rk

    from sinslab.core import earth as E
    conf, out = root / "rtklib.conf", root / "rtklib.pos"
    conf.write_text(RTKLIB_CONF.format(*BASE))
    rk.resetsysopts()
    if not rk.loadopts(str(conf), rk.sysopts[0]):
        sys.exit("rtk_static_pair: RTKLIB did not read its options")
    popt, sopt, fopt = rk.prcopt_t(), rk.solopt_t(), rk.filopt_t()
    rk.getsysopts(popt, sopt, fopt)
    files = [str(data / f) for f in ("SEPT078M1.21O", "3034078M1.21O", "SEPT078M.21P")]
    if rk.postpos(rk.gtime_t(), rk.gtime_t(), 0.0, 0.0, popt, sopt, fopt, files, len(files), str(out), "", ""):
        sys.exit("rtk_static_pair: RTKLIB's postpos failed")
    rows = [ln.split() for ln in out.read_text().splitlines() if ln.strip() and not ln.startswith("%")]
    xyz = np.array([[float(v) for v in r[2:5]] for r in rows])
    lat, lon, _ = E.ecef_to_geodetic(BASE)
    return dict(q=np.array([int(r[5]) for r in rows]), ratio=np.array([float(r[14]) for r in rows]),
                baseline=(xyz - BASE) @ E.enu_to_ecef_matrix(lat, lon))


def rtklib_figures(rt: dict, ours: Path) -> dict:
    """RTKLIB's figures as :func:`figures` computes them, and its fixed baseline against the
    fixed one of the run folder ``ours`` (the epochs both fixed)."""
    import pandas as pd
    fx = rt["q"] == 1
    err = rt["baseline"] - reference_baseline()
    hz = np.hypot(err[:, 0], err[:, 1])
    res = dict(rtk_epochs=int(fx.size), rtk_epochs_fixed=int(fx.sum()),
               rtk_first_fix_epochs=int(np.flatnonzero(fx)[0]) + 1 if fx.any() else None,
               rtk_ratio_min=float(rt["ratio"][fx].min()), rtk_ratio_median=float(np.median(rt["ratio"][fx])))
    res["fixed_hz_rms_m"], res["fixed_hz_max_m"] = _rms_max(hz[fx])
    res["fixed_up_rms_m"], res["fixed_up_max_m"] = _rms_max(err[fx, 2])
    mean = err[fx].mean(0)
    res["fixed_mean_error_enu_m"], res["fixed_mean_error_3d_m"] = [float(v) for v in mean], float(np.linalg.norm(mean))
    tab = pd.read_csv(ours / "solution.csv")
    both = fx & (tab["status"].to_numpy() == 2)
    d = tab[["baseline_e_m", "baseline_n_m", "baseline_u_m"]].to_numpy()[both] - rt["baseline"][both]
    res["vs_sinslab_epochs"] = int(both.sum())
    res["vs_sinslab_hz_rms_m"], res["vs_sinslab_hz_max_m"] = _rms_max(np.hypot(d[:, 0], d[:, 1]))
    res["vs_sinslab_up_rms_m"], res["vs_sinslab_up_max_m"] = _rms_max(d[:, 2])
    return res


def reference_baseline():
    """The rover's reference minus the base's, east/north/up at the base [m]."""
    from sinslab.core import earth as E
    lat, lon, _ = E.ecef_to_geodetic(BASE)
    return (ROVER - BASE) @ E.enu_to_ecef_matrix(lat, lon)


def _rms_max(v):
    return float(np.sqrt(np.mean(v ** 2))), float(np.max(np.abs(v)))


def figures(out: Path, table: str) -> dict:
    """The figures of one run folder: its RTK metrics and the errors against the reference."""
    import pandas as pd
    m = json.loads((out / "summary.json").read_text())["metrics"]
    tab = pd.read_csv(out / table)
    err = tab[["baseline_e_m", "baseline_n_m", "baseline_u_m"]].to_numpy() - reference_baseline()
    st = tab["status"].to_numpy()
    res = {k: m[k] for k in ("rtk_epochs", "rtk_epochs_solved", "rtk_epochs_fixed", "rtk_fixed_fraction",
                             "rtk_first_fix_epochs", "rtk_first_fix_s", "rtk_ratio_median", "rtk_ratio_min",
                             "rtk_integers_fixed_median", "phase_nis_mean", "code_nis_mean")}
    res["restarts"] = int(sum(v for k, v in m.items() if k.startswith("restarts_")))
    hz = np.hypot(err[:, 0], err[:, 1])
    ok = np.isfinite(hz)
    res["hz_rms_m"], res["hz_max_m"] = _rms_max(hz[ok])
    res["up_rms_m"], res["up_max_m"] = _rms_max(err[ok, 2])
    for i, name in ((0, "first"), (9, "epoch10"), (int(np.flatnonzero(ok)[-1]), "last")):
        res[f"hz_{name}_m"], res[f"up_{name}_m"] = float(hz[i]), float(err[i, 2])
    fx = st == 2
    if fx.any():
        res["fixed_hz_rms_m"], res["fixed_hz_max_m"] = _rms_max(hz[fx])
        res["fixed_up_rms_m"], res["fixed_up_max_m"] = _rms_max(err[fx, 2])
        mean = err[fx].mean(0)
        res["fixed_mean_error_enu_m"] = [float(v) for v in mean]
        res["fixed_mean_error_3d_m"] = float(np.linalg.norm(mean))
        bl = tab.loc[fx, ["baseline_e_m", "baseline_n_m", "baseline_u_m"]].to_numpy().mean(0)
        res["fixed_baseline_m"] = float(np.linalg.norm(bl))
    res["reference_baseline_m"] = float(np.linalg.norm(ROVER - BASE))
    return res


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default=str(DATA), help="the cssrlib-static-rtk folder")
    p.add_argument("--out", default=None, help="write the figures as JSON")
    p.add_argument("--keep", default=None, help="keep the run folders here")
    a = p.parse_args(argv)
    from typer.testing import CliRunner

    from sinslab.cli import app
    data = Path(a.data)
    runner = CliRunner()
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(a.keep or tmp)
        root.mkdir(parents=True, exist_ok=True)
        imu = root / "imu_at_rest.csv"
        write_imu(data, imu)
        for variant in ("rtk_kinematic", "rtk_static", "float_kinematic", "float_static", "rtk_ins", "float_ins"):
            run = root / variant
            with_imu = variant.endswith("_ins")
            c0 = time.process_time()
            r = runner.invoke(app, command(data, variant, run, imu if with_imu else None))
            cpu = time.process_time() - c0
            if r.exit_code != 0:
                sys.exit(f"rtk_static_pair: {variant} failed:\n{r.output}")
            res = figures(run, "rtk_epochs.csv" if with_imu else "solution.csv")
            res["cpu_s"] = cpu
            out[variant] = res
            print(f"{variant:>15s}: fixed {res['rtk_epochs_fixed']}/{res['rtk_epochs_solved']}, first fix "
                  f"{res['rtk_first_fix_epochs']}, ratio median {res['rtk_ratio_median']}, min {res['rtk_ratio_min']}"
                  f", integers {res['rtk_integers_fixed_median']} | all epochs hz {100 * res['hz_rms_m']:.2f} / "
                  f"{100 * res['hz_max_m']:.2f} cm, up {100 * res['up_rms_m']:.2f} / {100 * res['up_max_m']:.2f} cm;"
                  f" first {100 * res['hz_first_m']:.1f}/{100 * res['up_first_m']:.1f}, 10th "
                  f"{100 * res['hz_epoch10_m']:.2f}/{100 * res['up_epoch10_m']:.2f}, last "
                  f"{100 * res['hz_last_m']:.2f}/{100 * res['up_last_m']:.2f} cm"
                  + (f" | fixed mean 3D {1e3 * res['fixed_mean_error_3d_m']:.1f} mm, baseline "
                     f"{res['fixed_baseline_m']:.4f} m (reference {res['reference_baseline_m']:.4f})"
                     if "fixed_mean_error_3d_m" in res else "") + f" | {cpu:.1f} s CPU", flush=True)
        res = out["rtklib_kinematic"] = rtklib_figures(rtklib(data, root), root / "rtk_kinematic")
        print(f"RTKLIB kinematic: fixed {res['rtk_epochs_fixed']}/{res['rtk_epochs']}, first fix "
              f"{res['rtk_first_fix_epochs']}, ratio min {res['rtk_ratio_min']} | fixed hz {100 * res['fixed_hz_rms_m']:.2f}"
              f" / {100 * res['fixed_hz_max_m']:.2f} cm, up {100 * res['fixed_up_rms_m']:.2f} / "
              f"{100 * res['fixed_up_max_m']:.2f} cm, mean 3D {1e3 * res['fixed_mean_error_3d_m']:.1f} mm | against "
              f"sinslab's fixed epochs ({res['vs_sinslab_epochs']}): hz {1e3 * res['vs_sinslab_hz_rms_m']:.1f} / "
              f"{1e3 * res['vs_sinslab_hz_max_m']:.1f} mm, up {1e3 * res['vs_sinslab_up_rms_m']:.1f} / "
              f"{1e3 * res['vs_sinslab_up_max_m']:.1f} mm", flush=True)
    if a.out:
        Path(a.out).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
