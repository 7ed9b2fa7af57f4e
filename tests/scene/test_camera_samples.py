"""engine/scene/camera_rays.py serial_pixels: the pixel and sample of each serial number of a
TileSamples range, against NumPy's % and //, on ranges that start and end mid-sample, span one pixel,
one sample or none; control: a range one off is caught."""
import numpy as np

from engine.scene.camera_rays import serial_pixels


def expected(first, count, pixels):
    serial = np.arange(first, first + count)
    return serial % pixels, serial // pixels


def test_serial_pixels_are_remainder_and_quotient():
    for first, count, pixels in ((0, 65536, 9216), (123457, 65536, 9216), (5, 3, 9216), (9215, 2, 9216),
                                 (0, 9216, 9216), (9216, 9216 * 3, 9216), (7, 100, 1), (0, 0, 16), (13, 0, 16),
                                 (3, 1, 4), (40, 17, 7), (2 ** 20 * 5 + 3, 16384, 2 ** 20), (2 ** 22 - 10, 30, 2 ** 21)):
        got = serial_pixels(first, count, pixels)
        for a, b in zip(got, expected(first, count, pixels)):
            assert a.dtype == np.int64 and np.array_equal(a, b), (first, count, pixels)


def test_control_a_range_one_off_is_caught():
    got = serial_pixels(123457, 1000, 9216)
    assert not np.array_equal(got[0], expected(123458, 1000, 9216)[0])
