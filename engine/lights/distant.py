"""Lights at infinity: Blender sun lights and the world (a constant background radiance).

Sun j: directions uniform in the cone of half-angle alpha_j = angle_j / 2 about -direction_j,
p_w = 1 / (2 pi (1 - cos alpha)), radiance E / (pi sin^2 alpha) so that a surface facing the
sun receives the irradiance E; a sun of angle 0 is a delta light (one direction, E cos theta).
The world: directions cosine-distributed about the receiver's normal, p_w = cos theta / pi, so
a diffuse receiver under an unoccluded sky gets a zero-variance estimate.

The light set picks among them by flux (power(): a sun's E through the scene's cross-section, the
world's radiance through a sphere around the scene), apart from the lamps and emissive surfaces
(engine/lights/light_set.py).  Shadow rays to them run to t = inf; a bounce ray that escapes
reaches the world (`reached_by_escaping_rays`; the integrator's misses stage weighs that by MIS);
suns are reached by shadow rays only.

Rays leaving them (sample_emission, as pbrt-v4's DistantLight::SampleLe): from a disk of the scene's
radius R (about the origin, engine/lights/emitters.py scene_radius) outside the scene, pdf_pos
1 / (pi R^2).  A sun's disk faces its axis and its rays leave in the sun's cone (a delta sun: along
the axis, 'density' 1 as in sample_li); the world's rays leave in directions uniform over the
sphere (pdf_dir 1 / 4 pi), each from a disk facing its direction.  The flux radiance |cos| /
(pdf_pos pdf_dir) is then E pi R^2 for a sun (the cosine to the disk's normal, the axis) and
L 4 pi pi R^2 for the world: the flux of power().
"""
from __future__ import annotations

import numpy as np

from ..sampling.warps import cosine_directions, orthonormal_basis, uniform_cone, uniform_sphere, unit_circle
from ..core.vec import dot, rows
from .protocol import EmissionSample, infinite_sample


class DistantKind:
    """What the lights at infinity share: selection by flux (`self.flux`, (K,)), no bounds for the
    light tree, rays emitted from a disk of the scene's radius (`self.scene_radius`)."""
    at_infinity = True
    first = 0
    compiled = None           # suns, the world: their light samples' kernel when the backend is numba

    def power(self):
        return self.flux

    def report_power(self):
        return self.flux / np.pi

    def bounds(self):
        return None

    def _disk_rays(self, facing, u3, u4, direction, radiance, pdf_dir, targets=None):
        """Rays along `direction` (rows) from points uniform (u3, u4) on the disk of radius R that
        faces the unit rows `facing`, a distance R behind the scene's sphere along them; with
        `targets` (engine/lights/aim.py) from the disk about a target that faces `direction`."""
        r = max(self.scene_radius, 1e-300)
        if targets is not None:
            far = 2.0 * r + np.sqrt(dot(targets.center, targets.center).max())
            origin, pdf_pos = targets.disk_origins(direction, u3, u4, far)
            return EmissionSample(origin, direction, direction, radiance, pdf_pos, pdf_dir)
        t1, t2 = orthonormal_basis(facing)
        c, s = unit_circle(u4)
        rho = r * np.sqrt(u3)
        origin = -2.0 * r * facing + rho * (c * t1 + s * t2)
        pdf_pos = np.full(len(u3), 1.0 / (np.pi * r * r))
        return EmissionSample(origin, direction, facing, radiance, pdf_pos, pdf_dir)


class SunLights(DistantKind):
    name = "sun"
    description = "sun lights"
    reached_by_escaping_rays = False

    def __init__(self, suns, scene_radius: float):
        """suns: engine/scene/model.py SunLight; scene_radius: of a sphere that holds the scene."""
        r2 = max(scene_radius, 1e-300) ** 2
        irradiance = np.array([s.irradiance for s in suns], dtype=np.float64).reshape(-1, 3)
        d = np.array([s.direction for s in suns], dtype=np.float64).reshape(-1, 3)
        self.count = len(suns)
        self.axis = rows(-d / np.linalg.norm(d, axis=1)[:, None])          # towards each sun
        half = np.array([0.5 * s.angle for s in suns], dtype=np.float64)
        self.one_minus_cos = 2.0 * np.sin(0.5 * half) ** 2             # 1 - cos(half), no cancellation
        self.cos_half = 1.0 - self.one_minus_cos
        self.delta = half < 1e-6
        sin2 = np.where(self.delta, 1.0, np.sin(half) ** 2)
        self.radiance = rows(np.where(self.delta[:, None], irradiance, irradiance / (np.pi * sin2)[:, None]))
        self.one_sided = np.zeros(self.count, dtype=bool)
        self.flux = np.pi * r2 * irradiance.mean(axis=1)
        self.scene_radius = scene_radius
        self.sky_disc = np.array([bool(getattr(s, "sky_disc", False)) for s in suns], dtype=bool)

    def sample_emission(self, idx, u1, u2, u3, u4, targets=None):
        """In the sun's cone (u1, u2), away from the sun, from the disk facing down its axis (u3, u4)."""
        towards = self.axis.take(idx, axis=1)
        cone, _ = uniform_cone(u1, u2, towards, self.one_minus_cos.take(idx))
        direction = -np.where(self.delta.take(idx), towards, cone)
        return self._disk_rays(-towards, u3, u4, direction, self.radiance.take(idx, axis=1),
                               self.pdf_li(None, idx, None), targets)

    def use_backend(self, backend: str) -> None:
        """The cone's directions compiled (engine/sampling/warps_jit.py, the same numbers) when
        backend is "numba" (set by engine/lights/light_set.py LightSet: the wavefront's backend)."""
        self.compiled = None
        if backend == "numba":
            from ..sampling import warps_jit
            self.compiled = warps_jit

    def sample_li(self, x, idx, u1, u2, n=None, solid_angle: bool = True):
        """Uniform in the sun's cone; a delta sun's 'density' is 1 (its radiance is the irradiance E)."""
        if self.compiled is not None:             # the line below in one loop, the same numbers
            direction = self.compiled.uniform_cone_at(u1, u2, idx, self.axis, self.one_minus_cos)
        else:
            direction, _ = uniform_cone(u1, u2, self.axis.take(idx, axis=1), self.one_minus_cos.take(idx))
        return infinite_sample(x, direction, self.radiance.take(idx, axis=1), self.pdf_li(x, idx, None))

    def pdf_li(self, x, idx, point, n=None, direction=None, solid_angle: bool = True):
        one_minus = self.one_minus_cos.take(idx)
        return np.where(self.delta.take(idx), 1.0, 1.0 / (2.0 * np.pi * np.maximum(one_minus, 1e-300)))

    def le(self, idx, point, direction):
        """E / (pi sin^2 alpha) for directions inside the sun's disk; 0 for a delta sun."""
        inside = ~self.delta.take(idx) & (dot(direction, self.axis.take(idx, axis=1)) >= self.cos_half.take(idx))
        return np.where(inside, self.radiance.take(idx, axis=1), 0.0)


class WorldLight(DistantKind):
    name = "world"
    description = "the world light"
    reached_by_escaping_rays = True
    count = 1

    def __init__(self, background, scene_radius: float):
        r2 = max(scene_radius, 1e-300) ** 2
        self.radiance = rows(np.asarray(background, dtype=np.float64)[None, :])
        self.one_sided = np.zeros(1, dtype=bool)
        self.flux = np.array([np.pi * float(np.mean(background)) * 4.0 * np.pi * r2])
        self.scene_radius = scene_radius

    def sample_emission(self, idx, u1, u2, u3, u4, targets=None):
        """Directions uniform over the sphere (u1, u2), each from the disk facing it (u3, u4)."""
        direction = uniform_sphere(u1, u2)
        return self._disk_rays(direction, u3, u4, direction, self.radiance.take(idx, axis=1),
                               np.full(len(u1), 1.0 / (4.0 * np.pi)), targets)

    def use_backend(self, backend: str) -> None:
        """The samples compiled when backend is "numba" (set by engine/lights/light_set.py LightSet: the
        wavefront's backend): the cosine-weighted directions and their cos / pi are those of
        Lambertian.sample, whose kernel (engine/materials/lambert_jit.py) gives NumPy's numbers."""
        self.compiled = None
        if backend == "numba":
            from ..materials import lambert_jit
            self.compiled = lambert_jit

    def sample_li(self, x, idx, u1, u2, n=None, solid_angle: bool = True):
        """Cosine-distributed about the receivers' facing normals n."""
        if self.compiled is not None:             # the lines below in one loop (pmf 1: the same numbers)
            direction, pdf = self.compiled.sample(u1, u2, n)
            return infinite_sample(x, direction, self.radiance.take(idx, axis=1), pdf)
        direction = cosine_directions(u1, u2, n)
        return infinite_sample(x, direction, self.radiance.take(idx, axis=1), self.pdf_li(x, idx, None, n, direction))

    def pdf_li(self, x, idx, point, n=None, direction=None, solid_angle: bool = True, pmf=1.0):
        """cos theta / pi about n.  pmf: a probability to multiply in before the 1 / pi (the order of
        LightSet.world_pdf, kept so that its MIS weights do not change in the last bit)."""
        return pmf * np.maximum(dot(direction, n), 0.0) * (1.0 / np.pi)

    def le(self, idx, point, direction):
        return self.radiance.take(idx, axis=1)
