"""Smoke tests of the benchmark scripts: each runs end to end at a small size and writes
its figures. No timing is asserted (speed figures come from the scripts themselves, as
ratios measured in one process); this only keeps the scripts from rotting when an API
they use moves, as benchmarks/schuler.py once did (schuler.nav_errors -> compare)."""
import importlib.util
import json
import os
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"

# A stand-in for ../shared/bench/reference_strapdown.py (same signature), used only when
# the real one is not next to the repository, e.g. on a bare clone.
STAND_IN = '''
import math
from numba import njit

@njit(cache=False)
def nav(dth, dvl, dt, q0, q1, q2, q3, ve, vn, vu, lat, lon, h):
    for k in range(dth.shape[0]):
        ve += dvl[k, 0]
        vn += dvl[k, 1]
        vu += dvl[k, 2] - 9.8 * dt
        q1 += 0.5 * dth[k, 0]
        q2 += 0.5 * dth[k, 1]
        q3 += 0.5 * dth[k, 2]
        n = 1.0 / math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        q0 *= n
        q1 *= n
        q2 *= n
        q3 *= n
    return q0, q1, q2, q3, ve, vn, vu, lat, lon, h
'''


def _load(name):
    spec = importlib.util.spec_from_file_location(f"bench_{name}", BENCH / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_speed_script(tmp_path, monkeypatch):
    mod = _load("speed")
    if not Path(os.environ.get("SINSLAB_REFERENCE", mod.DEFAULT_REFERENCE)).is_file():
        ref = tmp_path / "reference_strapdown.py"
        ref.write_text(STAND_IN)
        monkeypatch.setenv("SINSLAB_REFERENCE", str(ref))
    out = tmp_path / "speed.json"
    res = mod.main(["--quick", "--repeat", "1", "--out", str(out)])
    saved = json.loads(out.read_text())
    for key in ("mechanization_ratio", "synthesis_ratio", "generate_ratio", "apply_ratio",
                "long_run_48h_50hz_s", "first_touch_samples_per_s"):
        assert saved[key] == pytest.approx(res[key]) and saved[key] > 0
    # what the synthesis writes per sample: truth (time, lat, lon, h, velocity, attitude)
    # at n + 1 epochs, the exact and the erroneous increments (6 + 6), 8 bytes each
    n = saved["synthesis_samples"]
    assert saved["synthesis_new_bytes_per_sample"] == (10 * (n + 1) + 12 * n) * 8 / n
    assert isinstance(saved["numpy_madvise_hugepage"], (bool, type(None)))


def test_estimation_script(tmp_path):
    out = tmp_path / "estimation.json"
    res = _load("estimation").main(["--quick", "--json", str(out)])
    saved = json.loads(out.read_text())
    assert saved["cov21_steps_per_s"] > 0 and "lc_missing" not in saved
    # the INS + fixes run is also a consistency check: its error matches the filter's σ
    assert 0.5 < res["lc_horiz_pos_rms_m"] / res["lc_horiz_sigma_rms_m"] < 2.0
    # the compiled model evaluation reproduces the numpy reference run in the same script
    assert res["full_rate21_max_rel_diff"] < 1e-9 and res["default15_max_rel_diff"] < 1e-9


def test_schuler_script(tmp_path):
    out = tmp_path / "schuler.json"
    res = _load("schuler").main(["--hours", "1.5", "--out", str(out)])
    saved = json.loads(out.read_text())
    assert set(saved["stages"]) == {"synthesis", "imu_errors", "method", "analysis"}
    assert saved["samples"] == res["samples"] > 0


def test_transfer_script(tmp_path):
    out = tmp_path / "transfer.json"
    res = _load("transfer").main(["--runs", "8", "--wide", "4", "--lanes", "10", "--scheduler", "sync",
                                  "--out", str(out)])
    saved = json.loads(out.read_text())
    assert saved["runs"] == res["runs"] == 8 and saved["slave_ins"] == 64 and saved["steps"] > 0
    assert saved["strapdown_cpu_s"] > 0 and saved["linear_cpu_s"] > 0 and saved["lanes_samples_per_s"] > 0
    # the mechanised closed loop: the optimal form converges on both installations, Kain's
    # uncompensated form diverges on the large one
    assert saved["converged"]["optimal_large"] and saved["converged"]["optimal_small"]
    assert saved["diverged"]["kain_large"] == 8


def test_run_folder_script(tmp_path):
    out = tmp_path / "run_folder.json"
    rows = _load("run_folder").main(["static-alignment", "--json", str(out)])
    saved = json.loads(out.read_text())
    assert [r["experiment"] for r in saved] == [r["experiment"] for r in rows] == ["static-alignment"]
    r = saved[0]
    assert r["figures"] == 2 and r["compute_s"] > 0 and r["figures_reference_s"] > 0 and r["figures_s"] > 0
    assert r["writing_s"] == r["series_s"] + r["figures_s"] + r["report_s"]


def test_readers_script(tmp_path):
    out = tmp_path / "readers.json"
    res = _load("readers").main(["--rows", "5000", "--repeat", "1", "--out", str(out)])
    saved = json.loads(out.read_text())
    assert saved["rows"] == 5000 and saved["same_samples"] and res["csv_s"] > 0 and res["parquet_s"] > 0


def test_rotins_script_filter_part():
    """benchmarks/rotins.py: the driver-vs-compiled joint filter part on 1 h (the experiment
    stage times need a full run and are the script's job)."""
    res = _load("rotins").filter_ratio(1.0)
    assert res["steps"] == 360 and 0 < res["distinct_steps"] <= res["steps"]
    assert res["driver_s"] > 0 and res["compiled_s"] > 0


def test_rotins_script_grouping_part():
    """benchmarks/rotins.py: the experiment's INS grouped by random stream against one at a
    time, on 2 h: the grouping the experiment uses (INS #2's six β, INS #1 and its trend
    version, three alone) and identical outputs."""
    res = _load("rotins").grouping(2.0, repeats=1)
    assert res["n_ins"] == 11 and res["groups"] == [6, 2, 1, 1, 1] and res["identical"]
    assert res["grouped_cpu_s"] > 0 and res["one_at_a_time_cpu_s"] > 0


def test_startup_script(tmp_path):
    out = tmp_path / "startup.json"
    res = _load("startup").main(["--repeat", "1", "--out", str(out)])
    saved = json.loads(out.read_text())
    cmds = saved["commands"]
    assert set(cmds) == set(res["commands"])
    assert {"python -c pass", "import sinslab.cli", "list", "--help", "config static-alignment"} <= set(cmds)
    ref = saved["reference_median_s"]
    for r in cmds.values():
        assert r["min_s"] <= r["median_s"] <= r["max_s"]
        assert r["above_reference_s"] == pytest.approx(r["median_s"] - ref)


def test_against_script(tmp_path):
    """The two-tree comparison runs end to end (against HEAD itself: the rows must agree)."""
    out = tmp_path / "against.json"
    res = _load("against").main(["--rev", "HEAD", "--duration", "60", "--rounds", "1", "--repeat", "1",
                                 "--states", "15", "--out", str(out)])
    assert json.loads(out.read_text()) == res
    r = res["states15"]
    assert r["cpu_this_s"] > 0 and r["last_row_diff"] == {"attitude_rad": 0.0, "velocity_mps": 0.0, "position_m": 0.0}


def test_campaigns_script(tmp_path):
    out = tmp_path / "campaigns.json"
    res = _load("campaigns").main(["--runs", "1", "--only", "free-inertial", "--out", str(out)])
    r = res["free-inertial"]
    assert json.loads(out.read_text()) == res
    assert r["cpu_per_run_s"] > 0 and r["compiled_per_run_s"] > 0 and r["other_per_run_s"] >= 0
    assert r["compiled_share"] == pytest.approx(
        r["compiled_per_run_s"] / (r["compiled_per_run_s"] + r["other_per_run_s"]))
    # free-inertial is mostly compiled navigation and noise synthesis
    assert r["compiled_share"] > 0.5
    assert r["speedup"] == pytest.approx(r["cpu_per_run_one_at_a_time_s"] / r["cpu_per_run_s"])


def test_tightly_coupled_script(tmp_path):
    out = tmp_path / "tc.json"
    res = _load("tightly_coupled").main(["--quick", "--out", str(out)])
    saved = json.loads(out.read_text())
    assert saved["tc_cpu_s"] > 0 and saved["lc_cpu_s"] > 0 and saved["satellites_min"] >= 4
    # raw observations of 12+ satellites at 1 Hz do at least as well as 3 m fixes
    assert res["tc_hz_err_rms_m"] < res["lc_hz_err_rms_m"]


def test_full_rate_script(tmp_path):
    """benchmarks/full_rate.py on a 30 s drive: KF-GINS' model (21 states, 18 noises), its
    compiled path equal to the numpy reference, a profile of every stage, the saved-output
    comparison of a run against itself."""
    mod = _load("full_rate")
    saved = tmp_path / "out.npz"
    res = mod.main(["--duration", "30", "--rounds", "1", "--save", str(saved), "--compare", str(saved),
                    "--json", str(tmp_path / "full_rate.json")])
    assert res["epochs"] == 6000 and res["epochs_per_cpu_s"] > 0
    assert res["max_rel_diff_vs_numpy"] < 1e-9 and res["max_rel_diff_vs_saved"] == 0.0
    assert all(v > 0 for v in res["profile_us"].values())


def test_kfgins_process_reads_kfgins_files_and_writes_every_epoch(tmp_path):
    """sinslab's side of the whole-process comparison (benchmarks/kfgins_process.py) on a
    30 s drive written in KF-GINS' formats by full_rate.py: it reads the YAML configuration
    and the text files KF-GINS reads and writes the solution of every IMU epoch, which
    ends where the in-process filter of the same drive ends (the text files round the
    increments to 13 digits)."""
    import subprocess
    import sys

    import numpy as np

    fr = _load("full_rate")
    sc = fr.scenario(30.0)
    cfg = fr._kfgins_inputs(sc, str(tmp_path))
    p = subprocess.run([sys.executable, str(BENCH / "kfgins_process.py"), cfg, "--stages"], capture_output=True,
                       text=True, env=dict(os.environ, SINSLAB_QUIET="1"))
    assert p.returncode == 0, p.stderr
    lines = dict(ln.split(" ", 1) for ln in p.stdout.splitlines() if ln.startswith(("STAGES ", "SINSLAB ")))
    stages = dict(x.split("=") for x in lines["STAGES"].split())
    assert set(stages) == {"start-up_and_imports", "reading", "filter", "writing"}
    import sinslab
    assert os.path.samefile(lines["SINSLAB"], os.path.dirname(sinslab.__file__))   # the sinslab under test
    sol = np.load(tmp_path / "sinslab_solution.npy")
    assert sol.shape == (6001, 43) and np.all(np.isfinite(sol))
    res = fr._filter(sc, sc[0])
    assert abs(sol[-1, 1] - res.nav[-1, 7]) * 6.4e6 < 0.05 and abs(sol[-1, 2] - res.nav[-1, 8]) * 5.4e6 < 0.05


def test_navigate_cost_script(tmp_path):
    res = _load("navigate_cost").main(["--minutes", "1.5", "--rounds", "1", "--json", str(tmp_path / "n.json")])
    r = res["this"]["1.5min"]
    assert r["samples"] == 18000 and r["maxrss_mb"] > 0
    assert r["total"] == pytest.approx(r["startup"] + r["reading"] + r["compute"] + r["rest"])


def test_navigate_memory_script(tmp_path):
    res = _load("navigate_memory").main(["--minutes", "0.75", "--rounds", "1", "--json", str(tmp_path / "m.json")])
    r = res["this"]
    assert [s["stage"] for s in r["stages"]] == ["interpreter", "numpy", "cli", "parse", "reading", "filter",
                                                 "after filter", "tables", "figures", "report"]
    assert r["peak"] >= max(s["rss"] for s in r["stages"]) > 0
    assert r["stages"][5]["kernels"] > 0 and "numba" in r["imports"]
    assert json.loads((tmp_path / "m.json").read_text())["this"]["peak"] == r["peak"]


def test_workers_script():
    """benchmarks/workers.py: Dask's default worker environment and sinslab's give the same
    results (to the last bits: an allocator setting can move an array's alignment and with
    it BLAS's kernel path)."""
    res = _load("workers").main(["--runs", "8", "--rounds", "1"])
    assert res["max_rel_diff"] < 1e-9 and res["sinslab_worker_cpu_s"] > 0


def test_compile_cost_script(tmp_path):
    """benchmarks/compile_cost.py on one experiment: the first round compiles on an empty
    cache, the second loads what it wrote (it compiles nothing), and no kernel is compiled
    for two signatures."""
    res = _load("compile_cost").main(["--only", "free-inertial", "--out", str(tmp_path / "c.json")])
    r = res["experiments"]["free-inertial"]
    assert r["kernels_compiled"] > 0 and r["compile_cpu_s"] > 0 and r["cpu_fresh_s"] > 0
    assert r["kernels_compiled_warm"] == 0
    assert res["multi_signature"] == {}


def test_demo_script_parts(tmp_path):
    """benchmarks/demo.py (minutes: ``make demo`` on a fresh clone, not run here): its timer
    counts the CPU of the whole process tree, not only of the child it starts, and it reads
    the runs' compute times (and their robustness re-runs') and the cached kernels of a tree."""
    mod = _load("demo")
    burn = "import time\nt = time.process_time()\nwhile time.process_time() - t < 0.3: pass\n"
    cmd = [os.sys.executable, "-c",
           f"import subprocess, sys\nsubprocess.run([sys.executable, '-c', {burn!r}], check=True)"]
    r = mod._timed(cmd, tmp_path, dict(os.environ), tmp_path / "log")
    assert r["cpu_s"] >= 0.3 and r["wall_s"] >= 0.3           # the grandchild's CPU is counted
    (tmp_path / "runs" / "a").mkdir(parents=True)
    (tmp_path / "runs" / "a" / "summary.json").write_text(json.dumps({"metrics": {"runtime_s": 1.234}}))
    (tmp_path / "runs" / "b").mkdir()
    (tmp_path / "runs" / "b" / "summary.json").write_text(json.dumps({"metrics": {"runtime_s": 2.0},
                                                                      "robustness": {"wall_s": 3.456}}))
    assert mod._runs(tmp_path / "runs") == ({"a": 1.23, "b": 2.0}, {"a": 0.0, "b": 3.46})
    # the timeline: start stamp after t0, and the end after the run's stages
    for name, started, timing in (("a", "2026-01-01T00:00:10+00:00", {"compute_s": 2.0, "figures_s": 0.5}),
                                  ("b", "2026-01-01T00:00:04+00:00", {"compute_s": 1.0, "robustness_s": 3.0})):
        f = tmp_path / "runs" / name / "summary.json"
        f.write_text(json.dumps({**json.loads(f.read_text()), "started": started, "timing": timing}))
    t0 = 1767225600.0                                        # 2026-01-01T00:00:00Z
    assert list(mod._timeline(tmp_path / "runs", t0).items()) == [("b", [4.0, 8.0]), ("a", [10.0, 12.5])]
    (tmp_path / "src" / "p" / "__pycache__").mkdir(parents=True)
    assert mod._cached_kernels(tmp_path) == 0
    (tmp_path / "src" / "p" / "__pycache__" / "k-1.py311.nbi").touch()
    assert mod._cached_kernels(tmp_path) == 1


def test_demo_script_prints_and_saves_what_it_measured(tmp_path, monkeypatch, capsys):
    """benchmarks/demo.py's report of a measurement (the minutes of measuring stubbed): every
    run's line and its timeline printed, the figures saved to ``--out`` as measured."""
    mod = _load("demo")
    fresh = {"wall_s": 100.0, "cpu_s": 190.0, "load_avg_before": [0.5, 0.5, 0.5], "load_avg_after": [2.0, 1.0, 0.5],
             "kernels_cached_before": 83, "kernels_cached_after": 83, "runs": {"a": 1.5},
             "robustness_s": {"a": 0.25}, "timeline_s": {"a": [1.0, 3.0]}}
    res = {"commit": "abc", "install": {"wall_s": 90.0, "cpu_s": 120.0}, "compile": {"wall_s": 50.0, "kernels": 70},
           "fresh": fresh, "compile_and_demo_wall_s": 150.0, "install_and_demo_wall_s": 190.0,
           "install_and_demo_cpu_s": 310.0}
    monkeypatch.setattr(mod, "measure", lambda warm, keep, py: res)
    out = tmp_path / "demo.json"
    assert mod.main(["--out", str(out)]) == res
    text = capsys.readouterr().out
    assert "100.0 s wall, 190.0 s CPU" in text and "1.50 s, robustness re-runs   0.25 s" in text
    assert "1.0 ..    3.0" in text
    assert json.loads(out.read_text()) == res


def test_linear_batch_script(tmp_path):
    out = tmp_path / "linear_batch.json"
    res = _load("linear_batch").main(["--repeat", "1", "--out", str(out)])
    saved = json.loads(out.read_text())
    for case in ("small", "ins"):
        assert saved[case]["task_cpu_s"] > 0 and saved[case]["numpy_cpu_s"] > 0
        # the task and its textbook numpy form are the same filter: they agree to rounding
        assert max(res[case]["max_rel_diff"].values()) < 1e-6


def test_graph_script_parts():
    """benchmarks/graph.py: a free integration of its frame section (10 s) and the urban
    drive's fixes (jumps, biased stretches) run on the current API."""
    pytest.importorskip("gtsam", reason="gtsam (sinslab[graph]) is not installable here")
    import gtsam

    from sinslab.fusion.graph.frame import LocalFrame
    G = _load("graph")
    B = G._bench_smoother()
    g = B._trajectory()
    tru = g.truth
    row = G._free_graph(gtsam, g, LocalFrame(tru.lat[0], tru.lon[0], tru.h[0]), tru.t[0] + 10.0, "sinslab")
    assert G._pos_err(row, tru, 1000) < 0.01
    d, kw = G._urban_fixes(B, 1)
    assert kw["pos"].shape == (kw["t"].size, 3) and d["imu"] is not None


def test_outage_entry_no_worse_rule(tmp_path, monkeypatch):
    """benchmarks/outage_entry.py's verdict per outage (paired over IMU seeds): d̄ and its
    standard error ``std(d, ddof=1)/√N`` in closed form, and the rule's three cases: no
    worse when d̄ ≤ 0; when d̄ ≤ 2 SE and ≤ 5 % of the reference's mean; worse past either.
    Without NaveGo's files the script says so and exits 0; one seed is refused (status 2)."""
    mod = _load("outage_entry")
    ref = [10.0, 10.0, 10.0, 10.0]
    v = mod.paired_verdict([9.0, 10.5, 9.5, 10.2], ref)            # d = −1, 0.5, −0.5, 0.2: d̄ = −0.2
    assert v["diff_mean"] == pytest.approx(-0.2)
    assert v["diff_se"] == pytest.approx(float(np.std([-1, 0.5, -0.5, 0.2], ddof=1)) / 2)
    assert v["verdict"] == "no worse" and v["ref_mean"] == 10.0
    # d̄ = 0.4 ≤ 5 % of 10, SE = 0.346: within 2 SE
    assert mod.paired_verdict([9.8, 11.0, 9.8, 11.0], ref)["verdict"] == "no worse"
    # d̄ = 0.6 > 5 % of 10 although within 2 SE (0.346): worse
    assert mod.paired_verdict([10.0, 11.2, 10.0, 11.2], ref)["verdict"] == "worse"
    # d̄ = 0.4 ≤ 5 % but 0.4 > 2 SE (2 × 0.0577): worse
    assert mod.paired_verdict([10.3, 10.5, 10.3, 10.5], ref)["verdict"] == "worse"
    monkeypatch.delenv("NAVEGO_REAL_DATA", raising=False)
    out = tmp_path / "f.json"
    assert mod.main(["--out", str(out)]) == 0 and "skipped" in json.loads(out.read_text())
    assert mod.main(["--seeds", "1"]) == 2


def test_noise_shared_script(tmp_path):
    out = tmp_path / "noise_shared.json"
    res = _load("noise_shared").main(["--samples", "2000", "--repeat", "1", "--out", str(out)])
    assert [c["models"] for c in json.loads(out.read_text())["cases"]] == [1, 2, 7]
    assert all(c["identical"] and c["ratio"] > 0 for c in res["cases"])
