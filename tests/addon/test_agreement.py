"""TNCG15 MC agrees with Cycles on every sample scene (docs/hard-cases.md §3.5 region-mean test), and the
comparison catches a wrong light strength, a wrong field of view and mis-mapped materials.

Both renderers render the same .blend at 64x64, 32 spp, max depth 8, K = 4 independent seeds each
(Cycles with the fair reference settings of mcrt_addon.reference; TNCG15 MC with exact Fresnel).
8x8 block means and the image mean must agree within the Sidak-corrected z bound plus the
model-difference budget tau: 0.02 for diffuse scenes, 0.05 where glass/mirror spheres are implicit
in TNCG15 MC but tessellated (smooth-shaded) in Cycles.
"""
import copy

import pytest

from imagecompare import compare_runs
from rendering import RES, cycles_reference, export_blend, tncg15_agreement_runs


TAU = {"cornell": 0.05, "mirror_glass": 0.05, "principled": 0.05, "diffuse_room": 0.02,
       "suzanne_5k": 0.02, "suzanne_100k": 0.02, "area_light": 0.02, "nested_glass": 0.05,
       "near_lamp": 0.02, "many_lights": 0.02, "caustic": 0.05, "area_mirror": 0.05,
       "point_light": 0.05, "sun_window": 0.05, "spot_light": 0.05, "sky_lit": 0.05, "textured": 0.02,
       "smooth": 0.02}
# Scenes and controls in `make test-slow` only (.ci/run runs them): each one's subject has a faster test in
# `make test` -- smooth: tests/geometry/test_shading_normals.py; textured: tests/materials/test_textures.py;
# spot_light: test_spot_light_falloff_matches_cycles (tests/lights/test_point_sun_lights.py); many_lights:
# tests/lights/test_light_sampling.py; suzanne_100k: suzanne_5k here and tests/geometry/test_accelerators.py;
# the comparison's controls: glass_as_mirror, red_green_swapped and the light-unit controls stay.  Also slow,
# their subjects covered in `make test` by the scenes that stay (cornell: area light, mirror, glass, spheres;
# mirror_glass): suzanne_5k, diffuse_room, area_light, area_mirror, nested_glass (and
# tests/hard_cases/test_s_t_shading_transport.py), near_lamp, sun_window and point_light (tests/lights/);
# principled (tests/materials/test_principled*.py in `make test`).
SLOW = {"smooth", "textured", "spot_light", "many_lights", "suzanne_100k", "light_x1.3", "fov_lens_x1.1",
        "mirror_as_diffuse", "suzanne_5k", "diffuse_room", "area_light", "area_mirror", "nested_glass",
        "near_lamp", "sun_window", "point_light", "principled",
        # caustic: its glass ball and lamp are cornell's subjects, its caustic tests/integrators/photons/
        "caustic"}


def marked(*names):
    return [pytest.param(n, marks=pytest.mark.slow) if n in SLOW else n for n in names]


def reference(samples, name):
    return cycles_reference(samples[name], name)


def ours(scene, first_seed=1000):
    return tncg15_agreement_runs(scene, first_seed)


@pytest.mark.parametrize("name", marked(
    "cornell", "diffuse_room", "mirror_glass", "principled", "suzanne_5k", "suzanne_100k", "area_light",
    "nested_glass",
    # light-sampling stress scenes; area_mirror needs area lights that mirror and glass
    # rays can reach (AreaLight.visible_glossy / visible_transmission, the mis / solid-angle estimators)
    "near_lamp", "caustic", "many_lights", "area_mirror",
    # point, spot and sun lights, the world as the only light
    "point_light", "sun_window", "spot_light", "sky_lit",
    # image textures: colour, base colour through a second UV map, emission colour
    "textured",
    # smooth shading: interpolated normals, a coarse smooth sphere's shadow terminator
    "smooth"))
def test_agrees_with_cycles(samples, name):
    ref = reference(samples, name)
    exported = export_blend(samples[name], RES)
    result = compare_runs(ours(exported.scene), ref, tau=TAU[name])
    print(f"{name}: {result.summary()}")
    assert result.passed, result.summary()


def perturbed(samples, how):
    scene = copy.deepcopy(export_blend(samples["cornell"], RES).scene)
    if how == "light_x1.3":
        for m in scene.materials:
            m.emission = tuple(1.3 * e for e in m.emission)
    elif how == "fov_lens_x1.1":
        scene.camera.lens *= 1.1
    elif how == "mirror_as_diffuse":
        for m in scene.materials:
            if m.kind == "mirror":
                m.kind = "diffuse"
    elif how == "glass_as_mirror":
        for m in scene.materials:
            if m.kind == "glass":
                m.kind = "mirror"
    elif how == "red_green_swapped":
        red = next(m for m in scene.materials if m.name == "Red")
        green = next(m for m in scene.materials if m.name == "Green")
        red.color, green.color = green.color, red.color
    else:
        raise ValueError(how)
    return scene


@pytest.mark.parametrize("how", marked("light_x1.3", "fov_lens_x1.1", "mirror_as_diffuse", "glass_as_mirror",
                                        "red_green_swapped"))
def test_comparison_catches_wrong_export(samples, how):
    ref = reference(samples, "cornell")
    result = compare_runs(ours(perturbed(samples, how), first_seed=2000), ref, tau=TAU["cornell"])
    print(f"{how}: {result.summary()}")
    assert not result.passed, f"perturbation '{how}' was not detected: {result.summary()}"


@pytest.mark.slow          # every test_agrees_with_cycles that passes shows the comparison accepts a right render
def test_comparison_passes_renderer_against_itself(samples):
    """Sanity check of the statistics: two independent seed sets of the same renderer, tau = 0."""
    scene = export_blend(samples["cornell"], RES).scene
    result = compare_runs(ours(scene, 3000), ours(scene, 4000), tau=0.0)
    print(f"self: {result.summary()}")
    assert result.passed, result.summary()


@pytest.mark.parametrize("name, how", [("point_light", "intensity_x2"),
                                       pytest.param("sun_window", "irradiance_x0.8", marks=pytest.mark.slow),
                                       pytest.param("spot_light", "cone_x1.25", marks=pytest.mark.slow),
                                       pytest.param("spot_light", "no_spot_falloff", marks=pytest.mark.slow),
                                       ("sky_lit", "world_x1.2")])
def test_comparison_catches_wrong_light_units(samples, name, how):
    """Controls for the light exports: a point light twice too strong, a sun 20 % too weak, a spot
    cone 25 % too wide, a spot without its falloff (the point light it is), a world 20 % too bright."""
    scene = copy.deepcopy(export_blend(samples[name], RES).scene)
    spot = next((p for p in scene.points if p.is_spot), None)
    if how == "intensity_x2":
        scene.points[0].intensity = tuple(2 * i for i in scene.points[0].intensity)
    elif how == "irradiance_x0.8":
        scene.suns[0].irradiance = tuple(0.8 * e for e in scene.suns[0].irradiance)
    elif how == "cone_x1.25":
        spot.spot_size *= 1.25
    elif how == "no_spot_falloff":
        spot.spot_size = 0.0
    elif how == "world_x1.2":
        scene.background = tuple(1.2 * c for c in scene.background)
    else:
        raise ValueError(how)
    result = compare_runs(ours(scene, first_seed=5000), reference(samples, name), tau=TAU[name])
    print(f"{name} {how}: {result.summary()}")
    assert not result.passed


@pytest.mark.slow          # with the textured scene
def test_comparison_catches_texture_flipped_in_v(samples):
    """Control for the texture export: every image of the textured scene flipped in V (rows reversed)."""
    scene = copy.deepcopy(export_blend(samples["textured"], RES).scene)
    assert scene.textures and all(t.pixels is not None for t in scene.textures)   # packed: sent as pixels
    for texture in scene.textures:
        texture.pixels = texture.pixels[::-1].copy()
    result = compare_runs(ours(scene, first_seed=6000), reference(samples, "textured"), tau=TAU["textured"])
    print(f"textured flipped in V: {result.summary()}")
    assert not result.passed


def flat_shaded(scene):
    """The smooth scene with its normals not interpolated (every triangle flat)."""
    scene = copy.deepcopy(scene)
    for mesh in scene.meshes:
        mesh.normals = mesh.smooth = None
    return scene


@pytest.mark.slow          # with the smooth scene
def test_comparison_catches_flat_normals(samples):
    """Control for smooth shading: the smooth scene rendered with flat normals (as before smooth shading)
    must fail the comparison (the low-poly mirror ball reflects other parts of the room; measured
    z = -6.9 for the image mean, 12 of 193 regions failed).  Leaving out only the shadow-terminator
    offset is not detectable at 64 x 64 (z = -1.6): tests/geometry/test_shading_normals.py checks it."""
    scene = flat_shaded(export_blend(samples["smooth"], RES).scene)
    result = compare_runs(ours(scene, first_seed=7000), reference(samples, "smooth"), tau=TAU["smooth"])
    print(f"smooth normals_not_interpolated: {result.summary()}")
    assert not result.passed, f"flat normals were not detected: {result.summary()}"
