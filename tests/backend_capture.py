"""Inputs of the kernels that have compiled twins, recorded from real renders (engine.api.render,
one thread, NumPy backend): the light tree's walks, the sphere and quad tests, the Sobol' points.  Used by the twins' tests
(tests/lights/test_selection_jit.py, tests/geometry/test_spheres_jit.py) and scripts/bench_backend.py; recorded()
and same_bsdf_sample() for the twins of a single method (tests/materials/test_lambert_jit.py ...)."""
from __future__ import annotations

import numpy as np

from engine import api
from engine.core.settings import RenderSettings
from engine.geometry import scene_geometry
from engine.geometry.shapes.quads import QuadSet
from engine.sampling.qmc import SobolSampler, sample_2d
from engine.lights.light_set import LightSet
from engine.lights.parallelograms import Parallelograms
from engine.lights.selection import LightTree
from engine.scene.builtin import BUILTIN_SCENES


def capture(scene_name: str, resolution=16, samples=2, limit=64):
    """{"sample": [(tree, x, n, u)], "pmf": [(tree, x, n, light)], "sphere": [(o, d, center, radius,
    t_best)], "quad": [(quads, k, prim, o, d, t_best)], "sobol": [(index, pixel_seed, dim, count)],
    "pick": [(tree, x, n, u)] (LightTree.sample), "rectangle": [(lights, x, idx, u1, u2)]
    (Parallelograms.sample_li), "shadow": [(light set, args)] (LightSet.shadow_rays)}: up to `limit`
    calls of each, recorded while rendering a built-in scene."""
    calls = {"sample": [], "pmf": [], "sphere": [], "quad": [], "sobol": [], "pick": [], "rectangle": [], "shadow": []}
    sample, pmf, kernel = LightTree._tree_sample, LightTree._tree_pmf, scene_geometry.sphere_kernel
    one, pairs = QuadSet.intersect_one, QuadSet.intersect_pairs
    sobol = SobolSampler.kernel
    pick, rectangle, shadow = LightTree.sample, Parallelograms.sample_li, LightSet.shadow_rays

    def copied(a):
        return a.copy() if isinstance(a, np.ndarray) else a

    def rec_pick(self, x, n, u):
        if len(calls["pick"]) < limit:
            calls["pick"].append((self, x.copy(), n.copy(), u.copy()))
        return pick(self, x, n, u)

    def rec_rectangle(self, x, idx, u1, u2, n=None, solid_angle=True):
        if len(calls["rectangle"]) < limit and solid_angle:
            calls["rectangle"].append((self, x.copy(), copied(idx), u1.copy(), u2.copy()))
        return rectangle(self, x, idx, u1, u2, n, solid_angle)

    def rec_shadow(self, ls, valid, x, lift, ng, cos_ly, raised=None):
        if len(calls["shadow"]) < limit:
            calls["shadow"].append((self, (type(ls)(*(copied(getattr(ls, f)) for f in ls.__dataclass_fields__)),
                                           copied(valid), x.copy(), copied(lift), ng.copy(), cos_ly.copy(),
                                           None if raised is None else tuple(a.copy() for a in raised))))
        return shadow(self, ls, valid, x, lift, ng, cos_ly, raised)

    def rec_sobol(index, pixel_seed, dim, count):
        if len(calls["sobol"]) < limit:
            calls["sobol"].append((np.array(index), pixel_seed.copy(), np.array(dim), count))
        return sample_2d(index, pixel_seed, dim, count)

    def rec_one(self, k, o, d, t_best=None):
        if len(calls["quad"]) < limit:
            calls["quad"].append((self, k, None, o.copy(), d.copy(), None if t_best is None else t_best.copy()))
        return one(self, k, o, d, t_best)

    def rec_pairs(self, prim, o, d, t_best):
        if len(calls["quad"]) < limit:
            calls["quad"].append((self, None, prim.copy(), o.copy(), d.copy(), t_best.copy()))
        return pairs(self, prim, o, d, t_best)

    def rec_sample(self, x, n, u):
        if len(calls["sample"]) < limit:
            calls["sample"].append((self, x.copy(), n.copy(), u.copy()))
        return sample(self, x, n, u)

    def rec_pmf(self, x, n, light):
        if len(calls["pmf"]) < limit:
            calls["pmf"].append((self, x.copy(), n.copy(), light.copy()))
        return pmf(self, x, n, light)

    def rec_kernel(backend="numpy"):
        numpy_test = kernel("numpy")

        def test(o, d, center, radius, t_best=None):
            if len(calls["sphere"]) < limit:
                calls["sphere"].append((o.copy(), d.copy(), center.copy() if hasattr(center, "copy") else center,
                                        radius.copy() if hasattr(radius, "copy") else radius,
                                        None if t_best is None else t_best.copy()))
            return numpy_test(o, d, center, radius, t_best)
        return test

    LightTree._tree_sample, LightTree._tree_pmf, scene_geometry.sphere_kernel = rec_sample, rec_pmf, rec_kernel
    QuadSet.intersect_one, QuadSet.intersect_pairs = rec_one, rec_pairs
    SobolSampler.kernel = staticmethod(rec_sobol)
    LightTree.sample, Parallelograms.sample_li, LightSet.shadow_rays = rec_pick, rec_rectangle, rec_shadow
    try:
        settings = RenderSettings(samples=samples, threads=1, backend="numpy")
        api.render(BUILTIN_SCENES[scene_name]((resolution, resolution)), settings, log=lambda m: None)
    finally:
        LightTree._tree_sample, LightTree._tree_pmf, scene_geometry.sphere_kernel = sample, pmf, kernel
        QuadSet.intersect_one, QuadSet.intersect_pairs = one, pairs
        SobolSampler.kernel = staticmethod(sobol)
        LightTree.sample, Parallelograms.sample_li, LightSet.shadow_rays = pick, rectangle, shadow
    return calls


def recorded(owner, name: str, scene_name: str, record, limit: int = 8) -> list:
    """What record(*args) keeps (None: nothing) of up to `limit` calls of owner.name (a method of a
    class or a function of a module), recorded while a 16 x 16, 2 spp NumPy render of a built-in
    scene runs; owner.name is restored after."""
    calls, original = [], getattr(owner, name)

    def recording(*args, **kwargs):
        if len(calls) < limit:
            kept = record(*args, **kwargs)
            if kept is not None:
                calls.append(kept)
        return original(*args, **kwargs)
    setattr(owner, name, recording)
    try:
        api.render(BUILTIN_SCENES[scene_name]((16, 16)), RenderSettings(samples=2, threads=1, backend="numpy"),
                   log=lambda m: None)
    finally:
        setattr(owner, name, original)
    return calls


def same_bsdf_sample(a, b) -> bool:
    """Two BSDFSamples (engine/materials/protocol.py) the same bit for bit, dtypes included."""
    return all(x.dtype == y.dtype and np.array_equal(x, y, equal_nan=True)
               for x, y in ((a.wi, b.wi), (a.pdf, b.pdf), (a.value, b.value), (a.flags, b.flags)))


def require_compiled():
    """Skip without numba; compile the twins first when the cache is cold (once per machine)."""
    import pytest
    from engine.core import backend
    if not backend.numba_available():
        pytest.skip(f"numba is not available ({backend.numba_error()})")
    if not backend.is_warm():
        backend.warm_up(log=lambda m: None)
