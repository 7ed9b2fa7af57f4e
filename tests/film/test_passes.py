"""Render passes (engine/film/passes.py) against closed forms, their EXR layers, determinism, and the
denoiser (engine/film/denoise.py)."""
import os
import subprocess
import sys

import numpy as np
import pytest

from engine import RenderSettings, render
from engine.scene.builtin import cornell_scene
from engine.film.passes import NO_DEPTH, exr_channels, parse_passes, PassError, read_multilayer_exr
from engine.scene.model import DIFFUSE, MIRROR, Camera, Material, Quad, Scene

SILENT = dict(log=lambda *a: None)
ALL = ("albedo", "normal", "depth", "samples", "variance")
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def big_quad(name, z, material, size=50.0):
    s = size
    return Quad(name, np.array([(-s, -s, z), (s, -s, z), (s, s, z), (-s, s, z)], dtype=float), material)


def plane_seen_from(camera, color=(0.2, 0.5, 0.7), background=(0, 0, 0)):
    mats = [Material("Paint", DIFFUSE, color)]
    return Scene(camera, mats, quads=[big_quad("Floor", 0.0, 0)], background=background, resolution=(12, 8))


def test_diffuse_plane_albedo_normal_depth_closed_form():
    """Straight down from height 2 with a wide lens: albedo = colour, camera-space normal (0, 0, -1)
    (Cycles' camera space: z along the view),
    Z = 2 in every pixel although the rays' lengths differ by up to 60 % (Z is along the axis)."""
    cam = Camera.look_at((0.3, -0.2, 2.0), (0.3, -0.2, 0.0), up=(0, 1, 0), lens=12.0)
    r = render(plane_seen_from(cam), RenderSettings(samples=4, passes=ALL, threads=1), **SILENT)
    p = r.passes
    assert np.allclose(p["albedo"], (0.2, 0.5, 0.7), atol=1e-6)
    assert np.allclose(p["normal"], (0.0, 0.0, -1.0), atol=1e-6)
    assert np.allclose(p["depth"], 2.0, atol=1e-6)
    assert np.array_equal(p["samples"][..., 0], np.full((8, 12), 4.0))
    # negative control: the ray length (what a wrong Z would be) differs by far more than the tolerance
    corner = np.hypot(np.hypot(18.0 / 12.0, 12.0 / 12.0), 1.0) * 2.0
    assert corner - 2.0 > 0.5


def test_oblique_camera_normal_and_depth_in_camera_space():
    """A tilted camera: the floor's normal in camera space is axes^T (0, 0, 1) and Z at each
    pixel's hits is along the view axis (checked against the ray geometry by hand)."""
    cam = Camera.look_at((0.0, -3.0, 2.0), (0.0, 0.0, 0.0), lens=35.0)
    r = render(plane_seen_from(cam), RenderSettings(samples=8, passes=("normal", "depth"), threads=1), **SILENT)
    axes = np.asarray(cam.matrix)[:3, :3] * np.array([1.0, 1.0, -1.0])     # right, up, view direction
    expected_normal = axes.T @ np.array([0.0, 0.0, 1.0])
    assert np.allclose(r.passes["normal"], expected_normal, atol=1e-6)
    # the centre ray hits the look-at point, at distance |(0, -3, 2)| along the axis
    z = r.passes["depth"][..., 0]
    centre = z[3:5, 5:7].mean()
    assert abs(centre - np.sqrt(13.0)) < 0.15
    assert z[0].mean() > z[-1].mean()          # the top rows see farther floor


def test_features_through_a_mirror_and_the_background():
    """Camera straight down on a mirror floor (tint 0.5) under a diffuse ceiling: the albedo is
    0.5 x the ceiling's colour and the normal the ceiling's (facing the reflected ray, which goes
    back towards the camera: camera z +1), as Cycles' denoising features through perfect specular;
    Z is the mirror's.  Without the ceiling: albedo = 0.5 x the background (unclipped, as Cycles),
    normal 0, Z 1e10 where nothing is hit."""
    mats = [Material("Mirror", MIRROR, (0.5, 0.5, 0.5)), Material("Ceiling", DIFFUSE, (0.2, 0.4, 0.6))]
    cam = Camera.look_at((0, 0, 1.0), (0, 0, 0), up=(0, 1, 0), lens=30.0)
    scene = Scene(cam, mats, quads=[big_quad("Floor", 0.0, 0), big_quad("Ceiling", 3.0, 1)], resolution=(8, 8))
    p = render(scene, RenderSettings(samples=4, passes=ALL, threads=1), **SILENT).passes
    assert np.allclose(p["albedo"], (0.1, 0.2, 0.3), atol=1e-6)
    assert np.allclose(p["normal"], (0.0, 0.0, 1.0), atol=1e-6)
    assert np.allclose(p["depth"], 1.0, atol=1e-6)
    sky = Scene(cam, mats[:1], quads=[big_quad("Floor", 0.0, 0)], background=(0.3, 2.0, 0.0), resolution=(8, 8))
    p = render(sky, RenderSettings(samples=4, passes=ALL, threads=1), **SILENT).passes
    assert np.allclose(p["albedo"], (0.15, 1.0, 0.0), atol=1e-6)
    assert np.allclose(p["normal"], 0.0)
    up = Camera.look_at((0, 0, 1.0), (0, 0, 5.0), up=(0, 1, 0), lens=30.0)
    p = render(Scene(up, mats[:1], quads=[big_quad("Floor", 0.0, 0)], resolution=(8, 8)),
               RenderSettings(samples=2, passes=("depth",), threads=1), **SILENT).passes
    assert np.all(p["depth"] == np.float32(NO_DEPTH))


def test_sample_count_and_variance_are_the_films():
    scene = cornell_scene((24, 16))
    r = render(scene, RenderSettings(samples=8, passes=("samples", "variance"), threads=1), **SILENT)
    assert np.array_equal(r.passes["samples"][..., 0], np.full((16, 24), 8.0))
    assert np.array_equal(r.passes["variance"], r.variance)
    assert not r.stats["effects"]["passes"]            # neither is traced


def test_a_variance_beyond_float32_is_saturated_and_named(recwarn):
    """A lamp of radiance 1e25 (the scene allows up to 1e30): the pixel variance is about 1e50, which
    float32 cannot hold.  It was +inf in the Variance pass with no word (and 0 non-finite samples);
    now it is float32's largest value and a warning counts those pixels."""
    scene = cornell_scene((12, 12))
    scene.materials[3].emission = (1e25,) * 3
    r = render(scene, RenderSettings(samples=4, passes=("variance",), threads=1), **SILENT)
    variance = r.passes["variance"]
    assert np.isfinite(variance).all() and np.isfinite(r.variance).all()
    saturated = int((variance == np.finfo(np.float32).max).any(axis=-1).sum())
    assert saturated > 0 and r.stats["nonfinite_samples"] == 0
    assert [w for w in r.warnings if w.startswith(f"the variance of {saturated} pixel(s) is beyond float32")]
    assert not [w for w in recwarn if "overflow" in str(w.message)]         # no NumPy RuntimeWarning either


def test_passes_off_cost_nothing(monkeypatch):
    """No traced pass: the plan's `passes` is off and no feature object is ever made."""
    import engine.rendering.session

    def forbidden(*a, **k):
        raise AssertionError("feature tracking ran with the passes off")
    monkeypatch.setattr(engine.rendering.session, "TileFeatures", forbidden)
    r = render(cornell_scene((16, 16)), RenderSettings(samples=2, threads=1), **SILENT)
    assert r.passes == {} and r.stats["effects"]["passes"] is False
    with pytest.raises(AssertionError):
        render(cornell_scene((16, 16)), RenderSettings(samples=2, threads=1, passes=("depth",)), **SILENT)


def test_passes_are_identical_whatever_the_workers(monkeypatch):
    import engine.rendering.session
    import engine.rendering.units
    monkeypatch.setattr(engine.rendering.units, "UNIT_PATHS", 2048)          # several units per tile
    scene = cornell_scene((48, 32))
    one = render(scene, RenderSettings(samples=16, tile_size=16, threads=1, seed=3, passes=ALL), **SILENT)
    two = render(scene, RenderSettings(samples=16, tile_size=16, threads=2, seed=3, passes=ALL,
                                       parallelism="processes"), **SILENT)
    from engine.rendering.frame import Frame
    settings = RenderSettings(samples=16, tile_size=16, seed=3, passes=ALL)
    prepared = engine.rendering.session.PreparedScene(scene, settings, **SILENT)
    frame = Frame(scene, settings, prepared.facts())
    for unit in reversed(frame.units):
        frame.add(prepared.render_unit(unit))
    rev = frame.result(1.0).passes
    for name in ALL:
        assert np.array_equal(one.passes[name], two.passes[name]), name
        assert np.array_equal(one.passes[name], rev[name]), name
    assert np.array_equal(one.image, two.image)
    # the passes do not change the image
    plain = render(scene, RenderSettings(samples=16, tile_size=16, threads=1, seed=3), **SILENT)
    assert np.array_equal(plain.image, one.image)


def test_parse_passes():
    assert parse_passes("depth, albedo") == ("albedo", "depth")
    assert parse_passes("") == ()
    with pytest.raises(PassError, match="unknown pass 'z'"):
        parse_passes("albedo,z")


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "engine", "render", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)


def test_cli_writes_the_documented_exr_layers(tmp_path):
    out = tmp_path / "passes.exr"
    proc = run_cli("--resolution", "32", "24", "--samples", "4", "--quiet", "-o", str(out),
                   "--passes", "albedo,normal,depth,samples,variance")
    assert proc.returncode == 0, proc.stderr
    channels = read_multilayer_exr(out)
    assert sorted(channels) == sorted(exr_channels(ALL))
    for name in ("ViewLayer.Combined.R", "ViewLayer.Denoising Albedo.G", "ViewLayer.Denoising Normal.Z",
                 "ViewLayer.Depth.Z", "ViewLayer.Debug Sample Count.X", "ViewLayer.Variance.B"):
        assert name in channels
    assert np.all(channels["ViewLayer.Debug Sample Count.X"] == 4.0)
    assert channels["ViewLayer.Combined.R"].shape == (24, 32)
    expected = render(cornell_scene((32, 24)), RenderSettings(samples=4, passes=ALL), **SILENT)
    assert np.array_equal(channels["ViewLayer.Depth.Z"], expected.passes["depth"][..., 0])
    assert np.array_equal(channels["ViewLayer.Combined.G"], expected.image[..., 1])


def test_cli_refuses_passes_without_exr_and_unknown_names(tmp_path):
    proc = run_cli("-o", str(tmp_path / "a.png"), "--passes", "depth")
    assert proc.returncode == 2 and "need an .exr output" in proc.stderr
    assert "Traceback" not in proc.stderr
    proc = run_cli("-o", str(tmp_path / "a.exr"), "--passes", "depth,zz")
    assert proc.returncode == 2 and "unknown pass 'zz'" in proc.stderr
    assert not os.listdir(tmp_path)


def rel_mse(image, reference):
    """The study's metric (engine/studies/accuracy.py): mean((I - R)^2 / (R^2 + 0.01))."""
    i, r = np.asarray(image, float), np.asarray(reference, float)
    return float(np.mean((i - r) ** 2 / (r * r + 1e-2)))


@pytest.mark.slow   # statistical; the denoiser runs in test_cli_denoise_writes_noisy_and_combined
def test_denoiser_reduces_the_error_of_a_low_sample_render():
    """4 spp denoised with albedo and normal: relMSE against a 256-spp reference at most a quarter
    of the raw 4-spp image's (measured: about 1/20).  The raw image is kept as 'noisy'."""
    pytest.importorskip("pyoidn", reason="pyoidn (requirements.txt) is not installed")
    from engine.film.denoise import denoise_result
    scene = cornell_scene((64, 64))
    reference = render(scene, RenderSettings(samples=256, seed=1), **SILENT).image
    low = render(scene, RenderSettings(samples=4, seed=2, passes=("albedo", "normal")), **SILENT)
    raw = low.image.copy()
    denoise_result(low)
    assert np.array_equal(low.passes["noisy"], raw)
    e_raw, e_den = rel_mse(raw, reference), rel_mse(low.image, reference)
    assert e_den < 0.25 * e_raw, (e_den, e_raw)
    assert low.stats["denoised"] and low.stats["denoise_seconds"] > 0


def test_cli_denoise_writes_noisy_and_combined(tmp_path):
    pytest.importorskip("pyoidn", reason="pyoidn (requirements.txt) is not installed")
    out = tmp_path / "d.exr"
    proc = run_cli("--resolution", "32", "32", "--samples", "4", "--quiet", "-o", str(out), "--denoise")
    assert proc.returncode == 0, proc.stderr
    ch = read_multilayer_exr(out)
    assert "ViewLayer.Noisy Image.R" in ch and "ViewLayer.Denoising Albedo.R" in ch
    assert not np.array_equal(ch["ViewLayer.Noisy Image.R"], ch["ViewLayer.Combined.R"])


def test_depth_alone_carries_no_surface_state(monkeypatch):
    """Blender's view layers have Z on by default: depth alone adds no per-path arrays."""
    import engine.integrators.path_tracer
    seen = []
    original = engine.integrators.path_tracer.Paths.start.__func__

    def start(cls, *args, **kwargs):
        paths = original(cls, *args, **kwargs)
        seen.append(paths.f_thru is None and paths.f_open is None)
        return paths
    monkeypatch.setattr(engine.integrators.path_tracer.Paths, "start", classmethod(start))
    r = render(cornell_scene((16, 16)), RenderSettings(samples=2, threads=1, passes=("depth",)), **SILENT)
    assert seen and all(seen) and "depth" in r.passes
    seen.clear()
    render(cornell_scene((16, 16)), RenderSettings(samples=2, threads=1, passes=("albedo",)), **SILENT)
    assert seen and not any(seen)


def test_cli_denoise_without_pyoidn_is_one_line(tmp_path):
    """A pyoidn that cannot load: --denoise is refused before rendering, one line, exit 2."""
    fake = tmp_path / "fake" / "pyoidn"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("raise ImportError('libOpenImageDenoise.so.2: cannot open shared object')\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path / "fake"), ROOT]))
    proc = subprocess.run([sys.executable, "-m", "engine", "render", "-o", str(tmp_path / "d.exr"), "--denoise"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "pip install pyoidn" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert not (tmp_path / "d.exr").exists()
