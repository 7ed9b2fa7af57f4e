"""The Viewport sub-panel of Sampling, laid out as Cycles' (Render Properties > Sampling > Viewport)."""
import bpy

from .ui import TNCG15ButtonsPanel


class RENDER_PT_tncg15_sampling_viewport(TNCG15ButtonsPanel, bpy.types.Panel):
    bl_label = "Viewport"
    bl_parent_id = "RENDER_PT_tncg15_sampling"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.column(align=True).prop(context.scene.tncg15, "viewport_samples", text="Max Samples")


classes = (RENDER_PT_tncg15_sampling_viewport,)

register, unregister = bpy.utils.register_classes_factory(classes)
