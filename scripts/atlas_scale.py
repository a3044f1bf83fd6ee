"""Where an exported surface's smeared windows lie against how its copies are scaled: a
diagnostic for issue 44 (docs/surfaces.md, "Smears and the copies' scale").

    python scripts/atlas_scale.py SURFACE.ply SAMPLE.png OUT_DIR [--btfsynth BIN]

Exports SURFACE.ply twice with the same atlas: once as it is (its analysis, from the PLY's
header), once with a "coordinate sample" in its place (an analysis of an image the size of
SAMPLE whose red and green hold each texel's x and y), so that the second atlas holds, per
texel, the sample coordinate the first one looked up. From it every 12×12-texel window of
the atlas gets the local area scale of the coordinate map (sample texels per surface texel
squared: 1 where a copy lies at the sample's scale, below 1 where it is magnified). The
smeared flag is eval's: the window's luma deviation below the sample's flattest 5% at the
same scale. Prints the share of windows and of smeared windows per band of scale.
Needs numpy and pillow. For a photograph's surface (the atlas is the export's first image),
up to 256 texels a side: the coordinates travel as 8-bit values.
"""
import argparse
import io
import json
import os
import struct
import subprocess

import numpy as np
from PIL import Image, ImageDraw

WINDOW, STEP, FLATTEST = 12, 6, 0.05
BANDS = [(0, 0.6), (0.6, 0.85), (0.85, 1.15), (1.15, 1.5), (1.5, float("inf"))]


def read_glb(path):
    """The base-colour atlas (0–1 floats) and the texels its triangles cover."""
    data = open(path, "rb").read()
    length = struct.unpack("<I", data[12:16])[0]
    gltf = json.loads(data[20:20 + length])
    start = 20 + length
    blob = data[start + 8:start + 8 + struct.unpack("<I", data[start:start + 4])[0]]

    def accessor(i):
        a = gltf["accessors"][i]
        view = gltf["bufferViews"][a["bufferView"]]
        at = view.get("byteOffset", 0) + a.get("byteOffset", 0)
        n = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[a["type"]]
        dtype = {5126: np.float32, 5125: np.uint32, 5123: np.uint16}[a["componentType"]]
        return np.frombuffer(blob[at:at + a["count"] * n * np.dtype(dtype).itemsize], dtype).reshape(a["count"], n)

    view = gltf["bufferViews"][gltf["images"][0]["bufferView"]]
    at = view.get("byteOffset", 0)
    atlas = Image.open(io.BytesIO(blob[at:at + view["byteLength"]])).convert("RGB")
    covered = Image.new("L", atlas.size, 0)
    draw = ImageDraw.Draw(covered)
    for primitive in gltf["meshes"][0]["primitives"]:
        uv = accessor(primitive["attributes"]["TEXCOORD_0"]) * atlas.size
        for triangle in accessor(primitive["indices"]).reshape(-1, 3):
            draw.polygon([tuple(uv[k]) for k in triangle], fill=255)
    return np.asarray(atlas, dtype=float) / 255, np.asarray(covered) > 0


def luma(rgb):
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def analysis_of(surface):
    """The analysis a surface map names in its header (its absolute path)."""
    with open(surface, "rb") as f:
        for line in f:
            line = line.decode(errors="replace").strip()
            if line.startswith("comment analysis-absolute "):
                return line.split(" ", 2)[2]
            if line == "end_header":
                break
    raise SystemExit(f"{surface}: no analysis named in its header")


def run(*args):
    subprocess.run(args, check=True, stdout=subprocess.DEVNULL)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("surface")
    ap.add_argument("sample")
    ap.add_argument("out")
    ap.add_argument("--btfsynth", default="target/release/btfsynth")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    bin_ = a.btfsynth
    sample = Image.open(a.sample).convert("RGB")
    w, h = sample.size
    x, y = np.meshgrid(np.arange(w), np.arange(h))
    coords = np.stack([x * 256 // w, y * 256 // h, np.full_like(x, 128)], -1).astype(np.uint8)
    coord_png, coord_analysis = os.path.join(a.out, "coords.png"), os.path.join(a.out, "coords-analysis")
    Image.fromarray(coords).save(coord_png)
    run(bin_, "-q", "analyze", coord_png, "-o", coord_analysis, "--force")
    textured, mapped = os.path.join(a.out, "texture.glb"), os.path.join(a.out, "coords.glb")
    run(bin_, "-q", "export", a.surface, "-o", textured, "--force")
    run(bin_, "-q", "export", a.surface, "-o", mapped, "--force", "--analysis", coord_analysis, "--force-analysis")
    figures = subprocess.run(
        [bin_, "-q", "eval", analysis_of(a.surface), textured, "--json"], check=True, capture_output=True, text=True
    )
    scale = json.loads(figures.stdout)["texture"]["scale"]

    texture, covered = read_glb(textured)
    mapped_atlas, _ = read_glb(mapped)
    u, v = mapped_atlas[..., 0] * 255 * w / 256, mapped_atlas[..., 1] * 255 * h / 256

    def slope(c, axis, period, k=4):
        # Over 4 texels: the coordinates are 8-bit, so a one-texel step is mostly rounding.
        d = np.roll(c, -k, axis=axis) - c
        d = (d + period / 2) % period - period / 2
        return d / k

    area = np.abs(slope(u, 1, w) * slope(v, 0, h) - slope(u, 0, w) * slope(v, 1, h)) * scale * scale
    reference = np.asarray(sample.resize((round(w * scale), round(h * scale)), Image.BILINEAR), dtype=float) / 255
    ref = luma(reference)
    flat = np.quantile(
        [ref[j:j + WINDOW, i:i + WINDOW].std() for j in range(0, ref.shape[0] - WINDOW, 2) for i in range(0, ref.shape[1] - WINDOW, 2)],
        FLATTEST,
    )
    lum = luma(texture)
    rows = []
    for j in range(0, lum.shape[0] - WINDOW - 4, STEP):
        for i in range(0, lum.shape[1] - WINDOW - 4, STEP):
            # 4 texels more than the window, so that every slope stays on the surface.
            if covered[j:j + WINDOW + 4, i:i + WINDOW + 4].all():
                rows.append((np.median(area[j:j + WINDOW, i:i + WINDOW]), lum[j:j + WINDOW, i:i + WINDOW].std() < flat))
    rows = np.array(rows)
    print(f"{len(rows)} windows, smeared {rows[:, 1].mean():.3f} (scale {scale:.3f} atlas texels per sample texel)")
    print("| area scale | windows | smeared |\n|---|---|---|")
    for lo, hi in BANDS:
        band = (rows[:, 0] >= lo) & (rows[:, 0] < hi)
        smeared = rows[band, 1].mean() if band.any() else float("nan")
        print(f"| {lo:.2f}–{hi:.2f} | {band.mean():.2f} | {smeared:.3f} |")


if __name__ == "__main__":
    main()
