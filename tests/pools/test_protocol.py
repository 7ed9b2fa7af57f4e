"""Every local pool kind (the viewport's too) against the Pool protocol (engine/pools/protocol.py), the same image on
each (also under the stopping rules' rounds), and make_pool's one-line errors
(engine/pools/spec.py).  Dask runs the same conformance checks in tests/pools/test_dask_cluster.py."""
import os
import sys

import numpy as np
import pytest

from engine import RenderSettings, render
from engine.core.errors import SceneError
from engine.pools.processes import SubprocessPool, WorkerError
from engine.pools.viewport import ViewportPool
from engine.pools.spec import PoolSpecError, make_pool
from engine.scene.builtin import cornell_scene
from tests.file_safety import alive
from tests.pools.conformance import SCENE_SIZE, SETTINGS, check_cancel_answers_every_unit, check_renders_a_frame

QUIET = dict(log=lambda *a: None)
LOCAL_KINDS = ["threads", "processes", "workers", "viewport"]


@pytest.fixture(scope="module")
def reference():
    return render(cornell_scene(SCENE_SIZE), RenderSettings(threads=1, **SETTINGS), **QUIET).image


@pytest.mark.parametrize("spec", LOCAL_KINDS)
def test_every_local_pool_renders_a_frame_by_the_protocol(spec, reference):
    pool = make_pool(spec, 2, **QUIET)
    check_renders_a_frame(pool, reference)
    if isinstance(pool, (SubprocessPool, ViewportPool)):
        assert not any(alive(w.pid) for w in pool.workers), "workers left after close()"


@pytest.mark.parametrize("spec", LOCAL_KINDS)
def test_every_local_pool_answers_every_unit_after_cancel(spec):
    check_cancel_answers_every_unit(make_pool(spec, 2, **QUIET))


@pytest.mark.slow          # 3-40 s (subprocesses, built zips): make test-slow, which .ci/run runs too
@pytest.mark.parametrize("spec", LOCAL_KINDS)
def test_the_stopping_rules_give_the_same_image_on_every_pool(spec):
    """Rounds of adaptive units (noise target) on two workers of each kind: the image and the
    samples of every pixel of one thread."""
    settings = dict(samples=128, noise_target=0.2, tile_size=16, seed=4)
    one = render(cornell_scene((40, 24)), RenderSettings(threads=1, **settings), **QUIET)
    other = render(cornell_scene((40, 24)), RenderSettings(threads=2, **settings), pool=make_pool(spec, 2, **QUIET),
                   **QUIET)
    assert one.stats["rounds"] >= 2 and other.stats["rounds"] == one.stats["rounds"]
    assert np.array_equal(one.image, other.image)
    assert np.array_equal(one.film.samples_per_pixel, other.film.samples_per_pixel)
    assert one.film.samples_per_pixel.min() < one.film.samples_per_pixel.max()


def test_auto_forks_outside_blender_and_one_worker_is_a_thread(monkeypatch):
    monkeypatch.delitem(sys.modules, "bpy", raising=False)        # the add-on's tests import it
    two, one = make_pool("auto", 2, **QUIET), make_pool("auto", 1, **QUIET)
    try:
        assert (two.describe, one.describe) == ("processes" if sys.platform.startswith("linux") else "threads",
                                                "threads")
    finally:
        two.close()
        one.close()
    monkeypatch.setitem(sys.modules, "bpy", object())              # inside Blender: never forked
    inside = make_pool("auto", 2, **QUIET)
    inside.close()
    assert inside.describe == "threads"


@pytest.mark.parametrize("spec", ["thread", "", "dask", "processes:4", "workers-python", "viewports"])
def test_a_bad_spec_is_one_line_naming_the_kinds(spec):
    with pytest.raises(PoolSpecError) as err:
        make_pool(spec)
    message = str(err.value)
    assert isinstance(err.value, SceneError) and "\n" not in message
    assert repr(spec) in message and "threads, processes, auto, workers[:PYTHON], viewport[:PYTHON], dask:ADDRESS" in message


def test_a_bad_dask_address_is_one_line():
    pytest.importorskip("distributed")
    from engine.pools.dask_cluster import ClusterError
    with pytest.raises(ClusterError, match="not a Dask scheduler address") as err:
        make_pool("dask:http//nowhere")
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("kind", ["workers", "viewport"])
def test_a_missing_worker_python_is_one_line(tmp_path, kind):
    missing = str(tmp_path / "no-python")
    with pytest.raises((WorkerError, SceneError)) as err:
        make_pool(f"{kind}:{missing}", 1, **QUIET)
    assert missing in str(err.value) and "\n" not in str(err.value)
    assert not os.path.exists(missing)
