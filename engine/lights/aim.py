"""Aiming emitted rays at target spheres (Jensen's projection maps, with exact densities): the
bounding spheres of a scene's specular objects, so that most rays of a caustic photon pass
(engine/integrators/photons/) meet a mirror or glass first.

From a point x a ray picks one of the T targets uniformly, then a direction uniform in the cone
that target subtends from x (the whole sphere of directions when x is inside it).  Its density
per unit solid angle is the mixture over every target whose cone holds the direction:

    p(w) = (1 / T) sum_t [w in cone_t] / (2 pi (1 - cos beta_t))

so a ray that several cones hold is weighted by all of them.  Lights at infinity aim in position
instead: a ray of direction w starts on the disk of radius r_t about target t's centre that faces
w, with the mixture density per unit area p(y) = (1 / T) sum_t [ray within r_t of c_t] / (pi r_t^2).
Rays that no target's cone (or disk) holds are never drawn, and carry no light into a specular
object either: the targets must hold every specular surface.
"""
from __future__ import annotations

import numpy as np

from ..core.vec import dot
from ..sampling.warps import orthonormal_basis, uniform_cone, uniform_sphere, unit_circle


class SphereTargets:
    def __init__(self, centers, radii):
        """centers: (3, T) rows; radii: (T,), positive."""
        self.center = np.asarray(centers, dtype=np.float64).reshape(3, -1)
        self.radius = np.asarray(radii, dtype=np.float64).reshape(-1)
        self.count = len(self.radius)

    def _pick(self, u):
        """Target of each uniform u, and u rescaled to [0, 1) for reuse."""
        scaled = u * self.count
        t = np.minimum(scaled.astype(np.int64), self.count - 1)
        return t, np.clip(scaled - t, 0.0, 1.0 - 2.0 ** -53)

    def _cone(self, x, t):
        """(unit axis x -> centre t, 1 - cos beta, inside) of target t's cone from x (rows)."""
        axis = self.center.take(t, axis=1) - x
        d2 = dot(axis, axis)
        r2 = self.radius.take(t) ** 2
        inside = d2 <= r2
        d = np.sqrt(d2)
        with np.errstate(divide="ignore", invalid="ignore"):
            axis = axis / d
            sin2 = np.where(inside, 1.0, r2 / d2)
        one_minus = sin2 / (1.0 + np.sqrt(np.maximum(1.0 - sin2, 0.0)))   # 1 - cos beta, no cancellation
        return axis, one_minus, inside

    def directions(self, x, u1, u2):
        """(unit directions (3, N), their mixture density per unit solid angle) from the points x;
        u1 picks the target and, rescaled, the cone's polar angle."""
        t, u1 = self._pick(u1)
        axis, one_minus, inside = self._cone(x, t)
        w, _ = uniform_cone(u1, u2, np.where(inside[None, :], np.array([[0.0], [0.0], [1.0]]), axis), one_minus)
        if inside.any():
            w[:, inside] = uniform_sphere(u1[inside], u2[inside])
        return w, self.pdf(x, w)

    def solid_angle(self, x) -> float:
        """The sum of the targets' cones' solid angles from the point x (3,): the directions a ray
        aimed from x spreads over (4 pi for a target holding x; overlaps counted twice)."""
        axis, one_minus, inside = self._cone(np.repeat(np.reshape(x, (3, 1)), self.count, axis=1), np.arange(self.count))
        return float(np.sum(np.where(inside, 4.0 * np.pi, 2.0 * np.pi * one_minus)))

    def pdf(self, x, w):
        """(N,) mixture density of the unit directions w from the points x."""
        total = np.zeros(w.shape[1])
        for t in range(self.count):
            axis, one_minus, inside = self._cone(x, np.full(w.shape[1], t))
            held = inside | (dot(axis, w) >= 1.0 - one_minus)
            total += np.where(held, np.where(inside, 1.0 / (4.0 * np.pi), 1.0 / (2.0 * np.pi * one_minus)), 0.0)
        return total / self.count

    def disk_origins(self, w, u1, u2, distance):
        """(origins, mixture density per unit area across w) of rays along the unit rows w that
        start `distance` before the plane through the picked target's centre (u1 picks it)."""
        t, u1 = self._pick(u1)
        t1, t2 = orthonormal_basis(w)
        c, s = unit_circle(u2)
        rho = self.radius.take(t) * np.sqrt(u1)
        origin = self.center.take(t, axis=1) + rho * (c * t1 + s * t2) - distance * w
        return origin, self.disk_pdf(origin, w)

    def disk_pdf(self, origin, w):
        total = np.zeros(w.shape[1])
        for t in range(self.count):
            rel = self.center[:, t:t + 1] - origin
            along = dot(rel, w)
            miss2 = dot(rel, rel) - along * along
            r2 = self.radius[t] ** 2
            total += np.where(miss2 <= r2, 1.0 / (np.pi * r2), 0.0)
        return total / self.count
