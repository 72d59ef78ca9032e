"""Experiment registry and runner.

Every module in this package that defines ``NAME`` is an experiment (see
:mod:`sinslab.experiments.base` for what it declares). Adding an experiment is adding a
module: :func:`registry` discovers it, ``sinslab list`` shows it, ``sinslab run NAME``
runs it and ``sinslab demo`` includes it.

``sinslab list`` and ``sinslab config NAME`` start at once: :func:`catalog` reads the
names from the modules' sources without importing them, and :func:`get` imports only the
module whose source declares ``NAME`` (an experiment module imports its numerical
packages inside the functions that compute).

:func:`execute` is the whole run contract (docs/cli.md, run folders) in one function; the CLI calls it
and so can Python code::

    from sinslab.experiments import get, execute
    from sinslab.app.config import resolve
    exp = get("free-inertial")
    cfg = resolve(exp.config, quick=exp.quick, sets=["imu.gyro_bias=0.02 deg/h"])
    summary = execute(exp, cfg, "runs/fi-test")
"""
from __future__ import annotations

import datetime as _dt
import importlib
import pkgutil
import re
import sys
import time
from pathlib import Path
from typing import Callable

from sinslab import __version__
from sinslab.app.config import ExperimentConfig, config_to_toml
from sinslab.app.errors import UserError
from sinslab.app.outputs import RunDir
from sinslab.app.publish import complete_timed, describe_series, write_figures, write_series
from sinslab.experiments.base import Experiment, Result, RunContext

__all__ = ["registry", "register", "get", "names", "catalog", "execute", "UnknownExperiment", "Experiment"]

_SKIP = {"base", "sweep"}
_registry: dict[str, Experiment] | None = None
_broken: dict[str, str] = {}
#: ``{module: Experiment}`` imported one at a time by :func:`get` before the registry is built
_loaded: dict[str, Experiment] = {}


class UnknownExperiment(UserError, KeyError):
    """No experiment of that name (a user error: one line, exit 2)."""

    def __str__(self):
        return self.args[0]


def registry() -> dict[str, Experiment]:
    """``{name: Experiment}`` of every experiment module (imported once, sorted by name).

    A module that fails to import is left out and its error kept in :func:`broken`.
    """
    global _registry
    if _registry is None:
        found: dict[str, Experiment] = {}
        for modname in _candidates():
            try:
                mod = importlib.import_module(modname)
                if not hasattr(mod, "NAME"):
                    continue
                exp = _loaded.get(modname) or Experiment.from_module(mod)
            except Exception as e:  # a half-written module must not hide the others
                _broken[modname] = f"{type(e).__name__}: {e}"
                continue
            if exp.name in found:
                raise RuntimeError(f"experiment name {exp.name!r} declared twice "
                                   f"({found[exp.name].module}, {modname})")
            found[exp.name] = exp
        _registry = dict(sorted(found.items()))
    return _registry


def register(exp_or_module) -> Experiment:
    """Add an experiment (an :class:`Experiment` or a module with the declarations).

    Modules inside this package are found automatically; this is for experiments defined
    elsewhere (plugins, tests).
    """
    exp = exp_or_module if isinstance(exp_or_module, Experiment) else Experiment.from_module(exp_or_module)
    reg = registry()
    reg[exp.name] = exp
    return exp


def broken(load: bool = True) -> dict[str, str]:
    """Experiment modules that failed to import (or, after :func:`catalog` alone, whose
    source could not be read): ``{module: error}``. ``load=False``: do not import the
    modules to find out."""
    if load:
        registry()
    return dict(_broken)


def catalog() -> dict[str, str]:
    """``{name: purpose}`` of every experiment, sorted by name, without importing the
    experiment modules when the registry is not built yet: ``NAME`` and ``PURPOSE`` are
    read from each module's source (so ``sinslab list`` starts at once). A module whose
    source cannot be parsed is reported by :func:`broken`; one whose ``PURPOSE`` is not a
    plain string is imported.
    """
    if _registry is not None:
        return {n: e.purpose for n, e in _registry.items()}
    found: dict[str, str] = {}
    for modname in _candidates():
        try:
            lines = _source_lines(modname)
        except (OSError, ValueError) as e:
            _broken[modname] = f"{type(e).__name__}: {e}"
            continue
        consts = {k: _constant(lines, k) for k in ("NAME", "PURPOSE")}
        if consts["NAME"] is None and not any(ln.startswith("NAME") for ln in lines):
            continue
        if not all(isinstance(v, str) for v in consts.values()):
            return {n: e.purpose for n, e in registry().items()}
        found[consts["NAME"]] = consts["PURPOSE"]
    return dict(sorted(found.items()))


def _candidates() -> list[str]:
    """Dotted names of the modules of this package that may be experiments."""
    return [f"{__name__}.{info.name}" for info in pkgutil.iter_modules(__path__)
            if not (info.name.startswith("_") or info.name in _SKIP)]


def _source_lines(modname: str) -> list[str]:
    path = Path(__path__[0]) / f"{modname.rpartition('.')[2]}.py"
    return path.read_text(encoding="utf-8").splitlines()


def _declared_modules() -> dict[str, list[str]] | None:
    """``{NAME: [module, ...]}`` as the modules' sources declare it, without importing
    them; None when a source cannot be read or declares ``NAME`` other than as a plain
    string (only importing the modules tells then). A module without ``NAME`` is not an
    experiment and is left out; a name with two modules is an error :func:`registry`
    reports."""
    found: dict[str, list[str]] = {}
    for modname in _candidates():
        try:
            lines = _source_lines(modname)
        except (OSError, ValueError):
            return None
        name = _constant(lines, "NAME")
        if name is None and not any(ln.startswith("NAME") for ln in lines):
            continue
        if not isinstance(name, str):
            return None
        found.setdefault(name, []).append(modname)
    return found


def _import_one(name: str) -> Experiment | None:
    """The experiment ``name`` from its module alone (found by :func:`_declared_modules`);
    None when the sources do not settle it (unknown, declared twice, unreadable) or the
    module fails to import: then :func:`registry` decides and reports."""
    mods = (_declared_modules() or {}).get(name, [])
    if len(mods) != 1:
        return None
    modname = mods[0]
    if modname not in _loaded:
        try:
            exp = Experiment.from_module(importlib.import_module(modname))
        except Exception:
            return None
        if exp.name != name:
            return None
        _loaded[modname] = exp
    return _loaded[modname]


def _constant(lines: list[str], name: str):
    """The string assigned to ``name`` at module level (``NAME = "..."``, possibly over a
    few lines), read without importing the module; None if absent or not a literal."""
    import ast

    pat = re.compile(rf"^{name}\s*(:\s*str\s*)?=")
    for i, line in enumerate(lines):
        if pat.match(line):
            for j in range(i + 1, min(i + 20, len(lines)) + 1):
                try:
                    node = ast.parse("\n".join(lines[i:j])).body[0]
                except SyntaxError:
                    continue
                v = getattr(node, "value", None)
                return v.value if isinstance(v, ast.Constant) else None
            return None
    return None


def names() -> list[str]:
    return list(registry())


def get(name: str) -> Experiment:
    """The experiment called ``name``; UnknownExperiment (with the known names) otherwise.

    Before the registry is built, only the module that declares ``name`` is imported."""
    if _registry is None:
        exp = _import_one(name)
        if exp is not None:
            return exp
        declared = _declared_modules()
        if declared is not None and name not in declared:
            _unknown(name, sorted(declared))        # no module declares it: none imported
    reg = registry()
    if name not in reg:
        _unknown(name, list(reg))
    return reg[name]


def _unknown(name: str, known: list[str]):
    import difflib

    hint = difflib.get_close_matches(name, known, n=1)
    msg = f"unknown experiment {name!r}"
    msg += f"; did you mean {hint[0]!r}?" if hint else f"; known: {', '.join(known) or 'none'}"
    raise UnknownExperiment(msg)


def _check_result(exp: Experiment, res: Result, log) -> None:
    if not isinstance(res, Result):
        raise TypeError(f"{exp.module}.run must return a Result, got {type(res).__name__}")
    for m in res.metrics:
        if m not in exp.metrics:
            log(f"warning: metric {m!r} is not declared in {exp.module}.METRICS")
    ids = [c.id for c in res.claims]
    if len(set(ids)) != len(ids):
        raise ValueError(f"{exp.module}: duplicate claim ids {ids}")


def _robustness(exp, cfg, res, ctx, quick, mode) -> dict:
    """The robustness section of a run (its sweep made when ``mode`` asks for it)."""
    from sinslab.app.claims import robustness_section
    from sinslab.experiments import sweep

    if mode not in (None, "full", "demo"):
        raise ValueError(f"robustness must be None, 'full' or 'demo', got {mode!r}")
    if mode is None:
        return robustness_section(res.claims, swept=False, pending=sweep.pending(exp, cfg, res.claims))
    t0, c0 = time.perf_counter(), time.process_time()
    axes, left = sweep.sweep(exp, cfg, res, ctx, quick=quick, demo=mode == "demo")
    return robustness_section(res.claims, swept=True, pending=left, axes=axes, cpu_s=time.process_time() - c0,
                              wall_s=time.perf_counter() - t0)


def execute(exp: Experiment, cfg: ExperimentConfig, out: str | Path, *, quick: bool = False,
            scheduler: object = None, log: Callable[[str], None] | None = None,
            variant: tuple[str, list[str]] | None = None, force: bool | None = None,
            robustness: str | None = None) -> dict:
    """Run ``exp`` with the resolved ``cfg`` into folder ``out``; return the summary dict.

    Everything is written into a staging folder that replaces ``out``'s previous contents
    only when the run is complete (see :mod:`sinslab.app.outputs`): marker,
    ``config.toml``, series, tables, figures, ``summary.json``, ``report.html``, marker
    "complete", swap. Raises :class:`sinslab.app.outputs.OutputDirError` before writing
    anything if ``out`` is not usable (``force=True``: replace whatever it holds).
    ``variant=(name, sets)`` names a demo variant (its report carries that name and the
    ``--set`` lines that make it). ``summary["timing"]`` holds the seconds spent
    computing and writing series, figures and the report.

    ``robustness``: ``"full"`` (``--robustness``) or ``"demo"`` (the demo's sizes) re-runs the
    experiment under the physics alternatives of its claims (:mod:`sinslab.experiments.sweep`);
    None leaves them out. The readings and thresholds each claim carries are evaluated by the
    run either way; ``summary["robustness"]`` holds the labels
    (:func:`sinslab.app.claims.robustness_section`).
    """

    log = log or (lambda msg: None)
    rd = RunDir(out, exp.name, command="run", force=force).prepare()
    started = _dt.datetime.now().astimezone()
    header = (f"sinslab {__version__} — experiment {exp.name}{' (--quick)' if quick else ''}\n"
              f"resolved configuration, {started.isoformat(timespec='seconds')}\n"
              f"reproduce: sinslab run {exp.name} --config config.toml")
    rd.write_text("config.toml", config_to_toml(cfg, header))
    import hashlib
    import json

    # beside the output folder, not in its staging folder: a failed run's finished Monte Carlo
    # tasks outlive it, for a rerun of the same configuration into the same folder (a name
    # that the check of a folder holding runs passes over, as it does temporary files)
    campaigns = Path(out).absolute().parent / f".{Path(out).name}.tmp-campaigns"
    key = hashlib.sha256(json.dumps([exp.name, quick, cfg.model_dump(mode="json")], sort_keys=True,
                                    default=str).encode()).hexdigest()
    ctx = RunContext(name=exp.name, out=rd.path, seed=cfg.seed, runs=cfg.runs, quick=quick,
                     scheduler=scheduler, log=log, campaigns=campaigns, config_key=key)
    t0 = time.perf_counter()
    res = exp.run(cfg, ctx)
    runtime = time.perf_counter() - t0
    _check_result(exp, res, log)
    metrics = dict(res.metrics)
    metrics.setdefault("runtime_s", runtime)
    robust = _robustness(exp, cfg, res, ctx, quick, robustness)

    t1 = time.perf_counter()
    for name, table in res.series.items():
        write_series(rd, name, table, describe_series(name, table))
    tables = []
    for t in res.tables:
        info = rd.write_table(f"table_{t.name}", t.data, t.caption)
        tables.append({**info, "caption": t.caption})
    t2 = time.perf_counter()
    write_figures(rd, res.figures)
    t3 = time.perf_counter()
    timing = {"compute_s": runtime, "series_s": t2 - t1, "figures_s": t3 - t2, "report_s": None,
              "robustness_s": robust["wall_s"]}

    summary = {
        "experiment": exp.name,
        "sinslab_version": __version__,
        "config": cfg.model_dump(mode="json"),
        "metrics": metrics,
        "claims": [c.as_dict() for c in res.claims],
        "robustness": robust,
        # --- beyond the contract: what the report needs to rebuild itself
        "purpose": exp.purpose,
        "paper": exp.paper,
        "quick": quick,
        "started": started.isoformat(timespec="seconds"),
        "python": sys.version.split()[0],
        "metric_info": {m: {"unit": exp.metrics[m].unit, "description": exp.metrics[m].description}
                        for m in metrics if m in exp.metrics},
        "figures": rd.figure_files,
        "series": [s for s in rd.series_info if not s["name"].startswith("table_")],
        "tables": tables,
        "notes": list(exp.notes) + list(res.notes),
        "timing": timing,
    }
    if variant:
        summary["name"] = variant[0]
        summary["variant"] = {"name": variant[0], "sets": list(variant[1])}
        summary["rerun"] = f"sinslab run {exp.name} --config config.toml"
    rd.obsolete_when_complete(campaigns)
    return complete_timed(rd, summary)
