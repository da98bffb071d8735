"""Makes assets/DejaVuSans-Plot.ttf, the font the learning-curve plots embed (src/plot.rs).

Not part of the build: run it only to regenerate the font, with fontTools
(`pip install fonttools`), from DejaVu Sans 2.37 (Debian's fonts-dejavu-core):

    python3 learner/cli/assets/make_plot_font.py /usr/share/fonts/truetype/dejavu/DejaVuSans.ttf \
        learner/cli/assets/DejaVuSans-Plot.ttf

What it does, and why:
- keeps only printable ASCII and a few symbols (-- x +- epsilon degree ... minus), without hinting
  or OpenType layout tables: the plots need no more, and the file is 70 KB instead of 760 KB;
- rewrites the legacy `kern` table so that every pair (A, B) is kerned by the font's own kerning
  plus lsb(B) - lsb(A), where lsb is a glyph's left side bearing. plotters 0.3.7 draws each glyph
  of an ab_glyph font at the pen position, ignoring its left side bearing (the ink of glyphs with
  small bearings, like v and w, lands too far left, and text looks unevenly spaced). With these
  pairs the bearings telescope along a line of text, and every glyph lands where the font puts it
  (the whole line shifts left by the first glyph's bearing, about a pixel). The pairs of up to 104
  glyphs fit one format-0 subtable (at most 65,535 bytes), which limits the character set;
- renames the family to "DejaVu Sans Plot" (a modified DejaVu Sans; see DejaVuSans-LICENSE.txt).
"""

import sys

from fontTools import subset
from fontTools.ttLib import TTFont, newTable
from fontTools.ttLib.tables._k_e_r_n import KernTable_format_0

# Printable ASCII, en dash, multiplication sign, plus-minus, epsilon, degree, ellipsis, minus.
UNICODES = list(range(0x20, 0x7F)) + [0x2013, 0x00D7, 0x00B1, 0x03B5, 0x00B0, 0x2026, 0x2212]
FAMILY = "DejaVu Sans Plot"


def main(src, dst):
    options = subset.Options()
    options.hinting = False
    options.legacy_kern = True
    options.notdef_outline = True
    options.layout_features = []
    options.drop_tables += ["GSUB", "GPOS", "GDEF", "MATH", "FFTM", "gasp"]
    options.name_IDs = [0, 1, 2, 3, 4, 5, 6]
    font = subset.load_font(src, options)
    subsetter = subset.Subsetter(options)
    subsetter.populate(unicodes=UNICODES)
    subsetter.subset(font)

    glyf = font["glyf"]
    order = font.getGlyphOrder()
    assert len(order) <= 104, f"{len(order)} glyphs: too many pairs for one kern subtable"

    def lsb(name):
        g = glyf[name]
        if g.numberOfContours == 0:
            return 0
        g.recalcBounds(glyf)
        return g.xMin

    bearings = {name: lsb(name) for name in order}
    old = {}
    if "kern" in font:
        for table in font["kern"].kernTables:
            if table.format == 0 and table.coverage & 1:
                old.update(table.kernTable)
    pairs = {}
    for a in order:
        for b in order:
            v = old.get((a, b), 0) + bearings[b] - bearings[a]
            if v != 0:
                pairs[(a, b)] = v

    kern = newTable("kern")
    kern.version = 0
    sub = KernTable_format_0()
    sub.version = 0
    sub.coverage = 1
    sub.format = 0
    sub.kernTable = pairs
    kern.kernTables = [sub]
    font["kern"] = kern

    name = font["name"]
    for rec in list(name.names):
        if rec.nameID in (1, 4, 16):
            name.setName(FAMILY, rec.nameID, rec.platformID, rec.platEncID, rec.langID)
        elif rec.nameID == 3:
            name.setName(FAMILY + " (plot subset)", rec.nameID, rec.platformID, rec.platEncID, rec.langID)
        elif rec.nameID == 6:
            name.setName(FAMILY.replace(" ", ""), rec.nameID, rec.platformID, rec.platEncID, rec.langID)

    font.save(dst)
    print(f"{dst}: {len(order)} glyphs, {len(pairs)} kerning pairs")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
