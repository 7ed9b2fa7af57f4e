"""The compiled image lookup (engine/materials/textures_jit.py) against engine/materials/textures.py's
`lookup`: bit for bit on the lookups of a real render of a textured card (recorded from TextureSet.lookup
on the NumPy backend) and on hand-made points (every interpolation and extension, borders, far outside,
NaN and infinities, float32 and uint8 texels, one channel of four); controls show the comparison sees a
last-bit change of a point and a wrong extension."""
import numpy as np
import pytest

from engine import RenderSettings, render
from engine.materials.textures import TextureSet, lookup
from engine.scene.model import Camera, Material, Scene, TriangleMesh
from engine.scene.textures import ImageTexture, TextureSlot
from tests.backend_capture import require_compiled

EXTENSIONS = ("REPEAT", "EXTEND", "CLIP", "MIRROR")


def twin():
    require_compiled()
    from engine.materials import textures_jit
    return textures_jit


def same(a, b) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b, equal_nan=True)


def card_scene(interpolation, extension):
    """A card whose UVs run from -0.3 to 1.7 (every extension wraps) with an 8-bit sRGB noise image."""
    rng = np.random.default_rng(5)
    pixels = rng.integers(0, 256, size=(5, 7, 4)).astype(np.uint8)
    slot = TextureSlot(0, interpolation, extension)
    mats = [Material("Textured", color=(0.8, 0.2, 0.1), color_texture=slot)]
    lo, hi = -0.3, 1.7
    mesh = TriangleMesh("Card", np.array([(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)], float),
                        np.array([[0, 1, 2], [0, 2, 3]]), [0, 0],
                        uvs=np.array([[(lo, lo), (hi, lo), (hi, hi)], [(lo, lo), (hi, hi), (lo, hi)]], float))
    return Scene(Camera.look_at((0.5, -1.5, 0.5), (0.5, 0, 0.5)), mats, [mesh], background=(1, 1, 1),
                 resolution=(12, 12), textures=[ImageTexture("noise", pixels=pixels, colorspace="sRGB")])


def recorded_lookups(interpolation, extension):
    """[(pixels, u, v, interpolation, extension, channels)] of TextureSet.lookup in a NumPy render."""
    calls, original = [], TextureSet.lookup

    def recording(self, pixels, u, v, interp, ext, channels=None):
        calls.append((pixels, np.array(u), np.array(v), interp, ext, channels))
        return original(self, pixels, u, v, interp, ext, channels)
    TextureSet.lookup = recording
    try:
        render(card_scene(interpolation, extension), RenderSettings(samples=2, seed=1, threads=1, backend="numpy"),
               log=lambda *a: None)
    finally:
        TextureSet.lookup = original
    return calls


@pytest.mark.parametrize("interpolation", ["Closest", "Linear"])
def test_recorded_lookups_are_the_same(interpolation):
    jit = twin()
    for extension in EXTENSIONS:
        calls = recorded_lookups(interpolation, extension)
        assert len(calls) >= 1 and sum(len(c[1]) for c in calls) > 100
        for pixels, u, v, interp, ext, channels in calls:
            read = pixels if channels is None else pixels[:, :, channels[0]:channels[0] + channels[1]]
            assert same(lookup(read, u, v, interp, ext), jit.lookup(pixels, u, v, interp, ext, channels))


def hard_points():
    rng = np.random.default_rng(11)
    u = np.concatenate([rng.uniform(-3.0, 4.0, 300), [0.0, -0.0, 1.0, 0.5, 1 / 7, 6 / 7, -1e-17, np.nextafter(1.0, 0.0),
                                                       1e300, -1e300, 9.3e18, np.inf, -np.inf, np.nan]])
    v = np.concatenate([rng.uniform(-3.0, 4.0, 300), [0.0, 0.25, 0.999, -0.5, 2.0, 1e-300, 0.5, 0.5,
                                                       0.5, 0.5, 0.5, 0.5, 0.5, 0.5]])
    return u, v


@pytest.mark.parametrize("dtype", [np.float32, np.uint8])
def test_hard_points_every_mode(dtype):
    jit = twin()
    rng = np.random.default_rng(2)
    pixels = (rng.random((5, 7, 4)) * 255).astype(dtype)
    u, v = hard_points()
    with np.errstate(invalid="ignore"):
        for interpolation in ("Closest", "Linear"):
            for extension in EXTENSIONS:
                reference = lookup(pixels, u, v, interpolation, extension)
                assert same(reference, jit.lookup(pixels, u, v, interpolation, extension))
                # one channel of four (the alpha of TextureSet.sample), read without a strided view
                assert same(lookup(pixels[:, :, 3:4], u, v, interpolation, extension),
                            jit.lookup(pixels, u, v, interpolation, extension, (3, 1)))


def test_controls_see_an_ulp_and_a_wrong_extension():
    jit = twin()
    pixels = np.random.default_rng(4).random((4, 4, 3)).astype(np.float32)
    u, v = np.array([0.3, 0.61]), np.array([0.45, 0.2])
    nudged = np.nextafter(u, 1.0)
    assert not same(lookup(pixels, u, v), jit.lookup(pixels, nudged, v))
    far = np.array([1.3, -0.4])
    assert not same(lookup(pixels, far, v, "Linear", "REPEAT"), jit.lookup(pixels, far, v, "Linear", "MIRROR"))


def test_texture_set_takes_the_twin_on_numba():
    twin()
    scene = card_scene("Linear", "REPEAT")
    slot = scene.materials[0].color_texture
    u, v = hard_points()
    u, v = u[:300], v[:300]
    numpy_set, numba_set = TextureSet(scene), TextureSet(scene, "numba")
    assert numpy_set.compiled is None and numba_set.compiled is not None
    assert same(numpy_set.evaluate(slot, u, v), numba_set.evaluate(slot, u, v))
    assert all(same(a, b) for a, b in zip(numpy_set.sample(0, u, v), numba_set.sample(0, u, v)))
