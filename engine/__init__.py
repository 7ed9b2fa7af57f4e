"""TNCG15 MC tracer: the Monte Carlo ray tracer of the TNCG15 report, in NumPy + Embree.

No bpy import anywhere in this package: it renders on its own (``python -m engine``),
and the Blender add-on drives it through :func:`engine.api.render`.

The names below are imported on first use (PEP 562), not with the package: importing one
standard-library module of the tracer, such as the settings table engine/core/settings.py that
the Blender add-on reads at registration (mcrt_addon/bridge.py), must not need numpy.
"""
import importlib

_HOMES = {"render": ".api", "RenderResult": ".api", "RenderSettings": ".core.settings",
          "SceneError": ".core.errors", "Scene": ".scene.model", "Camera": ".scene.model",
          "Material": ".scene.model", "TriangleMesh": ".scene.model", "Sphere": ".scene.model",
          "Quad": ".scene.model"}
__all__ = ["render", "RenderResult", "RenderSettings", "Scene", "SceneError", "Camera",
           "Material", "TriangleMesh", "Sphere", "Quad"]


def __getattr__(name):
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(_HOMES[name], __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
