"""`sinslab run --workers N`: 0 runs the campaign in this process with the same numbers as
a run on an explicit serial scheduler; contradictions and a useless option are refused in
one line with exit status 2."""
import json

from typer.testing import CliRunner

from sinslab.cli import app


def _run(tmp_path, name, *extra):
    return CliRunner().invoke(app, ["-q", "run", "free-inertial", "--quick", "--runs", "2",
                                    "--out", str(tmp_path / name), *extra])


def test_workers_zero_is_serial(tmp_path):
    a = _run(tmp_path, "w0", "--workers", "0")
    b = _run(tmp_path, "sync", "--scheduler", "sync")
    assert a.exit_code == 0 and b.exit_code == 0, a.output + b.output
    ma = json.loads((tmp_path / "w0" / "summary.json").read_text())["metrics"]
    mb = json.loads((tmp_path / "sync" / "summary.json").read_text())["metrics"]
    drop = lambda m: {k: v for k, v in m.items() if "time" not in k and not k.endswith("_s")}  # noqa: E731
    assert drop(ma) == drop(mb)


def test_refusals(tmp_path):
    r = _run(tmp_path, "both", "--workers", "2", "--scheduler", "tcp://127.0.0.1:1")
    assert r.exit_code == 2 and "--workers" in r.output and len(r.output.strip().splitlines()) == 1, r.output
    r = CliRunner().invoke(app, ["-q", "run", "static-alignment", "--quick", "--workers", "2",
                                 "--out", str(tmp_path / "sa")])
    assert r.exit_code == 2 and "no Monte Carlo campaign" in r.output, r.output
    assert not (tmp_path / "sa").exists()
