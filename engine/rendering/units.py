"""The frame as work: tiles, the work units that render sample ranges of a tile, and the wait
for their outcomes.  Units depend on the frame only, never on the workers, so images stay
identical whatever renders them."""
from __future__ import annotations

from dataclasses import dataclass

from ..integrators import path_tracer

MIN_TILES = 4                     # so that both cores of a small frame have work
UNIT_PATHS = 1 << 18              # camera samples per work unit, about: each unit ends with a tail of
                                  # a few paths, so units much smaller than this cost time (1 << 16: +25 %)
TAIL_PATHS = 8192                 # what a unit's tail costs, in paths (engine/rendering/estimate.py)
BALANCE_WORKERS = (1, 2, 3, 4)    # the worker counts balance_units weighs (the units never see the workers)
MOST_BALANCE_SPLITS = 12          # at most this many units split in two by balance_units
MOST_BALANCED_UNITS = 400         # frames of more units lose under 1 % to their last round on 4 workers
SMALLEST_BAND_PATHS = 1 << 14     # balance_units for a known worker count: bands down to this (the
                                  # TAIL_PATHS of each unit in its cost keeps them from being many)
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
    """Samples start .. stop-1 of every pixel of one tile; `chunk` numbers it within the tile.
    With parts > 1 the tile's chunk is split in `parts` bands of rows (balance_units) and the unit
    renders band `part`: its `tile` is then that band (x0, y0, x1, y1) under the tile's index."""
    index: int
    tile: Tile
    chunk: int
    start: int
    stop: int
    mask: bytes | None = None    # packed active pixels of the tile (adaptive sampling); None = all
    halves: bool = False         # render [start, mid) and [mid, stop) apart: the half buffers
    part: int = 0
    parts: int = 1

    @property
    def paths(self) -> int:
        return self.tile.pixels * (self.stop - self.start)


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


def make_units(tiles, samples: int, order: str = "tiles", max_samples: int | None = None,
               balance: bool = True, workers: int | None = None) -> list[WorkUnit]:
    """Each tile's samples in chunks of about UNIT_PATHS camera samples.  order "tiles": a tile's
    chunks one after the other (the frame fills tile by tile); "frame": chunk 0 of every tile,
    then chunk 1, ... (the whole frame refines); "growing": as "frame", with chunks of 1, 1, 2, 4,
    ... samples up to that size (the viewport: a picture of the whole frame after one sample,
    big units after that, engine/pools/viewport.py).  max_samples: a cap on a unit's samples.
    balance: the last units split in bands of rows where that keeps workers busier (balance_units;
    never in the growing order, whose units are small on purpose); workers: see balance_units."""
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
    units = [WorkUnit(i, tile, c, start, stop) for i, (tile, c, start, stop) in enumerate(chunks)]
    return balance_units(units, workers) if balance and order != "growing" else units


def makespan(costs, workers: int) -> float:
    """When the last of `costs` (in dispatch order) ends on `workers` workers that each take the
    next unit as soon as they are free (engine/pools/faults.py Dispatch.feed)."""
    free = [0.0] * max(workers, 1)
    for c in costs:
        i = free.index(min(free))
        free[i] += c
    return max(free)


def split_rows(unit: WorkUnit) -> list[WorkUnit]:
    """The unit as two units of the same samples on the upper and lower half of its tile's rows."""
    t = unit.tile
    mid = t.y0 + (t.y1 - t.y0) // 2
    bands = (Tile(t.index, t.x0, t.y0, t.x1, mid), Tile(t.index, t.x0, mid, t.x1, t.y1))
    return [WorkUnit(unit.index, band, unit.chunk, unit.start, unit.stop, part=p, parts=2)
            for p, band in enumerate(bands)]


def balance_units(units: list[WorkUnit], workers: int | None = None) -> list[WorkUnit]:
    """A frame of few units leaves workers idle at its end (9 equal units on 2 workers: 5 rounds, one
    worker idle in the last).  Split the last k of the units that make two halves of at least
    UNIT_PATHS / 2 paths each in two bands of rows (split_rows), k = 0 .. MOST_BALANCE_SPLITS: the k
    whose makespans (each unit costing its paths plus TAIL_PATHS) summed over BALANCE_WORKERS are
    least, the fewest splits on a tie.  The units depend on the frame only, never on the workers
    that render them.  A band keeps every pixel's sample ranges, and each pixel's sums and random
    numbers (the Sobol' sampler seeds per frame pixel, engine/sampling/qmc.py) depend on nothing
    else: the image is the same bit for bit (tests/rendering/test_units.py; the random sampler
    seeds per unit and band, engine/rendering/session.py).  Frames of more than MOST_BALANCED_UNITS
    units are left as they are (and the search stays short).

    workers: the number of workers the render will have, for a sampler whose numbers depend on the
    frame pixel and the sample only (the Sobol' sampler: engine/rendering/frame.py passes it), whose
    images no split changes: the makespan on that many workers alone is weighed, and bands down to
    SMALLEST_BAND_PATHS paths (96x96 at 64 spp, 2 workers: the 32x32 corner tile split, not the
    64x64 one: makespan 1.19 -> 1.08 x the paths' even share; docs/performance.md "A render's fixed
    cost").  None: the counts of BALANCE_WORKERS and bands of at least UNIT_PATHS / 2."""
    if len(units) > MOST_BALANCED_UNITS:
        return units
    smallest = UNIT_PATHS // 2 if workers is None else SMALLEST_BAND_PATHS
    weighed = BALANCE_WORKERS if workers is None else (max(1, workers),)
    splittable = [i for i, u in enumerate(units)
                  if u.parts == 1 and u.tile.y1 - u.tile.y0 >= 2
                  and (u.tile.y1 - u.tile.y0) // 2 * (u.tile.x1 - u.tile.x0) * (u.stop - u.start) >= smallest]
    best, best_cost = 0, None
    for k in range(min(len(splittable), MOST_BALANCE_SPLITS) + 1):
        split = set(splittable[len(splittable) - k:])
        costs = [c for i, u in enumerate(units)
                 for c in ([u.paths / 2 + TAIL_PATHS] * 2 if i in split else [u.paths + TAIL_PATHS])]
        cost = sum(makespan(costs, w) for w in weighed)
        if best_cost is None or cost < best_cost:
            best, best_cost = k, cost
    split = set(splittable[len(splittable) - best:])
    if not split:
        return units
    out = [p for i, u in enumerate(units) for p in (split_rows(u) if i in split else [u])]
    return [WorkUnit(i, u.tile, u.chunk, u.start, u.stop, u.mask, u.halves, u.part, u.parts)
            for i, u in enumerate(out)]


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
