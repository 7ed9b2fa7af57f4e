"""Mixed materials (engine/materials/mix.py): the protocol's contract, the χ² of the mixture
sampler against its pdf (diffuse + glossy, glossy + mirror, diffuse + glass), weights from Fresnel
and Layer Weight factors, delta leaves and the medium stack, texture factors, scene files and
validation.  Controls: a pdf with the wrong closure probabilities fails the χ²; a mix whose
factors are ignored gives another image."""
import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from engine import RenderSettings
from engine.core.errors import SceneError
from engine.materials.fresnel import fresnel_exact
from engine.materials.media import MediumStack
from engine.materials.mix import MixBSDF, factor_value
from engine.materials.protocol import BSDFFlags, ShadingPoint
from engine.materials.specular import refract_cos
from engine.materials.table import KIND_CODE, MaterialTable
from engine.scene.files import load_scene, save_scene
from engine.scene.model import (DIFFUSE, GLASS, GLOSSY, MIRROR, MIX, Material, Mix, MixFactor, MixLeaf,
                                with_mix_leaves)
from engine.scene.textures import TextureSlot
from tests.chi_square import ALPHA, sphere_chi2
from tests.materials.test_bsdf_contract import conserves_energy, hits, reciprocal, sample_matches_eval

NORMAL = np.array([0.0, 0.0, 1.0])


def leaf(material, *factors):
    return MixLeaf(material, list(factors))


def const(value, invert=False):
    return MixFactor(value=value, invert=invert)


def mixed(*leaves, name="Mix"):
    return Material(name, MIX, mix=Mix(list(leaves)))


def diffuse(color=(0.8, 0.5, 0.2)):
    return Material("Diffuse", DIFFUSE, color)


def glossy(roughness=0.3, color=(0.9, 0.9, 0.9)):
    return Material("Glossy", GLOSSY, color, roughness=roughness)


MIXES = {
    "diffuse+glossy": mixed(leaf(diffuse(), const(0.4, invert=True)), leaf(glossy(), const(0.4))),
    "glossy+mirror": mixed(leaf(glossy(0.5), const(0.5, invert=True)),
                           leaf(Material("Mirror", MIRROR, (0.9, 0.9, 0.9)), const(0.5))),
    "diffuse+glass": mixed(leaf(diffuse(), const(0.5, invert=True)),
                           leaf(Material("Glass", GLASS, (1.0, 1.0, 1.0), ior=1.5), const(0.5))),
    "fresnel diffuse+glossy": mixed(leaf(diffuse(), MixFactor("fresnel", ior=1.45, invert=True)),
                                    leaf(glossy(0.2), MixFactor("fresnel", ior=1.45))),
    "layer weight": mixed(leaf(diffuse(), MixFactor("layer_weight", blend=0.3, output="facing", invert=True)),
                          leaf(glossy(0.25), MixFactor("layer_weight", blend=0.3, output="facing"))),
}


def mix_bsdf(material, settings=None, cls=MixBSDF):
    table = MaterialTable([material], settings or RenderSettings(fresnel="exact"))
    bsdf = table.bsdfs[KIND_CODE[MIX]]
    if cls is not MixBSDF:
        bsdf.__class__ = cls
    return bsdf


def incidence(mu, phi=0.3):
    s = np.sqrt(1.0 - mu * mu)
    return np.array([s * np.cos(phi), s * np.sin(phi), mu])


def facing_hits(wo, n, outward=1.0):
    def tile(v):
        return np.tile(np.asarray(v, dtype=np.float64)[:, None], (1, n))
    return ShadingPoint(tile(wo), tile(NORMAL), tile(NORMAL), tile(NORMAL * outward), np.ones((3, n)),
                        np.zeros(n, dtype=np.int64))


def sampler(bsdf, wo, seed=17):
    """(sample, pdf) of the non-delta samples for sphere_chi2 (delta samples count in no cell)."""
    def sample(u):
        n = u.shape[1]
        s = bsdf.sample(facing_hits(wo, n), np.random.default_rng(seed).random(n), (u[0], u[1]))
        keep = ((s.flags & BSDFFlags.DELTA) == 0) & (s.pdf > 0)
        return np.where(keep, s.wi, 0.0)

    def pdf(d):
        return bsdf.pdf(facing_hits(wo, d.shape[1]), d)
    return sample, pdf


# -- the contract ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(MIXES))
def test_sample_is_eval_over_pdf_and_reciprocal(name):
    bsdf = mix_bsdf(MIXES[name])
    assert sample_matches_eval(bsdf, hits(31), 31)
    # Energy with white, uncompensated leaves (coloured leaves picked by their albedo estimate may
    # weigh one channel's sample above 1, as Cycles' closure sampling does, and so does Cycles' energy
    # compensation of a glossy leaf; the albedo stays below 1).
    assert conserves_energy(mix_bsdf(whitened(MIXES[name])), 33, n=50_000)


def whitened(material):
    return mixed(*(MixLeaf(dataclasses.replace(leaf.material, color=(1.0, 1.0, 1.0), multiscatter=False), leaf.factors)
                   for leaf in material.mix.leaves))


def test_a_mix_of_reciprocal_leaves_with_constant_weights_is_reciprocal():
    """(Cycles' energy compensation is not reciprocal, nor are view-dependent weights: left out.)"""
    uncompensated = dataclasses.replace(glossy(0.3), multiscatter=False)
    assert reciprocal(mix_bsdf(mixed(leaf(diffuse(), const(0.6)), leaf(uncompensated, const(0.4)))), 32)


def test_flags_are_the_union_of_the_leaves():
    assert mix_bsdf(MIXES["glossy+mirror"]).flags == (BSDFFlags.GLOSSY | BSDFFlags.REFLECTION | BSDFFlags.DELTA)
    glass = mix_bsdf(MIXES["diffuse+glass"]).flags
    assert glass & BSDFFlags.TRANSMISSION and glass & BSDFFlags.DIFFUSE
    delta_only = mix_bsdf(mixed(leaf(Material("M", MIRROR)), leaf(Material("G", GLASS))))
    assert not (delta_only.flags & (BSDFFlags.DIFFUSE | BSDFFlags.GLOSSY))


# -- χ² ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name,mu", [("diffuse+glossy", 0.6), ("glossy+mirror", 0.8), ("diffuse+glass", 0.5),
                                     ("fresnel diffuse+glossy", 0.3), ("layer weight", 0.7)])
def test_mixture_sampler_matches_its_pdf(name, mu):
    sample, pdf = sampler(mix_bsdf(MIXES[name]), incidence(mu))
    p, dof = sphere_chi2(sample, pdf, n=60_000, z_bins=24, phi_bins=48, seed=7)
    assert dof > 50 and p > ALPHA, (p, dof)


class WeightOnlyPdf(MixBSDF):
    """Control: the pdf weights the closures by w_c alone while `sample` picks by w_c x albedo."""
    def pdf(self, si, wi):
        hit, row, weight, prob, _, leaves = self._pairs(si)
        _, pdf = self._eval_pairs(row, leaves, wi, hit)
        w_sum = np.bincount(hit, weights=weight, minlength=len(si))
        return np.bincount(hit, weights=pdf * weight / w_sum.take(hit), minlength=len(si))


def test_chi2_rejects_closure_probabilities_that_mismatch_the_sampler():
    material = mixed(leaf(diffuse((0.9, 0.9, 0.9)), const(0.5, invert=True)),
                     leaf(glossy(0.3, (0.1, 0.1, 0.1)), const(0.5)))
    sample, pdf = sampler(mix_bsdf(material, cls=WeightOnlyPdf), incidence(0.6))
    assert sphere_chi2(sample, pdf, n=60_000, z_bins=24, phi_bins=48, seed=7)[0] < 1e-6
    sample, pdf = sampler(mix_bsdf(material), incidence(0.6))                 # the real one passes
    assert sphere_chi2(sample, pdf, n=60_000, z_bins=24, phi_bins=48, seed=7)[0] > ALPHA


# -- weights and delta leaves ------------------------------------------------------------------------------
def test_fresnel_and_layer_weight_factors_are_cycles_nodes():
    mus = np.array([1.0, 0.7, 0.3, 0.05])
    n = len(mus)
    wo = np.stack([np.sqrt(1 - mus ** 2), np.zeros(n), mus])
    front = ShadingPoint(wo, np.tile(NORMAL[:, None], (1, n)), np.tile(NORMAL[:, None], (1, n)),
                         np.tile(NORMAL[:, None], (1, n)), np.ones((3, n)), np.zeros(n, dtype=np.int64))
    back = dataclasses.replace(front, normal=-front.normal)

    def exact(mu, eta):                                 # the reflectance entering a medium of ratio eta
        cos_t, tir = refract_cos(mu, np.full(len(mu), 1.0 / eta))
        return fresnel_exact(mu, cos_t, np.full(len(mu), 1.0 / eta), tir)
    assert np.allclose(factor_value(MixFactor("fresnel", ior=1.45), front), exact(mus, 1.45), atol=1e-12)
    assert np.allclose(factor_value(MixFactor("fresnel", ior=1.45), back), exact(mus, 1 / 1.45), atol=1e-12)
    assert np.allclose(factor_value(MixFactor("fresnel", ior=1.45, invert=True), front), 1 - exact(mus, 1.45))
    # Layer Weight: Fresnel output of blend b is the Fresnel of IOR 1 / (1 - b); Facing is 1 - mu^(2b).
    assert np.allclose(factor_value(MixFactor("layer_weight", blend=0.4), front), exact(mus, 1 / 0.6), atol=1e-12)
    assert np.allclose(factor_value(MixFactor("layer_weight", blend=0.5, output="facing"), front), 1 - mus)
    assert np.allclose(factor_value(MixFactor("layer_weight", blend=0.25, output="facing"), front), 1 - mus ** 0.5)
    assert np.allclose(factor_value(MixFactor("layer_weight", blend=0.75, output="facing"), front), 1 - mus ** 2)
    assert np.all(factor_value(const(3.0), front) == 3.0)                # Add Shader weights are not clamped


def test_weights_from_fresnel_reach_the_eval():
    """eval of (1 - F) diffuse + F glossy at a given direction is the weighted sum of the leaves."""
    material = MIXES["fresnel diffuse+glossy"]
    bsdf = mix_bsdf(material)
    si = hits(41, n=500)
    wi = hits(42, n=500).wo
    f_mix, _ = bsdf.eval(si, wi)
    fresnel = factor_value(MixFactor("fresnel", ior=1.45), si)
    table = bsdf.table
    parts = []
    for leaf_id in (1, 2):
        at = dataclasses.replace(si, material=np.full(len(si), leaf_id), color=table.color.take(
            np.full(len(si), leaf_id), axis=1))
        parts.append(table.bsdfs[table.kind[leaf_id]].eval(at, wi)[0])
    assert np.allclose(f_mix, (1 - fresnel) * parts[0] + fresnel * parts[1], rtol=1e-12, atol=1e-15)


def test_delta_leaf_samples_carry_weight_over_probability():
    """White diffuse 0.3 + white mirror 0.7: every sample's value is 1 (weights over probabilities),
    the mirror share of samples is its probability 0.7, and eval sees only the diffuse leaf."""
    material = mixed(leaf(diffuse((1, 1, 1)), const(0.3)), leaf(Material("M", MIRROR, (1, 1, 1)), const(0.7)))
    bsdf = mix_bsdf(material)
    n = 20_000
    rng = np.random.default_rng(3)
    si = facing_hits(incidence(0.5), n)
    s = bsdf.sample(si, rng.random(n), (rng.random(n), rng.random(n)))
    delta = (s.flags & BSDFFlags.DELTA) != 0
    assert abs(delta.mean() - 0.7) < 4 * np.sqrt(0.21 / n)
    assert np.allclose(s.value, 1.0, rtol=1e-12)
    assert np.allclose(s.pdf[delta], 0.7)
    f_cos, pdf = bsdf.eval(si, s.wi)
    assert np.allclose(pdf[~delta], 0.3 * s.wi[2, ~delta] / np.pi)


def test_glass_leaf_crosses_the_medium_stack():
    material = MIXES["diffuse+glass"]
    bsdf = mix_bsdf(material)
    n = 4000
    rng = np.random.default_rng(5)
    si = facing_hits(incidence(0.9), n)
    si.media = MediumStack.empty(n)
    s = bsdf.sample(si, rng.random(n), (rng.random(n), rng.random(n)))
    through = (s.flags & BSDFFlags.TRANSMISSION) != 0
    assert 0.55 < through.mean() < 0.7            # p_glass = 0.5 / (0.5 x 0.5 + 0.5) times T = 0.96
    assert np.all(si.media.depth[through] == 1) and np.all(si.media.media[through, 0] == 1.5)
    assert np.all(si.media.depth[~through] == 0)


def test_a_hit_with_all_weights_zero_ends_its_path():
    material = mixed(leaf(diffuse(), const(0.0)), leaf(glossy(), const(0.0)))
    s = mix_bsdf(material).sample(facing_hits(incidence(0.5), 10), np.full(10, 0.5), (np.full(10, 0.3),) * 2)
    assert np.all(s.value == 0.0) and np.all(np.isfinite(s.wi))


class FakeLookup:
    """A texture factor's values at the hits (what HitLookup gives); its scene's textures colour no leaf."""
    textures = SimpleNamespace(attributes=None, has_color=np.zeros(64, bool))

    def __init__(self, values):
        self.values = np.asarray(values, dtype=np.float64)

    def take(self, index):
        return FakeLookup(self.values.take(index))

    def __getitem__(self, span):
        return FakeLookup(self.values[span])

    def color(self, color, material):
        return color

    def factor(self, slot, fallback):
        return self.values


def test_a_texture_factor_weighs_each_hit_by_its_lookup():
    slot = TextureSlot(0, node="Mask")
    material = mixed(leaf(diffuse((1, 1, 1)), MixFactor("texture", value=0.5, texture=slot, invert=True)),
                     leaf(diffuse((0, 0, 0)), MixFactor("texture", value=0.5, texture=slot)))
    bsdf = mix_bsdf(material)
    mask = np.array([0.0, 0.25, 1.0, 1.7])                    # clamped to 1 as a Mix Shader's Fac
    si = facing_hits(incidence(1.0), 4)
    wi = np.tile(NORMAL[:, None], (1, 4))
    si.lookup = FakeLookup(mask)
    f_cos, _ = bsdf.eval(si, wi)
    assert np.allclose(f_cos[0], (1 - np.minimum(mask, 1)) / np.pi)
    si.lookup = None                                           # no textures: the fallback value
    assert np.allclose(bsdf.eval(si, wi)[0][0], 0.5 / np.pi)


# -- the scene model -------------------------------------------------------------------------------------
def test_leaves_are_numbered_after_the_scene_materials():
    materials = [diffuse(), MIXES["diffuse+glossy"], MIXES["glossy+mirror"]]
    expanded, ids = with_mix_leaves(materials)
    assert ids == [[], [3, 4], [5, 6]] and len(expanded) == 7
    assert expanded[5] is MIXES["glossy+mirror"].mix.leaves[0].material


@pytest.mark.parametrize("bad,message", [
    (mixed(), "at least one leaf"),
    (mixed(leaf(MIXES["diffuse+glossy"])), "is a mix itself"),
    (mixed(leaf(Material("Lamp", DIFFUSE, emission=(1, 1, 1)))), "emits"),
    (mixed(leaf(diffuse(), MixFactor("bogus"))), "unknown mix factor kind"),
    (mixed(leaf(diffuse(), MixFactor("fresnel", value=2.0))), "value must be from 0 to 1"),
    (mixed(leaf(diffuse(), MixFactor("layer_weight", output="edge"))), "Layer Weight output"),
    (mixed(leaf(glossy(roughness=2.0))), "roughness"),
    (Material("Plain", DIFFUSE, mix=Mix([leaf(diffuse())])), "only kind mix"),
    (Material("NoLeaves", MIX), "needs a Mix"),
])
def test_validation_names_the_material(bad, message):
    with pytest.raises(SceneError, match=message) as err:
        bad.validate()
    assert bad.name in str(err.value)


def test_scene_files_keep_mixes(tmp_path):
    from engine.scene.builtin import cornell_scene
    scene = cornell_scene((8, 8))
    scene.textures = []
    slot = TextureSlot(0, interpolation="Closest", extension="EXTEND", node="Mask")
    from engine.scene.textures import ImageTexture
    scene.textures.append(ImageTexture("Mask", pixels=np.full((2, 2, 3), 128, np.uint8)))
    material = mixed(leaf(diffuse(), MixFactor("layer_weight", blend=0.3, output="facing", invert=True, node="LW")),
                     leaf(glossy(0.25), MixFactor("layer_weight", blend=0.3, output="facing", node="LW"),
                          MixFactor("texture", value=0.4, texture=slot, node="Mask")),
                     leaf(Material("Glass", GLASS, ior=1.33), const(2.0)), name="Mixed")
    scene.materials.append(material)
    save_scene(scene, str(tmp_path / "s.json"))
    back = load_scene(str(tmp_path / "s.json"))
    assert back.materials[-1] == material
    back.validate()


def test_scene_file_errors_name_the_leaf():
    """engine/scene/mix_fields.py: a wrong "mix" entry is one SceneError naming the material."""
    from engine.scene.fields import Fields
    from engine.scene.mix_fields import read_mix
    with pytest.raises(SceneError, match="Material 'M': mix must be a list"):
        read_mix(Fields({"mix": 3}, "Material 'M'"), [], None)
    with pytest.raises(SceneError, match="mix leaf #0: factor #0: invert must be true or false"):
        read_mix(Fields({"mix": [{"material": {"kind": "diffuse"}, "factors": [{"invert": 1}]}]}, "Material 'M'"),
                 [], lambda f, name: Material(name))


# -- end to end: a texture factor at triangle hits ------------------------------------------------------
def textured_floor_scene(floor):
    """A floor of two triangles with UVs 0..1 under a square lamp, seen from above."""
    from engine.scene.model import Camera, Quad, Scene, TriangleMesh
    from engine.scene.textures import ImageTexture
    checker = np.array([[40, 200], [220, 90]], dtype=np.uint8)[:, :, None].repeat(3, axis=2)
    vertices = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=np.float64)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float64)
    triangles = np.array([[0, 1, 2], [0, 2, 3]])
    mesh = TriangleMesh("Floor", vertices, triangles, np.zeros(2, dtype=np.int64), uvs=uv[triangles])
    lamp = Material("Lamp", DIFFUSE, (0, 0, 0), emission=(6.0, 6.0, 6.0))
    corners = np.array([[-0.3, -0.3, 1.5], [-0.3, 0.3, 1.5], [0.3, 0.3, 1.5], [0.3, -0.3, 1.5]])
    return Scene(Camera.look_at((0.0, -0.2, 3.0), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), lens=30.0),
                 [floor, lamp], [mesh], [], [Quad("Lamp", corners, 1)], resolution=(16, 16),
                 textures=[ImageTexture("Checker", pixels=checker, colorspace="Non-Color")])


def test_a_texture_mix_of_white_and_black_renders_as_the_textured_colour():
    """Mix(texture, black, white diffuse) is the diffuse of colour = texture: both leaves sample the
    cosine lobe, so value and light samples are the textured Lambertian's up to rounding.  Control:
    the same mix without its texture lookups (the unlinked factor 0.5) renders another image."""
    from engine import render
    slot = TextureSlot(0, interpolation="Closest", node="Checker")
    mix = mixed(leaf(Material("Black", DIFFUSE, (0, 0, 0)), MixFactor("texture", value=0.5, texture=slot, invert=True)),
                leaf(Material("White", DIFFUSE, (1, 1, 1)), MixFactor("texture", value=0.5, texture=slot)))
    settings = dict(samples=8, seed=4, threads=1, parallelism="threads")
    quiet = dict(log=lambda *a: None)
    mixed_image = render(textured_floor_scene(mix), RenderSettings(**settings), **quiet)
    assert mixed_image.stats["effects"]["textures"] and mixed_image.stats["effects"]["mix"]
    textured = Material("Textured", DIFFUSE, (0.5, 0.5, 0.5), color_texture=slot)
    reference = render(textured_floor_scene(textured), RenderSettings(**settings), **quiet).image
    assert reference.mean() > 0.02
    assert np.allclose(mixed_image.image, reference, rtol=1e-4, atol=1e-6)
    flat = mixed(*(MixLeaf(leaf.material, [dataclasses.replace(f, kind="constant") for f in leaf.factors])
                   for leaf in mix.mix.leaves))
    flat_image = render(textured_floor_scene(flat), RenderSettings(**settings), **quiet).image
    assert not np.allclose(flat_image, reference, rtol=0.05, atol=1e-3)


def test_leaf_colours_are_looked_up_only_where_a_leaf_has_a_textured_colour(monkeypatch):
    """MixBSDF._colours_read: a mix of a textured diffuse (weight 1) and a black one renders as the
    textured diffuse (its colour looked up per pair); a texture-factor mix of untextured leaves skips
    the lookups and renders the same bits as with them.  Control: the textured leaf's lookups left out
    render another image."""
    from engine import render
    slot = TextureSlot(0, interpolation="Closest", node="Checker")
    settings = RenderSettings(samples=4, seed=4, threads=1, parallelism="threads", backend="numpy")
    quiet = dict(log=lambda *a: None)
    textured = Material("Textured", DIFFUSE, (0.5, 0.5, 0.5), color_texture=slot)
    mix = mixed(leaf(textured, const(1.0)), leaf(Material("Black", DIFFUSE, (0, 0, 0)), const(0.0)))
    asked = []
    original = MixBSDF._colours_read

    def recording(self, lookup):
        asked.append(original(self, lookup))
        return asked[-1]
    monkeypatch.setattr(MixBSDF, "_colours_read", recording)
    image = render(textured_floor_scene(mix), settings, **quiet).image
    reference = render(textured_floor_scene(textured), settings, **quiet).image
    assert asked and all(asked) and np.allclose(image, reference, rtol=1e-4, atol=1e-6)
    factor_mix = mixed(leaf(diffuse((1, 1, 1)), MixFactor("texture", value=0.5, texture=slot)),
                       leaf(diffuse((0, 0, 0)), MixFactor("texture", value=0.5, texture=slot, invert=True)))
    asked.clear()
    skipped = render(textured_floor_scene(factor_mix), settings, **quiet).image
    assert asked and not any(asked)
    monkeypatch.setattr(MixBSDF, "_colours_read", lambda self, lookup: True)
    assert np.array_equal(render(textured_floor_scene(factor_mix), settings, **quiet).image, skipped)
    monkeypatch.setattr(MixBSDF, "_colours_read", lambda self, lookup: False)       # control
    assert not np.allclose(render(textured_floor_scene(mix), settings, **quiet).image, reference, rtol=0.05, atol=1e-3)


def test_a_leaf_colour_from_a_node_program_is_looked_up(monkeypatch):
    """MixBSDF._colours_read's node-program branch: a mix of a diffuse whose colour is a node program
    (the floor's generated coordinates as RGBA, engine/scene/programs.py) at weight 1 and a black one
    reads the leaf colours (no image texture in the scene: the program alone says so), renders the same
    bits as with the lookups forced on, and as the programmed diffuse alone up to rounding.  Control:
    the lookups forced off render another image (the leaf's field colour)."""
    from engine import render
    from engine.scene.programs import Program, ProgramNode
    generated = Program([ProgramNode("ShaderNodeTexCoord", "Coords", {"_outputs": ["Generated"]})],
                        (0, "Generated", "VECTOR"), "RGBA")
    programmed = Material("Programmed", DIFFUSE, (0.9, 0.2, 0.1), programs={"color": generated})
    mix = mixed(leaf(programmed, const(1.0)), leaf(Material("Black", DIFFUSE, (0, 0, 0)), const(0.0)))
    settings = RenderSettings(samples=4, seed=4, threads=1, parallelism="threads", backend="numpy")
    quiet = dict(log=lambda *a: None)
    asked, seen = [], []
    original = MixBSDF._colours_read

    def recording(self, lookup):
        asked.append(original(self, lookup))
        seen.append((lookup.textures.attributes is not None, bool(lookup.textures.textures.has_color.any())))
        return asked[-1]
    monkeypatch.setattr(MixBSDF, "_colours_read", recording)
    image = render(textured_floor_scene(mix), settings, **quiet).image
    assert asked and all(asked) and set(seen) == {(True, False)}       # read: the program, not an image
    alone = render(textured_floor_scene(programmed), settings, **quiet).image
    assert alone.mean() > 0.02 and np.allclose(image, alone, rtol=1e-4, atol=1e-6)
    monkeypatch.setattr(MixBSDF, "_colours_read", lambda self, lookup: True)
    assert np.array_equal(render(textured_floor_scene(mix), settings, **quiet).image, image)
    monkeypatch.setattr(MixBSDF, "_colours_read", lambda self, lookup: False)       # control
    assert not np.allclose(render(textured_floor_scene(mix), settings, **quiet).image, image, rtol=0.05, atol=1e-3)


def test_the_effect_plan_names_the_mixed_lobes():
    from engine.integrators.effects import plan_effects
    scene = textured_floor_scene(MIXES["fresnel diffuse+glossy"])
    plan = plan_effects(scene, RenderSettings())
    assert plan.enabled["mix"] and plan.enabled["glossy"] and plan.enabled["direct_light"]
    assert "'Mix' diffuse [1 - fresnel] + glossy [fresnel]" in plan.reason["mix"]
    delta_only = plan_effects(textured_floor_scene(mixed(leaf(Material("M", MIRROR)), leaf(Material("G", GLASS)))),
                              RenderSettings())
    assert not delta_only.enabled["direct_light"] and delta_only.enabled["glass"]


def random_hits(rng, n, kinds):
    """n random hits of `kinds` materials for comparing two mixes' eval and sample: (normal, wo, the
    normal facing wo, material, wi, u_lobe, u, a sorted half of the indices), in this order of draws."""
    normal = rng.normal(size=(3, n))
    normal /= np.linalg.norm(normal, axis=0)
    wo = rng.normal(size=(3, n))
    wo /= np.linalg.norm(wo, axis=0)
    facing = np.where((wo * normal).sum(axis=0) < 0.0, -normal, normal)
    material = rng.integers(0, kinds, n)
    wi = rng.normal(size=(3, n))
    wi /= np.linalg.norm(wi, axis=0)
    u_lobe, u = rng.random(n), (rng.random(n), rng.random(n))
    idx = np.sort(rng.choice(n, n // 2, replace=False))
    return normal, wo, facing, material, wi, u_lobe, u, idx


def test_a_span_reads_its_pairs_once_for_the_light_samples_and_the_sample():
    """The pairs of a span (factors, leaves) computed once and gathered for a take of
    it (the light samples' eval) give the same eval and sample, medium stacks included, as pairs
    computed on those hits alone.  Control: the take reads the span's pairs (scaled ones show)."""
    materials = [MIXES[k] for k in ("diffuse+glossy", "diffuse+glass", "fresnel diffuse+glossy", "layer weight",
                                    "glossy+mirror")]
    bsdf = MaterialTable(materials, RenderSettings(fresnel="exact")).bsdfs[KIND_CODE[MIX]]
    n, rng = 2000, np.random.default_rng(23)
    normal, wo, facing, material, wi, u_lobe, u, idx = random_hits(rng, n, len(materials))

    def make():
        si = ShadingPoint(wo.copy(), facing.copy(), facing.copy(), normal.copy(), np.ones((3, n)), material.copy())
        si.media = MediumStack.empty(n)
        return si

    alone = make()
    f_a, p_a = bsdf.eval(alone.take(idx), wi.take(idx, axis=1))    # hits of no span: their own pairs
    s_a = bsdf.sample(alone, u_lobe, u)
    span = make()[0:n]
    f_b, p_b = bsdf.eval(span.take(idx), wi.take(idx, axis=1))     # the span's pairs, gathered
    s_b = bsdf.sample(span, u_lobe, u)                               # the same pairs again
    assert (p_a > 0).sum() > n // 4 and np.array_equal(f_a, f_b) and np.array_equal(p_a, p_b)
    for x, y in ((s_a.wi, s_b.wi), (s_a.value, s_b.value), (s_a.pdf, s_b.pdf), (s_a.flags, s_b.flags),
                 (alone.media.media, span.media.media), (alone.media.depth, span.media.depth)):
        assert np.array_equal(x, y)
    assert (s_a.flags & BSDFFlags.TRANSMISSION).any()
    span.memo_at((bsdf, "pairs"), None)[0][2][:] *= 1.5             # control: the weights of the span's pairs
    assert not np.array_equal(bsdf.eval(span.take(idx), wi.take(idx, axis=1))[0], f_b)


def test_rows_taken_whole_evaluate_and_sample_as_gathered_ones(monkeypatch):
    """When a call's pairs are all of a row's (the span's eval at every hit; a sample whose hits all
    scatter by non-delta leaves), _Leaves.at takes the row whole (ShadingPoint.take(None): no
    gathers): eval and sample give the same bits as the same pairs gathered by index.  Control: the
    whole takes happen in the first run and not in the second."""
    from engine.materials import mix
    from engine.materials.media import MediumStack
    materials = [MIXES[k] for k in ("diffuse+glossy", "fresnel diffuse+glossy", "layer weight")]
    bsdf = MaterialTable(materials, RenderSettings(fresnel="exact")).bsdfs[KIND_CODE[MIX]]
    n, rng = 1500, np.random.default_rng(41)
    normal, wo, facing, material, wi, u_lobe, u, _ = random_hits(rng, n, len(materials))
    whole_takes, take = [], ShadingPoint.take
    monkeypatch.setattr(ShadingPoint, "take", lambda self, index: whole_takes.append(index is None) or take(self, index))

    def run():
        si = ShadingPoint(wo.copy(), facing.copy(), facing.copy(), normal.copy(), np.ones((3, n)), material.copy())
        si.media = MediumStack.empty(n)
        span = si[0:n]
        f, p = bsdf.eval(span, wi)
        s = bsdf.sample(span, u_lobe, u)
        return f, p, s.wi, s.value, s.pdf, s.flags
    whole = run()
    assert sum(whole_takes) >= 4                                    # two rows, in the eval and the sample
    whole_takes.clear()
    leaves_take = mix._Leaves.take
    monkeypatch.setattr(mix._Leaves, "take", lambda self, pairs, hit, media: leaves_take(
        self, np.arange(len(self.slot)) if pairs is None else pairs, hit, media))
    gathered = run()
    assert not any(whole_takes)
    assert (whole[1] > 0).sum() > n // 4
    for x, y in zip(whole, gathered):
        assert np.array_equal(x, y)
