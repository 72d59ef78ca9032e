"""The ``sinslab`` command line (typer).

Commands: ``list``, ``run NAME``, ``config NAME``, ``report DIR``, ``demo --out DIR``.

Errors a user can fix (bad config key or unit, unreadable file, unusable output folder,
unknown experiment) print one line ``sinslab: error: ...`` on stderr and exit with
status 2, before any output file is created. Ctrl-C or SIGTERM stops the run; the
unfinished run is discarded and the output folder keeps what it held (exit 130 / 143).
A bug prints its traceback (exit 1).

Start-up is kept short: this module imports typer and nothing numerical; the command
modules import numba, scipy, matplotlib, pandas and dask inside the functions that use
them, ``sinslab list`` reads the experiments' names without importing them, and
``sinslab config NAME`` imports NAME's module alone (whose top level imports no
numerical package).

Adding a command (``navigate``, ``allan``, ``align``, ...): write a module in
:mod:`sinslab.app.commands` whose compute function returns a
:class:`sinslab.app.commands.runner.Output` and whose ``register(app)`` adds the typer
command, and list the module in ``COMMAND_MODULES``::

    def register(app):
        @app.command()
        def allan(file: Path = typer.Argument(..., help="recorded IMU file"),
                  out: Optional[Path] = typer.Option(None, help="output folder")):
            \"\"\"Allan deviation of recorded IMU data.\"\"\"
            cli_call(allan_file, file, out=out, echo=typer.echo)   # user errors -> exit 2

(annotations are evaluated by typer: import ``Optional``/``Path`` in that module).
:func:`sinslab.app.commands.runner.run_command` writes the run folder; raise
:class:`sinslab.app.errors.CliError` (or any of ``USER_ERRORS``) for a one-line user error.
"""
from __future__ import annotations

import contextlib
import datetime
import os
import sys
import threading
from pathlib import Path
from typing import List, Optional

import typer
from typer.core import TyperGroup

try:                                    # typer >= 0.20 carries its own copy of click
    from typer._click import exceptions as _cx
except ImportError:                     # pragma: no cover
    from click import exceptions as _cx

from sinslab import __version__
from sinslab.app.errors import USER_ERRORS, CliError, cli_process, error_line, exit_now, pause, user_errors
from sinslab.core.errors import InputError

__all__ = ["app", "main", "user_errors", "CliError", "USER_ERRORS"]

class _OneLineUsageError(_cx.ClickException):
    """A command-line usage error (bad option value, missing option) shown as one line."""

    exit_code = 2

    def show(self, file=None) -> None:
        typer.echo(f"sinslab: error: {self.format_message()}", err=True)


class _HelpAndExit(_cx.ClickException):
    """``sinslab`` alone: the help page on stdout, exit status 0 (asking for help is no error)."""

    exit_code = 0

    def __init__(self, ctx):
        super().__init__("")
        self.ctx = ctx

    def show(self, file=None) -> None:
        typer.echo(self.ctx.get_help())


def _one_line(e: _cx.UsageError) -> _cx.ClickException:
    if type(e).__name__ == "NoArgsIsHelpError":        # `sinslab` alone: the help page
        return _HelpAndExit(e.ctx) if e.ctx is not None and e.ctx.parent is None else e
    msg = e.format_message()
    if e.ctx is not None and e.ctx.info_name and e.ctx.parent is not None:
        msg = f"{e.ctx.info_name}: {msg}"
    return _OneLineUsageError(msg)


class _Group(TyperGroup):
    """Usage errors of the command line as one line ``sinslab: error: ...`` (exit 2),
    like every other bad input, instead of click's usage block."""

    def make_context(self, *args, **kwargs):
        try:
            return super().make_context(*args, **kwargs)
        except _cx.UsageError as e:
            raise _one_line(e) from None
        except KeyboardInterrupt as e:
            raise _stopped(e) from None

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except _cx.UsageError as e:
            raise _one_line(e) from None
        except KeyboardInterrupt as e:          # before or after a command's own handling
            raise _stopped(e) from None


def _stopped(e: KeyboardInterrupt) -> _cx.Exit:
    """Ctrl-C or SIGTERM outside a command's body (while the command line is parsed):
    nothing was started; one line, exit 130 / 143."""
    from sinslab.app.errors import Terminated

    code = 143 if isinstance(e, Terminated) else 130
    typer.echo(f"sinslab: error: {'terminated' if code == 143 else 'interrupted'}; nothing was written",
               err=True)
    return _cx.Exit(code)


app = typer.Typer(cls=_Group, add_completion=True, no_args_is_help=True, rich_markup_mode=None,
                  pretty_exceptions_enable=False,
                  help="sinslab: strapdown inertial navigation — experiments, runs and reports.")


def _err(msg: str) -> None:
    typer.echo(f"sinslab: error: {msg}", err=True)


_QUIET = False


def _log(msg: str) -> None:
    """A progress line on stderr (not with ``--quiet``, except warnings)."""
    if _QUIET and not msg.startswith(("warning", "note")):
        return
    typer.echo(f"sinslab: {msg}", err=True)


def version_line() -> str:
    """``sinslab X (numpy Y, numba Z, Python W)``: the versions that decide the numbers.

    Read from the installed packages' metadata, without importing numpy or numba."""
    import platform
    from importlib import metadata

    def v(dist: str) -> str:
        try:
            return metadata.version(dist)
        except metadata.PackageNotFoundError:
            return "not installed"

    return (f"sinslab {__version__} (numpy {v('numpy')}, numba {v('numba')}, "
            f"Python {platform.python_version()})")


def _version(value: bool) -> None:
    if value:
        typer.echo(version_line())
        raise typer.Exit()


@app.callback()
def _main(quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bars or progress lines"),
          version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                       help="print the version (and numpy's and numba's) and exit")):
    """sinslab: strapdown inertial navigation — experiments, runs and reports."""
    os.environ.setdefault("MPLBACKEND", "Agg")         # matplotlib is imported only when drawing
    global _QUIET
    _QUIET = bool(quiet)
    from sinslab.core.progress import set_lines, set_quiet

    set_lines(not quiet)                    # off a terminal: a line per stage, with its time
    if quiet:
        set_quiet(True)


@app.command("list")
def list_() -> None:
    """List the experiments and their one-line purpose."""
    from sinslab.experiments import broken, catalog

    cat = catalog()
    width = max((len(n) for n in cat), default=0)
    for name, purpose in cat.items():
        typer.echo(f"{name.ljust(width)}  {purpose}")
    for mod, err in broken(load=False).items():
        _log(f"warning: experiment module {mod} failed to import ({err})")
    for mod, err in _BROKEN_COMMANDS.items():
        _log(f"warning: commands of {mod} failed to load ({err})")


def _resolve(name, config, sets, seed, runs, quick):
    from sinslab.app.config import flatten, load_toml, resolve
    from sinslab.experiments import get

    exp = get(name)
    if quick and config is not None and exp.quick:
        # the file comes after --quick: say which of --quick's settings it replaces
        mine = flatten(load_toml(config))
        over = sorted(k for k, v in flatten(exp.quick).items() if k in mine and mine[k] != v)
        if over:
            _log(f"note: --config {config} overrides --quick for "
                 + ", ".join(f"{k} ({flatten(exp.quick)[k]} -> {mine[k]})" for k in over))
    over = {}
    if seed is not None:
        over["seed"] = seed
    if runs is not None:
        over["runs"] = runs
    cfg = resolve(exp.config, quick=exp.quick if quick else None, file=config, sets=sets,
                  overrides=over)
    return exp, cfg


def _print_summary(summary: dict, out: Path) -> None:
    from sinslab.app.report import claim_texts

    claims = summary["claims"]
    n = sum(c["passed"] for c in claims)
    robust = summary.get("robustness") or {}
    labels = {k: v.get("label", "") for k, v in (robust.get("claims") or {}).items() if v.get("label") != "not varied"}
    for c in claims:
        measured, expected = claim_texts(c)
        tags = [t for t in (c.get("origin"), labels.get(c["id"])) if t]
        o = f" ({'; '.join(tags)})" if tags else ""
        typer.echo(f"  [{'pass' if c['passed'] else 'FAIL'}] {c['id']}{o}: {measured} (expected "
                   f"{expected}) — {c['statement']}")
    from sinslab.app.claims import tally

    swept = ""
    if robust.get("swept") and robust.get("cpu_s") is not None:
        swept = f", robustness sweep {robust['wall_s']:.3g} s"
    typer.echo(f"{summary.get('name') or summary['experiment']}: {n}/{len(claims)} claims passed"
               + (f" ({tally(claims, robust)})" if any(c.get("origin") for c in claims) else "") + ", "
               f"{summary['metrics'].get('runtime_s', float('nan')):.3g} s{swept} -> {out / 'report.html'}")


def _complete_experiment(incomplete: str) -> list[str]:
    """Shell completion of an experiment name (read from the sources, nothing imported)."""
    from sinslab.experiments import catalog

    return [n for n in catalog() if n.startswith(incomplete)]


@app.command()
def run(name: str = typer.Argument(..., metavar="NAME", help="experiment name (see `sinslab list`)",
                                   autocompletion=_complete_experiment),
        config: Optional[Path] = typer.Option(None, "--config", "-c", help="TOML config file"),
        set_: Optional[List[str]] = typer.Option(None, "--set", "-s", metavar="KEY=VALUE",
                                                 help='override a dotted config key, e.g. imu.gyro_bias="0.02 deg/h" (repeatable)'),
        out: Optional[Path] = typer.Option(None, "--out", "-o", help="output folder [default: runs/NAME-<timestamp>]"),
        seed: Optional[int] = typer.Option(None, "--seed", min=0, help="random seed (overrides config seed)"),
        runs: Optional[int] = typer.Option(None, "--runs", min=1, help="Monte Carlo runs (overrides config runs)"),
        scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Dask scheduler address for Monte Carlo campaigns"),
        workers: Optional[int] = typer.Option(None, "--workers", min=0, help="worker processes of the local Dask cluster for Monte Carlo campaigns (0: run them in this process)"),
        quick: bool = typer.Option(False, "--quick", help="shortened run for tests and demos"),
        strict: bool = typer.Option(False, "--strict", help="exit status 1 if any claim fails"),
        robustness: bool = typer.Option(False, "--robustness", help="also re-run the experiment under the physics "
                                        "alternatives of its claims and label each claim robust or what it depends on"),
        force: bool = typer.Option(False, "--force", help="replace whatever --out holds (another run, other files)")) -> None:
    """Run an experiment; write config.toml, summary.json, series, figures, report.html."""
    import contextlib

    from sinslab.app.outputs import RunDir, default_out_dir
    from sinslab.experiments import execute

    with user_errors():
        exp, cfg = _resolve(name, config, set_, seed, runs, quick)
        from sinslab.app.validate import check_memory, check_scheduler

        check_memory(cfg)
        if workers is not None and scheduler is not None:
            raise CliError("--workers sizes the local cluster; --scheduler names another one: give one of them")
        if scheduler is not None:
            check_scheduler(scheduler, exp, cfg)
        cluster = contextlib.nullcontext(scheduler)
        if workers is not None:
            from sinslab.app.validate import starts_campaign

            if not starts_campaign(exp, cfg):
                raise CliError(f"--workers: experiment {exp.name!r} runs no Monte Carlo campaign with these "
                               "settings, so no workers would be used")
            if workers == 0:
                cluster = contextlib.nullcontext("sync")
            else:
                from sinslab.app.validate import check_workers
                from sinslab.estimation.montecarlo import dask_client

                check_workers(workers)

                cluster = dask_client(None, n_workers=workers)
        if out is None:
            out = default_out_dir(exp.name)
        else:
            RunDir(out, exp.name, command="run", force=force).check()
        try:
            with cluster as sched:
                summary = execute(exp, cfg, out, quick=quick, scheduler=sched, log=_log, force=force,
                                  robustness="full" if robustness else None)
        except InputError as e:                 # absurd values found while computing
            from sinslab.estimation.montecarlo import ClusterError

            given = [] if isinstance(e, ClusterError) else (
                [f"--set {x}" for x in (set_ or [])] + ([f"--config {config}"] if config else []))
            raise CliError(f"{exp.name}: {error_line(e)}"
                           + (f"; check the values given ({', '.join(given)})" if given else "")) from None
        pause("summary")
        _print_summary(summary, Path(out))
        if strict and not all(c["passed"] for c in summary["claims"]):
            raise typer.Exit(1)


@app.command("config")
def config_(name: str = typer.Argument(..., metavar="NAME", help="experiment name, or navigate",
                                       autocompletion=_complete_experiment),
            config: Optional[Path] = typer.Option(None, "--config", "-c", help="TOML config file"),
            set_: Optional[List[str]] = typer.Option(None, "--set", "-s", metavar="KEY=VALUE"),
            quick: bool = typer.Option(False, "--quick", help="show the --quick configuration")) -> None:
    """Print the resolved configuration of an experiment (or of ``navigate``) as TOML (a starting point for --config)."""
    from sinslab.app.config import config_to_toml

    if name == "navigate":
        from sinslab.app.commands import navigate_config as nc

        with user_errors():
            head = f"sinslab {__version__} — navigate: the configuration of `sinslab navigate --config FILE`"
            text = (nc.default_toml(head) if config is None and not set_ else
                    config_to_toml(nc.resolve_navigate(config, set_ or ()), head))
        typer.echo(text, nl=False)
        return
    with user_errors():
        exp, cfg = _resolve(name, config, set_, None, None, quick)
    typer.echo(config_to_toml(cfg, f"sinslab {__version__} — {exp.name}: {exp.purpose}"), nl=False)


@app.command()
def report(dir: Path = typer.Argument(..., metavar="DIR", help="run folder holding summary.json")) -> None:
    """(Re)build DIR/report.html from the run's files."""
    from sinslab.app import report as _report

    with user_errors():
        path = _report.build(dir)
    typer.echo(str(path))


@app.command("compile")
def compile_(jobs: int = typer.Option(2, "--jobs", "-j", min=1, max=2, help="processes compiling side by side"),
             portable: bool = typer.Option(False, "--portable",
                                           help="machine code for any CPU of the architecture (what a wheel ships)"),
             force: bool = typer.Option(False, "--force", help="compile even when nothing changed since the last compile")) -> None:
    """Compile the numerical kernels now, so that the first run starts warm (an install step:
    `make` runs it after pip install). Run again with nothing changed (sources, numba, CPU,
    the cached kernels), it says so and returns."""
    import subprocess

    # its own process: the module runs commands of this one
    r = subprocess.run([sys.executable, "-m", "sinslab.precompile", "--jobs", str(jobs)]
                       + (["--portable"] if portable else []) + (["--force"] if force else []))
    if r.returncode:
        raise typer.Exit(r.returncode)


@app.command()
def demo(out: Path = typer.Option(Path("runs"), "--out", "-o", help="folder for the runs and index.html"),
         quick: bool = typer.Option(False, "--quick", help="shortened runs"),
         only: Optional[List[str]] = typer.Option(None, "--only", help="run only these experiments")) -> None:
    """Run every registered experiment (full scale) into OUT/NAME and write OUT/index.html.

    With a Monte Carlo campaign among the runs, one local Dask cluster (a worker per CPU)
    serves the whole demo: the run with the highest declared cost computes here and every
    other run is a task on the workers, longest first, each run serial (a campaign
    computed in its own process, ``scheduler="sync"``). Three processes computing whole
    runs side by side keep both CPUs busy to the end; a campaign spread over the workers
    instead waits for a worker at every step while the others' runs hold them, and its
    serial parts leave the workers idle. Each run's seeds fix its numbers wherever it
    computes. The summaries are printed in the order of the runs, each as soon as it and
    those before it are done.
    """
    from sinslab.app import report as _report
    from sinslab.app.outputs import abort_all, completed_elsewhere
    from sinslab.estimation.montecarlo import dask_client
    from sinslab.experiments import execute

    done, failed = [], {}
    with user_errors():
        jobs = _demo_jobs(out, only, quick)
        with contextlib.ExitStack() as stack:
            # registered first, so called last, once the cluster is closed
            stack.callback(_completed_while_closing, jobs, out, datetime.datetime.now())
            shared = None
            if any(job.campaign for job in jobs):
                # one local cluster for every campaign of the demo: started once, its
                # workers keep their imports and loaded kernels from one run to the next
                shared = stack.enter_context(dask_client(None))
            lanes = None
            if _can_submit(shared):
                longest = max(jobs, key=lambda j: j.cost)
                lanes = _Lanes(shared, [job for job in jobs if job is not longest], out, quick)
            shown = 0

            def show(wait: bool) -> None:
                nonlocal shown
                shown = _show_due(jobs, shown, wait, out, done, failed)

            try:
                here = [job for job in jobs if not job.remote]
                # with a cluster that takes no runs, the campaigns longest first: the last
                # ones, short and spread over the workers, keep both CPUs busy to the end
                for job in _longest_first(here) if shared is not None else here:
                    _log(_running(job.exp.name, job.label, job.sets, quick))
                    try:
                        summary = execute(job.exp, job.cfg, out / job.label, quick=quick, log=_log,
                                          scheduler=("sync" if lanes else shared) if job.campaign else None,
                                          variant=(job.label, list(job.sets)) if job.sets else None,
                                          robustness="demo")
                    except (KeyboardInterrupt, *USER_ERRORS):
                        raise
                    except Exception as e:                  # one broken experiment: go on
                        import traceback

                        abort_all()                          # its folder keeps the previous run
                        job.outcome = ("failed", (f"{type(e).__name__}: {e}", traceback.format_exc()))
                    else:
                        job.outcome = ("done", summary)
                    show(wait=False)
                show(wait=True)
            finally:
                if lanes is not None:
                    lanes.close()
                # stopped early (interrupt, user error): the runs the workers completed are
                # in place, and not for this process to discard or report as unchanged
                for job in jobs:
                    if job.future is not None and job.future.status == "finished" \
                            and _remote_outcome(job.future)[0] == "done":
                        completed_elsewhere(out / job.label)
        idx = _report.index(out, done, failed)
        typer.echo(f"index: {idx}")
        if failed:
            raise typer.Exit(1)


def _demo_jobs(out: Path, only, quick: bool) -> list:
    """The runs of a demo into ``out``, every folder checked before any is written: each
    experiment's default scenario followed by its declared variants (``NAME-suffix``),
    configuration resolved and campaign known. One-line errors for an unusable ``out``."""
    from sinslab.app.config import resolve
    from sinslab.app.outputs import RunDir, is_run_dir
    from sinslab.app.validate import starts_campaign
    from sinslab.experiments import get, registry

    if out.exists() and not out.is_dir():
        raise CliError(f"output folder {out} exists and is a file")
    if is_run_dir(out):
        raise CliError(f"--out {out} is a run folder; demo writes one run folder per "
                       f"experiment under --out, never inside another run: choose another --out")
    idx_file = out / "index.html"
    if idx_file.exists() and not _is_sinslab_index(idx_file):
        raise CliError(f"{idx_file} exists and was not written by sinslab demo; "
                       f"choose another --out (it is never overwritten)")
    exps = [get(n) for n in (list(only) if only else list(registry()))]
    jobs = [_DemoJob(exp, f"{exp.name}-{suffix}" if suffix else exp.name, tuple(sets),
                     exp.demo_cost.get(suffix, 0.0))
            for exp in exps for suffix, sets in [("", ())] + list(exp.variants.items())]
    for job in jobs:
        RunDir(out / job.label, job.exp.name, command="run").check()
    for job in jobs:
        job.cfg = resolve(job.exp.config, quick=job.exp.quick if quick else None, sets=list(job.sets))
        job.campaign = starts_campaign(job.exp, job.cfg)
    return jobs


def _show_due(jobs: list, shown: int, wait: bool, out: Path, done: list, failed: dict) -> int:
    """Print the summaries that are due, in the order of the runs, from run ``shown`` on:
    a run on the workers waited for only with ``wait``; a failed run's traceback to stderr
    and its line into ``failed``; a user error raised. Returns how many are shown now."""
    while shown < len(jobs):
        job = jobs[shown]
        if job.remote and job.outcome is None:
            if not (wait or (job.future is not None and job.future.done())):
                return shown
            job.submitted.wait()
            if job.outcome is None:
                job.outcome = _remote_outcome(job.future)
        if job.outcome is None:
            return shown
        kind, value = job.outcome
        if kind == "user":
            raise value
        if kind == "failed":
            typer.echo(value[1], err=True, nl=False)        # its traceback
            failed[job.label] = value[0]
        else:
            _print_summary(value, out / job.label)
            done.append((job.label, out / job.label))
        shown += 1
    return shown


def _running(name: str, label: str, sets, quick: bool) -> str:
    """The progress line that starts a demo run."""
    what = f": {name} with {', '.join(sets)}" if sets else ""
    return f"running {label}{' (quick)' if quick else ''}{what} ..."


def _completed_while_closing(jobs: list, out: Path, started) -> None:
    """The runs the demo's workers put in place after the command last looked, marked as
    completed elsewhere (:func:`sinslab.app.outputs.completed_elsewhere`). Stopped early
    (an interrupt, a user error), the command closes the cluster, which lets a running
    run end: that folder then holds the new run, and an abort's message must say so (a
    run stopped mid-way is never half in place). ``started``: when the demo started."""
    from sinslab.app.outputs import completed_elsewhere, completed_since

    for job in jobs:
        if job.remote and job.future is not None and completed_since(out / job.label, started):
            completed_elsewhere(out / job.label)


class _DemoJob:
    """One run of ``sinslab demo``: an experiment with the ``--set`` lines of a variant."""

    def __init__(self, exp, label: str, sets: tuple, cost: float = 0.0):
        self.exp, self.label, self.sets = exp, label, sets
        #: its CPU time at full scale as the experiment declares it [s] (0: not declared)
        self.cost = cost
        self.cfg = None
        self.campaign = False
        #: computed on the cluster's workers (its future comes when a worker is free)
        self.remote = False
        #: the Dask future of a run handed to the workers
        self.future = None
        #: set once ``future`` is there
        self.submitted = threading.Event()
        #: ("done", summary), ("failed", (line, traceback)) or ("user", exception)
        self.outcome = None


def _longest_first(jobs: list) -> list:
    """``jobs`` by declared cost, longest first (a stable sort: the order of the runs among
    equal costs and those without one)."""
    return sorted(jobs, key=lambda j: -j.cost)


#: topic of the progress lines the demo's runs on Dask workers send to the command
_DEMO_TOPIC = "sinslab-demo"


def _can_submit(client) -> bool:
    """True for a ``distributed.Client`` (the demo's local cluster) that runs can be
    handed to."""
    if client is None or isinstance(client, str):
        return False
    from distributed import Client

    return isinstance(client, Client)


class _Lanes:
    """Hands demo runs to the cluster's workers, one per free worker thread, longest first
    by declared cost (LPT: the short runs fill the CPUs at the end).

    A run is submitted only when a worker thread is free for it (when a run ends, the next
    one goes out from the thread that learns of it): handed to a busy worker, a run would
    wait behind another run there while the other worker idles, and Dask, not knowing the
    runs' lengths, keeps no order among them. A run with a campaign computes it serially in
    its worker (``scheduler="sync"``): a worker starts no cluster of its own. Kernels two
    workers need at once are compiled by one of them (:mod:`sinslab.core.jitlock`).
    """

    def __init__(self, client, jobs: list, out: Path, quick: bool):
        self.client, self.out, self.quick = client, out, quick
        self.queue = _longest_first(jobs)
        for job in self.queue:
            job.remote = True
        self.lock = threading.Lock()
        self.closed = False

        def forward(event):
            # each line names its run: the runs' lines interleave
            name, label, msg = event[1]
            head, sep, rest = msg.partition(": ")
            if sep and head in ("warning", "note"):
                _log(f"{head}: {label}: {rest}")
            elif msg.startswith("running "):
                _log(msg)
            else:
                _log(f"{label}: {rest if sep and head == name else msg}")

        client.subscribe_topic(_DEMO_TOPIC, forward)
        slots = sum(w.get("nthreads", 1) for w in client.scheduler_info()["workers"].values())
        for _ in range(max(1, slots)):
            self._next()

    def _next(self, _ended=None) -> None:
        """Submit the next run, if any (also the callback of every run's future)."""
        with self.lock:
            if self.closed or not self.queue:
                return
            job = self.queue.pop(0)
            variant = (job.label, list(job.sets)) if job.sets else None
            try:
                job.future = self.client.submit(_run_on_worker, job.exp.name, job.cfg, str(self.out / job.label),
                                                self.quick, variant, scheduler="sync" if job.campaign else None,
                                                pure=False, key=f"sinslab-demo-{job.label}")
            except Exception as e:                         # noqa: BLE001 - the cluster is gone
                job.outcome = ("failed", (f"{type(e).__name__}: {e}", f"{job.label}: not started: {e}\n"))
            finally:
                job.submitted.set()
        if job.future is None:
            self._next()
        else:
            job.future.add_done_callback(self._next)

    def close(self) -> None:
        """Submit nothing more (the command stops)."""
        with self.lock:
            self.closed = True


def _remote_outcome(future) -> tuple:
    """The outcome of a run handed to a worker (the worker lost with it: a failed run)."""
    try:
        return future.result()
    except Exception as e:                                 # noqa: BLE001 - the run failed
        import traceback

        return ("failed", (f"{type(e).__name__}: {e}", traceback.format_exc()))


def _run_on_worker(name: str, cfg, out: str, quick: bool, variant, scheduler=None) -> tuple:
    """One demo run in a Dask worker: ``("done", summary)``; a failed run returns
    ``("failed", (line, traceback))`` (the other runs go on) and a user error
    ``("user", exception)``, its staging folder discarded either way. ``scheduler``: the
    run's (``"sync"`` for a campaign). Progress lines go to the command through the
    cluster's events; the worker shows no progress bars."""
    from distributed import get_worker

    from sinslab.app.outputs import abort_run
    from sinslab.core.progress import set_quiet
    from sinslab.experiments import execute, get

    set_quiet(True)
    worker = get_worker()

    def log(msg: str) -> None:
        worker.log_event(_DEMO_TOPIC, (name, variant[0] if variant else name, msg))

    log(_running(name, variant[0] if variant else name, variant[1] if variant else (), quick))
    try:
        return ("done", execute(get(name), cfg, out, quick=quick, log=log, variant=variant, robustness="demo",
                                scheduler=scheduler))
    except USER_ERRORS as e:
        abort_run(out)
        return ("user", e)
    except Exception as e:                                 # noqa: BLE001 - reported by the command
        import traceback

        abort_run(out)
        return ("failed", (f"{type(e).__name__}: {e}", traceback.format_exc()))


def _is_sinslab_index(path: Path) -> bool:
    """True if ``path`` is an index page written by ``sinslab demo``."""
    try:
        head = path.read_bytes()[:4096]
    except OSError:
        return False
    return b"<title>sinslab runs</title>" in head


#: Modules adding commands (``navigate``, ``allan``, ``align``, ...): each defines
#: ``register(app)`` that decorates its command functions with ``@app.command()``.
COMMAND_MODULES = (
    "sinslab.app.commands.navigate",
    "sinslab.app.commands.allan",
    "sinslab.app.commands.align",
    "sinslab.app.commands.transfer_align",
    "sinslab.app.commands.export",
)
_BROKEN_COMMANDS: dict[str, str] = {}

#: one example per command, shown at the end of its ``--help`` (paths of the repository's
#: shared data folder; ``tests/test_docs_commands.py`` runs every one of them)
EXAMPLES = {
    "list": "sinslab list",
    "run": 'sinslab run free-inertial --quick --set imu.gyro_bias="0.02 deg/h" --out runs/fi',
    "config": "sinslab config static-alignment --quick > sa.toml",
    "report": "sinslab report runs/fi",
    "demo": "sinslab demo --quick --only static-alignment --out runs/demo",
    "navigate": ('sinslab navigate --imu rtklib-drive/imu_1934.csv --fixes rtklib-drive/gnss_1934_sf.pos '
                 '--mount "rpy:180,-6.79,185.35" --frame frd --lever-arm "[-0.05, 0, 0] m" '
                 '--time-sync auto --velocity-lag 0.125 --outages 15/60@40 --out runs/drive'),
    "allan": "sinslab allan psins-lasergyro/lasergyro.imu --window 0:600 --out runs/allan",
    "align": "sinslab align --imu psins-lasergyro/lasergyro.imu --window 600:1200 --out runs/align",
    "transfer-align": ("sinslab transfer-align --slave psins-transfer/transfer_align_fog_mems.mat "
                       "--master psins-transfer/transfer_align_fog_mems.mat --method kain --window 0:60"),
    "export": "sinslab export runs/drive --to kml --out drive.kml",
}


def _add_examples() -> None:
    """Put each command's example at the end of its ``--help``."""
    for info in app.registered_commands:
        name = info.name or (info.callback.__name__.replace("_", "-").rstrip("-") if info.callback else "")
        if name in EXAMPLES and not info.epilog:
            info.epilog = f"\b\nExample:\n  {EXAMPLES[name]}"


def _load_commands() -> None:
    """Register the commands of COMMAND_MODULES; a broken one is skipped, not fatal.

    Each module's commands are first built on a scratch app (typer resolves the
    signatures then), so an error in one command cannot break the whole CLI.
    """
    import importlib

    for modname in COMMAND_MODULES:
        try:
            mod = importlib.import_module(modname)
            scratch = typer.Typer()
            mod.register(scratch)
            typer.main.get_command(scratch)
        except Exception as e:  # noqa: BLE001 - reported by `sinslab list`
            _BROKEN_COMMANDS[modname] = f"{type(e).__name__}: {e}"
            continue
        mod.register(app)


_load_commands()
_add_examples()


def main() -> None:
    """Console-script entry point. Signals are handled for the whole process
    (:func:`sinslab.app.errors.cli_process`): one arriving after the command's work is
    done ends the process with the command's status."""
    os.environ.setdefault("MPLBACKEND", "Agg")
    cli_process()
    try:
        app(prog_name="sinslab")
        code = 0
    except SystemExit as e:
        code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    pause("exit")
    exit_now(code)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
