"""The BSDF protocol: how a surface scatters light, vectorised over the hits of a wavefront.

In the spirit of pbrt-v4's BxDF (f / Sample_f / PDF / Flags) and Mitsuba 3's BSDF
(sample / eval / pdf), written for NumPy: every method takes the hits of one scatter group at
once, directions and colours as rows (3, N) (engine/core/vec.py).

* `sample(si, u_lobe, u)` draws an incident direction wi for the outgoing direction si.wo and
  returns a `BSDFSample`: wi, value = f cos / pdf (the throughput weight), pdf, and the flags of
  the lobe it took.
* `eval(si, wi)` returns (f cos, pdf) for given directions; `pdf(si, wi)` the pdf alone.  Delta
  lobes (perfect mirror and glass) contribute nothing to either: their f is a Dirac delta that
  no given direction meets, so eval returns 0 and pdf 0 for them.
* `lambert_albedo(si)`: the albedo rho of a BSDF whose f = rho / pi for every pair of directions,
  else None.  The direct-light stage then averages its N_s shadow rays before multiplying by
  f (eq. 2.11 with eq. 2.13a, as the report writes the estimator); other BSDFs are weighed per
  shadow ray through `eval`.

Directions point away from the surface (wo towards the viewer, wi towards the light), as in
pbrt and Mitsuba.  The cosine in f cos is the one with the shading normal si.n.

The integrator keeps two rules for every BSDF (engine/integrators/path_tracer.py): a sampled
direction must leave on the side of the geometric surface its flags say (REFLECTION: the
viewer's side, TRANSMISSION: the other), and light reaches non-delta lobes from the viewer's
side, and from the far side too for a BSDF whose flags have a non-delta lobe and TRANSMISSION
(`transmits_non_delta`: rough glass and refraction, translucent).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import IntFlag
from types import SimpleNamespace

import numpy as np


class BSDFFlags(IntFlag):
    """What a lobe does (pbrt-v4's BxDFFlags): the side it sends light to and its shape."""
    NONE = 0
    REFLECTION = 1          # wi on the viewer's side
    TRANSMISSION = 2        # wi through the surface
    DIFFUSE = 4             # f spread over the hemisphere (Lambert)
    GLOSSY = 8              # f peaked about a direction (microfacets: none yet)
    DELTA = 16              # f a Dirac delta: one direction (perfect mirror, smooth glass)
    STRAIGHT = 32           # with TRANSMISSION | DELTA: wi = -wo, the ray goes on as it was (alpha)


NON_DELTA = BSDFFlags.DIFFUSE | BSDFFlags.GLOSSY
# The lobe flags as plain ints, for arrays of flags (`flags & BSDFFlags.DELTA` converts the enum member on
# every call) and for the compiled kernels
REFLECTION_LOBE, TRANSMISSION_LOBE, DIFFUSE_LOBE, DELTA_LOBE, STRAIGHT_LOBE = (int(f) for f in (
    BSDFFlags.REFLECTION, BSDFFlags.TRANSMISSION, BSDFFlags.DIFFUSE, BSDFFlags.DELTA, BSDFFlags.STRAIGHT))


def has_non_delta(flags: BSDFFlags) -> bool:
    """Whether a BSDF with these lobes can be met by a given direction: it takes light samples
    and MIS, and its sample needs the 2D direction uniforms."""
    return bool(flags & NON_DELTA)


def sends_glossy_rays(flags: BSDFFlags) -> bool:
    """Whether a BSDF with these lobes sends non-delta glossy or transmission rays (the rays whose
    lamps the shadow rays already count: engine/integrators/path_tracer.py lamps_seen)."""
    return bool(flags & BSDFFlags.GLOSSY) or (bool(flags & BSDFFlags.TRANSMISSION) and has_non_delta(flags))


def transmits_non_delta(flags: BSDFFlags) -> bool:
    """Whether a BSDF's given directions may lie beyond the surface: light samples from both sides
    (a non-delta lobe and a transmission lobe; flags do not say whether they are the same lobe)."""
    return bool(flags & NON_DELTA) and bool(flags & BSDFFlags.TRANSMISSION)


@dataclass
class ShadingPoint:
    """Hits of one scatter group as a BSDF sees them (rows (3, N); Mitsuba's SurfaceInteraction).

    wo: unit directions towards the viewer (minus the ray directions).
    n: unit shading normals on the viewer's side of the geometric surface (flat: `ng` itself).
    ng: unit geometric normals on the viewer's side (dot(wo, ng) >= 0).
    normal: the geometric normals as the surface is oriented (outwards): which side is inside.
    color: the colour of each hit (textured or not): albedo, reflectance or tint.
    material: material ids (a BSDF takes its per-material parameters, such as the IOR, by them).
    smooth: n is an interpolated shading normal (else n is ng).
    media: the paths' nested-dielectric medium stacks (engine/materials/media.py), or None.
    lookup: texture lookups at these hits (engine/materials/textures.py HitLookup), or None when the
      scene has no textures: for BSDFs that read textures themselves (engine/materials/mix.py).
    alpha_floor: (N,) the least microfacet alpha of each hit (Filter Glossy,
    engine/integrators/light_paths.py), or None.
    glossy_off: (N,) hits whose glossy reflection lobes are left out (Reflective Caustics off after
    a diffuse bounce; a BSDF with diffuse and glossy lobes reads it), or None.

    A BSDF keeps what it derives from the hits alone (not from wi) through `memo`, once for its
    eval / pdf and sample at the same hits.  Views of one span (`si[span]`: the hits of a scatter
    group) share the memo, and a `take` of such a view (or of its takes) gathers the view's values;
    other ShadingPoints keep their own.  `dataclasses.replace` and setting a field start afresh.
    """
    wo: np.ndarray
    n: np.ndarray
    ng: np.ndarray
    normal: np.ndarray
    color: np.ndarray
    material: np.ndarray
    smooth: bool = False
    media: object = None
    lookup: object = None
    alpha_floor: np.ndarray | None = None
    glossy_off: np.ndarray | None = None
    _memo: dict = field(default_factory=dict, init=False, repr=False, compare=False)
    _spans: dict = field(default_factory=dict, init=False, repr=False, compare=False)  # span -> its views' memo
    _shared: bool = field(default=False, init=False, repr=False, compare=False)  # a span's view
    _source: tuple | None = field(default=None, init=False, repr=False, compare=False)  # (view, index) of a take

    def __setattr__(self, name, value):
        object.__setattr__(self, name, value)
        if name[0] != "_":
            self.__dict__.pop("_count", None)                 # a take's count: the rows tell from now on
        if name[0] != "_" and "_source" in self.__dict__:     # a field changed after __init__: other hits
            object.__setattr__(self, "_memo", {})
            object.__setattr__(self, "_spans", {})
            object.__setattr__(self, "_shared", False)
            object.__setattr__(self, "_source", None)

    def memo(self, key, compute):
        """compute(self) once per key for these hits: a value whose arrays all run over the hits
        on their last axis (tuples, lists, SimpleNamespaces and ShadingPoints of them too).  A take
        of a span's view computes it on the view and gathers (engine/integrators/path_tracer.py:
        the light samples' eval takes some hits of the span its sample then scatters)."""
        if key not in self._memo:
            if self._source is None:
                self._memo[key] = compute(self)
            else:
                source, index = self._source
                value = source.memo(key, compute)
                self._memo[key] = value if index is None else take_hits(value, index)
        return self._memo[key]

    def recolour(self, color: np.ndarray) -> "ShadingPoint":
        """These hits with another colour (a lobe's view of them): a memo of its own, which a take
        of it gathers from as from the view of a span when these hits are one."""
        view = replace(self, color=color)
        object.__setattr__(view, "_shared", self._shared)
        return view

    def __getitem__(self, span: slice) -> "ShadingPoint":
        """The hits in `span` (views: a medium stack updated through them updates the paths')."""
        media = None if self.media is None else self.media[span]
        view = ShadingPoint(self.wo[:, span], self.n[:, span], self.ng[:, span], self.normal[:, span],
                            self.color[:, span], self.material[span], self.smooth, media,
                            None if self.lookup is None else self.lookup[span],
                            *(None if a is None else a[span] for a in (self.alpha_floor, self.glossy_off)))
        object.__setattr__(view, "_memo", self._spans.setdefault((span.start, span.stop, span.step), {}))
        object.__setattr__(view, "_shared", True)
        return view

    def take(self, index: np.ndarray | None) -> "ShadingPoint":
        """The hits `index` (for evaluating directions only; None: every hit, in order).  The rows and
        the material ids are gathered when first read (a BSDF that reads its per-hit values through
        `memo_at` reads none of them; Lambert reads only n), so a row written in place in these hits'
        source after the take and before that read shows in the take (nothing in the tracer does
        that: a bounce's hits are written once, before their takes); the medium stacks, which a
        scattering updates in place, and the fields with defaults are copied at once.  A take of every
        hit (None) gathers nothing: its rows, lookups and memo values are the source's own arrays."""
        taken = object.__new__(ShadingPoint)
        state = taken.__dict__
        state.update(smooth=self.smooth, _memo={}, _spans={}, _shared=False, _source=None,
                     _lazy=(self, index), _count=len(self) if index is None else len(index))
        if self.media is None:
            state["media"] = None
        elif index is None:
            state["media"] = type(self.media)(self.media.media.copy(), self.media.depth.copy())
        else:
            state["media"] = type(self.media)(self.media.media.take(index, axis=0), self.media.depth.take(index))
        for name in ("lookup", "alpha_floor", "glossy_off"):      # fields with defaults: never lazy
            value = getattr(self, name)
            state[name] = value if value is None or index is None else value.take(index)
        if self._shared or self._source is not None:
            state["_source"] = (self, index)
        return taken

    def __getattr__(self, name):
        """A field of a take (`take`), gathered from the ShadingPoint it was taken from on first read."""
        lazy = self.__dict__.get("_lazy")
        if lazy is None or name not in _GATHERED:
            raise AttributeError(name)
        source, index = lazy
        value = getattr(source, name)
        if value is not None and index is not None:
            value = value.take(index, axis=1) if name in _ROWS else value.take(index)
        self.__dict__[name] = value
        return value

    def __len__(self) -> int:
        count = self.__dict__.get("_count")
        return self.wo.shape[1] if count is None else count

    def memo_at(self, key, compute):
        """(value, index): `memo`'s value for the hits these were taken from (the span's view: no
        gather) and the index of these hits in it, None where these hits are the ones it holds.
        For a compiled kernel that reads per-hit values by index."""
        if self._source is None:
            return self.memo(key, compute), None
        source, index = self._source
        if index is None:                                          # every hit of the source, in order
            return source.memo_at(key, compute)
        if len(index) and (index.min() < 0 or index.max() >= len(source)):
            raise IndexError(f"a take of {len(source)} hits at {index.min()}..{index.max()}")  # kernels read unchecked
        value, inner = source.memo_at(key, compute)
        return value, (index if inner is None else inner.take(index))


_ROWS = ("wo", "n", "ng", "normal", "color")                      # (3, N) rows
_GATHERED = _ROWS + ("material",)       # a take's fields read lazily (those without a class default)


def take_hits(value, index: np.ndarray):
    """A memo value (ShadingPoint.memo) at the hits `index`."""
    if isinstance(value, np.ndarray):
        return value.take(index, axis=-1)
    if isinstance(value, ShadingPoint):
        return value.take(index)
    if isinstance(value, (tuple, list)):
        return type(value)(take_hits(v, index) for v in value)
    if isinstance(value, SimpleNamespace):
        return SimpleNamespace(**{k: take_hits(v, index) for k, v in vars(value).items()})
    return value


@dataclass
class BSDFSample:
    """One sampled direction per hit (pbrt's BSDFSample).

    wi: (3, N) unit incident directions; value: (3, N) f cos / pdf, the factor the path
    throughput is multiplied by; pdf: (N,) the density of wi per unit solid angle for non-delta
    lobes, the probability of the lobe taken for delta lobes; flags: (N,) the BSDFFlags of the
    lobe each sample took."""
    wi: np.ndarray
    value: np.ndarray
    pdf: np.ndarray
    flags: np.ndarray


class BSDF:
    """A way of scattering, for every material of one kind (one row of the material table,
    engine/materials/table.py).  Subclasses set `flags` (the union of their lobes) and are made
    from the scene's materials and the render settings: `cls(materials, settings)`."""
    flags: BSDFFlags = BSDFFlags.NONE
    # True when pdf(si, wi) is max(<wi, si.n>, 0) * (1 / pi), in that order (the Lambertian's): the
    # compiled Lambertian direct light then computes it from the cosine it has (engine/integrators/
    # wavefront_jit.py lambert_light) instead of calling pdf.
    cosine_pdf: bool = False

    def __init__(self, materials, settings):
        pass

    def sample(self, si: ShadingPoint, u_lobe: np.ndarray, u) -> BSDFSample:
        """Sample wi for each hit.  u_lobe (N,): a uniform for choosing among lobes (Fresnel at
        glass); u: the pair (u1, u2) of (N,) uniforms for the direction, or None for BSDFs
        without a non-delta lobe (their directions need none)."""
        raise NotImplementedError

    def eval(self, si: ShadingPoint, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(f cos (3, N), pdf (N,)) for the directions wi (3, N); 0 for delta lobes."""
        raise NotImplementedError

    def pdf(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray:
        """The density (N,) with which `sample` draws wi, per unit solid angle; 0 for delta lobes."""
        raise NotImplementedError

    def lambert_albedo(self, si: ShadingPoint) -> np.ndarray | None:
        """rho (3, N) if f = rho / pi for every pair of directions, else None (see above)."""
        return None

    def diffuse_part(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray | None:
        """f cos (3, N) of the lobes Cycles counts as diffuse (CLOSURE_IS_BSDF_DIFFUSE), as weighted
        in eval, for a BSDF that has glossy lobes beside them: a Normal input shadows the two kinds
        differently (engine/nodes/normals.py bump_shadowing; engine/integrators/path_tracer.py).
        None for a BSDF whose lobes are all of one kind (the default)."""
        return None

    def use_backend(self, backends: dict) -> None:
        """Run the kernels that have compiled twins on the render's backends (engine/core/backend.py;
        backends: effect name -> "numba" | "numpy", the effect plan's); the BSDFs held as this
        one's attributes (its lobes) follow.  The default: NumPy, nothing to choose."""
        for part in vars(self).values():
            if isinstance(part, BSDF):
                part.use_backend(backends)


def delta_eval(si: ShadingPoint, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """eval of a BSDF with delta lobes only: no given direction meets them."""
    return np.zeros(wi.shape), np.zeros(wi.shape[1])
