"""engine/lights/seen.py: point, spot and sun lights that mirror and glass rays meet.

A bulb of radius r is a sphere of radiance I / (pi r^2) (a spot's falloff for the direction from
the light to the ray's origin); a sun of angle theta a disk of angular radius theta / 2 and radiance
E / (pi sin^2(theta / 2)).  Both are checked by what they give a receiver: the irradiance, by Monte
Carlo over a cone of directions wider than the lamp, is I / d^2 for the bulb and E for the sun (on
their axes).  Control: the radiance E / Omega (uniform over the sun's solid angle) gives another
irradiance, which the same interval rejects.  Also: what blocks them (a nearer hit, a ray from
inside the bulb, the visibility flags) and when there is nothing to see.
"""
import numpy as np
import pytest

from engine.lights.seen import SeenLamps
from engine.sampling.warps import uniform_cone
from engine.scene.model import PointLight, Scene, SunLight

N = 200_000


def scene(points=(), suns=()):
    return Scene(None, [], points=list(points), suns=list(suns))


def rays_in_cone(axis, half_angle, m, seed):
    """Unit directions uniform in the cone about `axis`, and the cone's solid angle."""
    rng = np.random.default_rng(seed)
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    one_minus = 1.0 - np.cos(half_angle)
    d, _ = uniform_cone(rng.random(m), rng.random(m), np.tile(axis[:, None], m), np.full(m, one_minus))
    return d, 2.0 * np.pi * one_minus


def irradiance(seen, origin, axis, half_angle, m=N, seed=0, transmission=False):
    """(E, its standard error) at `origin`, normal `axis`: E = integral of L cos over the cone."""
    d, omega = rays_in_cone(axis, half_angle, m, seed)
    o = np.tile(np.asarray(origin, dtype=np.float64)[:, None], m)
    le = seen.radiance(o, d, np.full(m, np.inf), np.full(m, transmission))
    axis = np.asarray(axis) / np.linalg.norm(axis)
    values = le.mean(axis=0) * (axis @ d) * omega
    return values.mean(), values.std() / np.sqrt(m)


def test_nothing_to_see():
    assert SeenLamps.of(scene()) is None
    assert SeenLamps.of(scene([PointLight("P", (0, 0, 1), (1.0, 1.0, 1.0))])) is None          # no radius
    assert SeenLamps.of(scene([PointLight("P", (0, 0, 1), (0.0, 0.0, 0.0), radius=0.1)])) is None   # dark
    assert SeenLamps.of(scene(suns=[SunLight("S", (0, 0, -1), (1.0, 1.0, 1.0))])) is None      # a delta sun
    hidden = PointLight("P", (0, 0, 1), (1.0, 1.0, 1.0), radius=0.1, visible_glossy=False, visible_transmission=False)
    assert SeenLamps.of(scene([hidden])) is None


def test_a_bulb_gives_its_irradiance_intensity_over_distance_squared():
    """A sphere of radius r and radiance I / (pi r^2) at distance d: E = I / d^2 on its axis."""
    intensity, r, dist = 3.0, 0.1, 0.7
    seen = SeenLamps.of(scene([PointLight("Bulb", (0.0, 0.0, dist), (intensity,) * 3, radius=r)]))
    e, err = irradiance(seen, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 1.5 * np.arcsin(r / dist))
    assert abs(e - intensity / dist ** 2) < 5 * err


def test_a_sun_gives_its_irradiance_and_the_uniform_normalisation_would_not():
    irr, angle = 2.0, 1.2
    sun = SunLight("Sun", (0.0, 0.0, -1.0), (irr,) * 3, angle)
    seen = SeenLamps.of(scene(suns=[sun]))
    e, err = irradiance(seen, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), angle)     # a cone wider than the disk
    assert abs(e - irr) < 5 * err
    # Control: radiance E / Omega over the disk gives E (1 + cos(angle / 2)) / 2: 9 % less here.
    alpha = angle / 2
    uniform = irr / (2 * np.pi * (1 - np.cos(alpha))) / (irr / (np.pi * np.sin(alpha) ** 2))
    assert abs(e * uniform - irr) > 5 * err * uniform


def test_the_lamps_radiance_and_what_blocks_it():
    intensity, r = (2.0, 4.0, 6.0), 0.2
    seen = SeenLamps.of(scene([PointLight("Bulb", (0.0, 0.0, 1.0), intensity, radius=r)]))
    o = np.zeros((3, 4))
    o[:, 3] = [0.0, 0.0, 0.95]                                              # inside the bulb
    d = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]).T
    tmax = np.array([np.inf, 0.5, np.inf, np.inf])                          # ray 1: a hit before the bulb
    le = seen.radiance(o, d, tmax, np.zeros(4, bool))
    assert np.allclose(le[:, 0], np.array(intensity) / (np.pi * r * r))
    assert not le[:, 1:].any()                                              # blocked, missed, inside


def test_visibility_flags_choose_the_rays_that_see_a_lamp():
    bulb = PointLight("Bulb", (0.0, 0.0, 1.0), (1.0, 1.0, 1.0), radius=0.2, visible_glossy=False)
    sun = SunLight("Sun", (0.0, 0.0, -1.0), (1.0, 1.0, 1.0), 0.1, visible_transmission=False)
    seen = SeenLamps.of(scene([bulb], [sun]))
    o, d = np.zeros((3, 2)), np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]).T
    glossy = seen.radiance(o, d, np.full(2, np.inf), np.array([False, False]))
    through_glass = seen.radiance(o, d, np.full(2, np.inf), np.array([True, True]))
    sun_le = 1.0 / (np.pi * np.sin(0.05) ** 2)
    assert np.allclose(glossy, sun_le)                                       # the sun only
    assert np.allclose(through_glass, 1.0 / (np.pi * 0.04))                  # the bulb only
    # A sun is met only by rays that leave the scene.
    assert not seen.radiance(o, d, np.array([5.0, 5.0]), np.array([False, False])).any()


@pytest.mark.parametrize("falloff", ["smoothstep", "cosine-smoothstep"])
def test_a_spot_shows_the_falloff_of_the_direction_to_the_rays_origin(falloff):
    size, blend = 1.0, 0.4
    spot = PointLight("Spot", (0.0, 0.0, 1.0), (1.0, 1.0, 1.0), radius=0.1, spot_size=size, spot_blend=blend,
                      spot_direction=(0.0, 0.0, -1.0), spot_falloff=falloff)
    seen = SeenLamps.of(scene([spot]))
    angles = np.array([0.0, 0.3, 0.45, 0.6])                               # of the origin, seen from the lamp
    o = np.stack([np.sin(angles), np.zeros(4), 1.0 - np.cos(angles)])       # one unit from the lamp
    d = np.array([[0.0], [0.0], [1.0]]) - o
    d /= np.linalg.norm(d, axis=0)
    le = seen.radiance(o, d, np.full(4, np.inf), np.zeros(4, bool))[0] * (np.pi * 0.01)
    c, c0 = np.cos(angles), np.cos(size / 2)
    t = np.clip((c - c0) / ((1 - c0) * blend), 0, 1)
    a = np.where(c > c0, t * t * (3 - 2 * t), 0.0)
    assert np.allclose(le, c * a if falloff == "cosine-smoothstep" else a, atol=1e-12)
    assert le[0] > 0 and le[-1] == 0                                        # on the axis; outside the cone


def loop_radiance(seen, o, d, tmax, transmission):
    """The definition the vectorised radiance keeps: one lamp after the other, each adding the
    emission of the rays that meet it (bulbs, then suns; the loop SeenLamps had before its pairs)."""
    from engine.core.vec import dot
    from engine.geometry.shapes.spheres import intersect_sphere
    total = np.zeros(o.shape)
    visible = np.where(transmission[None, :], seen.visible["transmission"][:, None], seen.visible["glossy"][:, None])
    for slot, j in enumerate(seen.bulbs):
        c, r = seen.points.center[:, j], float(seen.points.radius[j])
        away = o - c[:, None]
        outside = dot(away, away) > r * r
        t = intersect_sphere(o, d, c, r, tmax)
        hit = np.flatnonzero(visible[slot] & outside & (t < tmax))
        if len(hit):
            emitted = away.take(hit, axis=1)
            emitted = emitted / np.sqrt(dot(emitted, emitted))
            total[:, hit] += seen.points.le(np.full(len(hit), j), None, -emitted)
    if seen.suns is not None:
        escaped = np.isinf(tmax)
        for k in range(seen.suns.count):
            rays = np.flatnonzero(visible[len(seen.bulbs) + k] & escaped)
            if len(rays):
                total[:, rays] += seen.suns.le(np.full(len(rays), k), None, d.take(rays, axis=1))
    return total


@pytest.mark.parametrize("bulbs, suns", [(60, 3), (5, 0), (0, 4), (200, 1)])
def test_the_pairs_sum_as_the_loop_over_lamps_bit_for_bit(bulbs, suns):
    """Overlapping bulbs (of both visibilities, some spots) and wide suns seen by rays from inside
    and outside the cloud, some stopped by a nearer hit: the same sums to the last bit.  Control:
    summing the same lamps in another order (the bulbs reversed) changes some last bits."""
    rng = np.random.default_rng(bulbs + suns)
    points = [PointLight(f"P{i}", tuple(rng.uniform(-1, 1, 3)), tuple(rng.uniform(0.1, 5, 3)),
                         radius=float(rng.uniform(0.05, 0.4)), visible_glossy=bool(i % 3),
                         visible_transmission=bool(i % 4),
                         **({"spot_size": 1.2, "spot_blend": 0.3, "spot_direction": (0.0, 0.0, -1.0)} if i % 5 == 0
                            else {})) for i in range(bulbs)]
    sun_lights = [SunLight(f"S{k}", tuple(rng.normal(size=3)), tuple(rng.uniform(0.5, 3, 3)), 1.5 + 0.3 * k,
                           visible_transmission=bool(k % 2)) for k in range(suns)]
    seen = SeenLamps.of(scene(points, sun_lights))
    m = 20_000
    o = rng.uniform(-1.5, 1.5, (3, m))
    d = rng.normal(size=(3, m))
    d /= np.sqrt((d * d).sum(axis=0))
    tmax = np.where(rng.random(m) < 0.3, rng.uniform(0.1, 2.0, m), np.inf)
    transmission = rng.random(m) < 0.5
    vectorised, loop = seen.radiance(o, d, tmax, transmission), loop_radiance(seen, o, d, tmax, transmission)
    assert (vectorised > 0).any(axis=0).mean() > 0.01
    assert np.array_equal(vectorised, loop)
    if bulbs > 20:
        reversed_bulbs = loop_radiance(SeenLamps.of(scene(points[::-1], sun_lights)), o, d, tmax, transmission)
        assert not np.array_equal(reversed_bulbs, loop) and np.allclose(reversed_bulbs, loop, rtol=1e-14)
