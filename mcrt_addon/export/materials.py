"""Material export: Cycles node trees -> tracer Materials (diffuse, mirror, glass, glossy, principled, emission).

Supported: Diffuse BSDF (Roughness -> diffuse_roughness), Emission; Glass, Refraction, Transparent and
Translucent BSDFs in dielectric_nodes.py; the microfacet nodes
(Glossy / Anisotropic, Metallic, Principled v2 of 4.0+) in microfacet_nodes.py; Blender 3.4's
Principled v1 (the principled kind with PrincipledV1 inputs, its transmission too).
Anything else becomes diffuse with a warning naming the material and the node.  Node trees are read
from ``material.original`` (evaluated copies can lack them).
"""
import bpy
import numpy as np

from . import dielectric_nodes, microfacet_nodes, shader_mix
from .images import float_image, image_node
from .util import following_links, linked_from, socket, uses_nodes
from .unsupported import node_warnings

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


def _from(sock):
    """' from node 'NAME'' for a linked socket (the node is then named: unsupported.node_warnings)."""
    source = linked_from(sock)
    return f" from node '{source.name}'" if source is not None else ""


def _local_x(matrix):
    """The unit world direction of an object's local X axis (rounded: a key), (1, 0, 0) without one."""
    if matrix is None:
        return (1.0, 0.0, 0.0)
    x = np.asarray(matrix, dtype=np.float64)[:3, 0]
    length = float(np.linalg.norm(x))
    if not length > 0:
        return (1.0, 0.0, 0.0)
    return tuple(round(float(c) / length, 9) for c in x)


class MaterialTable:
    """Collects the tracer materials; one entry per Blender material (shared by all users)."""

    def __init__(self, model, warnings, images=None, version=None):
        """model: the tracer's scene model module (engine/scene/model.py: Material, Principled, kinds);
        version: the Blender whose node vocabulary is read (default: the running one)."""
        self.Material, self.Principled = model.Material, model.Principled
        self.PrincipledV1 = model.PrincipledV1
        self.images = images            # images.ImageTable: Image Texture nodes (None: not read)
        self._slots = {}                # the material being converted: role -> TextureSlot
        self.DIFFUSE, self.MIRROR, self.GLASS = model.DIFFUSE, model.MIRROR, model.GLASS
        self.GLOSSY, self.PRINCIPLED = model.GLOSSY, model.PRINCIPLED
        self.MIX, self.Mix, self.MixLeaf, self.MixFactor = model.MIX, model.Mix, model.MixLeaf, model.MixFactor
        self.REFRACTION, self.TRANSPARENT, self.TRANSLUCENT = model.REFRACTION, model.TRANSPARENT, model.TRANSLUCENT
        self.TEXTURED_INPUTS = getattr(model, "TEXTURED_INPUTS", ())      # float inputs image textures may drive
        self.version = tuple(bpy.app.version if version is None else version)[:2]
        self.materials = []
        self.warnings = warnings
        self._index = {}
        # Anisotropic materials take their tangent from the object (its local X axis): one tracer
        # material per Blender material and tangent.
        self.object_x = (1.0, 0.0, 0.0)     # the object being exported: its local X axis, world space
        self.used_object_tangent = False    # set by the conversion when it used `object_x`
        self._per_tangent = set()           # names of the Blender materials that use it
        self._programs = {}                 # the shader node being converted: role -> node program
        self._emission_color = (0.0, 0.0, 0.0)   # the unlinked emission colour read last
        self._converting = ""                    # the name of the Blender material being converted
        self._graph = None                  # node_graph.GraphCompiler, made on first use
        self._path = ()                     # the group nodes around the shader node being converted

    def graph(self):
        """The node-graph compiler (export/node_graph.py), or None when the tracer has no node layer."""
        if self._graph is None:
            from .. import bridge
            from .node_graph import GraphCompiler
            try:
                self._graph = GraphCompiler(self, bridge.module("scene.programs"), bridge.module("nodes.evaluator"),
                                            bridge.module("nodes.registry"))
            except ImportError:
                self._graph = False
        return self._graph or None

    def program(self, mat, node, sock, target):
        """(node program or None, folded constant or None) of the graph feeding ``sock``."""
        graph = self.graph() if self.images is not None else None
        if graph is None:
            return None, None
        return graph.compile(mat, node, sock, target, self._path)

    def graph_warned(self):
        """Whether the last program() named the node feeding its socket in a warning already."""
        return bool(self._graph and self._graph.warned)

    def add(self, material):
        self.materials.append(material)
        return len(self.materials) - 1

    def default_index(self):
        if None not in self._index:
            self._index[None] = self.add(self.Material(name="(default surface)", kind=self.DIFFUSE,
                                                       color=DEFAULT_GREY))
        return self._index[None]

    def index(self, bl_material, matrix=None):
        """Tracer material index for a Blender material (None -> Cycles' default grey) on an object
        with world matrix ``matrix`` (4x4; None: the identity)."""
        if bl_material is None:
            return self.default_index()
        original = bl_material.original if bl_material.original is not None else bl_material
        self.object_x = _local_x(matrix)
        key = original.name_full
        if key in self._per_tangent:
            key = (key, self.object_x)
        if key not in self._index:
            self._converting = original.name
            self._slots = {}
            self.used_object_tangent = False
            with following_links() as read:             # every node the conversion reads
                material = self.convert(original)
            self.warnings += node_warnings(original, read, self.warnings)
            material.color_texture = self._slots.get("color")
            material.emission_texture = self._slots.get("emission")
            if self.used_object_tangent:
                self._per_tangent.add(key)
                key = (key, self.object_x)
            self._index[key] = self.add(material)
        return self._index[key]

    def slot_indices(self, ob, matrix=None):
        """Tracer material index for every material slot of ``ob`` (at least one entry); ``matrix``:
        the instance's world matrix (anisotropic materials take their tangent from it)."""
        slots = [self.index(slot.material, matrix) for slot in ob.material_slots]
        return slots or [self.default_index()]

    def uv_map(self, slot_ids):
        """The UV map a mesh with these material slots needs: '' for the active render one, the
        name a UV Map node gives, or None when no material of the mesh has a texture."""
        names = [slot.uv_map for i in slot_ids for slot in shader_mix.texture_slots(self.materials[i])]
        names += [name for i in slot_ids for name in shader_mix.program_uv_maps(self.materials[i])]
        if not names:
            return None
        if len(set(names)) > 1:
            self.warnings.append(f"Materials of one mesh read UV maps {sorted(set(names))}: only "
                                 f"'{names[0] or 'the active render map'}' is used")
        return names[0]

    # --- conversion -----------------------------------------------------------------------------
    def warn(self, mat, node, text):
        if self._path and node is not None and "(inside node group" not in text:
            text = f"{text} (inside node group '{self._path[-1].node_tree.name}')"
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
        # Cycles renders an unconnected surface as black (no closure): shader(None).
        return self.shader(mat, *self.shader_source(mat, output.inputs.get("Surface")))

    def shader_source(self, mat, sock):
        """(shader node or None, its group path) feeding the shader socket ``sock`` of a node inside
        the current group path: through reroutes, muted nodes and node groups (export/node_graph.py
        shader_feed; without the tracer's node layer only reroutes are followed)."""
        graph = self.graph()
        if graph is None:
            return linked_from(sock), self._path
        found = graph.shader_feed(mat, sock, self._path)
        return found if found is not None else (None, self._path)

    def shader(self, mat, node, path=None):
        """The material of the shader node ``node`` inside the group nodes ``path`` (None: the current
        path; its value inputs are read through them); None: an unlinked shader socket, no closure.
        Its textures go to ``self._slots``."""
        outer_path, self._path = self._path, (self._path if path is None else tuple(path))
        try:
            return self._shader(mat, node)
        finally:
            self._path = outer_path

    def _shader(self, mat, node):
        if node is None:
            return self.Material(name=mat.name, kind=self.DIFFUSE, color=(0.0, 0.0, 0.0))
        handler = {
            "ShaderNodeBsdfDiffuse": self._diffuse,
            "ShaderNodeBsdfGlossy": self._glossy,
            "ShaderNodeBsdfAnisotropic": self._glossy,
            "ShaderNodeBsdfMetallic": self._metallic,
            "ShaderNodeBsdfGlass": self._glass,
            "ShaderNodeBsdfRefraction": lambda m, n: dielectric_nodes.refraction(self, m, n),
            "ShaderNodeBsdfTransparent": lambda m, n: dielectric_nodes.transparent(self, m, n),
            "ShaderNodeBsdfTranslucent": lambda m, n: dielectric_nodes.translucent(self, m, n),
            "ShaderNodeEmission": self._emission,
            "ShaderNodeBsdfPrincipled": self._principled,
            "ShaderNodeAddShader": self._add_shader,
            "ShaderNodeMixShader": self._mix_shader,
        }.get(node.bl_idname)
        if handler is None:
            self.warn(mat, node, f"{node.bl_idname} is not supported; rendered as diffuse grey")
            return self.Material(name=mat.name, kind=self.DIFFUSE, color=DEFAULT_GREY)
        outer, self._programs = self._programs, {}
        try:
            material = handler(mat, node)
            self._normal_program(mat, node)
            programs = {role: p for role, p in self._programs.items() if role != "emission_strength"}
        finally:
            self._programs = outer
        inputs = {name: self._slots.pop(name) for name in self.TEXTURED_INPUTS if name in self._slots}
        if inputs:                              # this BSDF's textured float inputs (read_float's roles)
            material.input_textures = inputs
        if programs and hasattr(material, "programs"):   # node programs on its inputs (export/node_graph.py)
            material.programs = dict(material.programs or {}, **programs)
        mix = getattr(material, "mix", None)
        if mix is not None and node.bl_idname in ("ShaderNodeMixShader", "ShaderNodeAddShader") and any(
                "normal" in (leaf.material.programs or {}) for leaf in mix.leaves):
            self.warn(mat, node, "a Normal input of a shader inside this mix is not modelled (the shading normal is used)")
        return material

    def _normal_program(self, mat, node):
        """A BSDF's linked Normal input (Normal Map, Bump, ...) as its "normal" program (export/node_graph.py)."""
        sock = node.inputs.get("Normal") if node.bl_idname != "ShaderNodeEmission" else None
        if sock is None or not sock.is_linked or sock.bl_idname == "NodeSocketShader":
            return
        program, _ = self.program(mat, node, sock, "VECTOR")
        if program is not None:
            self._programs["normal"] = program
        elif not self.graph_warned():
            self.warn(mat, node, f"input 'Normal' is linked{_from(sock)}, which is not modelled; the shading "
                                 "normal is used")

    def side(self, mat, node, path=None):
        """(material, texture slots) of a shader node (inside the group nodes ``path``) feeding an Add
        or Mix Shader."""
        outer, self._slots = self._slots, {}
        try:
            return self.shader(mat, node, path), self._slots
        finally:
            self._slots = outer

    def _add_shader(self, mat, node):
        return shader_mix.add_shader(self, mat, node)

    def _mix_shader(self, mat, node):
        return shader_mix.mix_shader(self, mat, node)

    def read_color(self, mat, node, *names, default=(0.8, 0.8, 0.8), role="color"):
        """The unlinked value of the first socket of ``names``; an Image Texture node feeding it
        becomes the material's texture slot ``role`` ("color", "emission"; None: textures are not
        supported on this socket: warned, the unlinked value is used)."""
        sock = socket(node, *names)
        if sock is None:
            return default
        image = (image_node(sock) if self.images is not None and sock.is_linked and role is not None
                 else None)
        if image is not None:
            slot = self.images.slot(mat, image)
            if slot is not None:
                self._slots[role] = slot
        elif sock.is_linked and role is not None:
            program, value = self.program(mat, node, sock, "RGBA")
            if program is not None:
                self._programs[role] = program
            elif value is not None:
                return tuple(float(c) for c in value)
            elif not self.graph_warned():
                self.warn(mat, node, f"input '{sock.name}' is linked{_from(sock)}, which is not modelled; "
                                     f"its unlinked value is used")
        elif sock.is_linked:
            self.warn(mat, node, f"input '{sock.name}' is linked{_from(sock)} (textures are not supported); "
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
        colour, power = self._programs.pop("emission", None), self._programs.pop("emission_strength", None)
        if slot is not None and strength > 0 and power is not None and colour is None:
            self.warnings.append(f"Material '{self._converting}': an image emission colour with a strength driven by "
                                 "nodes is not modelled; the strength's unlinked value is used")
            power = None
        if colour is not None or power is not None:      # radiance = colour x strength per hit
            from .node_graph import scaled
            self._programs["emission"] = scaled(self.graph(), colour, power, self._emission_color, strength)

    def read_float(self, mat, node, *names, default=0.0, role=None):
        """The unlinked value of the first socket of ``names``; with a ``role`` (a float input of
        engine/scene/model.py TEXTURED_INPUTS) an Image Texture feeding it, straight or through a
        Separate RGB / Color node, becomes the material's texture on that input."""
        sock = socket(node, *names)
        if sock is None:
            return default
        if sock.is_linked and self.images is not None:
            found = float_image(sock) if role in self.TEXTURED_INPUTS else None
            if found is not None:
                slot = self.images.slot(mat, found[0])
                if slot is not None:
                    slot.channel = found[1]
                    self._slots[role] = slot
                return float(sock.default_value)
            program, value = self.program(mat, node, sock, "VALUE")
            if value is not None:
                return float(value)
            if program is not None and (role in self.TEXTURED_INPUTS or role == "emission_strength"):
                self._programs[role] = program
                return float(sock.default_value)
            if program is not None:
                self.warn(mat, node, f"input '{sock.name}' is driven by nodes per hit, which this input does "
                                     "not take; its unlinked value is used")
                return float(sock.default_value)
            if self.graph_warned():
                return float(sock.default_value)
            source = linked_from(sock)
            what = f"'{source.name}' ({source.bl_idname})" if source is not None else "a muted link"
            self.warn(mat, node, f"input '{sock.name}' is linked to {what}, which is not modelled (docs/nodes.md "
                                 "lists the nodes that are); its unlinked value is used")
            return float(sock.default_value)
        if sock.is_linked:
            self.warn(mat, node, f"input '{sock.name}' is linked{_from(sock)}; its unlinked value is used")
        return float(sock.default_value)

    def tangent_need(self, slot_ids):
        """The corner tangents a mesh with these materials needs (engine/scene/model.py
        tangent_source): None, "radial" (Cycles' default) or ("uv", UV map name, "" the active render
        map); a warning when its materials ask for different ones (the first is used)."""
        needs = []
        for i in slot_ids:
            m = self.materials[i]
            mats = [leaf.material for leaf in m.mix.leaves] if getattr(m, "mix", None) is not None else [m]
            for x in mats:
                normal = (getattr(x, "programs", None) or {}).get("normal")
                needs += [("uv", n.props.get("uv_map", "") or "") for n in (normal.nodes if normal else [])
                          if n.kind == "ShaderNodeNormalMap" and n.props.get("space", "TANGENT") == "TANGENT"]
                source = getattr(x, "tangent_source", "fixed")
                if source == "uv":
                    needs.append(("uv", x.tangent_uv_map))
                elif source == "radial":
                    needs.append("radial")
        if not needs:
            return None
        if len(set(needs)) > 1:
            self.warnings.append(f"Materials of one mesh take tangents from {sorted(map(str, set(needs)))}: "
                                 f"only {needs[0]} is used")
        return needs[0]

    def principled_emission(self, mat, node):
        """Emitted radiance of a Principled BSDF: colour x strength (a textured colour: its slot)."""
        # 3.x: 'Emission' colour (default black) x 'Emission Strength' (default 1);
        # 4.x/5.0: 'Emission Color' (default white) x 'Emission Strength' (default 0).
        e_color = self.read_color(mat, node, "Emission Color", "Emission", default=(0.0, 0.0, 0.0),
                                  role="emission")
        self._emission_color = e_color
        e_strength = self.read_float(mat, node, "Emission Strength", default=1.0, role="emission_strength")
        self._emission_strength(e_strength)
        return tuple(max(c * e_strength, 0.0) for c in e_color)

    def _diffuse(self, mat, node):
        color = _clamp01(self.read_color(mat, node, "Color"))
        roughness = min(max(self.read_float(mat, node, "Roughness", role="diffuse_roughness"), 0.0), 1.0)
        return self.Material(name=mat.name, kind=self.DIFFUSE, color=color, diffuse_roughness=roughness)

    def _glossy(self, mat, node):
        return microfacet_nodes.glossy(self, mat, node)

    def _metallic(self, mat, node):
        return microfacet_nodes.metallic(self, mat, node)

    def _principled(self, mat, node):
        if self.version >= microfacet_nodes.PRINCIPLED_V2:
            return microfacet_nodes.principled(self, mat, node)
        return self._principled_v1(mat, node)

    def _glass(self, mat, node):
        return dielectric_nodes.glass(self, mat, node)

    def _emission(self, mat, node):
        color = self.read_color(mat, node, "Color", default=(1.0, 1.0, 1.0), role="emission")
        self._emission_color = color
        strength = self.read_float(mat, node, "Strength", default=1.0, role="emission_strength")
        self._emission_strength(strength)
        radiance = tuple(max(c * strength, 0.0) for c in color)
        return self.Material(name=mat.name, kind=self.DIFFUSE, color=(0.0, 0.0, 0.0), emission=radiance)

    def _principled_v1(self, mat, node):
        """Blender 3.x's Principled BSDF (v1) -> the principled kind with PrincipledV1 inputs
        (engine/materials/principled_v1.py); its transmission is 3.4's glass closures there
        (engine/materials/principled_v1_glass.py)."""
        base = _clamp01(self.read_color(mat, node, "Base Color"))
        transmission = min(max(self.read_float(mat, node, "Transmission"), 0.0), 1.0)
        per_hit = transmission == 0.0           # its glass closures take the material's roughness, metallic
        metallic = min(max(self.read_float(mat, node, "Metallic", role="metallic" if per_hit else None), 0.0), 1.0)
        roughness = min(max(self.read_float(mat, node, "Roughness", default=0.5,
                                            role="roughness" if per_hit else None), 0.0), 1.0)
        ior = max(self.read_float(mat, node, "IOR", default=1.45), 1e-3)
        emission = self.principled_emission(mat, node)
        alpha = min(max(self.read_float(mat, node, "Alpha", default=1.0), 0.0), 1.0)
        if alpha < 1:
            self.warn(mat, node, f"input 'Alpha' {alpha:g} is not modelled (rendered opaque)")
        subsurface = min(max(self.read_float(mat, node, "Subsurface"), 0.0), 1.0)
        if subsurface > 0:
            # Cycles' own fallback below a diffuse bounce: the base colour mixed with the subsurface colour.
            sss = _clamp01(self.read_color(mat, node, "Subsurface Color", role=None))
            base = tuple(b * (1.0 - subsurface) + c * subsurface for b, c in zip(base, sss))
            self.warn(mat, node, f"input 'Subsurface' {subsurface:g} is rendered as diffuse (Burley) of the "
                                 "base colour mixed with 'Subsurface Color'")
        for name in ("Clearcoat Normal",):         # Normal: a "normal" program (_normal_program)
            sock = socket(node, name)
            if sock is not None and sock.is_linked:
                self.warn(mat, node, f"input '{name}' is linked (normal inputs are not modelled)")
        dist, multiscatter = microfacet_nodes.distribution(self, mat, node)
        inputs = self.PrincipledV1(
            metallic=metallic,
            specular=max(self.read_float(mat, node, "Specular", default=0.5), 0.0),
            specular_tint=min(max(self.read_float(mat, node, "Specular Tint"), 0.0), 1.0),
            sheen=max(self.read_float(mat, node, "Sheen"), 0.0),
            sheen_tint=min(max(self.read_float(mat, node, "Sheen Tint", default=0.5), 0.0), 1.0),
            clearcoat=max(self.read_float(mat, node, "Clearcoat"), 0.0),
            clearcoat_roughness=min(max(self.read_float(mat, node, "Clearcoat Roughness", default=0.03), 0.0), 1.0),
            transmission=transmission,
            transmission_roughness=min(max(self.read_float(mat, node, "Transmission Roughness"), 0.0), 1.0),
            alpha=alpha)
        return self.Material(name=mat.name, kind=self.PRINCIPLED, color=base, emission=emission, ior=ior,
                             roughness=roughness, distribution=dist, multiscatter=multiscatter, principled=inputs,
                             **microfacet_nodes.anisotropy_fields(self, mat, node, "Anisotropic",
                                                                  "Anisotropic Rotation"))
