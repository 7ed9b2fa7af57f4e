"""Point and sun lights (Blender's, in Cycles' units) against closed forms, under every estimator."""
import math

import numpy as np
import pytest

from engine import RenderSettings, render
from engine.scene.model import DIFFUSE, Camera, Material, PointLight, Quad, Scene, SunLight

ESTIMATORS = ["report", "solid-angle", "mis"]


def white_floor(**lights):
    mats = [Material("Floor", DIFFUSE, (1.0, 1.0, 1.0))]
    floor = Quad("Floor", np.array([(-50, -50, 0), (50, -50, 0), (50, 50, 0), (-50, 50, 0)], float), 0)
    cam = Camera.look_at((0, 0, 0.5), (0, 0, 0), up=(0, 1, 0), lens=2000.0)    # sees the floor's origin
    return Scene(cam, mats, quads=[floor], resolution=(4, 4), **lights)


def floor_radiance(scene, estimator, spp=512):
    result = render(scene, RenderSettings(samples=spp, max_depth=0, estimator=estimator), log=lambda *a: None)
    assert result.stats["nonfinite_samples"] == 0
    return result.image[..., 0].mean(), np.sqrt(result.variance[..., 0].sum()) / 16


@pytest.mark.parametrize("estimator", ESTIMATORS)
@pytest.mark.parametrize("radius", [0.0, 0.5, 3.0])
def test_point_light_irradiance(estimator, radius):
    """A white floor 2 m under a point light of intensity I: L = I / (pi (d^2 + r^2)) on its axis
    (a disk of radius r facing the receiver, as Cycles 3.4 and 5.0 measured)."""
    i, h = 5.0, 2.0
    mean, se = floor_radiance(white_floor(points=[PointLight("Bulb", (0, 0, h), (i, i, i), radius)]), estimator)
    assert mean == pytest.approx(i / (math.pi * (h * h + radius * radius)), rel=1e-4, abs=4 * se)


# A spot of size 120 degrees and blend 0.5 pointing straight down from 2 m above the floor, its
# falloff a(theta) measured by rendering that floor with Cycles (direct light, 1024 spp):
# {falloff model: [(horizontal offset of the floor point, a)]}.
SPOT_MEASURED = {
    "smoothstep": [(0.98, 0.9990), (2.18, 0.7879), (2.66, 0.3569), (3.62, 0.0)],        # Cycles 5.0.1
    "cosine-smoothstep": [(0.98, 0.8963), (2.18, 0.5325), (2.66, 0.2146), (3.62, 0.0)],  # Cycles 3.4.1
}


@pytest.mark.parametrize("estimator", ["report", "mis"])
@pytest.mark.parametrize("falloff", sorted(SPOT_MEASURED))
def test_spot_light_falloff_matches_cycles(estimator, falloff):
    """L = I a(theta) cos(theta) / (pi d^2) on a white floor, with a(theta) as Cycles renders it."""
    i, h = 5.0, 2.0
    for offset, a in SPOT_MEASURED[falloff]:
        spot = PointLight("Spot", (offset, 0.0, h), (i, i, i), 0.0, spot_size=math.radians(120), spot_blend=0.5,
                          spot_direction=(0.0, 0.0, -1.0), spot_falloff=falloff)
        mean, se = floor_radiance(white_floor(points=[spot]), estimator, spp=64)
        d2 = h * h + offset * offset
        expected = i * a * (h / math.sqrt(d2)) / (math.pi * d2)
        assert mean == pytest.approx(expected, rel=0.004, abs=4 * se + 1e-12), (offset, a)


def test_a_spot_light_lights_only_its_cone_and_keeps_the_point_lights_power_on_its_axis():
    i, h = 5.0, 2.0
    down = PointLight("Spot", (0, 0, h), (i, i, i), 0.5, spot_size=math.radians(40), spot_direction=(0, 0, -1))
    away = PointLight("Spot", (0, 0, h), (i, i, i), 0.5, spot_size=math.radians(40), spot_direction=(0, 1, 0.2))
    bulb = PointLight("Bulb", (0, 0, h), (i, i, i), 0.5)
    assert floor_radiance(white_floor(points=[down]), "mis")[0] == pytest.approx(
        floor_radiance(white_floor(points=[bulb]), "mis")[0], rel=1e-9)
    assert floor_radiance(white_floor(points=[away]), "mis")[0] == 0.0


@pytest.mark.parametrize("estimator", ESTIMATORS)
@pytest.mark.parametrize("angle", [0.0, 0.5])
def test_sun_irradiance(estimator, angle):
    """A sun of irradiance E at 60 degrees from the zenith: L = E cos(60) / pi on a white floor,
    whatever its angular size (the disk is normalised to E on a surface facing it)."""
    e = 3.0
    sun = SunLight("Sun", (math.sin(math.radians(60)), 0.0, -math.cos(math.radians(60))), (e, e, e), angle)
    mean, se = floor_radiance(white_floor(suns=[sun]), estimator)
    assert mean == pytest.approx(e * 0.5 / math.pi, rel=0.002, abs=4 * se)


def test_a_point_light_behind_a_wall_casts_a_shadow_and_a_bright_one_does_not_fail_silently():
    scene = white_floor(points=[PointLight("Bulb", (0, 0, 2.0), (5.0, 5.0, 5.0), 0.1)])
    scene.quads.append(Quad("Blocker", np.array([(-1, -1, 1), (-1, 1, 1), (1, 1, 1), (1, -1, 1)], float), 0))
    assert floor_radiance(scene, "mis", spp=16)[0] == 0.0
    with pytest.raises(Exception, match="Bulb"):
        render(white_floor(points=[PointLight("Bulb", (0, 0, 2.0), (5.0, -1.0, 5.0), 0.1)]), RenderSettings(samples=1),
               log=lambda *a: None)


def mirror_facing(lens=2000.0, **lights):
    """A mirror (reflectance 1) in the plane y = 2 and a camera at the origin looking at it along
    +y: the reflected rays run back along -y past the origin."""
    from engine.scene.model import MIRROR
    mats = [Material("Mirror", MIRROR, (1.0, 1.0, 1.0))]
    mirror = Quad("Mirror", np.array([(-5, 2, -5), (5, 2, -5), (5, 2, 5), (-5, 2, 5)], float), 0)
    cam = Camera.look_at((0, 0, 0), (0, 1, 0), up=(0, 0, 1), lens=lens)
    return Scene(cam, mats, quads=[mirror], resolution=(4, 4), **lights)


def mirror_radiance(scene, estimator="mis"):
    result = render(scene, RenderSettings(samples=16, max_depth=2, estimator=estimator), log=lambda *a: None)
    return result.image[..., 0].mean(), result.stats["effects"]["seen_lamps"]


@pytest.mark.parametrize("falloff", ["smoothstep", "cosine-smoothstep"])
def test_point_spot_and_sun_lights_are_seen_in_a_mirror_as_cycles_shows_them(falloff):
    """Cycles (5.0, measured) shows a point light of radius r in a mirror with radiance I / (pi r^2),
    a sun of angle theta with E / (pi sin^2(theta / 2)); camera rays do not see them."""
    i, r = 5.0, 0.3
    behind = (0.0, -1.0, 0.0)                   # on the reflected rays' way, behind the camera
    bulb = PointLight("Bulb", behind, (i, i, i), r)
    assert mirror_radiance(mirror_facing(points=[bulb])) == (pytest.approx(i / (math.pi * r * r), rel=1e-6), True)
    spot = dict(spot_size=math.radians(60), spot_blend=0.0, spot_falloff=falloff)
    facing = PointLight("Spot", behind, (i, i, i), r, spot_direction=(0, 1, 0), **spot)
    away = PointLight("Spot", behind, (i, i, i), r, spot_direction=(0, -1, 0), **spot)
    assert mirror_radiance(mirror_facing(points=[facing]))[0] == pytest.approx(i / (math.pi * r * r), rel=1e-4)
    assert mirror_radiance(mirror_facing(points=[away]))[0] == 0.0
    e, angle = 3.0, math.radians(20)
    sun = SunLight("Sun", (0.0, 1.0, 0.0), (e, e, e), angle)          # shining along +y, seen along -y
    assert mirror_radiance(mirror_facing(suns=[sun]))[0] == pytest.approx(e / (math.pi * math.sin(angle / 2) ** 2),
                                                                          rel=1e-6)
    # not seen: by the camera directly, by the report's estimator, outside the sun's disk
    direct = mirror_facing(points=[bulb])
    direct.camera = Camera.look_at((0, 0, 0), (0, -1, 0), up=(0, 0, 1), lens=2000.0)    # at the lamp itself
    assert mirror_radiance(direct)[0] == 0.0
    assert mirror_radiance(mirror_facing(points=[bulb]), "report") == (0.0, False)
    tilted = SunLight("Sun", (math.sin(0.2), math.cos(0.2), 0.0), (e, e, e), angle)   # 11.5 deg off
    assert mirror_radiance(mirror_facing(suns=[tilted]))[0] == 0.0


def test_light_visibility_flags_as_cycles_ray_visibility():
    """Diffuse visibility off: the lamp lights no diffuse surface; Glossy off: no mirror shows it."""
    i, r = 5.0, 0.3
    lit = floor_radiance(white_floor(points=[PointLight("Bulb", (0, 0, 2.0), (i, i, i), r)]), "mis", spp=16)[0]
    unlit = floor_radiance(white_floor(points=[PointLight("Bulb", (0, 0, 2.0), (i, i, i), r, lights_diffuse=False)]),
                           "mis", spp=16)[0]
    assert lit > 0.1 and unlit == 0.0
    hidden = PointLight("Bulb", (0.0, -1.0, 0.0), (i, i, i), r, visible_glossy=False)
    assert mirror_radiance(mirror_facing(points=[hidden])) == (0.0, True)     # glass would still show it
    hidden.visible_transmission = False
    assert mirror_radiance(mirror_facing(points=[hidden])) == (0.0, False)
    sun = SunLight("Sun", (0.0, 1.0, 0.0), (3.0, 3.0, 3.0), 0.3, visible_glossy=False, visible_transmission=True)
    assert mirror_radiance(mirror_facing(suns=[sun])) == (0.0, True)     # seen through glass only: none here
