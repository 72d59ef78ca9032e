"""Writing a run's figures and report, timed: the run folder must cost less than the run.

:func:`write_figures` thins every long line of a figure to what its pixels can show
(:func:`sinslab.app.plotting.thin_lines`, min/max per pixel column, so the drawn envelope
is the full data's) before saving it as PNG and SVG; the full-rate data stay in the
series files. :func:`complete_timed` renders the report once to time it, records the
stage times in ``summary["timing"]`` and completes the run folder.
"""
from __future__ import annotations

import os
import time

from sinslab.app.errors import pause
from sinslab.core.blocks import release_free_memory

#: At most this many processes (the run's own and forked workers) draw figures at once.
MAX_FIGURE_PROCESSES = 4

__all__ = ["render_figure", "write_figures", "complete_timed", "describe_series", "write_series"]


def render_figure(fig, dpi: int = 110) -> tuple[bytes, bytes]:
    """``(png, svg)`` bytes of a matplotlib figure, laid out once and drawn once.

    Layout: a plain grid of axes is placed by :func:`sinslab.app.layout.lay_out` (the
    positions constrained layout gives it, from one measurement of the decorations);
    any other figure by its own layout engine during the draw; the positions are then
    frozen. Draw: once, on Agg, recording the primitives (:mod:`sinslab.app.svgcopy`); the
    SVG is written from that record, or drawn again when the record cannot be replayed.
    No ``bbox_inches="tight"`` pass (it draws the whole figure once more only to measure it).
    """
    import io

    import matplotlib
    from matplotlib.backend_bases import FigureCanvasBase
    from matplotlib.backends.backend_svg import FigureCanvasSVG

    from sinslab.app.layout import lay_out
    from sinslab.app.svgcopy import RecordingCanvas, write_svg

    fig.set_dpi(dpi)
    canvas = RecordingCanvas(fig)
    if lay_out(fig, canvas.get_renderer()):
        fig.set_layout_engine("none")
    canvas.draw()
    if fig.get_layout_engine() is not None:
        fig.set_layout_engine("none")
    png = _png(canvas, dpi)
    try:
        svg = write_svg(canvas)
    except Exception:          # the copy leans on matplotlib's renderer internals: if a
        svg = None             # release changes them, the SVG is drawn the usual way
    if svg is None:
        buf = io.BytesIO()
        # text as <text> elements rather than glyph outlines: less to write, searchable labels
        with matplotlib.rc_context({"svg.fonttype": "none"}):
            FigureCanvasSVG(fig).print_svg(buf)
        fig.set_dpi(dpi)                           # print_svg leaves it at 72
        svg = buf.getvalue()
    FigureCanvasBase(fig)                          # let the raster buffer and the record go
    return png, svg


def _png(canvas, dpi: int) -> bytes:
    """PNG bytes of the canvas' last draw, with matplotlib's metadata and dpi.

    An opaque figure (every figure here: white background) is stored as RGB: the same
    pixels as RGBA without the constant alpha channel, about 10 % smaller and quicker to
    compress. zlib level 3: faster to encode than the default 6, files about 6 % larger.
    """
    import io

    import matplotlib
    import numpy as np
    from PIL import Image, PngImagePlugin

    rgba = np.asarray(canvas.buffer_rgba())
    h, w = rgba.shape[:2]
    image = Image.frombuffer("RGBA", (w, h), rgba, "raw", "RGBA", 0, 1)
    if rgba[..., 3].min() == 255:
        image = image.convert("RGB")
    info = PngImagePlugin.PngInfo()
    info.add_text("Software", f"Matplotlib version{matplotlib.__version__}, https://matplotlib.org/")
    out = io.BytesIO()
    image.save(out, format="png", pnginfo=info, dpi=(dpi, dpi), compress_level=3)
    return out.getvalue()


#: Figures waiting to be rendered, the order to take them in and the shared count of
#: those taken (read by :func:`_take_and_render` in the run's process and in the forked
#: workers, which inherit this module's state at fork time).
_PENDING: list = []
_ORDER: list = []
_TAKEN = None


def _worker_init():
    """A drawing worker leaves Ctrl-C to the run and ends quietly when told to. It does
    without the cyclic garbage collector: it lives for a few figures, whose artists'
    cycles cost more to trace (about 5 % of drawing) than to keep until it exits."""
    import gc
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    gc.disable()


def _render_to_files(fig, dpi: int, folder, key: str) -> tuple[str, str]:
    """Draw ``fig`` (:func:`render_figure`) and write its PNG and SVG to files in
    ``folder`` under temporary names made of ``key``; return their paths. The process that
    draws a figure writes it: a long run's SVG is megabytes, which would otherwise be
    held, and sent between processes, until every figure is drawn."""
    png, svg = render_figure(fig, dpi)
    paths = []
    for ext, data in (("png", png), ("svg", svg)):
        path = os.path.join(os.fspath(folder), f".{key}.{ext}.{os.getpid()}.part")
        with open(path, "wb") as fh:
            fh.write(data)
        paths.append(path)
    del png, svg, data
    # a figure's drawing memory (the raster, the recorded primitives, the SVG text) is
    # freed but kept by the allocators: given back, the next figure reuses the system's
    release_free_memory()
    return paths[0], paths[1]


def _take_and_render(dpi: int, folder) -> list[tuple[int, tuple[str, str]]]:
    """Take the next figure not yet taken by any process and draw it, until none is left;
    ``[(index, (png path, svg path))]`` of those drawn here."""
    done = []
    while True:
        with _TAKEN.get_lock():
            k = _TAKEN.value
            _TAKEN.value = k + 1
        if k >= len(_ORDER):
            return done
        i = _ORDER[k]
        done.append((i, _render_to_files(_PENDING[i].fig, dpi, folder, f"figure{i}")))


def _drawing_cost(fig) -> int:
    """Rough relative cost of drawing ``fig``: its axes, counting a logarithmic axis twice
    (many minor ticks, math-text labels)."""
    return sum(1 + (ax.get_xscale() != "linear") + (ax.get_yscale() != "linear")
               for ax in fig.axes if ax.get_visible())


def _render_all(figures, dpi: int, folder) -> list[tuple[str, str]]:
    """PNG and SVG files of every figure, in order, written to temporary names in
    ``folder`` (:func:`_render_to_files`); drawn by this process and forked workers, one
    per further core, when there are several figures and cores (drawing is pure Python
    and holds the GIL, so threads would not help), serially otherwise or if the workers
    cannot be used. Each process takes the costliest figure left, so that cheap ones end
    the last turns."""
    global _PENDING, _ORDER, _TAKEN
    import gc
    import multiprocessing as mp

    n = min(len(figures), os.cpu_count() or 1, MAX_FIGURE_PROCESSES)
    # a daemonic process (a Dask worker drawing a demo run's figures) may have no children
    if n >= 2 and "fork" in mp.get_all_start_methods() and not mp.current_process().daemon:
        ctx = mp.get_context("fork")
        pool = None
        collecting, frozen = gc.isenabled(), gc.get_freeze_count()
        # Objects of the run's computation, inherited by the workers, would otherwise be
        # traversed by a worker's first full garbage collection (~0.1 s for a few 1e5
        # objects, each page touched copied): frozen, the collector skips them.
        gc.freeze()
        try:
            _PENDING = list(figures)
            _ORDER = sorted(range(len(figures)), key=lambda i: -_drawing_cost(figures[i].fig))
            _TAKEN = ctx.Value("i", 0)
            pool = ctx.Pool(n - 1, initializer=_worker_init)
            theirs = [pool.apply_async(_take_and_render, (dpi, folder)) for _ in range(n - 1)]
            pause("figures")
            gc.disable()                             # as in the workers, while drawing
            drawn = _take_and_render(dpi, folder)
            for r in theirs:
                drawn += r.get()
            pool.close()                             # let the workers end on their own
            pool.join()
            pool = None
            images = [None] * len(figures)
            for i, image in drawn:
                images[i] = image
            return images
        except (OSError, mp.ProcessError, RuntimeError):
            pass                                     # no processes here: draw in this one
        finally:
            _PENDING, _ORDER, _TAKEN = [], [], None
            if pool is not None:                      # interrupted or failed: stop them
                pool.terminate()
            if collecting:
                gc.enable()
            if not frozen:
                gc.unfreeze()
    pause("figures")
    return [_render_to_files(f.fig, dpi, folder, f"figure{i}") for i, f in enumerate(figures)]


def _ensure_title(f) -> None:
    """Give a figure without a title (suptitle) one, from its caption's first sentence, so
    every figure of a report carries its title the same way."""
    fig = f.fig
    if getattr(fig, "_suptitle", None) is not None and fig._suptitle.get_text():
        return
    text = (f.caption or f.name).strip()
    for sep in (". ", "; ", ": "):
        text = text.split(sep)[0]
    text = text.rstrip(".")
    if len(text) > 90:
        text = text[:90].rsplit(" ", 1)[0] + " …"
    fig.suptitle(text)


def write_figures(rd, figures, dpi: int = 110) -> list[dict]:
    """Save ``figures`` (:class:`sinslab.app.outputs.Figure`) into the run folder ``rd`` as
    ``NAME.png`` and ``NAME.svg``, in order; return their summary entries.

    A figure without a title gets one from its caption; lines are thinned to the figure's
    pixel columns (see the module notes); the figures are drawn concurrently when there
    are several (:func:`_render_all`).
    """
    if not figures:
        return []
    from sinslab.app.plotting import thin_lines

    images = []
    try:
        for f in figures:
            _ensure_title(f)
            thin_lines(f.fig, dpi)
        images = _render_all(figures, dpi, rd.path)
    finally:
        for f in figures:
            if getattr(f.fig.canvas, "manager", None) is not None:
                import matplotlib.pyplot as plt
                plt.close(f.fig)
    out = []
    try:
        for f, (png, svg) in zip(figures, images):
            info = {"name": f.name, "caption": f.caption, "png": f"{f.name}.png", "svg": f"{f.name}.svg"}
            rd.move_in(info["png"], png)
            rd.move_in(info["svg"], svg)
            rd.figure_files.append(info)
            out.append(info)
    finally:
        for path in (p for pair in images for p in pair):
            if os.path.exists(path):                      # not renamed: a failure on the way
                os.remove(path)
    return out


def complete_timed(rd, summary: dict) -> dict:
    """Time the report of ``summary``, record it in ``summary["timing"]["report_s"]``, then
    write ``summary.json`` and ``report.html`` and mark the run complete."""
    from sinslab.app import report

    t0 = time.perf_counter()
    report.render(rd.path, summary=summary)
    summary.setdefault("timing", {})["report_s"] = time.perf_counter() - t0
    return rd.complete(summary)


#: Column-name suffix -> what it says about the unit (the series' naming convention).
_SUFFIX_UNITS = (("_arcmin", "arcmin"), ("_arcsec", "arcsec"), ("_mps", "m/s"), ("_dph", "deg/h"),
                 ("_deg", "deg"), ("_ug", "µg"), ("_m", "m"), ("_s", "s"))


def describe_series(name: str, table) -> str:
    """A one-line description of a time-series table from its columns (name suffixes carry
    the units): "8 columns against t_s [s]: phiE_arcmin, ... (units: arcmin, deg/h)"."""
    cols = [str(c) for c in (table.columns if hasattr(table, "columns") else table.keys())]
    time_cols = [c for c in cols if c in ("t_s", "t", "time_s", "t_abs_s")]
    data = [c for c in cols if c not in time_cols]
    units = []
    for c in data:
        for suf, u in _SUFFIX_UNITS:
            if c.endswith(suf) and u not in units:
                units.append(u)
                break
    against = f" against {time_cols[0]} [s]" if time_cols else ""
    shown = ", ".join(data[:6]) + (", …" if len(data) > 6 else "")
    return (f"{name.replace('_', ' ')}: {len(data)} column(s){against} — {shown}"
            + (f" (units in the column suffixes: {', '.join(units)})" if units else ""))


def write_series(rd, name: str, table, description: str = "") -> dict:
    """Write a time-series table into the run folder ``rd``; return its summary entry.

    A dict of float columns is written a chunk at a time by
    :class:`sinslab.app.tablefile.TableWriter`, byte for byte as
    ``pandas.DataFrame.to_csv(float_format="%.10g")`` writes it (NaN as an empty field),
    so a run need not import pandas (half a second or more) only to write a table;
    anything else goes through pandas (:meth:`sinslab.app.outputs.RunDir.write_table`).
    """
    return rd.write_table(name, table, description)
