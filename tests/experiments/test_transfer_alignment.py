"""The transfer-alignment experiment (paper 002) on a --quick run, and the
``sinslab transfer-align`` command on the recorded MEMS/FOG car data (result, consistency
across methods and windows, bad input exit 2)."""
from pathlib import Path

import numpy as np
import pytest

from sinslab.app.config import resolve
from sinslab.experiments import execute, get

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "psins-transfer" / "transfer_align_fog_mems.mat"
KINDS = ("euler", "dcm", "kain", "optimal")


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    exp = get("transfer-alignment")
    cfg = resolve(exp.config, quick=exp.quick)
    out = tmp_path_factory.mktemp("ta") / "run"
    return execute(exp, cfg, out, quick=True, scheduler="sync"), out


def test_defaults_are_the_paper_scenario():
    cfg = get("transfer-alignment").config()
    assert cfg.runs == 200
    assert cfg.installation.large.text == "[10, 60, 8] deg"
    assert cfg.installation.error.text == "[40, 30, 20] arcmin"
    assert cfg.imu.gyro_bias.text == "3.3 deg/h" and cfg.imu.accel_scale.text == "500 ppm"


def test_quick_run_contract_and_claims(quick_run):
    summary, out = quick_run
    m = summary["metrics"]
    for k in KINDS:
        for c in ("large", "small"):
            for name in ("misalign_rms_end_arcmin", "misalign_sigma_end_arcmin", "misalign_rms_5s_arcmin"):
                assert len(m[f"{name}_{k}_{c}"]) == 3
            assert isinstance(m[f"converged_{k}_{c}"], bool)
        assert m[f"update_cost_us_{k}"] > 0
    for k in ("dcm_heading_rms_c22zero_arcmin", "dcm_phiU_H_norm_c22zero", "h_fd_max_rel_err", "runs"):
        assert k in m
    claims = {c["id"]: c for c in summary["claims"]}
    for cid in ("large_method_4_converges", "small_all_converge", "c22_phiU_column_zero", "h_fd",
                "compensation_fixes_1_3", "large_methods_1_3_fail"):
        assert claims[cid]["passed"], claims[cid]
    # the numbers behind the claims: the optimal form's large-installation error is within
    # 3 σ, the uncompensated Euler/DCM forms are off by tens of arcmin
    rms, sig = np.array(m["misalign_rms_end_arcmin_optimal_large"]), np.array(m["misalign_sigma_end_arcmin_optimal_large"])
    assert np.all(rms <= 3 * sig)
    assert max(m["misalign_rms_end_arcmin_euler_large"]) > 10 and max(m["misalign_rms_end_arcmin_dcm_large"]) > 10
    assert m["dcm_heading_rms_c22zero_arcmin"] > 2 * m["kain_heading_rms_c22zero_arcmin"]
    assert (out / "misalign_large.png").exists() and (out / "c22_zero.png").exists()


def test_same_seed_same_numbers(tmp_path):
    exp = get("transfer-alignment")
    cfg = resolve(exp.config, quick=exp.quick, sets=["runs=3", "scenario.duration=6 s"])
    a = execute(exp, cfg, tmp_path / "a", quick=True, scheduler="sync")["metrics"]
    b = execute(exp, cfg, tmp_path / "b", quick=True, scheduler="sync")["metrics"]
    for k in a:
        if k.startswith("misalign") or k.startswith("dcm_heading"):
            assert np.array_equal(np.asarray(a[k], float), np.asarray(b[k], float), equal_nan=True), k


# ------------------------------------------------------------------ recorded data ----
needs_data = pytest.mark.skipif(not DATA.exists(), reason="recorded transfer-alignment data not present")


@needs_data
def test_real_data_mounting_and_biases(tmp_path):
    """Mounting angles and gyro biases against the file's reference (mu0 [rad], eb0 [rad/s]),
    the same result from every attitude form and from a 60 s window."""
    from sinslab.app.commands.transfer_align import transfer_align_file
    from sinslab.core import units

    summary, res, refs = transfer_align_file(DATA, DATA, methods=KINDS, windows=(None, (0.0, 60.0)),
                                             out=tmp_path / "run", echo=lambda s: None)
    mu0, eb0 = refs["mu0"], refs["eb0"]
    assert np.all(np.abs(mu0) < 0.01) and 1e-4 < np.max(np.abs(eb0)) < 2e-3      # rad, rad/s
    for (m, w), r in res.items():
        assert np.all(np.abs(r.mounting - mu0) <= 3 * r.mounting_sigma + 0.5 * units.arcmin), (m, w)
        assert np.all(np.abs(r.gyro_bias - eb0) <= 3 * r.gyro_bias_sigma), (m, w)
    full = [res[(m, "all")].mounting for m in KINDS]
    assert np.max(np.ptp(full, axis=0)) < 0.1 * units.arcmin          # forms agree (small mounting)
    win = res[("optimal", "0_60s")]
    assert win.t[0] == pytest.approx(0.1) and win.t[-1] == pytest.approx(60.0)   # master epochs in the window
    assert res[("optimal", "all")].t[-1] == pytest.approx(100.0)
    assert np.all(np.abs(win.mounting - res[("optimal", "all")].mounting) <= 2 * win.mounting_sigma)
    assert (tmp_path / "run" / "summary.json").exists()


def _cli(args):
    from typer.testing import CliRunner
    from sinslab.cli import app
    return CliRunner().invoke(app, args)


@needs_data
def test_bad_input_exit_2(tmp_path):
    import scipy.io
    d = scipy.io.loadmat(DATA)
    m = tmp_path / "master_late.mat"
    late = d["fogavp"].copy()
    late[:, 9] += 1000.0
    scipy.io.savemat(m, {"fogavp": late})
    r = _cli(["transfer-align", "--slave", str(DATA), "--master", str(m), "--out", str(tmp_path / "o1")])
    assert r.exit_code == 2 and "do not overlap" in r.output
    odd = d["fogavp"][::1].copy()
    odd[:, 9] = 0.1 + np.arange(odd.shape[0]) * 0.015
    m2 = tmp_path / "master_odd.mat"
    scipy.io.savemat(m2, {"fogavp": odd})
    r = _cli(["transfer-align", "--slave", str(DATA), "--master", str(m2), "--out", str(tmp_path / "o2")])
    assert r.exit_code == 2 and "not a multiple" in r.output
    r = _cli(["transfer-align", "--slave", str(DATA), "--master", str(DATA), "--mount", "[10, 60, 8]",
              "--out", str(tmp_path / "o3")])
    assert r.exit_code == 2 and "--mount" in r.output and "no unit" in r.output
    m4 = tmp_path / "nothing.mat"
    scipy.io.savemat(m4, {"other": np.zeros((3, 3))})
    r = _cli(["transfer-align", "--slave", str(DATA), "--master", str(m4), "--out", str(tmp_path / "o4")])
    assert r.exit_code == 2 and "lacks the master solution" in r.output
    r = _cli(["transfer-align", "--slave", str(m4), "--master", str(DATA), "--out", str(tmp_path / "o5")])
    assert r.exit_code == 2 and "lacks the slave IMU" in r.output
