"""Blender features the tracer does not model, each named in a warning instead of being ignored
silently: holdout (object or collection), ray visibility, motion blur, Film > Transparent Glass
(Film > Transparent itself is rendered: engine/integrators/path_tracer.py misses).
(Transparent and Holdout shader nodes and Principled alpha are named by materials.py.)"""

RAY_VISIBILITY = (("visible_camera", "camera"), ("visible_diffuse", "diffuse"), ("visible_glossy", "glossy"),
                  ("visible_transmission", "transmission"), ("visible_volume_scatter", "volume scatter"),
                  ("visible_shadow", "shadow"))


def scene_warnings(scene, view_layer=None):
    warnings = []
    render = scene.render
    if getattr(render, "use_motion_blur", False):
        warnings.append("Motion blur is not rendered: every object is shown at the frame's instant")
    cycles = getattr(scene, "cycles", None)         # Cycles' own option, there when its add-on is
    if getattr(render, "film_transparent", False) and getattr(cycles, "film_transparent_glass", False):
        warnings.append("Film > Transparent Glass is not supported: glass is opaque in the alpha (the "
                        "background seen through it is rendered)")
    if view_layer is not None:
        stack = [view_layer.layer_collection]
        while stack:
            layer = stack.pop()
            if getattr(layer, "holdout", False):
                warnings.append(f"Collection '{layer.name}': holdout is not supported; its objects are "
                                "rendered as ordinary objects")
            stack.extend(layer.children)
    return warnings


def object_warnings(ob, label):
    """Warnings for one object (read from the original: the evaluated copy may lag)."""
    original = ob.original if getattr(ob, "original", None) is not None else ob
    warnings = []
    if getattr(original, "is_holdout", False):
        warnings.append(f"Object '{label}': holdout is not supported; rendered as an ordinary object")
    # Lights: Area lights export their ray visibility (export/lights.py); others are ignored.
    hidden = [] if ob.type == "LIGHT" else [name for attr, name in RAY_VISIBILITY if not getattr(original, attr, True)]
    if hidden:
        warnings.append(f"Object '{label}': ray visibility is not supported ({', '.join(hidden)} off); "
                        "the object is seen by every ray")
    return warnings
