"""ShadingPoint.memo (engine/materials/protocol.py): what a BSDF derives from the hits alone is
computed once per scatter group's span and shared by its eval and sample, gathered for takes,
and never leaks to other hits (a replaced colour, a changed field)."""
from dataclasses import replace

import numpy as np

from engine.materials.protocol import ShadingPoint


def hits(n=6):
    rng = np.random.default_rng(2)
    wo = rng.normal(size=(3, n))
    wo /= np.linalg.norm(wo, axis=0)
    up = np.tile([[0.0], [0.0], [1.0]], (1, n))
    return ShadingPoint(wo, up, up, up, rng.random((3, n)), np.arange(n) % 3)


def counting():
    calls = []

    def compute(si):
        calls.append(len(si))
        return (si.color.sum(axis=0), [si.color * 2.0])
    return compute, calls


def test_views_of_a_span_share_and_takes_gather():
    si, (compute, calls) = hits(), counting()
    a = si[1:5].memo("k", compute)
    b = si[1:5].memo("k", compute)                  # another view of the same span
    assert calls == [4] and b is a
    index = np.array([3, 0, 0])
    taken = si[1:5].take(index).memo("k", compute)  # gathered from the span's value
    assert calls == [4]
    direct = compute(si[1:5].take(index))
    assert np.array_equal(taken[0], direct[0]) and np.array_equal(taken[1][0], direct[1][0])
    si[0:2].memo("k", compute)                      # another span: its own
    assert calls == [4, 3, 2]


def test_changed_hits_compute_afresh():
    si, (compute, calls) = hits(), counting()
    view = si[0:4]
    view.memo("k", compute)
    recoloured = replace(view, color=np.ones((3, 4)))
    assert np.array_equal(recoloured.memo("k", compute)[0], np.full(4, 3.0))
    leaves = view.take(np.array([0, 1]))
    leaves.color = np.zeros((3, 2))                 # as the Mix BSDF sets its leaves' colours
    assert np.array_equal(leaves.memo("k", compute)[0], np.zeros(2))
    alone = hits(3)                                 # not a span's view: a take computes its own
    alone.take(np.array([0])).memo("k", compute)
    assert calls == [4, 4, 2, 1]


def test_a_recoloured_span_keeps_its_own_memo_and_gathers_for_its_takes():
    si, (compute, calls) = hits(), counting()
    span = si[0:4]
    span.memo("k", compute)
    lobe = span.recolour(np.ones((3, 4)))           # a lobe's view (engine/materials/principled.py)
    assert np.array_equal(lobe.memo("k", compute)[0], np.full(4, 3.0))
    assert np.array_equal(lobe.take(np.array([2, 1])).memo("k", compute)[0], np.full(2, 3.0))
    assert calls == [4, 4]


def test_a_take_of_every_hit_shares_arrays_and_memo_values():
    """ShadingPoint.take(None) (a Mix Shader's row of leaves taken whole, engine/materials/mix.py): the
    same hits in order, reading the source's arrays and memo values without a gather; its medium
    stacks are copies; memo_at gives the source's index.  Control: a take of every hit by index
    gathers (equal values, other arrays)."""
    from engine.materials.media import MediumStack
    si, (compute, calls) = hits(), counting()
    si.media = MediumStack.empty(6)
    span = si[1:5]
    whole = span.take(None)
    assert len(whole) == 4 and whole.n is span.n and whole.wo is span.wo and whole.material is span.material
    value = whole.memo("k", compute)
    assert calls == [4] and value is span.memo("k", compute)
    assert whole.media.media is not span.media.media and np.array_equal(whole.media.media, span.media.media)
    assert whole.memo_at("k", compute) == (value, None)
    inner = span.take(np.array([2, 0]))
    assert np.array_equal(inner.take(None).memo_at("k", compute)[1], [2, 0])
    by_index = span.take(np.arange(4))                                  # control
    assert by_index.n is not span.n and np.array_equal(by_index.n, span.n)
    assert by_index.memo("k", compute)[0] is not value[0] and np.array_equal(by_index.memo("k", compute)[0], value[0])
