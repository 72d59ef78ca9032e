"""Speed benchmark of sinslab against the reference strapdown kernel (DESIGN.md §3).

Everything is measured in one process, as ratios to ``reference_strapdown.nav`` run on the
same data, because the machine is noisy:

- mechanization throughput (IMU samples/s) of ``sinslab.nav.strapdown.step`` (nsub = 2, no
  output, like the reference) and of ``navigate`` (with output) / reference; target >= 0.5;
- 48 h at 50 Hz navigated with ``navigate`` (full output and 1 Hz output); target < 5 s;
- synthesis throughput (``sinslab.sim.trajectory.generate`` + ``sinslab.sim.imu.apply``) / reference
  on ``aircraft_mixed`` at 100 Hz with a navigation-grade error model (bias + ARW + VRW),
  and each of the two alone; target >= 0.3 for the sum (skipped with a message if those
  modules cannot be imported). All single thread.

Run: ``.venv/bin/python benchmarks/speed.py [--samples 1e7] [--repeat 3] [--quick]``.
The reference is ``../shared/bench/reference_strapdown.py`` relative to the repository
(override with the environment variable ``SINSLAB_REFERENCE``, a file path). Results are
printed as a table and written to ``benchmarks/results/speed.json``.
"""
from __future__ import annotations

import argparse
import atexit
import importlib.util
import json
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
DEFAULT_REFERENCE = HERE.parents[0] / ".." / "shared" / "bench" / "reference_strapdown.py"
TARGETS = {"mechanization_ratio": 0.5, "long_run_48h_50hz_s": 5.0, "synthesis_ratio": 0.3}


def load_reference():
    """Import the reference kernel module from a private copy of its file.

    The copy lives in a temporary folder, so numba's cache for it (the kernel says
    ``cache=True``) is written there: the shared folder is read-only, and a cache entry
    left there by another process made the next run fail to load it.
    """
    path = Path(os.environ.get("SINSLAB_REFERENCE", DEFAULT_REFERENCE)).resolve()
    if not path.is_file():
        raise SystemExit(f"reference kernel not found: {path} (set SINSLAB_REFERENCE)")
    tmp = Path(tempfile.mkdtemp(prefix="sinslab-ref-"))
    atexit.register(shutil.rmtree, tmp, ignore_errors=True)
    copy = tmp / path.name
    shutil.copyfile(path, copy)
    spec = importlib.util.spec_from_file_location("reference_strapdown", copy)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod, path


def _best(fn, repeat):
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def test_data(n, dt=0.01, seed=0):
    """The reference script's data: small random increments plus gravity on z."""
    rng = np.random.default_rng(seed)
    dth = rng.normal(0, 1e-6, (n, 3))
    dvl = rng.normal(0, 1e-5, (n, 3))
    dvl[:, 2] += 9.8 * dt
    return dth, dvl


def reference_rate(ref, dth, dvl, dt, repeat):
    """Reference throughput [samples/s] (after a warm-up compile)."""
    ref.nav(dth[:4], dvl[:4], dt, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.6, 2.0, 0.0)
    el = _best(lambda: ref.nav(dth, dvl, dt, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.6, 2.0, 0.0), repeat)
    return dth.shape[0] / el


def bench_mechanization(ref, n, repeat, dt=0.01):
    """Throughputs of reference, sinslab ``step`` and ``navigate`` on the same n samples."""
    from sinslab.nav import strapdown as sd
    from sinslab.core.records import ImuRecord, NavState

    dth, dvl = test_data(n, dt)
    init = NavState(0.6, 2.0, 0.0, np.zeros(3), np.zeros(3))
    s = sd.initial_state_array(init)
    sd.step(s.copy(), dth[:4], dvl[:4], dt, 2)                       # warm-up compile
    rates = {}
    # interleave to share the machine's noise
    r_ref, r_step = [], []
    for _ in range(repeat):
        r_ref.append(reference_rate(ref, dth, dvl, dt, 1))
        r_step.append(n / _best(lambda: sd.step(s.copy(), dth, dvl, dt, 2), 1))
    rates["reference"] = max(r_ref)
    rates["sinslab_step"] = max(r_step)
    imu = ImuRecord(dt * np.arange(1, n + 1), dth, dvl, dt)
    sd.navigate(ImuRecord(imu.t[:8], dth[:8], dvl[:8], dt), init, progress=False)
    rates["sinslab_navigate"] = n / _best(
        lambda: sd.navigate(imu, init, nsub=2, out_every=1, progress=False), repeat)
    return rates


def bench_long_run(hours=48.0, rate_hz=50.0, repeat=1):
    """Wall time [s] of navigating ``hours`` at ``rate_hz`` (nsub = 2): full output and 1 Hz."""
    from sinslab.nav import strapdown as sd
    from sinslab.core.records import ImuRecord, NavState

    dt = 1.0 / rate_hz
    n = int(round(hours * 3600 * rate_hz))
    dth, dvl = test_data(n, dt, seed=1)
    imu = ImuRecord(dt * np.arange(1, n + 1), dth, dvl, dt)
    del dth, dvl
    init = NavState(0.6, 2.0, 0.0, np.zeros(3), np.zeros(3))
    sd.navigate(ImuRecord(imu.t[:8], imu.dtheta[:8], imu.dv[:8], dt), init, vertical="hold",
                height=np.zeros(9), progress=False)
    full = _best(lambda: sd.navigate(imu, init, nsub=2, vertical="hold", height=0.0,
                                     progress=False), repeat)
    one_hz = _best(lambda: sd.navigate(imu, init, nsub=2, vertical="hold", height=0.0,
                                       out_every=int(rate_hz // 2), progress=False), repeat)
    return {"samples": n, "full_output_s": full, "output_1hz_s": one_hz}


NAV_GRADE = dict(gyro_bias="0.01 deg/h", gyro_arw="0.001 deg/sqrt(h)",
                 accel_bias="50 ug", accel_vrw="10 ug/sqrt(Hz)")


def synthesis_case(n, dt=0.01):
    """The realistic synthesis case: ``presets.aircraft_mixed`` (turns, climbs,
    accelerations, wing rock) at 100 Hz from the paper-003 start, and a navigation-grade
    ``ImuErrors`` (bias + ARW + VRW). Returns (generate(), errors)."""
    from sinslab.sim import imu as imu_mod
    from sinslab.sim import presets
    from sinslab.sim import trajectory as tr

    d = np.radians
    segs = presets.aircraft_mixed(n * dt)
    start = tr.Start(lat=d(32.0), lon=d(118.0), h=1000.0, speed=300.0, heading=0.0)
    errors = imu_mod.ImuErrors.from_datasheet(**NAV_GRADE)
    return (lambda: tr.generate(segs, start, dt, duration=n * dt)), errors


def bench_synthesis(n, repeat):
    """Synthesis throughputs [samples/s] of generate alone, apply alone and both, or a
    string saying why it was skipped. Single thread: both kernels are serial numba loops."""
    try:
        from sinslab.sim import imu as imu_mod
        gen, errors = synthesis_case(1000)
        imu_mod.apply(gen().imu, errors, 0)                               # warm-up compile
    except (ImportError, AttributeError) as e:
        return f"skipped: trajectory/imu not importable yet ({type(e).__name__}: {e})"
    gen, errors = synthesis_case(n)
    g = gen()
    t_gen = _best(gen, repeat)
    t_apply = _best(lambda: imu_mod.apply(g.imu, errors, 0), repeat)
    t_both = _best(lambda: imu_mod.apply(gen().imu, errors, 0), repeat)
    return {"generate": n / t_gen, "apply": n / t_apply, "both": n / t_both}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=float, default=1e7, help="samples for the ratio runs")
    ap.add_argument("--synth-samples", type=float, default=2e6, help="samples for synthesis")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="small sizes (smoke test)")
    ap.add_argument("--out", default=str(HERE / "results" / "speed.json"))
    a = ap.parse_args(argv)
    n = int(1e6 if a.quick else a.samples)
    ns = int(2e5 if a.quick else a.synth_samples)
    hours = 2.0 if a.quick else 48.0
    ref, ref_path = load_reference()

    mech = bench_mechanization(ref, n, a.repeat)
    long = bench_long_run(hours=hours, rate_hz=50.0)
    syn = bench_synthesis(ns, a.repeat)
    ref_rate = mech["reference"]
    res = {
        "python": sys.version.split()[0], "machine": platform.machine(),
        "cpu_count": os.cpu_count(), "reference": str(ref_path),
        "samples": n, "reference_samples_per_s": ref_rate,
        "step_samples_per_s": mech["sinslab_step"], "navigate_samples_per_s": mech["sinslab_navigate"],
        "mechanization_ratio": mech["sinslab_step"] / ref_rate,
        "navigate_ratio": mech["sinslab_navigate"] / ref_rate,
        "long_run_hours": hours, "long_run_samples": long["samples"],
        "long_run_48h_50hz_s": long["full_output_s"], "long_run_1hz_output_s": long["output_1hz_s"],
        "synthesis_samples": ns,
    }
    if isinstance(syn, str):
        res["synthesis_ratio"] = None
        res["synthesis_note"] = syn
    else:
        res["synthesis_case"] = {"motion": "presets.aircraft_mixed, 100 Hz", "errors": NAV_GRADE}
        res["synthesis_samples_per_s"] = syn["both"]
        res["synthesis_ratio"] = syn["both"] / ref_rate
        res["generate_samples_per_s"] = syn["generate"]
        res["generate_ratio"] = syn["generate"] / ref_rate
        res["apply_samples_per_s"] = syn["apply"]
        res["apply_ratio"] = syn["apply"] / ref_rate
    res["targets"] = TARGETS

    rows = [
        ("reference kernel", f"{ref_rate / 1e6:8.2f} M samples/s", "", ""),
        ("strapdown.step (nsub=2)", f"{mech['sinslab_step'] / 1e6:8.2f} M samples/s",
         f"{res['mechanization_ratio']:.2f}", ">= 0.5"),
        ("strapdown.navigate (full output)", f"{mech['sinslab_navigate'] / 1e6:8.2f} M samples/s",
         f"{res['navigate_ratio']:.2f}", ""),
        (f"{hours:g} h @ 50 Hz navigate, full output", f"{long['full_output_s']:8.2f} s", "",
         "< 5 s" if hours == 48.0 else ""),
        (f"{hours:g} h @ 50 Hz navigate, 1 Hz output", f"{long['output_1hz_s']:8.2f} s", "", ""),
    ]
    if isinstance(syn, str):
        rows.append(("synthesis (generate + apply)", syn, "", ">= 0.3"))
    else:
        rows.append(("trajectory.generate (aircraft_mixed)", f"{syn['generate'] / 1e6:8.2f} M samples/s",
                     f"{res['generate_ratio']:.2f}", ""))
        rows.append(("imu.apply (bias + ARW + VRW)", f"{syn['apply'] / 1e6:8.2f} M samples/s",
                     f"{res['apply_ratio']:.2f}", ""))
        rows.append(("synthesis (generate + apply)", f"{syn['both'] / 1e6:8.2f} M samples/s",
                     f"{res['synthesis_ratio']:.2f}", ">= 0.3"))
    w = max(len(r[0]) for r in rows)
    print(f"{'benchmark':<{w}}  {'measured':>22}  {'ratio':>6}  target")
    for name, val, ratio, tgt in rows:
        print(f"{name:<{w}}  {val:>22}  {ratio:>6}  {tgt}")
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(res, indent=2) + "\n")
    tmp.replace(out)
    print(f"wrote {out}")
    return res


if __name__ == "__main__":
    main()
