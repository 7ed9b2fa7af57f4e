"""World export: the constant background colour and the image world (engine/scene/model.py
Environment, lit by engine/lights/environment.py).

Node patterns read (Blender 3.4 to 5.0), into World Output's Surface:
* Background (Color x Strength; Strength a constant): a constant world (world.color without nodes);
* Environment Texture (image, Equirectangular / Mirror Ball, Linear / Closest; Cubic and Smart as
  Linear) -> Background Color, its Vector unlinked, from a Texture Coordinate node's Generated
  output, or through a Mapping node (rotation and scale of any vector type; a location is ignored)
  from either: the image world;
* Mix Shader whose Fac is Light Path's Is Camera Ray, between two of the above: camera rays see the
  second (Cycles: Fac 1), every other ray the first.
Anything else: a warning naming the world and the node, and the constant colour of the Background
node it found (black without one), as before the image world existed.
Node groups are entered as in materials (mcrt_addon/export/node_graph.py resolve, docs/nodes.md "Node
groups"): each link read here is followed through reroutes, muted nodes and groups, and a socket's
value through a Group Input is the group node's input value.
"""
import math

import numpy as np

from .util import linked_from, socket, uses_nodes

IDENTITY = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
# Baked Sky Textures by model and parameters: baking takes 1-7 s of CPU (docs/world.md "Sky Texture"),
# and the viewport exports the world again after every edit; the few last skies are kept.
SKY_BAKES_KEPT = 4
_SKY_BAKES = {}


def export_world(world, warnings, images=None, Environment=None, suns=None, SunLight=None):
    """(background colour, Environment or None).  images: the export's ImageTable
    (mcrt_addon/export/images.py) and Environment the scene model's class; without them only the
    constant colour is exported.  suns: the export's list of SunLight (the scene model's class)
    that a Sky Texture's sun disc is appended to."""
    if world is None:
        return (0.0, 0.0, 0.0), None
    tree = world.node_tree if uses_nodes(world) else None
    if tree is None:
        # 3.x without nodes uses world.color; 5.0 has no use_nodes and always a node tree
        return tuple(max(float(c), 0.0) for c in world.color[:3]), None
    output = tree.get_output_node("CYCLES")
    reader = WorldReader(world, warnings, images, Environment)
    reader.suns, reader.SunLight = suns, SunLight
    node = reader.source(output.inputs.get("Surface"), output) if output is not None else None
    if node is None:
        return (0.0, 0.0, 0.0), None
    if node.bl_idname == "ShaderNodeMixShader":
        return reader.mix(node)
    if node.bl_idname != "ShaderNodeBackground":
        reader.warn(node, f"({node.bl_idname}) is not supported; background is black")
        return (0.0, 0.0, 0.0), None
    colour, image = reader.background(node)
    if image is None:
        return colour, None
    return colour, Environment(**image, name=world.name)


class WorldReader:
    def __init__(self, world, warnings, images, Environment):
        self.world, self.warnings, self.images, self.Environment = world, warnings, images, Environment
        self.graph = _groups(self)           # node_graph.GraphCompiler for resolve(), None without the tracer
        self.paths = {}                      # a node found through groups -> the group nodes around it
        self.suns, self.SunLight = None, None  # where a Sky Texture's sun disc goes (export_world)

    def warn(self, node, text):
        self.warnings.append(f"World '{self.world.name}': node '{node.name}' {text}")

    # -- links and values through node groups --------------------------------------------------------
    def feed(self, sock, owner):
        """What feeds the input ``sock`` of the node ``owner`` (node_graph.resolve inside the groups
        around ``owner``): a Feed, a Constant, None (unlinked) or BLOCKED (warned)."""
        if sock is None or not sock.is_linked:
            return None
        if self.graph is None:
            node = linked_from(sock)
            return None if node is None else _Feed(node, sock.links[0].from_socket)
        self.graph.mat, self.graph.warned = self.world, False
        feed = self.graph.resolve(sock, self.paths.get(owner.as_pointer(), ()))
        if hasattr(feed, "path"):
            self.paths[feed.node.as_pointer()] = feed.path
        return feed

    def source(self, sock, owner):
        """The node feeding ``sock`` of ``owner`` through reroutes, muted nodes and groups, or None."""
        feed = self.feed(sock, owner)
        return feed.node if hasattr(feed, "node") else None

    def output_name(self, sock, owner):
        """The name of the output socket feeding ``sock`` of ``owner`` ("" when no node feeds it)."""
        feed = self.feed(sock, owner)
        return feed.out.name if hasattr(feed, "out") else ""

    def linked(self, sock, owner):
        """Whether a node (not a group socket's value) feeds ``sock`` of ``owner``."""
        return hasattr(self.feed(sock, owner), "node")

    def value(self, sock, owner):
        """The value ``sock`` of ``owner`` has unless a node feeds it: its own, or through a Group
        Input the group node's input value (as the group socket converts it)."""
        feed = self.feed(sock, owner)
        if hasattr(feed, "value"):
            value = self.graph._constant_as(feed, sock.type)
            return tuple(value) if isinstance(value, tuple) else value
        return sock.default_value

    def mix(self, node):
        """A Mix Shader: Light Path's Is Camera Ray between two Backgrounds, else a warning."""
        fac, feeds = node.inputs[0], [self.feed(node.inputs[i], node) for i in (1, 2)]
        first, second = (getattr(f, "node", None) for f in feeds)
        paths = [getattr(f, "path", ()) for f in feeds]     # one node may be both sides, in two group uses
        source = self.source(fac, node)
        is_camera = (source is not None and source.bl_idname == "ShaderNodeLightPath"
                     and self.output_name(fac, node) == "Is Camera Ray")
        backgrounds = [n for n in (first, second) if n is not None and n.bl_idname == "ShaderNodeBackground"]
        if not is_camera or len(backgrounds) != 2:
            self.warn(node, "is supported only as Light Path 'Is Camera Ray' mixing two Background nodes; "
                            "the first Background's constant colour is used")
            colour = self.constant(backgrounds[0]) if backgrounds else (0.0, 0.0, 0.0)
            return colour, None
        self.paths[first.as_pointer()] = paths[0]
        lit, lit_image = self.background(first)
        self.paths[second.as_pointer()] = paths[1]
        cam, cam_image = self.background(second)
        if lit_image is None and cam_image is None:
            self.warn(node, "mixes two constant Backgrounds: camera rays see the lighting colour here")
            return lit, None
        if lit_image is None:                      # the image is seen by camera rays only
            return lit, self.Environment(**cam_image, lighting=False, name=self.world.name)
        if cam_image is None:
            return lit, self.Environment(**lit_image, camera_color=cam, name=self.world.name)
        if any(cam_image[k] != lit_image[k] for k in ("texture", "projection", "interpolation", "matrix")):
            self.warn(node, "mixes two different environment images: camera rays see the lighting image here")
            return lit, self.Environment(**lit_image, name=self.world.name)
        return lit, self.Environment(**lit_image, camera_strength=cam_image["strength"], name=self.world.name)

    def constant(self, node):
        colour = tuple(float(c) for c in self.value(socket(node, "Color"), node)[:3])
        strength = float(self.value(socket(node, "Strength"), node))
        return tuple(max(c * strength, 0.0) for c in colour)

    def background(self, node):
        """(constant colour, the Environment fields of its image or None) of a Background node."""
        color_sock, strength_sock = socket(node, "Color"), socket(node, "Strength")
        if strength_sock is not None and self.linked(strength_sock, node):
            self.warn(node, "has its Strength linked (only a constant is supported); its unlinked value is used")
        strength = max(float(self.value(strength_sock, node)), 0.0)
        colour = self.constant(node)
        if not color_sock.is_linked or hasattr(self.feed(color_sock, node), "value"):
            return colour, None
        source = self.source(color_sock, node)
        if source is not None and source.bl_idname == "ShaderNodeTexSky" and self.images is not None:
            image = self.sky(source, strength)
            return colour, image
        if source is None or source.bl_idname != "ShaderNodeTexEnvironment" or self.images is None:
            name = "" if source is None else f" from '{source.name}' ({source.bl_idname})"
            self.warn(node, f"has its Color linked{name}: only an Environment Texture is supported; "
                            "its unlinked colour is used")
            return colour, None
        if self.output_name(color_sock, node) != "Color":
            self.warn(source, "feeds the Background through its Alpha: not supported; the unlinked colour is used")
            return colour, None
        image = self.texture(source)
        if image is None:
            return colour, None
        image["strength"] = strength
        return colour, image

    def sky(self, node, strength):
        """The Environment fields (with strength) of a Sky Texture baked into an equirectangular image
        (engine/lights/sky.py), its sun disc appended to the export's suns; None (a warning) for
        the sky types not ported (the Background's unlinked colour is used)."""
        kind = getattr(node, "sky_type", "")
        if kind not in ("SINGLE_SCATTERING", "MULTIPLE_SCATTERING", "NISHITA", "PREETHAM"):
            self.warn(node, f"(Sky Texture, type {kind}) is not supported (only Blender 5.0's Single and "
                            "Multiple Scattering, 3.4's Nishita and Preetham); the Background's unlinked colour is used")
            return None
        from .. import bridge
        import bpy
        sky = bridge.module("lights.sky")
        version = tuple(bpy.app.version[:2])
        if kind == "PREETHAM":
            key = (kind, tuple(node.sun_direction), float(node.turbidity), version)
            return self.baked(node, key, lambda: sky.PreethamSky(key[1], key[2], version), strength)
        params = sky.SkyParameters(
            sky_type=kind, sun_elevation=float(node.sun_elevation), sun_rotation=float(node.sun_rotation),
            sun_disc=bool(node.sun_disc), sun_size=float(node.sun_size),
            sun_intensity=float(node.sun_intensity), altitude=float(node.altitude),
            air_density=float(node.air_density),
            aerosol_density=float(getattr(node, "aerosol_density", getattr(node, "dust_density", 1.0))),
            ozone_density=float(node.ozone_density))
        return self.baked(node, (kind, repr(params), version), lambda: sky.SkyTexture(params, version), strength)

    def baked(self, node, key, make_texture, strength):
        """The Environment fields of a sky model baked (engine/lights/sky.py), its sun disc appended to the
        suns; `key` names the model and its parameters: a sky is baked once per key (_SKY_BAKES)."""
        if key not in _SKY_BAKES:
            texture = make_texture()
            if len(_SKY_BAKES) >= SKY_BAKES_KEPT:
                _SKY_BAKES.pop(next(iter(_SKY_BAKES)))
            _SKY_BAKES[key] = (texture.bake(), texture.sun_irradiance(), np.asarray(texture.sun_direction, dtype=np.float64),
                               float(texture.sun_size))
        pixels, sun_irradiance, sun_direction, sun_size = _SKY_BAKES[key]
        self.images.textures.append(self.images.ImageTexture(
            name=f"{self.world.name}: {node.name}", pixels=pixels.copy(), colorspace="Linear", is_float=True))
        matrix = self.coordinates(node)
        irradiance = sun_irradiance * strength
        if self.suns is not None and self.SunLight is not None and float(irradiance.max()) > 0.0:
            to_sun = np.linalg.solve(np.asarray(matrix, dtype=np.float64), sun_direction)
            to_sun /= np.linalg.norm(to_sun)
            fields = getattr(self.SunLight, "__dataclass_fields__", {})     # an older tracer's model has no sky_disc
            self.suns.append(self.SunLight(name=f"{self.world.name}: {node.name} (sun disc)",
                                           direction=tuple(float(c) for c in -to_sun),
                                           irradiance=tuple(float(c) for c in irradiance),
                                           angle=sun_size,
                                           **({"sky_disc": True} if "sky_disc" in fields else {})))
        return dict(texture=len(self.images.textures) - 1, projection="equirectangular",
                    interpolation="Linear", matrix=matrix, strength=strength)

    def texture(self, node):
        """The Environment fields of an Environment Texture node (without strength), or None."""
        if node.image is None:
            self.warn(node, "has no image; the Background's unlinked colour is used")
            return None
        index = self.images.texture_index(self.world, node, node.image)
        if index is None:
            return None
        if node.interpolation in ("Cubic", "Smart"):
            self.warn(node, f"{node.interpolation} interpolation is rendered as Linear")
        projection = {"EQUIRECTANGULAR": "equirectangular", "MIRROR_BALL": "mirror_ball"}.get(node.projection)
        if projection is None:
            self.warn(node, f"projection {node.projection} is not supported; rendered as equirectangular")
            projection = "equirectangular"
        return dict(texture=index, projection=projection,
                    interpolation="Closest" if node.interpolation == "Closest" else "Linear",
                    matrix=self.coordinates(node))

    def coordinates(self, node):
        """The texture's direction matrix from what feeds its Vector: nothing or Generated
        coordinates (the ray direction) -> identity, through a Mapping node -> its matrix."""
        vector = socket(node, "Vector")
        source = self.source(vector, node)
        if source is None:
            return IDENTITY
        if source.bl_idname == "ShaderNodeMapping":
            matrix = self.mapping(source)
            if not self.generated(source, socket(source, "Vector")):
                return IDENTITY
            return matrix
        self.generated(node, vector)              # a warning unless Generated coordinates
        return IDENTITY

    def generated(self, node, vector):
        """Whether `vector` of `node` is unlinked or Generated texture coordinates (else a warning)."""
        source = self.source(vector, node)
        if source is None:
            return True
        if source.bl_idname == "ShaderNodeTexCoord" and self.output_name(vector, node) == "Generated":
            return True
        self.warn(node, f"reads its Vector from '{source.name}' ({source.bl_idname}): only Generated "
                        "coordinates (or a Mapping node of them) are supported; the ray direction is used")
        return False

    def mapping(self, node):
        """A Mapping node's matrix on directions (Cycles' svm_mapping): Point and Vector R S, Texture
        S^-1 R^T, Normal R S^-1 (normalised afterwards by the texture); a location is ignored."""
        kind = getattr(node, "vector_type", "POINT")
        for name in ("Location", "Rotation", "Scale"):
            sock = socket(node, name)
            if sock is not None and self.linked(sock, node):
                self.warn(node, f"has its {name} linked (only constants are supported); its unlinked value is used")
        loc = socket(node, "Location")
        if kind in ("POINT", "TEXTURE") and loc is not None and any(abs(float(c)) > 0 for c in self.value(loc, node)):
            self.warn(node, "has a Location: a direction does not move with it in this tracer; ignored")
        rx, ry, rz = (float(c) for c in self.value(socket(node, "Rotation"), node))
        scale = [float(c) for c in self.value(socket(node, "Scale"), node)]
        r = euler_xyz(rx, ry, rz)
        if kind == "TEXTURE" or kind == "NORMAL":
            if any(s == 0.0 for s in scale):
                self.warn(node, "has a Scale of 0; rendered with 1 there")
            scale = [1.0 / s if s != 0.0 else 1.0 for s in scale]
        if kind == "TEXTURE":                          # S^-1 R^T
            m = [[scale[i] * r[j][i] for j in range(3)] for i in range(3)]
        else:                                          # R S (Normal: R S^-1)
            m = [[r[i][j] * scale[j] for j in range(3)] for i in range(3)]
        if abs(det3(m)) < 1e-12:
            self.warn(node, "maps every direction into a plane (a Scale of 0); rotation only is used")
            m = r if kind != "TEXTURE" else [[r[j][i] for j in range(3)] for i in range(3)]
        return tuple(tuple(row) for row in m)


class _Feed:
    """A node output feeding an input (without the tracer's node layer: no groups entered)."""
    def __init__(self, node, out):
        self.node, self.out, self.path = node, out, ()


class _WorldTable:
    """What node_graph.GraphCompiler reads of its table, for a world: warnings naming the world."""
    images = None

    def __init__(self, reader):
        import bpy
        self.reader, self.version = reader, tuple(bpy.app.version[:2])

    def warn(self, mat, node, text):
        self.reader.warn(node, text)


def _groups(reader):
    """A node_graph.GraphCompiler whose resolve() the reader follows links with, or None when the
    tracer's node layer is not there (then links are followed through reroutes only)."""
    from .. import bridge
    from .node_graph import GraphCompiler
    try:
        return GraphCompiler(_WorldTable(reader), bridge.module("scene.programs"), bridge.module("nodes.evaluator"),
                             bridge.module("nodes.registry"))
    except ImportError:
        return None


def euler_xyz(x, y, z):
    """Blender's (and Cycles' euler_to_transform) XYZ Euler rotation: Rz Ry Rx."""
    cx, cy, cz, sx, sy, sz = math.cos(x), math.cos(y), math.cos(z), math.sin(x), math.sin(y), math.sin(z)
    return [[cy * cz, sy * sx * cz - cx * sz, sy * cx * cz + sx * sz],
            [cy * sz, sy * sx * sz + cx * cz, sy * cx * sz - sx * cz],
            [-sy, cy * sx, cy * cx]]


def det3(m):
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))
