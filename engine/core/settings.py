"""Render settings: one table of rows (SETTINGS), and what is made from it.

Every knob of a render is one `Setting` row below.  From the rows are made:

* `RenderSettings` (the dataclass the tracer reads): one field per row, in table order, and its
  `validate()` (the row's limits or choices);
* both command lines' arguments and their conversion to settings (engine/cli/settings_args.py,
  used by engine/cli/main.py and mcrt_addon/cli.py);
* the Blender PropertyGroup ``scene.tncg15`` and its `to_settings` (mcrt_addon/properties.py);
* the settings the render stats list (`stats_of`, engine/rendering/frame.py);
* the user guide's settings reference docs/settings.md (scripts/settings_doc.py).

tests/core/test_settings_table.py checks that every row reaches every front end it declares with
the same default and limits.  This module imports only the standard library (and errors.py): the
Blender add-on reads the table at registration, before it knows whether numpy is there.
"""
from __future__ import annotations

import numbers
import os
from dataclasses import asdict, dataclass, field

from .errors import SceneError

INT32_MAX = 2**31 - 1

# Kinds of setting (`Setting.kind`) and the Python type of their RenderSettings field.
INT, FLOAT, BOOL, CHOICE, CHOICES = "int", "float", "bool", "choice", "choices"
FIELD_TYPES = {INT: int, FLOAT: float, BOOL: bool, CHOICE: str, CHOICES: tuple}

# The front ends a row can reach (`Setting.fronts`).
ENGINE_CLI = "engine-cli"        # python -m engine render|estimate (engine/cli/main.py)
ADDON_CLI = "addon-cli"          # python -m mcrt_addon render (mcrt_addon/cli.py)
BLENDER = "blender"              # scene.tncg15 and the Render Properties panels (mcrt_addon/)
EVERY_FRONT = frozenset((ENGINE_CLI, ADDON_CLI, BLENDER))
INTERNAL = frozenset()           # set by the tracer itself (or by Python callers) only

# How the render stats list a setting (`Setting.stats`).
STATS_AS_SET = "as set"          # under its name, the value of the setting (stats_of)
STATS_RESOLVED = "as resolved"   # under its name, what the render made of it (engine/rendering/frame.py)


@dataclass(frozen=True)
class Choice:
    """One value of a CHOICE / CHOICES setting."""
    value: str                   # the tracer's and both command lines' name
    label: str                   # Blender's menu entry
    description: str = ""        # Blender's tooltip

    @property
    def identifier(self) -> str:
        """Blender's enum identifier: 'solid-angle' -> 'SOLID_ANGLE'."""
        return self.value.upper().replace("-", "_")


@dataclass(frozen=True)
class OffToggle:
    """In Blender a setting whose 0 means off is a checkbox beside its value (Cycles' Noise
    Threshold): the value property then starts at `on_default` and cannot go below `on_min`."""
    prop: str                    # the checkbox's property name
    description: str
    on_default: float
    on_min: float


@dataclass(frozen=True)
class Setting:
    """One row of the settings table."""
    name: str                    # the RenderSettings field
    kind: str                    # INT, FLOAT, BOOL, CHOICE or CHOICES (a tuple of choices)
    default: object
    help: str                    # the command lines' help (and docs/settings.md)
    limits: tuple = None         # (low, high), both allowed: INT and FLOAT
    choices: tuple = ()          # Choice rows: CHOICE and CHOICES
    fronts: frozenset = EVERY_FRONT
    flag: str = None             # both command lines; a BOOL's flag flips its default (--no-... when on)
    metavar: str = None
    label: str = None            # Blender's label
    description: str = None      # Blender's tooltip (default: the help)
    prop: str = None             # Blender's property name where it is not `name`
    bpy_options: dict = field(default_factory=dict)   # more keywords of the bpy property (soft_max, ...)
    off_toggle: OffToggle = None
    panel: str = None            # where Blender draws it (docs; checked against mcrt_addon/ui.py)
    noun: str = None             # the validation message's name of a choice (default: the name)
    stats: str = None            # STATS_AS_SET, STATS_RESOLVED or None (not in the stats)
    blender_default: object = None   # a new Blender file's value where it is not `default` (Cycles' default)

    @property
    def values(self) -> tuple:
        return tuple(c.value for c in self.choices)

    @property
    def blender_prop(self) -> str:
        return self.prop or self.name

    @property
    def new_file_default(self):
        """The value scene.tncg15 starts with in a new Blender file: Cycles' default where the
        command lines' reference default differs (the pixel filter, the Light Paths options)."""
        return self.default if self.blender_default is None else self.blender_default

    def identifier(self, value: str) -> str:
        """A CHOICE's value as Blender's enum identifier: 'solid-angle' -> 'SOLID_ANGLE'."""
        return next(c.identifier for c in self.choices if c.value == value)

    def value_of(self, identifier: str) -> str:
        """The inverse of `identifier`."""
        return next(c.value for c in self.choices if c.identifier == identifier)

    @property
    def dest(self) -> str:
        """The argparse attribute of the flag."""
        return self.flag[2:].replace("-", "_")

    def check(self, value) -> None:
        """Raises SceneError naming the setting when `value` is not allowed."""
        words = self.name.replace("_", " ")
        if self.kind == INT:
            low, high = self.limits
            if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not low <= value <= high:
                raise SceneError(f"{words} must be an integer from {low} to {high:,}, got {value!r}")
        elif self.kind == FLOAT:
            low, high = self.limits
            if isinstance(value, bool) or not isinstance(value, numbers.Real) or not low <= value <= high:
                low_text = f"{low:g} (off)" if low == 0 else f"{low:g}"
                raise SceneError(f"{words} must be a number from {low_text} to {high:g}, got {value!r}")
        elif self.kind == CHOICE:
            if value not in self.values:
                raise SceneError(f"unknown {self.noun or words} '{value}' (expected one of "
                                 f"{', '.join(self.values)})")
        elif self.kind == CHOICES:
            bad = [v for v in value if v not in self.values]
            if bad:
                raise SceneError(f"unknown {self.noun or words} '{bad[0]}' (known: {', '.join(self.values)})")

    def parse_choices(self, text) -> tuple:
        """A CHOICES setting from text: 'normal,albedo' -> ('albedo', 'normal') in table order;
        '' or None -> (); SceneError for an unknown name."""
        if not text:
            return ()
        names = [n.strip().lower() for n in str(text).split(",") if n.strip()]
        self.check(names)
        return tuple(v for v in self.values if v in names)


def plain(*values: str) -> tuple:
    """Choices that have no Blender menu of their own."""
    return tuple(Choice(v, v) for v in values)


STOPPING = "engine/rendering/stopping.py"
BOUNCES_OFF = 1024                   # a bounce type's limit at which only the total limits it (fair)
SETTINGS = (
    Setting("samples", INT, 16, "camera rays per pixel", limits=(1, INT32_MAX), flag="--samples",
            label="Samples", description="Camera rays per pixel", bpy_options={"soft_max": 4096},
            panel="Sampling > Render", stats=STATS_AS_SET),
    Setting("shadow_rays", INT, 1, "shadow rays per diffuse hit (N_s in eq. 2.11)", limits=(0, 1024),
            flag="--shadow-rays", label="Shadow Rays", description="Light samples per diffuse hit",
            bpy_options={"soft_max": 64}, panel="Sampling > Lights", stats=STATS_AS_SET),
    Setting("max_depth", INT, 8, "bounces after the camera hit (0 = direct light only; report 3.4)",
            limits=(0, INT32_MAX - 1), flag="--max-depth", label="Max Bounces",
            description="Bounces after the camera hit (0 = direct light only)", bpy_options={"soft_max": 128},
            panel="Light Paths > Max Bounces", stats=STATS_AS_SET, blender_default=12),
    # Cycles' Light Paths (docs/user-guide.md "Light paths"; engine/integrators/path_tracer.py): the
    # table's defaults are the fair reference (no limit of a bounce type below the total, no clamp,
    # no filter, caustics on), `cycles` Cycles' defaults (a new .blend file, --preset cycles).
    Setting("diffuse_bounces", INT, BOUNCES_OFF, "diffuse reflection bounces (bounded by --max-depth)",
            limits=(0, INT32_MAX - 1), flag="--diffuse-bounces", label="Diffuse Bounces",
            description="Maximum number of diffuse reflection bounces, bounded by total maximum",
            bpy_options={"soft_max": 1024}, panel="Light Paths > Max Bounces", stats=STATS_AS_SET,
            blender_default=4),
    Setting("glossy_bounces", INT, BOUNCES_OFF, "glossy and mirror reflection bounces (bounded by --max-depth)",
            limits=(0, INT32_MAX - 1), flag="--glossy-bounces", label="Glossy Bounces",
            description="Maximum number of glossy reflection bounces, bounded by total maximum",
            bpy_options={"soft_max": 1024}, panel="Light Paths > Max Bounces", stats=STATS_AS_SET,
            blender_default=4),
    Setting("transmission_bounces", INT, BOUNCES_OFF, "transmission (refraction) bounces (bounded by "
            "--max-depth)", limits=(0, INT32_MAX - 1), flag="--transmission-bounces", label="Transmission Bounces",
            description="Maximum number of transmission bounces, bounded by total maximum",
            bpy_options={"soft_max": 1024}, panel="Light Paths > Max Bounces", stats=STATS_AS_SET,
            blender_default=12),
    Setting("transparent_bounces", INT, BOUNCES_OFF, "transparent bounces: straight pass-throughs (the "
            "Transparent BSDF, the Principled BSDF's alpha); Cycles does not count them in --max-depth, the "
            "tracer does",
            limits=(0, INT32_MAX - 1), flag="--transparent-bounces", label="Transparent Max Bounces",
            description="Maximum number of transparent bounces. This is independent of maximum number of other "
            "bounces", bpy_options={"soft_max": 1024}, panel="Light Paths > Max Bounces", stats=STATS_AS_SET,
            blender_default=8),
    Setting("clamp_direct", FLOAT, 0.0, "clamp each direct-light contribution (camera-seen emission and light "
            "after one bounce) to a mean over R, G, B of X (0 = off)", limits=(0.0, 1e8), flag="--clamp-direct",
            metavar="X", label="Clamp Direct", description="If non-zero, the maximum value for a direct sample, "
            "higher values will be scaled down to avoid too much noise and slow convergence at the cost of accuracy",
            bpy_options={"soft_max": 1000.0}, panel="Light Paths > Clamping", stats=STATS_AS_SET),
    Setting("clamp_indirect", FLOAT, 0.0, "clamp each indirect contribution (after two or more bounces) to a "
            "mean over R, G, B of X (0 = off)", limits=(0.0, 1e8), flag="--clamp-indirect", metavar="X",
            label="Clamp Indirect", description="If non-zero, the maximum value for an indirect sample, higher "
            "values will be scaled down to avoid too much noise and slow convergence at the cost of accuracy",
            bpy_options={"soft_max": 1000.0}, panel="Light Paths > Clamping", stats=STATS_AS_SET,
            blender_default=10.0),
    Setting("filter_glossy", FLOAT, 0.0, "widen the roughness of microfacet lobes after blurry bounces (Cycles' "
            "Filter Glossy; 0 = off)", limits=(0.0, 10.0), flag="--filter-glossy", metavar="X",
            label="Filter Glossy", description="Adaptively blur glossy shaders after blurry bounces, to reduce "
            "noise at the cost of accuracy", panel="Light Paths > Caustics", stats=STATS_AS_SET,
            blender_default=1.0),
    Setting("caustics_reflective", BOOL, True, "leave out glossy and mirror reflection after a diffuse bounce",
            flag="--no-caustics-reflective", label="Reflective Caustics", description="Use reflective caustics, "
            "resulting in a brighter image (more noise but added realism)", panel="Light Paths > Caustics",
            stats=STATS_AS_SET),
    Setting("caustics_refractive", BOOL, True, "leave out refraction after a diffuse bounce",
            flag="--no-caustics-refractive", label="Refractive Caustics", description="Use refractive caustics, "
            "resulting in a brighter image (more noise but added realism)", panel="Light Paths > Caustics",
            stats=STATS_AS_SET),
    Setting("caustics_method", CHOICE, "path", "caustics (light through mirrors and glass onto diffuse "
            "surfaces): path tracing alone, a progressive caustic photon map beside it (docs/photons.md), or auto "
            "(photons where there are specular objects and non-specular receivers, path tracing under the report "
            "estimator)", flag="--caustics-method",
            noun="caustics method", label="Method", description="How caustics are rendered",
            panel="Light Paths > Caustics", stats=STATS_AS_SET,
            choices=(Choice("auto", "Auto", "A photon map where the scene has specular objects and receivers"),
                     Choice("path", "Path Tracing", "Path tracing alone (point-light caustics stay black)"),
                     Choice("photons", "Photon Map", "A progressive caustic photon map beside the path tracer"))),
    Setting("photons_per_pass", INT, 0, "caustic photons emitted per photon pass (one pass per sample "
            "per pixel; 0 = auto: a quarter of the render's pixels, 1000 to 50000)", limits=(0, INT32_MAX),
            flag="--photons-per-pass", label="Photons per Pass",
            description="Caustic photons emitted per pass (one pass per sample; 0: a quarter of the pixels)",
            bpy_options={"soft_max": 2000000},
            panel="Light Paths > Caustics", stats=STATS_AS_SET),
    Setting("photon_radius", FLOAT, 0.0, "the caustic photon map's first gather radius (0 = auto: one pixel "
            "footprint at the specular objects)", limits=(0.0, 1e30), flag="--photon-radius", metavar="R",
            label="Initial Radius", description="First gather radius of the caustic photon map (0: automatic)",
            panel="Light Paths > Caustics", stats=STATS_AS_SET),
    Setting("photon_alpha", FLOAT, 2.0 / 3.0, "the photon radius's reduction per pass: r^2 shrinks by "
            "(k + alpha) / (k + 1) (SPPM's alpha)", limits=(0.01, 0.99), flag="--photon-alpha", metavar="A",
            label="Alpha", description="Radius reduction of the progressive photon map (SPPM's alpha)",
            panel="Light Paths > Caustics", stats=STATS_AS_SET),
    Setting("russian_roulette", BOOL, True, "disable Russian roulette (report 2.4)", flag="--no-russian-roulette",
            label="Russian Roulette", description="Terminate paths randomly (unbiased) from the start depth on",
            panel="Light Paths", stats=STATS_AS_SET),
    Setting("rr_start_depth", INT, 3, "first bounce at which Russian roulette applies", limits=(0, INT32_MAX),
            flag="--rr-start-depth", label="Start Depth",
            description="First bounce at which Russian roulette applies", bpy_options={"soft_max": 64},
            panel="Light Paths"),
    Setting("fresnel", CHOICE, "schlick", "Fresnel model for glass: Schlick's approximation (eq. 2.17) or "
            "exact dielectric Fresnel as Cycles", flag="--fresnel", noun="Fresnel model", label="Fresnel",
            description="Fresnel model for glass", panel="Light Paths", stats=STATS_AS_SET,
            choices=(Choice("schlick", "Schlick", "Schlick's approximation (report eq. 2.17)"),
                     Choice("exact", "Exact", "Exact dielectric Fresnel, as Cycles uses"))),
    Setting("nested_dielectrics", BOOL, False, "track nested glass media (glass in glass refracts by the IOR "
            "ratio; Cycles has no such model)", flag="--nested-dielectrics", label="Nested Dielectrics",
            description="Track the media a path is inside, so glass inside glass refracts by the ratio of the "
            "two IORs (off: every glass surface is against air, as Cycles)", panel="Light Paths"),
    Setting("estimator", CHOICE, "mis", "direct light: mis (solid-angle light samples and BSDF samples "
            "combined by MIS), solid-angle (light samples only), report (eq. 2.11: area sampling, pdf 1/A)",
            flag="--estimator", label="Estimator", description="How direct light is estimated",
            panel="Light Paths", stats=STATS_AS_SET,
            choices=(Choice("mis", "Multiple Importance", "Lights sampled by solid angle (spherical rectangles "
                            "and triangles, sphere cones) and picked by a light tree, combined with the BSDF "
                            "sample by multiple importance sampling, as Cycles"),
                     Choice("solid-angle", "Light Sampling", "Lights sampled by solid angle and picked by a "
                            "light tree; emission found by diffuse bounces is left to the shadow rays"),
                     Choice("report", "Report (Area)", "The report's estimator (eq. 2.11): a light picked by "
                            "power, a point on it uniform by area (pdf 1/A); noisy near lights"))),
    Setting("sampler", CHOICE, "sobol", "sobol: Owen-scrambled Sobol' points per pixel "
            "(engine/sampling/qmc.py); random: independent uniforms", flag="--sampler", label="Pattern",
            description="Where the random numbers of each pixel come from", panel="Sampling > Advanced",
            stats=STATS_AS_SET,
            choices=(Choice("sobol", "Sobol", "Owen-scrambled Sobol' points per pixel, each dimension pair "
                            "shuffled independently (lower noise, as Cycles' default pattern)"),
                     Choice("random", "Random", "Independent uniform random numbers (plain Monte Carlo)"))),
    Setting("sample_net", INT, 0, "the size of each pixel's Sobol' net (engine/sampling/qmc.py: sample i "
            "depends on it); 0 = samples.  Estimate Render Time's pilot (engine/rendering/estimate.py) "
            "renders the real render's first rounds with the real render's nets, and so the very samples "
            "that render starts with", limits=(0, INT32_MAX), fronts=INTERNAL),
    Setting("threads", INT, 0, "worker threads or processes (0 = all cores)", limits=(0, 1024), flag="--threads",
            label="Threads", description="Worker threads (0 = all cores)", bpy_options={"soft_max": 256},
            panel="Performance", stats=STATS_RESOLVED),
    Setting("seed", INT, 0, "random seed; the same seed gives the same image", limits=(0, INT32_MAX),
            flag="--seed", label="Seed", description="Random seed; the same seed gives the same image",
            panel="Sampling > Advanced", stats=STATS_AS_SET),
    Setting("tile_size", INT, 64, "tile edge in pixels", limits=(8, 16384), flag="--tile-size",
            label="Tile Size", description="Tile edge in pixels", bpy_options={"soft_max": 1024},
            panel="Performance", stats=STATS_RESOLVED),
    Setting("accelerator", CHOICE, "auto", "ray-intersection acceleration structure", flag="--accelerator",
            label="Accelerator", panel="Performance", stats=STATS_RESOLVED,
            description="Ray-intersection acceleration structure",
            choices=(Choice("auto", "Auto", "Pick the fastest available accelerator"),
                     Choice("embree", "Embree", "Intel Embree through embreex"),
                     Choice("octree", "Octree", "The tracer's own octree (NumPy)"),
                     Choice("brute", "Brute Force", "Test every primitive (reference, slow)"))),
    Setting("backend", CHOICE, "auto", "the hot kernels: numba's compiled twins or NumPy (engine/core/backend.py; "
            "auto = numba once its kernels are compiled, else NumPy)", flag="--backend",
            label="Backend", panel="Performance", stats=STATS_RESOLVED,
            description="Kernels compiled with numba, or the NumPy reference (the same images)",
            choices=(Choice("auto", "Auto", "numba when installed and compiled (it compiles in the background "
                                            "once), else NumPy"),
                     Choice("numpy", "NumPy", "The NumPy kernels (the reference)"),
                     Choice("numba", "numba", "The compiled kernels (compiling first if needed)"))),
    Setting("parallelism", CHOICE, "auto", "how several workers run: threads, processes (forked, Linux, "
            "outside Blender) or auto (engine/pools/local.py)", fronts=INTERNAL, stats=STATS_RESOLVED,
            choices=plain("auto", "threads", "processes")),
    # Stopping rules (engine/rendering/stopping.py): the render stops at whichever comes first of
    # `samples`, the time limit and the noise target.
    Setting("time_limit", FLOAT, 0.0, "stop rendering after this many seconds (0 = no limit)",
            limits=(0.0, 1e9), flag="--time-limit", metavar="SECONDS", label="Time Limit",
            description="Stop rendering after this many seconds (0 = no limit)",
            bpy_options={"soft_max": 3600.0, "precision": 1}, panel="Sampling > Render", stats=STATS_AS_SET),
    Setting("noise_target", FLOAT, 0.0, "stop when the estimated relative error of the image reaches REL, "
            "e.g. 0.01 (0 = off)", limits=(0.0, 1.0), flag="--noise-target", metavar="REL", label="Noise Target",
            description="Estimated relative error (RMS over the pixels, relative to the pixel values) at which "
            "the render stops", bpy_options={"precision": 4, "step": 0.1}, panel="Sampling > Render",
            off_toggle=OffToggle("use_noise_target", "Stop when the estimated relative error of the image "
                                 "reaches the target", on_default=0.01, on_min=0.0001),
            stats=STATS_AS_SET),
    Setting("min_samples", INT, 0, "samples every pixel gets before the noise target may stop it (0 = automatic: "
            "ceil(16 / target^0.3) as Cycles, at most 128; 8 without a target)", limits=(0, INT32_MAX),
            flag="--min-samples", metavar="N", label="Min Samples",
            description="Samples every pixel gets before the noise target may stop it (0 = automatic: "
            "16 / Noise Target^0.3, as Cycles)", bpy_options={"soft_max": 4096}, panel="Sampling > Render",
            stats=STATS_AS_SET),
    Setting("adaptive", BOOL, True, "with --noise-target: keep sampling every pixel (no adaptive sampling)",
            flag="--no-adaptive", label="Adaptive Sampling", description="With a noise target: blocks of 8x8 "
            "pixels whose error reached it get no more samples", panel="Sampling > Render", stats=STATS_RESOLVED),
    Setting("passes", CHOICES, (), "extra passes in the EXR, comma-separated: albedo,normal,depth,samples,"
            "variance, and Cycles' mist,world_normal,uv,position,object_index,material_index,emission,"
            "environment, diffuse_direct,diffuse_indirect,glossy_direct,glossy_indirect,transmission_direct,"
            "transmission_indirect,diffuse_color,glossy_color,transmission_color, crypto_object,crypto_material,"
            "crypto_asset (engine/film/passes.py; layers "
            "named as Blender's)", flag="--passes", metavar="LIST",
            fronts=frozenset((ENGINE_CLI, ADDON_CLI)), noun="pass", stats=STATS_AS_SET,
            panel="View Layer > Passes (mcrt_addon/passes.py)",
            choices=plain("albedo", "normal", "depth", "samples", "variance", "mist", "world_normal", "uv",
                          "position", "object_index", "material_index", "emission", "environment",
                          "diffuse_direct", "diffuse_indirect", "glossy_direct", "glossy_indirect",
                          "transmission_direct", "transmission_indirect", "diffuse_color", "glossy_color",
                          "transmission_color", "crypto_object", "crypto_material", "crypto_asset")),
    Setting("denoise", BOOL, False, "denoise with Intel Open Image Denoise (pyoidn), guided by the albedo and "
            "normal passes; the raw image is kept in the EXR as 'Noisy Image' (engine/film/denoise.py)",
            flag="--denoise", label="Denoise", prop="use_denoising", panel="Render > Denoise",
            description="Denoise the final render with Intel Open Image Denoise (pyoidn in the worker Python), "
            "guided by the Denoising Albedo and Normal passes; the raw image is kept as the Noisy Image pass"),
)
# The film (engine/film/pixel_filter.py, engine/rendering/frame.py FrameFilm): Cycles' Film panel.
FILM = (
    Setting("film_exposure", FLOAT, 1.0, "scale the image (Combined, Noisy Image, Variance by its square) by "
            "this factor, as Cycles' Film > Exposure", limits=(0.0, 1e6), flag="--exposure", metavar="SCALE",
            label="Exposure", description="Image brightness scale", bpy_options={"soft_max": 10.0},
            panel="Film", stats=STATS_AS_SET),
    Setting("pixel_filter", CHOICE, "box", "pixel filter of the camera samples (engine/film/pixel_filter.py): "
            "box (the reference: width 1 = a uniform jitter inside the pixel), gaussian or blackman-harris "
            "(Cycles' default, width 1.5), importance-sampled as Cycles, every sample weighted equally",
            flag="--pixel-filter", noun="pixel filter", label="Pixel Filter", prop="pixel_filter_type",
            description="Pixel filter type", panel="Film > Pixel Filter", stats=STATS_AS_SET,
            blender_default="blackman-harris",
            choices=(Choice("box", "Box", "Box filter"), Choice("gaussian", "Gaussian", "Gaussian filter"),
                     Choice("blackman-harris", "Blackman-Harris", "Blackman-Harris filter"))),
    Setting("filter_width", FLOAT, 1.0, "pixel filter width in pixels (Cycles: the Gaussian's footprint is 3 x "
            "the width, Blackman-Harris' 2 x)", limits=(0.01, 10.0), flag="--filter-width", metavar="PIXELS",
            label="Width", description="Pixel filter width", blender_default=1.5, panel="Film > Pixel Filter",
            bpy_options={"subtype": "PIXEL"}, stats=STATS_AS_SET),
    Setting("film_transparent", BOOL, False, "transparent background: camera rays that leave the scene give "
            "alpha 0 and no world colour (the world still lights the scene); Combined is premultiplied RGBA. "
            "Blender: Film > Transparent (scene.render.film_transparent)", flag="--film-transparent",
            fronts=frozenset((ENGINE_CLI, ADDON_CLI)), panel="Film (scene.render.film_transparent)",
            stats=STATS_AS_SET),
    Setting("animated_seed", BOOL, False, "a new noise pattern each frame: the seed used is Cycles' "
            "hash_uint2(frame, seed) (animated_seed(); resolved by the add-on, which knows the frame)",
            flag="--animated-seed", fronts=frozenset((ADDON_CLI, BLENDER)), label="Use Animated Seed",
            prop="use_animated_seed", description="Use different seed values (and hence noise patterns) at "
            "different frames", panel="Sampling > Advanced"),
)
SETTINGS = SETTINGS + FILM
SETTING = {s.name: s for s in SETTINGS}

FRESNEL_MODELS = SETTING["fresnel"].values
ESTIMATORS = SETTING["estimator"].values
SAMPLERS = SETTING["sampler"].values
ACCELERATORS = SETTING["accelerator"].values
PIXEL_FILTERS = SETTING["pixel_filter"].values
PASSES = SETTING["passes"].values           # render passes besides Combined (engine/film/passes.py)
INT_LIMITS = {s.name: s.limits for s in SETTINGS if s.kind == INT}

# Presets of both command lines (--preset): "fair", the reference settings (what TNCG15 MC and a fair
# Cycles reference, mcrt_addon/reference.py, compute without Cycles' speed-ups: no limit of a bounce
# type below the total, no clamp, no filter, caustics on); "cycles", Cycles' defaults (a new .blend).
# The fair preset leaves the total (max_depth) alone: a .blend file keeps its own (where it sets one:
# mcrt_addon/properties.py apply_preset).
LIGHT_PATH_SPEEDUPS = ("diffuse_bounces", "glossy_bounces", "transmission_bounces", "transparent_bounces",
                       "clamp_direct", "clamp_indirect", "filter_glossy", "caustics_reflective", "caustics_refractive")
FAIR, CYCLES = "fair", "cycles"
PRESETS = (FAIR, CYCLES)


def preset_values(name: str) -> dict:
    """{setting: value} of a preset: FAIR the table's defaults of LIGHT_PATH_SPEEDUPS, CYCLES every
    row's Cycles default (rows without one: their default)."""
    if name == FAIR:
        return {n: SETTING[n].default for n in LIGHT_PATH_SPEEDUPS}
    if name == CYCLES:
        return {s.name: s.new_file_default for s in SETTINGS
                if s.blender_default is not None or s.name in LIGHT_PATH_SPEEDUPS}
    raise SceneError(f"unknown preset '{name}' (expected one of {', '.join(PRESETS)})")


def settings_for(front: str) -> tuple:
    """The rows a front end (ENGINE_CLI, ADDON_CLI, BLENDER) exposes, in table order."""
    return tuple(s for s in SETTINGS if front in s.fronts)


def _fields_from_table(cls):
    """One dataclass field per row of SETTINGS, in table order, with the row's default."""
    clash = [s.name for s in SETTINGS if s.name in vars(cls)]
    assert not clash, f"setting names clash with RenderSettings attributes: {clash}"
    cls.__annotations__ = {s.name: FIELD_TYPES[s.kind] for s in SETTINGS}
    for s in SETTINGS:
        setattr(cls, s.name, s.default)
    return dataclass(cls)


@_fields_from_table
class RenderSettings:
    """Every knob of a render: the fields are the rows of SETTINGS (see there for each one)."""

    def stopping_rules(self) -> bool:
        """True when the frame renders in rounds (engine/rendering/stopping.py)."""
        return self.time_limit > 0 or self.noise_target > 0

    def resolved_threads(self) -> int:
        return self.threads if self.threads > 0 else (os.cpu_count() or 1)

    def validate(self) -> None:
        """SceneError naming the first setting (in table order) outside its limits or choices."""
        for s in SETTINGS:
            s.check(getattr(self, s.name))

    def as_dict(self) -> dict:
        return asdict(self)


def stats_of(settings) -> dict:
    """The settings the render stats list as set (rows with stats=STATS_AS_SET); JSON types."""
    return {s.name: list(getattr(settings, s.name)) if s.kind == CHOICES else getattr(settings, s.name)
            for s in SETTINGS if s.stats == STATS_AS_SET}



def _rot(x: int, k: int) -> int:
    return ((x << k) | (x >> (32 - k))) & 0xFFFFFFFF


def animated_seed(seed: int, frame: int) -> int:
    """The seed of `frame` with Use Animated Seed on, as Cycles' Blender sync: hash_uint2(frame,
    seed) (Bob Jenkins' lookup3 final mix), its top bit dropped to stay within the seed's limits."""
    m = 0xFFFFFFFF
    a = b = c = 0xDEADBEEF + (2 << 2) + 13
    a, b = (a + frame) & m, (b + seed) & m
    c = ((c ^ b) - _rot(b, 14)) & m
    a = ((a ^ c) - _rot(c, 11)) & m
    b = ((b ^ a) - _rot(a, 25)) & m
    c = ((c ^ b) - _rot(b, 16)) & m
    a = ((a ^ c) - _rot(c, 4)) & m
    b = ((b ^ a) - _rot(a, 14)) & m
    c = ((c ^ b) - _rot(b, 24)) & m
    return c & INT32_MAX
