"""The Sky Texture's port (engine/lights/sky.py): the structure of its table, its bake and its sun.
Cycles' per-pixel agreement and the sky-lit scene: tests/addon/test_agreement_sky.py (slow)."""
import math

import numpy as np

from engine.lights.sky import SkyParameters, SkyTexture, single_scattering_table, wrapped_sun


def test_table_is_finite_positive_and_brightest_towards_the_sun():
    table = single_scattering_table(math.radians(20.0), 100.0, 1.0, 1.0, 1.0, width=32, height=16)
    assert np.isfinite(table).all() and (table >= 0).all()
    upper = table[8:]
    assert (upper > 0).all()
    # columns 15 and 16 look at the sun's azimuth (0): each row is brightest there
    assert set(np.argmax(upper[..., 1], axis=1)) <= {15, 16}
    assert np.allclose(table[8:, :16], table[8:, 16:][:, ::-1])       # mirrored about the sun


def test_the_sun_direction_is_the_brightest_and_the_bake_is_finite():
    sky = SkyTexture(SkyParameters(sun_elevation=math.radians(30.0), sun_rotation=math.radians(60.0)),
                     table_size=(64, 32))
    image = sky.bake(128, 64)
    assert image.shape == (64, 128, 3) and np.isfinite(image).all() and (image >= 0).all()
    assert (image[33:] > 0).all()                                     # the upper hemisphere is lit
    assert image[:16].max() == 0.0                                    # far below the horizon: black
    s = sky.sun_direction
    assert abs(math.degrees(math.asin(s[2])) - 30.0) < 1e-9
    on = sky.radiance(s[None], sun=True)[0]
    off = sky.radiance(s[None], sun=False)[0]
    assert (on > 1e3 * off).all()                                     # the disc outshines the sky
    e = sky.sun_irradiance()
    assert (e > 0).all() and e[0] > e[2]                              # a yellowish sun at 30 degrees
    assert not SkyTexture(SkyParameters(sun_disc=False), table_size=(16, 8)).sun_irradiance().any()


def test_sun_position_wraps_as_cycles():
    e, r = wrapped_sun(math.radians(100.0), 0.0)
    assert math.isclose(e, math.radians(80.0)) and math.isclose(r, math.pi)
