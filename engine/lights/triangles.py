"""Triangle emitters (emissive mesh faces): area or spherical-triangle sampling.

* by area (eq. 2.11): barycentrics uniform over the triangle, p_w = d^2 / (A |cos theta_y|);
* by solid angle: Arvo, "Stratified Sampling of Spherical Triangles" (SIGGRAPH 1995),
  directions uniform over the spherical triangle, p_w = 1 / Omega, with Omega from
  Van Oosterom and Strackee (atan2 form, right for Omega > pi too).

As pbrt-v4's `Triangle::Sample(ctx)`, the spherical map is used only where it is stable:
Omega not vanishing and x not (almost) in the triangle's plane; elsewhere area sampling,
which is exact there.  `sample_li` and `pdf_li` share that predicate.
"""
from __future__ import annotations

import numpy as np

from ..sampling.warps import uniform_triangle
from ..core.vec import cross, dot, normalize, rows
from .emitting_surface import EmittingSurface
from .parallelograms import GRAZING, OMEGA_MIN, area_pdf
from .protocol import LightBounds


def _unit(a):
    with np.errstate(divide="ignore", invalid="ignore"):
        return normalize(a)


def angle_between(a, b):
    """Angle between unit rows, accurate near 0 and pi (pbrt's AngleBetween)."""
    d = dot(a, b)
    plus = np.sqrt(np.maximum(dot(a + b, a + b), 0.0))
    minus = np.sqrt(np.maximum(dot(a - b, a - b), 0.0))
    return np.where(d >= 0.0, 2.0 * np.arcsin(np.minimum(0.5 * minus, 1.0)),
                    np.pi - 2.0 * np.arcsin(np.minimum(0.5 * plus, 1.0)))


class Triangles(EmittingSurface):
    name = "triangle"

    def __init__(self, a, b, c, radiance=None, one_sided=None):
        """Corners a, b, c ((K, 3) each); radiance, one_sided: as EmittingSurface."""
        a, b, c = (np.asarray(v, dtype=np.float64).reshape(-1, 3) for v in (a, b, c))
        self.count = len(a)
        self._set_emission(radiance, one_sided)
        n = np.cross(b - a, c - a)
        doubled = np.linalg.norm(n, axis=1)
        self.area = 0.5 * doubled
        self.normal = rows(n / np.maximum(doubled, 1e-300)[:, None])
        self.a, self.b, self.c = rows(a), rows(b), rows(c)
        centroid = (a + b + c) / 3.0
        self.center = rows(centroid)
        self.radius = np.linalg.norm(np.stack([a, b, c], axis=1) - centroid[:, None], axis=2).max(axis=1)

    def _directions(self, x, idx):
        return (_unit(self.a.take(idx, axis=1) - x), _unit(self.b.take(idx, axis=1) - x),
                _unit(self.c.take(idx, axis=1) - x))

    def _omega(self, A, B, C):
        """Solid angle of the spherical triangle A, B, C (unit rows; Van Oosterom-Strackee)."""
        return 2.0 * np.arctan2(np.abs(dot(A, cross(B, C))), 1.0 + dot(A, B) + dot(B, C) + dot(C, A))

    def _use_solid_angle(self, x, idx, omega):
        centre = self.center.take(idx, axis=1) - x
        height = np.abs(dot(self.a.take(idx, axis=1) - x, self.normal.take(idx, axis=1)))
        ok = (omega >= OMEGA_MIN) & (height >= GRAZING * np.sqrt(dot(centre, centre)))
        return ok & np.isfinite(omega)

    def _spherical_direction(self, A, B, C, omega, u1, u2):
        """Arvo's map from (u1, u2) to a direction inside the spherical triangle."""
        with np.errstate(divide="ignore", invalid="ignore"):
            alpha = angle_between(_unit(cross(A, B)), _unit(cross(A, C)))   # angle at vertex A
            cos_a, sin_a = np.cos(alpha), np.sin(alpha)
            sub = u1 * omega - alpha                    # the sub-triangle's area minus alpha
            s, t = np.sin(sub), np.cos(sub)
            k1 = t - cos_a
            k2 = s + sin_a * dot(A, B)
            cb = np.clip(((k2 * t - k1 * s) * cos_a - k2) / ((k2 * s + k1 * t) * sin_a), -1.0, 1.0)
            c_prime = cb * A + np.sqrt(1.0 - cb * cb) * _unit(C - dot(C, A) * A)
            z = 1.0 - u2 * (1.0 - dot(c_prime, B))
            w = z * B + np.sqrt(np.maximum(1.0 - z * z, 0.0)) * _unit(c_prime - dot(c_prime, B) * B)
        return w

    def sample_li(self, x, idx, u1, u2, n=None, solid_angle: bool = True):
        a, point = self._area_point(idx, u1, u2)
        normal = self.normal.take(idx, axis=1)
        pdf = area_pdf(x, point, normal, self.area.take(idx))
        if solid_angle:
            A, B, C = self._directions(x, idx)
            omega = self._omega(A, B, C)
            use = self._use_solid_angle(x, idx, omega)
            if use.any():
                sel = np.flatnonzero(use)
                xs, ns = x.take(sel, axis=1), normal.take(sel, axis=1)
                w = self._spherical_direction(A.take(sel, axis=1), B.take(sel, axis=1), C.take(sel, axis=1),
                                              omega.take(sel), u1.take(sel), u2.take(sel))
                with np.errstate(divide="ignore", invalid="ignore"):
                    t = dot(a.take(sel, axis=1) - xs, ns) / dot(w, ns)    # onto the triangle's plane
                good = np.isfinite(t) & (t > 0.0) & np.isfinite(w).all(axis=0)
                p = np.where(good, xs + np.where(good, t, 0.0) * w, point.take(sel, axis=1))
                point[:, sel] = p
                pdf[sel] = np.where(good, 1.0 / omega.take(sel), 0.0)    # a failed map: no sample
        return self._li(x, idx, point, normal, pdf)

    def _area_point(self, idx, u1, u2):
        """(corner a of each light, a point uniform over its area)."""
        a = self.a.take(idx, axis=1)
        e1, e2 = self.b.take(idx, axis=1) - a, self.c.take(idx, axis=1) - a
        b1, b2 = uniform_triangle(u1, u2)
        return a, a + b1 * e1 + b2 * e2

    def pdf_li(self, x, idx, point, n=None, direction=None, solid_angle: bool = True):
        normal = self.normal.take(idx, axis=1)
        pdf = area_pdf(x, point, normal, self.area.take(idx))
        if solid_angle:
            omega = self._omega(*self._directions(x, idx))
            use = self._use_solid_angle(x, idx, omega)
            pdf = np.where(use, 1.0 / np.where(use, omega, 1.0), pdf)
        return pdf

    def solid_angle(self, x, idx):
        return self._omega(*self._directions(x, idx))

    def bounds(self):
        return LightBounds(self.center, self.radius, self.normal, np.where(self.one_sided, 1.0, -1.0))

    def sample_area(self, idx, u1, u2):
        return self._area_point(idx, u1, u2)[1], self.normal.take(idx, axis=1)

    def normal_at(self, idx, point):
        return self.normal.take(idx, axis=1)
