"""Holds the page's font (web/subset_font.py's output) to egui's Ubuntu-Light.ttf it was made from, with fontTools:
the same glyphs in the same order, the same codepoints, advances and side bearings, the same outlines (every
point, flag and contour end; every composite's components and offsets), the same kerning and substitutions (GPOS,
GSUB compiled to the same bytes), the same vertical metrics; no hinting program left (fpgm, prep, cvt and every
glyph's instructions); the family renamed "... derivative meshvox" as the Ubuntu Font Licence asks, the copyright
record kept. Prints JSON: {"problems": [one line per difference], "glyphs", "codepoints", "family"}.

    python tests/tools/font_check.py ORIGINAL.ttf DERIVED.ttf
"""

import json
import sys

from fontTools.ttLib import TTFont


def outline(glyph, glyf, index):
    if glyph.isComposite():
        return ("composite", [(index[c.glyphName], c.x, c.y, c.flags & ~0x0200, getattr(c, "transform", None))
                              for c in glyph.components])
    coordinates, ends, flags = glyph.getCoordinates(glyf)
    return ("simple", list(coordinates), list(ends), [f & 0x01 for f in flags])


def main(original_path, derived_path):
    original, derived = TTFont(original_path), TTFont(derived_path)
    problems = []
    # Glyphs by index: the derived font has no glyph names (post format 3), so fontTools names them glyph00001...
    order, order_d = original.getGlyphOrder(), derived.getGlyphOrder()
    index, index_d = {n: i for i, n in enumerate(order)}, {n: i for i, n in enumerate(order_d)}
    if len(order_d) != len(order):
        problems.append(f"{len(order_d)} glyphs against {len(order)}")
        order_d = order_d[: len(order)]
    cmap = {cp: index[name] for cp, name in original.getBestCmap().items()}
    if {cp: index_d[name] for cp, name in derived.getBestCmap().items()} != cmap:
        problems.append("the codepoints map to other glyphs")
    if [derived["hmtx"].metrics[n] for n in order_d] != [original["hmtx"].metrics[n] for n in order]:
        problems.append("advances or side bearings differ")
    for table, fields in (("hhea", ("ascent", "descent", "lineGap")), ("head", ("unitsPerEm",)),
                          ("OS/2", ("sTypoAscender", "sTypoDescender", "sTypoLineGap", "usWinAscent",
                                    "usWinDescent"))):
        for field in fields:
            if getattr(derived[table], field) != getattr(original[table], field):
                problems.append(f"{table}.{field} differs")
    glyf_o, glyf_d = original["glyf"], derived["glyf"]
    changed = [o for o, d in zip(order, order_d)
               if outline(glyf_o[o], glyf_o, index) != outline(glyf_d[d], glyf_d, index_d)]
    if changed:
        problems.append(f"{len(changed)} outlines differ, first {changed[:5]}")
    for table in ("GPOS", "GSUB"):
        if derived[table].compile(derived) != original[table].compile(original):
            problems.append(f"{table} differs")
    hinted = [t for t in ("fpgm", "prep", "cvt ", "hdmx", "VDMX") if t in derived]
    if hinted:
        problems.append(f"still has {hinted}")
    programs = [n for n in order_d if not glyf_d[n].isComposite() and getattr(glyf_d[n], "program", None)
                and glyf_d[n].program.getBytecode()]
    if programs:
        problems.append(f"{len(programs)} glyphs keep instructions")
    names = {(r.nameID, r.platformID): r.toUnicode() for r in derived["name"].names}
    for name_id in (1, 4):
        if not names.get((name_id, 3), "").endswith(" derivative meshvox"):
            problems.append(f"name {name_id} is {names.get((name_id, 3))!r}, not '... derivative meshvox'")
    copyright_o = {r.toUnicode() for r in original["name"].names if r.nameID == 0}
    if {r.toUnicode() for r in derived["name"].names if r.nameID == 0} != copyright_o:
        problems.append("the copyright record differs")
    print(json.dumps({"problems": problems, "glyphs": len(order), "codepoints": len(cmap),
                      "family": names.get((1, 3))}))

if __name__ == "__main__":
    main(*sys.argv[1:3])
