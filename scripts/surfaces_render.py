"""Renders one route of benches/surfaces.sh in Blender (bpy): an exported .glb as it is, or
with --triplanar TILE the same model with its material replaced by TILE box-projected
(triplanar, blend 0.2) at TEXELS texels per model unit. Two views (the whole model and a
close-up), one sun and a grey world, Cycles on the CPU, same cameras for every route.

    python scripts/surfaces_render.py MODEL.glb OUT_PREFIX [--triplanar TILE.png --texels-per-unit T]
        [--size 384] [--samples 16]

Writes OUT_PREFIX-whole.png and OUT_PREFIX-close.png.
"""
import argparse
import math
import os

import bpy
from mathutils import Vector


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("model")
    ap.add_argument("out")
    ap.add_argument("--triplanar")
    ap.add_argument("--texels-per-unit", type=float, default=0.0)
    ap.add_argument("--size", type=int, default=384)
    ap.add_argument("--samples", type=int, default=16)
    a = ap.parse_args()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=a.model)
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    if a.triplanar:
        triplanar(meshes, a.triplanar, a.texels_per_unit)
    lo, hi = bounds(meshes)
    centre, extent = (lo + hi) / 2, max(hi - lo)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = a.samples
    scene.cycles.use_denoising = False
    scene.render.resolution_x = scene.render.resolution_y = a.size
    scene.view_settings.view_transform = "Standard"
    world = bpy.data.worlds.new("grey")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs[0].default_value = (0.25, 0.25, 0.25, 1)
    scene.world = world
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (math.radians(40), 0, math.radians(30))
    scene.collection.objects.link(sun)
    camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    camera.data.lens = 50
    scene.collection.objects.link(camera)
    scene.camera = camera
    # glTF is Y up; Blender imports it Z up: look along -Y from the front, a little above.
    direction = Vector((0.0, -1.0, 0.35)).normalized()
    for name, distance, aim in (("whole", 2.2 * extent, centre), ("close", 0.55 * extent, front_point(meshes, centre))):
        camera.location = aim + direction * distance
        camera.rotation_euler = (-direction).to_track_quat("-Z", "Y").to_euler()
        scene.render.filepath = os.path.abspath(f"{a.out}-{name}.png")
        bpy.ops.render.render(write_still=True)


def bounds(meshes):
    points = [o.matrix_world @ Vector(c) for o in meshes for c in o.bound_box]
    lo = Vector([min(p[i] for p in points) for i in range(3)])
    hi = Vector([max(p[i] for p in points) for i in range(3)])
    return lo, hi


def front_point(meshes, centre):
    """The surface point nearest the camera's side on the line through the centre."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    hit, location, *_ = bpy.context.scene.ray_cast(depsgraph, centre + Vector((0, -1000, 0)), Vector((0, 1, 0)))
    return location if hit else centre


def triplanar(meshes, tile, texels_per_unit):
    image = bpy.data.images.load(tile)
    side = max(image.size)
    material = bpy.data.materials.new("triplanar")
    material.use_nodes = True
    nodes, links = material.node_tree.nodes, material.node_tree.links
    bsdf = nodes["Principled BSDF"]
    bsdf.inputs["Roughness"].default_value = 1.0
    coords = nodes.new("ShaderNodeTexCoord")
    mapping = nodes.new("ShaderNodeMapping")
    # Object coordinates in model units; the tile repeats every `side` texels.
    scale = texels_per_unit / side
    mapping.inputs["Scale"].default_value = (scale, scale, scale)
    texture = nodes.new("ShaderNodeTexImage")
    texture.image = image
    texture.projection = "BOX"
    texture.projection_blend = 0.2
    texture.extension = "REPEAT"
    links.new(coords.outputs["Object"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], texture.inputs["Vector"])
    links.new(texture.outputs["Color"], bsdf.inputs["Base Color"])
    for o in meshes:
        o.data.materials.clear()
        o.data.materials.append(material)


if __name__ == "__main__":
    main()
