"""Rules of the recorded front end that keep "a new sensor is one file" true
(docs/architecture.md):

- nothing outside an aid's module names its blocks: no string in the package equal to the
  name of a block a registered aid (or a GNSS source) owns (a subscript or dict key aside:
  a module's own table), and no ``startswith`` on a block name, except in the aid's own
  module and in :mod:`sinslab.nav.errstate` (where the block builders define their default
  names);
- no function under ``app/commands/`` or ``fusion/recorded*`` longer than 80 lines.
"""
import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "sinslab"
MAX_LINES = 80


def _owned_blocks():
    """``{block name: module that owns it}`` of the registered aids (every state any
    setting of theirs can add) and of the raw GNSS source."""
    import inspect

    from sinslab.fusion.aids import aid_types
    from sinslab.nav import errstate as es
    out = {}
    for t in aid_types().values():
        mod = Path(inspect.getfile(t)).resolve()
        for aid in (t(), *(t(**{k: v}) for k, v in _switches(t).items())):
            for s in aid.states():
                out[s.block.name] = mod
    out[es.receiver_clock().name] = (SRC / "fusion" / "tightly_coupled.py").resolve()
    return out


def _switches(t):
    """Flag settings flipped from their default (states an aid adds only when asked)."""
    from sinslab.fusion.aids.base import settings_of
    return {k: not getattr(t(), k) for k, s in settings_of(t).items() if s.kind == "flag"}


def _keys(tree):
    """The string constants of a module used as subscripts or dict keys (``d["clk"]``: a
    key of the module's own dict, not a block)."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Subscript):
            out.add(id(node.slice))
        elif isinstance(node, ast.Dict):
            out.update(id(k) for k in node.keys if k is not None)
    return out


def test_no_block_name_outside_its_aid():
    owned = _owned_blocks()
    assert {"lev", "kod", "vm", "nlev", "clk"} <= set(owned), owned
    exempt = {(SRC / "nav" / "errstate.py").resolve()}
    bad = []
    for path in sorted(SRC.rglob("*.py")):
        p = path.resolve()
        tree = ast.parse(path.read_text(encoding="utf-8"))
        keys = _keys(tree)
        for node in ast.walk(tree):
            names = []
            if (isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in owned
                    and id(node) not in keys):
                names = [node.value]
            elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                  and node.func.attr == "startswith" and node.args and isinstance(node.args[0], ast.Constant)
                  and isinstance(node.args[0].value, str)):
                names = [b for b in owned if node.args[0].value.startswith(b) or b.startswith(node.args[0].value)]
            for b in names:
                if p not in exempt and p != owned[b]:
                    bad.append(f"{path.relative_to(SRC.parent)}:{node.lineno} names block {b!r}")
    assert not bad, "\n".join(bad)


def test_no_long_function_in_the_front_end():
    files = sorted((SRC / "app" / "commands").glob("*.py")) + sorted((SRC / "fusion").glob("recorded*.py"))
    long = []
    for path in files:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_LINES:
                    long.append(f"{path.relative_to(SRC.parent)}:{node.lineno} {node.name}: {n} lines")
    assert not long, "\n".join(long)
