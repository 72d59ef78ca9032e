"""Run-folder writers: the chunked CSV writer equals pandas' bytes; min/max thinning keeps the
envelope; figures drawn in worker processes equal those drawn in the run's process."""
import numpy as np
import pytest

from sinslab.app import plotting as P
from sinslab.app import publish
from sinslab.app.outputs import Figure, RunDir


def test_numpy_csv_equals_pandas_bytes(tmp_path):
    rng = np.random.default_rng(1)
    x = rng.normal(size=(500, 4)) * 10.0 ** rng.integers(-12, 12, size=(500, 4))
    x[3, 1] = np.nan
    x[7, 2] = np.inf
    x[9, 0] = -0.0
    table = {"t_s": np.arange(500) * 0.1, "a_m": x[:, 0], "b_arcsec": x[:, 1], "c": x[:, 2], "d": x[:, 3]}
    a = RunDir(tmp_path / "a", "x").prepare()
    b = RunDir(tmp_path / "b", "x").prepare()
    import pandas as pd

    ia = publish.write_series(a, "s", table, "d")
    pd.DataFrame(table).to_csv(tmp_path / "pandas.csv", index=False, float_format="%.10g")
    assert (a.path / "s.csv").read_bytes() == (tmp_path / "pandas.csv").read_bytes()     # staged file
    ib = b.write_table("s", table, "d")
    assert ia == ib and ia["rows"] == 500 and ia["parquet"] is None


def test_other_tables_go_through_pandas(tmp_path):
    rd = RunDir(tmp_path / "r", "x").prepare()
    info = publish.write_series(rd, "s", {"n": np.arange(3), "v": [0.5, 1.5, 2.5]})
    assert info["rows"] == 3 and (rd.path / "s.csv").read_text().splitlines()[1] == "0,0.5"


def test_minmax_decimation_keeps_the_envelope():
    rng = np.random.default_rng(2)
    t = np.arange(200_000) * 0.01
    y = np.sin(t / 30) + rng.standard_t(3, t.size)
    y[1234] = np.nan
    xs, ys = P.minmax_decimate(t, y, 800)
    assert xs.size <= 4 * 800 + 800 and np.all(np.diff(xs) > 0)
    # every pixel column keeps its extremes: the same min and max per column
    cols = np.minimum((t / t[-1] * 800).astype(int), 799)
    for c in (0, 57, 400, 799):
        m = cols == c
        k = np.minimum((xs / t[-1] * 800).astype(int), 799) == c
        assert np.nanmax(ys[k]) == np.nanmax(y[m]) and np.nanmin(ys[k]) == np.nanmin(y[m])
    assert np.isnan(ys).any()                               # the gap stays a gap


def _figs():
    out = []
    for k in range(2):
        fig, axes = P.figure(2)
        t = np.linspace(0, 100, 2001)
        for ax in axes:
            P.components(ax, t, np.c_[np.sin(t * (k + 1)), np.cos(t)], ["a", "b"], "y [m]")
        out.append(Figure(f"f{k}", fig, f"caption {k}. more"))
    return out


def test_worker_processes_draw_the_same_figures(monkeypatch, tmp_path):
    """Serial and forked drawing write the same PNG files (each process writes what it
    draws, under temporary names)."""
    images = {}
    for procs in (1, 2):
        monkeypatch.setattr(publish, "MAX_FIGURE_PROCESSES", procs)
        d = tmp_path / str(procs)
        d.mkdir()
        images[procs] = [(open(p, "rb").read(), open(s, "rb").read())
                         for p, s in publish._render_all(_figs(), 80, d)]
        assert len(list(d.iterdir())) == 4
    assert [p for p, _ in images[1]] == [p for p, _ in images[2]]
