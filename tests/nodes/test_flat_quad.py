"""The flat-quad harness itself (tests/nodes/flat_quad.py): Cycles' image of the Texture Coordinate
(snapped to the pixel centres) is the coordinates it returns, through the Emission and the AOVs, in
Blender 5.0 and 3.4."""
import numpy as np
import pytest

from tests.nodes import flat_quad


def build_coordinate(nodes, links, coord):
    return coord


def build_coordinate_aovs(nodes, links, coord, operation="SINE"):
    math = nodes.new("ShaderNodeMath")
    math.operation = operation
    links.new(coord, math.inputs[0])              # a vector into a float socket: its average
    return {"coord": coord, "math": math.outputs[0]}


def test_coordinates_are_pixel_centres_in_image_order():
    p = flat_quad.coordinates(4, z=0.5)
    assert p.shape == (3, 16)
    assert np.allclose(p[:, 0], (-0.75, 0.75, 0.5))          # top-left pixel
    assert np.allclose(p[:, 3], (0.75, 0.75, 0.5))           # top-right
    assert np.allclose(p[:, 15], (0.75, -0.75, 0.5))         # bottom-right
    with pytest.raises(ValueError):
        flat_quad.render(build_coordinate, resolution=30)


def _check(image, points, sine):
    assert image.shape == (32, 32, 3)
    assert np.array_equal(image.reshape(-1, 3).T, points)             # negatives pass unclamped too
    expect = np.sin(points.mean(axis=0).astype(np.float32))
    assert np.abs(sine[..., 0].ravel() - expect).max() < 1e-6
    assert np.abs(sine[..., 0].ravel() - np.cos(points.mean(axis=0))).max() > 0.1   # control


@pytest.mark.slow
def test_texture_coordinate_image_is_the_coordinates_blender50():
    image, points = flat_quad.render(build_coordinate)
    assert np.array_equal(image.reshape(-1, 3).T, points)
    images, points = flat_quad.render(build_coordinate_aovs, z=0.25)
    _check(images["coord"], points, images["math"])


@pytest.mark.slow
def test_texture_coordinate_image_is_the_coordinates_blender34():
    images, points = flat_quad.render(build_coordinate_aovs, blender="3.4", z=0.25, operation="SINE")
    _check(images["coord"], points, images["math"])
