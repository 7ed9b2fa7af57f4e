"""Image textures on float inputs and tangents from the mesh (engine/materials/textures.py per_hit,
hit_tangent; engine/scene/model.py Material.input_textures, tangent_source, TriangleMesh.tangents).

A plate whose roughness (metallic, diffuse roughness) texture is 0.2 on its left half and 0.8 on its
right renders, pixel for pixel, as the same plate made of two materials of those values: the sampler's
numbers depend on the pixel and sample only, so the two renders agree to rounding.  Control: the
textured material without its texture (the unlinked value) renders another image.  The same for an
anisotropic plate whose corner tangents are the y axis against a material whose fixed tangent is y.
"""
import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from engine import RenderSettings, render
from engine.core.errors import SceneError
from engine.materials.glossy import MicrofacetReflection
from engine.materials.protocol import ShadingPoint
from engine.materials.textures import per_hit
from engine.scene.files import load_scene, save_scene
from engine.scene.model import (DIFFUSE, GLASS, GLOSSY, PRINCIPLED, Camera, Material, Principled, PrincipledV1, Quad,
                                Scene, TriangleMesh)
from engine.scene.textures import ImageTexture, TextureSlot

SLOT = TextureSlot(0, interpolation="Closest", extension="EXTEND")
SETTINGS = RenderSettings(samples=4, seed=3, threads=1, parallelism="threads")
QUIET = dict(log=lambda *a: None)


def plate_scene(materials, textures=(), tangents=None, split=True):
    """A 2 x 2 m plate in z = 0 (left half x < 0: material 0 and u < 0.5; right: material 1) under a
    square lamp, seen from the front and above."""
    v = np.array([[-1, -1, 0], [0, -1, 0], [0, 1, 0], [-1, 1, 0], [1, -1, 0], [1, 1, 0]], float)
    tris = np.array([[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]])
    uv = np.array([[0, 0], [0.5, 0], [0.5, 1], [0, 1], [1, 0], [1, 1]], float)[tris]
    ids = np.array([0, 0, 1, 1]) if split else np.zeros(4, dtype=np.int64)
    lamp = Material("Lamp", DIFFUSE, (0, 0, 0), emission=(5.0, 5.0, 5.0))
    corners = np.array([[-0.4, 0.6, 1.2], [-0.4, 1.4, 1.2], [0.4, 1.4, 1.2], [0.4, 0.6, 1.2]])
    mesh = TriangleMesh("Plate", v, tris, ids, uvs=uv, tangents=tangents)
    cam = Camera.look_at((0.0, -2.5, 1.5), (0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0), lens=35.0)
    mats = list(materials) + [lamp]
    return Scene(cam, mats, [mesh], [], [Quad("Lamp", corners, len(mats) - 1)], resolution=(16, 16),
                 textures=list(textures))


def half_texture(left, right, channel=None):
    """A 2 x 1 float image: `left` in its left texel, `right` in its right (grey, or in `channel` only)."""
    px = np.zeros((1, 2, 3), np.float32)
    for x, value in enumerate((left, right)):
        px[0, x] = value if channel is None else [value if c == channel else 0.37 for c in range(3)]
    return ImageTexture("Halves", pixels=px, colorspace="Non-Color", is_float=True)


def principled(**kw):
    p = {k: kw.pop(k) for k in ("metallic",) if k in kw}
    return Material(kw.pop("name", "P"), PRINCIPLED, kw.pop("color", (0.5, 0.3, 0.2)), principled=Principled(**p), **kw)


def principled_v1(roughness, metallic=0.0):
    return Material("P34", PRINCIPLED, (0.9, 0.6, 0.2), roughness=roughness, multiscatter=True,
                    principled=PrincipledV1(metallic=metallic))


# (input, the two materials of the split plate, the textured material's unlinked fields, the texels)
CASES = {
    "glossy roughness": ("roughness", lambda r: Material("G", GLOSSY, (0.9, 0.9, 0.9), roughness=r), (0.2, 0.8)),
    "principled roughness": ("roughness", lambda r: principled(roughness=r), (0.2, 0.8)),
    "principled metallic": ("metallic", lambda m: principled(roughness=0.3, metallic=m, color=(0.9, 0.6, 0.2)),
                            (0.0, 1.0)),
    # Blender 3.x's Principled (engine/materials/principled_v1.py), "Multiscatter GGX": 0.05 is single scattering
    "principled v1 roughness": ("roughness", lambda r: principled_v1(roughness=r), (0.05, 0.8)),
    "principled v1 metallic": ("metallic", lambda m: principled_v1(roughness=0.3, metallic=m), (0.0, 1.0)),
    "diffuse roughness": ("diffuse_roughness", lambda r: Material("D", DIFFUSE, (0.8, 0.8, 0.8), diffuse_roughness=r),
                          (0.2, 0.8)),
    "glass roughness": ("roughness", lambda r: Material("Gl", GLASS, (1, 1, 1), roughness=r), (0.2, 0.8)),
}


@pytest.mark.parametrize("case", CASES)
def test_a_half_and_half_texture_renders_as_two_materials(case):
    name, make, (left, right) = CASES[case]
    two = render(plate_scene([make(left), make(right)]), SETTINGS, **QUIET).image
    textured = dataclasses.replace(make(0.5), input_textures={name: SLOT})
    one = render(plate_scene([textured], [half_texture(left, right)], split=False), SETTINGS, **QUIET)
    assert one.stats["effects"]["textures"]
    assert two.mean() > 0.01
    assert np.allclose(one.image, two, rtol=1e-4, atol=1e-6), np.abs(one.image - two).max()
    # Control: the material without its texture (the unlinked 0.5) is another image.
    plain = dataclasses.replace(textured, input_textures={})
    ignored = render(plate_scene([plain], [half_texture(left, right)], split=False), SETTINGS, **QUIET).image
    assert not np.allclose(ignored, two, rtol=0.05, atol=1e-3)


def test_a_channel_reads_one_colour_component():
    """A Separate RGB's G output: the slot's channel "g" reads green only (the others are 0.37)."""
    make = CASES["glossy roughness"][1]
    two = render(plate_scene([make(0.2), make(0.8)]), SETTINGS, **QUIET).image
    slot = dataclasses.replace(SLOT, channel="g")
    textured = dataclasses.replace(make(0.5), input_textures={"roughness": slot})
    one = render(plate_scene([textured], [half_texture(0.2, 0.8, channel=1)], split=False), SETTINGS, **QUIET).image
    assert np.allclose(one, two, rtol=1e-4, atol=1e-6)
    lum = dataclasses.replace(textured, input_textures={"roughness": SLOT})      # luminance: mixes in 0.37
    other = render(plate_scene([lum], [half_texture(0.2, 0.8, channel=1)], split=False), SETTINGS, **QUIET).image
    assert not np.allclose(other, two, rtol=0.05, atol=1e-3)


def anisotropic(**kw):
    return Material("Brushed", GLOSSY, (0.9, 0.9, 0.9), roughness=0.4, anisotropy=0.8, **kw)


def test_mesh_tangents_orient_the_anisotropy():
    """Corner tangents along y (tangent_source "uv") render as the fixed tangent y; control: the fixed
    tangent x (the object's X, what the material holds where a hit has no mesh tangent) differs."""
    fixed_y = render(plate_scene([anisotropic(tangent=(0, 1, 0))], split=False), SETTINGS, **QUIET).image
    along_y = np.tile(np.array([0.0, 1.0, 0.0]), (4, 3, 1))
    from_mesh = render(plate_scene([anisotropic(tangent=(1, 0, 0), tangent_source="uv")], tangents=along_y,
                                   split=False), SETTINGS, **QUIET)
    assert from_mesh.stats["effects"]["textures"]
    assert np.allclose(from_mesh.image, fixed_y, rtol=1e-4, atol=1e-6)
    fixed_x = render(plate_scene([anisotropic(tangent=(1, 0, 0))], split=False), SETTINGS, **QUIET).image
    assert not np.allclose(fixed_x, fixed_y, rtol=0.05, atol=1e-3)
    # A mesh without tangents: the material's own tangent.
    no_tangents = render(plate_scene([anisotropic(tangent=(1, 0, 0), tangent_source="radial")], split=False),
                         SETTINGS, **QUIET).image
    assert np.allclose(no_tangents, fixed_x, rtol=1e-4, atol=1e-6)


def test_scene_files_keep_input_textures_channels_and_tangents(tmp_path):
    slot = dataclasses.replace(SLOT, channel="b", node="Rough")
    glass = Material("Gl", GLASS, (1, 1, 1), distribution="beckmann", input_textures={"roughness": slot})
    brushed = anisotropic(tangent_source="uv", tangent_uv_map="Brush", input_textures={"roughness": SLOT})
    tangents = np.tile(np.array([0.0, 1.0, 0.0]), (4, 3, 1))
    scene = plate_scene([glass, brushed], [half_texture(0.2, 0.8)], tangents=tangents)
    save_scene(scene, str(tmp_path / "s.json"))
    again = load_scene(str(tmp_path / "s.json"))
    assert again.validate() == []
    assert again.materials[0].input_textures == {"roughness": slot}
    assert again.materials[0].distribution == "beckmann" and again.materials[0].roughness == 0.0
    assert again.materials[1].tangent_source == "uv" and again.materials[1].tangent_uv_map == "Brush"
    assert np.array_equal(again.meshes[0].tangents, tangents)
    a = render(scene, SETTINGS, **QUIET).image
    b = render(again, SETTINGS, **QUIET).image
    assert np.array_equal(a, b)


@pytest.mark.parametrize("edit, message", [
    (lambda m, s: setattr(m, "input_textures", {"ior": SLOT}), "unknown textured input 'ior'"),
    (lambda m, s: setattr(m, "input_textures", {"roughness": dataclasses.replace(SLOT, channel="a")}),
     "roughness texture channel 'a'"),
    (lambda m, s: setattr(m, "input_textures", {"roughness": dataclasses.replace(SLOT, texture=5)}),
     "roughness texture index 5 out of range"),
    (lambda m, s: setattr(m, "tangent_source", "object"), "unknown tangent source 'object'"),
    (lambda m, s: setattr(s.meshes[0], "tangents", np.zeros((4, 2, 3))), "tangents must be 3 finite vectors"),
])
def test_bad_inputs_are_scene_errors_naming_them(edit, message):
    material = anisotropic()
    scene = plate_scene([material], [half_texture(0.2, 0.8)], split=False)
    edit(material, scene)
    with pytest.raises(SceneError, match=message):
        scene.validate()


def test_per_hit_without_lookups_is_the_material_value():
    from engine.materials.protocol import ShadingPoint
    z = np.zeros((3, 3))
    si = ShadingPoint(z, z, z, z, z, np.array([1, 0, 1]))
    values = np.array([0.25, 0.75])
    assert np.array_equal(per_hit(si, values, "roughness"), values.take(si.material))


class CountingLookup:
    """A roughness texture's values at hits (what HitLookup.input gives), counting its reads."""
    def __init__(self, values, reads, textured):
        self.values, self.reads = np.asarray(values, dtype=np.float64), reads
        self.textures = SimpleNamespace(textures=SimpleNamespace(has_input={"roughness": textured}))

    def take(self, index):
        return CountingLookup(self.values.take(index), self.reads, self.textures.textures.has_input["roughness"])

    def __getitem__(self, span):
        return CountingLookup(self.values[span], self.reads, self.textures.textures.has_input["roughness"])

    def input(self, name, values, material):
        self.reads.append(len(self.values))
        return np.where(self.textures.textures.has_input[name].take(material), self.values, values)


def test_a_span_reads_a_roughness_texture_once():
    """The alphas of a span's hits from a roughness texture: read once for the span (its takes gather
    them), the same numbers as hits of no span, which read it at every call.  Control: a second span
    reads it again."""
    materials = [Material("G", GLOSSY, (0.9, 0.9, 0.9), roughness=0.5, input_textures={"roughness": SLOT}),
                 Material("H", GLOSSY, (0.9, 0.9, 0.9), roughness=0.3, anisotropy=0.4)]
    lobe = MicrofacetReflection(materials, RenderSettings())
    n, rng = 40, np.random.default_rng(3)
    up = np.tile([[0.0], [0.0], [1.0]], (1, n))
    material, rough = rng.integers(0, 2, n), rng.random(n)
    textured = np.array([True, False])

    def make(reads):
        si = ShadingPoint(up.copy(), up.copy(), up.copy(), up.copy(), np.ones((3, n)), material.copy())
        si.lookup = CountingLookup(rough, reads, textured)
        return si

    alone_reads, span_reads = [], []
    alone = make(alone_reads)
    expected = lobe.alphas(alone)
    idx = np.sort(rng.choice(n, n // 2, replace=False))
    taken = lobe.alphas(alone.take(idx))
    assert len(alone_reads) == 2
    span = make(span_reads)[0:n]
    got_taken = lobe.alphas(span.take(idx))
    got = lobe.alphas(span)
    assert span_reads == [n]
    for a, b in zip(expected + taken, got + got_taken):
        assert np.array_equal(a, b)
    assert not np.array_equal(expected[0], lobe.ax.take(material))      # the texture is read
    lobe.alphas(make(span_reads)[0:n])
    assert span_reads == [n, n]
