"""Imports a btfsynth glTF export into Blender, renders it headless, and checks it is textured.

Blender as a Python module: `pip install bpy` (Python 3.11; about 350 MB). Then

    python scripts/blender_check.py model.glb render.png [--size 1024] [--samples 32]

writes `render.png` (Cycles on the CPU, a sun and a dim sky) and exits non-zero unless

1. the imported material's Base Color comes from an image texture (not a flat colour), and
2. the rendered object is textured: its high-frequency energy (mean squared difference of
   neighbouring pixels inside the object) is several times that of the same render with
   every texture disconnected, at a small size so the check is quick.
"""

import argparse
import math
import os
import sys
import warnings

import bpy
import numpy as np
from mathutils import Vector


def parse():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("model", help="a .glb or .gltf written by btfsynth export")
    p.add_argument("render", help="the PNG to write")
    p.add_argument("--size", type=int, default=1024, help="render width and height (default 1024)")
    p.add_argument("--samples", type=int, default=32, help="Cycles samples per pixel (default 32)")
    p.add_argument("--view", type=float, nargs=2, default=(60.0, 35.0), metavar=("AZIMUTH", "ELEVATION"),
                   help="camera direction in degrees around the model's vertical axis and above it")
    return p.parse_args()


def load(model):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=model)
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    if not meshes:
        sys.exit(f"{model}: no mesh was imported")
    return meshes


def base_colour_link(obj):
    """The link feeding the Principled BSDF's Base Color from an image texture, if any."""
    for slot in obj.material_slots:
        tree = slot.material.node_tree if slot.material else None
        if tree is None:
            continue
        for node in tree.nodes:
            if node.type == "BSDF_PRINCIPLED":
                socket = node.inputs["Base Color"]
                for link in socket.links:
                    if link.from_node.type == "TEX_IMAGE":
                        return tree, link
    return None, None


def frame(meshes, azimuth, elevation):
    """A 30° camera looking at the models from (azimuth, elevation), framing their
    silhouette; a sun beside the camera."""
    scene = bpy.context.scene
    bpy.context.view_layer.update()  # world matrices of the imported nodes
    points = np.concatenate([
        np.array([(o.matrix_world @ v.co)[:] for v in o.data.vertices], dtype=np.float64) for o in meshes
    ])
    a, e = math.radians(azimuth), math.radians(elevation)
    # Blender is Z-up; the glTF importer turns glTF's +Y up into +Z.
    back = np.array([math.sin(a) * math.cos(e), -math.cos(a) * math.cos(e), math.sin(e)])
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    x, y, z = points @ right, points @ up, points @ back
    half = max(x.max() - x.min(), y.max() - y.min()) / 2
    target = right * (x.max() + x.min()) / 2 + up * (y.max() + y.min()) / 2 + back * (z.max() + z.min()) / 2
    distance = (z.max() - z.min()) / 2 + 1.08 * half / math.tan(math.radians(15))
    camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    camera.data.lens_unit = "FOV"
    camera.data.angle = math.radians(30)
    camera.location = Vector(target + back * distance)
    camera.rotation_euler = Vector(-back).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(camera)
    scene.camera = camera
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (math.radians(40), 0.0, math.radians(azimuth + 35))
    scene.collection.objects.link(sun)
    world = bpy.data.worlds.new("world")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # node trees become implicit in Blender 6
        world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.35, 0.38, 0.42, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.6
    scene.world = world


def render(path, size, samples):
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = True
    scene.view_settings.view_transform = "Standard"
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = os.path.abspath(path)
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(os.path.abspath(path), check_existing=False)
    pixels = np.array(image.pixels[:], dtype=np.float32).reshape(size, size, 4)
    bpy.data.images.remove(image)
    return pixels


def detail(pixels):
    """Mean squared difference of horizontally and vertically neighbouring pixels, where
    both lie well inside the object (alpha 1)."""
    rgb, inside = pixels[..., :3], pixels[..., 3] > 0.999
    dx = ((rgb[:, 1:] - rgb[:, :-1]) ** 2).sum(-1)[inside[:, 1:] & inside[:, :-1]]
    dy = ((rgb[1:] - rgb[:-1]) ** 2).sum(-1)[inside[1:] & inside[:-1]]
    return float(np.concatenate([dx, dy]).mean()), int(inside.sum())


def main():
    args = parse()
    meshes = load(args.model)
    tree, link = base_colour_link(meshes[0])
    if link is None:
        sys.exit(f"{args.model}: the imported material's Base Color is not an image texture")
    image = link.from_node.image
    print(f"{args.model}: {len(meshes[0].data.vertices)} vertices, base colour {image.name} "
          f"{image.size[0]}x{image.size[1]}")
    frame(meshes, *args.view)
    render(args.render, args.size, args.samples)
    print(f"wrote {args.render}")
    # Small but with many samples, so that path-tracing noise does not pass for texture.
    small = 192
    check = args.render + ".check.png"
    textured, covered = detail(render(check, small, 64))
    for unused in [l for l in tree.links if l.from_node.type == "TEX_IMAGE"]:
        tree.links.remove(unused)  # every texture: base colour, normals, roughness
    flat, _ = detail(render(check, small, 64))
    os.remove(check)
    ratio = textured / max(flat, 1e-12)
    print(f"detail at {small}²: textured {textured:.3e}, flat {flat:.3e} (x{ratio:.1f}) over {covered} pixels")
    if covered < small * small // 20:
        sys.exit("the object covers almost nothing of the frame")
    if ratio < 3.0:
        sys.exit("the render is not textured: it has no more detail than the flat-shaded model")
    print("ok: textured")


if __name__ == "__main__":
    main()
