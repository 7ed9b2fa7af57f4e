"""The effect plan: kernels a scene does not need never run."""
from types import SimpleNamespace

import pytest

import engine.geometry.scene_geometry
import engine.materials.glass
from engine import RenderSettings, render
from engine.integrators.effects import plan_effects
from engine.scene.model import GLASS, Material, Sphere

from tests.scenes import diffuse_box_scene

EXPECTED_KEYS = {"engine", "render_seconds", "samples", "resolution", "threads", "accelerator", "rays",
                 "effects", "effects_reason", "nonfinite_samples", "seconds_in_intersection"}


class CallCounter:
    def __init__(self, fn):
        self.fn, self.calls = fn, 0

    def __call__(self, *a, **kw):
        self.calls += 1
        return self.fn(*a, **kw)

    @staticmethod
    def counting(counter, fn):
        """fn, each call counted in `counter`."""
        def counted(*a, **kw):
            counter.calls += 1
            return fn(*a, **kw)
        return counted


@pytest.fixture
def spies(monkeypatch):
    kernel = engine.geometry.scene_geometry.sphere_kernel          # the sphere test of either backend
    sphere = CallCounter(None)

    def counted_kernel(backend="numpy"):
        sphere.fn = kernel(backend)
        return sphere
    loops = engine.geometry.scene_geometry.sphere_loop_kernels     # numba: every sphere in one loop

    def counted_loops(backend="numpy"):
        found = loops(backend)
        return None if found is None else tuple(CallCounter.counting(sphere, fn) for fn in found)
    refract = CallCounter(engine.materials.glass.refract_cos)
    monkeypatch.setattr(engine.geometry.scene_geometry, "sphere_kernel", counted_kernel)
    monkeypatch.setattr(engine.geometry.scene_geometry, "sphere_loop_kernels", counted_loops)
    monkeypatch.setattr(engine.materials.glass, "refract_cos", refract)
    use_backend = engine.materials.glass.SmoothGlass.use_backend

    def counted_backend(self, backends):            # numba: Snell's law in engine/materials/glass_jit.py
        use_backend(self, backends)
        if self.jit is not None:
            self.jit = SimpleNamespace(cosines=CallCounter.counting(refract, self.jit.cosines),
                                       directions=self.jit.directions)
    monkeypatch.setattr(engine.materials.glass.SmoothGlass, "use_backend", counted_backend)
    return sphere, refract


def test_diffuse_only_scene_never_runs_sphere_or_refraction_code(spies):
    sphere, refract = spies
    result = render(diffuse_box_scene(), RenderSettings(samples=4, parallelism="threads"), log=lambda *a: None)
    assert sphere.calls == 0 and refract.calls == 0
    fx = result.stats["effects"]
    assert fx == {"spheres": False, "quads": True, "triangles": True, "smooth_normals": False,
                  "area_lights": False, "diffuse": True, "seen_lamps": False, "world_light": False,
                  "mirror": False, "glass": False, "glossy": False, "principled": False, "rough_diffuse": False, "mix": False, "emission": True,
                  "direct_light": True,
                  "rough_glass": False, "refraction": False, "transparent": False, "translucent": False,
                  "solid_angle": True,
                  "light_tree": False, "mis": True, "deferred_roulette": False, "passes": False, "textures": False,
                  "bounce_limits": False, "clamp": False, "filter_glossy": False, "caustics": False,
                  "photon_caustics": False}
    assert "never evaluated" in result.stats["effects_reason"]["glass"]
    assert EXPECTED_KEYS <= set(result.stats)
    assert set(result.stats["rays"]) == {"camera", "extension", "shadow"}


def test_glass_sphere_turns_both_kernels_on(spies):
    sphere, refract = spies
    scene = diffuse_box_scene()
    scene.materials.append(Material("Glass", GLASS, (1, 1, 1), ior=1.5))
    scene.spheres.append(Sphere("Glass ball", (0, 0.3, 0.5), 0.3, len(scene.materials) - 1))
    result = render(scene, RenderSettings(samples=4, parallelism="threads"), log=lambda *a: None)
    assert sphere.calls > 0 and refract.calls > 0
    assert result.stats["effects"]["glass"] and result.stats["effects"]["spheres"]
    assert "'Glass ball'" in result.stats["effects_reason"]["spheres"]


def test_unused_glass_material_does_not_enable_glass():
    scene = diffuse_box_scene()
    scene.materials.append(Material("Spare glass", GLASS))
    plan = plan_effects(scene, RenderSettings())
    assert not plan.glass
