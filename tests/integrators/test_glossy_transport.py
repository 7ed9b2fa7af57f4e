"""Light transport at glossy (microfacet) surfaces through the whole tracer
(engine/integrators/path_tracer.py with engine/materials/glossy.py):

* Veach's MIS scene in small (four glossy plates of rising roughness lit by four spheres of rising
  size and equal power): light samples only (`solid-angle`), BSDF samples only (`mis` with 0 shadow
  rays) and `mis` converge to the same image; a wrong MIS weight (the glossy pdf doubled on the
  light-sample side) does not;
* a white furnace: a white glossy sphere (Fresnel "none", colour 1) under a uniform white sky reads
  1 where compensated (Cycles 4.x multiscatter GGX) and E(mu) < 1 where not (the control);
* point, spot and sun lamps seen after a glossy bounce are counted once: by the shadow rays when
  they run, by the bounce ray when none do (both give the same image; counting both fails).
"""
import numpy as np
import pytest
from scipy.stats import norm

import engine.integrators.path_tracer
import engine.materials.glossy
from engine import RenderSettings, render
from engine.scene.model import DIFFUSE, GLOSSY, Camera, Material, PointLight, Quad, Scene, Sphere, SunLight

SILENT = dict(log=lambda *a: None)
ROUGHNESS = (0.05, 0.15, 0.35, 0.7)
EMITTER_RADII = (0.03, 0.1, 0.3, 0.6)


def settings(**kw):
    return RenderSettings(**{"threads": 2, "tile_size": 16, **kw})


def block_test(a, b, block=8, alpha=0.01, floor=0.0):
    """Largest |z| of the block-mean differences of two results, and the Sidak-corrected bound
    (as tests/integrators/test_mis.py).  `floor` is added to the standard error in quadrature:
    the far tails of a glossy lobe that one strategy cannot reach in the samples given (a BSDF
    sample meets a 0.03-radius sphere from the tail of a roughness-0.05 lobe with p < 1e-5, so
    its estimate there is 0 with variance 0) differ by less than it."""
    def blocks(x):
        h, w = x.shape[0] // block * block, x.shape[1] // block * block
        return x[:h, :w].reshape(h // block, block, w // block, block, 3).mean(axis=(1, 3))
    delta = blocks(a.image.astype(np.float64)) - blocks(b.image.astype(np.float64))
    var = (blocks(a.variance.astype(np.float64)) + blocks(b.variance.astype(np.float64))) / block ** 2
    z = np.abs(delta) / np.maximum(np.sqrt(var + floor ** 2), 1e-12)
    z_crit = norm.isf((1 - (1 - alpha) ** (1 / z.size)) / 2)
    return float(z.max()), float(z_crit)


TAIL = 2e-4            # the floor for the plates: 0.1 % of their brightest blocks (about 0.17)


def facing_quad(name, centre, normal, half_width, half_height, material_id):
    """A rectangle about `centre` with unit `normal`, its long side along x."""
    along = np.array([1.0, 0.0, 0.0])
    across = np.cross(normal, along)
    c = np.asarray(centre, dtype=np.float64)
    corners = np.array([c - half_width * along - half_height * across, c + half_width * along - half_height * across,
                        c + half_width * along + half_height * across, c - half_width * along + half_height * across])
    return Quad(name, corners, material_id)          # counter-clockwise about `normal`


def glossy_plates(resolution=(64, 40), pdf_scale=None):
    """Veach's MIS scene in small: plate i (roughness ROUGHNESS[i], nearest the camera first) is
    tilted to mirror the row of emitters into the camera; emitter j has radius EMITTER_RADII[j] and
    radiance 0.05 / r^2 (the same power)."""
    eye, lamps = np.array([0.0, -6.0, 3.0]), np.array([0.0, 3.0, 3.0])
    mats = [Material(f"Plate {r}", GLOSSY, (0.8, 0.8, 0.8), roughness=r) for r in ROUGHNESS]
    quads = []
    for i, y in enumerate((-1.5, -0.5, 0.5, 1.5)):
        c = np.array([0.0, y, 0.0])
        n = (eye - c) / np.linalg.norm(eye - c) + (lamps - c) / np.linalg.norm(lamps - c)
        quads.append(facing_quad(f"Plate {i}", c, n / np.linalg.norm(n), 2.5, 0.42, i))
    spheres = []
    for j, (x, r) in enumerate(zip((-1.8, -0.6, 0.6, 1.8), EMITTER_RADII)):
        mats.append(Material(f"Emitter {j}", DIFFUSE, (0, 0, 0), emission=(0.05 / r ** 2,) * 3))
        spheres.append(Sphere(f"Emitter {j}", (x, 3.0, 3.0), r, len(mats) - 1))
    camera = Camera.look_at(eye, (0, 0, 0), up=(0, 0, 1), lens=50.0)
    return Scene(camera, mats, quads=quads, spheres=spheres, resolution=resolution)


@pytest.fixture(scope="module")
def light_only():
    return render(glossy_plates(), settings(samples=1024, estimator="solid-angle", seed=1), **SILENT)


@pytest.mark.parametrize("case", [pytest.param("bsdf only", marks=pytest.mark.slow), "mis",
                                  pytest.param("mis 3 shadow rays", marks=pytest.mark.slow)])
def test_glossy_plates_light_bsdf_and_mis_converge_to_the_same_image(light_only, case):
    kw = {"bsdf only": dict(estimator="mis", shadow_rays=0, samples=1024),
          "mis": dict(estimator="mis", samples=512),
          "mis 3 shadow rays": dict(estimator="mis", shadow_rays=3, samples=256)}[case]
    other = render(glossy_plates(), settings(seed=2, **kw), **SILENT)
    assert other.stats["effects"]["glossy"] and other.stats["effects"]["mis"] == (case != "bsdf only")
    assert light_only.image.mean() > 0.01                 # the highlights are there
    z, z_crit = block_test(other, light_only, floor=TAIL)
    assert z < z_crit, (case, z, z_crit)


def test_a_wrong_glossy_mis_weight_is_caught(light_only, monkeypatch):
    """Control: the light samples weigh themselves with twice the glossy pdf (the BSDF samples keep
    the right one): the weights no longer sum to 1 and the highlights darken."""
    right = engine.materials.glossy.MicrofacetReflection.eval

    def doubled_pdf(self, si, wi):
        f_cos, pdf = right(self, si, wi)
        return f_cos, 2.0 * pdf
    monkeypatch.setattr(engine.materials.glossy.MicrofacetReflection, "eval", doubled_pdf)
    wrong = render(glossy_plates(), settings(estimator="mis", samples=512, seed=2), **SILENT)
    z, z_crit = block_test(wrong, light_only, floor=TAIL)
    assert z > z_crit, (z, z_crit)


def glossy_sphere_in_a_white_world(multiscatter=True, roughness=1.0):
    """A white glossy sphere (F = 1) filling the middle of the view under a uniform sky of
    radiance 1.  It is convex: each camera ray scatters once, so a pixel reads the lobe's albedo
    at its angle: 1 compensated, E(mu) uncompensated."""
    mats = [Material("Chrome", GLOSSY, (1.0, 1.0, 1.0), roughness=roughness, multiscatter=multiscatter)]
    camera = Camera.look_at((0, -4.0, 0), (0, 0, 0), up=(0, 0, 1), lens=60.0)
    return Scene(camera, mats, spheres=[Sphere("Ball", (0, 0, 0), 1.0, 0)], background=(1.0, 1.0, 1.0),
                 resolution=(32, 32))


def sphere_blocks(result, block=8):
    """Block means (4 x 4 blocks of 8 x 8) of the red channel over the 2 x 2 blocks inside the
    sphere's outline, and their standard errors."""
    inner = slice(8, 24)
    img = result.image[inner, inner, 0].astype(np.float64)
    var = result.variance[inner, inner, 0].astype(np.float64)
    means = img.reshape(2, block, 2, block).mean(axis=(1, 3))
    se = np.sqrt(var.reshape(2, block, 2, block).sum(axis=(1, 3))) / block ** 2
    return means, se


@pytest.mark.parametrize("estimator", ["mis", "solid-angle"])
def test_white_furnace_through_the_tracer(estimator):
    """Compensated: every block inside the sphere reads 1 within 1 % (and within 4 standard
    errors of the table's 1 +- 0.002); the world outside reads exactly 1."""
    result = render(glossy_sphere_in_a_white_world(), settings(samples=256, estimator=estimator, seed=3), **SILENT)
    assert result.stats["effects"]["world_light"]
    means, se = sphere_blocks(result)
    assert np.all(se < 0.0025), se
    assert np.all(np.abs(means - 1.0) < 0.01), means
    assert np.all(np.abs(means - 1.0) < 4 * se + 0.002), (means, se)
    assert result.image[0, 0, 0] == 1.0


def test_white_furnace_control_uncompensated_is_darker():
    """Control: without compensation the sphere loses the multiply scattered energy (at
    roughness 1 about half of it at normal incidence)."""
    result = render(glossy_sphere_in_a_white_world(multiscatter=False), settings(samples=256, seed=3), **SILENT)
    means, se = sphere_blocks(result)
    assert np.all(means < 0.8), means


def lamp_over_glossy_plate(lamp: str):
    """A glossy plate (roughness 0.3, colour 0.8) on z = 0 seen from (0, -3, 2), with a point lamp
    (radius 0.25), a spot lamp (the same, 90 degree cone) or a sun (angle 0.2 rad) whose mirror
    image falls in the view."""
    mats = [Material("Plate", GLOSSY, (0.8, 0.8, 0.8), roughness=0.3)]
    plate = Quad("Plate", np.array([(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], float), 0)
    camera = Camera.look_at((0, -3.0, 2.0), (0, 0, 0), up=(0, 0, 1), lens=30.0)
    points, suns = [], []
    if lamp in ("point", "spot"):
        spot = dict(spot_size=np.pi / 2, spot_blend=0.2, spot_direction=(0, -0.5, -1)) if lamp == "spot" else {}
        points.append(PointLight("Bulb", (0.0, 1.5, 1.5), (3.0, 3.0, 3.0), radius=0.25, **spot))
    else:
        suns.append(SunLight("Sun", (0.0, -1.0, -0.6), (3.0, 3.0, 3.0), angle=0.2))
    return Scene(camera, mats, quads=[plate], points=points, suns=suns, resolution=(32, 24))


@pytest.mark.parametrize("lamp", ["point", "spot", "sun"])
def test_lamps_after_a_glossy_bounce_are_counted_once(lamp):
    """With shadow rays the lamp is theirs (the bounce ray's lamp counts 0); with none the glossy
    bounce ray meets it (engine/lights/seen.py): the two images agree."""
    shadowed = render(lamp_over_glossy_plate(lamp), settings(samples=256, estimator="mis", seed=4), **SILENT)
    bounced = render(lamp_over_glossy_plate(lamp), settings(samples=2048, estimator="mis", shadow_rays=0, seed=5),
                     **SILENT)
    assert not shadowed.stats["effects"]["seen_lamps"] and bounced.stats["effects"]["seen_lamps"]
    assert shadowed.image.mean() > 0.02
    z, z_crit = block_test(bounced, shadowed, floor=1e-3)     # 0.1 % of the highlight's blocks
    assert z < z_crit, (lamp, z, z_crit)


def test_lamps_after_a_glossy_bounce_control_counted_twice(monkeypatch):
    """Control: glossy bounce rays that also count the lamp the shadow rays found (the lamps
    seen, and no prev_delta filter): the image is brighter than the reference."""
    tracer = engine.integrators.path_tracer.PathTracer
    scene = lamp_over_glossy_plate("point")
    reference = render(scene, settings(samples=256, estimator="mis", seed=4), **SILENT)
    init, seen = tracer.__init__, tracer.lamps_seen

    def init_seeing(self, *args, **kw):
        init(self, *args, **kw)
        self.seen_lamps = self.lights.seen

    def seen_unfiltered(self, p, hits):
        use_nee, self.use_nee = self.use_nee, False
        try:
            seen(self, p, hits)
        finally:
            self.use_nee = use_nee
    monkeypatch.setattr(tracer, "__init__", init_seeing)
    monkeypatch.setattr(tracer, "lamps_seen", seen_unfiltered)
    doubled = render(scene, settings(samples=256, estimator="mis", seed=6), **SILENT)
    z, z_crit = block_test(doubled, reference, floor=1e-3)
    assert z > z_crit, (z, z_crit)
