"""The typed public API: the type checker (mypy, pinned in the dev extra) finds no error in
the modules mypy.ini lists, and every public function and method of those modules is
annotated (its parameters and its return).

mypy.ini holds the list (``files``): the modules the README's tour and the docs name,
grown module by module. ``python -m mypy`` in the repository runs the same check.
"""
from __future__ import annotations

import ast
import configparser
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
mypy_api = pytest.importorskip("mypy.api", reason="mypy comes with the dev extra")


def checked_files() -> list[Path]:
    """The Python files of mypy.ini's ``files`` (folders expanded)."""
    cfg = configparser.ConfigParser()
    cfg.read(ROOT / "mypy.ini")
    out: list[Path] = []
    for item in cfg["mypy"]["files"].split(","):
        p = ROOT / item.strip()
        out.extend(sorted(p.rglob("*.py")) if p.is_dir() else [p])
    return out


def _annotated(fn: ast.FunctionDef | ast.AsyncFunctionDef, method: bool) -> bool:
    a = fn.args
    params = a.posonlyargs + a.args + a.kwonlyargs
    static = any(isinstance(d, ast.Name) and d.id == "staticmethod" for d in fn.decorator_list)
    if method and params and not static:
        params = params[1:]                     # self / cls
    ok = all(p.annotation is not None for p in params)
    ok &= all(v.annotation is not None for v in (a.vararg, a.kwarg) if v is not None)
    return ok and (fn.returns is not None or fn.name == "__init__")


def public_functions(path: Path) -> list[tuple[str, bool]]:
    """``[(qualified name, fully annotated)]`` of the public functions of a module and the
    public methods (``__init__`` and ``__call__`` included) of its public classes."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    mod = ".".join(path.relative_to(SRC).with_suffix("").parts)
    out = []
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not node.name.startswith("_"):
            out.append((f"{mod}.{node.name}", _annotated(node, False)))
        elif isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
            for m in node.body:
                if isinstance(m, (ast.FunctionDef, ast.AsyncFunctionDef)) and \
                        (not m.name.startswith("_") or m.name in ("__init__", "__call__")):
                    out.append((f"{mod}.{node.name}.{m.name}", _annotated(m, True)))
    return out


def test_checked_modules_exist_and_ship_py_typed():
    files = checked_files()
    assert files and all(f.is_file() for f in files)
    assert (SRC / "sinslab" / "py.typed").is_file()


def test_public_functions_of_checked_modules_are_annotated():
    missing = [name for f in checked_files() for name, ok in public_functions(f) if not ok]
    assert not missing, "public functions without full annotations:\n" + "\n".join(missing)


def test_mypy_finds_no_error():
    out, err, status = mypy_api.run(["--config-file", str(ROOT / "mypy.ini"),
                                     "--cache-dir", str(ROOT / ".mypy_cache")])
    assert status == 0, out + err


def annotated_share(paths: list[Path]) -> tuple[int, int]:
    """``(annotated, public)`` function counts over ``paths``."""
    funcs = [ok for p in paths for _, ok in public_functions(p)]
    return sum(funcs), len(funcs)


if __name__ == "__main__":                     # the figures of the report
    n, total = annotated_share(checked_files())
    print(f"checked modules: {len(checked_files())} files, {n}/{total} public functions annotated")
    n, total = annotated_share(sorted((SRC / "sinslab").rglob("*.py")))
    print(f"whole package: {n}/{total} public functions annotated ({100 * n / total:.0f} %)")
