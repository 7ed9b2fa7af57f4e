"""Filter Glossy on Blender 3.4's Principled BSDF v1 (engine/materials/principled_v1.py,
principled_v1_glass.py, principled_v1_jit.py): a hit with ShadingPoint.alpha_floor F evaluates and
samples each microfacet closure (specular single and "Multiscatter GGX", clearcoat, GGX glass
reflection and refraction, multiscatter glass) as the same material of alpha F does (Cycles 3.4's
bsdf_blur, docs/cycles34-filter-glossy.md), and the compiled closures take the floored alphas bit for
bit.  Control: the closures without the floor (the old behaviour) are far from the floored ones."""
import numpy as np
import pytest

from engine.core.settings import RenderSettings
from engine.integrators.effects import plan_effects
from engine.materials.principled_glass import PrincipledGlass
from engine.materials.principled_v1 import PrincipledV1
from engine.scene.model import Material, PrincipledV1 as Inputs
from tests.backend_capture import require_compiled
from tests.materials.test_bsdf_contract import hits as random_hits, uniforms
from tests.materials.test_principled_jit import _hits

FLOOR = 0.3                                     # alpha; the same closure of roughness sqrt(FLOOR) unfloored
ROUGH = float(np.sqrt(FLOOR))


def v1(roughness, multiscatter=False, anisotropy=0.0, **inputs):
    return Material("P34", "principled", (0.8, 0.6, 0.4), roughness=roughness, multiscatter=multiscatter,
                    anisotropy=anisotropy, ior=1.5, principled=Inputs(**inputs))


# (the sharp material, the same material at alpha FLOOR); each pair differs only in the closure named
CASES = {
    "specular": (v1(0.0, metallic=1.0), v1(ROUGH, metallic=1.0)),
    "multiscatter specular": (v1(0.1, True, metallic=1.0), v1(ROUGH, True, metallic=1.0)),
    "clearcoat": (v1(0.9, clearcoat=1.0, clearcoat_roughness=0.0), v1(0.9, clearcoat=1.0, clearcoat_roughness=ROUGH)),
    "glass": (v1(0.0, transmission=1.0), v1(ROUGH, transmission=1.0)),
    "multiscatter glass": (v1(0.1, True, transmission=1.0), v1(ROUGH, True, transmission=1.0)),
}


def _both_sides(seed, n=4000):
    si = random_hits(seed, n, normal_side=np.where(np.random.default_rng(seed).random(n) < 0.5, 1.0, -1.0))
    wi = np.random.default_rng(seed + 1).normal(size=(3, n))
    return si, wi / np.linalg.norm(wi, axis=0)


def _floored(si):
    si.alpha_floor = np.full(len(si), FLOOR)
    return si


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_floored_closure_is_the_closure_of_that_alpha(case):
    sharp, rough = (PrincipledV1([m], RenderSettings()) for m in CASES[case])
    si, wi = _both_sides(3)
    f_floor, p_floor = sharp.eval(_floored(si), wi)
    f_rough, p_rough = rough.eval(_both_sides(3)[0], wi)
    assert (p_rough > 0).sum() > 1000
    assert np.allclose(f_floor, f_rough, rtol=1e-7, atol=1e-12) and np.allclose(p_floor, p_rough, rtol=1e-7, atol=1e-12)
    u_lobe, u = uniforms(4, len(si))
    a, b = sharp.sample(_floored(_both_sides(3)[0]), u_lobe, u), rough.sample(_both_sides(3)[0], u_lobe, u)
    assert np.allclose(a.wi, b.wi, atol=1e-7) and np.allclose(a.pdf, b.pdf, rtol=1e-6, atol=1e-12)
    assert np.allclose(a.value, b.value, rtol=1e-6, atol=1e-9) and np.array_equal(a.flags, b.flags)
    # Control: the closure without the floor (the v1 before Filter Glossy reached it) is far off.
    f_old, p_old = sharp.eval(_both_sides(3)[0], wi)
    assert not np.allclose(p_old, p_rough, rtol=0.1) and not np.allclose(f_old, f_rough, rtol=0.1)


def test_the_floor_raises_only_lower_alphas_and_keeps_burley():
    bsdf = PrincipledV1([v1(0.02, specular=1.0), v1(0.8, anisotropy=0.8, specular=1.0)], RenderSettings())
    def hits():
        si = random_hits(5, 200)
        si.material = np.arange(200) % 2
        return si
    plain, hit = bsdf.inputs(hits()), bsdf.inputs(_floored(hits()))
    assert np.array_equal(hit.ax, np.maximum(plain.ax, FLOOR)) and np.array_equal(hit.ay, np.maximum(plain.ay, FLOOR))
    assert (hit.ay < FLOOR).sum() == 0 and (plain.ax > FLOOR).any() and (plain.ay < FLOOR).any()
    assert np.array_equal(hit.roughness, plain.roughness) and np.array_equal(hit.multi, plain.multi)
    raised = (hit.ax != plain.ax) | (hit.ay != plain.ay)
    assert np.array_equal(hit.table[~raised], plain.table[~raised])
    assert np.allclose(hit.table[raised], np.sqrt(np.sqrt(hit.ax * hit.ay))[raised])


def test_the_compiled_closures_take_the_floored_alphas():
    require_compiled()
    materials = [v1(r, i % 2 == 0, metallic=m, specular=0.5, sheen=0.3)
                 for i, (r, m) in enumerate([(0.0, 1.0), (0.1, 0.0), (0.3, 0.5), (0.9, 1.0)])]
    numpy_bsdf, compiled = PrincipledV1(materials, RenderSettings()), PrincipledV1(materials, RenderSettings())
    numpy_bsdf.use_backend({"principled": "numpy"})
    compiled.use_backend({"principled": "numba"})
    assert numpy_bsdf.compiled is None and compiled.compiled is not None
    count = 1500

    def hits():
        return _hits(np.random.default_rng(11), len(materials), count, extras=True)   # floor 0.3 at half
    rng = np.random.default_rng(6)
    wi = rng.normal(size=(3, count))
    wi /= np.linalg.norm(wi, axis=0)
    f_a, p_a = numpy_bsdf.eval(hits(), wi)
    f_b, p_b = compiled.eval(hits(), wi)
    assert np.array_equal(f_a, f_b) and np.array_equal(p_a, p_b)
    u_lobe, u = rng.random(count), (rng.random(count), rng.random(count))
    a, b = numpy_bsdf.sample(hits(), u_lobe, u), compiled.sample(hits(), u_lobe, u)
    for x, y in ((a.wi, b.wi), (a.value, b.value), (a.pdf, b.pdf), (a.flags, b.flags)):
        assert np.array_equal(x, y)
    # Control: the same hits without the floor give other values.
    plain = hits()
    plain.alpha_floor = None
    assert not np.allclose(compiled.eval(plain, wi)[1], p_b)


def test_the_effect_plan_widens_the_v1_closures():
    from tests.materials.test_principled_v1 import small_scene
    plan = plan_effects(small_scene(), RenderSettings(filter_glossy=1.0))
    assert plan.enabled["filter_glossy"] and "'P34'" in plan.reason["filter_glossy"], plan.reason["filter_glossy"]
    assert not plan_effects(small_scene(), RenderSettings()).enabled["filter_glossy"]        # 0: off


def test_the_v2_glass_closure_takes_the_floor_too():
    """The Principled v2's transmission (engine/materials/principled_glass.py): the running Blender's
    Cycles blurs its GGX glass closure as well."""
    def glass(roughness):
        m = Material("g", "principled", (0.9, 0.8, 0.7), roughness=roughness, ior=1.5, multiscatter=False)
        return PrincipledGlass([m], np.array([1.0]), np.ones((3, 1)))
    sharp, rough = glass(0.0), glass(ROUGH)
    si, wi = _both_sides(8)
    f_floor, p_floor = sharp.eval(_floored(si), wi)
    f_rough, p_rough = rough.eval(_both_sides(8)[0], wi)
    assert (p_rough > 0).sum() > 1000
    assert np.allclose(f_floor, f_rough, rtol=1e-7, atol=1e-12) and np.allclose(p_floor, p_rough, rtol=1e-7, atol=1e-12)
    u_lobe, u = uniforms(9, len(si))
    a = sharp.sample(_floored(_both_sides(8)[0]), u_lobe, *u)
    b = rough.sample(_both_sides(8)[0], u_lobe, *u)
    assert np.allclose(a[0], b[0], atol=1e-7) and np.allclose(a[2], b[2], rtol=1e-6, atol=1e-12)
    f_old, p_old = sharp.eval(_both_sides(8)[0], wi)                  # control: unfloored
    assert not np.allclose(p_old, p_rough, rtol=0.1)
