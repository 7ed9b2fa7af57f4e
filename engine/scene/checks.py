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


def validate_quads(quads, n_materials: int) -> None:
    """Quad.validate (engine/scene/model.py) of every quad, its geometric checks as arrays over all
    of them at once (100k quads: 0.1 s, not 3 s); a quad they flag is validated alone, which raises
    its own message."""
    try:
        q = np.array([np.asarray(quad.corners, dtype=np.float64) for quad in quads])
    except (ValueError, TypeError):                       # ragged or not numbers: find which, by itself
        q = None
    if q is None or q.shape != (len(quads), 4, 3):
        for quad in quads:
            quad.validate(n_materials)
        return
    with np.errstate(invalid="ignore", over="ignore"):
        e1, e2, e3 = q[:, 1] - q[:, 0], q[:, 2] - q[:, 0], q[:, 3] - q[:, 0]
        normal = np.cross(e1, e3)
        size = np.maximum(np.maximum(np.linalg.norm(e1, axis=1), np.linalg.norm(e3, axis=1)),
                          np.linalg.norm(e2, axis=1))
        length = np.linalg.norm(normal, axis=1)
        ok = np.isfinite(q).all(axis=(1, 2)) & (np.abs(q).max(axis=(1, 2)) <= LARGEST_VALUE)
        ok &= (length > 1e-12 * size * size) & (size > 0)
        unit = normal / np.where(length > 0, length, 1.0)[:, None]
        ok &= np.abs(np.einsum("ij,ij->i", e2, unit)) <= 1e-6 * size
        for i in range(4):                                 # convex, counter-clockwise
            a, b, c = q[:, i], q[:, (i + 1) % 4], q[:, (i + 2) % 4]
            ok &= np.einsum("ij,ij->i", np.cross(b - a, c - b), unit) > 0
    ids = np.array([quad.material_id for quad in quads], dtype=object)
    ok &= np.array([isinstance(m, (int, np.integer)) and 0 <= m < n_materials for m in ids], dtype=bool)
    for k in np.flatnonzero(~ok):
        quads[k].validate(n_materials)                     # raises (rounding aside: then it passes)
    for quad, corners in zip(quads, q):
        quad.corners = corners
