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

__all__ = ["figure", "time_axis", "components", "envelope", "COLORS", "error_figure"]

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
