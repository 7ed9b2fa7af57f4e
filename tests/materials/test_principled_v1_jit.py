"""The compiled Principled v1 closures (engine/materials/principled_v1_jit.py) against the NumPy path of
engine/materials/principled_v1.py PrincipledV1: eval (on a span's hits and on a take of them, as the
light samples evaluate) and sample bit for bit, over metallic 0 to 1, roughness 0.02 to 1 (single and
"Multiscatter GGX"), anisotropy, specular 0 to 1, specular and sheen tints, colours above 1, directions
below the surface and at grazing.  Control: one ulp of alpha is told apart.  Clearcoat and transmission
keep the NumPy closures."""
import numpy as np

from engine.core.settings import RenderSettings
from engine.materials.principled_v1 import PrincipledV1
from engine.scene.model import Material, PrincipledV1 as Params
from tests.backend_capture import require_compiled
from tests.materials.test_principled_jit import _hits

TWIN = "engine.materials.principled_v1_jit"        # imported by use_backend, not here: numba may be missing
NUMBA = {"principled": "numba"}


def _materials():
    out = []
    for i, (metallic, rough, aniso, spec, sheen) in enumerate([(0.0, 0.02, 0.0, 0.5, 0.0), (1.0, 0.3, 0.0, 0.5, 0.0),
                                                               (0.5, 1.0, 0.6, 0.8, 0.5), (0.0, 0.5, 0.0, 0.0, 1.0),
                                                               (0.3, 0.07, 0.9, 1.0, 0.2), (1.0, 0.7, 0.2, 0.5, 0.0)]):
        out.append(Material(f"m{i}", kind="principled", color=(0.9, 0.5 + 0.2 * i, 0.2), roughness=rough,
                            anisotropy=aniso, rotation=0.1 * i, multiscatter=i % 2 == 0,
                            principled=Params(metallic=metallic, specular=spec, specular_tint=0.1 * i, sheen=sheen)))
    return out


def test_eval_and_sample_are_bit_identical():
    require_compiled()
    materials = _materials()
    numpy_bsdf, compiled = PrincipledV1(materials, RenderSettings()), PrincipledV1(materials, RenderSettings())
    numpy_bsdf.use_backend({"principled": "numpy"})
    compiled.use_backend(NUMBA)
    assert numpy_bsdf.compiled is None and compiled.compiled.__name__ == TWIN
    count = 1500

    def hits():
        return _hits(np.random.default_rng(11), len(materials), count)
    rng = np.random.default_rng(5)
    wi = rng.normal(size=(3, count))
    wi /= np.linalg.norm(wi, axis=0)                                # half of them below the surface
    f_a, p_a = numpy_bsdf.eval(hits(), wi)
    f_b, p_b = compiled.eval(hits(), wi)
    assert (p_a > 0).sum() > 500 and np.array_equal(f_a, f_b) and np.array_equal(p_a, p_b)
    idx = np.sort(rng.integers(0, count, count // 2))               # a take, as the light samples' hits
    f_a, p_a = numpy_bsdf.eval(hits().take(idx), wi.take(idx, axis=1))
    span = hits()
    span.memo((compiled, "fused"), compiled._fused_hits)            # the span's values, read by index
    f_b, p_b = compiled.eval(span.take(idx), wi.take(idx, axis=1))
    assert np.array_equal(f_a, f_b) and np.array_equal(p_a, p_b)
    u_lobe, u = rng.random(count), (rng.random(count), rng.random(count))
    a, b = numpy_bsdf.sample(hits(), u_lobe, u), compiled.sample(hits(), u_lobe, u)
    assert (a.pdf > 0).sum() > 500 and len(np.unique(a.flags)) == 2
    for x, y in ((a.wi, b.wi), (a.value, b.value), (a.pdf, b.pdf), (a.flags, b.flags)):
        assert np.array_equal(x, y)
    # Control: closures 1 ulp rougher are told apart.
    p_a = compiled.eval(hits(), wi)[1]
    compiled.ax = np.nextafter(compiled.ax, 1.0)
    assert not np.array_equal(compiled.eval(hits(), wi)[1], p_a)


def test_clearcoat_and_transmission_keep_the_numpy_closures():
    require_compiled()
    for extra in (Params(clearcoat=0.5), Params(transmission=0.5)):
        bsdf = PrincipledV1(_materials() + [Material("x", kind="principled", principled=extra)], RenderSettings())
        bsdf.use_backend(NUMBA)
        assert bsdf.compiled is None
