"""Stopping rules and adaptive sampling: the frame rendered in rounds of sample ranges.

Used by Frame.run (engine/rendering/frame.py) when a time limit or a noise target is set
(settings.stopping_rules()).  Round k renders samples [start_k, stop_k) of every pixel that is
still active, one work unit per tile that has active pixels, each unit in two halves whose sums
the film keeps apart (the half buffers of engine/film/error_estimate.py).  After each round, once
all of its units are merged:

* the image's estimated relative error E is computed; the render stops when E <= noise target and
  every pixel has at least `min_samples` (the noise target), or when the samples run out;
* with adaptive sampling, blocks of BLOCK x BLOCK pixels whose own error is at or below the
  target (after min_samples) get no more samples; the next round renders the others;
* the time limit cancels the units in flight when it expires (they are dropped whole, as Esc);
  the image keeps every finished unit.

Decisions are made only between rounds, on the film after the whole round is merged in the
film's fixed per-tile order, so with a fixed seed and no time limit the samples each pixel gets,
and the image, are the same for any number or kind of workers.  A pool takes rounds when its
`takes_rounds` is true (engine/pools/protocol.py): it accepts start() again with more units.

Round sizes: the first round is max(min_samples, FIRST_ROUND) samples, each later one half of the
samples so far (at least FIRST_ROUND), so there are about log1.5(samples) rounds.  Under a time
limit a round is cut to the samples that fit in the time left at the rate measured so far (units
cancelled at the limit are lost work: up to a third of the render with uncut rounds).

The stats gain `stopped_by`, `rounds` (the rounds rendered) and `round_log`; with caustic photons,
`round_photons`: per round, the photon batches traced and their units' seconds
(engine/rendering/photon_passes.py).  The photon batches are work of the rounds like the camera
units: the time limit, the rates of fit_round and the round times that the error estimate
(engine/rendering/estimate.py) prices include them.
"""
from __future__ import annotations

import math
import time

import numpy as np

from ..film.error_estimate import BLOCK, block_rel_errors, half_buffer_variance, seconds_to_target
from .masked_samples import pack_mask

FIRST_ROUND = 8            # samples of the first round at least
AUTO_MIN_SAMPLES_CAP = 128  # automatic min samples at most (Cycles' guess at T = 0.001)


def round_schedule(samples: int, min_samples: int = 0) -> list[tuple[int, int]]:
    """[(start, stop)] sample ranges of the rounds, covering 0 .. samples."""
    ranges, done = [], 0
    first = min(samples, max(FIRST_ROUND, min_samples))
    while done < samples:
        size = first if not ranges else max(FIRST_ROUND, done // 2)
        ranges.append((done, min(samples, done + size)))
        done = ranges[-1][1]
    return ranges


def effective_min_samples(settings) -> int:
    """Min samples; 0 is automatic: FIRST_ROUND, and with a noise target T Cycles' guess
    ceil(16 / T^0.3) (T = 0.1 -> 32, 0.01 -> 64; at most 128).  Heavy-tailed noise (caustics) hides
    from a pixel's first samples: a block that has not met its rare bright paths reads converged.
    No min samples makes heavy-tailed noise safe, it only makes an early stop less likely
    (measured: docs/accuracy.md, "Min samples and heavy-tailed noise")."""
    if settings.min_samples:
        return min(settings.samples, settings.min_samples)
    auto = FIRST_ROUND
    if settings.noise_target > 0:
        auto = max(FIRST_ROUND, min(AUTO_MIN_SAMPLES_CAP, math.ceil(16.0 / settings.noise_target ** 0.3)))
    return min(settings.samples, auto)


class RoundState:
    """What the rounds decide from the film: the error, the active blocks, the stop reason."""

    def __init__(self, frame):
        self.frame = frame
        h, w = frame.film.count.shape
        self.block_shape = (-(-h // BLOCK), -(-w // BLOCK))
        self.active_blocks = np.ones(self.block_shape, dtype=bool)
        self.error = float("nan")

    def update(self) -> None:
        film, s = self.frame.film, self.frame.settings
        mean = film.mean().astype(np.float64)
        var = half_buffer_variance(film.sum, film.count, film.sum_a, film.count_a)
        from ..film.error_estimate import image_rel_error
        self.error = image_rel_error(mean, var)
        if s.noise_target > 0 and s.adaptive:
            errors = block_rel_errors(mean, var)
            min_count = film.count.copy()
            h, w = min_count.shape
            bh, bw = self.block_shape
            padded = np.full((bh * BLOCK, bw * BLOCK), np.inf)
            padded[:h, :w] = min_count
            fewest = padded.reshape(bh, BLOCK, bw, BLOCK).min(axis=(1, 3))
            done = (errors <= s.noise_target) & (fewest >= effective_min_samples(s))
            self.active_blocks &= ~done

    def reached_target(self) -> bool:
        s, film = self.frame.settings, self.frame.film
        return (s.noise_target > 0 and np.isfinite(self.error) and self.error <= s.noise_target
                and film.count.min() >= effective_min_samples(s))

    def tile_mask(self, tile):
        """None (all pixels), False (none) or the packed mask of the tile's active pixels."""
        if self.active_blocks.all():
            return None
        pixel_active = np.repeat(np.repeat(self.active_blocks, BLOCK, axis=0), BLOCK, axis=1)
        active = pixel_active[tile.y0:tile.y1, tile.x0:tile.x1]
        if not active.any():
            return False
        return None if active.all() else pack_mask(active)


def run_rounds(frame, pool, on_tile=None, should_cancel=None, on_progress=None, clock=time.perf_counter):
    """Frame.run under stopping rules; the same callbacks.  `clock` is replaceable (tests)."""
    from .units import WorkUnit, await_units
    s = frame.settings
    state = RoundState(frame)
    schedule = round_schedule(s.samples, effective_min_samples(s))
    frame.units, frame.film.units_total = [], 0
    chunk_of = {t.index: 0 for t in frame.tiles}
    cancelled = timed_out = False
    error, stopped_by, rounds = None, "samples", 0
    # per finished round: (pixel-samples added, seconds, [(tile, unit pixel-samples, unit seconds)])
    round_log = []
    round_photons = []                  # per finished round: (photon batches traced, their units' seconds)
    schedule_of_photons = frame.photon_schedule
    start = clock()
    try:
        if not pool.takes_rounds:
            from ..core.errors import SceneError
            raise SceneError(f"the time limit and the noise target do not work on {pool.describe} yet "
                             "(it takes the units of a frame once)")
        done_samples = 0
        for first, stop in schedule:
            first = done_samples
            if first >= s.samples:
                break
            if s.time_limit > 0 and rounds:
                stop = fit_round(first, stop, frame.film.count, clock() - start, s.time_limit)
                if stop <= first:
                    timed_out = True
                    break
            done_samples = stop
            units = []
            for tile in frame.tiles:
                mask = state.tile_mask(tile)
                if mask is False:
                    continue
                units.append(WorkUnit(len(frame.units) + len(units), tile, chunk_of[tile.index], first, stop,
                                      mask=mask, halves=True))
                chunk_of[tile.index] += 1
            if not units:
                stopped_by = "noise target"
                break
            frame.units.extend(units)
            frame.film.units_total = len(frame.units)
            round_start, samples_before = clock(), float(frame.film.count.sum())
            photons_before = ((schedule_of_photons.photon_units, schedule_of_photons.photon_seconds)
                              if schedule_of_photons is not None else None)
            pool.start(units)
            rounds += 1
            unit_log = []

            def merge(result):
                unit_log.append((result.unit.index, result.unit.tile.index, float(result.count.sum()),
                                 result.seconds))
                frame.add_and_show(result, on_tile)

            def interrupt():
                if should_cancel is not None and should_cancel():
                    return "cancelled"
                return "time limit" if s.time_limit > 0 and clock() - start >= s.time_limit else None
            reason, exc = await_units(pool, len(units), merge, interrupt, poll=0.05)
            error = error or exc
            cancelled, timed_out = reason == "cancelled", reason == "time limit"
            if error is not None or cancelled or timed_out:
                break
            round_log.append((float(frame.film.count.sum()) - samples_before, clock() - round_start,
                              [u[1:] for u in sorted(unit_log)]))      # in dispatch order
            if photons_before is not None:
                round_photons.append((schedule_of_photons.photon_units - photons_before[0],
                                      schedule_of_photons.photon_seconds - photons_before[1]))
            state.update()
            elapsed = clock() - start
            if on_progress is not None:
                on_progress(stop / s.samples, progress_message(
                    stop, s.samples, state.error, remaining_seconds(stop, s, state.error, elapsed)))
            if state.reached_target():
                stopped_by = "noise target"
                break
            if s.time_limit > 0 and elapsed >= s.time_limit:
                timed_out = True
                break
    finally:
        pool.close()
    if error is not None:
        raise error
    stopped_by = "cancelled" if cancelled else "time limit" if timed_out else stopped_by
    unsampled = int((frame.film.count == 0).sum())
    if timed_out and unsampled:
        frame.warnings.append(f"the time limit ({s.time_limit:g} s) ran out before {unsampled} of "
                              f"{frame.film.count.size} pixels had a sample: they are black and have no error estimate")
    result = frame.result(clock() - start, cancelled, pool.describe)
    result.stats.update({"stopped_by": stopped_by, "rounds": rounds, "round_log": round_log})
    if schedule_of_photons is not None:
        result.stats["round_photons"] = round_photons
    return result


def fit_round(first: int, stop: int, count: np.ndarray, elapsed: float, limit: float) -> int:
    """The end of a round cut so that it ends by the time limit, at the pixel-sample rate so far
    (the round covers at most every pixel: a conservative cost for adaptive rounds)."""
    rendered = float(count.sum())
    if rendered <= 0 or elapsed <= 0:
        return stop
    per_sample = elapsed / rendered * count.size               # seconds per sample of every pixel
    fits = int((limit - elapsed) / per_sample * 0.9)           # 10 % margin for the tail of a round
    return min(stop, first + fits) if fits >= 1 else first


def remaining_seconds(samples: int, settings, error: float, seconds: float) -> float:
    """The time left after `seconds` and `samples` of the cap: at the sample rate so far for the
    samples to come, sooner when the noise target (seconds_to_target, engine/film/error_estimate.py)
    or the time limit comes first."""
    left = seconds * (settings.samples - samples) / samples if samples > 0 else float("nan")
    if settings.noise_target > 0 and np.isfinite(error):
        left = min(left, max(seconds_to_target(seconds, error, settings.noise_target) - seconds, 0.0))
    if settings.time_limit > 0:
        left = min(left, max(settings.time_limit - seconds, 0.0))
    return left


def clock_text(seconds: float) -> str:
    """mm:ss (h:mm:ss from an hour on), as Cycles' "Remaining"; "--:--" when unknown."""
    if not np.isfinite(seconds):
        return "--:--"
    whole = int(round(max(seconds, 0.0)))
    hours, rest = divmod(whole, 3600)
    return f"{hours}:{rest // 60:02d}:{rest % 60:02d}" if hours else f"{rest // 60:02d}:{rest % 60:02d}"


def progress_message(samples: int, cap: int, error: float, remaining: float) -> str:
    """The stats line: "Sample 48/256 · Remaining 00:12 · est. error 2.1 %" (the error left out
    while some pixel has no estimate yet)."""
    text = f"Sample {samples}/{cap} · Remaining {clock_text(remaining)}"
    if np.isfinite(error):
        text += f" · est. error {error * 100:.1f} %"
    return text
