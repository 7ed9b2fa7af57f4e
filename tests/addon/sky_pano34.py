"""Runs inside Debian's Blender 3.4 (tests/addon/test_agreement_sky.py starts it): renders the world
seen by an equirectangular panoramic camera twice, the Generated texture coordinate (each pixel's
direction) and a Nishita Sky Texture of the given settings.

  blender -b --factory-startup --python-use-system-env --python tests/addon/sky_pano34.py -- OUTDIR W H JSON

Writes OUTDIR/directions.exr and OUTDIR/sky.exr (JSON: the Sky node's properties, 3.4 names).
"""
import json
import math
import os
import sys

import bpy


def render(setup, path, width, height):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    sc.cycles.device, sc.cycles.samples, sc.cycles.use_denoising = "CPU", 4, False
    sc.cycles.use_adaptive_sampling, sc.cycles.filter_width = False, 0.01
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = width, height, 100
    sc.view_settings.view_transform = "Standard"
    cam = bpy.data.cameras.new("Pano")
    cam.type = "PANO"
    cam.cycles.panorama_type = "EQUIRECTANGULAR"
    ob = bpy.data.objects.new("Pano", cam)
    sc.collection.objects.link(ob)
    sc.camera, ob.rotation_euler = ob, (math.pi / 2, 0.0, 0.0)
    sc.world = bpy.data.worlds.new("Sky")
    sc.world.use_nodes = True
    tree = sc.world.node_tree
    tree.nodes.clear()
    out, bg = tree.nodes.new("ShaderNodeOutputWorld"), tree.nodes.new("ShaderNodeBackground")
    tree.links.new(bg.outputs[0], out.inputs[0])
    setup(tree, bg)
    sc.render.filepath = path
    sc.render.image_settings.file_format, sc.render.image_settings.color_depth = "OPEN_EXR", "32"
    bpy.ops.render.render(write_still=True)


def main(argv):
    outdir, width, height, props = argv[0], int(argv[1]), int(argv[2]), json.loads(argv[3])

    def directions(tree, bg):
        tree.links.new(tree.nodes.new("ShaderNodeTexCoord").outputs["Generated"], bg.inputs["Color"])

    def sky(tree, bg):
        node = tree.nodes.new("ShaderNodeTexSky")
        node.sky_type = "NISHITA"
        for key, value in props.items():
            setattr(node, key, value)
        tree.links.new(node.outputs["Color"], bg.inputs["Color"])

    os.makedirs(outdir, exist_ok=True)
    render(directions, os.path.join(outdir, "directions.exr"), width, height)
    render(sky, os.path.join(outdir, "sky.exr"), width, height)


if __name__ == "__main__":
    main(sys.argv[sys.argv.index("--") + 1:])
