"""Estimate render time: a short pilot render predicts the time to reach a noise target.

The pilot is the real render's own beginning: the real settings (noise target, min samples,
adaptive, the sample cap's Sobol' nets via `sample_net`) stopped at the first round end of the real
round schedule (engine/rendering/stopping.py) at or past `pilot_samples` (64).  Its rounds, and its adaptive
decisions, are therefore exactly those the real render takes first; if it reaches the target, it
is the prediction.  Otherwise, per pixel p, u_p = n_p * Var[m_p] / (R_p^2 + 0.01)
(engine/film/error_estimate.py) is the relative variance of one sample: after s samples the pixel's
term is u_p / s.  The prediction replays the rest of the round schedule on 8x8 blocks
(U_b = mean of u_p over the block), from each block's samples so far:

* every active block gets the round's samples; with adaptive sampling a block whose error e_b
  (sqrt(U_b / s_b), with the samples to come at F_b below) is at or below the target (after min
  samples) stops;
* the render stops after the first round whose image error sqrt(sum_b w_b e_b^2) (w_b: the
  block's share of the pixels) is at or below the target, or at the samples cap;

and prices each replayed round by its units (and, with caustic photons, by the photon batches it
traces first: the pilot's seconds per batch, `round_photons` of engine/rendering/stopping.py) (one per tile with active blocks, in tile order): a unit
of N pixel-samples costs b (N + 2 TAIL_PATHS), each of its two halves ending with a tail of few
paths that costs about as much as TAIL_PATHS more paths, and the round lasts c times the makespan
of its units on the workers, each taking the next unit when free: when few tiles are left active, a
worker idles (the measurements behind both: docs/performance.md, "Stopping rules").  b (seconds per
unit of work) and c (wall seconds per makespan second; the workers take units greedily, see
engine/pools/faults.py Dispatch.feed) come from the pilot's rounds after the first (the first
pays the workers' warm-up); the pilot's own seconds are part of the predicted time.  Setup (scene
preparation, worker start) is reported apart, as `setup_seconds`.

Heavy-tailed noise (caustics, small lamps seen in mirrors): a block's U from the pilot is a
sample of a skewed estimate.  Most blocks have not yet met their rare bright paths (U too small),
a few have (U far too large).  The pilot's samples stay in the block's error as they are, but the
samples to come are replayed at F = (U + the 3x3 neighbourhood's mean U) / 2
(future_unit_variance): the neighbours' 9x the samples tell how often such paths come.  A block
whose error is then (s0 U + (s - s0) F) / s^2 after s samples falls faster than 1/s after a firefly
(as measured on the caustic room: s^-1.4 to s^-2) and slower where the neighbours met some.
The choice of F against the alternatives (3x3, 5x5, 7x7 and image means), and the predictions
against real renders, are measured in docs/accuracy.md, "Estimate Render Time against the real
render"; paths rarer than one per pilot (spot_light's) stay unseen by any pilot of this length.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..film.error_estimate import BLOCK, rel_terms
from .stopping import effective_min_samples, round_schedule
from .units import TAIL_PATHS, makespan

PILOT_SAMPLES = 64


def block_sums(values: np.ndarray, block: int = BLOCK):
    """(sum over each block, pixels in each block, max over each block), blocks flattened."""
    h, w = values.shape
    bh, bw = -(-h // block), -(-w // block)
    padded = np.zeros((bh * block, bw * block))
    inside = np.zeros_like(padded)
    padded[:h, :w], inside[:h, :w] = values, 1.0
    tiles = padded.reshape(bh, block, bw, block)
    return (tiles.sum(axis=(1, 3)).ravel(), inside.reshape(bh, block, bw, block).sum(axis=(1, 3)).ravel(),
            tiles.max(axis=(1, 3)).ravel())


def block_unit_variance(mean: np.ndarray, var: np.ndarray, count: np.ndarray, block: int = BLOCK):
    """(U_b, pixels_b) per block: the mean relative variance of one sample, and the pixel count."""
    u = rel_terms(mean, var) * count
    sums, pixels, _ = block_sums(np.where(np.isfinite(u), u, 0.0), block)
    return sums / np.maximum(pixels, 1), pixels


def neighbourhood_mean(values: np.ndarray, pixels: np.ndarray, block_shape) -> np.ndarray:
    """Per block (flattened), the pixel-weighted mean of `values` over its 3x3 neighbourhood of
    blocks, itself included (fewer at the image's edges)."""
    bh, bw = block_shape
    total = np.pad((values * pixels).reshape(bh, bw), 1)
    weight = np.pad(pixels.reshape(bh, bw).astype(float), 1)
    near = [(dy, dx) for dy in range(3) for dx in range(3)]
    s = sum(total[dy:dy + bh, dx:dx + bw] for dy, dx in near)
    w = sum(weight[dy:dy + bh, dx:dx + bw] for dy, dx in near)
    return (s / np.maximum(w, 1e-300)).ravel()


def future_unit_variance(unit_var: np.ndarray, pixels: np.ndarray, block_shape) -> np.ndarray:
    """F, the relative variance of a block's samples to come: half its own U, half its 3x3
    neighbourhood's (module doc: heavy-tailed noise)."""
    return 0.5 * (unit_var + neighbourhood_mean(unit_var, pixels, block_shape))


def replay(unit_var: np.ndarray, pixels: np.ndarray, settings, target: float, tile_of_block=None,
           samples=None, done: int = 0, future_var=None) -> dict:
    """The round schedule of engine/rendering/stopping.py played on blocks; pixel-samples, error, stop, and the
    units of work of each round (unit_works).  From the start, or, with
    `samples` (each block's samples so far) and `done` (the round end the pilot reached), from there
    on: the blocks still active are those that got the pilot's last round.  A block's error^2 after
    s samples is (s0 U + (s - s0) F) / s^2: its s0 samples so far at their relative variance U
    (`unit_var`), the ones to come at F (`future_var`, U unless given)."""
    weights = pixels / pixels.sum()
    tile_of_block = np.zeros(len(unit_var), dtype=int) if tile_of_block is None else tile_of_block
    future_var = unit_var if future_var is None else future_var
    round_units = []
    samples = np.zeros(len(unit_var)) if samples is None else np.asarray(samples, dtype=float).copy()
    start = samples.copy()
    active = samples >= done
    minimum = effective_min_samples(settings)
    error, stopped_by = float("nan"), "samples"
    if done > 0 and settings.adaptive:         # the decision the real render takes after that round
        active &= ~((unit_var / samples <= target * target) & (samples >= minimum))
    for _, stop in round_schedule(settings.samples, minimum):
        if stop <= done:
            continue
        if not active.any():
            stopped_by = "noise target"
            break
        units = unit_works(pixels * (stop - samples) * active, tile_of_block)
        round_units.append(units)
        samples[active] = stop
        block_err2 = (start * unit_var + (samples - start) * future_var) / (samples * samples)
        error = float(np.sqrt(np.sum(weights * block_err2)))
        if error <= target and samples.min() >= minimum:
            stopped_by = "noise target"
            break
        if settings.adaptive:
            active &= ~((block_err2 <= target * target) & (samples >= minimum))
    return {"pixel_samples": float(np.sum(pixels * samples)), "mean_samples": float(np.sum(weights * samples)),
            "error": error, "stopped_by": stopped_by, "round_units": round_units}


def unit_works(block_samples: np.ndarray, tile_of_block: np.ndarray) -> list:
    """[(tile, work)] of the units of a round in dispatch (tile) order, one per tile with samples to
    render; work: pixel-samples + the tails of the unit's two halves."""
    per_tile = np.bincount(tile_of_block, weights=block_samples)
    return [(tile, float(w) + 2 * TAIL_PATHS) for tile, w in enumerate(per_tile) if w > 0]


def tile_costs(units, fallback: float):
    """b(tile): a tile's unit seconds per unit of work over the pilot's units [(tile, pixel-samples,
    seconds)]; the mean over all units for a tile without any, `fallback` without units.  Per tile,
    because the blocks that stay active are the costly ones: on the near-lamp room a pixel-sample
    cost 1.3-1.4 us in the first rounds and 1.6 in the last."""
    seconds, work = {}, {}
    for tile, n, t in units:
        seconds[tile] = seconds.get(tile, 0.0) + t
        work[tile] = work.get(tile, 0.0) + n + 2 * TAIL_PATHS
    total = sum(work.values())
    mean = sum(seconds.values()) / total if total > 0 else fallback
    return lambda tile: seconds[tile] / work[tile] if work.get(tile) else mean


def tiles_of_blocks(shape, tile_size: int, block: int = BLOCK) -> np.ndarray:
    """The tile index (engine/rendering/units.py make_tiles order) of each block, flattened as the blocks."""
    h, w = shape
    bh, bw = -(-h // block), -(-w // block)
    by, bx = np.meshgrid(np.arange(bh), np.arange(bw), indexing="ij")
    tiles_x = -(-w // tile_size)
    return ((by * block // tile_size) * tiles_x + bx * block // tile_size).ravel()


def pilot_stop(settings, pilot_samples: int) -> int:
    """The first round end of the real render's schedule at or after `pilot_samples` (or its cap), so
    that the pilot's rounds are the real render's first rounds."""
    for _, stop in round_schedule(settings.samples, effective_min_samples(settings)):
        if stop >= pilot_samples:
            return stop
    return settings.samples


def new_batches(ranges, done: int) -> list:
    """Photon batches each of the sample ranges [(start, stop)] of replayed rounds traces: those of
    its samples not traced by the rounds before it (the pilot's rounds end at sample `done`)."""
    from ..integrators.photons.caustics import batches_of
    traced = set(batches_of(0, done))
    out = []
    for start, stop in ranges:
        mine = set(batches_of(start, stop)) - traced
        out.append(len(mine))
        traced |= mine
    return out


def predict(film, seconds: float, settings, target: float, round_log, tile_size: int, workers: int,
            done: int, round_photons=None) -> dict:
    """The prediction from a pilot that was the real render's first rounds up to the round end
    `done`: its film (FrameFilm), render seconds and rounds [(pixel-samples, seconds, [(tile,
    unit pixel-samples, unit seconds)])] (engine/rendering/stopping.py run_rounds).  From the pilot's rounds after the first (all, if it had one):
    b, the seconds of a unit per unit of work (unit_works), and c, a round's wall seconds per second
    of its makespan on `workers`; each replayed round then costs c * makespan(b * its units).
    round_photons (per pilot round: photon batches, their units' seconds; None without photons): a
    photon batch costs the pilot's seconds per batch, one more unit in its round's makespan."""
    count = film.samples_per_pixel
    unit_var, pixels = block_unit_variance(film.mean().astype(np.float64), film.half_buffer_variance(), count)
    h, w = count.shape
    future = future_unit_variance(unit_var, pixels, (-(-h // BLOCK), -(-w // BLOCK)))
    played = replay(unit_var, pixels, settings, target, tiles_of_blocks(film.count.shape, tile_size),
                    block_sums(count)[2], done, future)
    later = list(round_log)[1:] or list(round_log)
    units = [u for _, _, round_units in later for u in round_units]
    b = tile_costs(units, seconds / max(float(count.sum()), 1.0))
    photons = list(round_photons or [])
    later_photons = (photons[1:] or photons) if len(photons) == len(round_log) else [(0, 0.0)] * len(later)
    batches = sum(n for n, _ in photons)
    per_batch = sum(t for _, t in photons) / batches if batches else 0.0

    def batch_costs(n, t=None):
        return [t / n if t is not None else per_batch] * n if n else []
    spans = sum(makespan(batch_costs(pn, pt) + [b(tile) * (n + 2 * TAIL_PATHS) for tile, n, _ in round_units],
                         workers)
                for (_, _, round_units), (pn, pt) in zip(later, later_photons))
    c = sum(t for _, t, _ in later) / spans if spans > 0 else 1.0
    ranges = [r for r in round_schedule(settings.samples, effective_min_samples(settings)) if r[1] > done]
    traced = new_batches(ranges[:len(played["round_units"])], done) if batches else [0] * len(played["round_units"])
    played["seconds"] = seconds + sum(c * makespan(batch_costs(n) + [b(tile) * w for tile, w in round_units], workers)
                                      for round_units, n in zip(played["round_units"], traced))
    played["reachable"] = played["stopped_by"] == "noise target"
    return played


def estimate(scene, settings, target: float, render, pilot_samples: int = PILOT_SAMPLES, **render_kwargs) -> dict:
    """Render the pilot with `render(scene, settings, **render_kwargs)` (engine/api.py render, with any
    pool) and predict the real render under `settings` with noise
    target `target` (the settings' own time limit is ignored).  The pilot is the real render's own
    first rounds (module doc): when it reaches the target, it is the prediction."""
    real = dataclasses.replace(settings, noise_target=target, time_limit=0.0)
    done = pilot_stop(real, pilot_samples)
    pilot = dataclasses.replace(real, samples=done, sample_net=real.sample_net or real.samples)
    result = render(scene, pilot, **render_kwargs)
    if result.cancelled or result.film is None:
        raise RuntimeError("the pilot render was cancelled")
    seconds = result.stats["render_seconds"]
    st = result.stats
    if st.get("stopped_by") == "noise target":
        spp = result.film.samples_per_pixel
        out = {"pixel_samples": float(spp.sum()), "mean_samples": float(spp.mean()), "stopped_by": "noise target",
               "error": st["estimated_rel_error"], "seconds": seconds, "reachable": True}
    else:
        out = predict(result.film, seconds, real, target, st["round_log"], st["tile_size"], st["threads"], done,
                      st.get("round_photons"))
        if done >= real.samples:         # the pilot was the whole render: its error is the answer
            out["error"] = st.get("estimated_rel_error")
    out.update({"target_rel_error": target, "pilot_samples": pilot.samples, "pilot_seconds": seconds,
                "pilot_rel_error": result.stats.get("estimated_rel_error"),
                "setup_seconds": result.stats.get("setup_seconds"), "samples_cap": settings.samples,
                "adaptive": settings.adaptive, "resolution": list(scene.resolution)})
    return {k: None if isinstance(v, float) and not np.isfinite(v) else v for k, v in out.items()}  # JSON has no NaN


def describe(e: dict) -> str:
    """One line: "≈ 42 s to 1 % (adaptive, mean 180 spp; pilot 16 spp: error 8.0 % in 2.1 s)";
    without a reachable target: "the cap of 16 samples reaches ≈ 4.2 % (not 1 %) in ≈ 0.8 s (...)".
    With `no_noise_target` (the add-on's panel has the noise target off) the render is uniform and
    the line says so.  Unknown errors read "?", never "nan"."""
    percent = (lambda x: "?" if x is None or not np.isfinite(x) else f"{x * 100:.2f}")
    if e["reachable"]:
        head = f"≈ {e['seconds']:.1f} s to {e['target_rel_error'] * 100:g} %"
    else:
        head = (f"the cap of {e['samples_cap']} samples reaches ≈ {percent(e.get('error'))} % "
                f"(not {e['target_rel_error'] * 100:g} %) in ≈ {e['seconds']:.1f} s")
    if e["adaptive"]:
        mode = "adaptive"
    elif e.get("no_noise_target"):
        mode = "uniform: adaptive sampling off without a noise target"
    else:
        mode = "uniform: adaptive sampling off"
    pilot = e.get("pilot_rel_error")
    pilot_error = "?" if pilot is None or not np.isfinite(pilot) else f"{pilot * 100:.1f}"
    return (f"{head} ({mode}, mean {e['mean_samples']:.0f} spp; pilot "
            f"{e['pilot_samples']} spp: error {pilot_error} % in {e['pilot_seconds']:.2f} s)")
