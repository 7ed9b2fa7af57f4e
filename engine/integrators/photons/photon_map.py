"""One pass's caustic photons and the density estimate over them (Jensen 1996, eq. of the photon
map's radiance estimate):

    L_c(x, wo) = 1 / (pi r^2)  sum over photons p within r of x  f(x, wo, wi_p) Phi_p

with a disk kernel of the pass's radius r, over the photons whose surface faces the same way
(facing normals within 60 degrees: photons on the other side of a thin wall, or on a
perpendicular wall within r, are not gathered).  The photons are held in scipy's cKDTree; where
scipy is missing (Blender's own Python, which the add-on's render workers run) a uniform grid of
NumPy arrays finds the same pairs (`grid_pairs`).

The radius schedule: r_k^2 = r_1^2 prod_{i=1}^{k-1} (i + alpha) / (i + 1) for pass k = 1, 2, ...
(SPPM's reduction, Hachisuka & Jensen 2009, as a global per-pass radius: probabilistic
progressive photon mapping, Knaus & Zwicker 2011).  Each pass is an independent estimate whose
bias falls as r_k^2 ~ k^(alpha - 1) and whose variance grows as 1 / r_k^2; the image is the mean
over the passes, whose bias falls as n^(alpha - 1) and variance as n^(-alpha): consistent for
0 < alpha < 1.
"""
from __future__ import annotations

import itertools
import math

import numpy as np

from ...core.vec import dot

try:
    from scipy.spatial import cKDTree
    from scipy.special import gammaln
except ImportError:             # Blender's Python: the grid below, and the standard library's log Gamma
    cKDTree = None
    gammaln = math.lgamma

SAME_SIDE_COS = 0.5
GRID_CELLS = 1 << 20            # the grid's cells per axis at most (its int64 keys)


def radius_of_pass(r1: float, k: int, alpha: float) -> float:
    """r_k (k = 0, 1, ...: the first pass has r1), the product in closed form with Gamma functions."""
    j = k + 1
    log_ratio = gammaln(j + alpha) - gammaln(1.0 + alpha) - gammaln(j + 1.0)
    return float(r1 * np.exp(0.5 * log_ratio))


def grid_pairs(points, photons, radius):
    """(query index, photon index) of every photon (rows `photons`) within `radius` of each point
    (rows `points`), as cKDTree.sparse_distance_matrix finds them (distance <= radius), in another
    order: the photons sorted into cubic cells of at least the radius, each point against the 27
    cells around its own."""
    lo = np.minimum(points.min(axis=1), photons.min(axis=1))
    extent = float(np.max(np.maximum(points.max(axis=1), photons.max(axis=1)) - lo))
    cell = max(radius, extent / GRID_CELLS, 1e-300)
    pc = np.floor((photons - lo[:, None]) / cell).astype(np.int64) + 1
    qc = np.floor((points - lo[:, None]) / cell).astype(np.int64) + 1
    dims = np.maximum(pc.max(axis=1), qc.max(axis=1)) + 2

    def key(c):
        return (c[0] * dims[1] + c[1]) * dims[2] + c[2]
    order = np.argsort(key(pc), kind="stable")
    keys = key(pc)[order]
    m = points.shape[1]
    found_i, found_j = [], []
    for step in itertools.product((-1, 0, 1), repeat=3):
        k = key(qc + np.array(step)[:, None])
        first = np.searchsorted(keys, k, "left")
        count = np.searchsorted(keys, k, "right") - first
        total = int(count.sum())
        if not total:
            continue
        i = np.repeat(np.arange(m), count)
        j = order[np.repeat(first - (np.cumsum(count) - count), count) + np.arange(total)]
        near = ((points.take(i, axis=1) - photons.take(j, axis=1)) ** 2).sum(axis=0) <= radius * radius
        found_i.append(i[near])
        found_j.append(j[near])
    if not found_i:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(found_i).astype(np.int64), np.concatenate(found_j).astype(np.int64)


class PhotonMap:
    def __init__(self, stored, radius: float, label=None):
        """stored: engine/integrators/photons/tracing.py Stored; radius: this pass's; label: keep only
        the stored photons of that label (None: all)."""
        keep = slice(None) if label is None else np.flatnonzero(stored.label == label)
        self.position, self.incoming, self.flux, self.normal = (a[:, keep] for a in (
            stored.position, stored.incoming, stored.flux, stored.normal))
        self.segments = stored.segments[keep]
        self.chain = stored.chain[:, keep]
        self.count = self.position.shape[1]
        self.radius = float(radius)
        self.tree = cKDTree(self.position.T) if self.count and cKDTree is not None else None
        # The tree's nodes and index: about 40 bytes a photon more.
        self.nbytes = sum(a.nbytes for a in (self.position, self.incoming, self.flux, self.normal)) + 40 * self.count

    def pairs(self, points, radius):
        """(query index, photon index) of every photon within the radius of each point (rows): the
        pairs of a tree over the points against the photons' (cKDTree.sparse_distance_matrix, which
        returns them as arrays)."""
        if self.count == 0 or points.shape[1] == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        if self.tree is None:
            return grid_pairs(points, self.position, radius)
        found = cKDTree(points.T).sparse_distance_matrix(self.tree, radius, output_type="ndarray")
        return found["i"].astype(np.int64), found["j"].astype(np.int64)

    def radiance(self, bsdf, si, points, facing, segments=None, scale: float = 1.0, budget=None) -> np.ndarray:
        """(3, M) the caustic radiance towards si.wo at the M points (rows) of the ShadingPoint si
        (engine/materials/protocol.py) whose BSDF is `bsdf`; facing: their geometric normals on the
        viewer's side; segments (M,): the most segments a photon's path may have at each point
        (the camera path's depth limit; None: any); scale: of the radius (vertices seen after a
        diffuse bounce gather over a wider disk); budget (3, M): the most glossy, transmission and
        transparent bounces a photon's chain may make but its first (Cycles' bounce limits per type
        left over by the camera path, engine/integrators/light_paths.py; None: any)."""
        m = points.shape[1]
        out = np.zeros((3, m))
        radius = self.radius * scale
        query, photon = self.pairs(points, radius)
        if not len(query):
            return out
        same = dot(facing.take(query, axis=1), self.normal.take(photon, axis=1)) > SAME_SIDE_COS
        if segments is not None:
            same &= self.segments.take(photon) <= segments.take(query)
        if budget is not None:
            same &= (self.chain.take(photon, axis=1) <= budget.take(query, axis=1)).all(axis=0)
        query, photon = query[same], photon[same]
        if not len(query):
            return out
        albedo = bsdf.lambert_albedo(si)
        if albedo is not None:              # f = rho / pi for every direction: sum the flux per point first
            flux = self.flux.take(photon, axis=1)
            for c in range(3):
                out[c] = np.bincount(query, flux[c], minlength=m)
            return out * albedo * (1.0 / (np.pi * np.pi * radius * radius))
        at = si.take(query)
        wi = self.incoming.take(photon, axis=1)
        f_cos, _ = bsdf.eval(at, wi)
        cos = np.abs(dot(at.n, wi))
        f = np.where(cos > 1e-6, f_cos / np.maximum(cos, 1e-6), 0.0)
        contrib = f * self.flux.take(photon, axis=1)
        for c in range(3):
            out[c] = np.bincount(query, contrib[c], minlength=m)
        return out * (1.0 / (np.pi * radius * radius))
