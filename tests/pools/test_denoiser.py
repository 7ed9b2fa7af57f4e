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


def viewport_pictures(seed):
    """(denoised, noisy) pictures of the built-in Cornell box at 8 samples in the viewport (rows bottom
    first), through viewport workers, the denoiser process and OIDN together."""
    from engine.core.settings import RenderSettings
    from engine.pools.spec import make_pool
    from engine.pools.viewport import ViewportRender
    from engine.scene.builtin import cornell_scene
    render = ViewportRender(make_pool(f"viewport:{sys.executable}", 1, log=lambda *a: None))
    view = DenoisedView(render, lambda: DenoiserProcess(sys.executable))
    try:
        view.set_denoise(1)
        view.set_scene(cornell_scene((40, 30)), RenderSettings(max_depth=3, seed=seed, accelerator="embree"), 8)
        deadline = time.perf_counter() + 120
        while time.perf_counter() < deadline and not (view.shown and view.shown[1] == 8):
            time.sleep(0.05)
        _, shown, samples, _, level, error = view.snapshot()
        noisy = render.snapshot()[1]
        assert error is None and level == 1 and samples == 8 and view.note() == "Denoised"
        assert view.denoise_count <= 4, "1, 2, 4, 8 samples at most"
    finally:
        view.close()
    return shown[..., :3], noisy[..., :3]


# The denoised / noisy RMS error of one 8-sample view of 40 x 30 pixels spreads widely from seed to seed:
# over 36 seeds (12 each with the Sobol' sampler's Kensler shuffle, its shuffle before, and the random
# sampler; docs/performance.md "The index shuffle re-landed") it had mean 0.66-0.70 and standard deviation
# 0.12-0.13 for every sampler, and one view's 0.70 bound failed 19 of the 36 (a coin flip).  Pooled over
# SEEDS views (the root of the mean squared errors) the mean stays and the spread falls to 0.06: the
# bound 0.90 is more than 3.5 standard deviations above every sampler's mean (a false failure about
# once in 5000 runs), and a denoiser that removes less than a tenth of the error, or none, fails it.
DENOISED_RMS_BOUND, SEEDS = 0.90, (5, 5 + (1 << 16), 5 + (2 << 16), 5 + (3 << 16))   # seeds 2^16 apart: no shared pixel seed


@pytest.mark.slow
def test_a_viewport_render_is_denoised_at_its_target():
    """Viewport workers, the denoiser process and OIDN together: the converged view is shown
    denoised (smoother than the render's own picture of the same samples), judged over SEEDS views
    against a converged render of another seed (its samples none of the views')."""
    pytest.importorskip("pyoidn", reason="pyoidn (requirements.txt) is not installed")
    from engine.api import render as render_image
    from engine.core.settings import RenderSettings
    from engine.scene.builtin import cornell_scene
    settings = RenderSettings(max_depth=3, seed=1 << 30, accelerator="embree", samples=1024)
    ref = render_image(cornell_scene((40, 30)), settings, log=lambda *a: None).image[::-1]   # rows: bottom first
    ref = np.clip(ref, 0.0, 1.0)                     # as displayed: the lamp and fireflies do not dominate
    sq_shown = sq_noisy = 0.0
    for seed in SEEDS:
        shown, noisy = viewport_pictures(seed)
        sq_shown += np.mean((np.clip(shown, 0.0, 1.0) - ref) ** 2)
        sq_noisy += np.mean((np.clip(noisy, 0.0, 1.0) - ref) ** 2)
    err_shown, err_noisy = np.sqrt(sq_shown / len(SEEDS)), np.sqrt(sq_noisy / len(SEEDS))
    print(f"viewport at 8 spp against 1024 spp, {len(SEEDS)} seeds: RMS {err_noisy:.4f} noisy, {err_shown:.4f} denoised")
    assert err_shown < DENOISED_RMS_BOUND * err_noisy
