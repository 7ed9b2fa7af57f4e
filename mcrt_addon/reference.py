"""A fair Cycles reference (docs/hard-cases.md §2d, C1-C10): what TNCG15 MC computes, without Cycles' speed-ups.

Box filter of width 1 px (pixels independent, as the tracer's jittered box), no clamping, no
denoising, no adaptive sampling, Filter Glossy 0, light threshold 0, caustics on, every bounce
limit = max_depth, Standard view transform, fixed seed, CPU.  `film` (FilmSettings) replaces the
box, opaque, unscaled film with TNCG15 MC's film settings, so that the two renderers can be compared
at equal film settings (the add-on command line's --engine CYCLES does).

The Light Paths options (LIGHT_PATHS, the settings table's rows of engine/core/settings.py) can
be given in the tracer's terms, so that Cycles renders with the values TNCG15 MC renders with
(`python -m mcrt_addon render --engine CYCLES`); each one not given keeps the fair value above.
"""
from dataclasses import dataclass


@dataclass(frozen=True)
class FilmSettings:
    """Cycles' film options in the tracer's terms (engine/core/settings.py FILM rows)."""
    pixel_filter: str = "box"           # box | gaussian | blackman-harris
    filter_width: float = 1.0
    exposure: float = 1.0
    transparent: bool = False

    @classmethod
    def of(cls, settings):
        """The film of a RenderSettings."""
        return cls(settings.pixel_filter, settings.filter_width, settings.film_exposure, settings.film_transparent)


# The settings table's rows handed to Cycles: tracer name -> Cycles' property.
LIGHT_PATHS = {"diffuse_bounces": "diffuse_bounces", "glossy_bounces": "glossy_bounces",
               "transmission_bounces": "transmission_bounces", "transparent_bounces": "transparent_max_bounces",
               "clamp_direct": "sample_clamp_direct", "clamp_indirect": "sample_clamp_indirect",
               "filter_glossy": "blur_glossy", "caustics_reflective": "caustics_reflective",
               "caustics_refractive": "caustics_refractive"}
CYCLES_MAX_BOUNCES = 1024            # Cycles' properties stop there (the tracer's 1024 means "the total only")


def _set(obj, name, value):
    if hasattr(obj, name):
        setattr(obj, name, value)


def setup_cycles_reference(scene, *, samples, max_depth, seed=0, threads=0, film=FilmSettings(), **light_paths):
    scene.render.engine = "CYCLES"
    c = scene.cycles
    _set(c, "device", "CPU")
    c.samples = int(samples)
    _set(c, "use_adaptive_sampling", False)
    _set(c, "use_denoising", False)
    _set(c, "use_preview_denoising", False)
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.light_sampling_threshold = 0.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    depth = int(max_depth)
    c.max_bounces = depth
    c.diffuse_bounces = depth
    c.glossy_bounces = depth
    c.transmission_bounces = depth
    c.transparent_max_bounces = depth
    c.volume_bounces = 0
    for name, value in light_paths.items():          # KeyError: not a Light Paths option
        prop = LIGHT_PATHS[name]
        setattr(c, prop, min(int(value), CYCLES_MAX_BOUNCES) if prop.endswith("bounces") else value)
    _set(c, "min_light_bounces", 0)
    _set(c, "min_transparent_bounces", 0)
    c.pixel_filter_type = film.pixel_filter.upper().replace("-", "_")
    c.filter_width = film.filter_width
    c.film_exposure = film.exposure
    c.film_transparent_glass = False
    c.seed = int(seed)
    c.use_animated_seed = False
    _set(c, "use_guiding", False)
    _set(c, "sample_offset", 0)
    _set(c, "use_auto_tile", False)
    _set(c, "use_layer_samples", "IGNORE")
    scene.render.film_transparent = film.transparent
    scene.render.threads_mode = "AUTO" if not threads else "FIXED"
    if threads:
        scene.render.threads = int(threads)
    view = scene.view_settings
    view.view_transform = "Standard"
    view.look = "None"
    view.exposure = 0.0
    view.gamma = 1.0
    for layer in scene.view_layers:
        _set(layer, "samples", 0)
        if hasattr(layer, "cycles"):
            _set(layer.cycles, "use_denoising", False)
