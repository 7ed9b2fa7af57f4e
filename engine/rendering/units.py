"""The frame as work: tiles, the work units that render sample ranges of a tile, and the wait
for their outcomes.  Units depend on the frame only, never on the workers, so images stay
identical whatever renders them."""
from __future__ import annotations

from dataclasses import dataclass

from ..integrators import path_tracer

MIN_TILES = 4                     # so that both cores of a small frame have work
UNIT_PATHS = 1 << 18              # camera samples per work unit, about: each unit ends with a tail of
                                  # a few paths, so units much smaller than this cost time (1 << 16: +25 %)
PHOTON_UNIT_SAMPLES = 16          # at most, per unit, with caustic photons: each sample of a pixel is one
                                  # photon pass (engine/integrators/photons/caustics.py), which a unit traces


@dataclass(frozen=True)
class Tile:
    index: int
    x0: int
    y0: int
    x1: int
    y1: int

    @property
    def pixels(self) -> int:
        return (self.x1 - self.x0) * (self.y1 - self.y0)


@dataclass(frozen=True)
class WorkUnit:
    """Samples start .. stop-1 of every pixel of one tile; `chunk` numbers it within the tile."""
    index: int
    tile: Tile
    chunk: int
    start: int
    stop: int
    mask: bytes | None = None    # packed active pixels of the tile (adaptive sampling); None = all
    halves: bool = False         # render [start, mid) and [mid, stop) apart: the half buffers


@dataclass(frozen=True)
class PhotonUnit:
    """Trace photon batch `batch` (the caustic photon passes PASSES_PER_BATCH batch .. of
    engine/integrators/photons/caustics.py) for the units that gather from it
    (engine/rendering/photon_passes.py).  Its index, -1 - batch, never equals a camera unit's (the
    pools key retries and tasks by index).  `scheduler`: which PhotonScheduler asked for it (a pool
    kept across renders may answer an earlier render's unit late: it is not this render's batch)."""
    batch: int
    scheduler: int = 0

    @property
    def index(self) -> int:
        return -1 - self.batch


def tile_size_for(width: int, height: int, size: int) -> int:
    """The tile edge used: `size`, halved (not below 16) until the frame has MIN_TILES tiles.
    It depends on the frame only, never on the workers, so images stay identical whatever
    the number of workers."""
    while size > 16 and -(-width // size) * -(-height // size) < MIN_TILES:
        size = max(16, size // 2)
    return size


def make_tiles(width: int, height: int, size: int) -> list[Tile]:
    tiles = []
    for y0 in range(0, height, size):
        for x0 in range(0, width, size):
            tiles.append(Tile(len(tiles), x0, y0, min(x0 + size, width), min(y0 + size, height)))
    return tiles


ORDERS = ("tiles", "frame", "growing")        # the progressive orders of make_units


def chunk_starts(samples: int, step: int, growing: bool) -> list[int]:
    """Where a tile's chunks start: every `step` samples, or (growing) 0, 1, 2, 4, 8, ... with
    chunks of at most `step` samples."""
    if not growing:
        return list(range(0, samples, step))
    starts, s = [], 0
    while s < samples:
        starts.append(s)
        s += min(max(s, 1), step)
    return starts


def make_units(tiles, samples: int, order: str = "tiles", max_samples: int | None = None) -> list[WorkUnit]:
    """Each tile's samples in chunks of about UNIT_PATHS camera samples.  order "tiles": a tile's
    chunks one after the other (the frame fills tile by tile); "frame": chunk 0 of every tile,
    then chunk 1, ... (the whole frame refines); "growing": as "frame", with chunks of 1, 1, 2, 4,
    ... samples up to that size (the viewport: a picture of the whole frame after one sample,
    big units after that, engine/pools/viewport.py).  max_samples: a cap on a unit's samples."""
    if order not in ORDERS:
        raise ValueError(f"progressive order {order!r}: expected one of {', '.join(ORDERS)}")
    per_tile = []
    # A unit smaller than a wavefront pays the tail of a wavefront that never fills (measured: a
    # unit of 4k paths costs about 20 ms more than its paths' share, docs/performance.md "Speed"):
    # a tile's last chunk that small joins the one before it.
    smallest = min(path_tracer.WAVEFRONT_SIZE, UNIT_PATHS // 2)
    for tile in tiles:
        step = max(1, min(samples, -(-UNIT_PATHS // tile.pixels), max_samples or samples))
        starts = chunk_starts(samples, step, order == "growing")
        if order != "growing" and len(starts) > 1 and (samples - starts[-1]) * tile.pixels < smallest:
            starts.pop()
        per_tile.append([(tile, c, s, starts[c + 1] if c + 1 < len(starts) else samples)
                         for c, s in enumerate(starts)])
    if order in ("frame", "growing"):
        chunks = [units[d] for d in range(max(map(len, per_tile))) for units in per_tile if d < len(units)]
    else:
        chunks = [u for units in per_tile for u in units]
    return [WorkUnit(i, tile, c, start, stop) for i, (tile, c, start, stop) in enumerate(chunks)]


def next_outcome(pool, timeout: float):
    """(came, result, error) of the next unit from `pool` (engine/pools/protocol.py Pool): came
    is False when none finished within `timeout`; result is None for a cancelled or failed unit;
    a failed unit cancels the others (its error is raised once they have stopped)."""
    item = pool.next_result(timeout=timeout)
    if item is None:
        return False, None, None
    _, result, exc = item
    if exc is not None:
        pool.cancel()
        return True, None, exc
    return True, result, None


def await_units(pool, count: int, on_result, interrupt=None, poll: float = 0.1):
    """Wait for the outcomes of `count` started units, handing each finished UnitResult to
    on_result(result).  interrupt() is polled between waits until it returns a reason to stop
    (e.g. "cancelled"); then the pool is cancelled and the other units drain, dropped whole.
    Returns (that reason or None, the first unit error or None)."""
    reason, error, done = None, None, 0
    while done < count:
        if reason is None and interrupt is not None:
            reason = interrupt() or None
            if reason is not None:
                pool.cancel()
        came, result, exc = next_outcome(pool, poll)
        if not came:
            continue
        done += 1
        error = error or exc
        if result is not None:
            on_result(result)
    return reason, error
