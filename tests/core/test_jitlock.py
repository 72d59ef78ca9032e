"""The cross-process compile lock (sinslab.core.jitlock): on an empty disk cache, a process
that needs a kernel another process is compiling waits for it and loads the kernel from
the cache instead of compiling it a second time."""
import os
import subprocess
import sys
import textwrap
import time

#: a process that holds radii_s's lock (A) or calls radii_s (B), then reports what it compiled
_SCRIPT = textwrap.dedent("""
    import json, os, sys, time
    from sinslab.core import earth, jitlock, jitnotice
    role, d = sys.argv[1], sys.argv[2]

    def mark(name):
        open(os.path.join(d, name), "w").close()

    def wait(name):
        while not os.path.exists(os.path.join(d, name)):
            time.sleep(0.02)

    if role == "A":
        with jitlock.kernel_lock(earth.radii_s):
            mark("locked")
            wait("go")
            earth.radii_s(0.5, 10.0)        # compiled here, inside the (re-entered) lock
    else:
        mark("calling")
        earth.radii_s(0.5, 10.0)
    print(json.dumps([n for n, _ in jitnotice.compile_log()]))
""")


def _start(role, d, env):
    return subprocess.Popen([sys.executable, "-c", _SCRIPT, role, str(d)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_for(path, proc, timeout=60.0):
    t0 = time.monotonic()
    while not path.exists():
        assert proc.poll() is None, proc.communicate()[1]
        assert time.monotonic() - t0 < timeout, f"{path.name} never appeared"
        time.sleep(0.02)


def test_second_process_waits_and_loads_instead_of_compiling(tmp_path):
    import json

    cache = tmp_path / "cache"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), SINSLAB_QUIET="1", SINSLAB_JITCACHE="0")
    a = _start("A", tmp_path, env)
    _wait_for(tmp_path / "locked", a)
    b = _start("B", tmp_path, env)
    _wait_for(tmp_path / "calling", b)
    # B is now at the kernel with the cache still empty: without the lock it compiles it
    # itself right away; with the lock it waits for A
    time.sleep(0.5)
    (tmp_path / "go").touch()
    out_a, err_a = a.communicate(timeout=120)
    out_b, err_b = b.communicate(timeout=120)
    assert a.returncode == 0, err_a
    assert b.returncode == 0, err_b
    compiled_a = json.loads(out_a.strip().splitlines()[-1])
    compiled_b = json.loads(out_b.strip().splitlines()[-1])
    assert "sinslab.core.earth.radii_s" in compiled_a
    assert "sinslab.core.earth.radii_s" not in compiled_b
    assert list(cache.rglob("*radii_s*.nbc"))        # and B loaded it from there


def test_kernels_of_other_packages_and_uncached_ones_are_not_locked():
    import numba

    from sinslab.core import earth, jitlock

    def f(x):
        return x + 1.0

    f.__module__ = "elsewhere"
    assert jitlock._lock_path(numba.njit(cache=False)(f)) is None
    f.__module__ = "sinslab.core.jitlock_probe"
    assert jitlock._lock_path(numba.njit(cache=False)(f)) is None     # no disk cache
    assert jitlock._lock_path(earth.radii_s).endswith(".nbi.lock")
