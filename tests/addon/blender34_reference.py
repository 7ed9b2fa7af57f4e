"""Runs inside Debian's Blender 3.4 (tests/addon/blender34.py starts it): builds one scene, exports it
with the add-on's exporter to a scene file and renders Cycles 3.4 references of it.

  blender -b --factory-startup --python-use-system-env --python tests/addon/blender34_reference.py -- \\
      --scene NAME --outdir DIR --resolution 64 64 --samples 32 --depth 8 --seeds 1 2 3 4 [--distribution D]

NAME is "startup_cube" (the factory startup file as it is: the default cube with its Principled
material, the point light, the grey world, the camera), "normals" (tests/nodes/normal_scene.py),
"checker_room" (tests/nodes/node_scene.py) or a
scene of sample_blends/make_samples.py.
--distribution sets every Principled, Glossy and Anisotropic BSDF's distribution menu (e.g. MULTI_GGX,
GGX) before the export.
--no-light-sampling MAT ... turns the Cycles setting Multiple Importance (cycles.sample_as_light) of
these materials off for the references only (the exporter does not read it): their emission reaches
Cycles 3.4 through BSDF-sampled rays alone, the same converged image without Cycles 3.x's
light-sampling error on textured emissive triangles (docs/nodes.md "Agreement with Cycles").
--edit sharp_principled_plates replaces every Glossy BSDF node by a Principled BSDF (metallic 1, the
Glossy's colour, roughness 0.05, GGX) before the export (the glossy_plates scene as sharp v1 metal).
--light-paths NAME=VALUE ... sets Light Paths options of the references (mcrt_addon/reference.py
setup_cycles_reference's names, e.g. filter_glossy=1).
Writes DIR/NAME.blend, DIR/NAME.json (the exported scene; cycles_version is the running Blender's),
DIR/NAME.warnings.json (the exporter's warnings) and DIR/NAME.cycles.SEED.exr per seed.
"""
import argparse
import importlib.util
import json
import os
import sys

import bpy

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DISTRIBUTION_NODES = ("ShaderNodeBsdfPrincipled", "ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic")


def build(name, outdir, resolution):
    path = os.path.join(outdir, f"{name}.blend")
    if name == "startup_cube":
        bpy.ops.wm.save_as_mainfile(filepath=path, check_existing=False)
        return path
    if name == "checker_room":            # tests/nodes/node_scene.py (the node room, a procedural floor)
        spec = importlib.util.spec_from_file_location("node_scene", os.path.join(REPO, "tests", "nodes", "node_scene.py"))
        node_scene = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(node_scene)
        return node_scene.build_checker_room(path, tuple(resolution))
    if name == "normals":                 # tests/nodes/normal_scene.py (Normal Map and Bump)
        spec = importlib.util.spec_from_file_location("normal_scene", os.path.join(REPO, "tests", "nodes", "normal_scene.py"))
        normal_scene = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(normal_scene)
        return normal_scene.build(path, tuple(resolution))
    spec = importlib.util.spec_from_file_location("make_samples", os.path.join(REPO, "sample_blends", "make_samples.py"))
    make_samples = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_samples)
    return make_samples.make(name, outdir, tuple(resolution))


def sharp_principled_plates():
    """Every Glossy BSDF node replaced by a Principled BSDF: metallic 1, roughness 0.05, its colour."""
    for mat in bpy.data.materials:
        tree = mat.node_tree
        for node in list(tree.nodes if tree else ()):
            if node.bl_idname != "ShaderNodeBsdfGlossy":
                continue
            principled = tree.nodes.new("ShaderNodeBsdfPrincipled")
            principled.distribution = "GGX"
            principled.inputs["Base Color"].default_value = node.inputs["Color"].default_value
            principled.inputs["Metallic"].default_value = 1.0
            principled.inputs["Roughness"].default_value = 0.05
            for link in list(node.outputs[0].links):
                tree.links.new(principled.outputs[0], link.to_socket)
            tree.nodes.remove(node)


EDITS = {"sharp_principled_plates": sharp_principled_plates}


def main(argv):
    parser = argparse.ArgumentParser()
    parser.add_argument("--scene", required=True)
    parser.add_argument("--outdir", required=True)
    parser.add_argument("--resolution", type=int, nargs=2, default=(64, 64))
    parser.add_argument("--samples", type=int, default=32)
    parser.add_argument("--depth", type=int, default=8)
    parser.add_argument("--seeds", type=int, nargs="*", default=[1, 2, 3, 4])
    parser.add_argument("--distribution", default=None)
    parser.add_argument("--no-light-sampling", nargs="*", default=[])
    parser.add_argument("--edit", choices=sorted(EDITS), default=None)
    parser.add_argument("--light-paths", nargs="*", default=[])
    args = parser.parse_args(argv)
    os.makedirs(args.outdir, exist_ok=True)
    path = build(args.scene, args.outdir, args.resolution)
    bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = args.resolution
    scene.render.resolution_percentage = 100
    if args.distribution:
        for mat in bpy.data.materials:
            for node in (mat.node_tree.nodes if mat.node_tree else ()):
                if node.bl_idname in DISTRIBUTION_NODES:
                    node.distribution = args.distribution
    if args.edit:
        EDITS[args.edit]()
    light_paths = {k: float(v) for k, v in (item.split("=") for item in args.light_paths)}

    import mcrt_addon
    from mcrt_addon import bridge
    from mcrt_addon.export import export_scene
    from mcrt_addon.headless import ensure_registered, set_exr_output
    from mcrt_addon.reference import setup_cycles_reference
    ensure_registered(mcrt_addon)
    exported = export_scene(bpy.context.evaluated_depsgraph_get(), resolution=tuple(args.resolution))
    stem = os.path.join(args.outdir, args.scene)
    bridge.module("scene.files").save_scene(exported.scene, stem + ".json")
    with open(stem + ".warnings.json", "w") as f:
        json.dump({"warnings": exported.warnings, "blender": list(bpy.app.version)}, f)
    for name in args.no_light_sampling:
        bpy.data.materials[name].cycles.sample_as_light = False
    for seed in args.seeds:
        setup_cycles_reference(scene, samples=args.samples, max_depth=args.depth, seed=seed, **light_paths)
        scene.cycles.use_denoising = False
        set_exr_output(scene, f"{stem}.cycles.{seed}.exr")
        bpy.ops.render.render(write_still=True)


if __name__ == "__main__":
    main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
