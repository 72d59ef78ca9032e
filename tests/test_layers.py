"""The package layers: every import of every module (function-local ones too, relative
imports resolved) follows the allowed edges of docs/architecture.md, and no modules import
each other around a loop."""
import ast
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "sinslab"

#: layer -> sinslab layers it may import (its own layer is always allowed)
ALLOWED = {
    "core": set(),
    "data": {"core"},
    "sim": {"core"},
    "nav": {"core"},
    "estimation": {"core"},
    "fusion": {"core", "nav", "estimation"},
    "methods": {"core", "nav", "estimation", "fusion"},
    "app": {"core", "data", "sim", "nav", "estimation", "fusion", "methods"},
    "experiments": {"core", "data", "sim", "nav", "estimation", "fusion", "methods", "app"},
    "cli": {"core", "data", "sim", "nav", "estimation", "fusion", "methods", "app", "experiments"},
    # sinslab compile: runs the commands of the CLI on simulated inputs
    "precompile": {"core", "data", "sim", "nav", "estimation", "fusion", "methods", "app", "experiments", "cli"},
    "__main__": {"cli"},                # `python -m sinslab`: the command line, nothing else
}
#: third-party packages the core may use (plus the standard library)
CORE_THIRD_PARTY = {"numpy", "scipy", "numba", "rich",
                    "pandas"}                # the records' to_pandas, imported when called
#: what the top-level sinslab/__init__.py may import eagerly
TOP_LIGHT = set(sys.stdlib_module_names)


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imports(path: Path):
    """(line, imported module) of every import in the file, relative ones resolved."""
    mod = _module_name(path)
    pkg = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield node.lineno, a.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg.split(".")
                base = base[:len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            if node.module is None or node.level:
                for a in node.names:           # `from . import x` may name a module
                    yield node.lineno, f"{target}.{a.name}" if not node.module else target
            else:
                yield node.lineno, target


def _layer(mod: str) -> str | None:
    parts = mod.split(".")
    if parts[0] != "sinslab" or len(parts) == 1:
        return None
    return parts[1]


def offences():
    bad = []
    for path in sorted(SRC.rglob("*.py")):
        mod = _module_name(path)
        layer = _layer(mod)
        for line, target in _imports(path):
            where = f"{path.relative_to(SRC.parent.parent)}:{line} {mod} -> {target}"
            top = target.split(".")[0]
            tl = _layer(target)
            if layer is None:                   # sinslab/__init__.py: nothing heavy
                if top != "sinslab" and top not in TOP_LIGHT:
                    bad.append(where)
                continue
            if top != "sinslab":
                if layer == "core" and top not in CORE_THIRD_PARTY and top not in sys.stdlib_module_names:
                    bad.append(where)
                continue
            if tl is None or tl == layer:       # `import sinslab` (the version) or own layer
                continue
            if tl not in ALLOWED[layer]:
                bad.append(where)
    return bad


def test_imports_follow_the_layers():
    bad = offences()
    assert not bad, "imports against the layers (file:line module -> module):\n" + "\n".join(bad)


def _module_graph():
    """{module: sinslab modules it imports}; ``from package import name`` points at the
    submodule ``name`` when there is one, an imported attribute at its module."""
    mods = {_module_name(p): p for p in SRC.rglob("*.py")}
    graph = {}
    for mod, path in mods.items():
        pkg = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        deps = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = pkg.split(".")
                    base = ".".join(up[:len(up) - node.level + 1] + ([node.module] if node.module else []))
                targets = [f"{base}.{a.name}" for a in node.names]
            else:
                continue
            for t in targets:
                while t and t not in mods:
                    t = t.rpartition(".")[0]
                if t and t != mod:
                    deps.add(t)
        graph[mod] = deps
    return graph


def test_no_import_circles():
    """No two modules import each other, directly or around a loop (function-local imports
    included): values and calls travel one way."""
    graph = _module_graph()
    state, stack, circles = {}, [], []

    def visit(m):
        state[m] = "open"
        stack.append(m)
        for d in sorted(graph.get(m, ())):
            if state.get(d) == "open":
                circles.append(" -> ".join(stack[stack.index(d):] + [d]))
            elif d not in state:
                visit(d)
        stack.pop()
        state[m] = "done"

    for m in sorted(graph):
        if m not in state:
            visit(m)
    assert not circles, "import circles:\n" + "\n".join(circles)


if __name__ == "__main__":
    print("\n".join(offences()))
