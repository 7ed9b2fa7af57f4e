"""Render settings stored on the scene (``scene.tncg15``) and per-object options (``object.tncg15``).

Mirrors Cycles' ``properties.py``: plain PropertyGroups, no behaviour except converting the
scene settings into the tracer's ``RenderSettings``.
"""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty

FRESNEL_ITEMS = (
    ("SCHLICK", "Schlick", "Schlick's approximation (report eq. 2.17)"),
    ("EXACT", "Exact", "Exact dielectric Fresnel, as Cycles uses"),
)
ESTIMATOR_ITEMS = (
    ("MIS", "Multiple Importance", "Lights sampled by solid angle (spherical rectangles and triangles, "
                                   "sphere cones) and picked by a light tree, combined with the BSDF "
                                   "sample by multiple importance sampling, as Cycles"),
    ("SOLID_ANGLE", "Light Sampling", "Lights sampled by solid angle and picked by a light tree; "
                                      "emission found by diffuse bounces is left to the shadow rays"),
    ("REPORT", "Report (Area)", "The report's estimator (eq. 2.11): a light picked by power, a point on "
                                "it uniform by area (pdf 1/A); noisy near lights"),
)
SAMPLER_ITEMS = (
    ("SOBOL", "Sobol", "Owen-scrambled Sobol' points per pixel, each dimension pair shuffled "
                       "independently (lower noise, as Cycles' default pattern)"),
    ("RANDOM", "Random", "Independent uniform random numbers (plain Monte Carlo)"),
)
ACCELERATOR_ITEMS = (
    ("AUTO", "Auto", "Pick the fastest available accelerator"),
    ("EMBREE", "Embree", "Intel Embree through embreex"),
    ("OCTREE", "Octree", "The tracer's own octree (NumPy)"),
    ("BRUTE", "Brute Force", "Test every primitive (reference, slow)"),
)
SPHERE_ITEMS = (
    ("AUTO", "Auto", "Render as an exact sphere when the mesh is a closed sphere "
                     "(all vertices equidistant from the centre, uniform scale)"),
    ("ALWAYS", "Always", "Always render as the mesh's bounding sphere"),
    ("NEVER", "Never", "Always render the triangles"),
)


class TNCG15RenderSettings(bpy.types.PropertyGroup):
    samples: IntProperty(name="Samples", description="Camera rays per pixel",
                         default=16, min=1, soft_max=4096)
    viewport_samples: IntProperty(name="Max Samples", description="Samples per pixel the 3D viewport's "
                                  "Rendered mode accumulates", default=32, min=1, soft_max=4096)
    shadow_rays: IntProperty(name="Shadow Rays", description="Light samples per diffuse hit",
                             default=1, min=0, soft_max=64)
    # Stopping rules, laid out as Cycles' Noise Threshold, Min Samples, Time Limit (README: Stopping rules)
    use_noise_target: BoolProperty(name="Noise Target", description="Stop when the estimated relative error "
                                   "of the image reaches the target", default=False)
    noise_target: FloatProperty(name="Noise Target", description="Estimated relative error (RMS over the "
                                "pixels, relative to the pixel values) at which the render stops",
                                default=0.01, min=0.0001, max=1.0, precision=4, step=0.1)
    adaptive: BoolProperty(name="Adaptive Sampling", description="With a noise target: blocks of 8x8 pixels "
                           "whose error reached it get no more samples", default=True)
    min_samples: IntProperty(name="Min Samples", description="Samples every pixel gets before the noise "
                             "target may stop it (0 = automatic: 16 / Noise Target^0.3, as Cycles)", default=0, min=0, soft_max=4096)
    time_limit: FloatProperty(name="Time Limit", description="Stop rendering after this many seconds "
                              "(0 = no limit)", default=0.0, min=0.0, soft_max=3600.0, precision=1)
    estimate_text: bpy.props.StringProperty(name="Estimate", description="The last Estimate Render Time",
                                            default="", options={"SKIP_SAVE"})
    sampler: EnumProperty(name="Pattern", description="Where the random numbers of each pixel come from",
                          items=SAMPLER_ITEMS, default="SOBOL")
    seed: IntProperty(name="Seed", description="Random seed; the same seed gives the same image",
                      default=0, min=0)
    max_depth: IntProperty(name="Max Bounces", description="Bounces after the camera hit (0 = direct light only)",
                           default=8, min=0, soft_max=128)
    russian_roulette: BoolProperty(name="Russian Roulette", description="Terminate paths randomly "
                                   "(unbiased) from the start depth on", default=True)
    rr_start_depth: IntProperty(name="Start Depth", description="First bounce at which Russian roulette applies",
                                default=3, min=0, soft_max=64)
    fresnel: EnumProperty(name="Fresnel", description="Fresnel model for glass", items=FRESNEL_ITEMS,
                          default="SCHLICK")
    estimator: EnumProperty(name="Estimator", description="How direct light is estimated",
                            items=ESTIMATOR_ITEMS, default="MIS")
    nested_dielectrics: BoolProperty(name="Nested Dielectrics", description="Track the media a path is "
                                     "inside, so glass inside glass refracts by the ratio of the two IORs "
                                     "(off: every glass surface is against air, as Cycles)", default=False)
    threads: IntProperty(name="Threads", description="Worker threads (0 = all cores)", default=0, min=0,
                         soft_max=256)
    accelerator: EnumProperty(name="Accelerator", description="Ray-intersection acceleration structure",
                              items=ACCELERATOR_ITEMS, default="AUTO")
    tile_size: IntProperty(name="Tile Size", description="Tile edge in pixels", default=64, min=8,
                           soft_max=1024)
    use_denoising: BoolProperty(name="Denoise", description="Denoise the final render with Intel Open Image "
                                "Denoise (pyoidn in the worker Python), guided by the Denoising Albedo and "
                                "Normal passes; the raw image is kept as the Noisy Image pass", default=False)

    def to_settings(self, settings_cls):
        """The tracer's RenderSettings for these values (the class is passed in: the tracer loads lazily)."""
        return settings_cls(
            samples=self.samples, shadow_rays=self.shadow_rays, max_depth=self.max_depth,
            russian_roulette=self.russian_roulette, rr_start_depth=self.rr_start_depth,
            fresnel=self.fresnel.lower(), nested_dielectrics=self.nested_dielectrics,
            estimator=self.estimator.lower().replace("_", "-"), sampler=self.sampler.lower(),
            threads=self.threads, seed=self.seed,
            tile_size=self.tile_size, accelerator=self.accelerator.lower(),
            noise_target=self.noise_target if self.use_noise_target else 0.0, adaptive=self.adaptive,
            min_samples=min(self.min_samples, self.samples), time_limit=self.time_limit)


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
