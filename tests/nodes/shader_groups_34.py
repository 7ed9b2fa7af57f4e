"""Run in Blender 3.4 (tests/nodes/test_shader_groups_34.py): the materials of
tests/nodes/test_shader_groups.py (the Surface group, nested, two sets of inputs; the changed group
as the control) exported with the add-on in 3.4's node vocabulary; writes JSON to the path after
"--": each grouped material against its ungrouped twin, and the warnings by material."""
import json
import os
import sys

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path[:0] = [REPO, os.path.join(REPO, "sample_blends")]

import make_samples as ms  # noqa: E402

from mcrt_addon.export import export_scene  # noqa: E402
from tests.nodes import shader_group_graphs as sg  # noqa: E402

RED = ((0.8, 0.3, 0.2), 4.0, 0.0)
BLUE = ((0.2, 0.5, 0.9), sg.value_node(9.0), 1.0)

scene = ms.reset()
ms.camera(scene)
ms.black_world(scene)
ms.settings(scene, (8, 8))
surface = sg.surface_group()
changed = sg.changed_group()
mats = [sg.plain_material("PlainRed", *RED), sg.plain_material("PlainBlue", *BLUE),
        sg.group_material("GroupRed", surface, *RED)[0],
        sg.group_material("NestedBlue", sg.wrapper_group(surface), *BLUE)[0],
        sg.group_material("ChangedRed", changed, *RED)[0]]
for i, mat in enumerate(mats):
    x = 2.5 * i
    ob = ms.plane(scene, mat.name, [(x - 1, -1, 0), (x + 1, -1, 0), (x + 1, 1, 0), (x - 1, 1, 0)], mat)
    ob.data.uv_layers.new(name="UVMap")
bpy.context.view_layer.update()
result = export_scene(bpy.context.evaluated_depsgraph_get(), resolution=(8, 8))
m = {x.name: sg.canonical(x) for x in result.scene.materials}
warnings = {}
for w in result.warnings:                 # "Material 'NAME', ...": the rest of the text by material
    name, _, rest = w.partition("', ")
    warnings.setdefault(name.replace("Material '", ""), []).append(rest.replace(" (inside node group 'Surface')", ""))
out = {"version": list(bpy.app.version), "kinds": {k: v["kind"] for k, v in m.items()},
       "red": m["GroupRed"] == m["PlainRed"], "blue": m["NestedBlue"] == m["PlainBlue"],
       "control": m["ChangedRed"] == m["PlainRed"], "warnings": warnings}
with open(sys.argv[sys.argv.index("--") + 1], "w") as f:
    json.dump(out, f, indent=1)
