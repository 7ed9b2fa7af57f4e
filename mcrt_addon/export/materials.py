"""Material export: Cycles node trees -> tracer Materials (diffuse, mirror, glass, emission).

Supported: Diffuse BSDF, Glossy BSDF (roughness 0 -> mirror), Glass BSDF, Emission, Principled BSDF
(Base Color, Metallic, Roughness, Transmission (Weight), IOR, Emission (Color) x Emission Strength;
socket names of 3.x and 4.x/5.0).  Anything else becomes diffuse with a warning naming the material
and the node.  Node trees are read from ``material.original`` (evaluated copies can lack them).
"""
from .images import image_node
from .util import linked_from, socket, uses_nodes

DEFAULT_GREY = (0.8, 0.8, 0.8)   # Cycles' surface for objects without material


def _value(node, *names, default=None):
    sock = socket(node, *names)
    if sock is None:
        return default
    return sock.default_value


def _rgb(value):
    return tuple(float(c) for c in tuple(value)[:3])


def _clamp01(rgb):
    return tuple(min(max(c, 0.0), 1.0) for c in rgb)


class MaterialTable:
    """Collects the tracer materials; one entry per Blender material (shared by all users)."""

    def __init__(self, Material, kinds, warnings, images=None):
        self.Material = Material
        self.images = images            # images.ImageTable: Image Texture nodes (None: not read)
        self._slots = {}                # the material being converted: role -> TextureSlot
        self.DIFFUSE, self.MIRROR, self.GLASS = kinds
        self.materials = []
        self.warnings = warnings
        self._index = {}

    def add(self, material):
        self.materials.append(material)
        return len(self.materials) - 1

    def default_index(self):
        if None not in self._index:
            self._index[None] = self.add(self.Material(name="(default surface)", kind=self.DIFFUSE,
                                                       color=DEFAULT_GREY))
        return self._index[None]

    def index(self, bl_material):
        """Tracer material index for a Blender material (None -> Cycles' default grey)."""
        if bl_material is None:
            return self.default_index()
        original = bl_material.original if bl_material.original is not None else bl_material
        key = original.name_full
        if key not in self._index:
            self._slots = {}
            material = self.convert(original)
            material.color_texture = self._slots.get("color")
            material.emission_texture = self._slots.get("emission")
            self._index[key] = self.add(material)
        return self._index[key]

    def slot_indices(self, ob):
        """Tracer material index for every material slot of ``ob`` (at least one entry)."""
        slots = [self.index(slot.material) for slot in ob.material_slots]
        return slots or [self.default_index()]

    def uv_map(self, slot_ids):
        """The UV map a mesh with these material slots needs: '' for the active render one, the
        name a UV Map node gives, or None when no material of the mesh has a texture."""
        names = [slot.uv_map for i in slot_ids for slot in (self.materials[i].color_texture,
                                                            self.materials[i].emission_texture)
                 if slot is not None]
        if not names:
            return None
        if len(set(names)) > 1:
            self.warnings.append(f"Materials of one mesh read UV maps {sorted(set(names))}: only "
                                 f"'{names[0] or 'the active render map'}' is used")
        return names[0]

    # --- conversion -----------------------------------------------------------------------------
    def warn(self, mat, node, text):
        where = f"Material '{mat.name}'" + (f", node '{node.name}'" if node is not None else "")
        self.warnings.append(f"{where}: {text}")

    def convert(self, mat):
        M = self.Material
        tree = mat.node_tree if uses_nodes(mat) else None
        if tree is None:
            return M(name=mat.name, kind=self.DIFFUSE, color=_clamp01(_rgb(mat.diffuse_color)))
        output = tree.get_output_node("CYCLES")
        if output is None:
            self.warn(mat, None, "no active Material Output node; rendered black like Cycles")
            return M(name=mat.name, kind=self.DIFFUSE, color=(0.0, 0.0, 0.0))
        node = linked_from(output.inputs.get("Surface"))
        if node is None:
            # Cycles renders an unconnected surface as black (no closure).
            return M(name=mat.name, kind=self.DIFFUSE, color=(0.0, 0.0, 0.0))
        handler = {
            "ShaderNodeBsdfDiffuse": self._diffuse,
            "ShaderNodeBsdfGlossy": self._glossy,
            "ShaderNodeBsdfAnisotropic": self._glossy,
            "ShaderNodeBsdfGlass": self._glass,
            "ShaderNodeEmission": self._emission,
            "ShaderNodeBsdfPrincipled": self._principled,
        }.get(node.bl_idname)
        if handler is None:
            self.warn(mat, node, f"{node.bl_idname} is not supported; rendered as diffuse grey")
            return M(name=mat.name, kind=self.DIFFUSE, color=DEFAULT_GREY)
        return handler(mat, node)

    def _color(self, mat, node, *names, default=(0.8, 0.8, 0.8), role="color"):
        sock = socket(node, *names)
        if sock is None:
            return default
        image = image_node(sock) if self.images is not None and sock.is_linked else None
        if image is not None:
            slot = self.images.slot(mat, image)
            if slot is not None:
                self._slots[role] = slot
        elif sock.is_linked:
            self.warn(mat, node, f"input '{sock.name}' is linked (textures are not supported); "
                                 f"its unlinked value is used")
        return _rgb(sock.default_value)

    def _emission_strength(self, strength):
        """A textured emission colour: radiance = texture x strength (none at strength 0)."""
        slot = self._slots.get("emission")
        if slot is not None:
            if strength > 0:
                slot.scale = (float(strength),) * 3
            else:
                del self._slots["emission"]

    def _float(self, mat, node, *names, default=0.0):
        sock = socket(node, *names)
        if sock is None:
            return default
        if sock.is_linked:
            self.warn(mat, node, f"input '{sock.name}' is linked; its unlinked value is used")
        return float(sock.default_value)

    def _diffuse(self, mat, node):
        color = _clamp01(self._color(mat, node, "Color"))
        if self._float(mat, node, "Roughness") > 0:
            self.warn(mat, node, "Oren-Nayar roughness is ignored (Lambertian)")
        return self.Material(name=mat.name, kind=self.DIFFUSE, color=color)

    def _glossy(self, mat, node):
        color = _clamp01(self._color(mat, node, "Color"))
        roughness = self._float(mat, node, "Roughness")
        if roughness > 0:
            self.warn(mat, node, f"roughness {roughness:g} is treated as 0 (perfect mirror)")
        return self.Material(name=mat.name, kind=self.MIRROR, color=color)

    def _glass(self, mat, node):
        color = _clamp01(self._color(mat, node, "Color"))
        roughness = self._float(mat, node, "Roughness")
        if roughness > 0:
            self.warn(mat, node, f"roughness {roughness:g} is treated as 0 (smooth glass)")
        ior = self._float(mat, node, "IOR", default=1.45)
        return self.Material(name=mat.name, kind=self.GLASS, color=color, ior=max(ior, 1e-3))

    def _emission(self, mat, node):
        color = self._color(mat, node, "Color", default=(1.0, 1.0, 1.0), role="emission")
        strength = self._float(mat, node, "Strength", default=1.0)
        self._emission_strength(strength)
        radiance = tuple(max(c * strength, 0.0) for c in color)
        return self.Material(name=mat.name, kind=self.DIFFUSE, color=(0.0, 0.0, 0.0), emission=radiance)

    def _principled(self, mat, node):
        base = _clamp01(self._color(mat, node, "Base Color"))
        metallic = self._float(mat, node, "Metallic")
        roughness = self._float(mat, node, "Roughness", default=0.5)
        transmission = self._float(mat, node, "Transmission Weight", "Transmission")
        ior = self._float(mat, node, "IOR", default=1.45)
        # 3.x: 'Emission' colour (default black) x 'Emission Strength' (default 1);
        # 4.x/5.0: 'Emission Color' (default white) x 'Emission Strength' (default 0).
        e_color = self._color(mat, node, "Emission Color", "Emission", default=(0.0, 0.0, 0.0), role="emission")
        e_strength = self._float(mat, node, "Emission Strength", default=1.0)
        self._emission_strength(e_strength)
        emission = tuple(max(c * e_strength, 0.0) for c in e_color)
        alpha = self._float(mat, node, "Alpha", default=1.0)
        if alpha < 1:
            self.warn(mat, node, f"alpha {alpha:g} is not modelled (rendered opaque)")
        for names in (("Coat Weight", "Clearcoat"), ("Sheen Weight", "Sheen"),
                      ("Subsurface Weight", "Subsurface")):
            value = self._float(mat, node, *names)
            if value > 0:
                self.warn(mat, node, f"'{names[0]}' {value:g} is not modelled")
        if transmission >= 0.5:
            if transmission < 1 or metallic > 0:
                self.warn(mat, node, f"transmission {transmission:g} / metallic {metallic:g} "
                                     "approximated as pure glass")
            if roughness > 0:
                self.warn(mat, node, f"roughness {roughness:g} is treated as 0 (smooth glass)")
            return self.Material(name=mat.name, kind=self.GLASS, color=base, ior=max(ior, 1e-3),
                                 emission=emission)
        if metallic >= 0.5:
            if metallic < 1:
                self.warn(mat, node, f"metallic {metallic:g} approximated as a pure mirror")
            if roughness > 0:
                self.warn(mat, node, f"roughness {roughness:g} is treated as 0 (perfect mirror)")
            return self.Material(name=mat.name, kind=self.MIRROR, color=base, emission=emission)
        if metallic > 0 or transmission > 0:
            self.warn(mat, node, f"metallic {metallic:g} / transmission {transmission:g} "
                                 "approximated as diffuse")
        specular = self._float(mat, node, "Specular IOR Level", "Specular", default=0.0)
        if specular > 0:
            self.warn(mat, node, f"specular layer (level {specular:g}) is not modelled: "
                                 "rendered as pure Lambertian (set it to 0 to match Cycles)")
        return self.Material(name=mat.name, kind=self.DIFFUSE, color=base, emission=emission)
