"""Fast checks of the procedural texture kernels (engine/nodes/procedural/): the hashes against
values computed by compiling Cycles' C code (intern/cycles/util/hash.h, lookup3 and PCG), a few
pixels recorded from Cycles 5.0 renders (tests/nodes/test_procedural_cycles.py checks every pixel,
slow), the per-point octave masks, the kernel contract and the version switches."""
import types

import numpy as np
import pytest

from engine.core.errors import SceneError
from engine.nodes.procedural import KERNELS
from engine.nodes.procedural.hash import (float_bits, hash_float_n_to_float, hash_pcg2d_i,
                                          hash_pcg3d_i, hash_pcg4d_i, hash_uint, hash_uint2,
                                          hash_uint3, hash_uint4)
from engine.nodes.procedural.perlin import perlin, snoise


def a(*v):
    return [np.array([x]) for x in v]


def ctx(n, version=(5, 0)):
    return types.SimpleNamespace(n=n, cycles_version=version)


# Printed by a C program with hash.h's rot/mix/final macros and hash_pcg*_i (gcc -O0).
def test_lookup3_hashes_equal_cycles_c_code():
    assert list(hash_uint(np.array([0, 1, 0xFFFFFFFF], dtype=np.uint32))) == [2501500005, 1255655072, 1116397369]
    assert hash_uint2(*a(0, 0))[0] == 3695015161 and hash_uint2(*a(7, -3))[0] == 454448407
    assert hash_uint3(*a(1, 2, 3))[0] == 3100736010 and hash_uint3(*a(-1, -2, 5))[0] == 3440264291
    assert hash_uint4(*a(1, 2, 3, 4))[0] == 92593857 and hash_uint4(*a(-9, 0, 17, -1))[0] == 1941401154
    assert hash_float_n_to_float(np.float32([0.5]))[0] == np.float32(0.983314931)
    k = [np.float32([v]) for v in (1.25, -3.5, 100.0)]
    assert hash_float_n_to_float(*k)[0] == np.float32(0.536102414)


def test_pcg_hashes_equal_cycles_c_code():
    assert [int(v[0]) for v in hash_pcg2d_i(*a(0, 5))] == [919735224, 1560739074]
    assert [int(v[0]) for v in hash_pcg2d_i(*a(-7, 123456))] == [1535265053, 310643102]
    assert [int(v[0]) for v in hash_pcg3d_i(*a(1, -2, 3))] == [908989604, 457968326, 792426977]
    assert [int(v[0]) for v in hash_pcg4d_i(*a(1, -2, 3, -4))] == [1763984726, 1588721378, 1422690215, 1711506339]


def test_float_bits_are_float32_patterns():
    assert float_bits(np.array([1.0]))[0] == 0x3F800000
    assert float_bits(np.array([-0.0]))[0] == 0x80000000


def test_perlin_vanishes_on_the_lattice_and_is_not_constant():
    ints = [np.arange(-3, 4, dtype=np.float32)]
    for d in (1, 2, 3, 4):
        assert np.all(perlin(tuple(ints * d)) == 0)
        x = np.linspace(0.1, 3.3, 50, dtype=np.float32)
        assert np.ptp(snoise(tuple(x * (i + 1) for i in range(d)))) > 0.1


def test_snoise_of_blender_42_wraps_coordinates_at_100000():
    x = np.float32([0.3, 7.7])
    far = x + np.float32(200000.0)
    assert np.allclose(snoise((far, x, x)), snoise((x, x, x)), atol=1e-2)
    assert not np.allclose(snoise((far, x, x), (4, 1)), snoise((x, x, x), (4, 1)), atol=1e-2)


# Pixels of Cycles 5.0 renders (tests/nodes/test_procedural_cycles.py cases) at four pixel centres.
PIXELS = np.array([(-0.984375, 0.984375, 0.37), (-0.703125, 0.609375, 0.37),
                   (-0.921875, -0.015625, 0.37), (0.984375, -0.984375, 0.37)]).T
CYCLES_50 = [
    ("ShaderNodeTexNoise", {"noise_dimensions": "3D"}, {"Scale": 3.0, "Detail": 2.0}, "Fac",
     [0.5269322395324707, 0.5429136157035828, 0.6017270088195801, 0.47077253460884094]),
    ("ShaderNodeTexNoise", {"noise_dimensions": "4D"}, {"Scale": 3.0, "Detail": 2.3, "Distortion": 0.5},
     "Fac", [0.5642584562301636, 0.4997905194759369, 0.5160856246948242, 0.37766414880752563]),
    ("ShaderNodeTexNoise", {"noise_type": "RIDGED_MULTIFRACTAL"},
     {"Scale": 2.0, "Detail": 4.0, "Offset": 1.0, "Gain": 2.0}, "Fac",
     [1.0383278131484985, 1.262251853942871, 1.2770977020263672, 1.6991807222366333]),
    ("ShaderNodeTexVoronoi", {"feature": "F1"}, {"Scale": 3.0}, "Distance",
     [0.5911564826965332, 0.6443243622779846, 0.24784539639949799, 0.5751489996910095]),
    ("ShaderNodeTexVoronoi", {"feature": "F2"}, {"Scale": 3.0, "Randomness": 0.8}, "Distance",
     [0.8178884387016296, 0.7304954528808594, 0.6188759207725525, 0.7908111810684204]),
    ("ShaderNodeTexVoronoi", {"feature": "SMOOTH_F1"}, {"Scale": 3.0, "Smoothness": 0.6}, "Distance",
     [0.5844525098800659, 0.6035149097442627, 0.24784541130065918, 0.563398540019989]),
    ("ShaderNodeTexVoronoi", {"feature": "F1", "distance": "CHEBYCHEV", "voronoi_dimensions": "4D"},
     {"Scale": 3.0}, "Distance",
     [0.38638177514076233, 0.43758827447891235, 0.535607099533081, 0.41395020484924316]),
    ("ShaderNodeTexMagic", {"turbulence_depth": 5}, {"Distortion": 2.5}, "Fac",
     [0.4458599090576172, 0.6887609958648682, 0.14923794567584991, 0.36158525943756104]),
    ("ShaderNodeTexBrick", {"offset": 0.3, "offset_frequency": 3, "squash": 0.6, "squash_frequency": 2},
     {"Scale": 3.0, "Mortar Size": 0.05, "Mortar Smooth": 0.4, "Bias": 0.2}, "Color",
     [0.24845421314239502, 0.263150155544281, 0.18687744438648224, 0.18898236751556396]),
]


@pytest.mark.parametrize("bl_idname,props,inputs,output,expected", CYCLES_50,
                         ids=[f"{c[0][13:]}-{i}" for i, c in enumerate(CYCLES_50)])
def test_kernels_give_the_pixels_of_cycles_50(bl_idname, props, inputs, output, expected):
    got = KERNELS[bl_idname]({"Vector": PIXELS, "W": PIXELS[0], **inputs}, props, ctx(4))[output]
    got = got[0] if got.ndim == 2 else got
    assert np.allclose(got, expected, rtol=0, atol=3e-6), (got, expected)
    wrong = KERNELS[bl_idname]({"Vector": PIXELS, "W": PIXELS[0], **inputs,
                                "Scale": inputs.get("Scale", 5.0) * 1.01}, props, ctx(4))[output]
    wrong = wrong[0] if wrong.ndim == 2 else wrong
    assert not np.allclose(wrong, expected, rtol=0, atol=3e-6)


@pytest.mark.parametrize("bl_idname,props", [
    ("ShaderNodeTexNoise", {"noise_type": "FBM"}),
    ("ShaderNodeTexNoise", {"noise_type": "HYBRID_MULTIFRACTAL"}),
    ("ShaderNodeTexVoronoi", {"feature": "F1", "normalize": True}),
    ("ShaderNodeTexVoronoi", {"feature": "DISTANCE_TO_EDGE"}),
])
def test_per_point_detail_equals_one_call_per_detail(bl_idname, props):
    """Octave loops run to the batch's largest Detail with a mask: each point as if alone."""
    rng = np.random.default_rng(3)
    pts = rng.uniform(-1, 1, (3, 12))
    detail = np.repeat([0.0, 1.5, 3.0, 2.25], 3)
    kernel = KERNELS[bl_idname]
    out = "Fac" if "Noise" in bl_idname else "Distance"
    together = kernel({"Vector": pts, "Detail": detail, "Offset": np.full(12, 0.5)}, props, ctx(12))[out]
    for d in np.unique(detail):
        m = detail == d
        alone = kernel({"Vector": pts[:, m], "Detail": np.full(m.sum(), d), "Offset": np.full(m.sum(), 0.5)},
                       props, ctx(int(m.sum())))[out]
        assert np.array_equal(together[m], alone)


OUTPUTS = {"ShaderNodeTexNoise": {"Fac": 1, "Color": 3}, "ShaderNodeTexMusgrave": {"Fac": 1},
           "ShaderNodeTexVoronoi": {"Distance": 1, "Color": 3, "Position": 3, "W": 1, "Radius": 1},
           "ShaderNodeTexWave": {"Fac": 1, "Color": 3}, "ShaderNodeTexGradient": {"Fac": 1, "Color": 3},
           "ShaderNodeTexMagic": {"Fac": 1, "Color": 3}, "ShaderNodeTexChecker": {"Fac": 1, "Color": 3},
           "ShaderNodeTexBrick": {"Fac": 1, "Color": 3}, "ShaderNodeTexWhiteNoise": {"Value": 1, "Color": 3}}


@pytest.mark.parametrize("bl_idname", sorted(OUTPUTS))
def test_kernel_contract(bl_idname):
    """Every output as float64: floats (N,), colours and vectors rows (3, N); finite."""
    pts = np.random.default_rng(5).uniform(-2, 2, (3, 7))
    out = KERNELS[bl_idname]({"Vector": pts}, {}, ctx(7))
    assert set(out) == set(OUTPUTS[bl_idname])
    for name, rows in OUTPUTS[bl_idname].items():
        assert out[name].dtype == np.float64
        assert out[name].shape == ((7,) if rows == 1 else (3, 7)), name
        assert np.all(np.isfinite(out[name]))


def test_noise_skips_color_when_ctx_names_the_outputs_in_use():
    c = ctx(5)
    c.outputs = {"Fac"}
    out = KERNELS["ShaderNodeTexNoise"]({"Vector": np.zeros((3, 5)) + 0.3}, {}, c)
    assert set(out) == {"Fac"}


def test_voronoi_hashes_follow_the_blender_version():
    """5.0 hashes 2-D..4-D cells with PCG, 3.x-4.5 with lookup3; 1-D never changed."""
    pts = np.random.default_rng(2).uniform(-1, 1, (3, 64))
    k = KERNELS["ShaderNodeTexVoronoi"]
    for dims, same in (("3D", False), ("2D", False), ("1D", True)):
        props = {"voronoi_dimensions": dims}
        new = k({"Vector": pts, "W": pts[0]}, props, ctx(64, (5, 0)))["Distance"]
        old = k({"Vector": pts, "W": pts[0]}, props, ctx(64, (4, 5)))["Distance"]
        assert np.array_equal(new, old) == same, dims


@pytest.mark.parametrize("bl_idname,props", [
    ("ShaderNodeTexNoise", {"noise_type": "PERLIN"}), ("ShaderNodeTexVoronoi", {"distance": "L3"}),
    ("ShaderNodeTexVoronoi", {"voronoi_dimensions": "5D"}), ("ShaderNodeTexWave", {"wave_profile": "SQUARE"}),
    ("ShaderNodeTexGradient", {"gradient_type": "CONE"})])
def test_unknown_enum_values_raise_scene_errors_naming_the_node(bl_idname, props):
    with pytest.raises(SceneError, match="Texture"):
        KERNELS[bl_idname]({"Vector": np.zeros((3, 2))}, props, ctx(2))


# -- the family modules' building blocks --------------------------------------------------------

def test_brick_noise_and_random_offsets_equal_cycles_c_code():
    from engine.nodes.procedural.brick import brick_noise
    from engine.nodes.procedural.noise import random_offset
    keys = np.array([0, (3 << 16) + (-2 & 0xFFFF), ((-5 << 16) + 7) & 0xFFFFFFFF])
    assert list(brick_noise(keys)) == [np.float32(v) for v in (0.263250649, 0.0457506068, 0.575086892)]
    assert random_offset(0.0, 1) == (np.float32(158.242584),)
    assert random_offset(3.0, 3) == tuple(np.float32(v) for v in (165.445282, 162.768219, 193.408417))


def test_checker_parity_of_cells():
    from engine.nodes.procedural.checker import checker
    p = tuple(np.float32(v) for v in ([0.5, 1.5, 1.5, -0.5], [0.5, 0.5, 1.5, 0.5], [0.5, 0.5, 0.5, 0.5]))
    assert list(checker(p)) == [0.0, 1.0, 0.0, 1.0]


def test_fbm_of_detail_zero_is_one_octave_of_unsigned_noise():
    from engine.nodes.procedural.fractal import fbm
    from engine.nodes.procedural.perlin import unoise
    x = np.linspace(0.1, 4.0, 20, dtype=np.float32)
    p = (x, x * np.float32(0.7), x * np.float32(1.3))
    one = np.ones(20, dtype=np.float32)
    assert np.array_equal(fbm(p, one * 0, one * 0.5, one * 2, True), unoise(p))


def test_gradient_types_at_known_points():
    from engine.nodes.procedural.gradient import gradient
    f = np.float32
    assert gradient(f(0.25), f(0), f(0), "LINEAR") == f(0.25)
    assert gradient(f(0.5), f(0), f(0), "EASING") == f(0.5)
    assert gradient(f(0), f(1), f(0), "RADIAL") == f(0.75)
    assert gradient(f(0.6), f(0.8), f(0), "SPHERICAL") == f(0)


def test_magic_without_turbulence_or_distortion_is_its_first_sines():
    from engine.nodes.procedural.magic import magic
    p = tuple(np.float32([v]) for v in (0.1, 0.2, 0.3))
    x, y, z = magic(p, np.float32(1.0), 0, np.float32([0.0]))
    assert np.isclose(x[0], 0.5 - np.sin(3.0), atol=1e-6)
    assert np.isclose(y[0], 0.5 - np.cos(-1.0), atol=1e-6)
    assert np.isclose(z[0], 0.5 + np.cos(0.0), atol=1e-6)


def test_voronoi_without_randomness_measures_to_the_lattice():
    """Randomness 0 puts every feature point on its cell's corner: F1 = distance to the nearest
    integer point, in each metric."""
    from engine.nodes.procedural.voronoi import Cells, f1
    rng = np.random.default_rng(4)
    p = tuple(rng.uniform(-3, 3, 200).astype(np.float32) for _ in range(3))
    d = [np.abs(c - np.round(c)) for c in p]
    zero = np.float32(0.0)
    for metric, expect in (("EUCLIDEAN", np.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)),
                           ("MANHATTAN", d[0] + d[1] + d[2]), ("CHEBYCHEV", np.maximum(np.maximum(d[0], d[1]), d[2]))):
        dist, _, _ = f1(Cells(3, (5, 0), metric, np.float32(1.0)), p, zero)
        assert np.allclose(dist, expect, atol=1e-6), metric


def test_choice_names_the_node_and_the_allowed_values():
    from engine.nodes.procedural.common import choice
    assert choice({}, "wave_type", ("BANDS", "RINGS"), "BANDS", "Wave Texture") == "BANDS"
    with pytest.raises(SceneError, match="Wave Texture: wave_type 'X' is not one of BANDS, RINGS"):
        choice({"wave_type": "X"}, "wave_type", ("BANDS", "RINGS"), "BANDS", "Wave Texture")


def test_wave_bands_and_rings_follow_their_formulas():
    from engine.nodes.procedural.wave import wave
    x = np.linspace(-1, 1, 33)
    p = tuple(np.asarray(c, dtype=np.float32) for c in (x, x * 0.5, x * 0.25))
    zero, one = np.zeros(33, np.float32), np.ones(33, np.float32)
    q = [(c + 1e-6) * 0.999999 for c in (x, x * 0.5, x * 0.25)]
    bands = wave(p, {}, zero, one, one, one, zero, (5, 0))
    assert np.allclose(bands, 0.5 + 0.5 * np.sin(q[0] * 20 - np.pi / 2), atol=2e-6)
    rings = wave(p, {"wave_type": "RINGS", "rings_direction": "SPHERICAL", "wave_profile": "SAW"},
                 zero, one, one, one, zero, (5, 0))
    n = np.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2) * 20 / (2 * np.pi)
    assert np.allclose(rings, n - np.floor(n), atol=2e-6)


def test_white_noise_hashes_the_float32_bits_of_its_input():
    from engine.nodes.procedural.white_noise import white_noise_texture
    w = np.array([0.25, 0.25, np.nextafter(np.float32(0.25), np.float32(1))], dtype=np.float64)
    out = white_noise_texture({"Vector": np.zeros((3, 3)), "W": w}, {"noise_dimensions": "1D"}, ctx(3))
    assert out["Value"][0] == out["Value"][1] != out["Value"][2]
    assert out["Value"][0] == hash_float_n_to_float(np.float32([0.25]))[0]


@pytest.mark.parametrize("bl_idname", sorted(OUTPUTS))
def test_non_finite_and_huge_coordinates_raise_no_warning(bl_idname):
    import warnings
    pts = np.array([[np.nan, np.inf, 1e10, -1e12, 0.5], [0.1, 0.2, 0.3, 1e9, -np.inf], [0, 0, 0, 0, 0.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = KERNELS[bl_idname]({"Vector": pts, "W": pts[0]}, {}, ctx(5))
    assert all(v.shape[-1] == 5 for v in out.values())


@pytest.mark.parametrize("props,version", [
    ({"feature": "F1"}, (5, 0)), ({"feature": "SMOOTH_F1", "voronoi_dimensions": "2D"}, (5, 0)),
    ({"feature": "F2", "voronoi_dimensions": "4D"}, (4, 5)), ({"feature": "N_SPHERE_RADIUS"}, (5, 0)),
    ({"feature": "DISTANCE_TO_EDGE", "voronoi_dimensions": "1D"}, (3, 4))])
def test_voronoi_hashes_per_distinct_cell_equal_hashes_per_point(monkeypatch, props, version):
    """Grid hashes a neighbour once per distinct cell when points share cells: same bits."""
    from engine.nodes.procedural import voronoi
    pts = np.random.default_rng(6).uniform(-1, 1, (3, 3000))
    inputs = {"Vector": pts, "W": pts[0], "Scale": np.full(3000, 2.0)}
    shared = voronoi.voronoi_texture(inputs, props, ctx(3000, version))
    assert voronoi.Grid(tuple(np.floor(c * 2).astype(np.float32) for c in pts), None).rep is not None
    monkeypatch.setattr(voronoi.Grid, "MIN_POINTS", 10 ** 9)
    alone = voronoi.voronoi_texture(inputs, props, ctx(3000, version))
    for name in alone:
        assert np.array_equal(shared[name], alone[name]), name


def test_musgrave_fbm_of_detail_one_is_one_signed_octave_and_detail_counts_octaves():
    """Blender 3.x's Musgrave loops `i < (int)detail`: Detail 1 is one snoise octave (not two, as
    the Noise Texture's `<=` would give), Detail 1.5 adds half the next."""
    from engine.nodes.procedural.musgrave import musgrave
    x = np.linspace(0.1, 4.0, 20, dtype=np.float32)
    p = (x, x * np.float32(0.7), x * np.float32(1.3))
    one = np.ones(20, dtype=np.float32)
    lac, pwhl = one * 2, one * np.float32(0.25)
    assert np.array_equal(musgrave("FBM", p, pwhl, lac, one, one * 0, one), snoise(p, (3, 4)))
    half = musgrave("FBM", p, pwhl, lac, one * 1.5, one * 0, one)
    second = snoise(tuple(c * np.float32(2) for c in p), (3, 4))
    assert np.allclose(half, snoise(p, (3, 4)) + 0.5 * second * 0.25, atol=1e-7)
