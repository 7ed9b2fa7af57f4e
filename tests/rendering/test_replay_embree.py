"""scripts/replay_embree.py: the recorder sees every Embree batch of a render, and its replay
through embreex alone gives the answers the render got."""
import importlib.util
import os

import numpy as np

from engine.core.settings import RenderSettings
from engine.scene.builtin import cornell_scene

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def script():
    spec = importlib.util.spec_from_file_location("replay_embree", os.path.join(ROOT, "scripts", "replay_embree.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_ray_is_recorded_and_replays_to_the_same_answers():
    replay_embree = script()
    scene, settings = cornell_scene((24, 24)), RenderSettings(samples=2, threads=1, seed=0)
    _, _, prepared, recorder = replay_embree.trace_units(scene, settings, record=True)
    assert prepared.geometry.accelerator is recorder.inner           # unwrapped after the render
    queries = [b[0] for b in recorder.batches]
    rays = {q: sum(len(b[1]) for b in recorder.batches if b[0] == q) for q in ("INTERSECT", "OCCLUDED")}
    assert rays["INTERSECT"] >= 24 * 24 * 2 and rays["OCCLUDED"] > 0 and queries[0] == "INTERSECT"
    # The replay's rays are the render's: embreex alone answers as the accelerator did.
    embree = recorder.inner
    for query, o, d, tfar in recorder.batches[:6]:
        if query == "INTERSECT":
            t, prim, _, _ = embree.intersect(o, d, tfar.astype(np.float64))
            alone = embree.scene.run(o, d, dists=tfar.copy(), output=1)["primID"]
            assert np.array_equal(np.where(prim >= 0, prim, -1), np.where(alone >= 0, alone, -1))
    seconds, count = replay_embree.replay(recorder, 1)
    assert count == sum(rays.values()) and seconds >= 0.0
    # Control: a recorder that drops the shadow rays misses rays of the render.
    recorder.batches = [b for b in recorder.batches if b[0] == "INTERSECT"]
    assert replay_embree.replay(recorder, 1)[1] < count
