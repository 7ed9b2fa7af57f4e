"""The panels Blender shows for TNCG15 MC on a light (mcrt_addon/ui.py): one Light panel, ours,
with the options the exporter reads; EEVEE's light panels are not lent (bpy 5.0 in-process).
The panels are enumerated as Blender picks them: Properties-editor panels of the "data" context
whose poll passes for a light with the engine TNCG15_MC (the same context under EEVEE is the
control: there EEVEE's own Light panel shows)."""
from types import SimpleNamespace

import bpy
import pytest


def shown(engine, light):
    context = SimpleNamespace(engine=engine, light=light, object=None, scene=bpy.context.scene)
    names = []
    for panel in bpy.types.Panel.__subclasses__():
        if getattr(panel, "bl_space_type", "") != "PROPERTIES" or getattr(panel, "bl_context", "") != "data":
            continue
        poll = getattr(panel, "poll", None)
        try:
            ok = poll(context) if poll else engine in getattr(panel, "COMPAT_ENGINES", ())
        except AttributeError:           # a poll that reads what the mock lacks is for other data
            ok = False
        if ok:
            names.append(panel.__name__)
    return names


@pytest.mark.parametrize("kind", ["AREA", "POINT", "SUN", "SPOT"])
def test_one_light_panel_for_tncg15(addon, kind):
    light = bpy.data.lights.new(f"probe_{kind}", kind)
    try:
        ours = [n for n in shown("TNCG15_MC", light) if getattr(bpy.types, n).bl_label == "Light"]
        assert ours == ["DATA_PT_tncg15_light"], ours
        assert not any("EEVEE" in n for n in shown("TNCG15_MC", light))
        eevee = [n for n in shown("BLENDER_EEVEE_NEXT" if hasattr(bpy.types, "EEVEE_NEXT_WORLD_PT_surface")
                                  else "BLENDER_EEVEE", light) if getattr(bpy.types, n).bl_label == "Light"]
        assert eevee and "DATA_PT_tncg15_light" not in eevee
    finally:
        bpy.data.lights.remove(light)
