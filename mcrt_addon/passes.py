"""Render passes in Blender: which are on (the view layer's toggles, as Cycles has them), their
registration (`update_render_passes`) and writing them into the render result.

Names, channels and types are Cycles' (``list_render_passes``), so the compositor's Render Layers
node and Denoise node know them; the tracer's names are in engine/film/passes.py (the same table,
kept equal by tests/addon/test_passes_addon.py).  Kept free of numpy and the tracer so that
`update_render_passes`, which Blender calls very often, stays cheap.

  tracer pass   Blender pass           channels  toggle
  depth         Depth                  Z         View Layer > Passes > Data > Z (use_pass_z)
  albedo        Denoising Albedo       RGB       Denoising Data (view_layer.tncg15), or Denoise
  normal        Denoising Normal       XYZ       Denoising Data, or Denoise
  samples       Debug Sample Count     X         Sample Count (view_layer.tncg15)
  variance      Variance               RGB       Variance (view_layer.tncg15)
  noisy         Noisy Image            RGBA      Denoise (scene.tncg15.use_denoising)
  mist          Mist                   Z         Data > Mist (use_pass_mist; World > Mist Pass settings)
  world_normal  Normal                 XYZ       Data > Normal (use_pass_normal)
  uv            UV                     UVA       Data > UV (use_pass_uv)
  position      Position               XYZ       Data > Position (use_pass_position)
  object_index  Object Index (IndexOB) X         Indexes > Object Index (use_pass_object_index)
  material_index Material Index (IndexMA) X      Indexes > Material Index (use_pass_material_index)
  emission      Emission (Emit)        RGB       Light > Other > Emission (use_pass_emit)
  environment   Environment (Env)      RGB       Light > Other > Environment (use_pass_environment)
  diffuse_direct  Diffuse Direct (DiffDir) RGB   Light > Diffuse > Direct (use_pass_diffuse_direct); the
                same for _indirect (DiffInd), _color (DiffCol), glossy_ (GlossDir, GlossInd, GlossCol),
                transmission_ (TransDir, TransInd, TransCol)

Blender before 5.0 names four of them as in brackets (LEGACY_NAMES; Blender 3.4's Cycles registers
those, Blender 5.0's the long ones).
"""
CRYPTO_LEVELS = 3       # Cryptomatte Levels 6 (engine/film/cryptomatte.py DEPTH): 3 passes of 2 ids each
BLENDER_PASSES = {
    "albedo": ("Denoising Albedo", 3, "RGB", "COLOR"),
    "normal": ("Denoising Normal", 3, "XYZ", "VECTOR"),
    "depth": ("Depth", 1, "Z", "VALUE"),
    "samples": ("Debug Sample Count", 1, "X", "VALUE"),
    "variance": ("Variance", 3, "RGB", "COLOR"),
    "noisy": ("Noisy Image", 4, "RGBA", "COLOR"),
    "mist": ("Mist", 1, "Z", "VALUE"),
    "world_normal": ("Normal", 3, "XYZ", "VECTOR"),
    "uv": ("UV", 3, "UVA", "VECTOR"),
    "position": ("Position", 3, "XYZ", "VECTOR"),
    "object_index": ("Object Index", 1, "X", "VALUE"),
    "material_index": ("Material Index", 1, "X", "VALUE"),
    "emission": ("Emission", 3, "RGB", "COLOR"),
    "environment": ("Environment", 3, "RGB", "COLOR"),
    **{f"{kind}_{part}": (f"{kind.title()} {part.title()}", 3, "RGB", "COLOR")
       for kind in ("diffuse", "glossy", "transmission") for part in ("direct", "indirect", "color")},
    # Cryptomatte: CRYPTO_LEVELS passes of 4 (CryptoObject00 ...), as Cycles registers them
    "crypto_object": ("CryptoObject", 4 * CRYPTO_LEVELS, "rgba" * CRYPTO_LEVELS, "COLOR"),
    "crypto_material": ("CryptoMaterial", 4 * CRYPTO_LEVELS, "rgba" * CRYPTO_LEVELS, "COLOR"),
    "crypto_asset": ("CryptoAsset", 4 * CRYPTO_LEVELS, "rgba" * CRYPTO_LEVELS, "COLOR"),
}
CRYPTO = ("crypto_object", "crypto_material", "crypto_asset")
ORDER = ("albedo", "normal", "depth", "samples", "variance", "noisy", "mist", "world_normal", "uv", "position",
         "object_index", "material_index", "emission", "environment", "diffuse_direct", "diffuse_indirect",
         "glossy_direct", "glossy_indirect", "transmission_direct", "transmission_indirect", "diffuse_color",
         "glossy_color", "transmission_color", "crypto_object", "crypto_material", "crypto_asset")
# The view layer's own toggle of each Cycles pass (Blender's, so files made for Cycles keep them).
TOGGLES = {"mist": "use_pass_mist", "world_normal": "use_pass_normal", "uv": "use_pass_uv",
           "position": "use_pass_position", "object_index": "use_pass_object_index",
           "material_index": "use_pass_material_index", "emission": "use_pass_emit",
           "environment": "use_pass_environment",
           **{f"{kind}_{part}": f"use_pass_{kind}_{part}" for kind in ("diffuse", "glossy", "transmission")
              for part in ("direct", "indirect", "color")},
           "crypto_object": "use_pass_cryptomatte_object", "crypto_material": "use_pass_cryptomatte_material",
           "crypto_asset": "use_pass_cryptomatte_asset"}
LEGACY_NAMES = {"Object Index": "IndexOB", "Material Index": "IndexMA", "Emission": "Emit", "Environment": "Env",
                "Diffuse Direct": "DiffDir", "Diffuse Indirect": "DiffInd", "Glossy Direct": "GlossDir",
                "Glossy Indirect": "GlossInd", "Transmission Direct": "TransDir", "Transmission Indirect": "TransInd",
                "Diffuse Color": "DiffCol", "Glossy Color": "GlossCol", "Transmission Color": "TransCol"}


def blender_name(name) -> str:
    """The running Blender's name of tracer pass `name` (Cycles' names changed by 5.0)."""
    import bpy
    pass_name = BLENDER_PASSES[name][0]
    return LEGACY_NAMES.get(pass_name, pass_name) if tuple(bpy.app.version) < (5, 0) else pass_name


def enabled_passes(scene, view_layer) -> tuple:
    """Tracer pass names switched on for this view layer (and 'noisy' with Denoise)."""
    on = set()
    props = getattr(view_layer, "tncg15", None)
    denoise = bool(getattr(getattr(scene, "tncg15", None), "use_denoising", False))
    if getattr(view_layer, "use_pass_z", False):
        on.add("depth")
    if denoise or (props is not None and props.denoising_store_passes):
        on.update(("albedo", "normal"))
    if props is not None and props.pass_sample_count:
        on.add("samples")
    if props is not None and props.pass_variance:
        on.add("variance")
    if denoise:
        on.add("noisy")
    on.update(name for name, toggle in TOGGLES.items() if getattr(view_layer, toggle, False))
    return tuple(p for p in ORDER if p in on)


def register_passes(engine, scene, view_layer) -> None:
    """RenderEngine.update_render_passes: Combined and every enabled pass."""
    engine.register_pass(scene, view_layer, "Combined", 4, "RGBA", "COLOR")
    for name in enabled_passes(scene, view_layer):
        _, channels, chan_id, kind = BLENDER_PASSES[name]
        if name in CRYPTO:
            for level in range(CRYPTO_LEVELS):
                engine.register_pass(scene, view_layer, f"{blender_name(name)}{level:02d}", 4, "RGBA", kind)
            continue
        engine.register_pass(scene, view_layer, blender_name(name), channels, chan_id, kind)


def write_pass(render_pass, pixels) -> None:
    """(h, w, c) float pixels, row 0 = top -> the pass (row 0 = bottom, render_pass.channels
    channels: padded with 1 (alpha) or cut).  Flat buffer in 4.x/5.0, (N, c) in 3.x."""
    import numpy as np
    h, w = pixels.shape[:2]
    c = render_pass.channels
    src = np.asarray(pixels, dtype=np.float32).reshape(h, w, -1)[::-1]
    out = np.ones((h, w, c), np.float32)
    k = min(c, src.shape[2])
    out[..., :k] = src[..., :k]
    out[~np.isfinite(out)] = 0.0
    try:
        render_pass.rect.foreach_set(out.ravel())
    except (TypeError, AttributeError):
        try:
            render_pass.rect.foreach_set(out.reshape(-1, c))
        except (TypeError, AttributeError):
            render_pass.rect = out.reshape(-1, c).tolist()


def write_frame(engine, width, height, image, passes: dict, metadata=()) -> list:
    """One full-frame result: Combined = image, plus each pass Blender has a slot for, and the
    (key, value) metadata (the Cryptomatte manifests); returns the Blender names written."""
    written = []
    result = engine.begin_result(0, 0, width, height)
    try:
        slots = {p.name: p for p in result.layers[0].passes}
        write_pass(slots["Combined"], image)
        written.append("Combined")
        for name in CRYPTO:
            for level in range(CRYPTO_LEVELS):
                slot = f"{blender_name(name)}{level:02d}"
                if name in passes and slot in slots:
                    write_pass(slots[slot], passes[name][..., 4 * level:4 * level + 4])
                    written.append(slot)
        for name in ORDER:
            if name in CRYPTO:
                continue
            if name in passes and blender_name(name) in slots:
                write_pass(slots[blender_name(name)], passes[name])
                written.append(blender_name(name))
    finally:
        engine.end_result(result)
    if metadata:                            # on the render's own result, as Cycles' stamp_view_layer_metadata
        main = engine.get_result()
        for key, value in metadata:
            main.stamp_data_add_field(key, value)
    return written


def apply_pass_options(scene, passes, denoise) -> None:
    """The command line's --passes/--denoise as the view layer's toggles and the Denoise option."""
    for view_layer in scene.view_layers:
        view_layer.use_pass_z = "depth" in passes
        view_layer.tncg15.denoising_store_passes = "albedo" in passes or "normal" in passes
        view_layer.tncg15.pass_sample_count = "samples" in passes
        view_layer.tncg15.pass_variance = "variance" in passes
        for name, toggle in TOGGLES.items():
            if hasattr(view_layer, toggle):
                setattr(view_layer, toggle, name in passes)
    scene.tncg15.use_denoising = bool(denoise)


def set_multilayer_output(scene) -> None:
    """Blender writes every pass: OpenEXR MultiLayer (a media type in 5.0), 32-bit float."""
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):
        settings.media_type = "MULTI_LAYER_IMAGE"
    settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "32"
    settings.exr_codec = "ZIP"


def passes_from_channels(channels, wanted) -> tuple:
    """Blender's multi-layer EXR channels ({'ViewLayer.Depth.Z': (H, W)}) -> (image (H, W, 3),
    {tracer pass name: (H, W, c)}) for the passes in `wanted` (and 'noisy' when present)."""
    import numpy as np

    def layer(blender, chans):
        found = [channels.get(f"ViewLayer.{blender}.{c}", channels.get(f"ViewLayer.{blender}.{c.swapcase()}"))
                 for c in chans]
        return None if any(f is None for f in found) else np.stack(found, axis=-1)
    image = layer("Combined", "RGB")
    out = {}
    for name in CRYPTO:
        if name in wanted:
            found = [layer(f"{blender_name(name)}{level:02d}", "rgba") for level in range(CRYPTO_LEVELS)]
            if all(f is not None for f in found):
                out[name] = np.concatenate(found, axis=-1)
    for name in ORDER:
        _, n, chan_id, _ = BLENDER_PASSES[name]
        if name in CRYPTO:
            continue
        if name in wanted or name == "noisy":
            pixels = layer(blender_name(name), chan_id[:3] if name == "noisy" else chan_id)
            if pixels is not None:
                out[name] = pixels
    return image, out
