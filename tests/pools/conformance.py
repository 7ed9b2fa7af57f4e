"""The Pool protocol (engine/pools/protocol.py) checked on a pool of any kind: used by
tests/pools/test_protocol.py for the local kinds and tests/pools/test_dask_cluster.py for Dask."""
import time

import numpy as np

from engine.core.settings import RenderSettings
from engine.pools.protocol import Pool
from engine.rendering.frame import Frame
from engine.rendering.session import TracerFacts
from engine.scene.builtin import cornell_scene

SCENE_SIZE = (48, 32)
SETTINGS = dict(samples=8, tile_size=16, seed=5)


def drain(pool, count: int, timeout: float = 120.0) -> list:
    """The next `count` outcomes (unit, result, error) of `pool`."""
    outcomes, deadline = [], time.monotonic() + timeout
    while len(outcomes) < count:
        assert time.monotonic() < deadline, f"{pool.describe}: {len(outcomes)} of {count} units answered"
        item = pool.next_result(0.2)
        if item is not None:
            outcomes.append(item)
    return outcomes


def check_renders_a_frame(pool, reference_image) -> None:
    """prepare, start (twice where the pool takes rounds), next_result, close: every unit answered
    once with its own result, merged into the reference image bit for bit."""
    assert isinstance(pool, Pool)
    assert isinstance(pool.describe, str) and pool.describe
    assert isinstance(pool.takes_rounds, bool)
    scene, settings = cornell_scene(SCENE_SIZE), RenderSettings(**SETTINGS)
    try:
        facts = pool.prepare(scene, settings)
        assert isinstance(facts, TracerFacts) and facts.accelerator and facts.plan is not None
        frame = Frame(scene, settings, facts)
        units = frame.units
        assert len(units) >= 4
        if pool.takes_rounds:                                # a second start() adds units
            half = len(units) // 2
            pool.start(units[:half])
            outcomes = drain(pool, half)
            pool.start(units[half:])
            outcomes += drain(pool, len(units) - half)
        else:
            pool.start(units)
            outcomes = drain(pool, len(units))
        assert sorted(u.index for u, _, _ in outcomes) == [u.index for u in units]
        for unit, result, error in outcomes:
            assert error is None and result is not None and result.unit == unit
            frame.add(result)
        assert frame.film.units_added == len(units)
        assert np.array_equal(frame.film.mean(), reference_image)
        assert pool.stats() is not None and isinstance(pool.warnings(), list)
    finally:
        pool.close()


def check_cancel_answers_every_unit(pool) -> None:
    """After cancel() every started unit is still answered, finished or as cancelled (None), and
    none with an error; close() then returns."""
    scene, settings = cornell_scene((64, 64)), RenderSettings(samples=256, tile_size=16, seed=2)
    try:
        frame = Frame(scene, settings, pool.prepare(scene, settings))
        pool.start(frame.units)
        first = drain(pool, 1)
        pool.cancel()
        rest = drain(pool, len(frame.units) - 1, timeout=60)
        outcomes = first + rest
        assert sorted(u.index for u, _, _ in outcomes) == [u.index for u in frame.units]
        assert all(error is None for _, _, error in outcomes)
        assert any(result is None for _, result, _ in rest), "nothing was cancelled"
    finally:
        pool.close()
