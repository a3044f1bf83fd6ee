#!/usr/bin/env python3
"""Writes a large DFMF .btf by tiling the pixel factors of a smaller one.

For memory and speed benchmarks of lazy decoding: a UBO2014-sized file (400×400 texels ×
22,801 images) from a generated ubo151 stack converted with `btfsynth convert --to btf`.
The image-side factors are kept; texel (x, y) of the output takes the factors of texel
(x mod w, y mod h) of the input.

Usage: python3 scripts/tile_dfmf.py IN.btf OUT.btf --size 400
"""

import argparse
import struct
import sys

import numpy as np


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("input")
    parser.add_argument("output")
    parser.add_argument("--size", type=int, default=400, help="width and height of the output")
    args = parser.parse_args()
    data = open(args.input, "rb").read()
    if not data.startswith(b"!DFMF08FC"):
        sys.exit(f"{args.input}: not a DFMF file")
    pos = 10 if data[9:10] == b"R" else 9
    has_rotations = pos == 10
    (meta_size,) = struct.unpack_from("<I", data, pos)
    pos += meta_size
    (views,) = struct.unpack_from("<I", data, pos)
    pos += 4
    for _ in range(views):
        (lights,) = struct.unpack_from("<I", data, pos + 8)
        pos += 12 + 8 * lights
    size_at = pos
    width, height = struct.unpack_from("<II", data, pos)
    pos += 8
    if has_rotations:
        (count,) = struct.unpack_from("<I", data, pos)
        pos += 4 + 36 * count
    body = pos + 4 + 4 + 48
    out = bytearray(data[:size_at])
    out += struct.pack("<II", args.size, args.size)
    out += data[size_at + 8:body]
    pos = body
    ys, xs = np.mgrid[0:args.size, 0:args.size]
    source_rows = ((xs % width) + width * (ys % height)).ravel()
    for _ in range(3):
        scalar, k, rows, cols = struct.unpack_from("<BIII", data, pos)
        dtype = {2: np.float16, 4: np.float32, 8: np.float64}[scalar]
        header_end = pos + 13
        s_end = header_end + k * scalar
        u_end = s_end + rows * k * scalar
        sxv = np.frombuffer(data, dtype=dtype, count=cols * k, offset=u_end).reshape(cols, k)
        out += struct.pack("<BIII", scalar, k, rows, args.size * args.size)
        out += data[header_end:u_end]
        out += sxv[source_rows].tobytes()
        pos = u_end + cols * k * scalar
    open(args.output, "wb").write(out)
    print(f"{args.output}: {args.size}x{args.size} texels from {width}x{height}, {len(out) / 2**20:.1f} MiB")


if __name__ == "__main__":
    main()
