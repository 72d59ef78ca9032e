"""The robustness sweep: an experiment re-run under the physics alternatives of its claims.

:func:`sweep` takes an experiment's finished run (its :class:`~sinslab.experiments.base.Result`)
and the axes of its module's ``ROBUSTNESS(cfg)`` (:class:`~sinslab.experiments.base.Axis`),
re-runs the experiment once per alternative — at the axis's reduced size, with the reduced
run at the default assumptions made as well, so that an alternative is compared with a run
of its own size — and adds each listed claim's verdict to that claim as an
:class:`~sinslab.app.claims.Alternative` (``how = "rerun"``). Readings and thresholds need
no re-run: ``run`` evaluates them on its own results. A reduced run whose default verdict
differs from the full run's is itself recorded, as an alternative of the assumption "size
of the sweep's runs", so a reduction that does not decide the same shows in the label.

Re-runs with the same resolved configuration are made once. A re-run that fails (an
alternative outside the model's validity, say) is recorded as undecided with its error,
not raised: the run it belongs to is complete without it.
"""
from __future__ import annotations

import json
import time

from sinslab.app.claims import Alternative
from sinslab.app.config import resolve
from sinslab.app.errors import UserError
from sinslab.experiments.base import RunContext

__all__ = ["sweep", "pending", "SIZE"]

#: the assumption under which a reduced run's own default verdict is recorded
SIZE = "size of the sweep's runs"


def pending(exp, cfg, claims, axes=None) -> dict:
    """``{claim id: [assumption, ...]}``: the physics alternatives declared for each claim
    (of ``axes``, default all of the experiment's: not run, the sweep was not asked for)."""
    ids = [c.id for c in claims]
    out: dict[str, list] = {}
    for ax in (exp.axes(cfg) if axes is None else axes):
        for cid in (ax.claims or ids):
            if cid in ids and ax.assumption not in out.setdefault(cid, []):
                out[cid].append(ax.assumption)
    return out


def _key(cfg) -> str:
    return json.dumps(cfg.model_dump(mode="json"), sort_keys=True, default=str)


class _Runner:
    """Re-runs of one experiment, each configuration once: ``{claim id: Claim}`` or an error."""

    def __init__(self, exp, cfg, ctx, quick):
        self.exp, self.ctx, self.quick = exp, ctx, quick
        self.base = cfg.model_dump(mode="json")
        self.cache = {_key(cfg): None}           # the run itself: never re-run
        self.cpu = 0.0

    def config(self, sets):
        return resolve(self.exp.config, overrides=self.base, sets=list(sets))

    def claims(self, sets):
        """The claims of the experiment re-run with ``sets`` on top of the run's config
        (None for the run's own configuration); an error line for a failed re-run."""
        try:
            cfg = self.config(sets)
        except UserError as e:
            return f"configuration refused: {e}"
        key = _key(cfg)
        if key not in self.cache:
            self.ctx.log(f"robustness: re-run with {', '.join(sets)}")
            c0 = time.process_time()
            sub = RunContext(name=self.exp.name, out=self.ctx.out, seed=cfg.seed, runs=cfg.runs,
                             quick=self.quick, scheduler=self.ctx.scheduler, claims_only=True)
            try:
                res = self.exp.run(cfg, sub)
            except (KeyboardInterrupt, MemoryError):
                raise
            except Exception as e:                       # noqa: BLE001 - recorded, not raised
                self.cache[key] = f"re-run failed: {type(e).__name__}: {e}"
            else:
                _close(res.figures)
                self.cache[key] = {c.id: c for c in res.claims}
            self.cpu += time.process_time() - c0
        return self.cache[key]


def _close(figures) -> None:
    """Close the matplotlib figures a re-run drew anyway."""
    if not figures:
        return
    import matplotlib.pyplot as plt

    for f in figures:
        plt.close(getattr(f, "fig", f))


def _record(claim, axis, name, got, base):
    """Add the verdict of ``claim`` in a re-run (``got``: its claims or an error line)."""
    claim.assume(axis.assumption, axis.default, axis.source)
    if isinstance(got, str) or claim.id not in got:
        why = got if isinstance(got, str) else "the claim is not made in this re-run"
        claim.alternatives.append(Alternative(axis.assumption, name, None, None, "rerun", note=why))
        return
    c = got[claim.id]
    b = base.get(claim.id) if isinstance(base, dict) else None
    claim.alternatives.append(Alternative(axis.assumption, name, c.measured, c.passed, "rerun",
                                          baseline=None if b is None else b.passed))
    if axis.readings:
        for a in c.alternatives:
            if a.how == "rerun":
                continue
            ref = next((x for x in (b.alternatives if b is not None else claim.alternatives)
                        if x.assumption == a.assumption and x.name == a.name), None)
            # a reading of the axis's own assumption (the report time inside a longer run)
            # varies that one assumption, not two
            claim.alternatives.append(Alternative(
                axis.assumption, f"{name}; {a.name}", a.value, a.passed, "rerun",
                baseline=None if ref is None else ref.passed,
                combined="" if a.assumption == axis.assumption else a.assumption))


def sweep(exp, cfg, result, ctx, *, quick: bool = False, demo: bool = False) -> tuple[list[dict], dict]:
    """Re-run ``exp`` for every alternative of its axes and add the verdicts to the claims
    of ``result`` (in place). Returns the record of the axes run — per axis its assumption,
    default, source, alternatives with their ``--set`` items, the reduction used, the
    claims it applies to and the CPU seconds of its re-runs (this process's) — and the
    :func:`pending` alternatives of the axes the demo leaves out (``demo``)."""
    runner = _Runner(exp, cfg, ctx, quick)
    by_id = {c.id: c for c in result.claims}
    sized = set()
    record = []
    axes = exp.axes(cfg)
    left = [a for a in axes if demo and not a.in_demo]
    for axis in (a for a in axes if a not in left):
        cpu0 = runner.cpu
        red = () if quick else axis.sets(demo)
        ids = [i for i in (axis.claims or by_id) if i in by_id]
        base = runner.claims(red) if red else None
        if red and isinstance(base, dict):
            for cid in ids:
                c, b = by_id[cid], base.get(cid)
                if b is not None and b.passed != c.passed and (cid, red) not in sized:
                    sized.add((cid, red))
                    c.assume(SIZE, "the run's own size")
                    c.alternatives.append(Alternative(SIZE, f"reduced scenario ({', '.join(red)})", b.measured,
                                                      b.passed, "rerun"))
        for name, sets in axis.alternatives.items():
            got = runner.claims(list(red) + list(sets))
            if got is None:                             # the alternative is the run itself
                continue
            for cid in ids:
                _record(by_id[cid], axis, name, got, base)
        record.append({"assumption": axis.assumption, "default": axis.default, "source": axis.source,
                       "alternatives": {k: list(v) for k, v in axis.alternatives.items()}, "reduced": list(red),
                       "claims": ids, "cpu_s": runner.cpu - cpu0})
    return record, pending(exp, cfg, result.claims, left)
