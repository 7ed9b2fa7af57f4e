"""engine/pools/denoiser.py: the viewport's denoiser process (OIDN loaded once, away from the
caller) and the denoised view of a progressive render: denoised from the start sample on, at each
doubling of the samples and at the target, never shown for another view, the noisy picture kept
when off or unavailable."""
import sys
import threading
import time

import numpy as np
import pytest

from engine.film.denoise import DenoiserUnavailable
from engine.pools.denoiser import DenoisedView, DenoiserProcess, due
from tests.film.test_denoise_trial import ABORTS, fake_pyoidn


def test_due_denoises_at_the_start_each_doubling_and_the_target():
    shown, last = [], 0
    for samples in range(1, 33):
        if due(samples, last, start=2, target=24):
            shown.append(samples)
            last = samples
    assert shown == [2, 4, 8, 16, 24]


class FakeRender:
    """ViewportRender's surface: a picture of `samples` samples of the view `gen`."""

    def __init__(self):
        self.lock = threading.Lock()
        self.gen, self.version, self.samples, self.target = 1, 1, 0, 16
        self.closed = False
        self.on_frame = None

    def advance(self, samples, gen=None):
        with self.lock:
            self.samples, self.version = samples, self.version + 1
            self.gen = gen or self.gen

    def snapshot(self):
        with self.lock:
            rgba = np.full((3, 4, 4), float(self.samples), np.float32)
            rgba[..., 3] = 1.0
            return self.version, rgba, self.samples, 0.1, 1, None

    def close(self):
        self.closed = True


class FakeDenoiser:
    def __init__(self, fail=False):
        self.calls, self.fail = [], fail

    def denoise(self, image):
        self.calls.append(float(image[0, 0, 0]))
        if self.fail:
            raise DenoiserUnavailable("no pyoidn here")
        return -np.asarray(image)                       # recognisable

    def close(self):
        pass


def settle(view, until, timeout=5.0):
    deadline = time.perf_counter() + timeout
    while time.perf_counter() < deadline and not until():
        time.sleep(0.01)
    return view.snapshot()


def test_the_view_shows_the_last_denoised_picture_of_its_own_view():
    render, denoiser = FakeRender(), FakeDenoiser()
    view = DenoisedView(render, lambda: denoiser)
    try:
        render.advance(4)
        time.sleep(0.2)
        assert view.snapshot()[1][0, 0, 0] == 4.0 and not denoiser.calls, "off: nothing denoised"
        view.set_denoise(2)
        snap = settle(view, lambda: denoiser.calls)
        assert snap[1][0, 0, 0] == -4.0 and snap[1][0, 0, 3] == 1.0 and view.note() == "Denoised"
        render.advance(6)                               # not yet doubled: the denoised 4 stays
        time.sleep(0.2)
        assert denoiser.calls == [4.0] and view.snapshot()[1][0, 0, 0] == -4.0
        render.advance(8)
        assert settle(view, lambda: len(denoiser.calls) == 2)[1][0, 0, 0] == -8.0
        before = view.version
        render.advance(1, gen=2)                        # a new view: its own noisy picture, at once
        assert view.snapshot()[1][0, 0, 0] == 1.0 and view.version != before
        time.sleep(0.2)
        assert view.snapshot()[1][0, 0, 0] == 1.0, "below the start sample: noisy"
        render.advance(2)
        assert settle(view, lambda: len(denoiser.calls) == 3)[1][0, 0, 0] == -2.0
        view.set_denoise(None)
        assert view.snapshot()[1][0, 0, 0] == 2.0 and view.note() is None
    finally:
        view.close()
    assert render.closed


def test_an_unavailable_denoiser_leaves_the_noisy_picture_and_says_why():
    render, denoiser = FakeRender(), FakeDenoiser(fail=True)
    view = DenoisedView(render, lambda: denoiser)
    try:
        view.set_denoise(1)
        render.advance(2)
        settle(view, lambda: view.problem)
        assert view.snapshot()[1][0, 0, 0] == 2.0
        assert view.note() == "Denoise off: no pyoidn here"
    finally:
        view.close()


def test_the_denoiser_process_denoises_with_oidn():
    pytest.importorskip("pyoidn", reason="pyoidn (requirements.txt) is not installed")
    rng = np.random.default_rng(3)
    clean = np.tile(np.linspace(0.1, 0.9, 48, dtype=np.float32)[None, :, None], (32, 1, 3))
    noisy = clean * rng.uniform(0.5, 1.5, clean.shape).astype(np.float32)
    process = DenoiserProcess(sys.executable)
    try:
        out = process.denoise(noisy)
    finally:
        process.close()
    assert out.shape == noisy.shape
    assert np.sqrt(np.mean((out - clean) ** 2)) < 0.5 * np.sqrt(np.mean((noisy - clean) ** 2))


def test_a_denoiser_process_that_aborts_is_unavailable_not_fatal(tmp_path):
    process = DenoiserProcess(sys.executable, (fake_pyoidn(tmp_path, ABORTS),))
    try:
        with pytest.raises(DenoiserUnavailable, match="SIGABRT"):
            process.denoise(np.zeros((4, 4, 3), np.float32))
        with pytest.raises(DenoiserUnavailable, match="ended"):
            process.denoise(np.zeros((4, 4, 3), np.float32))
    finally:
        process.close()


@pytest.mark.slow
def test_a_viewport_render_is_denoised_at_its_target():
    """Viewport workers, the denoiser process and OIDN together: the converged view is shown
    denoised (smoother than the render's own picture of the same samples)."""
    pytest.importorskip("pyoidn", reason="pyoidn (requirements.txt) is not installed")
    from engine.core.settings import RenderSettings
    from engine.pools.spec import make_pool
    from engine.pools.viewport import ViewportRender
    from engine.scene.builtin import cornell_scene
    render = ViewportRender(make_pool(f"viewport:{sys.executable}", 1, log=lambda *a: None))
    view = DenoisedView(render, lambda: DenoiserProcess(sys.executable))
    try:
        view.set_denoise(1)
        view.set_scene(cornell_scene((40, 30)), RenderSettings(max_depth=3, seed=5, accelerator="embree"), 8)
        deadline = time.perf_counter() + 120
        while time.perf_counter() < deadline and not (view.shown and view.shown[1] == 8):
            time.sleep(0.05)
        _, shown, samples, _, level, error = view.snapshot()
        noisy = render.snapshot()[1]
        assert error is None and level == 1 and samples == 8 and view.note() == "Denoised"
        assert view.denoise_count <= 4, "1, 2, 4, 8 samples at most"
    finally:
        view.close()
    from engine.api import render as render_image
    settings = RenderSettings(max_depth=3, seed=5, accelerator="embree", samples=128)
    ref = render_image(cornell_scene((40, 30)), settings, log=lambda *a: None).image[::-1]   # rows: bottom first
    ref = np.clip(ref, 0.0, 1.0)                     # as displayed: the lamp and fireflies do not dominate
    err_shown = np.sqrt(np.mean((np.clip(shown[..., :3], 0.0, 1.0) - ref) ** 2))
    err_noisy = np.sqrt(np.mean((np.clip(noisy[..., :3], 0.0, 1.0) - ref) ** 2))
    print(f"viewport at 8 spp against 128 spp: RMS {err_noisy:.4f} noisy, {err_shown:.4f} denoised")
    assert err_shown < 0.7 * err_noisy
