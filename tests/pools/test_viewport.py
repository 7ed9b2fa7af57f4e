"""The viewport (engine/pools/viewport.py): its pool keeps the workers and prepares only a new
camera on a new view; its progressive render shows a coarse frame first, then samples of the whole
frame that add up to a final render's image, restarts on a new view without a rebuild; the noise
estimate; shutdown without orphans."""
import sys
import time
from dataclasses import replace

import numpy as np
import pytest

from engine.scene.builtin import cornell_scene
from engine.api import render
from engine.core.settings import RenderSettings
from engine.film.accumulator import Film
from engine.pools.spec import make_pool
from engine.pools.viewport import ViewportRender, coarse_resolution, film_image, frame_dividers, relative_error
from engine.rendering.frame import Frame
from tests.pools.conformance import drain
from tests.file_safety import alive

SETTINGS = RenderSettings(max_depth=3, seed=5, accelerator="embree")


def wait(workers, until, timeout=60.0):
    deadline = time.perf_counter() + timeout
    while time.perf_counter() < deadline:
        snap = workers.snapshot()
        assert snap[5] is None, snap[5]
        if until(snap):
            return snap
        time.sleep(0.01)
    raise AssertionError(f"timed out: {workers.snapshot()[2:5]}")


@pytest.fixture
def workers():
    w = ViewportRender(make_pool(f"viewport:{sys.executable}", 2, log=lambda *a: None))
    yield w
    w.close()
    assert not any(alive(p) for p in w.pids)


def test_coarse_first_then_the_final_render_image(workers):
    scene = cornell_scene((40, 30))
    frames = []
    workers.on_frame = lambda: frames.append(workers.snapshot()[4])
    workers.set_scene(scene, SETTINGS, 8, start_resolution=8)      # tiny views: coarse frames of 8² pixels at most
    version, rgba, samples, noise, level, _ = wait(workers, lambda s: s[4] == 1 and s[2] >= 8)
    levels = [level for level in frames if level >= 0]            # -1: "ready" before any frame
    assert levels[0] == 0 and levels[-1] == 1, "the first frame must be the coarse pass"
    assert samples == 8 and rgba.shape == (30, 40, 4)
    # two workers' interleaved sample numbers 0..7 = the final render with 8 samples (Sobol': a
    # sample number is the same random numbers anywhere); row 0 of the film is the bottom
    final = render(scene, replace(SETTINGS, samples=8, threads=1), log=lambda *a: None).image
    np.testing.assert_allclose(rgba[::-1, :, :3], final, rtol=1e-4, atol=1e-5)
    assert (rgba[..., 3] == 1).all()
    time.sleep(0.3)
    assert workers.snapshot()[0] == version, "workers must stop at the target"


def test_a_new_view_restarts_without_rebuilding(workers):
    scene = cornell_scene((32, 32))
    workers.set_scene(scene, SETTINGS, 4, start_resolution=8)
    wait(workers, lambda s: s[4] == 1 and s[2] >= 4)
    time.sleep(0.1)
    builds = workers.builds
    assert builds == 2, "one session per worker"
    narrow = replace(scene.camera, lens=scene.camera.lens * 2)
    shapes = []
    workers.on_frame = lambda: shapes.append((time.perf_counter(), workers.snapshot()[1]))
    t0 = time.perf_counter()
    workers.set_view(narrow, (24, 16), tag="narrow")
    wait(workers, lambda s: s[1] is not None)
    assert workers.picture().tag == "narrow", "a picture carries the view it was rendered for"
    first_time, coarse = next((t, img) for t, img in shapes if img is not None)
    first = first_time - t0
    assert coarse.shape[:2] == coarse_resolution((24, 16), 4)[::-1]
    _, rgba, *_ = wait(workers, lambda s: s[4] == 1 and s[2] >= 4)
    assert rgba.shape[:2] == (16, 24) and workers.builds == builds
    expected = render(replace(scene, camera=narrow, resolution=(24, 16)), replace(SETTINGS, samples=4, threads=1),
                      log=lambda *a: None).image
    np.testing.assert_allclose(rgba[::-1, :, :3], expected, rtol=1e-4, atol=1e-5)
    print(f"view change: first (coarse) frame after {1000 * first:.0f} ms")


def test_frames_of_a_view_follow_cycles_start_pixels_and_pixel_size():
    """Cycles' rule: the first frame has at most Start Pixels² pixels (the resolution halved),
    every next frame twice the resolution, the last at the resolution over the Pixel Size."""
    assert frame_dividers((528, 399), 64, 1) == [8, 4, 2, 1]       # 66 x 49 = 3234 <= 64²
    assert frame_dividers((528, 399), 64, 2) == [8, 4, 2]
    assert frame_dividers((1321, 879), 64, 1) == [32, 16, 8, 4, 2, 1]
    assert frame_dividers((40, 30), 64, 1) == [1], "a view of fewer pixels has no coarse frame"
    assert frame_dividers((40, 30), 64, 4) == [4]


def test_scene_errors_are_reported_not_raised(workers):
    bad = cornell_scene((16, 16))
    bad.camera = replace(bad.camera, lens=-1.0)
    workers.set_scene(bad, SETTINGS, 2)
    deadline = time.perf_counter() + 30
    while workers.snapshot()[5] is None and time.perf_counter() < deadline:
        time.sleep(0.01)
    error = workers.snapshot()[5]
    assert error and "lens" in error.lower() and "Traceback" not in error, error
    workers.set_scene(cornell_scene((16, 16)), SETTINGS, 2)       # recovers on the next scene
    wait(workers, lambda s: s[4] == 1 and s[2] >= 2)


def test_noise_estimate_is_the_standard_error_of_the_pixel_means():
    rng = np.random.default_rng(1)
    film = Film(25, 20)
    n, pixels, sd = 64, 500, 0.3
    assert relative_error(film) is None, "no estimate below two samples"
    for _ in range(n):
        x = 1.0 + sd * rng.standard_normal((pixels, 3))
        film.add_sums(0, 0, x.reshape(20, 25, 3), (x * x).reshape(20, 25, 3), 1)
    expected = sd / np.sqrt(n)
    assert abs(relative_error(film) / expected - 1) < 0.05, (relative_error(film), expected)
    assert np.array_equal(film_image(film)[::-1, :, :3], film.mean())
    # a black background (half the frame) changes nothing
    film2 = Film(50, 20)
    rng = np.random.default_rng(1)
    for _ in range(n):
        x = 1.0 + sd * rng.standard_normal((pixels, 3))
        x2 = np.concatenate([x.reshape(20, 25, 3), np.zeros((20, 25, 3))], axis=1)
        film2.add_sums(0, 0, x2, x2 * x2, 1)
    assert relative_error(film2) == pytest.approx(relative_error(film), rel=1e-9)


def test_the_pool_prepares_a_new_view_without_a_rebuild_and_renders_after_a_cancel():
    """The pool alone (engine/pools/protocol.py): a cancelled frame, then a new camera and size
    prepared again (no new build), whose units merge into the final render of that view bit for bit."""
    pool = make_pool("viewport", 2, log=lambda *a: None)
    scene, settings = cornell_scene((48, 32)), replace(SETTINGS, samples=64, tile_size=16)
    try:
        facts = pool.prepare(scene, settings)
        frame = Frame(scene, settings, facts)
        pool.start(frame.units)
        drain(pool, 1)
        pool.cancel()
        drain(pool, len(frame.units) - 1)
        built = pool.stats()["scenes_prepared"]
        view = replace(scene, camera=replace(scene.camera, lens=scene.camera.lens * 1.5), resolution=(40, 24))
        assert pool.prepare(view, settings) is facts
        frame = Frame(view, settings, facts)
        pool.start(frame.units)
        for unit, result, error in drain(pool, len(frame.units)):
            assert error is None and result is not None, "units after a cancel render"
            frame.add(result)
        assert pool.stats()["scenes_prepared"] == built, "a new view builds nothing"
        assert pool.prepare(replace(view, meshes=list(view.meshes)), settings) is not facts, \
            "another scene is prepared again"
    finally:
        pool.close()
    expected = render(view, replace(settings, threads=1), log=lambda *a: None).image
    assert np.array_equal(frame.film.mean(), expected)
