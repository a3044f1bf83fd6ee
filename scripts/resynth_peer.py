#!/usr/bin/env python3
"""Resynthesizer (the engine of GIMP's plug-in) as a texture-synthesis peer for
benches/quality.sh: SAMPLE.png -> OUT.png of SIDE x SIDE pixels.

Resynthesizer fills the masked part of a canvas from the unmasked rest, so the sample goes
in the top-left corner of a (SIDE + sample) square canvas, everything else is masked, and
the SIDE x SIDE square in the opposite corner (which does not overlap the sample) is the
result: no verbatim copy of the sample is counted as output.

With --timing the canvas is SIDE x SIDE instead, the sample in its corner and the rest to
fill (SIDE² − sample pixels, fewer than a SIDE² result): the setup of the speed benchmark
(benches/speed.sh resynth), which does not flatter btfsynth; the whole canvas is saved.

Resynthesizer is GPL: it is only ever run as this outside program (pip package
`resynthesizer`, a ctypes wrapper of its C engine), never linked or shipped.
usage: resynth_peer.py [--timing] SAMPLE.png OUT.png SIDE
"""
import sys

from PIL import Image
from resynthesizer import resynthesizer as rs


def main():
    args = sys.argv[1:]
    timing = bool(args) and args[0] == "--timing"
    if timing:
        args = args[1:]
    if len(args) != 3:
        sys.exit("usage: resynth_peer.py [--timing] SAMPLE.png OUT.png SIDE")
    sample = Image.open(args[0]).convert("RGB")
    side = int(args[2])
    w, h = sample.size
    canvas_w, canvas_h = (side, side) if timing else (side + w, side + h)
    canvas = Image.new("RGB", (canvas_w, canvas_h))
    canvas.paste(sample, (0, 0))
    mask = Image.new("L", (canvas_w, canvas_h), 255)
    mask.paste(0, (0, 0, w, h))
    params = rs.getDefaultParams()
    # A plane, not a tile: the result is judged as one picture like the other tools'.
    params.isMakeSeamlesslyTileableHorizontally = 0
    params.isMakeSeamlesslyTileableVertically = 0
    result = rs.resynthesize(canvas, mask, params)
    (result if timing else result.crop((w, h, canvas_w, canvas_h))).save(args[1])


if __name__ == "__main__":
    main()
