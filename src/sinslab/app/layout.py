"""Laying out a plain grid of axes from one measurement of its decorations.

:func:`lay_out` puts the axes of a figure made by :func:`sinslab.app.plotting.figure`
where matplotlib's constrained layout puts them for a plain grid — per grid column the
widest left and right decorations (tick labels, axis labels, offset text, legends outside
the axes), per grid row the tallest top and bottom ones, the same pads between and around
the cells, the suptitle on top — but without constrained layout's constraint solver and
its second measuring pass, which always runs and costs as much as the first (each pass
updates every axis' ticks and measures every tick label).

The decorations are measured at provisional positions close to the final ones. Their size
does not depend on where the axes sit as long as each axis shows the same ticks (same
view interval, locations, labels and offset), so after placing the axes the ticks are
computed again (locator and formatter only, no measuring) and the figure is measured
once more only if they changed — or while an axes has a legend or text outside its area
that has not settled (it is placed at a fraction of the axes' size, which the layout
changes). As in constrained layout, a margin re-measured because ticks changed never
shrinks below the earlier measurement, so that labels that come and go cannot make the
passes oscillate. A figure that has not settled after :data:`MAX_PASSES` passes is left
to constrained layout.

Figures this does not cover (colorbars, twinned or inset axes, cells spanning rows or
columns, nested grids, figure legends, sub-figures, supx/ylabels, another layout engine)
are left to their layout engine: :func:`lay_out` returns False for them.
"""
from __future__ import annotations

__all__ = ["lay_out"]

#: Measuring passes at most (usually one; a legend below an axes takes three or four).
MAX_PASSES = 5


def _plain_grid(fig):
    """``(gridspec, {(row, col): axes}, constrained-layout params)`` or None."""
    from matplotlib.gridspec import GridSpec
    from matplotlib.layout_engine import ConstrainedLayoutEngine

    engine = fig.get_layout_engine()
    if not isinstance(engine, ConstrainedLayoutEngine):
        return None
    params = engine.get()
    if tuple(params["rect"]) != (0, 0, 1, 1) or getattr(engine, "_compress", False):
        return None
    if fig.subfigs or fig.legends or fig._supxlabel is not None or fig._supylabel is not None:
        return None
    gs, cells = None, {}
    for ax in fig.axes:
        ss = ax.get_subplotspec()
        if (ss is None or not ax.get_in_layout() or ax.get_axes_locator() is not None
                or ax._colorbars or ax.child_axes):
            return None
        g = ss.get_gridspec()
        if type(g) is not GridSpec or (gs is not None and g is not gs):
            return None
        gs = g
        if len(ss.rowspan) != 1 or len(ss.colspan) != 1:
            return None
        cell = (ss.rowspan.start, ss.colspan.start)
        if cell in cells:                          # twinned axes share a cell
            return None
        cells[cell] = ax
    if gs is None:
        return None
    return gs, cells, params


def _ticks(ax):
    """What an axes' decorations depend on besides their fonts: per axis the view
    interval and the major and minor tick locations, labels and offset text."""
    ax.apply_aspect()
    out = []
    for axis in (ax.xaxis, ax.yaxis):
        out.append(tuple(axis.get_view_interval()))
        for level in (axis.major, axis.minor):
            locs = level.locator()
            out.append(tuple(locs))
            out.append(tuple(level.formatter.format_ticks(locs)))
            out.append(level.formatter.get_offset())
    return out


def _decorations(ax, renderer):
    """Bounding box [px] of ``ax`` and everything drawn around it, as constrained layout
    measures it (``Axes.get_tightbbox(for_layout_only=True)``), except that the spines'
    extent — the axes' edges plus the tick marks pointing out of them — is taken from the
    tick length instead of from each spine, which would update its axis' ticks once more.
    A spine moved off the axes' edge is measured as it is."""
    from matplotlib.spines import Spine
    from matplotlib.transforms import Bbox

    extras = [a for a in ax.get_default_bbox_extra_artists()
              if not (isinstance(a, Spine) and a.get_position() == ("outward", 0.0))]
    bb = ax.get_tightbbox(renderer, bbox_extra_artists=extras, for_layout_only=True)
    box = ax.get_window_extent(renderer)
    x0, y0, x1, y1 = box.extents
    px = ax.get_figure(root=True).dpi / 72.0
    for axis, (low, high) in ((ax.xaxis, ("bottom", "top")), (ax.yaxis, ("left", "right"))):
        if not (ax.axison and axis.get_visible()):
            continue
        ticks = [t[0] for t in (axis.majorTicks, axis.minorTicks) if t]
        for side, first in ((low, True), (high, False)):
            spine = ax.spines.get(side)
            if spine is None or not spine.get_visible() or spine.get_position() != ("outward", 0.0):
                continue
            out = max((t.get_tick_padding() * px for t in ticks
                       if (t.tick1line if first else t.tick2line).get_visible()), default=0.0)
            if side == "bottom":
                y0 = min(y0, box.y0 - out)
            elif side == "top":
                y1 = max(y1, box.y1 + out)
            elif side == "left":
                x0 = min(x0, box.x0 - out)
            else:
                x1 = max(x1, box.x1 + out)
    return Bbox.union([bb, Bbox([[x0, y0], [x1, y1]])])


def _outside(ax, renderer) -> bool:
    """Whether a legend or text of ``ax`` reaches out of its area (its place is then a
    fraction of the axes' size, which the layout changes)."""
    box = ax.bbox
    for a in [ax.get_legend(), *ax.texts]:
        if a is None or not a.get_visible() or not a.get_in_layout():
            continue
        bb = a.get_window_extent(renderer)
        if (bb.x0 < box.x0 - 0.5 or bb.x1 > box.x1 + 0.5 or bb.y0 < box.y0 - 0.5
                or bb.y1 > box.y1 + 0.5):
            return True
    return False


def _guess(fig, cells, nrows, ncols):
    """Provisional margins [px] per column (left, right) and row (top, bottom): typical
    decorations — a tick label of four characters, one line of tick labels, the axis
    labels and titles present — so that the first measurement is usually made at the
    final axes size, where the ticks are those drawn."""
    import matplotlib as mpl
    from matplotlib.font_manager import FontProperties

    rc = mpl.rcParams
    px = fig.dpi / 72.0

    def size(key):
        return FontProperties(size=rc[key]).get_size_in_points()

    yfs, xfs, lfs, tfs = size("ytick.labelsize"), size("xtick.labelsize"), size("axes.labelsize"), \
        size("axes.titlesize")
    left, right = [0.0] * ncols, [0.0] * ncols
    top, bottom = [0.0] * nrows, [0.0] * nrows
    for (r, c), ax in cells.items():
        lft = rc["ytick.major.size"]
        if ax.yaxis.get_tick_params().get("labelleft", True):
            lft += rc["ytick.major.pad"] + 2.4 * yfs
        if ax.yaxis.label.get_text():
            lft += rc["axes.labelpad"] + 1.2 * lfs
        bot = rc["xtick.major.size"]
        if ax.xaxis.get_tick_params().get("labelbottom", True):
            bot += rc["xtick.major.pad"] + 1.2 * xfs
        if ax.xaxis.label.get_text():
            bot += rc["axes.labelpad"] + 1.2 * lfs
        tp = rc["axes.titlepad"] + 1.2 * tfs if ax.get_title() else 0.0
        left[c] = max(left[c], lft * px)
        bottom[r] = max(bottom[r], bot * px)
        top[r] = max(top[r], tp * px)
    return left, right, top, bottom


def lay_out(fig, renderer) -> bool:
    """Place the axes of ``fig`` (figure made with constrained layout) as constrained
    layout would, from one measurement of their decorations where that suffices.

    Returns True when done (the caller then switches the figure's layout engine off so
    drawing keeps these positions), False when the figure is not a plain grid of axes or
    did not settle (see the module notes): its layout engine then places the axes anew.
    """
    grid = _plain_grid(fig)
    if grid is None:
        return False
    gs, cells, p = grid
    nrows, ncols = gs.get_geometry()
    W, H = fig.bbox.width, fig.bbox.height                       # [px]
    w_pad, h_pad = p["w_pad"] * fig.dpi, p["h_pad"] * fig.dpi     # [px]
    wspace = gs.wspace if gs.wspace is not None else p["wspace"]
    hspace = gs.hspace if gs.hspace is not None else p["hspace"]
    # pads of the cells (constrained layout's "cb" margins): w_pad around every cell, or
    # its share of wspace/hspace between cells when that is larger
    wgap = max(w_pad, wspace / 2 / ncols * W)
    hgap = max(h_pad, hspace / 2 / nrows * H)
    lpad = [w_pad if c == 0 else wgap for c in range(ncols)]
    rpad = [w_pad if c == ncols - 1 else wgap for c in range(ncols)]
    tpad = [h_pad if r == 0 else hgap for r in range(nrows)]
    bpad = [h_pad if r == nrows - 1 else hgap for r in range(nrows)]
    wr = gs.get_width_ratios() or [1.0] * ncols
    hr = gs.get_height_ratios() or [1.0] * nrows

    sup = fig._suptitle
    if sup is not None and (not sup.get_in_layout() or not sup.get_visible()):
        sup = None
    if sup is not None and getattr(sup, "_autopos", False):
        sup.set_position((sup.get_position()[0], 1.0 - h_pad / H))

    def place(left, right, top, bottom):
        head = 0.0
        if sup is not None:
            head = sup.get_tightbbox(renderer).height + 2 * h_pad
        aw = W - sum(lpad) - sum(rpad) - sum(left) - sum(right)
        ah = H - head - sum(tpad) - sum(bpad) - sum(top) - sum(bottom)
        if aw <= 0 or ah <= 0:
            return False
        xs, x = [], 0.0
        for c in range(ncols):
            x += lpad[c] + left[c]
            w = aw * wr[c] / sum(wr)
            xs.append((x, w))
            x += w + right[c] + rpad[c]
        ys, y = [], H - head
        for r in range(nrows):
            y -= tpad[r] + top[r]
            h = ah * hr[r] / sum(hr)
            ys.append((y - h, h))
            y -= h + bottom[r] + bpad[r]
        from matplotlib.transforms import Bbox
        for (r, c), ax in cells.items():
            (x0, w), (y0, h) = xs[c], ys[r]
            ax._set_position(Bbox.from_bounds(x0 / W, y0 / H, w / W, h / H))
        return True

    shown = {cell: ax for cell, ax in cells.items() if ax.get_visible()}
    left, right, top, bottom = _guess(fig, shown, nrows, ncols)
    if not place(left, right, top, bottom):
        return False
    # per axes (left, right, bottom, top) [px]; a column/row takes the largest
    need, ticks, anchored = {}, {}, set()
    todo = shown
    for _ in range(MAX_PASSES):
        for cell, ax in todo.items():
            ticks[cell] = _ticks(ax)
            pos = ax.get_position(original=True).transformed(fig.transFigure)
            bb = _decorations(ax, renderer)
            m = (pos.x0 - bb.x0, bb.x1 - pos.x1, pos.y0 - bb.y0, bb.y1 - pos.y1)
            old = need.get(cell)
            if _outside(ax, renderer):
                # a legend below the axes sits a fraction of the axes' height below it:
                # its margin follows the size, so the latest measurement counts
                settled = old is not None and max(abs(a - b) for a, b in zip(m, old)) < 0.5
                if settled:
                    anchored.discard(cell)
                else:
                    anchored.add(cell)
            elif old is not None:
                # ticks changed with the size: never below an earlier measurement (as in
                # constrained layout), so that labels that come and go cannot oscillate
                m = tuple(max(a, b) for a, b in zip(m, old))
            need[cell] = m
        left, right = [0.0] * ncols, [0.0] * ncols
        top, bottom = [0.0] * nrows, [0.0] * nrows
        for (r, c), m in need.items():
            left[c], right[c] = max(left[c], m[0]), max(right[c], m[1])
            bottom[r], top[r] = max(bottom[r], m[2]), max(top[r], m[3])
        if not place(left, right, top, bottom):
            return False
        # measure again what the new sizes may have changed: axes whose ticks changed, and
        # those whose legend or text outside has not settled yet
        todo = {cell: ax for cell, ax in shown.items() if cell in anchored or _ticks(ax) != ticks[cell]}
        if not todo:
            return True
    return False
