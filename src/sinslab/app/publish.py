"""Writing a run's figures and report, timed: the run folder must cost less than the run.

:func:`write_figures` thins every long line of a figure to what its pixels can show
(:func:`sinslab.app.plotting.thin_lines`, min/max per pixel column, so the drawn envelope
is the full data's) before saving it as PNG and SVG; the full-rate data stay in the
series files. :func:`complete_timed` renders the report once to time it, records the
stage times in ``summary["timing"]`` and completes the run folder.
"""
from __future__ import annotations

import time

__all__ = ["render_figure", "write_figures", "complete_timed"]


def render_figure(fig, dpi: int = 110) -> tuple[bytes, bytes]:
    """``(png, svg)`` bytes of a matplotlib figure, laid out once.

    The figure's layout engine (constrained layout) runs for the PNG and is then frozen,
    so the SVG reuses the same axes positions instead of laying the figure out again; no
    ``bbox_inches="tight"`` pass (it draws the whole figure once more only to measure it).
    """
    import io

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.backends.backend_svg import FigureCanvasSVG

    # The canvases' print methods draw exactly once each; ``savefig`` would add a
    # layout-only draw before every format.
    png, svg = io.BytesIO(), io.BytesIO()
    fig.set_dpi(dpi)
    # zlib level 3: faster to encode than the default 6, files about 10 % larger
    FigureCanvasAgg(fig).print_png(png, pil_kwargs={"compress_level": 3})
    if fig.get_layout_engine() is not None:
        fig.set_layout_engine("none")
    FigureCanvasSVG(fig).print_svg(svg)
    return png.getvalue(), svg.getvalue()


def write_figures(rd, figures, dpi: int = 110) -> list[dict]:
    """Save ``figures`` (:class:`sinslab.app.outputs.Figure`) into the run folder ``rd`` as
    ``NAME.png`` and ``NAME.svg``, in order; return their summary entries.

    Lines are thinned to the figure's pixel columns first (see the module notes).
    """
    if not figures:
        return []
    from sinslab.app.plotting import thin_lines

    out = []
    for f in figures:
        try:
            thin_lines(f.fig, dpi)
            png, svg = render_figure(f.fig, dpi)
        finally:
            if getattr(f.fig.canvas, "manager", None) is not None:
                import matplotlib.pyplot as plt
                plt.close(f.fig)
        info = {"name": f.name, "caption": f.caption, "png": f"{f.name}.png", "svg": f"{f.name}.svg"}
        rd.write_bytes(info["png"], png)
        rd.write_bytes(info["svg"], svg)
        rd.figure_files.append(info)
        out.append(info)
    return out


def complete_timed(rd, summary: dict) -> dict:
    """Time the report of ``summary``, record it in ``summary["timing"]["report_s"]``, then
    write ``summary.json`` and ``report.html`` and mark the run complete."""
    from sinslab.app import report

    t0 = time.perf_counter()
    report.render(rd.path, summary=summary)
    summary.setdefault("timing", {})["report_s"] = time.perf_counter() - t0
    return rd.complete(summary)
