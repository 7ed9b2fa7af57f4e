"""Panels, laid out as Cycles lays out its render properties: Sampling (Viewport with its Denoise,
Render with its Denoise, Lights, Advanced), Light Paths (Max Bounces, Clamping, Caustics), Film
(Pixel Filter, Transparent), Performance, View Layer passes,
plus an object panel for the implicit-sphere option.  Also lends our engine id to Blender's generic
panels (output, dimensions, camera, light, material and world surface) the way the RenderEngine
documentation template does.

The scene properties drawn here are the rows of the settings table (engine/core/settings.py), by
name; a row's `panel` says which panel draws it (tests/core/test_settings_table.py checks)."""
import bpy

ENGINE_ID = "TNCG15_MC"

# Generic panels that draw nothing engine-specific but are gated by COMPAT_ENGINES.
# (EEVEE's light panels are not lent: their options are EEVEE's; DATA_PT_tncg15_light draws ours.)
EXTRA_PANELS = (
    "EEVEE_MATERIAL_PT_context_material", "EEVEE_MATERIAL_PT_surface", "EEVEE_WORLD_PT_surface",
    "EEVEE_NEXT_MATERIAL_PT_surface", "EEVEE_NEXT_WORLD_PT_surface", "MATERIAL_PT_preview",
    "WORLD_PT_context_world",
)
# The doc template's two, and the generic Light panel (the type row only; its node-editor twin
# shares its COMPAT_ENGINES set), which DATA_PT_tncg15_light replaces as Cycles' own panel does.
EXCLUDED_PANELS = {"VIEWLAYER_PT_filter", "VIEWLAYER_PT_layer_passes", "DATA_PT_light", "NODE_DATA_PT_light"}


class TNCG15ButtonsPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {ENGINE_ID}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class RENDER_PT_tncg15_sampling(TNCG15ButtonsPanel, bpy.types.Panel):
    """Sampling, with Cycles' sub-panels: Viewport, Render, Lights, Advanced."""
    bl_label = "Sampling"

    def draw(self, context):
        pass


class TNCG15SamplingChild(TNCG15ButtonsPanel):
    bl_parent_id = "RENDER_PT_tncg15_sampling"


def split(layout):
    """The layout with labels on the left and no animation decorators (Cycles' property style)."""
    layout.use_property_split = True
    layout.use_property_decorate = False
    return layout


class RENDER_PT_tncg15_sampling_viewport(TNCG15SamplingChild, bpy.types.Panel):
    bl_label = "Viewport"

    def draw(self, context):
        split(self.layout).column(align=True).prop(context.scene.tncg15, "viewport_samples", text="Max Samples")


class RENDER_PT_tncg15_sampling_render(TNCG15SamplingChild, bpy.types.Panel):
    """Render: the stopping rules (docs/user-guide.md: Stopping rules) and the render-time estimate."""
    bl_label = "Render"

    def draw(self, context):
        layout = split(self.layout)
        props = context.scene.tncg15
        heading = layout.column(align=True, heading="Noise Target")
        row = heading.row(align=True)
        row.prop(props, "use_noise_target", text="")
        sub = row.row()
        sub.active = props.use_noise_target
        sub.prop(props, "noise_target", text="")
        col = layout.column(align=True)
        col.prop(props, "samples", text="Max Samples" if props.use_noise_target else "Samples")
        sub = col.column(align=True)
        sub.active = props.use_noise_target
        sub.prop(props, "min_samples")
        col.prop(props, "time_limit")
        sub = layout.column()
        sub.active = props.use_noise_target
        sub.prop(props, "adaptive")
        layout.operator("tncg15.estimate_render_time", icon="TIME")
        if props.estimate_text:
            layout.label(text=props.estimate_text)


class RENDER_PT_tncg15_sampling_viewport_denoise(TNCG15ButtonsPanel, bpy.types.Panel):
    """Sampling > Viewport > Denoise, as Cycles' (a Blender-only option: engine/pools/denoiser.py)."""
    bl_label = "Denoise"
    bl_parent_id = "RENDER_PT_tncg15_sampling_viewport"
    bl_options = {"DEFAULT_CLOSED"}

    def draw_header(self, context):
        self.layout.prop(context.scene.tncg15, "use_preview_denoising", text="")

    def draw(self, context):
        layout = split(self.layout)
        props = context.scene.tncg15
        layout.active = props.use_preview_denoising
        layout.prop(props, "viewport_denoise_start")
        denoiser_note(layout)


class RENDER_PT_tncg15_sampling_render_denoise(TNCG15ButtonsPanel, bpy.types.Panel):
    """Sampling > Render > Denoise, as Cycles': OIDN after the render, the raw image kept as the
    Noisy Image pass (mcrt_addon/render_engine.py)."""
    bl_label = "Denoise"
    bl_parent_id = "RENDER_PT_tncg15_sampling_render"
    bl_options = {"DEFAULT_CLOSED"}

    def draw_header(self, context):
        self.layout.prop(context.scene.tncg15, "use_denoising", text="")

    def draw(self, context):
        layout = split(self.layout)
        layout.active = context.scene.tncg15.use_denoising
        layout.label(text="OpenImageDenoise, Albedo and Normal")
        denoiser_note(layout)


def denoiser_note(layout):
    """One line when the denoiser is not there: where to install it (the preferences' button)."""
    from . import denoiser_install
    problem = denoiser_install.known_problem()
    if problem:
        layout.label(text="Denoiser missing: Preferences > Add-ons > Install Denoiser", icon="ERROR")


class RENDER_PT_tncg15_sampling_lights(TNCG15SamplingChild, bpy.types.Panel):
    """Lights: how many shadow rays each diffuse hit sends (eq. 2.11)."""
    bl_label = "Lights"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        split(self.layout).prop(context.scene.tncg15, "shadow_rays")


class RENDER_PT_tncg15_sampling_advanced(TNCG15SamplingChild, bpy.types.Panel):
    bl_label = "Advanced"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = split(self.layout)
        props = context.scene.tncg15
        layout.prop(props, "sampler")
        row = layout.row(align=True)
        row.prop(props, "seed")
        row.prop(props, "use_animated_seed", text="", icon="TIME")


class RENDER_PT_tncg15_light_paths(TNCG15ButtonsPanel, bpy.types.Panel):
    bl_label = "Light Paths"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        props = context.scene.tncg15
        layout.prop(props, "estimator")
        col = layout.column(heading="Russian Roulette")
        col.prop(props, "russian_roulette", text="")
        sub = col.column()
        sub.active = props.russian_roulette
        sub.prop(props, "rr_start_depth")
        layout.prop(props, "fresnel")
        layout.prop(props, "nested_dielectrics")


class TNCG15LightPathsChild(TNCG15ButtonsPanel):
    bl_parent_id = "RENDER_PT_tncg15_light_paths"


class RENDER_PT_tncg15_light_paths_max_bounces(TNCG15LightPathsChild, bpy.types.Panel):
    """Max Bounces as Cycles': the total, then per type (engine/integrators/light_paths.py)."""
    bl_label = "Max Bounces"

    def draw(self, context):
        layout = split(self.layout)
        props = context.scene.tncg15
        layout.column(align=True).prop(props, "max_depth", text="Total")
        col = layout.column(align=True)
        col.prop(props, "diffuse_bounces", text="Diffuse")
        col.prop(props, "glossy_bounces", text="Glossy")
        col.prop(props, "transmission_bounces", text="Transmission")
        layout.column(align=True).prop(props, "transparent_bounces", text="Transparent")


class RENDER_PT_tncg15_light_paths_clamping(TNCG15LightPathsChild, bpy.types.Panel):
    bl_label = "Clamping"

    def draw(self, context):
        col = split(self.layout).column(align=True)
        props = context.scene.tncg15
        col.prop(props, "clamp_direct", text="Direct Light")
        col.prop(props, "clamp_indirect", text="Indirect Light")


class RENDER_PT_tncg15_light_paths_caustics(TNCG15LightPathsChild, bpy.types.Panel):
    bl_label = "Caustics"

    def draw(self, context):
        layout = split(self.layout)
        props = context.scene.tncg15
        layout.column().prop(props, "filter_glossy")
        col = layout.column(heading="Caustics", align=True)
        col.prop(props, "caustics_reflective", text="Reflective")
        col.prop(props, "caustics_refractive", text="Refractive")
        col = layout.column(heading="Photon Map", align=True)
        col.prop(props, "caustics_method")
        col.prop(props, "photons_per_pass")
        col.prop(props, "photon_radius")
        col.prop(props, "photon_alpha")


class RENDER_PT_tncg15_film(TNCG15ButtonsPanel, bpy.types.Panel):
    """Film, as Cycles': Exposure (a linear scale), then Pixel Filter and Transparent."""
    bl_label = "Film"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        split(self.layout).prop(context.scene.tncg15, "film_exposure")


class RENDER_PT_tncg15_film_pixel_filter(TNCG15ButtonsPanel, bpy.types.Panel):
    bl_label = "Pixel Filter"
    bl_parent_id = "RENDER_PT_tncg15_film"

    def draw(self, context):
        col = split(self.layout).column()
        props = context.scene.tncg15
        col.prop(props, "pixel_filter_type", text="Type")
        col.prop(props, "filter_width")


class RENDER_PT_tncg15_film_transparency(TNCG15ButtonsPanel, bpy.types.Panel):
    """Blender's Film > Transparent (scene.render.film_transparent), which Cycles reads too."""
    bl_label = "Transparent"
    bl_parent_id = "RENDER_PT_tncg15_film"

    def draw_header(self, context):
        self.layout.prop(context.scene.render, "film_transparent", text="")

    def draw(self, context):
        layout = self.layout
        layout.active = context.scene.render.film_transparent
        layout.label(text="Alpha from the camera rays that see the world")
        layout.label(text="Glass stays opaque (no Transparent Glass)")


class RENDER_PT_tncg15_performance(TNCG15ButtonsPanel, bpy.types.Panel):
    bl_label = "Performance"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        props = context.scene.tncg15
        layout.prop(props, "threads")
        layout.prop(props, "accelerator")
        layout.prop(props, "backend")
        layout.prop(props, "tile_size")
        # Final Render > Persistent Data, Blender's own property as in Cycles (mcrt_addon/persistent.py)
        layout.prop(context.scene.render, "use_persistent_data", text="Persistent Data")
        # Viewport: Pixel Size (Blender's own property) and Start Pixels, as Cycles (mcrt_addon/viewport.py)
        layout.prop(context.scene.render, "preview_pixel_size", text="Pixel Size")
        layout.prop(props, "viewport_start_resolution", text="Start Pixels")


class VIEWLAYER_PT_tncg15_passes(TNCG15ButtonsPanel, bpy.types.Panel):
    """View Layer > Passes, as Cycles: Z (Blender's), Denoising Data, Sample Count, Variance."""
    bl_label = "Passes"
    bl_context = "view_layer"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        view_layer = context.view_layer
        col = layout.column(heading="Include", align=True)
        col.prop(view_layer, "use_pass_combined")
        col.prop(view_layer, "use_pass_z")
        col.prop(view_layer.tncg15, "denoising_store_passes")
        col.prop(view_layer.tncg15, "pass_sample_count")
        col.prop(view_layer.tncg15, "pass_variance")
        col = layout.column(heading="Data", align=True)     # Cycles' own toggles (mcrt_addon/passes.py TOGGLES)
        for toggle in ("use_pass_mist", "use_pass_position", "use_pass_normal", "use_pass_uv"):
            col.prop(view_layer, toggle)
        col = layout.column(heading="Indexes", align=True)
        col.prop(view_layer, "use_pass_object_index")
        col.prop(view_layer, "use_pass_material_index")
        for kind in ("diffuse", "glossy", "transmission"):
            col = layout.column(heading=kind.title(), align=True)
            col.prop(view_layer, f"use_pass_{kind}_direct", text="Direct")
            col.prop(view_layer, f"use_pass_{kind}_indirect", text="Indirect")
            col.prop(view_layer, f"use_pass_{kind}_color", text="Color")
        col = layout.column(heading="Other", align=True)
        col.prop(view_layer, "use_pass_emit", text="Emission")
        col.prop(view_layer, "use_pass_environment")
        col = layout.column(heading="Cryptomatte", align=True)
        col.prop(view_layer, "use_pass_cryptomatte_object", text="Object")
        col.prop(view_layer, "use_pass_cryptomatte_material", text="Material")
        col.prop(view_layer, "use_pass_cryptomatte_asset", text="Asset")


class WORLD_PT_tncg15_mist(TNCG15ButtonsPanel, bpy.types.Panel):
    """World > Mist Pass, as Cycles: shown when the view layer's Mist pass is on."""
    bl_label = "Mist Pass"
    bl_context = "world"

    @classmethod
    def poll(cls, context):
        return (super().poll(context) and context.world is not None
                and getattr(context.view_layer, "use_pass_mist", False))

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        mist = context.world.mist_settings
        col = layout.column(align=True)
        col.prop(mist, "start")
        col.prop(mist, "depth")
        layout.prop(mist, "falloff")


class OBJECT_PT_tncg15(TNCG15ButtonsPanel, bpy.types.Panel):
    bl_label = "TNCG15 MC"
    bl_context = "object"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and context.object is not None and context.object.type == "MESH"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(context.object.tncg15, "implicit_sphere")


class DATA_PT_tncg15_light(TNCG15ButtonsPanel, bpy.types.Panel):
    """The light's options the exporter reads (mcrt_addon/export/lights.py), laid out as Cycles'
    Light panel: type, colour, power and exposure, then the type's shape."""
    bl_label = "Light"
    bl_context = "data"

    @classmethod
    def poll(cls, context):
        return context.light is not None and super().poll(context)

    def draw(self, context):
        layout = self.layout
        light = context.light
        layout.row().prop(light, "type", expand=True)
        split(layout)
        col = layout.column()
        col.prop(light, "color")
        col.prop(light, "energy")
        if hasattr(light, "exposure"):                       # Blender 4.0 on
            col.prop(light, "exposure")
        col.separator()
        if light.type in {"POINT", "SPOT"}:
            col.prop(light, "shadow_soft_size", text="Radius")
        elif light.type == "SUN":
            col.prop(light, "angle")
        elif light.type == "AREA":
            col.prop(light, "shape", text="Shape")
            sub = col.column(align=True)
            if light.shape in {"SQUARE", "DISK"}:
                sub.prop(light, "size")
            else:
                sub.prop(light, "size", text="Size X")
                sub.prop(light, "size_y", text="Y")
            if hasattr(light, "normalize"):
                col.prop(light, "normalize")
        cycles = getattr(light, "cycles", None)              # the Cycles add-on's light options
        if cycles is not None:
            col.separator()
            col.prop(cycles, "use_multiple_importance_sampling", text="Multiple Importance")
            if light.type == "AREA":
                col.prop(cycles, "is_portal", text="Portal")


classes = (RENDER_PT_tncg15_sampling, RENDER_PT_tncg15_sampling_viewport,
           RENDER_PT_tncg15_sampling_viewport_denoise, RENDER_PT_tncg15_sampling_render,
           RENDER_PT_tncg15_sampling_render_denoise, RENDER_PT_tncg15_sampling_lights, RENDER_PT_tncg15_sampling_advanced, RENDER_PT_tncg15_light_paths,
           RENDER_PT_tncg15_light_paths_max_bounces, RENDER_PT_tncg15_light_paths_clamping,
           RENDER_PT_tncg15_light_paths_caustics, RENDER_PT_tncg15_film, RENDER_PT_tncg15_film_pixel_filter,
           RENDER_PT_tncg15_film_transparency, RENDER_PT_tncg15_performance, VIEWLAYER_PT_tncg15_passes, WORLD_PT_tncg15_mist, OBJECT_PT_tncg15,
           DATA_PT_tncg15_light)

_lent = []   # panels we added our engine id to, so unregister removes exactly those


def _compatible_panels():
    for panel in bpy.types.Panel.__subclasses__():
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if engines is None or panel.__name__ in EXCLUDED_PANELS:
            continue
        if "BLENDER_RENDER" in engines or panel.__name__ in EXTRA_PANELS:
            yield panel


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    for panel in _compatible_panels():
        if ENGINE_ID not in panel.COMPAT_ENGINES:
            panel.COMPAT_ENGINES.add(ENGINE_ID)
            _lent.append(panel)


def unregister():
    while _lent:
        panel = _lent.pop()
        panel.COMPAT_ENGINES.discard(ENGINE_ID)
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
