"""The image world's construction (engine/lights/environment.py) computed without the per-point
lookups and roll copies it used: the same numbers bit for bit, with controls that an equal formula
in another order is told apart."""
import numpy as np
import pytest

from engine.lights import environment as E
from engine.materials.textures import lookup


def grid(pixels, k):
    h, w = pixels.shape[0] * k, pixels.shape[1] * k
    return (np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h


@pytest.mark.parametrize("shape", [(16, 32, 4), (7, 13, 3), (5, 9, 1)])
@pytest.mark.parametrize("k", [2, 6, 8])
def test_fine_lookup_is_the_linear_lookup_at_every_grid_point(shape, k):
    pixels = np.random.default_rng(sum(shape) + k).random(shape, dtype=np.float32) * 10
    us, vs = grid(pixels, k)
    expected = lookup(pixels, np.tile(us, len(vs)), np.repeat(vs, len(us)), "Linear", "REPEAT")
    got = E.fine_lookup(pixels, us, vs)
    assert got.shape == expected.shape and np.array_equal(got, expected)


def test_control_the_same_blend_in_another_order_is_told_apart():
    """tx (p1 - p0) + p0 is the same blend; its last bits differ somewhere: array_equal sees it."""
    shape, k = (16, 32, 4), 6                       # weights of 1/12: not exact in binary
    pixels = np.random.default_rng(3).random(shape, dtype=np.float32) * 10
    us, vs = grid(pixels, k)
    expected = E.fine_lookup(pixels, us, vs)
    tx, x0, x1 = E._axis(us, shape[1])
    ty, y0, y1 = E._axis(vs, shape[0])
    texels = pixels.astype(np.float64)
    rows = tx[None, :, None] * (texels[:, x1] - texels[:, x0]) + texels[:, x0]
    other = (ty[:, None, None] * (rows[y1] - rows[y0]) + rows[y0]).reshape(-1, shape[2])
    assert np.allclose(other, expected) and not np.array_equal(other, expected)


@pytest.mark.parametrize("shape", [(6, 9), (1, 4), (32, 64)])
@pytest.mark.parametrize("axis", [0, 1])
def test_cell_mean_is_the_sum_of_the_rolled_copies(shape, axis):
    lum = np.random.default_rng(shape[0] + axis).random(shape)
    lum[0, 0] = -0.0                                # 0 + (-0.0) is +0.0: the sum's start is kept
    expected = sum(k * np.roll(lum, s, axis=axis) for k, s in zip(E.CELL_KERNEL, (1, 0, -1)))
    got = E.cell_mean(lum, axis)
    assert np.array_equal(got, expected) and np.array_equal(np.signbit(got), np.signbit(expected))


def test_control_the_kernel_summed_in_another_order_is_told_apart():
    lum = np.random.default_rng(4).random((32, 64))
    expected = E.cell_mean(lum, 1)
    flipped = sum(k * np.roll(lum, s, axis=1) for k, s in zip(E.CELL_KERNEL, (-1, 0, 1)))
    assert np.allclose(flipped, expected) and not np.array_equal(flipped, expected)


@pytest.fixture
def kept():
    E.keep_last_map()
    yield
    E.keep_last_map(False)


def world(pixels, strength=1.0):
    from types import SimpleNamespace
    from engine.scene.model import Environment
    from engine.scene.textures import ImageTexture
    return SimpleNamespace(environment=Environment(texture=0, strength=strength),
                           textures=[ImageTexture("sky", pixels=pixels.copy(), colorspace="Linear Rec.709",
                                                  is_float=True)])


def test_a_process_that_keeps_its_last_map_gives_it_back_for_an_equal_world(kept):
    pixels = np.random.default_rng(5).random((8, 16, 3), dtype=np.float32)
    first = E.EnvironmentMap.of(world(pixels))
    assert E.EnvironmentMap.of(world(pixels)) is first              # new objects, the same values
    changed = pixels.copy()
    changed[3, 4, 1] += 1.0
    other = E.EnvironmentMap.of(world(changed))                      # one texel: another map
    assert other is not first and not np.array_equal(other.distribution.density, first.distribution.density)
    assert E.EnvironmentMap.of(world(changed, strength=2.0)) is not other     # the world's strength
    again = E.EnvironmentMap.of(world(changed, strength=2.0))
    assert again is E.EnvironmentMap.of(world(changed, strength=2.0))
    E.keep_last_map(False)                                           # control: not kept, built each time
    assert E.EnvironmentMap.of(world(pixels)) is not E.EnvironmentMap.of(world(pixels))
