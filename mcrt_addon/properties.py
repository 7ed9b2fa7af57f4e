"""Render settings stored on the scene (``scene.tncg15``) and per-object options (``object.tncg15``).

Mirrors Cycles' ``properties.py``: plain PropertyGroups, no behaviour except converting the
scene settings into the tracer's ``RenderSettings`` and back.  The scene's properties are made
from the tracer's settings table (engine/core/settings.py, read through bridge.py without numpy):
one bpy property per row that Blender exposes, with the row's label, default (Cycles' default
where the row names one for new files: the pixel filter, the Light Paths options) and limits; a row
whose 0 means off (noise_target) gets a checkbox beside it, as Cycles' Noise Threshold.  Two
settings are Blender's own, read where Cycles reads them: Film > Transparent
(scene.render.film_transparent) and the frame that the animated seed hashes with the seed
(scene.frame_current).  `apply_preset` sets the command lines' presets (fair, cycles) onto a scene.
"""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty

from . import bridge

TABLE = bridge.settings_table()
SCENE_SETTINGS = TABLE.settings_for(TABLE.BLENDER)


def enum_items(setting) -> tuple:
    """(identifier, label, description) of each choice: 'solid-angle' -> 'SOLID_ANGLE'."""
    return tuple((c.identifier, c.label, c.description) for c in setting.choices)


ACCELERATOR_ITEMS = enum_items(TABLE.SETTING["accelerator"])
SPHERE_ITEMS = (
    ("AUTO", "Auto", "Render as an exact sphere when the mesh is a closed sphere "
                     "(all vertices equidistant from the centre, uniform scale)"),
    ("ALWAYS", "Always", "Always render as the mesh's bounding sphere"),
    ("NEVER", "Never", "Always render the triangles"),
)


def scene_property(s):
    """The bpy property of one row of the table."""
    common = dict(name=s.label, description=s.description or s.help, **s.bpy_options)
    default = s.new_file_default
    if s.kind == TABLE.INT:
        return IntProperty(default=default, min=s.limits[0], max=s.limits[1], **common)
    if s.kind == TABLE.FLOAT:
        low = s.limits[0]
        if s.off_toggle is not None:
            low, default = s.off_toggle.on_min, s.off_toggle.on_default
        return FloatProperty(default=default, min=low, max=s.limits[1], **common)
    if s.kind == TABLE.BOOL:
        return BoolProperty(default=default, **common)
    if s.kind == TABLE.CHOICE:
        return EnumProperty(items=enum_items(s), default=s.identifier(default), **common)
    raise TypeError(f"setting {s.name}: no Blender property for a {s.kind} setting")


def scene_properties() -> dict:
    """The annotations of TNCG15RenderSettings: the table's rows, then Blender's own options."""
    props = {}
    for s in SCENE_SETTINGS:
        if s.off_toggle is not None:
            props[s.off_toggle.prop] = BoolProperty(name=s.label, description=s.off_toggle.description,
                                                    default=False)
        props[s.blender_prop] = scene_property(s)
    props["viewport_samples"] = IntProperty(name="Max Samples", description="Samples per pixel the 3D viewport's "
                                            "Rendered mode accumulates", default=32, min=1, soft_max=4096)
    # Performance > Viewport > Start Pixels, as Cycles' preview_start_resolution: the first coarse
    # frame of a view has at most this squared pixels (engine/pools/viewport.py start_divider)
    props["viewport_start_resolution"] = IntProperty(name="Start Pixels", default=64, min=8, max=16384,
                                                     subtype="PIXEL", description="Resolution to start "
                                                     "rendering the viewport at, progressively increasing "
                                                     "it to the full viewport size")
    # Viewport > Denoise, as Cycles' use_preview_denoising and preview_denoising_start_sample: the
    # viewport's display only (engine/pools/denoiser.py), never the tracer's settings
    props["use_preview_denoising"] = BoolProperty(name="Denoise", default=False, description="Denoise the "
                                                  "Rendered viewport with Intel Open Image Denoise (colour only)")
    props["viewport_denoise_start"] = IntProperty(name="Start Sample", default=1, min=1, soft_max=64,
                                                  description="Sample from which the viewport is denoised")
    props["estimate_text"] = StringProperty(name="Estimate", description="The last Estimate Render Time",
                                            default="", options={"SKIP_SAVE"})
    return props


class TNCG15RenderSettings(bpy.types.PropertyGroup):
    # Built from the table (a dict, not written annotations: the same in Python 3.10 and 3.11+).
    __annotations__ = scene_properties()

    def setting(self, s):
        """The value of one row (engine/core/settings.py) in the tracer's terms."""
        value = getattr(self, s.blender_prop)
        if s.off_toggle is not None and not getattr(self, s.off_toggle.prop):
            return s.default                        # off
        if s.kind == TABLE.CHOICE:
            return s.value_of(value)                # 'SOLID_ANGLE' -> 'solid-angle'
        return value

    def set_setting(self, s, value):
        """One row's value (the tracer's terms) onto these properties; the inverse of `setting`."""
        if s.off_toggle is not None:
            setattr(self, s.off_toggle.prop, value != s.default)
            if value == s.default:
                return                              # off: the value the user last chose stays
        if s.kind == TABLE.CHOICE:
            value = s.identifier(value)
        setattr(self, s.blender_prop, value)

    def to_settings(self, settings_cls):
        """The tracer's RenderSettings for these values (the class is passed in: the tracer loads lazily)."""
        settings = settings_cls(**{s.name: self.setting(s) for s in SCENE_SETTINGS})
        settings.min_samples = min(settings.min_samples, settings.samples)    # the panel lets Min exceed Max
        scene = self.id_data
        settings.film_transparent = bool(scene.render.film_transparent)
        if settings.animated_seed:                  # Cycles: hash_uint2(frame, seed)
            settings.seed = TABLE.animated_seed(settings.seed, scene.frame_current)
        return settings


def apply_preset(props, name):
    """A preset of the settings table (engine/core/settings.py preset_values: "fair" or "cycles")
    onto scene.tncg15.  "fair" also gives the total (Max Bounces) the table's default where the
    file does not set it: a file saved before it had Cycles' default renders as it did."""
    for setting, value in TABLE.preset_values(name).items():
        props.set_setting(TABLE.SETTING[setting], value)
    total = TABLE.SETTING["max_depth"]
    if name == TABLE.FAIR and not props.is_property_set(total.blender_prop):
        props.set_setting(total, total.default)


class TNCG15ViewLayerSettings(bpy.types.PropertyGroup):
    """Pass toggles as Cycles' view layer has them (Depth is Blender's own use_pass_z)."""
    denoising_store_passes: BoolProperty(name="Denoising Data", description="Denoising Albedo and Denoising "
                                         "Normal passes (first non-specular hit, as Cycles)", default=False)
    pass_sample_count: BoolProperty(name="Sample Count", description="Camera samples per pixel "
                                    "(Debug Sample Count pass)", default=False)
    pass_variance: BoolProperty(name="Variance", description="Variance of each pixel's mean "
                                "(sample variance / samples)", default=False)


class TNCG15ObjectSettings(bpy.types.PropertyGroup):
    implicit_sphere: EnumProperty(name="Implicit Sphere", items=SPHERE_ITEMS, default="AUTO",
                                  description="Render this mesh as an exact (implicit) sphere")


classes = (TNCG15RenderSettings, TNCG15ViewLayerSettings, TNCG15ObjectSettings)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.tncg15 = PointerProperty(type=TNCG15RenderSettings, name="TNCG15 MC")
    bpy.types.Object.tncg15 = PointerProperty(type=TNCG15ObjectSettings, name="TNCG15 MC")
    bpy.types.ViewLayer.tncg15 = PointerProperty(type=TNCG15ViewLayerSettings, name="TNCG15 MC")


def unregister():
    del bpy.types.ViewLayer.tncg15
    del bpy.types.Object.tncg15
    del bpy.types.Scene.tncg15
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
