"""Speed benchmark of sinslab against the reference strapdown kernel (DESIGN.md §3) and its
port to C.

Everything is measured in one process, as ratios to yardsticks run on the same data in the
same rounds (the contenders take turns), in CPU time of this process, because the machine
is shared. The yardsticks: ``reference_strapdown.nav`` (numba) and
``benchmarks/reference_strapdown.c``, the same loop statement for statement in C, compiled
here with ``cc -O2`` when a C compiler is found (``CC`` chooses it) and called through
ctypes; it ends on the numba kernel's state bit for bit.

- mechanization throughput (IMU samples per CPU second) of ``sinslab.nav.strapdown.step``
  (nsub = 2, no output, like the reference) and of ``navigate`` (with output), against
  both yardsticks; target >= 0.9 of the C port;
- 48 h at 50 Hz navigated with ``navigate`` (full output and 1 Hz output); target < 5 s;
- synthesis throughput (``sinslab.sim.trajectory.generate`` + ``sinslab.sim.imu.apply``,
  outputs allocated as a caller gets them) on ``aircraft_mixed`` at 100 Hz with a
  navigation-grade error model (bias + ARW + VRW), and each of the two alone; target >= 0.5
  of the C port for the sum (skipped with a message if those modules cannot be imported).
  All single thread.

What each ratio covers. Mechanization: the same samples in and no output on both sides
(``step`` and the yardsticks end on a state), the same 2-sample update; sinslab's update
does more (bias compensation, the third-order rotation term, the Earth model at
mid-interval), the yardsticks none of that. Synthesis is a different job measured against
the same yardsticks' rate: per sample it writes 22 new doubles (truth: time, position,
velocity, attitude; the exact increments; the erroneous increments) into arrays it
allocates, where the yardsticks write nothing. The first write to new memory costs the
process page faults and the kernel's zeroing of the pages, which on a virtual machine can
be as much as the synthesis's arithmetic, so the same round also fills new arrays of the
same size (``first touch``), and the synthesis rate without that time is reported beside the
whole (``synthesis_compute``: an estimate, the two times subtracted round by round).

The process runs with sinslab's own settings (it imports sinslab before numpy, as the
command line does): in particular numpy does not ask for transparent huge pages, which
changes what the first touch of new memory costs (``numpy_madvise_hugepage`` in the output).

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

import sinslab  # noqa: F401  (before numpy: the process settings sinslab makes, see above)
import numpy as np

HERE = Path(__file__).resolve().parent
DEFAULT_REFERENCE = HERE.parents[0] / ".." / "shared" / "bench" / "reference_strapdown.py"
TARGETS = {"mechanization_ratio_c": 0.9, "long_run_48h_50hz_s": 5.0, "synthesis_ratio_c": 0.5}


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


C_SOURCE = HERE / "reference_strapdown.c"


def load_c_reference():
    """The C port of the reference kernel (``benchmarks/reference_strapdown.c``) compiled
    with ``cc -O2`` into a temporary folder and called through ctypes on the same arrays:
    ``nav(dth, dvl, dt, state)`` with ``state`` (10,) in and out. Returns ``(nav, compiler
    line)`` or ``(None, reason)`` when no C compiler is found or the build fails."""
    import ctypes
    import subprocess

    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if not cc:
        return None, "no C compiler (set CC)"
    tmp = Path(tempfile.mkdtemp(prefix="sinslab-cref-"))
    atexit.register(shutil.rmtree, tmp, ignore_errors=True)
    lib_path = tmp / "reference_strapdown.so"
    cmd = [cc, "-O2", "-shared", "-fPIC", "-o", str(lib_path), str(C_SOURCE), "-lm"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode:
        return None, f"{' '.join(cmd)} failed: {r.stderr.strip()[-300:]}"
    lib = ctypes.CDLL(str(lib_path))
    dp = ctypes.POINTER(ctypes.c_double)
    lib.nav.argtypes = [dp, dp, ctypes.c_long, ctypes.c_double, dp]
    lib.nav.restype = None

    def nav(dth, dvl, dt, state):
        dth = np.ascontiguousarray(dth, dtype=np.float64)
        dvl = np.ascontiguousarray(dvl, dtype=np.float64)
        lib.nav(dth.ctypes.data_as(dp), dvl.ctypes.data_as(dp), dth.shape[0], float(dt), state.ctypes.data_as(dp))
        return state
    version = subprocess.run([cc, "--version"], capture_output=True, text=True).stdout.splitlines()
    return nav, f"{' '.join(cmd[:3])} ({version[0] if version else cc})"


def _cpu(fn):
    """CPU seconds of this process spent in ``fn()`` (one thread: the kernels are serial)."""
    c = time.process_time()
    fn()
    return time.process_time() - c


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


def _yardsticks(ref, c_nav, dth, dvl, dt):
    """CPU-time rates [samples per CPU s] of one run of the numba reference and of its C
    port (None without a compiler) on ``dth``, ``dvl``."""
    n = dth.shape[0]
    r = n / _cpu(lambda: ref.nav(dth, dvl, dt, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.6, 2.0, 0.0))
    c = None
    if c_nav is not None:
        st = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.6, 2.0, 0.0])
        c = n / _cpu(lambda: c_nav(dth, dvl, dt, st))
    return r, c


def bench_mechanization(ref, c_nav, n, repeat, dt=0.01):
    """Throughputs [samples per CPU second] of the numba reference, its C port, sinslab
    ``step`` and ``navigate`` on the same n samples, the contenders taking turns in each
    of ``repeat`` rounds (best of each kept); and whether ``step`` ends on the same state
    as the two references (it integrates more: it need not)."""
    from sinslab.nav import strapdown as sd
    from sinslab.core.records import ImuRecord, NavState

    dth, dvl = test_data(n, dt)
    init = NavState(0.6, 2.0, 0.0, np.zeros(3), np.zeros(3))
    s = sd.initial_state_array(init)
    sd.step(s.copy(), dth[:4], dvl[:4], dt, 2)                       # warm-up compile
    ref.nav(dth[:4], dvl[:4], dt, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.6, 2.0, 0.0)
    r_ref, r_c, r_step = [], [], []
    for _ in range(repeat):                 # interleaved: the machine's noise falls on all alike
        r, c = _yardsticks(ref, c_nav, dth, dvl, dt)
        r_ref.append(r)
        if c is not None:
            r_c.append(c)
        r_step.append(n / _cpu(lambda: sd.step(s.copy(), dth, dvl, dt, 2)))
    rates = {"reference": max(r_ref), "c_reference": max(r_c) if r_c else None, "sinslab_step": max(r_step)}
    imu = ImuRecord(dt * np.arange(1, n + 1), dth, dvl, dt)
    sd.navigate(ImuRecord(imu.t[:8], dth[:8], dvl[:8], dt), init, progress=False)
    rates["sinslab_navigate"] = n / min(_cpu(lambda: sd.navigate(imu, init, nsub=2, out_every=1, progress=False))
                                        for _ in range(repeat))
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


def _new_arrays(g, applied):
    """The distinct arrays a caller gets from ``generate`` (truth and exact increments) and
    ``apply`` (erroneous increments): a view shared by two records counted once."""
    arrays = []
    for a in (g.truth.t, g.truth.lat, g.truth.lon, g.truth.h, g.truth.vel, g.truth.att, g.truth.att_imu,
              g.imu.t, g.imu.dtheta, g.imu.dv, g.mount, applied.dtheta, applied.dv):
        if a is not None and not any(np.shares_memory(a, b) for b in arrays):
            arrays.append(a)
    return arrays


def _first_touch(shapes):
    """Allocate arrays of these shapes and write every element once (page faults and the
    kernel's zeroing of new pages, then the stores), as the synthesis does to its outputs."""
    return [np.ones(s) for s in shapes]


def bench_synthesis(n, repeat, ref, c_nav):
    """Synthesis throughputs [samples per CPU second] of generate alone, apply alone and
    both (allocating their outputs, as a caller does), each round beside one run of the
    yardsticks on n samples (:func:`_yardsticks`) and one fill of new arrays of the size
    of the synthesis's outputs (:func:`_first_touch`), or a string saying why it was
    skipped. Single thread: every kernel is a serial numba loop."""
    try:
        from sinslab.sim import imu as imu_mod
        gen, errors = synthesis_case(1000)
        imu_mod.apply(gen().imu, errors, 0)                               # warm-up compile
    except (ImportError, AttributeError) as e:
        return f"skipped: trajectory/imu not importable yet ({type(e).__name__}: {e})"
    gen, errors = synthesis_case(n)
    g = gen()
    arrays = _new_arrays(g, imu_mod.apply(g.imu, errors, 0))
    shapes = [a.shape for a in arrays]
    dth, dvl = test_data(n)
    rates = {"generate": [], "apply": [], "both": [], "reference": [], "c_reference": [], "first_touch": [],
             "compute": []}
    for _ in range(repeat):
        r, c = _yardsticks(ref, c_nav, dth, dvl, 0.01)
        rates["reference"].append(r)
        if c is not None:
            rates["c_reference"].append(c)
        rates["generate"].append(n / _cpu(gen))
        rates["apply"].append(n / _cpu(lambda: imu_mod.apply(g.imu, errors, 0)))
        both = _cpu(lambda: imu_mod.apply(gen().imu, errors, 0))
        touch = _cpu(lambda: _first_touch(shapes))
        rates["both"].append(n / both)
        rates["first_touch"].append(n / touch)
        if both > touch:
            rates["compute"].append(n / (both - touch))
    res = {k: (max(v) if v else None) for k, v in rates.items()}
    res["bytes_per_sample"] = sum(a.nbytes for a in arrays) / n
    return res


def _madvise_hugepage():
    """Whether numpy asks for transparent huge pages on large arrays in this process (None
    if this numpy does not say)."""
    for name in ("numpy._core.multiarray", "numpy.core.multiarray"):
        try:
            mod = importlib.import_module(name)
        except ImportError:
            continue
        get = getattr(mod, "_get_madvise_hugepage", None)
        if get is not None:
            return bool(get())
    return None


def _ratios(res, prefix, rate, ref, cref):
    """``prefix_ratio`` (to the numba reference) and ``prefix_ratio_c`` (to its C port)."""
    res[f"{prefix}_ratio"] = rate / ref
    res[f"{prefix}_ratio_c"] = None if cref is None else rate / cref


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
    c_nav, c_note = load_c_reference()

    mech = bench_mechanization(ref, c_nav, n, a.repeat)
    long = bench_long_run(hours=hours, rate_hz=50.0)
    syn = bench_synthesis(ns, a.repeat, ref, c_nav)
    ref_rate, c_rate = mech["reference"], mech["c_reference"]
    res = {
        "python": sys.version.split()[0], "machine": platform.machine(),
        "cpu_count": os.cpu_count(), "reference": str(ref_path), "c_reference": c_note if c_nav else None,
        "c_reference_note": None if c_nav else c_note, "timing": "CPU time of this process, best of the rounds",
        "samples": n, "reference_samples_per_s": ref_rate, "c_reference_samples_per_s": c_rate,
        "step_samples_per_s": mech["sinslab_step"], "navigate_samples_per_s": mech["sinslab_navigate"],
        "long_run_hours": hours, "long_run_samples": long["samples"],
        "long_run_48h_50hz_s": long["full_output_s"], "long_run_1hz_output_s": long["output_1hz_s"],
        "synthesis_samples": ns, "numpy_madvise_hugepage": _madvise_hugepage(),
    }
    _ratios(res, "mechanization", mech["sinslab_step"], ref_rate, c_rate)
    _ratios(res, "navigate", mech["sinslab_navigate"], ref_rate, c_rate)
    if isinstance(syn, str):
        res["synthesis_ratio"] = res["synthesis_ratio_c"] = None
        res["synthesis_note"] = syn
    else:
        res["synthesis_case"] = {"motion": "presets.aircraft_mixed, 100 Hz", "errors": NAV_GRADE}
        res["synthesis_reference_samples_per_s"] = syn["reference"]
        res["synthesis_c_reference_samples_per_s"] = syn["c_reference"]
        for key, k in (("synthesis", "both"), ("generate", "generate"), ("apply", "apply"),
                       ("synthesis_compute", "compute")):
            res[f"{key}_samples_per_s"] = syn[k]
            if syn[k] is not None:
                _ratios(res, key, syn[k], syn["reference"], syn["c_reference"])
        res["synthesis_new_bytes_per_sample"] = syn["bytes_per_sample"]
        res["first_touch_samples_per_s"] = syn["first_touch"]
    res["targets"] = TARGETS

    def ratio(key):
        r, c = res.get(f"{key}_ratio"), res.get(f"{key}_ratio_c")
        return f"{r:.2f}" + ("" if c is None else f" / {c:.2f}")

    rows = [("reference kernel (numba / C -O2)", f"{ref_rate / 1e6:.2f} / " + (f"{c_rate / 1e6:.2f}" if c_rate else "-")
             + " M samples/s", "", ""),
            ("strapdown.step (nsub=2)", f"{mech['sinslab_step'] / 1e6:8.2f} M samples/s", ratio("mechanization"),
             f">= {TARGETS['mechanization_ratio_c']} of C"),
            ("strapdown.navigate (full output)", f"{mech['sinslab_navigate'] / 1e6:8.2f} M samples/s",
             ratio("navigate"), ""),
            (f"{hours:g} h @ 50 Hz navigate, full output", f"{long['full_output_s']:8.2f} s", "",
             "< 5 s" if hours == 48.0 else ""),
            (f"{hours:g} h @ 50 Hz navigate, 1 Hz output", f"{long['output_1hz_s']:8.2f} s", "", "")]
    if isinstance(syn, str):
        rows.append(("synthesis (generate + apply)", syn, "", ""))
    else:
        rows += [("trajectory.generate (aircraft_mixed)", f"{syn['generate'] / 1e6:8.2f} M samples/s",
                  ratio("generate"), ""),
                 ("imu.apply (bias + ARW + VRW)", f"{syn['apply'] / 1e6:8.2f} M samples/s", ratio("apply"), ""),
                 ("synthesis (generate + apply)", f"{syn['both'] / 1e6:8.2f} M samples/s", ratio("synthesis"),
                  f">= {TARGETS['synthesis_ratio_c']} of C"),
                 (f"  first touch of its {syn['bytes_per_sample']:.0f} B/sample of new arrays",
                  f"{syn['first_touch'] / 1e6:8.2f} M samples/s", "", ""),
                 ("  synthesis less the first touch (estimate)",
                  "-" if syn["compute"] is None else f"{syn['compute'] / 1e6:8.2f} M samples/s",
                  "" if syn["compute"] is None else ratio("synthesis_compute"), "")]
    w = max(len(r[0]) for r in rows)
    print(f"{'benchmark (CPU time)':<{w}}  {'measured':>24}  {'ratio (numba / C)':>17}  target")
    for name, val, rt, tgt in rows:
        print(f"{name:<{w}}  {val:>24}  {rt:>17}  {tgt}")
    if c_nav is None:
        print(f"no C port: {c_note}")
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(res, indent=2) + "\n")
    tmp.replace(out)
    print(f"wrote {out}")
    return res


if __name__ == "__main__":
    main()
