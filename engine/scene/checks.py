"""Validation of scene values shared by the scene model, its files and the textures: magnitudes,
vectors and resolutions, each failing with a SceneError that names the object."""
from __future__ import annotations

import numpy as np

from ..core.errors import SceneError

# Radiance, colours, coordinates and radii: far inside float32 (3.4e38, the image and Embree's
# type), so that sums over samples and squares (r^2 of a sphere) stay finite.
LARGEST_VALUE = 1e30
LENS_RANGE = (1e-3, 1e6)          # millimetres; Blender's own minimum is 1 mm


def check_magnitude(owner: str, label: str, value) -> None:
    """SceneError when any of the (already finite) numbers exceeds LARGEST_VALUE in magnitude."""
    largest = float(np.abs(np.asarray(value, dtype=np.float64)).max(initial=0.0))
    if largest > LARGEST_VALUE:
        raise SceneError(f"{owner}: {label} {largest:.3g} is too large (at most {LARGEST_VALUE:.0e})")


def check_resolution(name: str, resolution) -> tuple:
    try:
        w, h = resolution
    except (TypeError, ValueError):
        raise SceneError(f"Scene '{name}': resolution must be 2 integers, got {resolution!r}") from None
    if any(isinstance(v, bool) or not isinstance(v, (int, np.integer)) for v in (w, h)):
        raise SceneError(f"Scene '{name}': resolution must be 2 integers, got {resolution!r}")
    return int(w), int(h)


def check_vector(owner: str, label: str, value, non_negative: bool = False) -> np.ndarray:
    """The 3 finite (and, if asked, non-negative) numbers of `value` within LARGEST_VALUE, or a
    SceneError naming them."""
    v = np.asarray(value, dtype=np.float64)
    if v.shape != (3,) or not np.isfinite(v).all() or (non_negative and (v < 0).any()):
        raise SceneError(f"{owner}: {label} must be 3 finite {'non-negative ' if non_negative else ''}numbers")
    check_magnitude(owner, label, v)
    return v
