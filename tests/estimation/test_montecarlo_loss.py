"""A campaign whose cluster loses every worker ends in one line naming the runs that had
finished (no worker tracebacks), and its shared inputs are task results the scheduler can
recompute, not scattered data."""
import os
import sys

import cloudpickle
import numpy as np
import pytest

from sinslab.core.errors import InputError
from sinslab.estimation import montecarlo as mc

cloudpickle.register_pickle_by_value(sys.modules[__name__])


def dying_batch(seeds, scale):
    """Every run kills the worker process that computes it."""
    os._exit(1)


def test_every_worker_lost_is_one_line():
    import dask
    import distributed  # noqa: F401 - its configuration must exist before it is overridden

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        with pytest.raises(InputError) as e:
            mc.run_campaign(dying_batch, 4, 0, batch=2, n_workers=1, args=(np.ones(3),), progress=False,
                            auto_serial=False)
    msg = str(e.value)
    assert "\n" not in msg and "lost its workers" in msg and "0 of 4 runs had finished" in msg


def draws(seeds, scale):
    return np.stack([scale * np.random.default_rng(s).standard_normal(3) for s in seeds])


def test_small_campaign_runs_serially_with_the_same_bytes(capsys, monkeypatch):
    """Cheap runs: the first batch, timed here, says a cluster cannot pay for its start-up;
    the rest run here too, in the batches the cluster would have had, and the decision is
    printed."""
    monkeypatch.delenv("SINSLAB_QUIET", raising=False)
    ref = mc.run_campaign(draws, 40, 3, batch=5, scheduler="sync", args=(2.0,), progress=False)
    out = mc.run_campaign(draws, 40, 3, n_workers=2, args=(2.0,), progress=False)
    assert np.array_equal(out, ref)
    err = capsys.readouterr().err
    assert "Monte Carlo: 40 runs" in err and "serial in this process" in err
