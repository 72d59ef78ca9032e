"""The package as a user installs it: a source distribution and a wheel built from a clean
copy of the tracked files, the wheel installed into a fresh virtual environment with no
source tree beside it, and the command line run from there.

The fresh environment gets sinslab from the wheel alone. Its dependencies are the test
environment's installed packages, reached through a folder of links to each of them that
leaves out sinslab's own editable install (its path entry and its metadata), so nothing
is downloaded and the source tree cannot stand in for a file the wheel lacks.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import tarfile
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
pytest.importorskip("build", reason="the wheel test builds with the dev extra's `build`")


def _tracked_files() -> list[str]:
    """The files git tracks (the clean copy a release is built from), with the files of the
    working tree not yet committed."""
    r = subprocess.run(["git", "ls-files", "-co", "--exclude-standard"], cwd=ROOT,
                       capture_output=True, text=True)
    if r.returncode:
        pytest.skip("not a git checkout: no list of tracked files to build from")
    return [f for f in r.stdout.splitlines() if (ROOT / f).is_file()]


def _clean_copy(dest: Path) -> Path:
    for f in _tracked_files():
        if f.startswith(("src/", "tools/")) or "/" not in f:
            (dest / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / f, dest / f)
    return dest


def _dependencies_folder(dest: Path) -> Path:
    """Links to every package of the test environment but sinslab itself."""
    site = Path(sysconfig.get_paths()["purelib"])
    dest.mkdir()
    for entry in site.iterdir():
        name = entry.name.lower()
        if name.startswith(("sinslab", "__editable__", "_sinslab")) or name.endswith(".pth"):
            continue
        (dest / entry.name).symlink_to(entry)
    return dest


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """``(venv bin folder, work folder, env, dist folder)`` of the wheel installed fresh."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = _clean_copy(tmp / "source")
    dist = tmp / "dist"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    # the kernels then compile on first use, as numba does; building them into the wheel
    # would take minutes
    env["SINSLAB_BUILD_KERNELS"] = "0"
    r = subprocess.run([sys.executable, "-m", "build", "--no-isolation", "--outdir", str(dist), str(src)],
                       capture_output=True, text=True, env=env, cwd=tmp)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    py = venv / "bin" / "python"
    wheel = next(dist.glob("sinslab-*.whl"))
    r = subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps",
                        "--no-index", "-q", str(wheel)], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr[-3000:]
    deps = _dependencies_folder(tmp / "deps")
    site = Path(subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               capture_output=True, text=True, check=True).stdout.strip())
    (site / "zz_test_dependencies.pth").write_text(f"{deps}\n")
    work = tmp / "work"
    work.mkdir()
    env["MPLBACKEND"] = "Agg"
    env["SINSLAB_QUIET"] = "1"
    return venv / "bin", work, env, dist


def _run(installed, *args, timeout=600):
    bin_, work, env, _ = installed
    return subprocess.run([*args], cwd=work, env=env, capture_output=True, text=True, timeout=timeout)


def test_distributions_carry_the_licence_and_the_changelog(installed):
    dist = installed[3]
    sdist = next(dist.glob("sinslab-*.tar.gz"))
    with tarfile.open(sdist) as tf:
        names = {n.split("/", 1)[1] for n in tf.getnames() if "/" in n}
    assert {"LICENSE", "CHANGELOG.md", "README.md", "pyproject.toml", "src/sinslab/py.typed",
            "src/sinslab/app/fonts/cjk-subset.otf"} <= names
    wheel = next(dist.glob("sinslab-*.whl"))
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
        meta = zf.read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    assert {"sinslab/py.typed", "sinslab/__main__.py", "sinslab/app/fonts/cjk-subset.otf"} <= names
    from sinslab import __version__

    assert f"\nVersion: {__version__}\n" in meta
    assert "License-Expression: MIT" in meta and "Project-URL: Repository, " in meta
    assert "Classifier: Typing :: Typed" in meta and "Keywords: " in meta


def test_installed_command_line_runs_from_the_wheel(installed, tmp_path):
    bin_, work, env, _ = installed
    r = _run(installed, str(bin_ / "python"), "-c",
             "import sinslab, sys; print(sinslab.__file__); print('\\n'.join(sys.path))")
    assert r.returncode == 0, r.stderr
    where, *path = r.stdout.splitlines()
    assert Path(where).is_relative_to(bin_.parent), where          # the wheel's copy, not the tree
    assert not any(p and Path(p).resolve().is_relative_to(ROOT) for p in path), path

    r = _run(installed, str(bin_ / "sinslab"), "--version")
    assert r.returncode == 0, r.stderr
    from sinslab import __version__

    assert r.stdout.startswith(f"sinslab {__version__} (numpy ") and "numba " in r.stdout

    r = _run(installed, str(bin_ / "python"), "-m", "sinslab", "list")
    assert r.returncode == 0, r.stderr
    assert "static-alignment" in r.stdout and "warning" not in r.stderr, r.stderr

    out = work / "fi"
    r = _run(installed, str(bin_ / "sinslab"), "run", "free-inertial", "--quick", "--out", str(out))
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert (out / "report.html").is_file() and (out / "summary.json").is_file()
    assert "claims passed" in r.stdout
