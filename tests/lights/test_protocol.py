"""Every light kind against the light protocol (engine/lights/protocol.py): the methods agree with
each other, over random receivers and all the kind's lights.

* sample_li: unit directions, finite non-negative radiance, a pdf that pdf_li gives again at the
  sampled point (direction), points inside the light's bounds, at infinity one unit away;
* le: the sample's radiance where the light faces the receiver, 0 behind a one-sided light;
* power, report_power: positive and finite per light;
* sample_emission: rays that leave the light from its bounds, whose flux radiance |cos| / (pdf_pos pdf_dir)
  averages to power() (spot lights: at most), or NotImplementedError naming the kind.

Controls: the same check fails a kind whose pdf_li is off by 0.1 %, one whose power is off by 1 %,
one whose sample_li returns directions that are not unit, and one whose le ignores the side.
"""
import numpy as np
import pytest

from engine.lights.protocol import EmissionSample, LightBounds, LightKind, LiSample

from tests.lights.kinds import EVERY_KIND

M = 20_000


def receivers(rng, m=M):
    """Receivers x in a box around the lights (none in a light's plane) and random unit normals."""
    x = rng.uniform(-3.0, 3.0, (3, m)) + np.array([[0.0], [0.0], [1.0]])
    n = rng.normal(size=(3, m))
    return x, n / np.sqrt((n * n).sum(axis=0))


def unit(d):
    return np.abs(np.sqrt((d * d).sum(axis=0)) - 1.0).max() < 1e-12


def check_kind(kind, seed=0):
    """Assert everything the protocol promises of `kind`; returns the number of samples checked."""
    assert isinstance(kind, LightKind)
    rng = np.random.default_rng(seed)
    x, n = receivers(rng)
    idx = rng.integers(0, kind.count, M)
    s = kind.sample_li(x, idx, rng.random(M), rng.random(M), n)
    assert isinstance(s, LiSample)
    assert s.point.shape == s.direction.shape == s.normal.shape == s.radiance.shape == (3, M)
    assert np.isfinite(s.pdf).all() and (s.pdf >= 0).all(), "pdf not finite and non-negative"
    ok = np.flatnonzero(s.pdf > 0)
    assert len(ok) > 0.9 * M, "too few samples"
    d = s.direction[:, ok]
    assert unit(d), "directions are not unit"
    assert np.isfinite(s.radiance).all() and (s.radiance >= 0).all(), "radiance not finite and non-negative"
    # pdf_li gives the sampled density again (MIS): at the point, or for the direction at infinity.
    again = kind.pdf_li(x[:, ok], idx[ok], s.point[:, ok], n[:, ok], d)
    assert np.allclose(again, s.pdf[ok], rtol=1e-9, atol=0), "pdf_li differs from the sample's pdf"
    # Power per light.
    for power in (kind.power(), kind.report_power()):
        assert power.shape == (kind.count,) and np.isfinite(power).all() and (power > 0).all(), "power"
    bounds = kind.bounds()
    if kind.at_infinity:
        assert bounds is None
        assert np.isinf(s.distance).all() and np.array_equal(s.point, x + s.direction)
        assert np.array_equal(s.normal, -s.direction)
        # le: a ray leaving the scene along the sampled direction gets the sample's radiance (a
        # delta sun: 0, no ray meets it).
        le = kind.le(idx[ok], None, d)
        met = le.any(axis=0)
        assert np.array_equal(le[:, met], s.radiance[:, ok][:, met]) and not le[:, ~met].any(), "le differs"
        assert met.mean() > 0.3, "le is 0 for the sampled directions"
    else:
        assert isinstance(bounds, LightBounds)
        assert np.allclose(s.point[:, ok] - x[:, ok], d * s.distance[ok], rtol=0, atol=1e-9)
        check_in_bounds(bounds, idx[ok], s.point[:, ok], s.normal[:, ok])
        # le: what a ray along the sampled direction gets where it meets the light.
        le = kind.le(idx[ok], s.point[:, ok], d)
        front = ~kind.one_sided[idx[ok]] | ((s.normal[:, ok] * d).sum(axis=0) < 0)
        assert np.array_equal(le[:, front], s.radiance[:, ok][:, front]), "le differs from the sample's radiance"
        assert not le[:, ~front].any(), "a one-sided light shines from behind"
    check_sample_emission(kind, rng)
    return len(ok)


def check_in_bounds(bounds, idx, point, normal):
    c, r = bounds.center[:, idx], bounds.radius[idx]
    assert (np.sqrt(((point - c) ** 2).sum(axis=0)) <= r * (1 + 1e-9) + 1e-12).all(), "a point outside the bounds"
    assert ((normal * bounds.axis[:, idx]).sum(axis=0) >= bounds.cos_o[idx] - 1e-9).all(), "a normal outside the cone"


def check_sample_emission(kind, rng, m=M):
    idx = np.repeat(np.arange(kind.count), m // kind.count)
    u = [rng.random(len(idx)) for _ in range(4)]
    try:
        e = kind.sample_emission(idx, *u)
    except NotImplementedError as exc:
        assert kind.name in str(exc), "NotImplementedError without the kind's name"
        assert kind.at_infinity, "only lights at infinity may not emit rays yet"
        return
    assert isinstance(e, EmissionSample)
    assert unit(e.direction) and unit(e.normal), "sample_emission: directions or normals are not unit"
    cos = (e.direction * e.normal).sum(axis=0)
    assert (cos >= 0).all(), "a ray leaves from the other side"
    assert (e.pdf_pos > 0).all() and (e.pdf_dir > 0).all() and np.isfinite(e.pdf_pos * e.pdf_dir).all()
    if kind.at_infinity:                # from a disk outside the scene's sphere, facing into it
        r = kind.scene_radius
        assert (np.sqrt((e.origin ** 2).sum(axis=0)) >= r * (1 - 1e-9)).all(), "a ray starts inside the scene"
        assert np.allclose(((e.origin + 2 * r * e.normal) * e.normal).sum(axis=0), 0.0, atol=1e-9 * r)
        le = kind.le(idx, None, -e.direction)
        met = le.any(axis=0)            # a delta sun: no ray meets it, its rays carry E
        assert np.array_equal(le[:, met], e.radiance[:, met]), "sample_emission's radiance is not le"
    else:
        check_in_bounds(kind.bounds(), idx, e.origin, e.normal)
        # A receiver on the ray sees the light with the radiance the ray carries.
        assert np.array_equal(kind.le(idx, e.origin, -e.direction), e.radiance), "sample_emission's radiance is not le"
    flux = e.radiance.mean(axis=0) * cos / (e.pdf_pos * e.pdf_dir)
    mean = np.bincount(idx, flux) / np.bincount(idx)
    sigma = np.sqrt(np.bincount(idx, (flux - mean[idx]) ** 2) / np.bincount(idx) / np.bincount(idx))
    power = kind.power()
    spot = getattr(kind, "spot_slot", np.full(kind.count, -1)) >= 0        # falloff: below 4 pi I
    close = np.abs(mean - power) <= 5 * sigma + 1e-9 * power
    assert (close | spot).all() and (mean[spot] <= power[spot] * (1 + 1e-9)).all(), "flux of sample_emission != power"


@pytest.mark.parametrize("name", list(EVERY_KIND))
def test_every_kind_keeps_the_protocol(name):
    assert check_kind(EVERY_KIND[name]()) > 0.9 * M


@pytest.mark.parametrize("name", list(EVERY_KIND))
def test_the_area_sampling_branch_keeps_it_too(name):
    """solid_angle=False (the report's estimator): sample_li and pdf_li still agree."""
    kind = EVERY_KIND[name]()
    rng = np.random.default_rng(1)
    x, n = receivers(rng)
    idx = rng.integers(0, kind.count, M)
    s = kind.sample_li(x, idx, rng.random(M), rng.random(M), n, solid_angle=False)
    ok = s.pdf > 0
    assert ok.mean() > 0.9
    again = kind.pdf_li(x[:, ok], idx[ok], s.point[:, ok], n[:, ok], s.direction[:, ok], solid_angle=False)
    assert np.allclose(again, s.pdf[ok], rtol=1e-9, atol=0)


# -- controls: the check fails kinds that break the protocol -----------------------------------
class Broken:
    """A kind that delegates to `kind` except for one method, replaced by `method`."""

    def __init__(self, kind, name, method):
        self.kind, self.name_of_broken, self.method = kind, name, method

    def __getattr__(self, attr):
        if attr == self.name_of_broken:
            return lambda *a, **k: self.method(getattr(self.kind, attr), *a, **k)
        return getattr(self.kind, attr)


def pdf_off(pdf_li, *a, **k):
    return pdf_li(*a, **k) * 1.001


def power_off(power):
    return power() * 1.01


def not_unit(sample_li, *a, **k):
    s = sample_li(*a, **k)
    s.direction = s.direction * (1 + 1e-9)
    return s


def le_two_sided(le, idx, point, direction):
    return le(idx, point, -direction) + le(idx, point, direction)


@pytest.mark.parametrize("name, method, fn, message", [
    ("parallelograms", "pdf_li", pdf_off, "pdf_li differs"), ("world", "pdf_li", pdf_off, "pdf_li differs"),
    ("spheres", "power", power_off, "flux of sample_emission"), ("triangles", "sample_li", not_unit, "not unit"),
    ("parallelograms", "le", le_two_sided, "le differs")])
def test_the_check_fails_a_kind_that_breaks_the_protocol(name, method, fn, message):
    with pytest.raises(AssertionError, match=message):
        check_kind(Broken(EVERY_KIND[name](), method, fn))
