"""Noise-aware comparison of two renderers (docs/hard-cases.md §3.5, region-mean test).

Each renderer is run K times with independent seeds (TNCG15 MC's seeds through `independent_seed`: its
seeds s and s + 1 give the same camera samples one pixel row apart, engine/sampling/qmc.py pixel_seeds,
so consecutive seeds make correlated runs and too small a spread between them).  Pixels are independent in both renderers
(box filter of width 1), so the variance of a block mean is the block average of the per-pixel
variances of the K-run means, divided by the block's pixel count; the per-pixel variances come
from the K runs (K-1 degrees of freedom each, pooled over the block's pixels).

A block/channel passes if  |mean_I - mean_R| <= z * SE + tau * |mean_R|,  where z is the
Sidak-corrected two-sided normal quantile for all blocks x channels and tau an explicit
model-difference budget (e.g. Schlick vs exact Fresnel, tessellated vs implicit spheres).
The image mean is tested the same way.  The comparison fails when any test fails.
"""
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import norm

SEED_STRIDE = 1 << 16       # more pixel rows than any image has: no two runs share a pixel seed


def independent_seed(label: int) -> int:
    """The tracer seed of run `label` (0 <= label < 2^15; the tests number their runs first_seed,
    first_seed + 1, ...): label x 2^16, so the seeds of any two labels differ by more than an image's
    rows and their runs share no camera samples (see the module's docstring)."""
    if not 0 <= label < 1 << 15:
        raise ValueError(f"run label {label} outside [0, 2^15)")
    return label * SEED_STRIDE


def run_seeds(first: int, k: int) -> list:
    """The tracer seeds of the K runs labelled first .. first + k - 1 (independent_seed)."""
    return [independent_seed(first + i) for i in range(k)]


@dataclass
class Comparison:
    passed: bool
    image_mean_ours: float
    image_mean_ref: float
    image_z: float
    worst_block_z: float            # largest |delta| / SE over blocks and channels (no tau)
    worst_block_excess: float       # largest (|delta| - tau*|ref|) / SE; > z_crit means fail
    z_crit: float
    failed_blocks: int
    n_tests: int
    tau: float
    details: dict = field(default_factory=dict)

    def summary(self):
        return (f"{'PASS' if self.passed else 'FAIL'}: image mean {self.image_mean_ours:.4f} vs "
                f"{self.image_mean_ref:.4f} (z={self.image_z:+.2f}), worst block |z|={self.worst_block_z:.2f}, "
                f"worst excess={self.worst_block_excess:.2f} vs z_crit={self.z_crit:.2f}, "
                f"failed {self.failed_blocks}/{self.n_tests}, tau={self.tau}")


def block_means(x, block):
    """(..., H, W, C) -> (..., H/b, W/b, C) block means (H, W cropped to multiples of b)."""
    h, w = x.shape[-3] // block * block, x.shape[-2] // block * block
    x = x[..., :h, :w, :]
    shape = x.shape[:-3] + (h // block, block, w // block, block, x.shape[-1])
    return x.reshape(shape).mean(axis=(-4, -2))


def compare_runs(ours, ref, *, block=8, alpha=0.01, tau=0.02, var_floor=1e-8):
    """ours, ref: (K, H, W, 3) linear images from K independent seeds each."""
    ours = np.asarray(ours, dtype=np.float64)
    ref = np.asarray(ref, dtype=np.float64)
    if ours.shape[1:] != ref.shape[1:]:
        raise ValueError(f"image shapes differ: {ours.shape} vs {ref.shape}")
    if len(ours) < 2 or len(ref) < 2:
        raise ValueError("need at least 2 runs of each renderer")
    if not (np.isfinite(ours).all() and np.isfinite(ref).all()):
        return Comparison(False, float("nan"), float("nan"), float("inf"), float("inf"), float("inf"),
                          0.0, -1, 0, tau, {"reason": "non-finite pixels"})
    mi, mr = ours.mean(0), ref.mean(0)
    vi = ours.var(0, ddof=1) / len(ours)          # variance of the K-run mean, per pixel
    vr = ref.var(0, ddof=1) / len(ref)
    n_pix = block * block
    bi, br = block_means(mi, block), block_means(mr, block)
    se = np.sqrt((block_means(vi, block) + block_means(vr, block)) / n_pix + var_floor)
    delta = np.abs(bi - br)
    n_tests = delta.size + 1
    alpha_sidak = 1.0 - (1.0 - alpha) ** (1.0 / n_tests)
    z_crit = float(norm.isf(alpha_sidak / 2))
    excess = (delta - tau * np.abs(br)) / se
    failed = int((excess > z_crit).sum())
    # image mean (all channels)
    P = mi.size
    img_i, img_r = mi.mean(), mr.mean()
    img_se = np.sqrt((vi.sum() + vr.sum()) / P ** 2 + var_floor)
    img_excess = (abs(img_i - img_r) - tau * abs(img_r)) / img_se
    image_ok = img_excess <= z_crit
    return Comparison(
        passed=bool(failed == 0 and image_ok),
        image_mean_ours=float(img_i), image_mean_ref=float(img_r),
        image_z=float((img_i - img_r) / img_se),
        worst_block_z=float((delta / se).max()), worst_block_excess=float(excess.max()),
        z_crit=z_crit, failed_blocks=failed + (0 if image_ok else 1), n_tests=n_tests, tau=tau,
        details=dict(block_delta=bi - br, block_se=se, block_ref=br))
