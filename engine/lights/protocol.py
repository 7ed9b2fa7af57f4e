"""The light protocol: what every kind of light offers the light set (engine/lights/light_set.py),
in the spirit of pbrt-v4's `Light` (SampleLi, PDF_Li, L / Le, Phi, Bounds, SampleLe) and
Mitsuba 3's `Emitter`.

A *kind* holds all the lights of one form in a scene (every parallelogram emitter, every point
light, the suns, the world), vectorised over a wavefront: `idx` (N,) numbers each ray's light
within the kind (0 .. count - 1), per-ray vectors are rows (3, N) (engine/core/vec.py), per-light
vectors rows (3, count).  The light set numbers the lights of a scene kind after kind, so each kind
owns the contiguous range `first` .. `first + count - 1` of light numbers, and it reaches a kind
through that range, never through a name (`name` is for messages only).

Densities are per unit solid angle at the receiver x.  `solid_angle=False` asks a kind that samples
by solid angle to sample by area instead (the report's estimator, eq. 2.11); kinds that have one
way only ignore it, as lights at infinity ignore `x` and lights at finite distance ignore the
receiver's normal `n`.  Delta lights (a point light without a radius, a sun without an angle) use
the convention of this tracer: their sample's pdf is a stand-in that makes radiance / pdf the right
irradiance (d^2 for a point: radiance I; 1 for a sun: radiance E), and no ray ever reaches them, so
no MIS weight asks for their pdf_li.

How to add a kind: see the `LightKind` docstring below.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Protocol, runtime_checkable

import numpy as np

from ..core.vec import dot


@dataclass
class LiSample:
    """Light that receivers x get from one light each (pbrt's LightLiSample)."""
    point: np.ndarray      # (3, N) on the light; at infinity: x + direction
    direction: np.ndarray  # (3, N) unit, from the receiver to the point
    distance: np.ndarray   # (N,) to the point; inf at infinity
    normal: np.ndarray     # (3, N) unit normal of the light at the point; at infinity: -direction
    radiance: np.ndarray   # (3, N) Le arriving along -direction (the side of one-sided lights is
                           #   not tested here: LightSample.one_sided lets the integrator do it)
    pdf: np.ndarray        # (N,) density of `direction` per unit solid angle at x; 0: no sample


@dataclass
class EmissionSample:
    """A ray leaving a light (pbrt's SampleLe), for a pass that traces light from the lamps:
    the ray carries the flux radiance |cos theta| / (pdf_pos pdf_dir), theta between the ray and
    `normal`."""
    origin: np.ndarray     # (3, N) on the light
    direction: np.ndarray  # (3, N) unit, leaving the light
    normal: np.ndarray     # (3, N) unit normal at the origin, on the side the ray leaves from
    radiance: np.ndarray   # (3, N) Le along the ray
    pdf_pos: np.ndarray    # (N,) density of the origin per unit area (1: a point, a delta in position)
    pdf_dir: np.ndarray    # (N,) density of the direction per unit solid angle


@dataclass
class LightBounds:
    """Where a kind's lights are and where they face (pbrt's LightBounds), for the light tree."""
    center: np.ndarray     # (3, K) centre of each light's bounding sphere
    radius: np.ndarray     # (K,) its radius
    axis: np.ndarray       # (3, K) unit axis of the cone that holds the light's normals
    cos_o: np.ndarray      # (K,) cosine of that cone's half-angle (-1: normals in every direction)


@runtime_checkable
class LightKind(Protocol):
    """Every kind of light implements these (engine/lights/parallelograms.py is a full example).

    To add a kind: write a class with these attributes and methods in a module of its own under
    engine/lights/ (an emitting surface derives from EmittingSurface in
    engine/lights/emitting_surface.py and writes only sample_li, pdf_li, sample_area, normal_at and
    bounds); let SceneEmitters (engine/lights/emitters.py) gather the scene's emitters of that kind
    and build it; add its name to the effect plan's description (engine/integrators/effects.py);
    and add an instance to EVERY_KIND in tests/lights/kinds.py: tests/lights/test_protocol.py then
    checks every method below against the others.
    """

    name: str              # for messages ("parallelogram", "point", ...); never dispatched on
    count: int             # lights of this kind
    first: int             # light number of light 0 in the light set (set by the light set)
    at_infinity: bool      # directions only: shadow rays to t = inf, no position, no bounds
    radiance: np.ndarray   # (3, K) the radiance (or a delta light's intensity / irradiance)
    one_sided: np.ndarray  # (K,) bool: emits only to the side its normal faces

    def sample_li(self, x, idx, u1, u2, n=None, solid_angle: bool = True) -> LiSample:
        """A direction from each receiver x (rows) towards light idx, drawn with the uniforms u1, u2
        (N,); n: the receivers' facing normals (rows)."""
        ...

    def pdf_li(self, x, idx, point, n=None, direction=None, solid_angle: bool = True) -> np.ndarray:
        """(N,) the density sample_li has for the direction from x to `point` on light idx (lights at
        infinity: for the unit `direction`), assuming that direction reaches the light (MIS asks only
        for lights its rays met)."""
        ...

    def le(self, idx, point, direction) -> np.ndarray:
        """(3, N) radiance that a ray travelling along the unit `direction` gets from light idx where
        it meets it at `point` (at infinity: where it leaves the scene; `point` unused): 0 behind a
        one-sided light, outside a spot's cone or a sun's disk."""
        ...

    def power(self) -> np.ndarray:
        """(K,) emitted flux Phi [W], averaged over the colour channels: the light tree's weight and
        the share of lamps against lights at infinity."""
        ...

    def report_power(self) -> np.ndarray:
        """(K,) the report's weight for picking a light by power (eq. 2.11's estimator): area x mean
        radiance, i.e. the flux of one face / pi; a light without an area (or at infinity): Phi / pi."""
        ...

    def bounds(self) -> Optional[LightBounds]:
        """Bounding sphere and normal cone of each light; None for lights at infinity."""
        ...

    def sample_emission(self, idx, u1, u2, u3, u4, targets=None) -> EmissionSample:
        """A ray leaving light idx, from four uniforms (N,) each; a kind that cannot emit rays yet
        raises NotImplementedError naming itself.  targets: an engine/lights/aim.py SphereTargets
        to aim the rays at (their density in pdf_dir, or in pdf_pos at infinity), or None."""
        ...


def finite_sample(x, point, normal, radiance, pdf) -> LiSample:
    """The LiSample of a light at a finite distance: direction and distance from x to `point`
    (unused samples, of pdf 0, may have any point, so divisions by 0 are quiet)."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        w = point - x
        distance = np.sqrt(dot(w, w))
        direction = w / distance
    return LiSample(point, direction, distance, normal, radiance, pdf)


def infinite_sample(x, direction, radiance, pdf) -> LiSample:
    """The LiSample of a light at infinity: the point one unit along `direction` (rows)."""
    return LiSample(x + direction, direction, np.full(direction.shape[1], np.inf), -direction, radiance, pdf)
