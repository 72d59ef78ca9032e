"""Figure layout (sinslab.app.layout) on figures built by the experiments' and commands' own
code, as the run folder renders them (publish.render_figure).

Oracle, with the Agg renderer's extents of what was drawn: every text (suptitle, titles,
axis labels, offset texts, drawn tick labels, legend entries and frames, other texts)
lies inside the figure, and no decoration of one axes (its tick labels, axis labels,
title, offset texts, legend) reaches into another axes' area or another axes' labels. The
check is shown to fail when the layout's margins are too small. Cross-check: a plain grid
is placed where matplotlib's constrained layout places it.
"""
import pickle
from pathlib import Path

import numpy as np
import pytest
from matplotlib.text import Text
from matplotlib.transforms import Bbox

from sinslab.app import layout
from sinslab.app import plotting as P
from sinslab.app.publish import _ensure_title, render_figure
from sinslab.app.outputs import Figure

LASER = Path(__file__).resolve().parents[3] / "shared" / "data" / "psins-lasergyro" / "lasergyro.imu"
TOL = 1.0                                              # [px]


def _drawn_tick_labels(axis):
    """Tick labels the draw showed: visible, non-empty, at a location inside the view."""
    lo, hi = sorted(axis.get_transform().transform(np.asarray(axis.get_view_interval(), float)))
    out = []
    for tick in [*axis.get_major_ticks(), *axis.get_minor_ticks()]:
        loc = axis.get_transform().transform(np.asarray([tick.get_loc()], float))[0]
        span = max(hi - lo, 1e-300)
        if not (lo - 1e-9 * span <= loc <= hi + 1e-9 * span):
            continue
        out += [t for t in (tick.label1, tick.label2) if t.get_visible() and t.get_text().strip()]
    return out


def _decorations(ax, renderer):
    """``[(what, bbox)]`` of what is drawn around ``ax`` [px]."""
    texts = [("tick label", t) for axis in (ax.xaxis, ax.yaxis) for t in _drawn_tick_labels(axis)]
    texts += [("axis label", a.label) for a in (ax.xaxis, ax.yaxis)]
    texts += [("offset text", a.offsetText) for a in (ax.xaxis, ax.yaxis)]
    texts += [("title", t) for t in (ax.title, ax._left_title, ax._right_title)]
    out = [(f"{w} {t.get_text()!r}", t.get_window_extent(renderer)) for w, t in texts
           if t.get_visible() and t.get_text().strip()]
    leg = ax.get_legend()
    if leg is not None and leg.get_visible():
        out.append(("legend", leg.get_window_extent(renderer)))
    return out


def _overlap(a, b, tol=TOL):
    return min(a.x1, b.x1) - max(a.x0, b.x0) > tol and min(a.y1, b.y1) - max(a.y0, b.y0) > tol


def problems(fig):
    """What is clipped or overlaps in ``fig`` as last drawn (empty: a clean layout)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    # the PNG's draw once more (positions are frozen): axis labels keep the place of the
    # last draw in pixels, and a figure whose SVG was drawn again was last drawn at 72 dpi
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    page = Bbox.from_bounds(0, 0, fig.bbox.width, fig.bbox.height)
    axes = [ax for ax in fig.axes if ax.get_visible()]
    found = []
    texts = [t for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()
             and (t.axes is None or t.axes.get_visible())]
    # tick labels: only those drawn (an axis keeps spare ticks, unplaced, for other sizes)
    tick_texts = {id(t) for ax in fig.axes for a in (ax.xaxis, ax.yaxis)
                  for tick in [*a.majorTicks, *a.minorTicks] for t in (tick.label1, tick.label2)}
    drawn = {id(t) for ax in axes for a in (ax.xaxis, ax.yaxis) for t in _drawn_tick_labels(a)}
    boxes = [(f"text {t.get_text()!r}", t.get_window_extent(renderer)) for t in texts
             if id(t) not in tick_texts or id(t) in drawn]
    boxes += [("legend", ax.get_legend().get_window_extent(renderer)) for ax in axes if ax.get_legend()]
    for what, bb in boxes:
        if bb.x0 < page.x0 - TOL or bb.y0 < page.y0 - TOL or bb.x1 > page.x1 + TOL or bb.y1 > page.y1 + TOL:
            found.append(f"{what} leaves the figure: {np.round(bb.extents, 1).tolist()}")
    decorations = {id(ax): _decorations(ax, renderer) for ax in axes}
    for a in axes:
        for b in axes:
            if a is b:
                continue
            for what, bb in decorations[id(a)]:
                if _overlap(bb, b.bbox):
                    found.append(f"{what} of axes {axes.index(a)} overlaps axes {axes.index(b)}")
                for other, ob in decorations[id(b)]:
                    if id(a) < id(b) and _overlap(bb, ob):
                        found.append(f"{what} of axes {axes.index(a)} overlaps {other} of axes {axes.index(b)}")
    sup = fig._suptitle
    if sup is not None and sup.get_visible() and sup.get_text():
        sb = sup.get_window_extent(renderer)
        for ax in axes:
            for what, bb in [("axes", ax.bbox), *decorations[id(ax)]]:
                if _overlap(sb, bb):
                    found.append(f"suptitle overlaps {what} of axes {axes.index(ax)}")
    return found


def _quick_figures(name):
    from support import run_experiment

    return run_experiment(name).figures


def _grid_figure():
    """A 3x3 grid with what experiments put on their panels: titles, a suptitle, legends
    inside and below an axes, a logarithmic axis, an offset text, a hidden panel."""
    fig, ax = P.figure(3, 3, width=11.0, row_height=2.3, title="a grid of panels")
    t = np.linspace(0, 1800.0, 4000)
    for i, a in enumerate(ax[:8]):
        a.plot(t / 60, np.sin(t / (50 + 10 * i)) * 10.0 ** (i - 3), label="estimate")
        a.plot(t / 60, np.cos(t / 70) * 10.0 ** (i - 3), "--", label="truth")
        a.set_title(f"panel {i} [unit]", fontsize="small")
        if i % 3 == 0:
            a.set_ylabel("error [arcmin]")
    ax[4].semilogy(t / 60, 1e-3 + np.abs(np.sin(t / 40)) * 1e3, label="|x|")
    ax[5].plot(t / 60, 1.2345e6 + np.sin(t / 90), label="offset")
    ax[0].legend(fontsize="x-small")
    ax[7].legend(fontsize=7, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.3))
    ax[8].set_visible(False)
    for a in ax[5:8]:
        a.set_xlabel("time [min]")
        a.xaxis.set_tick_params(labelbottom=True)
    return Figure("grid", fig, "grid")


@pytest.fixture(scope="module")
def figures():
    figs = _quick_figures("static-alignment") + _quick_figures("free-inertial") + [_grid_figure()]
    if LASER.exists():
        from sinslab.app.commands import allan

        figs += allan._compute(LASER, None, "0:600", lambda *a, **k: None, {}).figures
    for f in figs:
        _ensure_title(f)
    return pickle.dumps(figs)


def test_rendered_figures_have_no_clipped_or_overlapping_text(figures):
    figs = pickle.loads(figures)
    names = [f.name for f in figs]
    assert {"fig2_reduced", "fig3_full", "pos_err", "track", "grid"} <= set(names)
    for f in figs:
        render_figure(f.fig)
        assert problems(f.fig) == [], f.name


def test_the_check_fails_when_margins_are_too_small(figures, monkeypatch):
    # margins measured without any decoration: the axes fill the figure up to the pads
    monkeypatch.setattr(layout, "_decorations", lambda ax, renderer: ax.get_window_extent(renderer))
    for f in pickle.loads(figures):
        if f.name in ("fig3_full", "grid", "pos_err"):
            render_figure(f.fig)
            assert problems(f.fig), f.name


def test_the_check_fails_when_margins_are_a_little_too_small(figures, monkeypatch):
    # every margin 12 px short of the decorations, more than the pads (3 pt = 4.6 px at the
    # figure's edge, twice that between panels) absorb
    real = layout._decorations

    def short(ax, renderer):
        bb, box = real(ax, renderer), ax.get_window_extent(renderer)
        return Bbox([[min(box.x0, bb.x0 + 12), min(box.y0, bb.y0 + 12)],
                     [max(box.x1, bb.x1 - 12), max(box.y1, bb.y1 - 12)]])

    monkeypatch.setattr(layout, "_decorations", short)
    f = next(f for f in pickle.loads(figures) if f.name == "grid")
    render_figure(f.fig)
    assert problems(f.fig)


def test_plain_grids_land_where_constrained_layout_puts_them(figures):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    checked = 0
    for f in pickle.loads(figures):
        if any(ax.get_aspect() != "auto" for ax in f.fig.axes):
            continue                                 # view limits follow the box: see the module notes
        a, b = pickle.loads(pickle.dumps(f.fig)), f.fig
        for fig in (a, b):
            fig.set_dpi(110)
            FigureCanvasAgg(fig)
        a.get_layout_engine().execute(a)
        assert layout.lay_out(b, b.canvas.get_renderer()), f.name
        for pa, pb in zip(a.axes, b.axes):
            if pa.get_visible():
                da = np.abs(np.subtract(pa.get_position(original=True).extents,
                                        pb.get_position(original=True).extents))
                px = da * [a.bbox.width, a.bbox.height, a.bbox.width, a.bbox.height]
                assert np.all(px < 1.5), (f.name, px)
        checked += 1
    assert checked >= 5


def test_figures_that_are_not_plain_grids_keep_constrained_layout():
    fig, ax = P.figure(1, 2, sharex=False)
    img = ax[0].imshow(np.arange(12.0).reshape(3, 4))
    fig.colorbar(img, ax=ax[0])
    ax[1].plot([0, 1], [0, 1])
    ax[1].set_xlabel("x [m]")
    fig.set_dpi(110)
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    assert not layout.lay_out(fig, FigureCanvasAgg(fig).get_renderer())
    twin, tax = P.figure(1)
    tax[0].twinx()
    assert not layout.lay_out(twin, FigureCanvasAgg(twin).get_renderer())
    render_figure(fig)                                # constrained layout, in the draw
    assert problems(fig) == []
