"""TNCG15 MC tracer: the Monte Carlo ray tracer of the TNCG15 report, in NumPy + Embree.

No bpy import anywhere in this package: it renders on its own (``python -m engine``),
and the Blender add-on drives it through :func:`engine.api.render`.
"""
from .api import RenderResult, render
from .scene.model import Camera, Material, Quad, Scene, Sphere, TriangleMesh
from .core.errors import SceneError
from .core.settings import RenderSettings

__all__ = ["render", "RenderResult", "RenderSettings", "Scene", "SceneError", "Camera",
           "Material", "TriangleMesh", "Sphere", "Quad"]
