"""``sinslab compile`` run again with nothing changed: the stamp of the last compile is
believed only while every input of the compiled kernels is as it was (the package's source
files, numba, Python, the CPU) and every kernel cache file it left is still there; else it
compiles. Kernels compiled since, for other calls, change nothing."""
import json

from pathlib import Path

import pytest

from sinslab import precompile as pc


@pytest.fixture
def package(tmp_path, monkeypatch):
    """A stand-in package folder with one module and one kernel index, and no other cache."""
    pkg = tmp_path / "sinslab"
    (pkg / "__pycache__").mkdir(parents=True)
    (pkg / "a.py").write_text("x = 1\n")
    (pkg / "__pycache__" / "a.k-3.py311.nbi").write_bytes(b"index")
    (pkg / "__pycache__" / "a.k-3.py311.1.nbc").write_bytes(b"kernel")
    monkeypatch.setattr(pc, "_package", lambda: pkg)
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    calls = []
    monkeypatch.setattr(pc, "precompile", lambda jobs, env=None: calls.append(jobs) or {
        "kernels": 5, "commands": ["navigate"] * 3})
    return pkg, calls


def test_second_compile_with_nothing_changed_returns_at_once(package, capsys):
    pkg, calls = package
    assert pc.up_to_date() is None                         # never compiled: no stamp
    assert pc.main([]) == 0 and calls == [2]
    stamp = json.loads((pkg / "__pycache__" / "sinslab-compiled.json").read_text())
    assert stamp["kernels"] == 5 and sorted(Path(f).name for f in stamp["files"]) == [
        "a.k-3.py311.1.nbc", "a.k-3.py311.nbi"]
    assert pc.main([]) == 0 and calls == [2]               # up to date: not compiled again
    assert "kernels up to date" in capsys.readouterr().out
    assert pc.main(["--force"]) == 0 and calls == [2, 2]


@pytest.mark.parametrize("change", ["source edited", "source added", "kernel deleted", "index deleted",
                                    "cache cleared", "other numba", "other CPU"])
def test_any_changed_input_compiles_again(package, change, monkeypatch):
    pkg, calls = package
    assert pc.main([]) == 0 and pc.up_to_date() is not None
    idx = pkg / "__pycache__" / "a.k-3.py311.nbi"
    if change == "source edited":
        (pkg / "a.py").write_text("x = 2\n")
    elif change == "source added":
        (pkg / "b.py").write_text("")
    elif change == "kernel deleted":
        (pkg / "__pycache__" / "a.k-3.py311.1.nbc").unlink()
    elif change == "index deleted":
        idx.unlink()
    elif change == "cache cleared":
        for p in (pkg / "__pycache__").glob("*.nb?"):
            p.unlink()
    elif change == "other numba":
        import numba
        monkeypatch.setattr(numba, "__version__", "0.0.1")
    else:
        monkeypatch.setenv("NUMBA_CPU_NAME", "generic")
    assert pc.up_to_date() is None
    assert pc.main([]) == 0 and calls == [2, 2]


def test_kernels_compiled_since_leave_the_stamp_true(package):
    pkg, calls = package
    assert pc.main([]) == 0
    (pkg / "__pycache__" / "a.k-3.py311.nbi").write_bytes(b"index with a second signature")
    (pkg / "__pycache__" / "a.k-3.py311.2.nbc").write_bytes(b"kernel")
    (pkg / "__pycache__" / "a.j-9.py311.nbi").write_bytes(b"index")
    assert pc.up_to_date() is not None and pc.main([]) == 0 and calls == [2]


def test_portable_compile_leaves_no_stamp_and_always_compiles(package):
    pkg, calls = package
    assert pc.main(["--portable"]) == 0 and pc.main(["--portable"]) == 0 and len(calls) == 2
    assert not (pkg / "__pycache__" / "sinslab-compiled.json").exists()


def test_read_only_package_keeps_its_stamp_in_the_user_cache(package, tmp_path, monkeypatch):
    pkg, calls = package
    monkeypatch.setattr(pc.os, "access", lambda p, mode: False)
    assert pc.main([]) == 0 and pc.main([]) == 0 and calls == [2]
    assert list((tmp_path / "cache" / "sinslab").glob("compiled-*.json"))


def test_compile_runs_every_run_of_the_demo(tmp_path):
    """The experiments' commands of ``sinslab compile`` are the runs ``sinslab demo`` makes,
    variants included (a variant may reach a kernel of its own: the turntable's mount), each
    at its quick scale. Only the package's own experiments: other test files register theirs
    in the same process, and the compile runs whatever is registered."""
    import sinslab.experiments as E

    own = [e for e in E.registry().values() if e.module.startswith("sinslab.experiments.")]
    assert len(own) >= 7
    names = {e.name for e in own}
    cmds = [c for c in pc._commands("experiments", tmp_path) if c[1] in names]
    want = {(e.name, tuple(a for kv in sets for a in ("--set", kv)))
            for e in own for sets in [()] + list(e.variants.values())}
    got = {(c[1], tuple(c[3:c.index("--workers")] if "--workers" in c else c[3:])) for c in cmds}
    assert all(c[0] == "run" and c[2] == "--quick" for c in cmds)
    assert want <= got and len(cmds) == len(want)
    assert ("schuler-suppression", ("--set", "scenario.kind=turntable")) in got
