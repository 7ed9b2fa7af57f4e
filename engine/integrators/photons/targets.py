"""The specular objects' bounding spheres, the targets photons are aimed at (engine/lights/aim.py).

A specular object is a primitive whose scatter group has a delta lobe (a mirror, smooth glass, a
Transparent BSDF, a Principled BSDF with alpha below 1): each implicit sphere and quad of such a
material is one target, and the triangles of such materials in one mesh make one target (the
sphere about their bounding box).  Targets hold every specular surface, so aiming loses no
caustic photon.
"""
from __future__ import annotations

import numpy as np

from ...lights.aim import SphereTargets
from ...materials.protocol import BSDFFlags


def specular_groups(mats) -> np.ndarray:
    """(groups,) bool: whether each scatter group's BSDF has a delta lobe."""
    return np.array([bool(b.flags & BSDFFlags.DELTA) for b in mats.bsdfs] + [False, False])


def specular_targets(scene, mats) -> SphereTargets | None:
    """The targets of `scene` under the material table `mats` (engine/materials/table.py), or None
    when no primitive is specular."""
    groups = specular_groups(mats)
    specular = groups[mats.scatter_group]             # per material id
    centers, radii = [], []
    for s in scene.spheres:
        if specular[s.material_id]:
            centers.append(np.asarray(s.center, dtype=np.float64))
            radii.append(float(s.radius))
    pieces = [np.asarray(q.corners, dtype=np.float64) for q in scene.quads if specular[q.material_id]]
    for mesh in scene.meshes:
        if len(mesh.triangles):
            mine = specular[np.asarray(mesh.material_ids, dtype=np.int64)]
            if mine.any():
                pieces.append(np.asarray(mesh.vertices)[np.unique(np.asarray(mesh.triangles)[mine])])
    for points in pieces:
        lo, hi = points.min(axis=0), points.max(axis=0)
        centers.append(0.5 * (lo + hi))
        radii.append(max(0.5 * float(np.linalg.norm(hi - lo)), 1e-9) * (1.0 + 1e-6))
    if not centers:
        return None
    return SphereTargets(np.array(centers).T, np.array(radii))
