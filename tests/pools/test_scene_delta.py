"""engine/pools/scene_delta.py: a scene sent again leaves out the mesh arrays the workers hold
already, and a worker puts them back: the scene it prepares is the one it would have been sent."""
import copy
import pickle
import sys
from dataclasses import fields, replace

import numpy as np
import pytest

from engine.api import render
from engine.core.settings import RenderSettings
from engine.pools.scene_delta import ARRAYS, with_unchanged, without_unchanged
from engine.pools.spec import make_pool
from engine.rendering.frame import Frame
from engine.scene.builtin import cornell_scene, torus
from tests.pools.conformance import drain


def scenes():
    """A validated scene and the next frame's: the torus moved (new vertices), a wall with its two
    triangles turned round (new triangles, same vertices), the rest equal in new arrays."""
    first = cornell_scene((24, 16))
    first.meshes.append(torus("Torus", (0.0, 0.0, 0.0), 0.5, 0.2, 12, 8, 1))
    first.validate()
    second = pickle.loads(pickle.dumps(first))
    second.meshes[-1].vertices = second.meshes[-1].vertices + [0.05, 0.0, 0.0]
    second.meshes[0].triangles = second.meshes[0].triangles[:, ::-1].copy()
    second.validate()
    return first, second


def same_scene(a, b):
    for m, n in zip(a.meshes, b.meshes, strict=True):
        for f in fields(m):
            x, y = getattr(m, f.name), getattr(n, f.name)
            if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
                assert type(x) is type(y) and x.dtype == y.dtype and np.array_equal(x, y), (m.name, f.name)
            else:
                assert x == y, (m.name, f.name)


def test_the_unchanged_arrays_stay_out_and_come_back():
    first, second = scenes()
    kept_copy = pickle.loads(pickle.dumps(second))
    sent, kept = without_unchanged(second, first, 7)
    same_scene(second, kept_copy)                               # the scene given is not changed
    left_out = set(kept[1])
    assert kept[0] == 7
    assert (len(second.meshes) - 1, "vertices") not in left_out, "moved vertices are sent"
    assert (len(second.meshes) - 1, "triangles") in left_out, "the moved mesh's triangles stay out"
    assert (0, "triangles") not in left_out and (0, "vertices") in left_out, "new triangles are sent"
    for i, f in left_out:
        assert getattr(sent.meshes[i], f) is None
    # the worker's side: the message unpickled, the last scene it holds
    received = with_unchanged(pickle.loads(pickle.dumps(sent)), kept, pickle.loads(pickle.dumps(first)), 7)
    same_scene(received, second)
    # the control: put back from another scene, the turned wall or the moved torus would be wrong
    wrong = pickle.loads(pickle.dumps(sent))
    for i, f in left_out | {(0, "triangles")}:
        setattr(wrong.meshes[i], f, getattr(first.meshes[i], f))
    with pytest.raises(AssertionError):
        same_scene(wrong, second)


def test_a_renamed_or_added_mesh_is_sent_whole_and_a_wrong_base_is_refused():
    first, second = scenes()
    second.meshes[1] = replace(second.meshes[1], name="Other")
    second.meshes.append(copy.copy(second.meshes[2]))
    _, (_, left_out) = without_unchanged(second, first, 1)
    assert not any(i in (1, len(second.meshes) - 1) for i, _ in left_out)
    assert {f for _, f in left_out} <= set(ARRAYS)
    sent, kept = without_unchanged(second, first, 3)
    with pytest.raises(RuntimeError):
        with_unchanged(sent, kept, first, 2)
    assert without_unchanged(second, replace(first, meshes=[]), 1) == (second, (1, [])), \
        "nothing to leave out: the scene itself"


@pytest.mark.slow
def test_a_kept_worker_renders_the_next_frame_as_a_fresh_render():
    """The pool sends frame 2 without the arrays frame 1 gave its worker (checked scenes, as the
    add-on's Persistent Data): the image is the fresh render's bit for bit."""
    first, second = scenes()
    settings = RenderSettings(samples=4, max_depth=3, seed=5, accelerator="embree", tile_size=16)
    pool = make_pool(f"viewport:{sys.executable}", 1, log=lambda *a: None)
    try:
        for scene in (first, second):
            facts = pool.prepare(scene, settings, checked=True)
            frame = Frame(scene, settings, facts)
            pool.start(frame.units)
            for _, result, error in drain(pool, len(frame.units)):
                assert error is None, error
                frame.add(result)
        assert pool.sent[0] == 2
    finally:
        pool.close()
    expected = render(second, replace(settings, threads=1), log=lambda *a: None).image
    assert np.array_equal(frame.film.mean(), expected)
