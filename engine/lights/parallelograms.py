"""Parallelogram emitters (Cornell-style quads, Blender rectangle and square Area lights).

A light is v0 + s e1 + t e2, s, t in [0, 1].  Two ways to draw a point y on it:

* by area (the report's eq. 2.11): y uniform over the parallelogram, pdf 1/A, i.e.
  p_w = d^2 / (A |cos theta_y|) per unit solid angle at the receiver x;
* by solid angle (rectangles only): the area-preserving map of Urena, Fajardo and King,
  "An Area-Preserving Parametrization for Spherical Rectangles" (EGSR 2013), as Cycles'
  `area_light_rect_sample`: directions uniform over the rectangle's solid angle Omega,
  p_w = 1 / Omega.  Omega comes from the edge-plane normals in the arcsin form (no
  cancellation against 2 pi; docs/light-sampling.md §2).  The arcsines and the cos and sin of
  the drawn angle are engine/lights/trig.py's (+ - * / sqrt only), which the compiled twin
  (engine/lights/parallelograms_jit.py) repeats bit for bit in vectorised loops.

`use` (of `_frame`) is the one predicate both `sample_li` and `pdf_li` consult, so the pdf of a
BSDF-sampled direction is the density the light set really has there.  Where the
spherical map loses precision (x almost in the light's plane, or a vanishing Omega) it
falls back to area sampling, which is exact there.  All vectors are rows (engine/core/vec.py);
`idx` picks each ray's light within this kind.
"""
from __future__ import annotations

import numpy as np

from ..core.vec import cross, dot, gather, rows
from .emitting_surface import EmittingSurface
from .protocol import LightBounds, LiSample
from .trig import asin, sincos

OMEGA_MIN = 1e-6          # sr: below this area sampling is as good and cheaper
GRAZING = 1e-5            # |plane distance| / distance to the centre below which x is "in the plane"
RECTANGLE_TOLERANCE = 1e-9


class Parallelograms(EmittingSurface):
    name = "parallelogram"
    compiled = None               # engine/lights/parallelograms_jit.py when the backend is numba

    def use_backend(self, backend: str) -> None:
        """The spherical-rectangle arithmetic compiled (the same numbers) when backend is "numba"."""
        if backend == "numba":
            from . import parallelograms_jit
            self.compiled = parallelograms_jit
        else:
            self.compiled = None

    def __init__(self, v0, e1, e2, radiance=None, one_sided=None):
        """Corners v0 and edges e1, e2 ((K, 3) each); radiance, one_sided: as EmittingSurface."""
        v0, e1, e2 = (np.asarray(a, dtype=np.float64).reshape(-1, 3) for a in (v0, e1, e2))
        self.count = len(v0)
        self._set_emission(radiance, one_sided)
        n = np.cross(e1, e2)
        self.area = np.linalg.norm(n, axis=1)
        len1, len2 = np.linalg.norm(e1, axis=1), np.linalg.norm(e2, axis=1)
        scale = np.maximum(len1 * len2, 1e-300)
        self.rectangle = np.abs(np.einsum("ij,ij->i", e1, e2)) <= RECTANGLE_TOLERANCE * scale
        self.v0, self.e1, self.e2 = rows(v0), rows(e1), rows(e2)
        self.normal = rows(n / np.maximum(self.area, 1e-300)[:, None])
        self.len1, self.len2 = len1, len2
        self.axis1 = rows(e1 / np.maximum(len1, 1e-300)[:, None])
        self.axis2 = rows(e2 / np.maximum(len2, 1e-300)[:, None])
        self.axis3 = cross(self.axis1, self.axis2)
        self.center = rows(v0 + 0.5 * (e1 + e2))
        corners = np.stack([v0, v0 + e1, v0 + e2, v0 + e1 + e2], axis=1)
        self.radius = np.linalg.norm(corners - (v0 + 0.5 * (e1 + e2))[:, None], axis=2).max(axis=1)

    # -- the spherical rectangle ---------------------------------------------------------
    def _frame(self, x, idx):
        """Local coordinates of each light seen from x (Urena et al., section 3), its solid
        angle and `use`: the predicate that sample_li() and pdf_li() share."""
        ax, ay = gather(self.axis1, idx), gather(self.axis2, idx)
        az = gather(self.axis3, idx)
        rel = gather(self.v0, idx) - x
        z0 = dot(rel, az)
        flip = np.where(z0 > 0.0, -1.0, 1.0)          # z points away from the light: z0 <= 0
        az, z0 = az * flip, z0 * flip
        x0, y0 = dot(rel, ax), dot(rel, ay)
        x1, y1 = x0 + gather(self.len1, idx), y0 + gather(self.len2, idx)
        z2 = z0 * z0
        with np.errstate(divide="ignore", invalid="ignore"):
            e0 = -y0 / np.sqrt(y0 * y0 + z2)          # z components of the edge-plane normals
            e1 = x1 / np.sqrt(x1 * x1 + z2)
            e2 = y1 / np.sqrt(y1 * y1 + z2)
            e3 = -x0 / np.sqrt(x0 * x0 + z2)
            g = [asin(np.clip(-a * b, -1.0, 1.0)) for a, b in ((e0, e1), (e1, e2), (e2, e3), (e3, e0))]
        omega = -(g[0] + g[1] + g[2] + g[3])         # spherical excess, arcsin form
        centre = gather(self.center, idx) - x
        use = (gather(self.rectangle, idx) & (omega >= OMEGA_MIN) & np.isfinite(omega)
               & (-z0 >= GRAZING * np.sqrt(dot(centre, centre))))
        return dict(ax=ax, ay=ay, az=az, x0=x0, y0=y0, x1=x1, y1=y1, z0=z0, e0=e0, e2=e2,
                    g23=g[2] + g[3], omega=omega, use=use)

    def _spherical_point(self, x, f, u1, u2):
        """The point of the rectangle in the direction that (u1, u2) maps to (Cycles' form)."""
        e0, z0 = f["e0"], f["z0"]
        with np.errstate(divide="ignore", invalid="ignore"):
            sin, cos = sincos(u1 * f["omega"] + f["g23"])
            fu = (cos * e0 + f["e2"]) / sin
            cu = np.clip(np.copysign(1.0, fu) / np.sqrt(fu * fu + e0 * e0), -1.0, 1.0)
            xu = np.clip(-(cu * z0) / np.maximum(np.sqrt(1.0 - cu * cu), 1e-300), f["x0"], f["x1"])
            d2 = xu * xu + z0 * z0
            y0, y1 = f["y0"], f["y1"]
            h0 = y0 / np.sqrt(d2 + y0 * y0)
            h1 = y1 / np.sqrt(d2 + y1 * y1)
            hv = h0 + u2 * (h1 - h0)
            yv = np.where(hv * hv < 1.0 - 1e-12, hv * np.sqrt(d2) / np.sqrt(1.0 - hv * hv), y1)
        yv = np.clip(np.nan_to_num(yv), y0, y1)
        return x + xu * f["ax"] + yv * f["ay"] + z0 * f["az"]

    # -- the light protocol (engine/lights/protocol.py) ----------------------------------
    def sample_li(self, x, idx, u1, u2, n=None, solid_angle: bool = True):
        """A point y on light idx and p_w of the direction x -> y, for receivers x (rows)."""
        m = x.shape[1]
        normal = np.broadcast_to(gather(self.normal, idx), (3, m))
        if not solid_angle:
            return self._li(x, idx, *self._area_sample(x, idx, u1, u2, normal))
        if self.compiled is not None:                          # all of the below in one compiled call
            point, direction, distance, pdf, radiance = self.compiled.sample_li(self, x, idx, u1, u2, OMEGA_MIN, GRAZING)
            return LiSample(point, direction, distance, normal, radiance, pdf)
        f = self._frame(x, idx)
        point = self._spherical_point(x, f, u1, u2)
        with np.errstate(divide="ignore"):
            pdf = 1.0 / f["omega"]
        if not f["use"].all():                                 # area sampling where unstable
            sel = np.flatnonzero(~f["use"])
            p, _, pd = self._area_sample(x.take(sel, axis=1), gather(idx, sel), u1.take(sel), u2.take(sel),
                                         normal.take(sel, axis=1))
            point[:, sel], pdf[sel] = p, pd
        return self._li(x, idx, point, normal, pdf)

    def _area_sample(self, x, idx, u1, u2, normal):
        point = self._area_point(idx, u1, u2)
        return point, normal, area_pdf(x, point, normal, gather(self.area, idx))

    def _area_point(self, idx, u1, u2):
        return gather(self.v0, idx) + u1 * gather(self.e1, idx) + u2 * gather(self.e2, idx)

    def pdf_li(self, x, idx, point, n=None, direction=None, solid_angle: bool = True):
        """p_w at x of the direction towards `point` on light idx (the density `sample_li` has)."""
        if solid_angle and self.compiled is not None:          # the same numbers, compiled
            return self.compiled.pdf_li(self, x, idx, point, OMEGA_MIN, GRAZING)
        pdf = area_pdf(x, point, gather(self.normal, idx), gather(self.area, idx))
        if solid_angle:
            f = self._frame(x, idx)
            pdf = np.where(f["use"], 1.0 / np.where(f["use"], f["omega"], 1.0), pdf)
        return pdf

    def solid_angle(self, x, idx):
        """Omega of each light seen from x (for tests)."""
        if self.compiled is not None:
            return self.compiled.solid_angle(self, x, idx)
        return self._frame(x, idx)["omega"]

    def bounds(self):
        return LightBounds(self.center, self.radius, self.normal, np.where(self.one_sided, 1.0, -1.0))

    def sample_area(self, idx, u1, u2):
        return self._area_point(idx, u1, u2), np.broadcast_to(gather(self.normal, idx), (3, len(u1)))

    def normal_at(self, idx, point):
        return gather(self.normal, idx)


def area_pdf(x, point, normal, area):
    """p_w = d^2 / (A |cos theta_y|): uniform area sampling seen from x (0 where undefined)."""
    w = point - x
    d2 = dot(w, w)
    cos_y = np.abs(dot(normal, w))                         # |cos theta_y| * d
    with np.errstate(divide="ignore", invalid="ignore"):
        pdf = d2 * np.sqrt(d2) / (area * cos_y)
    return np.where(np.isfinite(pdf), pdf, 0.0)
