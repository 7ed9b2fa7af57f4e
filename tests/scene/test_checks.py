"""engine/scene/checks.py: the shared value checks fail with a SceneError naming the object."""
import numpy as np
import pytest

from engine.core.errors import SceneError
from engine.scene.checks import LARGEST_VALUE, check_magnitude, check_resolution, check_vector


def test_magnitude():
    check_magnitude("Object 'Ball'", "radius", [LARGEST_VALUE, -LARGEST_VALUE])
    check_magnitude("Object 'Ball'", "radius", [])
    with pytest.raises(SceneError, match=r"^Object 'Ball': radius 2e\+30 is too large \(at most 1e\+30\)$"):
        check_magnitude("Object 'Ball'", "radius", [1.0, -2e30])


@pytest.mark.parametrize("value", [(64, 48), [64, 48], (np.int64(64), np.int32(48))])
def test_resolution_accepts_two_integers(value):
    assert check_resolution("Shot", value) == (64, 48)
    assert all(type(v) is int for v in check_resolution("Shot", value))


@pytest.mark.parametrize("value", [64, (64,), (64, 48, 1), (64.0, 48), (True, 48), ("64", 48), None])
def test_resolution_refuses_the_rest_naming_the_scene(value):
    with pytest.raises(SceneError, match=r"^Scene 'Shot': resolution must be 2 integers, got "):
        check_resolution("Shot", value)


def test_vector():
    assert check_vector("Light 'Sun'", "direction", (0, 0, -1)).tolist() == [0.0, 0.0, -1.0]
    for bad in ((0, 0), (0, 0, 0, 0), (0, 0, np.nan), (0, 0, np.inf)):
        with pytest.raises(SceneError, match=r"^Light 'Sun': direction must be 3 finite numbers$"):
            check_vector("Light 'Sun'", "direction", bad)
    with pytest.raises(SceneError, match="colour must be 3 finite non-negative numbers"):
        check_vector("Material 'M'", "colour", (0.5, -0.1, 0), non_negative=True)
    check_vector("Material 'M'", "colour", (0.5, 0, 0), non_negative=True)


def test_lamps_are_capped_as_area_lights_are():
    """Sun irradiance 3.5e38 (just under float32's largest) was accepted while area radiance is capped at
    LARGEST_VALUE; so were point-light intensities, positions and radii."""
    from engine.scene.model import AreaLight, PointLight, SunLight
    too_large = 3.5e38
    with pytest.raises(SceneError, match=r"^Light 'Lamp': radiance .* is too large"):
        AreaLight("Lamp", np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0)]), (too_large,) * 3).validate()
    with pytest.raises(SceneError, match=r"^Light 'Sun': irradiance 3.5e\+38 is too large \(at most 1e\+30\)$"):
        SunLight("Sun", (0, 0, -1), (too_large, 1, 1)).validate()
    for fields, label in [(dict(intensity=(too_large,) * 3), "intensity"), (dict(position=(0, 0, too_large)), "position"),
                          (dict(radius=too_large), "radius")]:
        light = PointLight("Bulb", **{"position": (0, 0, 1), "intensity": (1, 1, 1), **fields})
        with pytest.raises(SceneError, match=rf"^Light 'Bulb': {label} 3.5e\+38 is too large"):
            light.validate()
    SunLight("Sun", (0, 0, -1), (LARGEST_VALUE,) * 3).validate()
    PointLight("Bulb", (0, 0, 1), (LARGEST_VALUE,) * 3, LARGEST_VALUE).validate()
