"""The SVG of a figure from its PNG draw: primitives recorded once, written twice.

Drawing a figure runs every artist's Python code — ticks computed and updated, every
text laid out, transforms composed — and matplotlib's SVG writer would run all of it a
second time. Here the raster draw goes through :class:`RecordingRenderer`, an Agg
renderer that also keeps every primitive it is handed (paths, markers, path collections,
text, groups) with its graphics state and transforms frozen; :func:`write_svg` then hands
the same primitives, scaled from pixels [px] to points [pt] (72/dpi), to matplotlib's
SVG renderer, which writes them as it would have (``svg.fonttype`` none: text as
``<text>`` elements, anchored where matplotlib anchors them).

The SVG therefore shows the PNG's figure: where text sizes enter a position (a label
beside tick labels, a legend frame around its entries, an arrow leaving an annotation's
text) it is the raster renderer's text metrics (hinted at the figure's dpi) that placed
it, where matplotlib's own SVG draw would use unhinted metrics at 72 dpi — text moves by
up to about a point, legend frames by up to about 3 pt; everything else (data, ticks,
grid, axes, patches) is written with the same numbers.

Figures whose draw hands over anything else (images, meshes, Gouraud shading, TeX text,
Agg filters, sketched paths, rasterized artists) are not copied: :func:`write_svg`
returns None for them and the caller draws the SVG the usual way.
"""
from __future__ import annotations

import io

import numpy as np
from matplotlib.backend_bases import GraphicsContextBase
from matplotlib.backends.backend_agg import FigureCanvasAgg, RendererAgg
from matplotlib.backends.backend_svg import RendererSVG
from matplotlib.transforms import Affine2D, Bbox, TransformedPath

__all__ = ["RecordingCanvas", "RecordingRenderer", "write_svg"]


class _Anchor:
    """What the SVG writer asks of a text artist to anchor its text — anchor point (in
    the units of ``transform``, y up), horizontal alignment, rotation mode — as they were
    when the text was drawn."""

    def __init__(self, pos, ha, mode, transform):
        self._pos, self._ha, self._mode, self._transform = pos, ha, mode, transform

    @classmethod
    def of(cls, mtext):
        x, y = mtext.get_transform().transform(mtext.get_unitless_position())      # [px]
        return cls((float(x), float(y)), mtext.get_ha(), mtext.get_rotation_mode(), None)

    def scaled(self, transform):
        return _Anchor(self._pos, self._ha, self._mode, transform)

    def get_transform(self):
        return self._transform

    def get_unitless_position(self):
        return self._pos

    def get_ha(self):
        return self._ha

    def get_rotation_mode(self):
        return self._mode


def _frozen_gc(gc):
    """A copy of ``gc`` whose clip rectangle and clip path no longer follow the figure."""
    g = GraphicsContextBase()
    g.copy_properties(gc)
    rect = gc.get_clip_rectangle()
    g.set_clip_rectangle(None if rect is None else rect.frozen())
    path, affine = gc.get_clip_path()
    g.set_clip_path(None if path is None else TransformedPath(path, affine.frozen()))
    return g


def _scaled_gc(g, s, scale):
    """A copy of the frozen ``g`` with its clip rectangle and clip path scaled by
    ``scale`` (pixels -> points); line widths and dash patterns are in points already."""
    out = GraphicsContextBase()
    out.copy_properties(g)
    rect = g.get_clip_rectangle()
    if rect is not None:
        out.set_clip_rectangle(Bbox(np.asarray(rect.get_points()) * scale))
    path, affine = g.get_clip_path()
    if path is not None:
        out.set_clip_path(TransformedPath(path, affine + s))
    return out


_PARSER = []


def _mathtext_parser():
    from matplotlib.mathtext import MathTextParser

    if not _PARSER:
        _PARSER.append(MathTextParser("path"))
    return _PARSER[0]


class RecordingRenderer(RendererAgg):
    """An Agg renderer that also records the primitives it draws (see the module notes).

    ``calls`` holds them in drawing order; ``complete`` turns False when the draw handed
    over something :func:`write_svg` does not replay.
    """

    def __init__(self, width, height, dpi):
        self.calls = []
        self.complete = True
        super().__init__(width, height, dpi)
        # Agg gives every renderer its own mathtext parser, whose cache of parsed labels
        # (log-axis tick labels) is lost with the renderer: share one across figures
        self.mathtext_parser = _mathtext_parser()

    def _update_methods(self):
        # Agg binds these to its C++ renderer per instance; wrap them the same way
        super()._update_methods()
        agg_markers, agg_collection = self.draw_markers, self.draw_path_collection

        def draw_markers(gc, marker_path, marker_trans, path, trans, rgbFace=None):
            self._record("markers", gc, marker_path, marker_trans.frozen(), path, trans.frozen(), rgbFace)
            return agg_markers(gc, marker_path, marker_trans, path, trans, rgbFace)

        def draw_path_collection(gc, master_transform, paths, all_transforms, offsets, offset_trans,
                                 *args, **kwargs):
            self._record("collection", gc, master_transform.frozen(), list(paths),
                         np.array(all_transforms, copy=True), np.array(offsets, copy=True),
                         offset_trans.frozen(), args, kwargs)
            return agg_collection(gc, master_transform, paths, all_transforms, offsets, offset_trans,
                                  *args, **kwargs)

        self.draw_markers = draw_markers
        self.draw_path_collection = draw_path_collection
        for name in ("draw_image", "draw_gouraud_triangles", "draw_quad_mesh"):
            setattr(self, name, self._not_replayed(getattr(self, name)))

    def _not_replayed(self, method):
        def wrapper(*args, **kwargs):
            self.complete = False
            return method(*args, **kwargs)
        return wrapper

    def _record(self, kind, gc, *args):
        if gc.get_sketch_params() is not None:
            self.complete = False
        self.calls.append((kind, _frozen_gc(gc), *args))

    def clear(self):
        self.calls = []
        self.complete = True
        super().clear()

    def draw_path(self, gc, path, transform, rgbFace=None):
        self._record("path", gc, path, transform.frozen(), rgbFace)
        return super().draw_path(gc, path, transform, rgbFace)

    def draw_text(self, gc, x, y, s, prop, angle, ismath=False, mtext=None):
        if ismath == "TeX":
            self.complete = False
        anchor = None if mtext is None else _Anchor.of(mtext)
        # Agg's flipy() is True: y [px] counts from the top, as the SVG writer expects
        self._record("text", gc, x, y, s, prop.copy(), angle, ismath, anchor)
        return super().draw_text(gc, x, y, s, prop, angle, ismath, mtext)

    def draw_tex(self, gc, x, y, s, prop, angle, *, mtext=None):
        self.complete = False
        return super().draw_tex(gc, x, y, s, prop, angle, mtext=mtext)

    def start_filter(self):
        self.complete = False
        return super().start_filter()

    def start_rasterizing(self):
        self.complete = False
        return super().start_rasterizing()

    def open_group(self, s, gid=None):
        self.calls.append(("open", s, gid))

    def close_group(self, s):
        self.calls.append(("close", s))


class RecordingCanvas(FigureCanvasAgg):
    """An Agg canvas drawing through a :class:`RecordingRenderer`."""

    def get_renderer(self):
        # as FigureCanvasAgg.get_renderer, with the recording renderer
        w, h = self.get_width_height(physical=True)
        key = w, h, self.figure.dpi
        if self._lastKey != key:
            self.renderer = RecordingRenderer(w, h, self.figure.dpi)
            self._lastKey = key
        return self.renderer


class _SVGRenderer(RendererSVG):
    def draw_markers(self, gc, marker_path, marker_trans, path, trans, rgbFace=None):
        # matplotlib's writer builds the same style string once per marker; build it once
        # per call (thousands of fix markers otherwise dominate the SVG's time)
        style = RendererSVG._get_style(self, gc, rgbFace)
        self._get_style = lambda *_: style
        try:
            super().draw_markers(gc, marker_path, marker_trans, path, trans, rgbFace)
        finally:
            del self._get_style


def write_svg(canvas: RecordingCanvas, metadata=None) -> bytes | None:
    """SVG bytes of the figure last drawn on ``canvas`` from its recorded primitives, or
    None when that draw cannot be replayed (see the module notes) or its record was
    written already (the record is let go once written)."""
    import matplotlib as mpl

    renderer = canvas.renderer
    fig = canvas.figure
    if not renderer.complete:
        return None
    dpi = fig.dpi
    k = 72.0 / dpi
    s = Affine2D().scale(k)
    width, height = fig.get_size_inches()
    out = io.StringIO()
    with mpl.rc_context({"svg.fonttype": "none"}):
        svg = _SVGRenderer(width * 72, height * 72, out, image_dpi=dpi, metadata=metadata)
        for call in renderer.calls:
            kind = call[0]
            if kind == "path":
                _, g, path, t, face = call
                svg.draw_path(_scaled_gc(g, s, k), path, t + s, face)
            elif kind == "markers":
                _, g, mpath, mtrans, path, t, face = call
                svg.draw_markers(_scaled_gc(g, s, k), mpath, mtrans + s, path, t + s, face)
            elif kind == "text":
                _, g, x, y, text, prop, angle, ismath, anchor = call
                svg.draw_text(_scaled_gc(g, s, k), x * k, y * k, text, prop, angle, ismath,
                              None if anchor is None else anchor.scaled(s))
            elif kind == "collection":
                # each path goes through its own transform, then the master transform; the
                # offsets through offset_trans: scaling both outer transforms scales all
                _, g, master, paths, transforms, offsets, offset_trans, args, kwargs = call
                svg.draw_path_collection(_scaled_gc(g, s, k), master + s, paths, transforms, offsets,
                                         offset_trans + s, *args, **kwargs)
            elif kind == "open":
                svg.open_group(call[1], call[2])
            elif kind == "close":
                svg.close_group(call[1])
        svg.finalize()
    renderer.calls, renderer.complete = [], False    # consumed: drawn again before any reuse
    return out.getvalue().encode("utf-8")
