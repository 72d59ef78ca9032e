"""Shared figure helpers: one look for every experiment's figures.

Figures are built on :class:`matplotlib.figure.Figure` directly (no pyplot state, no GUI
backend needed); the framework saves them as PNG and SVG. Typical use in an experiment::

    from sinslab.app import plotting as P

    fig, axes = P.figure(3, sharex=True)
    tt, tlabel = P.time_axis(t)
    P.components(axes[0], tt, pos_err_m, ["east", "north", "up"], "position error [m]")
    ...
    axes[-1].set_xlabel(tlabel)
    return Figure("pos_err", fig, "caption")

Angles printed in figures say which convention they use (heading clockwise from north,
or yaw counter-clockwise) — the labels are the caller's job.
"""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure as _MplFigure

__all__ = ["figure", "time_axis", "components", "envelope", "COLORS", "error_figure", "minmax_decimate",
           "thin_lines"]

#: Colours for x/east/pitch, y/north/roll, z/up/heading, then extras.
COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"]


def figure(nrows: int = 1, ncols: int = 1, *, sharex: bool = True, width: float = 8.0,
           row_height: float = 2.4, title: str | None = None):
    """A new figure and a flat array of axes (``nrows*ncols``), grid on, tight layout."""
    fig = _MplFigure(figsize=(width, row_height * nrows + (0.4 if title else 0.0)),
                     layout="constrained")
    axes = fig.subplots(nrows, ncols, sharex=sharex, squeeze=False).ravel()
    for ax in axes:
        ax.grid(True, alpha=0.35)
    if title:
        fig.suptitle(title)
    return fig, axes


def time_axis(t_s):
    """Scale times [s] to s, min or h for plotting: returns ``(t_scaled, label)``."""
    t = np.asarray(t_s, dtype=float)
    span = float(t[-1] - t[0]) if t.size else 0.0
    if span > 3 * 3600:
        return t / 3600.0, "time [h]"
    if span > 600:
        return t / 60.0, "time [min]"
    return t, "time [s]"


def components(ax, t, y, labels, ylabel: str = "", styles=None):
    """Plot the columns of ``y`` (N, k) against ``t`` with a legend."""
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    for i in range(y.shape[1]):
        kw = dict(color=COLORS[i % len(COLORS)], lw=1.2,
                  label=labels[i] if i < len(labels) else None)
        if styles:
            kw.update(styles[i])
        ax.plot(t, y[:, i], **kw)
    if ylabel:
        ax.set_ylabel(ylabel)
    if labels:
        ax.legend(loc="best", fontsize="small", ncol=min(len(labels), 4))
    return ax


def envelope(ax, t, bound, label: str = "bound", color: str = "0.3"):
    """Dashed ±bound lines (e.g. a closed-form error envelope or ±σ)."""
    b = np.broadcast_to(np.asarray(bound, float), np.shape(t))
    ax.plot(t, b, ls="--", color=color, lw=1.0, label=label)
    ax.plot(t, -b, ls="--", color=color, lw=1.0)
    return ax


def error_figure(t_s, blocks, title: str | None = None):
    """One subplot per block ``(ylabel, y (N,k), labels)`` against time; returns the figure."""
    fig, axes = figure(len(blocks), title=title)
    tt, tlabel = time_axis(t_s)
    for ax, (ylabel, y, labels) in zip(axes, blocks):
        components(ax, tt, y, labels, ylabel)
    axes[-1].set_xlabel(tlabel)
    return fig


def minmax_decimate(x, y, columns: int, edges=None):
    """Thin a line to what ``columns`` pixel columns can show, keeping its envelope.

    The samples are split into ``columns`` groups of consecutive samples (by index, so
    the x values must be sorted); each group is replaced by its first sample, its minimum,
    its maximum and its last sample in time order. Every extreme of ``y`` survives, so the
    drawn line covers the same pixels as the full line. Lines of at most ``4·columns``
    samples are returned unchanged. NaN gaps are kept (a group holding a NaN keeps one).

    Parameters
    ----------
    x, y : array_like, shape (N,)
        Sorted abscissae and ordinates.
    columns : int
        Pixel columns of the axes the line is drawn in.
    edges : array_like of int (columns + 1,), optional
        The groups' boundaries (default: ``columns`` equal groups); given, the line is
        thinned whatever its length (a piece of a longer line thinned on its own groups).

    Returns
    -------
    x, y : ndarray, shape (M,), M <= 4·columns (+ NaN markers)
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    n = y.size
    if edges is None:
        if n <= 4 * columns or columns < 1:
            return x, y
        edges = np.linspace(0, n, columns + 1).astype(np.int64)
    edges = np.asarray(edges, dtype=np.int64)
    starts = edges[:-1]
    ends = edges[1:] - 1
    bad = np.isnan(y)
    yf = np.where(bad, np.inf, y)
    imin = np.minimum.reduceat(yf, starts)
    yf = np.where(bad, -np.inf, y)
    imax = np.maximum.reduceat(yf, starts)
    # indices of the min and max inside each group
    grp = np.repeat(np.arange(columns), np.diff(edges))
    kmin = np.full(columns, -1, np.int64)
    kmax = np.full(columns, -1, np.int64)
    hit = np.flatnonzero(y == imin[grp])
    kmin[grp[hit[::-1]]] = hit[::-1]               # first index of the minimum
    hit = np.flatnonzero(y == imax[grp])
    kmax[grp[hit[::-1]]] = hit[::-1]
    nan_grp = np.flatnonzero(np.add.reduceat(bad.astype(np.int64), starts) > 0)
    idx = [starts, ends, kmin[kmin >= 0], kmax[kmax >= 0]]
    if nan_grp.size:
        first_nan = np.flatnonzero(bad)
        g = grp[first_nan]
        keep = np.r_[True, g[1:] != g[:-1]]
        idx.append(first_nan[keep])
    k = np.unique(np.concatenate(idx))
    return x[k], y[k]


def thin_lines(fig, dpi: float = 110.0) -> int:
    """Decimate every long line of ``fig`` to its axes' pixel width (:func:`minmax_decimate`).

    Drawing cost (PNG and above all SVG) grows with the number of vertices, not with what
    a screen shows; the full-rate data stay in the run's series files. Only lines with
    sorted x are thinned (time series); others are left as they are. Returns the number
    of lines thinned.
    """
    n_thinned = 0
    width_in = fig.get_figwidth()
    for ax in fig.axes:
        cols = max(int(ax.get_position().width * width_in * dpi), 50)
        for line in ax.get_lines():
            x = np.asarray(line.get_xdata(orig=True), dtype=float)
            y = np.asarray(line.get_ydata(orig=True), dtype=float)
            if x.ndim != 1 or x.shape != y.shape or y.size <= 4 * cols:
                continue
            dx = np.diff(x)
            if not (np.all(dx >= 0) or np.all(dx <= 0)):
                continue
            if line.get_marker() not in (None, "None", "", " ") and line.get_linestyle() in ("None", "", " "):
                continue                              # scattered markers: every point is data
            xs, ys = minmax_decimate(x, y, cols)
            line.set_data(xs, ys)
            n_thinned += 1
    return n_thinned
