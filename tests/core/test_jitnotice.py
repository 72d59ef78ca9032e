"""The first-run compile notice (sinslab.core.jitnotice): while a sinslab kernel compiles,
stderr shows the status line, erased when the compilation ends; nothing is shown for
functions outside sinslab, nor when bars are off."""
import numba
import numpy as np

from sinslab.core import jitnotice
from sinslab.core.progress import set_quiet


def _fresh_kernel(module):
    def kernel(x):
        s = 0.0
        for v in x:
            s += v * v
        return s
    kernel.__module__ = module
    return numba.njit(kernel)          # no cache: it compiles in this test


def test_status_line_while_a_sinslab_kernel_compiles(capfd):
    jitnotice.install()
    set_quiet(False)
    try:
        k = _fresh_kernel("sinslab.core.jitnotice_probe")
        assert k(np.arange(3.0)) == 5.0
        err = capfd.readouterr().err
        assert jitnotice.MESSAGE in err and "sinslab.core.jitnotice_probe." in err
        assert err.endswith("\r\x1b[K")                 # erased when done
        assert any(name.startswith("sinslab.core.jitnotice_probe.") and t >= 0
                   for name, t in jitnotice.compile_log())
        other = _fresh_kernel("elsewhere")
        assert other(np.arange(2.0)) == 1.0
        assert capfd.readouterr().err == ""
    finally:
        set_quiet(None)


def test_quiet_shows_nothing(capfd):
    jitnotice.install()
    set_quiet(True)
    try:
        assert _fresh_kernel("sinslab.core.jitnotice_probe2")(np.ones(2)) == 2.0
        assert capfd.readouterr().err == ""
    finally:
        set_quiet(None)
