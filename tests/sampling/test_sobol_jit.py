"""The compiled Sobol' points (engine/sampling/sobol_jit.py) against engine/sampling/qmc.py
`sample_2d`: bit for bit over net sizes 1 to 2^20, single and per-path dimensions (inside and
beyond the dimension-hash table), and on the calls recorded from a render of the built-in Cornell box."""
import numpy as np
import pytest

from engine.sampling import qmc
from tests.backend_capture import capture, require_compiled

TWIN = "engine.sampling.sobol_jit"      # imported after require_compiled(): numba may be missing


@pytest.mark.parametrize("count", [1, 2, 16, 1000, 1 << 16, 1 << 20])
def test_points_are_bit_identical(count):
    require_compiled()
    from engine.sampling.sobol_jit import sample_2d
    rng = np.random.default_rng(count)
    n = 4096
    index = rng.integers(0, count, n).astype(np.uint32)
    seeds = rng.integers(0, 2**32, n, dtype=np.uint64).astype(np.uint32)
    for dim in (0, 7, 2000, rng.integers(0, 40, n), rng.integers(0, 5000, n)):
        a, b = qmc.sample_2d(index, seeds, dim, count), sample_2d(index, seeds, dim, count)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


def test_captured_calls_are_bit_identical():
    require_compiled()
    from engine.sampling.sobol_jit import sample_2d
    calls = capture("cornell")["sobol"]
    assert len(calls) > 10
    for index, seeds, dim, count in calls:
        a, b = qmc.sample_2d(index, seeds, dim, count), sample_2d(index, seeds, dim, count)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


def test_a_render_sampler_gives_the_same_pairs():
    require_compiled()
    from engine.sampling.sobol_jit import sample_2d
    numpy_sampler = qmc.SobolSampler(3, 64, 0, 128, 64, 16, 2)
    compiled = qmc.SobolSampler(3, 64, 0, 128, 64, 16, 2)
    compiled.kernel = sample_2d
    rng = np.random.default_rng(1)
    pixel, index = rng.integers(0, 64 * 64, 20000), rng.integers(0, 32, 20000)
    for dim, light in ((0, False), (5, True), (rng.integers(0, 30, 20000), False)):
        a, b = numpy_sampler.pair(pixel, index, dim, light), compiled.pair(pixel, index, dim, light)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    # Control: another seed's points differ.
    other = qmc.SobolSampler(4, 64, 0, 128, 64, 16, 2)
    other.kernel = sample_2d
    assert not np.array_equal(numpy_sampler.pair(pixel, index, 0)[0], other.pair(pixel, index, 0)[0])


def test_the_seeded_kernel_gives_the_same_pairs():
    """sample_2d_seeded (the pixel seed and the dimension hash read inside the loop) against
    SobolSampler.pair's NumPy gather and qmc.sample_2d: int32 and int64 dims inside and beyond the
    dimension-hash table, a single dim, light nets; control: a neighbouring pixel's seeds differ."""
    require_compiled()
    from engine.sampling.sobol_jit import sample_2d_seeded
    rng = np.random.default_rng(2)
    numpy_sampler = qmc.SobolSampler(7, 0, 32, 64, 96, 64, 4)
    seeded = qmc.SobolSampler(7, 0, 32, 64, 96, 64, 4)
    seeded.seeded_kernel = sample_2d_seeded
    n = 30000
    pixel, index = rng.integers(0, 64 * 64, n), rng.integers(0, 256, n)
    for dim, light in ((0, False), (1023, True), (1024, False), (rng.integers(0, 40, n).astype(np.int32), False),
                       (rng.integers(0, 3000, n), True), (1 + 4 * rng.integers(0, 9, n).astype(np.int32), False)):
        a, b = numpy_sampler.pair(pixel, index, dim, light), seeded.pair(pixel, index, dim, light)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    shifted = sample_2d_seeded(index, (pixel + 1) % (64 * 64), numpy_sampler.pixel_seed, 5, 64)
    assert not np.array_equal(numpy_sampler.pair(pixel, index, 5)[0], shifted[0])


@pytest.mark.parametrize("count", [1, 2, 1000, 1 << 20])
def test_the_seeded_kernel_at_every_net_size(count):
    """Nets of 1 point (no index bits: qmc.permute's zeros), 2, 1000 and 2^20 (a 32-bit key's shifts)."""
    require_compiled()
    from engine.sampling.sobol_jit import sample_2d_seeded
    rng = np.random.default_rng(count)
    n = 4096
    table = rng.integers(0, 2**32, 300, dtype=np.uint64).astype(np.uint32)
    pixel, index = rng.integers(0, 300, n), rng.integers(0, count, n)
    for dim in (0, 2000, rng.integers(0, 5000, n)):
        a, b = qmc.sample_2d(index, table.take(pixel), dim, count), sample_2d_seeded(index, pixel, table, dim, count)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


def test_the_seeded_kernel_on_no_paths():
    require_compiled()
    from engine.sampling.sobol_jit import sample_2d_seeded
    empty = np.zeros(0, np.int64)
    x, y = sample_2d_seeded(empty, empty, np.arange(4, dtype=np.uint32), empty, 16)
    assert x.shape == (0,) and y.shape == (0,)
