"""The error estimate of a rendered image, from two independent half buffers (as Cycles).

Every round of the stopping rules (engine/rendering/stopping.py) renders each pixel's sample range in two
halves, A and B, kept apart in the film (engine/rendering/frame.py FrameFilm.sum_a / count_a).  With
n_a and n_b samples and half means m_a and m_b, the pixel mean m = (n_a m_a + n_b m_b) / n has variance sigma^2 / n
and m_a - m_b has variance sigma^2 (1/n_a + 1/n_b), so

    Var[m] ~ (m_a - m_b)^2 n_a n_b / n^2          (= (m_a - m_b)^2 / 4 for equal halves)

is an unbiased estimate of the variance of the pixel mean per channel that needs no sum of
squares: a single firefly in one half shows as a large difference, and a pixel does not look
converged just because its few samples agree (the sample variance of a pixel that has not yet met
its rare bright paths is small, and so is this one; averaging over a block, below, helps both).

The relative error of an image (docs/user-guide.md, "Stopping rules"), matching the study's relMSE
(engine/studies/accuracy.py: mean((I - R)^2 / (R^2 + 0.01))):

    relative error E = sqrt( mean over pixels p and channels c of Var[m_pc] / (m_pc^2 + 0.01) )

so E^2 is the expected relMSE of the image against the converged one.  A block's error is the
same mean over the block's pixels only.
"""
from __future__ import annotations

import numpy as np

REL_FLOOR = 0.01          # the + 0.01 of relMSE: dark pixels do not dominate
BLOCK = 8                 # adaptive sampling decides per BLOCK x BLOCK pixels


def half_buffer_variance(sum_: np.ndarray, count: np.ndarray, sum_a: np.ndarray, count_a: np.ndarray) -> np.ndarray:
    """(H, W, 3) variance of each pixel mean from the two halves; NaN where a half is empty."""
    n_a = count_a[..., None]
    n_b = (count - count_a)[..., None]
    n = count[..., None]
    with np.errstate(invalid="ignore", divide="ignore"):
        m_a = sum_a / n_a
        m_b = (sum_ - sum_a) / n_b
        var = (m_a - m_b) ** 2 * n_a * n_b / (n * n)
    var[np.broadcast_to((n_a == 0) | (n_b == 0), var.shape)] = np.nan
    return var


def neighbour_mean(image: np.ndarray) -> np.ndarray:
    """(H, W, C) mean of each pixel's 8 neighbours, the pixel itself left out; at the image's edges
    over the neighbours inside it (a 1-pixel image keeps its own value)."""
    h, w = image.shape[:2]
    padded = np.pad(image, ((1, 1), (1, 1), (0, 0)))
    inside = np.pad(np.ones((h, w, 1)), ((1, 1), (1, 1), (0, 0)))
    ring = [(dy, dx) for dy in range(3) for dx in range(3) if (dy, dx) != (1, 1)]
    total = sum(padded[dy:dy + h, dx:dx + w] for dy, dx in ring)
    count = sum(inside[dy:dy + h, dx:dx + w] for dy, dx in ring)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1), image)


def rel_terms(mean: np.ndarray, var: np.ndarray) -> np.ndarray:
    """(H, W) per-pixel Var / (R^2 + 0.01), averaged over the channels (NaN stays NaN), with the
    converged value R estimated by the mean of the pixel's 8 neighbours, the pixel left out.

    Not the pixel's own mean: that is correlated with its variance estimate (a pixel that met a bright
    path has a large mean and a large variance, one that did not has both small), which made E 35 %
    too small on the Cornell box at 64 spp.  Not the 3x3 box mean either (used until 2026-12): its
    ninth share of the pixel's own firefly still inflates R exactly where the variance is.  The
    neighbours' samples are independent of the pixel's, so the ratio is not biased by that
    correlation (measured: docs/accuracy.md, "The error estimate")."""
    r = neighbour_mean(np.nan_to_num(mean))
    return np.mean(var / (r * r + REL_FLOOR), axis=-1)


def image_rel_error(mean: np.ndarray, var: np.ndarray) -> float:
    """E above over the pixels that have an estimate; NaN when none has."""
    terms = rel_terms(mean, var)
    good = np.isfinite(terms)
    return float(np.sqrt(terms[good].mean())) if good.any() else float("nan")


def block_rel_errors(mean: np.ndarray, var: np.ndarray, block: int = BLOCK) -> np.ndarray:
    """(ceil(H/block), ceil(W/block)) E of each block; NaN for a block without any estimate."""
    terms = rel_terms(mean, var)
    h, w = terms.shape
    bh, bw = -(-h // block), -(-w // block)
    padded = np.full((bh * block, bw * block), np.nan)
    padded[:h, :w] = terms
    blocks = padded.reshape(bh, block, bw, block).swapaxes(1, 2).reshape(bh, bw, block * block)
    good = np.isfinite(blocks)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_terms = np.where(good, blocks, 0.0).sum(axis=-1) / good.sum(axis=-1)
    return np.sqrt(mean_terms)


def seconds_to_target(seconds: float, error: float, target: float) -> float:
    """Render time at which the error reaches `target`: the variance of an unbiased estimate falls
    as 1/samples, so E^2 t is constant at a constant sample rate (pbrt-v3 §13.7)."""
    if not (np.isfinite(error) and error > 0 and target > 0):
        return 0.0 if error == 0 else float("nan")
    return seconds * (error / target) ** 2
