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
            mc.run_campaign(dying_batch, 4, 0, batch=2, n_workers=1, args=(np.ones(3),), progress=False)
    msg = str(e.value)
    assert "\n" not in msg and "lost its workers" in msg and "0 of 4 runs had finished" in msg
