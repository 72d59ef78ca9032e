"""A figure of plain panels (:class:`sinslab.fusion.aids.base.PanelFigure`, what a plug-in
or the RTK engine reports) drawn for the run folder."""
from __future__ import annotations

import numpy as np

from sinslab.app.commands.runner import Figure

__all__ = ["panel_figure"]


def panel_figure(f, t0):
    """A figure of panels (:class:`sinslab.fusion.aids.base.PanelFigure`) drawn on one
    time axis (times from the filter start ``t0``)."""
    from sinslab.app import plotting
    fig, axes = plotting.figure(len(f.panels), 1, width=9.0)
    for ax, pan in zip(np.atleast_1d(axes), f.panels):
        for k, ln in enumerate(pan.lines):
            t = np.asarray(ln.t, dtype=float)
            y = np.asarray(ln.y, dtype=float)
            c = plotting.COLORS[k % len(plotting.COLORS)]
            (ax.semilogy if pan.log else ax.plot)(t, y, ln.style, lw=1, ms=1.5, color=c, label=ln.label or None)
            if ln.band is not None:
                b = np.asarray(ln.band, dtype=float)
                ax.fill_between(t, y - b, y + b, color=c, alpha=0.2, lw=0)
        for a, b in pan.spans:
            ax.axvspan(a, b, color="0.85", lw=0)
        ax.set_ylabel(pan.ylabel)
        if any(ln.label for ln in pan.lines):
            ax.legend(fontsize=8)
    np.atleast_1d(axes)[-1].set_xlabel("time since the filter start [s]")
    if f.title:
        fig.suptitle(f.title)
    return Figure(f.name, fig, f.caption)
