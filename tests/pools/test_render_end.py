"""A final render on the viewport workers started ahead (engine/pools/viewport.py ViewportPool, F12 through
engine/pools/kept.py KeptPool): the dispatch keeps a second unit off a worker while no more units are
pending than workers (the rule of engine/pools/faults.py Dispatch.feed), and the render's end does not
wait for its workers' teardown (engine/pools/transport.py close_all wait=False).  Fake workers: no process."""
import threading
import time
from types import SimpleNamespace

from engine.pools import transport
from engine.pools.viewport import ViewportPool


class FakeWorker:
    def __init__(self, seconds=0.0):
        self.alive, self.prepared, self.in_flight, self.sent = True, 1, [], []
        self.closed, self.ended, self.seconds = False, threading.Event(), seconds

    def send(self, message):
        self.sent.append(message)

    def close(self):
        self.closed = True

    def wait(self, timeout):
        time.sleep(self.seconds)
        self.ended.set()


def pool_of(workers):
    pool = ViewportPool.__new__(ViewportPool)
    pool.workers, pool.pending, pool.preparation, pool.cancelled = workers, [], 1, False
    return pool


def units(n):
    return [SimpleNamespace(index=i) for i in range(n)]


def test_a_second_unit_goes_to_a_worker_only_while_many_units_are_pending():
    a, b = FakeWorker(), FakeWorker()
    pool = pool_of([a, b])
    pool.start(units(5))
    # one each; 3 pending are not more than 2 per worker: none queued, the next goes to whoever is free
    assert [u.index for u in a.in_flight] == [0] and [u.index for u in b.in_flight] == [1]
    assert [u.index for u in pool.pending] == [2, 3, 4]
    b.in_flight.clear()                     # b answered: it takes the next, alone
    pool._feed(b)
    assert [u.index for u in b.in_flight] == [2] and [u.index for u in pool.pending] == [3, 4]
    # control: many units pending: both hold two (the viewport's small units keep their queue)
    c, d = FakeWorker(), FakeWorker()
    many = pool_of([c, d])
    many.start(units(9))
    assert [len(c.in_flight), len(d.in_flight), len(many.pending)] == [2, 2, 5]


def test_the_dispatch_of_the_other_process_pools_follows_the_same_rule():
    from engine.pools.faults import Dispatch, Worker

    class Sent(Worker):
        def send_unit(self, unit):
            pass
    workers = [Sent(), Sent()]
    dispatch = Dispatch(workers, log=lambda *a: None)
    dispatch.start(units(5))
    assert [len(w.in_flight) for w in workers] == [1, 1] and len(dispatch.pending) == 3
    dispatch.finished(workers[1], workers[1].in_flight[0])
    assert [u.index for u in workers[1].in_flight] == [2]


def test_close_all_without_wait_returns_before_the_workers_end_and_reaps_them():
    slow = [FakeWorker(0.3), FakeWorker(0.3)]
    start = time.perf_counter()
    transport.close_all(slow, grace=2.0, wait=False)
    assert time.perf_counter() - start < 0.2 and all(w.closed for w in slow)
    assert all(w.ended.wait(5) for w in slow)          # waited for by the reaper thread
    waited = [FakeWorker(0.3)]                          # control: wait=True blocks until the end
    start = time.perf_counter()
    transport.close_all(waited, grace=2.0)
    assert time.perf_counter() - start >= 0.3 and waited[0].ended.is_set()


def test_the_viewport_pool_waits_when_a_worker_may_not_end_by_itself(monkeypatch):
    calls = []
    monkeypatch.setattr("engine.pools.viewport.close_all", lambda workers, grace, wait=True: calls.append(wait))
    idle = pool_of([FakeWorker(), FakeWorker()])
    idle.close(wait=False)
    busy = pool_of([FakeWorker(), FakeWorker()])
    busy.workers[0].in_flight.append(object())          # a unit not answered: its worker may be stopped
    busy.close(wait=False)
    dead = pool_of([FakeWorker(), FakeWorker()])
    dead.workers[1].alive = False
    dead.close(wait=False)
    pool_of([FakeWorker()]).close()
    assert calls == [False, True, True, True]
