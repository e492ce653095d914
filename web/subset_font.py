"""Makes the page's text font, assets/fonts/Ubuntu-Light-derivative-meshvox.ttf, from egui's Ubuntu-Light.ttf
(epaint_default_fonts): every glyph, codepoint, advance and outline and the layout tables (kerning, substitutions)
kept; what egui's text stack never reads dropped: the TrueType hinting programs (skrifa then hints with its
autohinter, as it does for any font without them), the device metrics tables (hdmx, VDMX) and the glyph names.
171 KB gzipped becomes 71 KB, the largest single part of the page's wasm that nothing needs.

The Ubuntu Font Licence (assets/fonts/UFL.txt) asks a modified version that is not substantially changed to keep
its name with "derivative X" appended: the family is "Ubuntu Light derivative meshvox", copyright and licence
records kept.

    python web/subset_font.py PATH/TO/epaint_default_fonts-0.37.0/fonts/Ubuntu-Light.ttf
(needs fontTools: `pip install fonttools==4.68.0`). tests/it/page_font.rs holds the result to its source.
"""

import pathlib
import sys

from fontTools.ttLib import TTFont
from fontTools.ttLib.tables import ttProgram

SUFFIX = " derivative meshvox"
OUT = pathlib.Path(__file__).resolve().parents[1] / "assets" / "fonts" / "Ubuntu-Light-derivative-meshvox.ttf"


def main(source: str) -> None:
    # Tables are edited in place, not run through fontTools' subsetter (which also merges duplicate feature
    # records): the tables not named here are written back as they were read.
    font = TTFont(source, recalcTimestamp=False)
    for table in ("fpgm", "prep", "cvt ", "hdmx", "VDMX"):
        if table in font:
            del font[table]
    glyf = font["glyf"]
    for name in font.getGlyphOrder():
        glyph = glyf[name]
        if not glyph.isComposite() and hasattr(glyph, "program"):
            glyph.program = ttProgram.Program()
            glyph.program.fromBytecode(b"")
    maxp = font["maxp"]
    maxp.maxSizeOfInstructions = maxp.maxFunctionDefs = maxp.maxInstructionDefs = maxp.maxStackElements = 0
    maxp.maxTwilightPoints = maxp.maxStorage = 0
    maxp.maxZones = 1
    font["post"].formatType = 3.0
    font["post"].extraNames, font["post"].mapping = [], {}
    for record in font["name"].names:
        # Family (1), unique id (3), full name (4), PostScript name (6), typographic family (16).
        if record.nameID in (1, 3, 4, 6, 16):
            text = record.toUnicode()
            record.string = text + (SUFFIX.replace(" ", "-") if record.nameID == 6 else SUFFIX)
    OUT.parent.mkdir(exist_ok=True)
    font.save(OUT)
    print(f"{OUT}: {OUT.stat().st_size:,} bytes")


if __name__ == "__main__":
    main(sys.argv[1])
