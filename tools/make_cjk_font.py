"""Write the CJK font subset that report pages embed (src/sinslab/app/fonts/cjk-subset.otf).

A report names its method's paper in the paper's own words, some of them Chinese; a
reader's machine without a CJK font would show boxes. The page embeds this subset (the
characters of every CJK text in sinslab's sources, about a hundred glyphs, tens of kB)
when it shows such text (:mod:`sinslab.app.report`). Made from Noto Sans CJK SC Regular
(SIL Open Font License 1.1, Adobe and Google; Debian's ``fonts-noto-cjk``), renamed as the
licence asks of a modified version. Run it again when a CJK text is added to the sources;
``tests/app/test_report_fonts.py`` fails until then.

    apt-get install fonts-noto-cjk && python tools/make_cjk_font.py
"""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "sinslab"
OUT = SRC / "app" / "fonts" / "cjk-subset.otf"
FAMILY = "sinslab CJK subset"


def noto_file() -> Path:
    """The installed Noto Sans CJK collection (found by fontconfig)."""
    import subprocess

    r = subprocess.run(["fc-match", "-f", "%{file}", "Noto Sans CJK SC:style=Regular"],
                       capture_output=True, text=True, check=True)
    p = Path(r.stdout.strip())
    if "NotoSansCJK" not in p.name:
        raise SystemExit(f"Noto Sans CJK is not installed (fontconfig offers {p}); apt-get install fonts-noto-cjk")
    return p


def source_characters() -> str:
    """Every CJK character (and CJK punctuation) in sinslab's Python sources, sorted."""
    sys.path.insert(0, str(ROOT / "src"))
    from sinslab.app.report import is_cjk

    chars = set()
    for p in SRC.rglob("*.py"):
        chars |= {c for c in p.read_text(encoding="utf-8") if is_cjk(c)}
    return "".join(sorted(chars))


def main() -> None:
    from fontTools import subset
    from fontTools.ttLib import TTCollection

    chars = source_characters()
    fonts = TTCollection(str(noto_file())).fonts
    font = fonts[[f["name"].getDebugName(1) for f in fonts].index("Noto Sans CJK SC")]
    opts = subset.Options()
    opts.name_IDs = ["*"]
    opts.layout_features = ["*"]
    opts.notdef_outline = True
    sub = subset.Subsetter(opts)
    sub.populate(text=chars)
    sub.subset(font)
    names = font["name"]
    for rec in names.names:
        if rec.nameID in (1, 3, 4, 16):
            rec.string = FAMILY
        elif rec.nameID == 6:
            rec.string = FAMILY.replace(" ", "")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    font.save(str(OUT))
    print(f"{OUT.relative_to(ROOT)}: {len(chars)} characters, {OUT.stat().st_size} bytes")


if __name__ == "__main__":
    main()
