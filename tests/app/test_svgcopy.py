"""The SVG written from the PNG draw's primitives (sinslab.app.svgcopy) against matplotlib's
own SVG of the same laid-out figure; the PNG against a plain Agg draw.

Cross-check, element by element: the same elements in the same order, the same text,
the same attributes; every number outside text and legends identical up to the 6
decimals written (data, ticks, grid, patches, markers, collections, clip paths), text
positions within 1.5 pt and legend frames within 3 pt (there the raster renderer's
hinted text metrics placed them, see the module notes). Figures the record cannot
replay are drawn again; the PNG holds exactly the pixels of an Agg draw.
"""
import io
import re
import xml.etree.ElementTree as ET

import matplotlib
import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.backends.backend_svg import FigureCanvasSVG
from matplotlib.patches import Circle
from PIL import Image

from sinslab.app import plotting as P
from sinslab.app import svgcopy
from sinslab.app.publish import render_figure

NUM = re.compile(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?")
REF = re.compile(r"#[A-Za-z_][\w.-]*|url\(#[^)]*\)")     # ids are hashes of the content


def _native_svg(fig):
    out = io.BytesIO()
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        FigureCanvasSVG(fig).print_svg(out)
    return out.getvalue()


def _elements(svg):
    out = []

    def walk(el, groups):
        if el.tag.endswith("}g") and el.get("id"):
            groups = groups + (el.get("id"),)
        out.append((el, groups))
        for child in el:
            walk(child, groups)

    walk(ET.fromstring(svg), ())
    return out


def svg_differences(native, copy):
    """``(problems, worst)``: structural differences, and the largest numeric difference
    [pt] per kind of element ("text", "legend", "other")."""
    a, b = _elements(native), _elements(copy)
    if [e.tag for e, _ in a] != [e.tag for e, _ in b]:
        return ["element sequences differ"], {}
    problems, worst = [], {"text": 0.0, "legend": 0.0, "other": 0.0}
    for (x, gx), (y, _) in zip(a, b):
        if x.tag.endswith("date"):
            continue
        kind = ("legend" if any(g.startswith("legend") for g in gx) else
                "text" if x.tag.endswith("text") or any(g.startswith("text") for g in gx) else "other")
        pairs = [(x.get(k), y.get(k)) for k in sorted(set(x.attrib) | set(y.attrib)) if k != "id"]
        for u, v in [*pairs, (x.text, y.text)]:
            u, v = REF.sub("#", u or ""), REF.sub("#", v or "")
            if NUM.sub("N", u).strip() != NUM.sub("N", v).strip():
                problems.append(f"{x.tag}: {u[:80]!r} != {v[:80]!r}")
                continue
            for p, q in zip(NUM.findall(u), NUM.findall(v)):
                worst[kind] = max(worst[kind], abs(float(p) - float(q)))
    return problems, worst


def _primitives_figure():
    """Every primitive the experiments' figures hand to a renderer, and a few more."""
    fig, ax = P.figure(2, 2, sharex=False, title="primitives: $\\sigma$ and more")
    t = np.linspace(0.0, 600.0, 3000)
    a = ax[0]
    a.plot(t, np.sin(t / 30), lw=1.2, label="line")
    a.plot(t[::50], np.cos(t[::50] / 30), "o", ms=3, label="markers")
    a.fill_between(t, -0.5, 0.5, alpha=0.3, label="±σ")
    a.axvspan(100, 150, color="0.85", lw=0)
    a.axhline(0.2, ls="--", color="r", lw=1)
    a.legend(fontsize="small", ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.15))
    a.set_ylabel("value [m]")
    b = ax[1]
    b.semilogy(t, 1e-3 + t ** 2, label="t²")
    b.scatter(t[::200], 1 + t[::200], s=np.linspace(5, 60, 15), c=t[::200], label="sizes")
    b.errorbar(t[::300], 10 + t[::300], yerr=5.0, fmt="none", ecolor="k")
    b.legend(loc="lower right", fontsize=8)
    b.set_title("log axis", fontsize="small")
    c = ax[2]
    c.plot(t, 1.2345e6 + np.sin(t / 9), color="#2ca02c", alpha=0.6)     # offset text
    c.text(300, 1.2345e6, "rotated note", rotation=30)
    # an arrow (from an empty annotation: an arrow from a text starts at the text's box)
    c.annotate("", xy=(100, 1.2345e6 + 1), xytext=(200, 1.2345e6 + 0.5), arrowprops=dict(arrowstyle="->"))
    c.set_xlabel("time [s]")
    d = ax[3]
    line, = d.plot(t, np.sin(t / 20), "k-")
    circle = Circle((300, 0), 150, transform=d.transData, facecolor="none", edgecolor="b", hatch="//")
    d.add_patch(circle)
    line.set_clip_path(circle)                            # a clip path, not a rectangle
    d.set_aspect("equal", "datalim")
    d.set_xlabel("east [m]")
    return fig


def _static_alignment_figure():
    from sinslab.experiments import static_alignment as sa

    rng = np.random.default_rng(3)
    t = np.arange(0.0, 1200.0, 0.5)
    resid = np.cumsum(rng.normal(size=(t.size, 5)), axis=0) * 1e-6
    lim = np.full(5, 2e-5)
    extra = [("εE estimate [°/h]", 1e-3 * np.sin(t / 100), 0.0),
             ("∇E estimate [µg]", np.cos(t / 90), 0.5), ("∇N estimate [µg]", t / 1e3, 1.0)]
    return sa._figure(t, resid, lim, "residuals", extra)


@pytest.mark.parametrize("build", [_primitives_figure, _static_alignment_figure])
def test_copy_matches_matplotlibs_svg(build):
    fig = build()
    png, copy = render_figure(fig)                      # laid out, drawn, copied
    problems, worst = svg_differences(_native_svg(fig), copy)
    assert problems == []
    assert worst["other"] < 1e-5                        # geometry: identical as written
    assert worst["text"] < 1.5 and worst["legend"] < 3.0, worst


def test_what_the_copy_cannot_replay_is_drawn_again():
    fig, ax = P.figure(1, 2, sharex=False)
    ax[0].imshow(np.arange(12.0).reshape(3, 4))          # an image
    ax[1].plot([0, 1], [0, 1])
    fig.set_dpi(110)
    canvas = svgcopy.RecordingCanvas(fig)
    canvas.draw()
    assert not canvas.renderer.complete and svgcopy.write_svg(canvas) is None
    _, svg = render_figure(fig)
    assert fig.dpi == 110
    assert b"<image" in svg and svg_differences(_native_svg(fig), svg)[0] == []

    fig, ax = P.figure(1)
    ax[0].plot(np.arange(10.0), rasterized=True)         # rasterized: an image in an SVG
    fig.set_dpi(110)
    canvas = svgcopy.RecordingCanvas(fig)
    canvas.draw()
    assert svgcopy.write_svg(canvas) is None
    _, svg = render_figure(fig)
    assert b"<image" in svg


def test_png_holds_the_pixels_of_an_agg_draw():
    fig = _primitives_figure()
    png, _ = render_figure(fig)                          # positions frozen from here on
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    agg = np.asarray(canvas.buffer_rgba())
    img = Image.open(io.BytesIO(png))
    assert img.mode == "RGB" and img.info["dpi"] == pytest.approx((110, 110), abs=0.01)
    assert np.array_equal(np.asarray(img), agg[..., :3]) and agg[..., 3].min() == 255

    clear, _ = P.figure(1)
    clear.patch.set_alpha(0.0)                           # see-through: the alpha channel stays
    img = Image.open(io.BytesIO(render_figure(clear)[0]))
    assert img.mode == "RGBA" and np.asarray(img)[..., 3].min() == 0


def test_a_failing_copy_falls_back_to_matplotlibs_svg(monkeypatch):
    """If the recorded copy breaks (e.g. a matplotlib release changes the renderer
    internals it relies on), the figure still gets matplotlib's own SVG."""
    def broken(canvas, metadata=None):
        raise AttributeError("renderer internals changed")

    monkeypatch.setattr(svgcopy, "write_svg", broken)
    fig, ax = P.figure(1, 1, title="fallback")
    ax[0].plot(np.arange(10.0), np.arange(10.0) ** 2, label="y")
    ax[0].legend()
    png, svg = render_figure(fig)
    assert png.startswith(b"\x89PNG") and b"<svg" in svg and b"fallback" in svg
