#!/usr/bin/env python3
"""Resynthesizer (the engine of GIMP's plug-in) as a texture-synthesis peer for
benches/quality.sh: SAMPLE.png -> OUT.png of SIDE x SIDE pixels.

Resynthesizer fills the masked part of a canvas from the unmasked rest, so the sample goes
in the top-left corner of a (SIDE + sample) square canvas, everything else is masked, and
the SIDE x SIDE square in the opposite corner (which does not overlap the sample) is the
result: no verbatim copy of the sample is counted as output.

Resynthesizer is GPL: it is only ever run as this outside program (pip package
`resynthesizer`, a ctypes wrapper of its C engine), never linked or shipped.
usage: resynth_peer.py SAMPLE.png OUT.png SIDE
"""
import sys

from PIL import Image
from resynthesizer import resynthesizer as rs


def main():
    if len(sys.argv) != 4:
        sys.exit("usage: resynth_peer.py SAMPLE.png OUT.png SIDE")
    sample = Image.open(sys.argv[1]).convert("RGB")
    side = int(sys.argv[3])
    w, h = sample.size
    canvas_w, canvas_h = side + w, side + h
    canvas = Image.new("RGB", (canvas_w, canvas_h))
    canvas.paste(sample, (0, 0))
    mask = Image.new("L", (canvas_w, canvas_h), 255)
    mask.paste(0, (0, 0, w, h))
    params = rs.getDefaultParams()
    # A plane, not a tile: the result is judged as one picture like the other tools'.
    params.isMakeSeamlesslyTileableHorizontally = 0
    params.isMakeSeamlesslyTileableVertically = 0
    result = rs.resynthesize(canvas, mask, params)
    result.crop((w, h, canvas_w, canvas_h)).save(sys.argv[2])


if __name__ == "__main__":
    main()
