"""engine/core/collector.py: the cyclic collector off while a scene is prepared, restored after."""
import gc

import pytest

from engine.core.collector import collector_paused
from engine.rendering.session import PreparedScene
from engine.scene.builtin import cornell_scene
from engine.core.settings import RenderSettings


@pytest.fixture
def restore_gc():
    was = gc.isenabled()
    yield
    (gc.enable if was else gc.disable)()


def test_paused_inside_and_restored(restore_gc):
    gc.enable()
    with collector_paused():
        assert not gc.isenabled()
    assert gc.isenabled()


def test_restored_after_an_exception(restore_gc):
    gc.enable()
    with pytest.raises(RuntimeError):
        with collector_paused():
            raise RuntimeError("cancelled")
    assert gc.isenabled()


def test_left_off_when_it_was_off(restore_gc):
    gc.disable()
    with collector_paused():
        pass
    assert not gc.isenabled()


def collections_while_preparing(monkeypatch):
    """Collections that start inside PreparedScene's preparation, with a collection threshold of 1."""
    from engine.rendering import session
    scene, settings = cornell_scene((8, 8)), RenderSettings(samples=1, backend="numpy")
    inside, seen = [False], []
    prepare = session.PreparedScene._prepare

    def watched(self, *args):
        inside[0] = True
        try:
            prepare(self, *args)
        finally:
            inside[0] = False
    monkeypatch.setattr(session.PreparedScene, "_prepare", watched)

    def callback(phase, info):
        if phase == "start" and inside[0]:
            seen.append(info["generation"])
    threshold = gc.get_threshold()
    gc.enable()
    gc.callbacks.append(callback)
    gc.set_threshold(1)
    try:
        PreparedScene(scene, settings, log=lambda *a: None)
    finally:
        gc.set_threshold(*threshold)
        gc.callbacks.remove(callback)
    return seen


def test_preparation_runs_no_collection(restore_gc, monkeypatch):
    assert collections_while_preparing(monkeypatch) == []
    assert gc.isenabled()


def test_control_without_the_pause_collections_run(restore_gc, monkeypatch):
    from contextlib import nullcontext
    from engine.rendering import session
    monkeypatch.setattr(session, "collector_paused", nullcontext)
    assert len(collections_while_preparing(monkeypatch)) > 0
