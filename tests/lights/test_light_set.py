"""The light set (engine/lights/light_set.py, emitters.py): light numbers by kind, the two groups
and their selection, the maps from primitives to lights, and the densities MIS asks for.

Controls: the pick frequencies fail against the pmf without the group's share, and a wrong
primitive map fails the map check.
"""
import numpy as np
import pytest

from engine.lights.light_set import LightSet
from engine.scene.model import (AreaLight, Camera, Material, PointLight, Quad, Scene, Sphere, SunLight,
                                TriangleMesh)

from tests.chi_square import ALPHA, pooled_chi2
from tests.lights.kinds import disk

EVERY_NAME = ["parallelogram", "triangle", "sphere", "polygon", "point", "sun", "world"]


def every_emitter_scene(background=(0.1, 0.2, 0.3)):
    """Every kind of emitter: a lamp quad Blender split in two (one parallelogram light), single
    triangles, a rectangle and a skew quad, emissive spheres, Area lights (a disk, a two-sided
    panel, one not diffusely visible, one that lights nothing), point and spot lights, suns."""
    mats = [Material("Warm", emission=(3.0, 2.0, 1.0), color=(0, 0, 0)),
            Material("Cold", emission=(0.5, 0.7, 2.0), color=(0, 0, 0)),
            Material("Grey", color=(0.5, 0.5, 0.5))]
    lamp = TriangleMesh("Lamp", np.array([[0, 0, 3], [2, 0, 3], [2, 1, 3], [0, 1, 3]], float),
                        np.array([[0, 1, 2], [0, 2, 3]]), [0, 0])
    tris = TriangleMesh("Tris", np.array([[-2, 0, 0.5], [-1, 0, 0.6], [-1.5, 1, 1.5], [-2.5, 1.2, 0.7]], float),
                        np.array([[0, 1, 2], [0, 2, 3], [1, 2, 3]]), [0, 1, 2])
    quads = [Quad("Rect", np.array([[0, 0, 2], [1, 0, 2], [1, 1, 2], [0, 1, 2]], float), 0),
             Quad("Floor", np.array([[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]], float), 2),
             Quad("Skew", np.array([[2, 0, 1], [3, 0, 1], [3.5, 1, 1], [2.5, 1, 1]], float), 1)]
    spheres = [Sphere("Bulb", (0.5, -1, 0.5), 0.2, 1), Sphere("Ball", (0.5, 1, 0.5), 0.2, 2),
               Sphere("Bulb 2", (-0.5, -1, 0.5), 0.1, 0)]
    panel = np.array([[-1, 2, 1], [-1, 2, 2], [0, 2, 2], [0, 2, 1]], float)
    lights = [AreaLight("Disk", disk((0.0, -2.0, 1.8), 0.3, normal_sign=-1.0), (4.0, 4.0, 4.0)),
              AreaLight("Panel", panel, (1.0, 1.0, 1.0), two_sided=True),
              AreaLight("Hidden", panel + [0, 1, 0], (1.0, 2.0, 1.0), visible_diffuse=False),
              AreaLight("Dark", panel + [0, 2, 0], (1.0, 2.0, 1.0), lights_diffuse=False)]
    points = [PointLight("Point", (0.1, 0.2, 2.5), (5.0, 4.0, 3.0)),
              PointLight("Spot", (-1.1, 0.2, 2.4), (7.0, 4.0, 3.0), radius=0.05, spot_size=1.0, spot_blend=0.3),
              PointLight("Unlit", (0.1, 0.2, 2.5), (5.0, 4.0, 3.0), lights_diffuse=False)]
    suns = [SunLight("Sun", (0.3, 0.2, -1.0), (2.0, 2.0, 1.5)), SunLight("Soft", (-0.3, 0.2, -1.0), (1.0, 2.0, 1.5), 0.2)]
    return Scene(Camera.look_at((0, -5, 1), (0, 0, 1)), mats, meshes=[lamp, tris], quads=quads, spheres=spheres,
                 lights=lights, points=points, suns=suns, background=background)


def receivers(rng, m):
    x = rng.uniform(-3, 3, (3, m)) + np.array([[0.0], [0.0], [1.0]])
    n = rng.normal(size=(3, m))
    return x, n / np.sqrt((n * n).sum(axis=0))


def owner(lights, light):
    """The kind that owns light number `light` (by its range), and the light's number in it."""
    for kind in lights.kinds:
        if kind.first <= light < kind.first + kind.count:
            return kind, light - kind.first
    raise AssertionError(f"no kind owns light {light}")


def test_the_kinds_own_contiguous_ranges_of_light_numbers():
    lights = LightSet(every_emitter_scene(), lamps_hittable=True, world=True)
    assert lights.kind_names() == EVERY_NAME
    start = 0
    for kind in lights.kinds:
        assert kind.first == start and kind.count > 0
        start += kind.count
    total = start
    assert lights.radiance.shape == (3, total) and len(lights.one_sided) == len(lights.bsdf_reachable) == total
    assert lights.local.first == 0 and lights.distant.first == lights.local.count == total - 3   # 2 suns, world
    # The lamp pair, the rectangle, the skew quad, the panel and the hidden one are parallelograms;
    # two emissive single triangles; two emissive spheres; the disk; two lit points; two suns; the world.
    assert [k.count for k in lights.kinds] == [5, 2, 2, 1, 2, 2, 1]


def test_primitives_map_to_the_lights_made_of_them():
    scene = every_emitter_scene()
    lights = LightSet(scene, lamps_hittable=True, world=True)
    check_maps(lights, scene)
    assert lights.triangle_light[0] == lights.triangle_light[1] >= 0          # the lamp pair: one light
    assert lights.quad_light[1] == -1 and lights.sphere_light[1] == -1          # not emissive
    assert lights.area_light_light[3] == -1                                    # lights nothing
    # The report's estimator keeps the lamp's two triangles.
    report = LightSet(scene, solid_angle=False, spatial=False)
    assert report.triangle_light[0] != report.triangle_light[1]
    check_maps(report, scene)


def check_maps(lights, scene):
    """Each primitive's light has the primitive's emission and lies on it."""
    emission = [np.array(m.emission) for m in scene.materials]
    tri = np.concatenate([np.asarray(m.vertices, float)[np.asarray(m.triangles)] for m in scene.meshes])
    tri_le = np.concatenate([[emission[i] for i in m.material_ids] for m in scene.meshes])
    prims = ([(t, le) for t, le in zip(tri, tri_le)], lights.triangle_light), \
        ([(np.asarray(q.corners, float), emission[q.material_id]) for q in scene.quads], lights.quad_light), \
        ([(np.asarray(a.vertices, float), np.array(a.radiance)) for a in scene.lights], lights.area_light_light)
    for prim, table in prims:
        assert len(prim) == len(table)
        for (corners, le), light in zip(prim, table):
            if light < 0:
                continue
            kind, i = owner(lights, light)
            assert np.array_equal(kind.radiance[:, i], le)
            point = kind.sample_area(np.array([i]), np.array([0.3]), np.array([0.6]))[0][:, 0]
            normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
            assert abs((point - corners[0]) @ normal) < 1e-9 * np.linalg.norm(normal)   # in its plane
    for sphere, light in zip(scene.spheres, lights.sphere_light):
        if light >= 0:
            kind, i = owner(lights, light)
            assert np.allclose(kind.center[:, i], sphere.center) and kind.radius[i] == sphere.radius


def test_a_wrong_map_fails_the_map_check():
    scene = every_emitter_scene()
    lights = LightSet(scene)
    lights.quad_light = lights.quad_light[::-1].copy()
    with pytest.raises(AssertionError):
        check_maps(lights, scene)


def test_which_lights_a_bounce_ray_can_reach():
    scene = every_emitter_scene()
    lights = LightSet(scene, lamps_hittable=True, world=True)
    reach = {name: lights.bsdf_reachable[k.first:k.first + k.count] for name, k in zip(EVERY_NAME, lights.kinds)}
    assert reach["triangle"].all() and reach["sphere"].all() and reach["world"].all()
    assert not reach["point"].any() and not reach["sun"].any()
    area = [lights.bsdf_reachable[i] for i in lights.area_light_light[:3]]
    assert area == [True, True, False]                                        # Hidden: no diffuse rays
    assert not LightSet(scene, lamps_hittable=False).bsdf_reachable[lights.area_light_light[0]]


def test_the_share_of_the_lights_at_infinity():
    scene = every_emitter_scene()
    lights = LightSet(scene, world=True)
    far, near = lights.distant_power.sum(), lights.power.sum()
    assert lights.distant_share == pytest.approx(np.clip(far / (far + near), 0.1, 0.9))
    assert LightSet(scene, world=False).distant.count == 2                    # the suns only
    only_suns = Scene(None, scene.materials, quads=scene.quads[1:2], suns=scene.suns)
    assert LightSet(only_suns).distant_share == 1.0 and LightSet(only_suns).local.count == 0
    assert LightSet(Scene(None, scene.materials, quads=scene.quads)).distant is None


@pytest.mark.parametrize("spatial", [False, True])
def test_sampled_pdfs_are_the_pdfs_mis_asks_for(spatial):
    """sample()'s pdf is pdf() for lamps and surfaces and world_pdf() for the world, with both
    groups in the set (the share of each included)."""
    lights = LightSet(every_emitter_scene(), solid_angle=spatial, spatial=spatial, world=True)
    rng = np.random.default_rng(3)
    m = 40_000
    x, n = receivers(rng, m)
    s = lights.sample(x, n, rng.random(m), rng.random(m), rng.random(m))
    assert np.isfinite(s.pdf).all() and (s.pdf > 0).mean() > 0.9
    local = np.flatnonzero((s.light < lights.distant.first) & (s.pdf > 0) & lights.bsdf_reachable[s.light])
    assert np.allclose(lights.pdf(x[:, local], n[:, local], s.light[local], s.point[:, local]), s.pdf[local],
                       rtol=1e-9, atol=0)
    world = np.flatnonzero(s.light == lights.world.first)
    assert len(world) > 100
    assert np.allclose(lights.world_pdf(n[:, world], s.direction[:, world]), s.pdf[world], rtol=1e-12, atol=0)
    sky = s.light >= lights.distant.first
    assert np.isinf(s.distance[sky]).all() and np.isfinite(s.distance[~sky]).all()


def pick_probabilities(lights, x, n, with_share=True):
    """P(light k) at one receiver, over every light of the set."""
    local = np.arange(lights.local.count)
    p_local = lights.local.selection.pmf(x[:, None].repeat(len(local), 1), n[:, None].repeat(len(local), 1), local)
    p_far = lights.distant.selection.prob
    if with_share:
        p_local, p_far = p_local * lights.local.share, p_far * lights.distant.share
    return np.concatenate([p_local, p_far])


@pytest.mark.parametrize("spatial", [False, True])
def test_lights_are_picked_with_the_share_times_the_pmf(spatial):
    lights = LightSet(every_emitter_scene(), spatial=spatial, world=True)
    x, n = np.array([0.5, 0.5, 1.0]), np.array([0.0, 0.0, 1.0])
    p = pick_probabilities(lights, x, n)
    assert p.sum() == pytest.approx(1.0, abs=1e-12) and (p > 0).all()
    m = 100_000
    rng = np.random.default_rng(4)
    s = lights.sample(x[:, None].repeat(m, 1), n[:, None].repeat(m, 1), rng.random(m), rng.random(m), rng.random(m))
    counts = np.bincount(s.light, minlength=len(p))
    assert pooled_chi2(counts, m * p)[0] > ALPHA
    # Control: the same counts against the pmfs without the groups' shares.
    wrong = pick_probabilities(lights, x, n, with_share=False)
    assert pooled_chi2(counts, m * wrong / wrong.sum())[0] < 1e-6
