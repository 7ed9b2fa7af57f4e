"""TNCG15 MC: a Monte Carlo path tracer (NumPy + Embree) as a Blender render engine.

Works as a Blender 4.2+ extension (``blender_manifest.toml``, built by
``scripts/build_extension.py``) and as a legacy add-on in Blender 3.4 (``bl_info``).  In the
repository the tracer is the top-level package ``engine``; the built zips ship a copy of it as
the sub-package ``tracer`` (see bridge.py).
"""
bl_info = {
    "name": "TNCG15 MC",
    "author": "TNCG15 MC authors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Render Properties > Render Engine > TNCG15 MC",
    "description": "Monte Carlo path tracer (diffuse, mirror, glass, area lights) with Embree",
    "category": "Render",
}

if "bpy" in locals():                     # "Reload Scripts": reload sub-modules too
    import importlib
    for _name in ("bridge", "worker_python", "denoiser_install", "properties", "ui", "viewport", "warm", "persistent", "render_engine", "estimate"):
        if _name in locals():
            importlib.reload(locals()[_name])

import bpy  # noqa: E402,F401  (its name in locals() tells "Reload Scripts" apart, above)

from . import worker_python  # noqa: E402

worker_python.ensure_numpy()      # before anything imports numpy (Blender 3.4)

from . import bridge, denoiser_install, persistent, properties, ui, render_engine, estimate, warm  # noqa: E402,F401

_modules = (worker_python, denoiser_install, properties, persistent, warm, render_engine, estimate, ui)


def register():
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
