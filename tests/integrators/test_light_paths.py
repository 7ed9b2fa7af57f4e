"""Cycles' Light Paths options in the path tracer (engine/integrators/light_paths.py): each one
changes the image as Cycles' does, and none changes anything at its fair value.

Exact checks where the option's meaning allows one (a diffuse-only scene: the diffuse bounce limit
is the total limit; Clamp Indirect at almost 0 leaves the direct light of max depth 0; every option
that acts after a bounce leaves a max-depth-0 render alone), statistical ones with fixed seeds
otherwise, each with a control that must fail.  The slow comparisons with Cycles are
tests/addon/test_agreement_light_paths.py.
"""
import copy
import dataclasses

import numpy as np
import pytest

from engine.api import render
from engine.core.settings import CYCLES, FAIR, RenderSettings, preset_values
from engine.integrators import light_paths as lp
from engine.integrators.effects import plan_effects
from engine.integrators.path_tracer import DIFFUSE_RAY, GLOSSY_RAY, TRANSMISSION_RAY, PathTracer
from engine.materials.glossy import MicrofacetReflection
from engine.materials.protocol import BSDFFlags, ShadingPoint
from engine.materials.table import SCATTERING, MaterialTable
from engine.scene.builtin import BUILTIN_SCENES
from engine.scene.model import DIFFUSE, GLOSSY, Material


def scene_of(name, size=24, **kinds):
    """A built-in scene at size x size; kinds: {material name: (kind, roughness)} to change."""
    scene = BUILTIN_SCENES[name]()
    scene.resolution = (size, size)
    for m in scene.materials:
        if m.name in kinds:
            m.kind, m.roughness = kinds[m.name]
    return scene


def diffuse_cornell(size=24):
    return scene_of("cornell", size, Mirror=(DIFFUSE, 0.0), Glass=(DIFFUSE, 0.0))


def image(scene, samples=8, seed=1, **settings):
    settings.setdefault("threads", 1)
    result = render(scene, RenderSettings(samples=samples, seed=seed, **settings), log=lambda *a: None)
    return np.asarray(result.image, dtype=np.float64)[..., :3]


# -- the pieces ------------------------------------------------------------------------------------
def test_clamp_scales_the_rgb_sum_down_to_three_times_the_clamp():
    c = np.array([[30.0, 1.0, -6.0], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    out = lp.clamp_contribution(c, np.array([2.0, 2.0, np.inf]))
    np.testing.assert_allclose(out[:, 0], [6.0, 0.0, 0.0])          # |R|+|G|+|B| = 30 -> 6 = 3 x 2
    np.testing.assert_array_equal(out[:, 1:], c[:, 1:])             # 3 <= 6, and no limit


def test_clamp_of_a_tiny_contribution_keeps_it_and_warns_nothing():
    """A denormal |R|+|G|+|B| makes bound / total overflow in the branch where() drops: no
    RuntimeWarning on the user's console (the workers printed one per render)."""
    import warnings
    c = np.array([[5e-324, 1.0], [0.0, 0.0], [0.0, 0.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = lp.clamp_contribution(c, np.array([1e10, 1e10]))
    np.testing.assert_array_equal(out, c)
    with pytest.warns(RuntimeWarning), np.errstate(over="warn"):       # the control: that division warns
        np.array([3e10]) / np.array([5e-324])

def test_blur_alpha_is_cycles_widening():
    np.testing.assert_allclose(lp.blur_alpha(np.array([np.inf, 0.36, 2.0]), 1.0), [0.0, 0.4, 0.0])
    np.testing.assert_allclose(lp.blur_alpha(np.array([0.36]), 0.5), [np.sqrt(1 - 0.72) / 2])


def test_bounce_types_follow_cycles_labels():
    f = BSDFFlags
    flags = np.array([f.DIFFUSE | f.REFLECTION, f.GLOSSY | f.REFLECTION, f.DELTA | f.REFLECTION,
                      f.DELTA | f.TRANSMISSION, f.DIFFUSE | f.TRANSMISSION, f.DELTA | f.TRANSMISSION | f.STRAIGHT],
                     dtype=np.int8)
    assert lp.bounce_type(flags).tolist() == [lp.DIFFUSE_BOUNCE, lp.GLOSSY_BOUNCE, lp.GLOSSY_BOUNCE,
                                              lp.TRANSMISSION_BOUNCE, lp.TRANSMISSION_BOUNCE, lp.TRANSPARENT_BOUNCE]
    # after a diffuse reflection or transmission; a straight pass-through keeps what was before
    assert lp.after_diffuse(flags, np.array([False] * 5 + [True])).tolist() == [True, False, False, False, True, True]


def test_caustics_leave_out_the_lobes_of_each_bsdf():
    """Per scatter group: mirror and glossy lose everything with Reflective off, refraction with
    Refractive off, glass only both of its lobes together; BSDFs with a diffuse lobe and straight
    pass-throughs (Transparent BSDF) are never blackened by the tracer."""
    kinds = [kind for kind, _ in SCATTERING]
    table = MaterialTable([Material(k, kind=k if k in ("diffuse", "mirror", "glass", "glossy", "principled")
                                    else DIFFUSE) for k in kinds], RenderSettings())
    group = np.arange(len(kinds))
    after = np.ones(len(kinds), dtype=bool)

    def gone(**toggles):
        settings = RenderSettings(**toggles)
        paths = lp.LightPaths(settings, plan_effects(BUILTIN_SCENES["cornell"](), settings), table.bsdfs)
        return {kinds[g] for g in np.flatnonzero(paths.no_closure(group, after))}
    assert gone() == set()
    assert not lp.LightPaths(RenderSettings(caustics_reflective=False), plan_effects(BUILTIN_SCENES["cornell"](),
                             RenderSettings()), [type("NoLobes", (), {"flags": BSDFFlags.NONE})()]).specular_only[0]
    assert gone(caustics_reflective=False) == {"mirror", "glossy", "blurred mirror"}
    assert gone(caustics_refractive=False) == {"refraction", "rough refraction"}
    assert gone(caustics_reflective=False, caustics_refractive=False) == {
        "mirror", "glossy", "glass", "rough glass", "refraction", "rough refraction",
        "blurred mirror"}   # never transparent


def test_alpha_floor_widens_the_microfacet_lobe():
    """eval with alpha_floor a equals eval of the material whose alpha is a (roughness sqrt(a)); a
    floor below the material's alpha changes nothing."""
    rng = np.random.default_rng(4)
    n = 64
    wo, wi = rng.normal(size=(3, n)), rng.normal(size=(3, n))
    wo[2], wi[2] = np.abs(wo[2]), np.abs(wi[2])
    wo, wi = wo / np.linalg.norm(wo, axis=0), wi / np.linalg.norm(wi, axis=0)
    z = np.tile([[0.0], [0.0], [1.0]], n)

    def f_cos(roughness, floor=None):
        bsdf = MicrofacetReflection([Material("g", kind=GLOSSY, roughness=roughness, multiscatter=False)],
                                    RenderSettings())
        si = ShadingPoint(wo, z, z, z, np.ones((3, n)), np.zeros(n, dtype=np.int64),
                          alpha_floor=None if floor is None else np.full(n, floor))
        return bsdf.eval(si, wi)
    wide, pdf_wide = f_cos(0.1, floor=0.25)
    ref, pdf_ref = f_cos(0.5)
    np.testing.assert_allclose(wide, ref, rtol=1e-12)
    np.testing.assert_allclose(pdf_wide, pdf_ref, rtol=1e-12)
    np.testing.assert_array_equal(f_cos(0.5, floor=0.01)[0], ref)
    assert not np.allclose(f_cos(0.1)[0], ref)                       # control: no floor, another lobe


# -- the fair values change nothing; the plan says what is on ----------------------------------------
def test_fair_settings_run_no_light_path_code():
    scene = scene_of("cornell", 8)
    settings = RenderSettings()
    plan = plan_effects(scene, settings)
    assert not any(plan.enabled[e] for e in ("bounce_limits", "clamp", "filter_glossy", "caustics"))
    assert dataclasses.replace(settings, **preset_values(FAIR)) == settings
    cycles = dataclasses.replace(settings, **preset_values(CYCLES))
    assert (cycles.max_depth, cycles.diffuse_bounces, cycles.glossy_bounces, cycles.transmission_bounces,
            cycles.transparent_bounces, cycles.clamp_direct, cycles.clamp_indirect, cycles.filter_glossy,
            cycles.caustics_reflective, cycles.caustics_refractive) == (12, 4, 4, 12, 8, 0.0, 10.0, 1.0, True, True)
    plan = plan_effects(scene, cycles)
    assert plan.enabled["bounce_limits"] and plan.enabled["clamp"] and plan.enabled["filter_glossy"]
    assert "diffuse at most 4, glossy at most 4 (of 12 in all)" in plan.reason["bounce_limits"]
    assert "indirect to 10" in plan.reason["clamp"]
    assert "'Mirror', 'Glass' as GGX lobes" in plan.reason["filter_glossy"]      # engine/integrators/delta_blur.py
    plan = plan_effects(diffuse_cornell(8), cycles)
    assert not plan.enabled["filter_glossy"] and "no microfacet material" in plan.reason["filter_glossy"]


def test_options_that_act_after_a_bounce_leave_direct_light_alone():
    """Max depth 0: no hit follows a diffuse or blurry bounce (the last ray only finds emission), so
    caustics off and Filter Glossy leave the image bit-identical; at depth 8 they change it."""
    scene = scene_of("cornell", 16, Mirror=(GLOSSY, 0.05))
    options = dict(caustics_reflective=False, caustics_refractive=False, filter_glossy=1.0)
    np.testing.assert_array_equal(image(scene, max_depth=0, **options), image(scene, max_depth=0))
    assert not np.array_equal(image(scene, **options), image(scene))               # control


# -- bounce limits -----------------------------------------------------------------------------------
def test_diffuse_limit_is_the_total_limit_in_a_diffuse_scene():
    """Every bounce of a diffuse-only scene is diffuse: Diffuse Bounces 2 under a total of 8 traces
    the very paths of a total of 2 (the bounce past the limit only finds emission, as the total's)."""
    scene = diffuse_cornell()
    limited = image(scene, max_depth=8, diffuse_bounces=2)
    np.testing.assert_allclose(limited, image(scene, max_depth=2), rtol=1e-12, atol=1e-15)
    assert not np.allclose(image(scene, max_depth=8, diffuse_bounces=3), limited, rtol=1e-3)   # control


def test_a_limit_at_the_total_changes_nothing():
    scene = scene_of("cornell", 16)
    np.testing.assert_array_equal(image(scene, max_depth=3, diffuse_bounces=3, glossy_bounces=5,
                                        transmission_bounces=3), image(scene, max_depth=3))


def test_transmission_limits_darken_what_is_seen_through_glass():
    """Transmission Bounces 0: the ball's inside only finds emission (black here); 2: the camera sees
    the room through the ball, but not what needs a third refraction."""
    scene = scene_of("caustic", 24)
    fair, two, zero = (image(scene, samples=16, transmission_bounces=n).mean() for n in (1024, 2, 0))
    assert zero < two < fair, (zero, two, fair)


# -- clamping ----------------------------------------------------------------------------------------
def clamped_contributions(scene, monkeypatch, **settings):
    """The largest mean over R, G, B of any contribution the clamp let through, in a 1-spp NumPy render
    (the compiled sums clamp in their loops, the same numbers: tests/integrators/test_wavefront_jit.py)."""
    seen = []
    clamp = lp.LightPaths.clamp

    def spy(self, contribution, direct):
        out = clamp(self, contribution, direct)
        if out.size:
            seen.append(np.abs(out).sum(axis=0).max() / 3.0)
        return out
    monkeypatch.setattr(lp.LightPaths, "clamp", spy)
    image(scene, samples=1, backend="numpy", **settings)
    return max(seen)


def test_clamp_bounds_every_sample_contribution(monkeypatch):
    scene = scene_of("cornell", 24)
    assert clamped_contributions(scene, monkeypatch, clamp_direct=0.5, clamp_indirect=0.2) <= 0.5 * (1 + 1e-12)
    assert clamped_contributions(scene, monkeypatch, clamp_direct=1e8, clamp_indirect=1e8) > 0.5   # control


def test_clamp_bounds_the_pixels_of_a_one_sample_render():
    """One sample, max depth 0, black background: a pixel is its camera ray's emission, one shadow
    ray and one BSDF ray, each clamped: at most 3 x the clamp (mean over R, G, B); the lamp is 12."""
    scene = scene_of("cornell", 24)
    img = image(scene, samples=1, max_depth=0, clamp_direct=0.5)
    assert img.mean(axis=-1).max() <= 1.5 * (1 + 1e-12)
    assert image(scene, samples=1, max_depth=0).mean(axis=-1).max() > 1.5                    # control


def test_clamp_indirect_near_zero_leaves_the_direct_light():
    """Direct = camera-seen emission and light after one bounce: with every indirect contribution
    scaled to ~0 the image is the max-depth-0 one; clamping direct light instead is far from it."""
    scene = diffuse_cornell()
    direct = image(scene, max_depth=0)
    np.testing.assert_allclose(image(scene, clamp_indirect=1e-12), direct, rtol=1e-9, atol=1e-9)
    assert not np.allclose(image(scene, clamp_direct=1e-12), direct, atol=1e-3)       # control


# -- caustics -----------------------------------------------------------------------------------------
def caustic_scatters(scene, monkeypatch, **settings):
    """{ray kind: how many scatters after a diffuse bounce went on as that kind with a throughput}."""
    counts = {GLOSSY_RAY: 0, TRANSMISSION_RAY: 0}
    scatter = PathTracer.scatter

    def spy(self, p, point, si, spans, u_lobe, u_dir):     # (NumPy's: the compiled bounce's tail comes later)
        before = p.ray_kind[:len(si)].copy()
        new_d, side, beta = scatter(self, p, point, si, spans, u_lobe, u_dir)
        went_on = (before == DIFFUSE_RAY) & (beta.max(axis=0) > 0.0)
        for kind in counts:
            counts[kind] += int((went_on & (p.ray_kind[:len(si)] == kind)).sum())
        return new_d, side, beta
    monkeypatch.setattr(PathTracer, "scatter", spy)
    image(scene, samples=4, backend="numpy", **settings)
    return counts


def test_caustics_off_ends_the_paths_that_would_make_caustics(monkeypatch):
    """Cornell box with a mirror and a glass ball: after a diffuse bounce no path goes on through a
    refraction (Refractive off) or a mirror or glass reflection (Reflective off); control: with the
    toggles on such paths exist, and each toggle keeps the other's lobes."""
    scene = scene_of("cornell", 24)
    on = caustic_scatters(scene, monkeypatch)
    assert on[GLOSSY_RAY] > 0 and on[TRANSMISSION_RAY] > 0, on
    refractive_off = caustic_scatters(scene, monkeypatch, caustics_refractive=False)
    assert refractive_off[TRANSMISSION_RAY] == 0 and refractive_off[GLOSSY_RAY] > 0, refractive_off
    reflective_off = caustic_scatters(scene, monkeypatch, caustics_reflective=False)
    assert reflective_off[GLOSSY_RAY] == 0 and reflective_off[TRANSMISSION_RAY] > 0, reflective_off


def test_caustics_off_renders_the_same_on_the_compiled_bounce():
    """The counts above are NumPy's (their spy reads the scatter's tail); the compiled bounce gives the same
    image with each toggle off (control: the toggle changes the image)."""
    from tests.backend_capture import require_compiled
    require_compiled()
    scene = scene_of("cornell", 24)
    for toggle in ("caustics_refractive", "caustics_reflective"):
        numpy_image = image(scene, samples=4, backend="numpy", **{toggle: False})
        assert np.array_equal(numpy_image, image(scene, samples=4, backend="numba", **{toggle: False}))
        assert not np.array_equal(numpy_image, image(scene, samples=4, backend="numpy"))


def test_principled_without_glossy_lobes_weights_its_diffuse_as_cycles():
    from engine.materials.principled import PrincipledV2
    from engine.scene.model import PRINCIPLED, Principled
    m = Material("p", kind=PRINCIPLED, color=(0.8, 0.5, 0.2), roughness=0.3, principled=Principled(metallic=0.25))
    bsdf = PrincipledV2([m], RenderSettings())
    z = np.array([[0.0], [0.0], [1.0]])
    wo = np.array([[0.3], [0.0], [0.95]]) / np.linalg.norm([0.3, 0.0, 0.95])
    si = ShadingPoint(wo, z, z, z, np.array([[0.8], [0.5], [0.2]]), np.zeros(1, dtype=np.int64))
    (metal, spec, diffuse), _ = bsdf.lobe_weights(si)
    assert metal[0] == 0.25 and spec[0] == 0.75 and diffuse[0] < 0.75
    (metal, spec, diffuse), prob = bsdf.lobe_weights(dataclasses.replace(si, glossy_off=np.array([True])))
    assert (metal[0], spec[0], diffuse[0]) == (0.0, 0.0, 0.75) and prob[2, 0] == 1.0


# -- Filter Glossy -------------------------------------------------------------------------------------
def test_filter_glossy_reduces_the_noise_of_sharp_glossy_paths():
    """Sharp glossy balls in the Cornell box: the difference of two seeds' images (their noise, off
    the lamp's pixels) is smaller with Filter Glossy 1; control: two other seeds without it are as
    noisy as the first two."""
    scene = scene_of("cornell", 24, Mirror=(GLOSSY, 0.05), Glass=(GLOSSY, 0.05))
    lamp = image(scene, samples=16).max(axis=-1) > 1.0

    def noise(fg, seeds=(1, 2)):
        a, b = (image(scene, samples=16, seed=s, filter_glossy=fg) for s in seeds)
        return np.sqrt(((a - b)[~lamp] ** 2).mean())
    sharp, filtered, other = noise(0.0), noise(1.0), noise(0.0, seeds=(3, 4))
    print(f"noise: sharp {sharp:.4f}, filtered {filtered:.4f}, sharp with other seeds {other:.4f}")
    assert filtered < 0.8 * sharp, (filtered, sharp)
    assert other > 0.9 * sharp, (other, sharp)                     # control


def test_path_tracer_keeps_no_light_path_state_at_fair_values():
    """The wavefront carries the bounce counts and the least pdf only when their option is on."""
    scene = scene_of("cornell", 8)
    from engine.rendering.session import PreparedScene
    fair = PreparedScene(scene, RenderSettings(threads=1))
    assert isinstance(fair.tracer, PathTracer) and fair.tracer.light_paths is None
    scene = diffuse_cornell(8)
    on = PreparedScene(scene, RenderSettings(threads=1, diffuse_bounces=2, filter_glossy=1.0))
    assert on.tracer.light_paths.bounce_limits and on.tracer.light_paths.filter_glossy == 0.0   # no glossy


@pytest.mark.parametrize("preset, depth, clamp", [(FAIR, 8, 0.0), (CYCLES, 12, 10.0)])
def test_the_command_line_presets(preset, depth, clamp):
    from engine.cli.main import build_parser, settings_from_args
    args = build_parser().parse_args(["render", "-o", "x.exr", "--preset", preset, "--glossy-bounces", "2",
                                      "--no-caustics-refractive"])
    s = settings_from_args(args)
    assert (s.max_depth, s.clamp_indirect, s.glossy_bounces, s.caustics_refractive) == (depth, clamp, 2, False)
