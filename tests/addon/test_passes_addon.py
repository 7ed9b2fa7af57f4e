"""Render passes and Denoise in Blender (bpy 5.0): registered with Cycles' names, filled with the
tracer's values, written by Blender's multi-layer EXR; the compositor sees them."""
import os
import tempfile

import bpy
import numpy as np
import pytest

from mcrt_addon import passes as addon_passes
from rendering import export_blend, last_report, open_blend

RES = (40, 32)


def setup(scene, denoise=False, data=True):
    p = scene.tncg15
    p.samples, p.seed, p.tile_size, p.max_depth = 4, 5, 16, 3
    p.use_denoising = denoise
    scene.render.engine = "TNCG15_MC"
    vl = scene.view_layers[0]
    vl.use_pass_z = data
    vl.tncg15.denoising_store_passes = data
    vl.tncg15.pass_sample_count = data
    vl.tncg15.pass_variance = data


def render_multilayer(scene):
    fd, path = tempfile.mkstemp(suffix=".exr")
    os.close(fd)
    s = scene.render.image_settings
    if hasattr(s, "media_type"):                  # 5.0: multi-layer is a media type
        s.media_type = "MULTI_LAYER_IMAGE"
    else:
        s.file_format = "OPEN_EXR_MULTILAYER"
    s.color_depth = "32"
    scene.render.filepath = path
    scene.render.use_file_extension = False
    scene.render.use_compositing = False
    bpy.ops.render.render(write_still=True)
    from engine.film.passes import read_multilayer_exr
    channels = read_multilayer_exr(path)
    os.remove(path)
    return channels


def layer(channels, name, chans):
    return np.stack([channels[f"ViewLayer.{name}.{c}"] for c in chans], axis=-1)     # EXR: top row first


def test_addon_names_are_the_tracers():
    from engine.film.passes import BLENDER_NAME, CHANNELS
    for name, (blender, n, chan_id, _) in addon_passes.BLENDER_PASSES.items():
        assert BLENDER_NAME[name] == blender
        assert CHANNELS[name] == chan_id[:n] or (name == "noisy" and chan_id == "RGBA")


def test_passes_are_registered_filled_and_written(samples):
    scene = open_blend(samples["cornell"], RES)
    setup(scene)
    ch = render_multilayer(scene)
    assert last_report().error is None
    for name in ("Combined.R", "Depth.Z", "Denoising Albedo.R", "Denoising Normal.X", "Debug Sample Count.X",
                 "Variance.R"):
        assert f"ViewLayer.{name}" in ch, sorted(ch)
    assert last_report().passes == ["Combined", "Denoising Albedo", "Denoising Normal", "Depth",
                                    "Debug Sample Count", "Variance"]
    # the tracer's own passes for the exported scene and the same settings
    from mcrt_addon import bridge
    settings = scene.tncg15.to_settings(bridge.settings_class())
    settings.passes = ("albedo", "normal", "depth", "samples", "variance")
    ref = bridge.render_function()(export_blend(samples["cornell"], RES).scene, settings, log=lambda *a: None)
    np.testing.assert_allclose(layer(ch, "Depth", "Z"), ref.passes["depth"], rtol=1e-6)
    np.testing.assert_allclose(layer(ch, "Denoising Albedo", "RGB"), ref.passes["albedo"], atol=1e-6)
    np.testing.assert_allclose(layer(ch, "Denoising Normal", "XYZ"), ref.passes["normal"], atol=1e-6)
    np.testing.assert_allclose(layer(ch, "Combined", "RGB"), ref.image, rtol=1e-5, atol=1e-6)
    assert np.all(ch["ViewLayer.Debug Sample Count.X"] == 4.0)
    np.testing.assert_allclose(layer(ch, "Variance", "RGB"), ref.passes["variance"], rtol=1e-5, atol=1e-9)


def test_compositor_sees_the_registered_passes(samples):
    scene = open_blend(samples["cornell"], RES)
    setup(scene)
    if hasattr(scene, "compositing_node_group"):          # 5.0
        tree = bpy.data.node_groups.new("passes", "CompositorNodeTree")
        scene.compositing_node_group = tree
    else:
        scene.use_nodes = True
        tree = scene.node_tree
    node = tree.nodes.new("CompositorNodeRLayers")
    names = {s.name for s in node.outputs if s.enabled}
    assert {"Depth", "Denoising Albedo", "Denoising Normal", "Debug Sample Count", "Variance"} <= names, names
    scene.view_layers[0].tncg15.pass_variance = False
    node2 = tree.nodes.new("CompositorNodeRLayers")
    assert "Variance" not in {s.name for s in node2.outputs if s.enabled}


def test_passes_off_add_nothing(samples):
    scene = open_blend(samples["cornell"], RES)
    setup(scene, data=False)
    ch = render_multilayer(scene)
    assert not [c for c in ch if "Denoising" in c or "Variance" in c or "Depth" in c]
    assert last_report().passes == [] and last_report().stats["effects"]["passes"] is False


def test_denoise_in_blender(samples):
    pytest.importorskip("pyoidn", reason="pyoidn (requirements.txt) is not installed")
    scene = open_blend(samples["cornell"], RES)
    setup(scene, denoise=True, data=False)
    scene.tncg15.caustics_method = "PATH"          # its fireflies: the noise the denoiser must take away
    ch = render_multilayer(scene)
    report = last_report()
    assert report.error is None and report.stats.get("denoised") is True, report.warnings
    noisy, combined = layer(ch, "Noisy Image", "RGB"), layer(ch, "Combined", "RGB")
    assert not np.array_equal(noisy, combined)
    # the denoised image is smoother: less energy in pixel-to-pixel differences
    assert np.abs(np.diff(combined, axis=1)).mean() < 0.7 * np.abs(np.diff(noisy, axis=1)).mean()


@pytest.mark.slow          # 2-5 s (renders, subprocesses): make test-slow, which .ci/run runs too
def test_noisy_image_is_the_render_without_denoise(samples):
    """Sampling > Render > Denoise on: Combined is denoised and Noisy Image is, to the float, what
    the same render gives with Denoise off (the denoiser's albedo and normal passes change no sample)."""
    pytest.importorskip("pyoidn", reason="pyoidn (requirements.txt) is not installed")
    scene = open_blend(samples["cornell"], RES)
    setup(scene, denoise=False, data=False)
    plain = layer(render_multilayer(scene), "Combined", "RGB")
    scene.tncg15.use_denoising = True
    ch = render_multilayer(scene)
    assert last_report().stats.get("denoised") is True, last_report().warnings
    np.testing.assert_array_equal(layer(ch, "Noisy Image", "RGB"), plain)
    assert np.abs(layer(ch, "Combined", "RGB") - plain).mean() > 0.01 * plain.mean()


@pytest.mark.slow          # 2-5 s (renders, subprocesses): make test-slow, which .ci/run runs too
def test_addon_cli_writes_the_same_layers_as_the_tracer_cli(samples, tmp_path):
    """python -m mcrt_addon render --passes ...: Blender's multi-part EXR rewritten with the layers
    python -m engine render writes (engine/film/passes.py exr_channels), values as Blender filled them."""
    import subprocess
    import sys
    from engine.film.passes import exr_channels, read_multilayer_exr
    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out = tmp_path / "passes.exr"
    proc = subprocess.run([sys.executable, "-m", "mcrt_addon", "render", samples["cornell"], "-o", str(out),
                           "--resolution", "40", "32", "--samples", "4", "--seed", "5", "--max-depth", "3",
                           "--passes", "depth,samples,normal"], cwd=repo, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr
    ch = read_multilayer_exr(out)
    assert sorted(ch) == sorted(exr_channels(("normal", "depth", "samples")))
    assert np.all(ch["ViewLayer.Debug Sample Count.X"] == 4.0)
    z = ch["ViewLayer.Depth.Z"]
    assert np.isfinite(z).all() and 1.0 < np.median(z) < 20.0
    proc = subprocess.run([sys.executable, "-m", "mcrt_addon", "render", samples["cornell"], "-o",
                           str(tmp_path / "x.png"), "--passes", "depth"], cwd=repo, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 2 and "need an .exr output" in proc.stderr and "Traceback" not in proc.stderr


def test_denoise_unavailable_is_a_warning_not_a_failure(samples, monkeypatch):
    """No OIDN for the worker Python: the render stays (undenoised) with one warning naming the fix."""
    from mcrt_addon import bridge
    denoise = bridge.module("film.denoise")

    def unavailable(*a, **k):
        raise denoise.DenoiserUnavailable("Denoise needs Intel Open Image Denoise: 'pip install pyoidn' for /x/python")
    monkeypatch.setattr(denoise, "denoise_in_subprocess", unavailable)
    scene = open_blend(samples["cornell"], RES)
    setup(scene, denoise=True, data=False)
    ch = render_multilayer(scene)
    report = last_report()
    assert report.error is None and not report.stats.get("denoised")
    assert any("Denoise skipped" in w and "pip install pyoidn" in w for w in report.warnings), report.warnings
    assert layer(ch, "Combined", "RGB").mean() > 0.02


def agreement(ours, cycles, tol):
    """(fraction of pixels whose channels all agree within tol, |difference of the image means|)."""
    close = (np.abs(ours - cycles) <= tol).all(axis=-1).mean()
    return float(close), np.abs(ours.mean(axis=(0, 1)) - cycles.mean(axis=(0, 1)))


@pytest.mark.parametrize("name", ["cornell", "mirror_glass"])
def test_passes_agree_with_cycles(samples, name):
    """Cycles' own Denoising Albedo/Normal and Depth for the same file: the same pixels to within
    0.05 nearly everywhere (the rest: edges, where Cycles tessellates the spheres we trace exactly,
    and noisy paths through glass), image means within 1.5 %; controls: a normal in the other camera
    convention (z towards the viewer) and Z as the ray length both fail."""
    from mcrt_addon.reference import setup_cycles_reference
    res = (48, 48)
    scene = open_blend(samples[name], res)
    setup(scene)
    scene.tncg15.samples = 32
    # the box of 1 px, as the reference: per-pixel data at edges (Cycles' Z is one sample's)
    scene.tncg15.pixel_filter_type, scene.tncg15.filter_width = "BOX", 1.0
    ours = render_multilayer(scene)
    scene = open_blend(samples[name], res)
    setup_cycles_reference(scene, samples=32, max_depth=8, seed=1)
    scene.view_layers[0].use_pass_z = True
    scene.view_layers[0].cycles.denoising_store_passes = True
    cycles = render_multilayer(scene)
    albedo = layer(ours, "Denoising Albedo", "RGB"), layer(cycles, "Denoising Albedo", "RGB")
    normal = layer(ours, "Denoising Normal", "XYZ"), layer(cycles, "Denoising Normal", "XYZ")
    depth = np.minimum(layer(ours, "Depth", "Z"), 1e3), np.minimum(layer(cycles, "Depth", "Z"), 1e3)
    frac, mean_diff = agreement(*albedo, 0.05)
    assert frac > 0.9 and (mean_diff < 0.015 * albedo[1].mean(axis=(0, 1))).all(), (frac, mean_diff)
    frac, mean_diff = agreement(*normal, 0.05)
    assert frac > 0.9 and (mean_diff < 0.01).all(), (frac, mean_diff)
    assert agreement(*depth, 0.01 * depth[1])[0] > 0.95
    flipped = normal[0] * np.array([1.0, 1.0, -1.0], np.float32)
    assert agreement(flipped, normal[1], 0.05)[0] < 0.8        # side walls (z = 0) agree either way
    assert agreement(depth[0] * 1.05, depth[1], 0.01 * depth[1])[0] < 0.5
