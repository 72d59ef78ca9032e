"""sinslab's side of the whole-process comparison with KF-GINS: KF-GINS' job done by one
sinslab process.

Run: ``.venv/bin/python benchmarks/kfgins_process.py CONFIG.yaml`` (what
``benchmarks/full_rate.py --kfgins BINARY`` starts beside ``BINARY CONFIG.yaml``).

The process does what KF-GINS' executable does with the same configuration file:

1. read KF-GINS' YAML configuration (its keys and units: initial position [deg, deg, m],
   velocity north-east-down [m/s], roll-pitch-yaw [deg], their σ, the IMU noise — ARW
   [deg/√h], VRW [m/s/√h], Gauss–Markov bias σ [deg/h, mGal] and scale-factor σ [ppm] with
   one correlation time [h] — and the antenna lever arm, forward-right-down [m]) and turn
   it into SI once;
2. read the IMU file (text, seconds and increments forward-right-down, the file KF-GINS
   reads) and the GNSS file (seconds, latitude and longitude [deg], height [m], σ
   north-east-down [m]) with sinslab's readers;
3. run the filter with KF-GINS' error model (21 states: φ, δv, δp, Gauss–Markov gyro and
   accelerometer biases and scale factors; 18 noises), the covariance propagated at every
   IMU epoch, closed loop (:func:`sinslab.fusion.loosely_coupled.loosely_coupled`);
4. write the solution at every IMU epoch with KF-GINS' fields — time, position, velocity,
   attitude; gyro and accelerometer bias and scale factor; the σ of the 21 states — as
   one binary ``.npy`` table ``sinslab_solution.npy`` in KF-GINS' output folder (float64,
   43 columns :data:`COLUMNS`, SI units, ENU velocity and sinslab's attitude angles) where
   KF-GINS writes three text files.

Prints the CPU time of each stage (``--stages``) for the benchmark's breakdown, and the
folder of the sinslab it ran. The garbage
collector is off while the modules load and the objects they made are then frozen
(:func:`gc.freeze`: later collections do not walk them); at its end the process freezes the
objects it leaves before the interpreter exits, whose last collections would otherwise walk
numba's compiler objects, ~0.4 s of CPU. Nothing else is skipped: every finaliser and flush
runs. (The ``sinslab`` commands end their process once their files are closed and
their exit handlers have run, without the interpreter's exit and its collections.)
"""
from __future__ import annotations

import gc
import time

_T0 = time.process_time()
# no garbage collection while the modules load (they make objects that live as long as the
# process); they are frozen once loaded, so later collections do not walk them
gc.disable()

import math  # noqa: E402
import os  # noqa: E402
import sys  # noqa: E402

import sinslab  # noqa: E402,F401 - its process settings take effect before numpy loads, as in the CLI

#: columns of the solution table, in order
COLUMNS = (["t", "lat", "lon", "h", "ve", "vn", "vu", "pitch", "roll", "yaw"]
           + [f"gyro_bias_{a}" for a in "xyz"] + [f"accel_bias_{a}" for a in "xyz"]
           + [f"gyro_scale_{a}" for a in "xyz"] + [f"accel_scale_{a}" for a in "xyz"]
           + [f"sigma_{i}" for i in range(21)])


def _config(path):
    """KF-GINS' configuration file -> (IMU path, GNSS path, output folder, SI values)."""
    import yaml
    with open(path, encoding="utf-8") as fh:
        c = yaml.safe_load(fh)
    deg = math.pi / 180.0
    n = c["imunoise"]
    return c["imupath"], c["gnsspath"], c["outputpath"], {
        "pos": [c["initpos"][0] * deg, c["initpos"][1] * deg, float(c["initpos"][2])],
        "vel_ned": [float(v) for v in c["initvel"]],
        "rpy": [a * deg for a in c["initatt"]],
        "pos_std": [float(v) for v in c["initposstd"]],
        "vel_std": [float(v) for v in c["initvelstd"]],
        "att_std": [a * deg for a in c["initattstd"]],
        "arw": [a * deg / 60.0 for a in n["arw"]], "vrw": [a / 60.0 for a in n["vrw"]],
        "gb_std": [a * deg / 3600.0 for a in n["gbstd"]], "ab_std": [a * 1e-5 for a in n["abstd"]],
        "gs_std": [a * 1e-6 for a in n["gsstd"]], "as_std": [a * 1e-6 for a in n["asstd"]],
        "tau": float(n["corrtime"]) * 3600.0,
        "lever_frd": [float(v) for v in c.get("antlever", [0, 0, 0])],
    }


def _model(cfg):
    """KF-GINS' error model and initial covariance in sinslab's state layout (ENU)."""
    import numpy as np

    from sinslab.core.earth import radii
    from sinslab.nav import errstate as es
    tau = cfg["tau"]
    model = es.ErrorModel("full", [es.gyro_markov(tau, np.array(cfg["gb_std"])),
                                   es.accel_markov(tau, np.array(cfg["ab_std"])),
                                   es.gyro_scale(tau=tau, sigma=np.array(cfg["gs_std"])),
                                   es.accel_scale(tau=tau, sigma=np.array(cfg["as_std"]))],
                          gyro_arw=np.array(cfg["arw"]), accel_vrw=np.array(cfg["vrw"]))
    lat, _, h = cfg["pos"]
    rm, rn = radii(lat, h)
    a, v, p = cfg["att_std"], cfg["vel_std"], cfg["pos_std"]
    # north-east-down σ -> sinslab's east-north-up φ and δv, δL δλ δh [rad, rad, m]
    sd = np.r_[a[1], a[0], a[2], v[1], v[0], v[2], p[0] / rm, p[1] / (rn * math.cos(lat)), p[2],
               cfg["gb_std"], cfg["ab_std"], cfg["gs_std"], cfg["as_std"]]
    return model, np.diag(sd ** 2)


def _pieces(res, a, b):
    """Rows ``a..b−1`` of the solution as blocks of columns in :data:`COLUMNS` order: the
    navigation rows split into position, velocity and attitude angles by
    :func:`sinslab.nav.strapdown.rows_to_series` (compiled), the rest views of the result."""
    from sinslab.nav.strapdown import rows_to_series

    s = rows_to_series(res.t[a:b], res.nav[a:b])
    sl = slice(a, b)
    return (s.t[:, None], s.lat[:, None], s.lon[:, None], s.h[:, None], s.vel, s.att, res.gyro_bias[sl],
            res.accel_bias[sl], res.scale[sl], res.sigma[sl])


#: rows of the solution assembled per write (a 1.4 MB buffer: the pieces of a block are
#: copied into it while it stays in the processor's cache)
BLOCK = 4096


def write_solution(path, res):
    """The solution as one ``.npy`` table (M, 43), float64, row after row, written a block of
    :data:`BLOCK` rows at a time through one buffer, so that no second copy of the solution
    is made in memory and each source array is read once, in order."""
    import numpy as np

    m = res.t.size
    buf = np.empty((min(m, BLOCK), len(COLUMNS)))
    with open(path, "wb") as fh:
        np.lib.format.write_array_header_2_0(fh, {"descr": "<f8", "fortran_order": False,
                                                  "shape": (m, len(COLUMNS))})
        for a in range(0, m, BLOCK):
            b = min(m, a + BLOCK)
            blk = buf[:b - a]
            np.concatenate(_pieces(res, a, b), axis=1, out=blk)
            fh.write(blk.data)


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    stages = "--stages" in argv
    argv = [a for a in argv if a != "--stages"]
    if len(argv) != 1:
        sys.exit("usage: kfgins_process.py CONFIG.yaml [--stages]")
    cpu = {}

    def mark(name, c0=[_T0]):
        c = time.process_time()
        cpu[name] = c - c0[0]
        c0[0] = c

    import numpy as np

    from sinslab.core.attitude import euler_from_ned, vec_ned_to_enu
    from sinslab.core.records import NavState
    from sinslab.data.tables import read_fix_table, read_table_imu
    from sinslab.fusion.loosely_coupled import loosely_coupled
    from sinslab.fusion.spec import FilterGrid, FixSpec, InsSpec
    mark("start-up and imports")
    gc.freeze()
    gc.enable()
    imu_path, gnss_path, out_dir, cfg = _config(argv[0])
    imu = read_table_imu(imu_path, columns="t=1[s],dtheta_x=2[rad],dtheta_y=3[rad],dtheta_z=4[rad],"
                         "dv_x=5[m/s],dv_y=6[m/s],dv_z=7[m/s]", frame="frd").imu
    fixes, _ = read_fix_table(gnss_path, columns="t=1[s],lat=2[deg],lon=3[deg],h=4[m],sd_n=5[m],"
                              "sd_e=6[m],sd_u=7[m]")
    mark("reading")
    model, P0 = _model(cfg)
    init = NavState(*cfg["pos"], vec_ned_to_enu(np.array(cfg["vel_ned"])), euler_from_ned(np.array(cfg["rpy"])),
                    imu.t0)
    sel = fixes.t <= imu.t[-1]
    pos = np.column_stack([fixes.lat, fixes.lon, fixes.h])[sel]
    spec = FixSpec(fixes.t[sel], pos, fixes.sigma[sel], lever_arm=vec_ned_to_enu(np.array(cfg["lever_frd"])))
    res = loosely_coupled(imu, init, spec, P0, model, ins=InsSpec(nsub=1), grid=FilterGrid(imu.dt),
                          progress=False)
    mark("filter")
    write_solution(os.path.join(out_dir, "sinslab_solution.npy"), res)
    mark("writing")
    if stages:
        print("STAGES " + " ".join(f"{k.replace(' ', '_')}={v:.3f}" for k, v in cpu.items()))
        print("SINSLAB " + os.path.dirname(os.path.abspath(sinslab.__file__)))
    # the work is done and its file closed: the objects left (numba's compiler among them)
    # are frozen, so that the interpreter's exit does not walk them in its last garbage
    # collections (~0.4 s of CPU once numba has loaded a kernel; nothing else is skipped:
    # every finaliser and flush still runs)
    gc.freeze()
    return 0


if __name__ == "__main__":
    sys.exit(main())
