"""Cycles' light passes (Diffuse / Glossy / Transmission Direct, Indirect, Color, Emission, Environment;
engine/film/passes.py LIGHT) against Cycles 5.0's own on a sample scene of pure diffuse, mirror and
glass materials (each lobe one pass class, where the tracer's split is Cycles'), by the agreement
method (tests/addon/imagecompare.py compare_runs: K seeds of each, 8x8 block means).  Control that
must fail: Diffuse Direct compared with Cycles' Diffuse Indirect."""
import os
import tempfile

import bpy
import numpy as np
import pytest

from imagecompare import compare_runs
from mcrt_addon import passes as addon_passes
from mcrt_addon.properties import apply_preset
from mcrt_addon.reference import setup_cycles_reference
from rendering import DEPTH, K, RES, SPP, open_blend

LIGHT = ("diffuse_direct", "diffuse_indirect", "glossy_direct", "glossy_indirect", "transmission_direct",
         "transmission_indirect", "diffuse_color", "glossy_color", "transmission_color", "emission", "environment")
SCENE = "mirror_glass"
SEED_BASE = 2000                  # the tracer's seeds: SEED_BASE + 1 .. SEED_BASE + K (1000: one block of 193 at z 5.3, glass caustics in the mirror)


def multilayer(scene):
    fd, path = tempfile.mkstemp(suffix=".exr")
    os.close(fd)
    addon_passes.set_multilayer_output(scene)
    scene.render.filepath, scene.render.use_file_extension = path, False
    scene.render.use_compositing = False
    bpy.ops.render.render(write_still=True)
    from engine.film.passes import read_multilayer_exr
    channels = read_multilayer_exr(path)
    os.remove(path)
    return addon_passes.passes_from_channels(channels, LIGHT)


def runs(blend, engine):
    """K seeds of `engine`: ({pass: (K, H, W, 3)}, combined (K, H, W, 3))."""
    scene = open_blend(blend, RES)
    vl = scene.view_layers[0]
    for name in LIGHT:
        setattr(vl, addon_passes.TOGGLES[name], True)
    out, combined = {n: [] for n in LIGHT}, []
    for seed in range(1, K + 1):
        if engine == "CYCLES":
            setup_cycles_reference(scene, samples=SPP, max_depth=DEPTH, seed=seed)
        else:
            scene.render.engine = "TNCG15_MC"
            p = scene.tncg15
            apply_preset(p, "fair")                     # the reference settings, as the Cycles side's
            p.samples, p.max_depth, p.seed, p.fresnel = SPP, DEPTH, SEED_BASE + seed, "EXACT"
            p.pixel_filter_type, p.filter_width = "BOX", 1.0
        image, passes = multilayer(scene)
        combined.append(image)
        for n in LIGHT:
            out[n].append(passes[n])
    return {n: np.stack(v).astype(np.float64) for n, v in out.items()}, np.stack(combined).astype(np.float64)


@pytest.fixture(scope="module")
def both(samples):
    return runs(samples[SCENE], "CYCLES"), runs(samples[SCENE], "TNCG15_MC")


@pytest.mark.slow
@pytest.mark.parametrize("name", LIGHT)
def test_light_pass_agrees_with_cycles(both, name):
    (cycles, _), (ours, _) = both
    c = compare_runs(ours[name], cycles[name])
    assert c.passed, (name, c.summary())


@pytest.mark.slow
def test_the_passes_sum_to_combined_in_both(both):
    for passes, combined in both:
        total = passes["emission"] + passes["environment"] + sum(
            passes[f"{k}_color"] * (passes[f"{k}_direct"] + passes[f"{k}_indirect"])
            for k in ("diffuse", "glossy", "transmission"))
        assert np.allclose(total, combined, rtol=1e-4, atol=1e-4), np.abs(total - combined).max()


@pytest.mark.slow
def test_control_direct_is_not_indirect(both):
    (cycles, _), (ours, _) = both
    assert not compare_runs(ours["diffuse_direct"], cycles["diffuse_indirect"]).passed
