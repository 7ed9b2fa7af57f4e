"""TNCG15 MC's film agrees with Cycles' (bpy 5.0): the pixel filter's blur of an edge, and the alpha of
a transparent film; each with a control that must fail.

* Edge: a lamp plane fills the right part of the view, its edge 0.3 px off a pixel boundary, against a
  black world: a pixel's value is the fraction of its samples that land on the lamp, so the column
  profile (the mean over the rows) is the step blurred by the filter.  Cycles and TNCG15 MC with
  Blackman-Harris 1.5 px (Cycles' default), K = 4 seeds at 64 x 64 and 32 spp; every column within the
  Sidak-corrected z bound plus PROFILE_TOLERANCE.  Control: TNCG15 MC's box of width 1 px fails.
* Alpha: sky_lit (the world is the only light, the camera sees sky above the horizon) with Film >
  Transparent: alpha and the premultiplied colour by the method of tests/addon/test_agreement.py
  (8 x 8 block means and the image mean).  Control: the opaque film (alpha 1) fails.
"""
import numpy as np
import pytest
from scipy.stats import norm

from imagecompare import compare_runs
from rendering import DEPTH, K, RES, SPP, export_blend, open_blend

from mcrt_addon.headless import set_exr_output
from mcrt_addon.reference import FilmSettings, setup_cycles_reference

EDGE_PX = 0.1                    # the lamp's edge, in pixels right of the central pixel boundary
# Cycles sees the edge about 0.01 px further left than TNCG15 MC, with the box filter too (the column
# next to the edge differs by ~0.01 with 32 spp x 64 rows x 4 seeds); each column may differ by this
# much besides the noise.  The control (box against Blackman-Harris) differs by ~0.06.
PROFILE_TOLERANCE = 0.02


def read_rgba(path):
    import OpenImageIO as oiio
    buf = oiio.ImageBuf(path)
    pixels = np.asarray(buf.get_pixels(oiio.FLOAT), dtype=np.float64)
    return pixels if pixels.shape[-1] == 4 else np.concatenate([pixels, np.ones(pixels.shape[:2] + (1,))], -1)


def cycles_rgba(blend, film, tmp_path):
    """K Cycles renders (seeds 1..K) of `blend` at RES with `film`: (K, H, W, 4) premultiplied RGBA."""
    import bpy
    scene = open_blend(str(blend), RES)
    out = []
    for seed in range(1, K + 1):
        setup_cycles_reference(scene, samples=SPP, max_depth=DEPTH, seed=seed, film=film)
        path = str(tmp_path / f"cycles-{seed}.exr")
        set_exr_output(scene, path)
        bpy.ops.render.render(write_still=True)
        out.append(read_rgba(path))
    return np.stack(out)


def ours_rgba(blend, tmp_path, **film):
    """K TNCG15 MC renders (seeds 1000..) of the exported `blend`: (K, H, W, 4)."""
    from mcrt_addon import bridge
    exported = export_blend(str(blend), RES)
    render, Settings = bridge.render_function(), bridge.settings_class()
    out = []
    for seed in range(1000, 1000 + K):
        result = render(exported.scene, Settings(samples=SPP, max_depth=DEPTH, seed=seed, fresnel="exact", **film),
                        log=lambda *a: None)
        alpha = np.ones(result.image.shape[:2]) if result.alpha is None else result.alpha
        out.append(np.concatenate([result.image, alpha[..., None]], axis=-1).astype(np.float64))
    return np.stack(out)


@pytest.fixture(scope="module")
def edge_blend(tmp_path_factory, make_samples_module):
    import bpy
    ms = make_samples_module
    scene = ms.reset()
    scene.name = "edge"
    ms.camera(scene)                                      # (0, -3.9, 1) looking along +y, lens 50
    ms.black_world(scene)
    metres_per_px = 36.0 / 50.0 * 3.9 / RES[0]            # the view's width at y = 0 over the pixels
    x = EDGE_PX * metres_per_px
    ms.plane(scene, "Lamp", [(x, 0, -4), (x, 0, 6), (6, 0, 6), (6, 0, -4)], ms.emission("Lamp", (1, 1, 1), 1.0))
    ms.settings(scene, RES)
    path = tmp_path_factory.mktemp("film") / "edge.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), check_existing=False)
    return path


def profiles_agree(ours, ref, alpha=0.01):
    """(passed, worst excess over the bound, largest difference): the column profiles (mean over rows
    and channels) of K runs each, every column within the Sidak-corrected bound of its standard
    error plus PROFILE_TOLERANCE."""
    po, pr = ours[..., :3].mean(axis=(1, 3)), ref[..., :3].mean(axis=(1, 3))      # (K, W)
    se = np.sqrt(po.var(0, ddof=1) / len(po) + pr.var(0, ddof=1) / len(pr) + 1e-8)
    delta = np.abs(po.mean(0) - pr.mean(0))
    z_crit = norm.isf((1.0 - (1.0 - alpha) ** (1.0 / delta.size)) / 2)
    excess = delta - (z_crit * se + PROFILE_TOLERANCE)
    return bool((excess <= 0).all()), float(excess.max()), float(delta.max())


@pytest.mark.slow
def test_pixel_filter_blurs_an_edge_as_cycles(edge_blend, tmp_path):
    ref = cycles_rgba(edge_blend, FilmSettings("blackman-harris", 1.5), tmp_path)
    ours = ours_rgba(edge_blend, tmp_path, pixel_filter="blackman-harris", filter_width=1.5)
    column = ref[..., 0].mean(axis=(0, 1))
    assert column[RES[0] // 2 - 1] > 0.03 and column[RES[0] // 2] < 0.97       # blurred beyond the edge pixel
    ok, excess, delta = profiles_agree(ours, ref)
    assert ok, f"Blackman-Harris 1.5 px: a column differs by {delta:.4f} ({excess:.4f} over the bound)"
    box_ok, _, box_delta = profiles_agree(ours_rgba(edge_blend, tmp_path), ref)         # control
    assert not box_ok, f"the control (box 1 px) passed: largest column difference {box_delta:.4f}"


@pytest.mark.slow
def test_transparent_film_alpha_agrees_with_cycles(samples, tmp_path):
    blend = samples["sky_lit"]
    ref = cycles_rgba(blend, FilmSettings(transparent=True), tmp_path)
    ours = ours_rgba(blend, tmp_path, film_transparent=True)
    sky = ref[..., 3].mean()
    assert 0.05 < 1.0 - sky < 0.95                          # some sky is seen
    as_colour = (lambda runs: np.repeat(runs[..., 3:4], 3, axis=-1))
    alpha = compare_runs(as_colour(ours), as_colour(ref))
    colour = compare_runs(ours[..., :3], ref[..., :3])
    assert alpha.passed, alpha
    assert colour.passed, colour
    opaque = ours_rgba(blend, tmp_path)                    # control: the opaque film
    assert not compare_runs(as_colour(opaque), as_colour(ref)).passed
