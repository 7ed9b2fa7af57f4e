"""Scene model: camera, materials and primitives the tracer renders.

Everything here is plain NumPy data with no behaviour beyond validation, so the
Blender exporter, the scene file reader and the built-in scenes all build the
same objects.  Units are Blender's: metres, millimetres for lens and sensor.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..core.errors import SceneError
from ..core.vec import cross_rows, norm, triangle_rows_chunks
from .checks import LENS_RANGE, check_magnitude, check_resolution, check_vector, validate_quads

# Material kinds: how a surface scatters (emission is independent of kind).
DIFFUSE = "diffuse"
MIRROR = "mirror"
GLASS = "glass"
GLOSSY = "glossy"
PRINCIPLED = "principled"
MIX = "mix"                 # a weighted list of leaf materials (Cycles' closure list): Material.mix
# Dielectric kinds (engine/materials/dielectric.py, transparent.py, translucent.py): Blender's
# Refraction, Transparent and Translucent BSDF nodes.
REFRACTION = "refraction"
TRANSPARENT = "transparent"
TRANSLUCENT = "translucent"
MATERIAL_KINDS = (DIFFUSE, MIRROR, GLASS, GLOSSY, PRINCIPLED, MIX, REFRACTION, TRANSPARENT, TRANSLUCENT)
# The glossy kind's choices (engine/materials/microfacet.py, engine/materials/glossy.py).
DISTRIBUTIONS = ("ggx", "beckmann")
# The glass and refraction kinds' choices: "multi_ggx" is GGX with Cycles 4.x's energy compensation.
DIELECTRIC_DISTRIBUTIONS = ("ggx", "beckmann", "multi_ggx")
# `Material.roughness` when not given: the Glossy node's 0.5, but 0 (smooth) for glass and refraction,
# so scenes written before rough glass existed (no "roughness" for their glass) render as they did.
DEFAULT_ROUGHNESS = {GLASS: 0.0, REFRACTION: 0.0}
FRESNEL_KINDS = ("none", "dielectric", "conductor", "f82", "interpolated")
# Float inputs an image texture may drive per hit (Material.input_textures; engine/materials/textures.py
# per_hit): the Material or Principled field of that name is then the unlinked value.
TEXTURED_INPUTS = ("roughness", "diffuse_roughness", "metallic")
# Where an anisotropic material's tangent comes from (Material.tangent_source): "fixed" = Material.tangent;
# "radial" (Cycles' default: radial about the object's Z axis) and "uv" (a UV map's tangent) are the
# mesh's per-corner tangents (TriangleMesh.tangents), Material.tangent where a hit has none.
TANGENT_SOURCES = ("fixed", "radial", "uv")


@dataclass
class Principled:
    """The Principled BSDF's own inputs (engine/materials/principled.py); the rest are Material's:
    base colour = ``color``, ``roughness``, ``ior``, anisotropy / rotation / tangent, the diffuse
    roughness and ``multiscatter`` (the node's distribution)."""
    metallic: float = 0.0
    specular_ior_level: float = 0.5
    specular_tint: tuple = (1.0, 1.0, 1.0)
    # The layers over the base (engine/materials/principled.py): a GGX dielectric coat, the
    # microfiber sheen, alpha (1 - alpha passes straight through); transmission_weight: the share
    # of the dielectric base that is rough glass (engine/materials/principled_glass.py).
    coat_weight: float = 0.0
    coat_roughness: float = 0.03
    coat_ior: float = 1.5
    coat_tint: tuple = (1.0, 1.0, 1.0)
    sheen_weight: float = 0.0
    sheen_roughness: float = 0.5
    sheen_tint: tuple = (1.0, 1.0, 1.0)
    alpha: float = 1.0
    transmission_weight: float = 0.0

    def validate(self, owner: str) -> None:
        for label, value, high in (("metallic", self.metallic, 1.0), ("specular_ior_level", self.specular_ior_level, 1e6),
                                   ("coat_weight", self.coat_weight, 1e6), ("coat_roughness", self.coat_roughness, 1.0),
                                   ("sheen_weight", self.sheen_weight, 1e6), ("sheen_roughness", self.sheen_roughness, 1.0),
                                   ("alpha", self.alpha, 1.0), ("transmission_weight", self.transmission_weight, 1.0)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and 0.0 <= value <= high):
                raise SceneError(f"{owner}: Principled {label} must be from 0 to {high:g}, got {value!r}")
        if not (isinstance(self.coat_ior, (int, float)) and math.isfinite(self.coat_ior) and 1.0 <= self.coat_ior <= 1e6):
            raise SceneError(f"{owner}: Principled coat_ior must be from 1 to 1e6, got {self.coat_ior!r}")
        for label in ("specular_tint", "coat_tint", "sheen_tint"):
            value = getattr(self, label)
            arr = np.asarray(value, dtype=np.float64)
            if arr.shape != (3,) or not np.isfinite(arr).all() or (arr < 0).any():
                raise SceneError(f"{owner}: Principled {label} must be 3 finite non-negative numbers, got {value!r}")
            check_magnitude(owner, label, arr)

    @property
    def layered(self) -> bool:
        """Whether any layer over the base is on (coat, sheen or alpha below 1)."""
        return self.coat_weight > 0.0 or self.sheen_weight > 0.0 or self.alpha < 1.0


@dataclass
class PrincipledV1:
    """Blender 3.x's Principled BSDF inputs (engine/materials/principled_v1.py), its socket
    vocabulary; base colour, roughness, anisotropy / rotation / tangent, ior and `multiscatter`
    (the node's distribution) are Material's; transmission and transmission_roughness reach 3.4's glass
    closures (engine/materials/principled_v1_glass.py)."""
    metallic: float = 0.0
    specular: float = 0.5
    specular_tint: float = 0.0
    sheen: float = 0.0
    sheen_tint: float = 0.5
    clearcoat: float = 0.0
    clearcoat_roughness: float = 0.03
    transmission: float = 0.0
    transmission_roughness: float = 0.0
    alpha: float = 1.0

    def validate(self, owner: str) -> None:
        for label in ("metallic", "specular", "specular_tint", "sheen", "sheen_tint", "clearcoat",
                      "clearcoat_roughness", "transmission", "transmission_roughness", "alpha"):
            value = getattr(self, label)
            high = 1e6 if label in ("specular", "sheen", "clearcoat") else 1.0
            if not (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
                    and 0.0 <= value <= high):
                raise SceneError(f"{owner}: Principled (3.x) {label} must be from 0 to {high:g}, got {value!r}")


@dataclass
class Material:
    """A surface: Lambertian, perfect mirror, smooth glass or rough (microfacet) reflection,
    optionally emitting.

    ``color`` is the diffuse albedo (diffuse), the reflectance (mirror) or the tint of
    both reflection and transmission (glass, as Cycles' Glass BSDF); for glossy materials the
    colour the Fresnel term uses (engine/materials/glossy.py: a tint, F0 or ignored by conductors).
    Glossy only: ``roughness`` (alpha = roughness^2), ``anisotropy`` in [-1, 1] along ``tangent``
    (a world direction made orthogonal to the normal) turned by ``rotation`` x 2 pi,
    ``distribution`` (ggx, beckmann), ``fresnel`` (none, dielectric with ``ior``, conductor with
    ``conductor_ior`` + i ``conductor_k``, f82 with ``edge_tint``, interpolated with ``ior``) and
    ``multiscatter`` (GGX energy compensation, Cycles 4.x).  Glass and refraction: ``roughness`` (0:
    smooth, the default) and ``distribution`` (ggx, beckmann, multi_ggx) with ``ior``; the colour tints
    both lobes (transparent: the pass-through colour; translucent: the diffuse transmittance).  ``emission`` is
    radiance (colour x strength), emitted from both sides as Cycles mesh lights do.
    A pure emitter (Cycles' Emission shader) is a diffuse material with colour 0.
    """
    name: str
    kind: str = DIFFUSE
    color: tuple = (0.8, 0.8, 0.8)
    ior: float = 1.5
    emission: tuple = (0.0, 0.0, 0.0)
    # Image textures (engine/materials/textures.py TextureSlot): replace `color` / give the emission per hit
    # (`emission` is then the unlinked value; the light sampler uses the texture's mean).
    color_texture: object = None
    emission_texture: object = None
    # Glossy, glass and refraction (defaults: Blender's Glossy BSDF node).  roughness None: the
    # kind's default, DEFAULT_ROUGHNESS (set on construction).
    roughness: float | None = None
    anisotropy: float = 0.0
    rotation: float = 0.0
    tangent: tuple = (1.0, 0.0, 0.0)
    distribution: str = "ggx"
    fresnel: str = "none"
    multiscatter: bool = True
    edge_tint: tuple = (1.0, 1.0, 1.0)
    conductor_ior: tuple = (0.18, 0.42, 1.37)        # gold-like defaults, n and k per channel
    conductor_k: tuple = (3.42, 2.35, 1.77)
    # The Diffuse BSDF's Roughness (Oren-Nayar, engine/materials/oren_nayar.py; the model follows
    # Scene.cycles_version); 0 = Lambert, exactly.
    diffuse_roughness: float = 0.0
    # Principled only: its own inputs (None: the node's defaults); a PrincipledV1: Blender 3.x's node.
    principled: Principled | PrincipledV1 | None = None
    # Mix only: the leaves and their weights (engine/materials/mix.py).
    mix: "Mix | None" = None
    # Image textures on float inputs (TEXTURED_INPUTS name -> TextureSlot, its `channel` the float):
    # per hit, the field of that name is the unlinked value (hits without UVs keep it).
    input_textures: dict = field(default_factory=dict)
    # The anisotropic tangent's source (TANGENT_SOURCES) and, for "uv", the UV map ("": the active one).
    tangent_source: str = "fixed"
    tangent_uv_map: str = ""
    # Shader-node programs (engine/scene/programs.py) on inputs (COLOR_ROLES and TEXTURED_INPUTS there):
    # per hit, the program's value replaces the field (the field is the value where none runs).
    programs: dict = field(default_factory=dict)
    pass_index: int = 0           # Blender's Material > Settings > Pass Index (the IndexMA pass)
    # Mirror, glass and refraction of roughness 0 made by Blender 3.x's Sharp distribution (Cycles 3.4's
    # REFLECTION, REFRACTION and SHARP_GLASS closures, which its Filter Glossy leaves sharp:
    # docs/cycles34-filter-glossy.md); False: a microfacet closure of alpha 0, which it blurs
    # (engine/integrators/delta_blur.py).
    sharp_closure: bool = False

    def __post_init__(self):
        if self.roughness is None:
            self.roughness = DEFAULT_ROUGHNESS.get(self.kind, 0.5)

    @property
    def is_emissive(self) -> bool:
        return max(self.emission) > 0.0 or self.emission_texture is not None or "emission" in (self.programs or {})

    def has_input_texture(self, name: str) -> bool:
        """Whether an image texture drives the float input `name` (TEXTURED_INPUTS)."""
        return bool(self.input_textures) and self.input_textures.get(name) is not None

    def validate(self) -> None:
        if self.kind not in MATERIAL_KINDS:
            raise SceneError(f"Material '{self.name}': unknown kind '{self.kind}' "
                             f"(expected one of {', '.join(MATERIAL_KINDS)})")
        for label, value in (("color", self.color), ("emission", self.emission)):
            arr = np.asarray(value, dtype=np.float64)
            if arr.shape != (3,) or not np.isfinite(arr).all() or (arr < 0).any():
                raise SceneError(f"Material '{self.name}': {label} must be 3 finite "
                                 f"non-negative numbers, got {value!r}")
            check_magnitude(f"Material '{self.name}'", label, arr)
        if not (math.isfinite(self.ior) and 0 < self.ior <= 1e6):
            raise SceneError(f"Material '{self.name}': IOR must be positive (at most 1e6), got {self.ior!r}")
        if self.kind == GLOSSY:
            self.validate_glossy()
        if self.kind in (GLASS, REFRACTION):
            self.validate_dielectric()
        if self.kind == PRINCIPLED:
            self.validate_glossy()
            if self.principled is not None and not isinstance(self.principled, (Principled, PrincipledV1)):
                raise SceneError(f"Material '{self.name}': principled must be a Principled or a PrincipledV1, "
                                 f"got {self.principled!r}")
            (self.principled or Principled()).validate(f"Material '{self.name}'")
        value = self.diffuse_roughness
        if not (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
                and 0.0 <= value <= 1.0):
            raise SceneError(f"Material '{self.name}': diffuse roughness must be from 0 to 1, got {value!r}")
        self.validate_inputs()
        if self.programs:
            from .programs import validate_programs
            validate_programs(self, TEXTURED_INPUTS)
        if self.kind == MIX:
            if not isinstance(self.mix, Mix):
                raise SceneError(f"Material '{self.name}': kind mix needs a Mix (its leaves), got {self.mix!r}")
            self.mix.validate(f"Material '{self.name}'")
        elif self.mix is not None:
            raise SceneError(f"Material '{self.name}': only kind mix has leaves (kind is {self.kind})")

    def validate_inputs(self) -> None:
        """The textured inputs' names and the tangent source (the slots: engine/scene/textures.py)."""
        owner = f"Material '{self.name}'"
        if not isinstance(self.input_textures, dict):
            raise SceneError(f"{owner}: input_textures must map input names to texture slots, got {self.input_textures!r}")
        for name in self.input_textures:
            if name not in TEXTURED_INPUTS:
                raise SceneError(f"{owner}: unknown textured input '{name}' (expected one of {', '.join(TEXTURED_INPUTS)})")
        if self.tangent_source not in TANGENT_SOURCES:
            raise SceneError(f"{owner}: unknown tangent source '{self.tangent_source}' "
                             f"(expected one of {', '.join(TANGENT_SOURCES)})")

    def validate_dielectric(self) -> None:
        owner = f"Material '{self.name}'"
        value = self.roughness
        if not (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
                and 0.0 <= value <= 1.0):
            raise SceneError(f"{owner}: roughness must be from 0 to 1, got {value!r}")
        if self.distribution not in DIELECTRIC_DISTRIBUTIONS:
            raise SceneError(f"{owner}: unknown distribution '{self.distribution}' "
                             f"(expected one of {', '.join(DIELECTRIC_DISTRIBUTIONS)})")

    def validate_glossy(self) -> None:
        owner = f"Material '{self.name}'"
        for label, value, low, high in (("roughness", self.roughness, 0.0, 1.0),
                                        ("anisotropy", self.anisotropy, -1.0, 1.0)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and low <= value <= high):
                raise SceneError(f"{owner}: {label} must be from {low:g} to {high:g}, got {value!r}")
        if not (isinstance(self.rotation, (int, float)) and math.isfinite(self.rotation)):
            raise SceneError(f"{owner}: rotation must be a finite number, got {self.rotation!r}")
        if self.distribution not in DISTRIBUTIONS:
            raise SceneError(f"{owner}: unknown distribution '{self.distribution}' "
                             f"(expected one of {', '.join(DISTRIBUTIONS)})")
        if self.fresnel not in FRESNEL_KINDS:
            raise SceneError(f"{owner}: unknown fresnel '{self.fresnel}' (expected one of {', '.join(FRESNEL_KINDS)})")
        for label, value in (("tangent", self.tangent), ("edge_tint", self.edge_tint),
                             ("conductor_ior", self.conductor_ior), ("conductor_k", self.conductor_k)):
            arr = np.asarray(value, dtype=np.float64)
            if arr.shape != (3,) or not np.isfinite(arr).all() or (label != "tangent" and (arr < 0).any()):
                raise SceneError(f"{owner}: {label} must be 3 finite {'' if label == 'tangent' else 'non-negative '}"
                                 f"numbers, got {value!r}")
            check_magnitude(owner, label, arr)
        if not np.any(np.asarray(self.tangent, dtype=np.float64)):
            raise SceneError(f"{owner}: tangent must not be zero")


# A mix leaf's weight factors (engine/materials/mix.py evaluates them at each hit).
CONSTANT, FRESNEL, LAYER_WEIGHT, TEXTURE = "constant", "fresnel", "layer_weight", "texture"
PROGRAM = "program"         # a shader-node program (engine/scene/programs.py) at the hit
FACTOR_KINDS = (CONSTANT, FRESNEL, LAYER_WEIGHT, TEXTURE, PROGRAM)
LAYER_OUTPUTS = ("fresnel", "facing")


@dataclass
class MixFactor:
    """One factor of a leaf's weight, as a Mix Shader passes it: its Fac clamped to [0, 1] (or
    1 - that, `invert`: the Mix Shader's first input).  `kind`:
      constant:      `value` (any weight >= 0: an Add Shader's 1, or a folded product);
      fresnel:       Cycles' Fresnel node of `ior` at the hit (the view direction and shading normal);
      layer_weight:  Cycles' Layer Weight node of `blend`, its `output` "fresnel" or "facing";
      texture:       the image `texture` (a TextureSlot) at the hit's UV, its colour's luminance
                     (Cycles' colour-to-float); `value` where the hit has no UV or the image is missing.
    `node`: the Blender node's name, for messages."""
    kind: str = CONSTANT
    value: float = 1.0
    invert: bool = False
    ior: float = 1.45
    blend: float = 0.5
    output: str = "fresnel"
    texture: object = None
    node: str = ""
    program: object = None          # kind program: the Program (engine/scene/programs.py)

    @property
    def is_constant(self) -> bool:
        return self.kind == CONSTANT

    def constant(self) -> float:
        """The weight of a constant factor."""
        return 1.0 - self.value if self.invert else self.value

    def validate(self, owner: str) -> None:
        if self.kind not in FACTOR_KINDS:
            raise SceneError(f"{owner}: unknown mix factor kind '{self.kind}' (expected one of {', '.join(FACTOR_KINDS)})")
        high = 1e6 if self.kind == CONSTANT and not self.invert else 1.0
        for label, value, low, top in (("value", self.value, 0.0, high), ("ior", self.ior, 0.0, 1e6),
                                       ("blend", self.blend, 0.0, 1.0)):
            if not (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
                    and low <= value <= top):
                raise SceneError(f"{owner}: mix factor {label} must be from {low:g} to {top:g}, got {value!r}")
        if self.kind == LAYER_WEIGHT and self.output not in LAYER_OUTPUTS:
            raise SceneError(f"{owner}: Layer Weight output must be one of {', '.join(LAYER_OUTPUTS)}, "
                             f"got {self.output!r}")
        if self.kind == TEXTURE and self.texture is None:
            raise SceneError(f"{owner}: a texture mix factor needs its texture slot")
        if self.kind == PROGRAM:
            from .programs import Program
            if not isinstance(self.program, Program):
                raise SceneError(f"{owner}: a program mix factor needs its node program")
            self.program.validate(f"{owner}, mix factor '{self.node}'")


@dataclass
class MixLeaf:
    """One closure of a mix: an ordinary material of any scattering kind (not a mix, not emitting:
    a mix's emission is the mix material's own) and its weight, the product of `factors`."""
    material: Material
    factors: list = field(default_factory=list)

    def constant_weight(self) -> float | None:
        """The weight if every factor is constant, else None."""
        if not all(f.is_constant for f in self.factors):
            return None
        return float(np.prod([f.constant() for f in self.factors])) if self.factors else 1.0


@dataclass
class Mix:
    """A material as Cycles' closure list: the weighted leaves, nested Mix and Add Shaders
    flattened (weights multiplied).  Scattered by engine/materials/mix.py."""
    leaves: list = field(default_factory=list)

    def validate(self, owner: str) -> None:
        if not self.leaves:
            raise SceneError(f"{owner}: a mix needs at least one leaf")
        for i, leaf in enumerate(self.leaves):
            if not isinstance(leaf, MixLeaf) or not isinstance(leaf.material, Material):
                raise SceneError(f"{owner}: mix leaf #{i} must be a MixLeaf holding a Material, got {leaf!r}")
            m = leaf.material
            where = f"{owner}: mix leaf #{i} '{m.name}'"
            if m.kind == MIX:
                raise SceneError(f"{where} is a mix itself (flatten nested mixes: multiply the weights)")
            if m.is_emissive:
                raise SceneError(f"{where} emits: a mix's emission belongs to the mix material")
            try:
                m.validate()
            except SceneError as exc:
                raise SceneError(f"{owner}: mix leaf #{i}: {exc}") from None
            for factor in leaf.factors:
                if not isinstance(factor, MixFactor):
                    raise SceneError(f"{where}: factors must be MixFactors, got {factor!r}")
                factor.validate(where)


def with_mix_leaves(materials) -> tuple[list, list]:
    """(materials followed by every mix's leaves, the leaf material ids of each material: [] for
    non-mixes).  The one order both the material table and the textures number leaves by."""
    expanded, leaf_ids = list(materials), []
    for m in materials:
        ids = []
        if m.kind == MIX and m.mix is not None:
            for leaf in m.mix.leaves:
                ids.append(len(expanded))
                expanded.append(leaf.material)
        leaf_ids.append(ids)
    return expanded, leaf_ids


SENSOR_FITS = ("AUTO", "HORIZONTAL", "VERTICAL")


@dataclass
class Camera:
    """A Blender perspective camera.

    ``matrix`` is the 4x4 camera-to-world matrix (Blender's ``matrix_world``): the camera
    looks down its local -Z axis with +Y up.  Lens and sensor are in millimetres; shift is
    in units of the fitted sensor side, as in Blender.
    """
    matrix: np.ndarray
    lens: float = 50.0
    sensor_width: float = 36.0
    sensor_height: float = 24.0
    sensor_fit: str = "AUTO"
    shift_x: float = 0.0
    shift_y: float = 0.0
    name: str = "Camera"

    @staticmethod
    def look_at(position, target, up=(0.0, 0.0, 1.0), **kwargs) -> "Camera":
        with np.errstate(all="ignore"):        # position == target or up along the view: NaN, refused by validate()
            position = np.asarray(position, dtype=np.float64)
            back = position - np.asarray(target, dtype=np.float64)
            back /= np.linalg.norm(back)
            right = np.cross(np.asarray(up, dtype=np.float64), back)
            right /= np.linalg.norm(right)
            true_up = np.cross(back, right)
        matrix = np.eye(4)
        matrix[:3, 0], matrix[:3, 1], matrix[:3, 2], matrix[:3, 3] = right, true_up, back, position
        return Camera(matrix=matrix, **kwargs)

    def validate(self) -> None:
        m = np.asarray(self.matrix, dtype=np.float64)
        if m.shape != (4, 4) or not np.isfinite(m).all():
            raise SceneError(f"Camera '{self.name}': transform must be a finite 4x4 matrix")
        if abs(np.linalg.det(m[:3, :3])) < 1e-12:
            raise SceneError(f"Camera '{self.name}': transform is singular (zero scale)")
        for label, value in (("lens", self.lens), ("sensor width", self.sensor_width),
                             ("sensor height", self.sensor_height)):
            if not (math.isfinite(value) and value > 0):
                raise SceneError(f"Camera '{self.name}': {label} must be positive, got {value!r}")
            check_magnitude(f"Camera '{self.name}'", label, value)
        if not LENS_RANGE[0] <= self.lens <= LENS_RANGE[1]:
            raise SceneError(f"Camera '{self.name}': lens must be from {LENS_RANGE[0]:g} to "
                             f"{LENS_RANGE[1]:g} mm, got {self.lens!r}")
        if self.sensor_fit not in SENSOR_FITS:
            raise SceneError(f"Camera '{self.name}': unknown sensor fit '{self.sensor_fit}'")
        if not (math.isfinite(self.shift_x) and math.isfinite(self.shift_y)):
            raise SceneError(f"Camera '{self.name}': shift must be finite")
        check_magnitude(f"Camera '{self.name}'", "shift", (self.shift_x, self.shift_y))
        check_magnitude(f"Camera '{self.name}'", "location", m[:3, 3])


@dataclass
class TriangleMesh:
    """Indexed triangles in world space with one material index per triangle.

    Smooth shading (engine/geometry/shading_normals.py): `normals` holds one shading normal per corner,
    (T, 3, 3) in the order of each triangle's vertices (Blender's split normals, world space);
    `smooth` (T,) flags the triangles that use them (None: all).  Without `normals` every
    triangle is flat (its geometric normal)."""
    name: str
    vertices: np.ndarray          # (V, 3) float64
    triangles: np.ndarray         # (T, 3) int
    material_ids: np.ndarray      # (T,) int, indices into Scene.materials
    uvs: np.ndarray | None = None  # (T, 3, 2) corner UVs (one UV map), only where textures need them
    normals: np.ndarray | None = None     # (T, 3, 3) corner normals of smooth triangles
    smooth: np.ndarray | None = None      # (T,) bool: shaded smooth (None: every triangle)
    terminator_offset: float = 0.1        # Cycles' Shadow Terminator > Geometry Offset (0: off)
    # (T, 3, 3) corner tangents, world space, for anisotropic materials whose tangent_source is not
    # "fixed" (a UV map's MikkTSpace tangent or Cycles' radial default), interpolated at hits.
    tangents: np.ndarray | None = None
    # (T, 3) the UV map's corner bitangent signs (Blender's MeshLoop.bitangent_sign, times the sign of
    # the object matrix's determinant) with `tangents` of that map, for Normal Map nodes.
    tangent_signs: np.ndarray | None = None
    # The object of this instance, for shader nodes (engine/nodes/inputs.py): its object-to-world
    # matrix (4x4; None: the identity), texture space (centre, half size) in object space (None: the
    # bounding box) for Generated coordinates, Object Info's Random; colour attributes by name,
    # (T, 3, 3) linear corner colours, as the UVs.
    object_matrix: np.ndarray | None = None
    texspace: tuple | None = None
    object_random: float = 0.0
    colors: dict | None = None
    pass_index: int = 0                   # Blender's Object > Relations > Pass Index (the IndexOB pass)
    crypto_object: str = ""               # Cryptomatte names (engine/film/cryptomatte.py); "": `name`
    crypto_asset: str = ""

    def validate(self, n_materials: int, emissive: np.ndarray | None = None) -> int:
        """Check the mesh; drop degenerate triangles.  Returns how many were dropped.

        ``emissive`` flags emissive materials: an emitter whose triangles all have
        zero area is an error (it would emit nothing), not a silent drop.
        """
        owner = f"Object '{self.name}'"
        try:
            vertices = np.ascontiguousarray(self.vertices, dtype=np.float64)
            triangles = np.ascontiguousarray(self.triangles, dtype=np.int64)
            ids = np.asarray(self.material_ids, dtype=np.int64)
        except (TypeError, ValueError, OverflowError):
            raise SceneError(f"{owner}: vertices, triangles and material ids must be numbers") from None
        if vertices.size % 3 or triangles.size % 3:
            raise SceneError(f"{owner}: vertices and triangles must be rows of 3 values")
        self.vertices, self.triangles = vertices.reshape(-1, 3), triangles.reshape(-1, 3)
        if ids.ndim > 1 or (ids.ndim == 1 and len(ids) not in (1, len(self.triangles))):
            raise SceneError(f"{owner}: {ids.size} material ids for {len(self.triangles)} triangles "
                             "(need one per triangle)")
        self.material_ids = np.broadcast_to(ids, (len(self.triangles),)).copy()
        if not np.isfinite(self.vertices).all():
            bad = int((~np.isfinite(self.vertices).all(axis=1)).sum())
            raise SceneError(f"{owner}: {bad} vertices have NaN or infinite coordinates")
        check_magnitude(owner, "vertex coordinate", self.vertices)
        if len(self.triangles) and (self.triangles.min() < 0 or self.triangles.max() >= len(self.vertices)):
            raise SceneError(f"Object '{self.name}': triangle indices out of range")
        if len(self.material_ids) and (self.material_ids.min() < 0 or self.material_ids.max() >= n_materials):
            raise SceneError(f"Object '{self.name}': material index out of range")
        # |(v1 - v0) x (v2 - v0)| and the largest corner coordinate of each triangle (as rows: the
        # same values as np.linalg.norm(np.cross(...), axis=1) on vertices[triangles], faster),
        # piece by piece (engine/core/vec.py triangle_rows_chunks: no page faults per frame)
        keep = np.empty(len(self.triangles), dtype=bool)
        for start, (_, e1, e2, scale) in triangle_rows_chunks(self.vertices, self.triangles):
            doubled_area = norm(cross_rows(e1, e2))
            scale = scale + 1e-300
            # area ~ 0 relative to float64 resolution
            np.greater(doubled_area, (scale * 1e-12) ** 2 * 16, out=keep[start:start + len(scale)])
        dropped = int((~keep).sum())
        if emissive is not None and len(self.material_ids):
            lit = emissive[self.material_ids]
            if lit.any() and not (lit & keep).any():
                raise SceneError(f"Object '{self.name}': emitter has zero area")
        if self.uvs is not None:
            uvs = np.asarray(self.uvs, dtype=np.float64)
            if uvs.size != len(self.triangles) * 6 or not np.isfinite(uvs).all():
                raise SceneError(f"{owner}: UVs must be 3 finite (u, v) pairs per triangle "
                                 f"({len(self.triangles)} triangles, {uvs.size // 2} UV pairs)")
            self.uvs = uvs.reshape(-1, 3, 2)
        if self.normals is not None:
            self._check_normal_shapes(owner)
        if self.tangents is not None:
            tangents = np.asarray(self.tangents, dtype=np.float64)
            if tangents.size != len(self.triangles) * 9 or not np.isfinite(tangents).all():
                raise SceneError(f"{owner}: tangents must be 3 finite vectors per triangle "
                                 f"({len(self.triangles)} triangles, {tangents.size // 3} tangents)")
            self.tangents = tangents.reshape(-1, 3, 3)
        if self.tangent_signs is not None:
            signs = np.asarray(self.tangent_signs, dtype=np.float64)
            if signs.size != len(self.triangles) * 3 or not np.isfinite(signs).all():
                raise SceneError(f"{owner}: tangent_signs must be 3 finite numbers per triangle")
            self.tangent_signs = signs.reshape(-1, 3)
        if not (isinstance(self.terminator_offset, (int, float)) and 0.0 <= self.terminator_offset <= 1.0):
            raise SceneError(f"{owner}: shadow terminator geometry offset must be from 0 to 1, "
                             f"got {self.terminator_offset!r}")
        if dropped:
            self.triangles = self.triangles[keep]
            self.material_ids = self.material_ids[keep]
            if self.uvs is not None:
                self.uvs = self.uvs[keep]
            if self.tangents is not None:
                self.tangents = self.tangents[keep]
            if self.tangent_signs is not None:
                self.tangent_signs = self.tangent_signs[keep]
            if self.colors:
                self.colors = {k: np.asarray(c).reshape(-1, 3, 3)[keep] for k, c in self.colors.items()}
            if self.normals is not None:
                self.normals = self.normals[keep]
                self.smooth = None if self.smooth is None else self.smooth[keep]
        return dropped

    def _check_normal_shapes(self, owner: str) -> None:
        try:
            normals = np.asarray(self.normals, dtype=np.float64)
            smooth = None if self.smooth is None else np.asarray(self.smooth)
        except (TypeError, ValueError, OverflowError):
            raise SceneError(f"{owner}: normals must be numbers") from None
        t = len(self.triangles)
        if normals.size != t * 9:
            raise SceneError(f"{owner}: {normals.size // 3 if normals.size % 3 == 0 else normals.size} "
                             f"normals for {t} triangles (need 3 per triangle, one per corner)")
        if smooth is not None and (smooth.shape != (t,) or smooth.dtype.kind not in "bi"):
            raise SceneError(f"{owner}: smooth flags must be {t} booleans (one per triangle)")
        self.normals = normals.reshape(t, 3, 3)
        self.smooth = None if smooth is None else smooth.astype(bool)

    def validate_normals(self) -> str | None:
        """Normalise the corner normals; bad ones (NaN, infinite, zero length) become the
        triangle's geometric normal.  Returns a warning naming the object, or None.
        Call after validate() (shapes checked, degenerate triangles dropped)."""
        if self.normals is None:
            return None
        n = self.normals
        with np.errstate(invalid="ignore", over="ignore"):
            length = np.sqrt((n * n).sum(axis=2))
            bad = ~(np.isfinite(length) & (length > 1e-12))
            n = n / np.where(bad, 1.0, length)[..., None]
        if bad.any():
            v = self.vertices[self.triangles]
            g = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
            g /= np.maximum(np.linalg.norm(g, axis=1), 1e-300)[:, None]
            n = np.where(bad[..., None], g[:, None, :], n)
        self.normals = n
        if not bad.any():
            return None
        return (f"Object '{self.name}': {int(bad.sum())} of {bad.size} shading normals are zero, NaN or "
                "infinite; those corners use the face (geometric) normal")


@dataclass
class Sphere:
    """An implicit sphere (report eq. 2.2)."""
    name: str
    center: tuple
    radius: float
    material_id: int
    pass_index: int = 0           # the object's Pass Index (the IndexOB pass)
    crypto_object: str = ""       # Cryptomatte names (engine/film/cryptomatte.py); "": `name`
    crypto_asset: str = ""

    def validate(self, n_materials: int) -> None:
        c = np.asarray(self.center, dtype=np.float64)
        if c.shape != (3,) or not np.isfinite(c).all():
            raise SceneError(f"Object '{self.name}': sphere centre must be 3 finite numbers")
        if not (math.isfinite(self.radius) and self.radius > 0):
            raise SceneError(f"Object '{self.name}': sphere radius must be positive, got {self.radius!r}")
        check_magnitude(f"Object '{self.name}'", "sphere centre coordinate", c)
        check_magnitude(f"Object '{self.name}'", "sphere radius", self.radius)
        if not 0 <= self.material_id < n_materials:
            raise SceneError(f"Object '{self.name}': material index out of range")


@dataclass
class Quad:
    """A planar convex quadrilateral v00, v10, v11, v01 in counter-clockwise order (report 2.2.2)."""
    name: str
    corners: np.ndarray           # (4, 3): v00, v10, v11, v01
    material_id: int
    pass_index: int = 0           # the object's Pass Index (the IndexOB pass)
    crypto_object: str = ""       # Cryptomatte names (engine/film/cryptomatte.py); "": `name`
    crypto_asset: str = ""

    def validate(self, n_materials: int) -> None:
        q = np.asarray(self.corners, dtype=np.float64)
        if q.shape != (4, 3) or not np.isfinite(q).all():
            raise SceneError(f"Object '{self.name}': quad needs 4 finite corners")
        check_magnitude(f"Object '{self.name}'", "quad corner coordinate", q)
        self.corners = q
        e1, e3 = q[1] - q[0], q[3] - q[0]
        normal = np.cross(e1, e3)
        size = max(np.linalg.norm(e1), np.linalg.norm(e3), np.linalg.norm(q[2] - q[0]))
        if np.linalg.norm(normal) <= 1e-12 * size * size or size == 0:
            raise SceneError(f"Object '{self.name}': quad is degenerate (zero area)")
        normal /= np.linalg.norm(normal)
        if abs(np.dot(q[2] - q[0], normal)) > 1e-6 * size:
            raise SceneError(f"Object '{self.name}': quad is not planar")
        # Convex and counter-clockwise: every corner turns the same way about the normal.
        for i in range(4):
            a, b, c = q[i], q[(i + 1) % 4], q[(i + 2) % 4]
            if np.dot(np.cross(b - a, c - b), normal) <= 0:
                raise SceneError(f"Object '{self.name}': quad is not convex or its corners are not in order")
        if not 0 <= self.material_id < n_materials:
            raise SceneError(f"Object '{self.name}': material index out of range")


@dataclass
class AreaLight:
    """A light-only emitter, as a Blender Area light in Cycles: a planar convex polygon that
    emits `radiance` from its front side only (the side its normal faces; the normal follows
    the counter-clockwise order of `vertices`), or from both sides with `two_sided`.

    As in Cycles it casts no shadow (shadow rays pass through it).  Under the `mis` and
    `solid-angle` estimators rays of the kinds marked visible reach it (Cycles' ray
    visibility: camera, diffuse, glossy = mirror and glass reflection, transmission =
    glass refraction), add its emission and go on through it; under the report's
    estimator it is reached by shadow rays only (eq. 2.11).
    """
    name: str
    vertices: np.ndarray          # (N, 3), N >= 3, in order around the polygon
    radiance: tuple
    two_sided: bool = False
    visible_camera: bool = False
    visible_diffuse: bool = True
    visible_glossy: bool = True
    visible_transmission: bool = True
    lights_diffuse: bool = True   # lights diffuse surfaces at all (Cycles: Diffuse visibility off: no)

    def triangles(self) -> np.ndarray:
        v = np.asarray(self.vertices, dtype=np.float64)
        return np.stack([np.repeat(v[:1], len(v) - 2, axis=0), v[1:-1], v[2:]], axis=1)

    def validate(self) -> None:
        v = np.asarray(self.vertices, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) < 3 or not np.isfinite(v).all():
            raise SceneError(f"Light '{self.name}': needs at least 3 finite corners")
        le = np.asarray(self.radiance, dtype=np.float64)
        if le.shape != (3,) or not np.isfinite(le).all() or (le < 0).any():
            raise SceneError(f"Light '{self.name}': radiance must be 3 finite non-negative numbers")
        check_magnitude(f"Light '{self.name}'", "radiance", le)
        check_magnitude(f"Light '{self.name}'", "corner coordinate", v)
        fan = v[1:] - v[0]                     # the fan triangles' doubled area, without np.cross
        a, b = fan[:-1].T, fan[1:].T
        area = 0.5 * np.sqrt((a[1] * b[2] - a[2] * b[1]) ** 2 + (a[2] * b[0] - a[0] * b[2]) ** 2
                             + (a[0] * b[1] - a[1] * b[0]) ** 2).sum()
        if not area > 0:
            raise SceneError(f"Light '{self.name}': area light has zero area")


SPOT_FALLOFFS = ("smoothstep", "cosine-smoothstep")


@dataclass
class PointLight:
    """A Blender point or spot light as Cycles has it: intensity I = power x colour / (4 pi)
    [W/sr] from `position`; with a radius it is a disk of that radius facing each receiver, of
    radiance I / (pi r^2) (measured against Cycles 3.4 and 5.0: irradiance I / (d^2 + r^2) on its
    axis).  It casts no shadow; it lights diffuse surfaces through shadow rays and, with a radius,
    is seen in mirrors and through glass (engine/lights/seen.py).  The visibility flags are Cycles'
    ray visibility of the light object (camera rays never see it, as in Cycles).

    A spot light (`spot_size` > 0, the cone's full angle in radians as Blender's Spot Size, up to
    pi) emits I x a(theta) at the angle theta to `spot_direction`: a = 0 outside the cone, and
    inside, with c = cos theta, c0 = cos(spot_size / 2) and the blend width w = (1 - c0) x
    spot_blend (measured against Cycles, within 0.2 % over the cone):
      "smoothstep" (Cycles 4.0 and later):       a = smoothstep(0, 1, (c - c0) / w)
      "cosine-smoothstep" (Cycles 3.x):          a = c x smoothstep(0, 1, (c - c0) / w)
    (w = 0: a hard edge).  The spot's power is not concentrated into the cone: a spot of the same
    power is exactly as bright as the point light on its axis, as in Cycles."""
    name: str
    position: tuple
    intensity: tuple
    radius: float = 0.0
    spot_size: float = 0.0
    spot_blend: float = 0.0
    spot_direction: tuple = (0.0, 0.0, -1.0)
    spot_falloff: str = "smoothstep"
    lights_diffuse: bool = True         # Cycles' ray visibility: Diffuse off lights no diffuse surface
    visible_glossy: bool = True         # seen in mirrors (engine/lights/seen.py)
    visible_transmission: bool = True   # seen through glass

    @property
    def is_spot(self) -> bool:
        return self.spot_size > 0.0

    def validate(self) -> None:
        owner = f"Light '{self.name}'"
        check_vector(owner, "position", self.position)
        check_vector(owner, "intensity", self.intensity, non_negative=True)
        if not (math.isfinite(self.radius) and self.radius >= 0):
            raise SceneError(f"{owner}: radius must be 0 or more, got {self.radius!r}")
        check_magnitude(owner, "radius", self.radius)
        if not (math.isfinite(self.spot_size) and 0 <= self.spot_size <= math.pi):
            raise SceneError(f"{owner}: spot size must be in [0, pi] radians (0: a point light), "
                             f"got {self.spot_size!r}")
        if not (math.isfinite(self.spot_blend) and 0 <= self.spot_blend <= 1):
            raise SceneError(f"{owner}: spot blend must be in [0, 1], got {self.spot_blend!r}")
        if not np.linalg.norm(check_vector(owner, "spot direction", self.spot_direction)) > 0:
            raise SceneError(f"{owner}: spot direction must not be 0")
        if self.spot_falloff not in SPOT_FALLOFFS:
            raise SceneError(f"{owner}: spot falloff must be one of {', '.join(SPOT_FALLOFFS)}, "
                             f"got {self.spot_falloff!r}")


@dataclass
class SunLight:
    """A Blender sun light: light arriving from directions within `angle` (its angular
    diameter, radians) about -`direction` (the direction the light travels), with irradiance
    `irradiance` [W/m^2] on a surface facing it.  Lights diffuse surfaces through shadow rays; with
    an angle it is seen in mirrors and through glass (engine/lights/seen.py).  The visibility flags
    are Cycles' ray visibility of the light object, as for PointLight.  `sky_disc`: the sun disc of
    the world's Sky Texture (mcrt_addon/export/world.py), picked beside the baked sky as Cycles'
    sun-guided sky (engine/lights/light_set.py SKY_MAP_WEIGHT)."""
    name: str
    direction: tuple
    irradiance: tuple
    angle: float = 0.0
    lights_diffuse: bool = True
    visible_glossy: bool = True
    visible_transmission: bool = True
    sky_disc: bool = False

    def validate(self) -> None:
        direction = check_vector(f"Light '{self.name}'", "direction", self.direction)
        if not np.linalg.norm(direction) > 0:
            raise SceneError(f"Light '{self.name}': direction must not be 0")
        check_vector(f"Light '{self.name}'", "irradiance", self.irradiance, non_negative=True)
        if not (math.isfinite(self.angle) and 0 <= self.angle < math.pi):
            raise SceneError(f"Light '{self.name}': angle must be in [0, pi), got {self.angle!r}")


# The world's Environment Texture node (engine/lights/environment.py): how a direction becomes
# image coordinates (Cycles' direction_to_equirectangular / direction_to_mirrorball).
ENVIRONMENT_PROJECTIONS = ("equirectangular", "mirror_ball")
IDENTITY3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


@dataclass
class Environment:
    """An image world: Environment Texture -> Background -> World Output, lighting the scene from
    infinity (engine/lights/environment.py).  `texture`: index into Scene.textures; `strength`: the
    Background node's; `matrix`: world direction -> the texture's direction before it is normalised
    (a Mapping node's rotation and scale; identity without one).  Rays that leave the scene see the
    image x strength, except camera rays (Light Path "Is Camera Ray" between two Backgrounds):
    `camera_strength` (the image x that) or `camera_color` (a constant) when given.  `lighting`
    False: only camera rays see the image, every other ray sees Scene.background (a constant)."""
    texture: int
    strength: float = 1.0
    projection: str = "equirectangular"
    interpolation: str = "Linear"
    matrix: tuple = IDENTITY3
    camera_strength: float | None = None
    camera_color: tuple | None = None
    lighting: bool = True
    name: str = "World"

    def validate(self, n_textures: int) -> None:
        owner = f"World '{self.name}'"
        if not (isinstance(self.texture, (int, np.integer)) and not isinstance(self.texture, bool)
                and 0 <= self.texture < n_textures):
            raise SceneError(f"{owner}: environment texture index {self.texture!r} out of range")
        for label, value in (("strength", self.strength), ("camera strength", self.camera_strength)):
            if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise SceneError(f"{owner}: {label} must be a finite number >= 0, got {value!r}")
        if self.projection not in ENVIRONMENT_PROJECTIONS:
            raise SceneError(f"{owner}: projection must be one of {', '.join(ENVIRONMENT_PROJECTIONS)}, "
                             f"got {self.projection!r}")
        if self.interpolation not in ("Linear", "Closest"):
            raise SceneError(f"{owner}: interpolation must be Linear or Closest, got {self.interpolation!r}")
        m = np.asarray(self.matrix, dtype=np.float64)
        if m.shape != (3, 3) or not np.isfinite(m).all() or not abs(np.linalg.det(m)) > 1e-12:
            raise SceneError(f"{owner}: matrix must be an invertible 3x3 matrix")
        if self.camera_color is not None:
            check_vector(owner, "camera colour", self.camera_color, non_negative=True)


@dataclass
class Scene:
    camera: Camera | None
    materials: list = field(default_factory=list)
    meshes: list = field(default_factory=list)
    spheres: list = field(default_factory=list)
    quads: list = field(default_factory=list)
    background: tuple = (0.0, 0.0, 0.0)
    resolution: tuple = (256, 256)
    name: str = "scene"
    lights: list = field(default_factory=list)      # AreaLight: light-only emitters
    points: list = field(default_factory=list)      # PointLight
    suns: list = field(default_factory=list)        # SunLight
    textures: list = field(default_factory=list)    # engine/materials/textures.py ImageTexture
    # (major, minor) of the Blender whose Cycles the models follow (the running one at export).
    cycles_version: tuple = (5, 0)
    environment: Environment | None = None          # an image world; None: the constant background
    # The Mist pass (engine/film/passes.py): World > Mist Pass start, depth (metres) and falloff
    # exponent (Blender's Quadratic 2, Linear 1, Inverse Quadratic 0.5).
    mist: tuple = (5.0, 25.0, 2.0)

    def validate(self) -> list[str]:
        """Raise SceneError on invalid input; return warnings (e.g. dropped triangles)."""
        warnings: list[str] = []
        if self.camera is None:
            raise SceneError(f"Scene '{self.name}': no camera")
        self.camera.validate()
        w, h = check_resolution(self.name, self.resolution)
        if w <= 0 or h <= 0:
            raise SceneError(f"Scene '{self.name}': resolution must be positive, got {w}x{h}")
        if w * h > 16384 * 16384:
            raise SceneError(f"Scene '{self.name}': resolution {w}x{h} is too large "
                             f"(at most {16384 * 16384:,} pixels)")
        if not self.materials:
            raise SceneError(f"Scene '{self.name}': no materials")
        version = self.cycles_version
        if not (isinstance(version, (tuple, list)) and len(version) == 2
                and all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in version)):
            raise SceneError(f"Scene '{self.name}': cycles_version must be 2 non-negative integers "
                             f"(major, minor), got {version!r}")
        self.cycles_version = tuple(version)
        for material in self.materials:
            material.validate()
        bg = np.asarray(self.background, dtype=np.float64)
        if bg.shape != (3,) or not np.isfinite(bg).all() or (bg < 0).any():
            raise SceneError(f"Scene '{self.name}': background must be 3 finite non-negative numbers")
        check_magnitude(f"Scene '{self.name}'", "background", bg)
        if self.environment is not None:
            self.environment.validate(len(self.textures))
        n = len(self.materials)
        emissive = np.array([m.is_emissive for m in self.materials])
        for mesh in self.meshes:
            dropped = mesh.validate(n, emissive)
            if dropped:
                warnings.append(f"Object '{mesh.name}': {dropped} degenerate triangle(s) dropped")
            bad_normals = mesh.validate_normals()
            if bad_normals:
                warnings.append(bad_normals)
        for sphere in self.spheres:
            sphere.validate(n)
        validate_quads(self.quads, n)
        for light in [*self.lights, *self.points, *self.suns]:
            light.validate()
        from .textures import validate_textures
        warnings += validate_textures(self)
        if not self.has_light():
            warnings.append("the scene has no emitters and a black background: the image will be black")
        return warnings

    def has_light(self) -> bool:
        if (max(self.background) > 0 or self.environment is not None or any(max(light.radiance) > 0 for light in self.lights)
                or any(max(p.intensity) > 0 for p in self.points) or any(max(s.irradiance) > 0 for s in self.suns)):
            return True
        emissive = {i for i, m in enumerate(self.materials) if m.is_emissive}
        return (any(s.material_id in emissive for s in self.spheres)
                or any(q.material_id in emissive for q in self.quads)
                or any(len(m.material_ids) and np.isin(m.material_ids, list(emissive)).any()
                       for m in self.meshes))
