"""Generates the sample .blend files used by the add-on tests and the docs (docs/user-guide.md,
"The sample scenes").

Runs with the bpy module (Blender 5.0) or inside a Blender binary (Debian's 3.4 too):

  .venv/bin/python sample_blends/make_samples.py [--outdir DIR] [--only NAME ...] [--resolution W H]
  blender -b --factory-startup --python sample_blends/make_samples.py -- --outdir DIR

The committed files are made by `make samples`: Debian's Blender 3.4 (files saved by 3.4 open in
3.4 and in every newer Blender, files saved by 5.0 do not open in 3.4), each with TNCG15 MC as its
render engine (use_tncg15; tests/addon/test_sample_files.py checks both).

Only the bpy data API and bmesh are used (no operators), so the script is independent of the UI
context and of the Blender version.  Meshes are small in the file: the heavy Suzannes are
Subdivision modifiers evaluated at render time.

Scenes (all in a Cornell-style room: x, y in [-1, 1], z in [0, 2], open towards the camera):
  cornell        red left wall, green right, white floor/ceiling/back, emissive ceiling plane,
                 a mirror sphere, a glass sphere and a ~5k-triangle diffuse torus (the report's scene)
  suzanne_5k     subdivided Suzanne, 5.8k triangles (triangulated Suzanne + Subdivision level 1), diffuse
  suzanne_100k   subdivided Suzanne, 93k triangles (Subdivision level 3), diffuse
  mirror_glass   a glass sphere and a glass cube resting on the floor, a mirror sphere
  diffuse_room   diffuse walls, boxes and a sphere only
  principled     the Cornell scene made of Principled BSDF materials (Specular IOR Level 0)
  area_light     a diffuse room lit by a Blender Area light (exporter checks; one-sided in Cycles)
  point_light    the room lit by a point light of radius 10 cm
  sun_window     a sun shining through a window in the left wall
  spot_light     the room lit by a spot light (30 degrees, blend 0.3) aimed at the floor and back
                 wall, and a dim point light; both are seen in a mirror ball
  sky_lit        an open scene: a floor with a box, a ball and a low wall under a uniform sky (the
                 world colour is the only light)
  textured       image textures packed in the file: a checker floor (Repeat), a tiled back wall
                 through a second UV map (Closest, Extend) and a lamp with a textured emission colour
  nested_glass   glass inside glass: a "water" sphere (IOR 1.33) inside a glass cube (IOR 1.5),
                 and a glass sphere resting on the cube's top face
  smooth         smooth shading: a shade-smooth diffuse Suzanne (Subdivision level 2), a diffuse and
                 a mirror low-poly 12 x 6 shade-smooth UV sphere (too coarse for the implicit-sphere
                 test: triangle meshes with interpolated normals; the diffuse one shows the shadow
                 terminator, the mirror one the valid-reflection normal), in the Cornell room
  glossy_plates  four Glossy BSDF plates (Multiscatter GGX, roughness 0.1, 0.25, 0.45, 0.7) tilted to
                 reflect the ceiling lamp towards the camera, in the Cornell room
  rough_diffuse  the diffuse_room with Diffuse BSDF Roughness 0.8 on every wall and box (Oren-Nayar)
  principled_default  a cube with Blender's default material (Principled BSDF, all defaults) in the
                 Cornell room
  principled_balls  a wall of Principled balls: roughness 0.15 / 0.4 / 0.8 x metallic 0 / 0.5 / 1, and
                 a column with clearcoat, sheen and both, in the Cornell room
  principled_grid  Principled BSDF balls: roughness 0.1, 0.3, 0.55, 0.8 across; rows dielectric,
                 metal, a tinted coat over white, sheen over dark blue; lit by an Area light
  roughness_map  a Glossy plate whose Roughness is a 4 x 4 checker image (0.1 / 0.6, Non-Color,
                 Closest) tilted to reflect an Area light, and an anisotropic Glossy ball (anisotropy
                 0.9) whose Tangent is a Tangent node reading the UV map (MikkTSpace), in the room
  node_room      node graphs (mcrt_addon/export/node_graph.py) in the Cornell room: the floor's Base
                 Color an image through Texture Coordinate Object -> Mapping, its Roughness the image at
                 Generated; a ball coloured by its Geometry Normal; a lamp coloured by Generated
  normal_map     a normal-mapped object: a smooth UV sphere whose Principled BSDF's Normal is a tangent-space
                 Normal Map of a packed 8-bit Non-Color image (scripts/make_sample_normal_map.py), on a
                 floor under a low sun and a dim sky
Light-sampling stress scenes (plain ceiling, the lamps are two-sided emissive meshes, as
mesh emission in Cycles, hung just under it so they also light the ceiling):
  near_lamp      a 0.5 m lamp quad (strength 12) 2 cm under the ceiling, two diffuse boxes
  caustic        a glass ball (r 0.35, IOR 1.5) resting on the floor, lit from behind and above by a
                 0.2 m lamp quad (strength 60) 2 cm under the ceiling: a caustic in front of the ball
  many_lights    a 6x6 grid of 8 cm lamp quads 1 cm under the ceiling (strength 13: 36 x 8 cm x 8 cm
                 x 13 ~ the Cornell lamp's 0.5 m x 0.5 m x 12), a diffuse sphere and box
  area_mirror    a Blender Area light (as area_light) seen in a mirror sphere and through a glass
                 sphere (Cycles: area lights are seen by mirror and glass rays, not by the camera)
"""
import math
import os
import sys

import bpy  # noqa: I001 - bpy must come before bmesh in the module build
import bmesh

HERE = os.path.dirname(os.path.abspath(__file__))
if os.path.dirname(HERE) not in sys.path:          # the add-on (use_tncg15) from this repository
    sys.path.insert(0, os.path.dirname(HERE))
V4 = bpy.app.version >= (4, 0, 0)
DEFAULT_RES = (128, 128)


# ---------------------------------------------------------------------------------------- helpers
def reset():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob)
    return scene


def empty_material(name):
    """A node material with only its Material Output: (material, nodes, links, output node)."""
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True              # always on (and deprecated) in 5.0
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    for n in list(nodes):
        nodes.remove(n)
    return mat, nodes, links, nodes.new("ShaderNodeOutputMaterial")


def node_material(name, kind, **kw):
    mat, nodes, _, out = empty_material(name)
    node = nodes.new(kind)
    for key, value in kw.items():
        sock = node.inputs.get(key)
        if sock is None:
            continue                      # socket absent in this Blender version
        sock.default_value = value
    mat.node_tree.links.new(node.outputs[0], out.inputs["Surface"])
    mat.diffuse_color = tuple(kw.get("Color", kw.get("Base Color", (0.8, 0.8, 0.8, 1.0))))[:3] + (1.0,)
    return mat


def diffuse(name, rgb):
    return node_material(name, "ShaderNodeBsdfDiffuse", Color=(*rgb, 1.0), Roughness=0.0)


def mirror(name, rgb):
    return node_material(name, "ShaderNodeBsdfGlossy", Color=(*rgb, 1.0), Roughness=0.0)


def glass(name, rgb=(1, 1, 1), ior=1.5):
    return node_material(name, "ShaderNodeBsdfGlass", Color=(*rgb, 1.0), Roughness=0.0, IOR=ior)


def emission(name, rgb, strength):
    return node_material(name, "ShaderNodeEmission", Color=(*rgb, 1.0), Strength=strength)


def principled(name, base, metallic=0.0, roughness=0.5, transmission=0.0, ior=1.5,
               emission_rgb=(0, 0, 0), emission_strength=0.0):
    kw = {"Base Color": (*base, 1.0), "Metallic": metallic, "Roughness": roughness, "IOR": ior,
          "Specular IOR Level": 0.0, "Specular": 0.0,
          "Transmission Weight": transmission, "Transmission": transmission,
          "Emission Strength": emission_strength}
    if V4:
        kw["Emission Color"] = (*emission_rgb, 1.0)
    else:
        kw["Emission"] = (*emission_rgb, 1.0)
    return node_material(name, "ShaderNodeBsdfPrincipled", **kw)


def mesh_object(scene, name, build, material=None, location=(0, 0, 0), rotation=(0, 0, 0),
                scale=(1, 1, 1), smooth=False):
    bm = bmesh.new()
    build(bm)
    me = bpy.data.meshes.new(name)
    bm.to_mesh(me)
    bm.free()
    if smooth:
        for p in me.polygons:
            p.use_smooth = True
    ob = bpy.data.objects.new(name, me)
    ob.location, ob.rotation_euler, ob.scale = location, rotation, scale
    if material is not None:
        me.materials.append(material)
    scene.collection.objects.link(ob)
    return ob


def quad(bm, corners):
    verts = [bm.verts.new(c) for c in corners]
    bm.faces.new(verts)


def plane(scene, name, corners, material):
    return mesh_object(scene, name, lambda bm: quad(bm, corners), material)


def uv_sphere(bm, radius, segments=64, rings=32):
    bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=rings, radius=radius)


def cube(bm, size):
    bmesh.ops.create_cube(bm, size=size)


def torus(bm, major=0.3, minor=0.12, nu=64, nv=40):
    rows = []
    for i in range(nu):
        u = 2 * math.pi * i / nu
        row = []
        for j in range(nv):
            v = 2 * math.pi * j / nv
            r = major + minor * math.cos(v)
            row.append(bm.verts.new((r * math.cos(u), r * math.sin(u), minor * math.sin(v))))
        rows.append(row)
    for i in range(nu):
        for j in range(nv):
            a, b = rows[i][j], rows[(i + 1) % nu][j]
            c, d = rows[(i + 1) % nu][(j + 1) % nv], rows[i][(j + 1) % nv]
            bm.faces.new((a, b, c, d))


def camera(scene, lens=50.0, location=(0.0, -3.9, 1.0), target=(0.0, 0.0, 1.0)):
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.data.lens = lens
    cam.data.sensor_width = 36.0
    cam.data.sensor_fit = "AUTO"
    cam.location = location
    dx, dy, dz = (t - l for t, l in zip(target, location))
    cam.rotation_euler = (math.atan2(math.hypot(dx, dy), -dz), 0.0, math.atan2(dx, dy) * -1.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    return cam


def world_colour(scene, rgb, strength=1.0):
    """A constant world: a Background node of colour `rgb` and `strength`."""
    black_world(scene)
    bg = next(n for n in scene.world.node_tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Color"].default_value = (*rgb, 1.0)
    bg.inputs["Strength"].default_value = strength
    scene.world.color = rgb


def black_world(scene):
    world = bpy.data.worlds.new("World")
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    nodes = world.node_tree.nodes
    for n in list(nodes):
        nodes.remove(n)
    bg = nodes.new("ShaderNodeBackground")
    bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    out = nodes.new("ShaderNodeOutputWorld")
    world.node_tree.links.new(bg.outputs[0], out.inputs["Surface"])
    world.color = (0.0, 0.0, 0.0)
    scene.world = world


def settings(scene, resolution):
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    scene.frame_start = scene.frame_end = scene.frame_current = 1
    if hasattr(scene, "tncg15"):                 # only when the add-on is registered
        scene.tncg15.samples = 16
        scene.tncg15.max_depth = 8


def room(scene, mats=None, light_strength=12.0, light_size=0.5, ceiling_light=True):
    """Walls as separate planes (normals facing into the room) and a ceiling light plane."""
    if mats is None:
        mats = dict(white=diffuse("White", (0.73, 0.73, 0.73)), red=diffuse("Red", (0.65, 0.05, 0.05)),
                    green=diffuse("Green", (0.12, 0.45, 0.15)),
                    light=emission("Light", (1.0, 0.9, 0.75), light_strength))
    w, r, g = mats["white"], mats["red"], mats["green"]
    plane(scene, "Floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], w)
    if ceiling_light:
        # the lamp fills a hole in the ceiling, flush with it: no gap between lamp and ceiling
        # (a gap makes a 1/r^2-bright strip next to the lamp: fireflies and edge bias)
        s = light_size / 2
        outer = [(-1, -1, 2), (-1, 1, 2), (1, 1, 2), (1, -1, 2)]
        inner = [(-s, -s, 2), (-s, s, 2), (s, s, 2), (s, -s, 2)]

        def ceiling(bm):
            vo = [bm.verts.new(c) for c in outer]
            vi = [bm.verts.new(c) for c in inner]
            for k in range(4):
                bm.faces.new((vo[k], vo[(k + 1) % 4], vi[(k + 1) % 4], vi[k]))
        mesh_object(scene, "Ceiling", ceiling, w)
        plane(scene, "Lamp", inner, mats["light"])
    else:
        plane(scene, "Ceiling", [(-1, -1, 2), (-1, 1, 2), (1, 1, 2), (1, -1, 2)], w)
    plane(scene, "Back", [(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)], w)
    plane(scene, "Left", [(-1, -1, 0), (-1, 1, 0), (-1, 1, 2), (-1, -1, 2)], r)
    plane(scene, "Right", [(1, -1, 0), (1, -1, 2), (1, 1, 2), (1, 1, 0)], g)
    return mats


# ----------------------------------------------------------------------------------------- scenes
def make_cornell(scene, res, principled_mats=False):
    if principled_mats:
        mats = dict(white=principled("White", (0.73, 0.73, 0.73), roughness=0.5),
                    red=principled("Red", (0.65, 0.05, 0.05)), green=principled("Green", (0.12, 0.45, 0.15)),
                    light=principled("Light", (0.0, 0.0, 0.0), emission_rgb=(1.0, 0.9, 0.75),
                                     emission_strength=12.0))
        mirror_mat = principled("Mirror", (0.95, 0.95, 0.95), metallic=1.0, roughness=0.0)
        glass_mat = principled("Glass", (1.0, 1.0, 1.0), roughness=0.0, transmission=1.0, ior=1.5)
        torus_mat = principled("Blue", (0.2, 0.3, 0.7))
    else:
        mats = None
        mirror_mat = mirror("Mirror", (0.9, 0.9, 0.9))
        glass_mat = glass("Glass", ior=1.5)
        torus_mat = diffuse("Blue", (0.2, 0.3, 0.7))
    room(scene, mats)
    mesh_object(scene, "MirrorSphere", lambda bm: uv_sphere(bm, 0.35), mirror_mat,
                location=(-0.45, 0.35, 0.35), smooth=True)
    mesh_object(scene, "GlassSphere", lambda bm: uv_sphere(bm, 0.3), glass_mat,
                location=(0.45, -0.2, 0.75), smooth=True)
    mesh_object(scene, "Torus", lambda bm: torus(bm), torus_mat, location=(0.4, 0.45, 0.25),
                rotation=(math.radians(60), 0, math.radians(20)))
    camera(scene)
    black_world(scene)
    settings(scene, res)


def make_suzanne(scene, res, level):
    room(scene)
    def monkey(bm):
        bmesh.ops.create_monkey(bm)
        bmesh.ops.triangulate(bm, faces=bm.faces[:])   # 968 triangles -> 3 quads each per level 1

    ob = mesh_object(scene, "Suzanne", monkey,
                     diffuse("Clay", (0.75, 0.6, 0.45)), location=(0, 0, 0.8),
                     rotation=(0, 0, math.radians(-20)), scale=(0.6, 0.6, 0.6), smooth=False)  # flat (the `smooth` scene has shading normals)
    mod = ob.modifiers.new("Subdivision", "SUBSURF")
    mod.levels = mod.render_levels = level
    camera(scene)
    black_world(scene)
    settings(scene, res)


def make_mirror_glass(scene, res):
    room(scene)
    mesh_object(scene, "GlassSphere", lambda bm: uv_sphere(bm, 0.35), glass("Glass", ior=1.5),
                location=(-0.35, -0.1, 0.35), smooth=True)          # resting on the floor
    mesh_object(scene, "GlassCube", lambda bm: cube(bm, 0.4), glass("GlassCube", (0.9, 1.0, 0.95), 1.5),
                location=(0.5, -0.3, 0.202), rotation=(0, 0, math.radians(30)))  # 2 mm above the floor: coplanar faces are ill-posed
    mesh_object(scene, "MirrorSphere", lambda bm: uv_sphere(bm, 0.4), mirror("Mirror", (0.95, 0.95, 0.95)),
                location=(0.2, 0.5, 0.4), smooth=True)
    camera(scene)
    black_world(scene)
    settings(scene, res)


def make_diffuse_room(scene, res):
    room(scene)
    white = bpy.data.materials["White"]
    mesh_object(scene, "TallBox", lambda bm: cube(bm, 1.0), white, location=(-0.35, 0.3, 0.6),
                rotation=(0, 0, math.radians(20)), scale=(0.3, 0.3, 0.6))
    mesh_object(scene, "ShortBox", lambda bm: cube(bm, 1.0), diffuse("Yellow", (0.7, 0.6, 0.2)),
                location=(0.4, -0.25, 0.3), rotation=(0, 0, math.radians(-17)), scale=(0.3, 0.3, 0.3))
    mesh_object(scene, "Ball", lambda bm: uv_sphere(bm, 0.2), diffuse("Pink", (0.8, 0.4, 0.5)),
                location=(0.45, 0.5, 0.2), smooth=True)
    camera(scene)
    black_world(scene)
    settings(scene, res)


def glossy(name, rgb, roughness, distribution="MULTI_GGX"):
    mat = node_material(name, "ShaderNodeBsdfGlossy", Color=(*rgb, 1.0), Roughness=roughness)
    next(n for n in mat.node_tree.nodes if n.bl_idname != "ShaderNodeOutputMaterial").distribution = distribution
    return mat


GLOSSY_PLATE_ROUGHNESS = (0.1, 0.25, 0.45, 0.7)


def make_glossy_plates(scene, res):
    room(scene)
    s = 0.17

    def panel(bm):                      # a 0.34 m square in the XZ plane facing -Y (the camera)
        quad(bm, [(-s, 0, -s), (s, 0, -s), (s, 0, s), (-s, 0, s)])
    for k, roughness in enumerate(GLOSSY_PLATE_ROUGHNESS):
        # tilted back by 48 degrees: the mirror direction of the view ray points at the ceiling lamp
        mesh_object(scene, f"Plate{k}", panel, glossy(f"Glossy {roughness:g}", (0.9, 0.9, 0.9), roughness),
                    location=(-0.6 + 0.4 * k, 0.2, 0.7), rotation=(math.radians(-48), 0, 0))
    camera(scene)
    black_world(scene)
    settings(scene, res)


def dielectric(name, kind, rgb, roughness, distribution, ior=1.5):
    """A Glass or Refraction BSDF node material with the given roughness and distribution menu."""
    mat = node_material(name, kind, Color=(*rgb, 1.0), Roughness=roughness, IOR=ior)
    next(n for n in mat.node_tree.nodes if n.bl_idname != "ShaderNodeOutputMaterial").distribution = distribution
    return mat


def make_rough_glass(scene, res):
    """A rough glass pane (Beckmann, roughness 0.35) in front of a lit window on the back wall, a
    rough multiscatter-GGX glass ball (roughness 0.7) on the floor, and a translucent sheet under the
    ceiling lamp (lit from behind) seen from below."""
    mats = room(scene)
    plane(scene, "Window", [(0.25, 0.99, 0.9), (0.65, 0.99, 0.9), (0.65, 0.99, 1.3), (0.25, 0.99, 1.3)],
          emission("Window light", (1.0, 0.95, 0.9), 6.0))
    mesh_object(scene, "Pane", lambda bm: cube(bm, 1.0),
                dielectric("Ground glass", "ShaderNodeBsdfGlass", (0.95, 1.0, 0.97), 0.35, "BECKMANN"),
                location=(0.45, 0.3, 1.1), scale=(0.7, 0.05, 0.7))
    mesh_object(scene, "RoughBall", lambda bm: uv_sphere(bm, 0.35),
                dielectric("Frosted", "ShaderNodeBsdfGlass", (1.0, 1.0, 1.0), 0.7, "MULTI_GGX"),
                location=(-0.4, -0.1, 0.35), smooth=True)           # resting on the floor
    plane(scene, "Sheet", [(-0.7, -0.6, 1.5), (-0.1, -0.6, 1.5), (-0.1, 0.2, 1.5), (-0.7, 0.2, 1.5)],
          node_material("Paper", "ShaderNodeBsdfTranslucent", Color=(0.8, 0.75, 0.6, 1.0)))
    camera(scene)
    black_world(scene)
    settings(scene, res)
    return mats


def make_rough_diffuse(scene, res):
    make_diffuse_room(scene, res)
    for mat in bpy.data.materials:
        node = next((n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfDiffuse"), None)
        if node is not None:
            node.inputs["Roughness"].default_value = 0.8


def make_principled_default(scene, res):
    room(scene)
    mesh_object(scene, "Cube", lambda bm: cube(bm, 1.0), node_material("Material", "ShaderNodeBsdfPrincipled"),
                location=(0.0, 0.2, 0.202), rotation=(0, 0, math.radians(30)), scale=(0.4, 0.4, 0.4))
    camera(scene)
    black_world(scene)
    settings(scene, res)


def make_principled_balls(scene, res):
    """A wall of Principled balls in the Cornell room: rows of roughness 0.15 / 0.4 / 0.8 (bottom to
    top) x columns of metallic 0 / 0.5 / 1, all orange, node defaults otherwise (Specular 0.5 in 3.x),
    and a fourth column: clearcoat 1 (clearcoat roughness 0.1), sheen 1, both (3.x's sockets; 4.x+
    name them Coat Weight / Sheen Weight)."""
    room(scene)
    orange = (0.8, 0.45, 0.2, 1.0)
    for i, roughness in enumerate((0.15, 0.4, 0.8)):
        for j, metallic in enumerate((0.0, 0.5, 1.0)):
            mat = node_material(f"Ball r{roughness:g} m{metallic:g}", "ShaderNodeBsdfPrincipled",
                                **{"Base Color": orange, "Metallic": metallic, "Roughness": roughness})
            mesh_object(scene, f"Ball{i}{j}", lambda bm: uv_sphere(bm, 0.2, 32, 16), mat,
                        location=(-0.72 + 0.48 * j, 0.2, 0.35 + 0.5 * i), smooth=True)
    for i, (coat, sheen) in enumerate(((1.0, 0.0), (0.0, 1.0), (1.0, 1.0))):
        mat = node_material(f"Coat {coat:g} sheen {sheen:g}", "ShaderNodeBsdfPrincipled",
                            **{"Base Color": orange, "Roughness": 0.4, "Clearcoat": coat, "Coat Weight": coat,
                               "Clearcoat Roughness": 0.1, "Coat Roughness": 0.1, "Sheen": sheen,
                               "Sheen Weight": sheen})
        mesh_object(scene, f"Coated{i}", lambda bm: uv_sphere(bm, 0.2, 32, 16), mat,
                    location=(0.72, 0.2, 0.35 + 0.5 * i), smooth=True)
    camera(scene)
    black_world(scene)
    settings(scene, res)


def area_light(scene):
    """A 0.6 x 0.4 m rectangle Area light of 40 W, 3 cm under the ceiling, emitting down (its
    local -Z); not seen by the camera (Cycles' default), seen in mirrors and through glass."""
    light = bpy.data.lights.new("AreaLight", "AREA")
    light.shape = "RECTANGLE"
    light.size, light.size_y = 0.6, 0.4
    light.energy = 40.0
    light.color = (1.0, 0.95, 0.9)
    ob = bpy.data.objects.new("AreaLight", light)
    ob.location = (0.0, 0.0, 1.97)
    scene.collection.objects.link(ob)
    return ob


def make_area_light(scene, res):
    room(scene, ceiling_light=False)
    area_light(scene)
    mesh_object(scene, "Ball", lambda bm: uv_sphere(bm, 0.3), diffuse("Pink", (0.8, 0.4, 0.5)),
                location=(0.0, 0.0, 0.3), smooth=True)
    camera(scene)
    black_world(scene)
    settings(scene, res)


def make_nested_glass(scene, res):
    room(scene)
    mesh_object(scene, "GlassBlock", lambda bm: cube(bm, 0.8), glass("BlockGlass", (0.95, 1.0, 0.97), 1.5),
                location=(0.0, 0.0, 0.402), rotation=(0, 0, math.radians(20)))   # 2 mm above the floor
    mesh_object(scene, "Water", lambda bm: uv_sphere(bm, 0.25), glass("Water", (0.85, 0.92, 1.0), 1.33),
                location=(0.0, 0.0, 0.4), smooth=True)                         # inside the block
    mesh_object(scene, "Marble", lambda bm: uv_sphere(bm, 0.15), glass("Marble", ior=1.5),
                location=(0.1, -0.1, 0.952), smooth=True)                       # resting on the block
    camera(scene)
    black_world(scene)
    settings(scene, res)


def lamp_quad(scene, name, material, size, z, centre=(0.0, 0.0)):
    """A square emissive mesh quad of side `size` at height z (normal down; emits both ways)."""
    s, (cx, cy) = size / 2, centre
    return plane(scene, name, [(cx - s, cy - s, z), (cx - s, cy + s, z), (cx + s, cy + s, z),
                               (cx + s, cy - s, z)], material)


def make_near_lamp(scene, res):
    mats = room(scene, ceiling_light=False)
    lamp_quad(scene, "Lamp", mats["light"], 0.5, 1.98)             # 2 cm under the ceiling
    # boxes 2 mm above the floor (coplanar faces are ill-posed)
    mesh_object(scene, "TallBox", lambda bm: cube(bm, 1.0), mats["white"], location=(-0.35, 0.3, 0.502),
                rotation=(0, 0, math.radians(20)), scale=(0.3, 0.3, 1.0))
    mesh_object(scene, "ShortBox", lambda bm: cube(bm, 1.0), diffuse("Yellow", (0.7, 0.6, 0.2)),
                location=(0.4, -0.25, 0.152), rotation=(0, 0, math.radians(-17)), scale=(0.3, 0.3, 0.3))
    camera(scene)
    black_world(scene)
    settings(scene, res)


def make_caustic(scene, res):
    mats = room(scene, mats=dict(white=diffuse("White", (0.73, 0.73, 0.73)),
                                 red=diffuse("Red", (0.65, 0.05, 0.05)),
                                 green=diffuse("Green", (0.12, 0.45, 0.15)),
                                 light=emission("Light", (1.0, 0.9, 0.75), 60.0)), ceiling_light=False)
    # lamp behind and above the ball: the caustic lands on the floor in front of the ball (towards
    # the camera), where shadow rays are blocked by the glass and only caustic paths light it
    lamp_quad(scene, "Lamp", mats["light"], 0.2, 1.98, centre=(0.0, 0.7))
    mesh_object(scene, "GlassBall", lambda bm: uv_sphere(bm, 0.35), glass("Glass", ior=1.5),
                location=(0.0, -0.4, 0.35), smooth=True)            # resting on the floor
    camera(scene, location=(0.0, -3.9, 1.3), target=(0.0, 0.0, 0.8))  # a little above: sees the floor
    black_world(scene)
    settings(scene, res)


def make_many_lights(scene, res, n=6, size=0.08, pitch=0.3, strength=13.0):
    mats = room(scene, ceiling_light=False)
    lamp = emission("Light", (1.0, 0.9, 0.75), strength)
    offsets = [(k - (n - 1) / 2) * pitch for k in range(n)]

    def grid(bm):                       # one mesh, n*n separate quads 1 cm under the ceiling
        h = size / 2
        for x in offsets:
            for y in offsets:
                quad(bm, [(x - h, y - h, 1.99), (x - h, y + h, 1.99), (x + h, y + h, 1.99),
                          (x + h, y - h, 1.99)])
    mesh_object(scene, "LampGrid", grid, lamp)
    mesh_object(scene, "Ball", lambda bm: uv_sphere(bm, 0.3), diffuse("Pink", (0.8, 0.4, 0.5)),
                location=(-0.35, 0.1, 0.3), smooth=True)
    mesh_object(scene, "Box", lambda bm: cube(bm, 1.0), mats["white"], location=(0.4, 0.3, 0.352),
                rotation=(0, 0, math.radians(25)), scale=(0.35, 0.35, 0.7))        # 2 mm above the floor
    camera(scene)
    black_world(scene)
    settings(scene, res)


def make_area_mirror(scene, res):
    room(scene, ceiling_light=False)
    area_light(scene)
    mesh_object(scene, "MirrorSphere", lambda bm: uv_sphere(bm, 0.35), mirror("Mirror", (0.9, 0.9, 0.9)),
                location=(-0.45, 0.1, 0.35), smooth=True)
    mesh_object(scene, "GlassSphere", lambda bm: uv_sphere(bm, 0.3), glass("Glass", ior=1.5),
                location=(0.45, -0.3, 0.6), smooth=True)
    camera(scene)
    black_world(scene)
    settings(scene, res)


def light_object(scene, name, kind, location, rotation=(0.0, 0.0, 0.0), **props):
    light = bpy.data.lights.new(name, kind)
    for key, value in props.items():
        setattr(light, key, value)
    ob = bpy.data.objects.new(name, light)
    ob.location, ob.rotation_euler = location, rotation
    scene.collection.objects.link(ob)
    return ob


def make_point_light(scene, res):
    """The Cornell room without its lamp, lit by a point light of radius 10 cm (Blender's default
    kind of light) above a diffuse box and ball."""
    room(scene, ceiling_light=False)
    light_object(scene, "Bulb", "POINT", (0.0, 0.1, 1.6), energy=40.0, shadow_soft_size=0.1, color=(1.0, 0.9, 0.8))
    mesh_object(scene, "Box", lambda bm: cube(bm, 1.0), bpy.data.materials["White"], location=(0.35, 0.3, 0.302),
                rotation=(0, 0, math.radians(20)), scale=(0.3, 0.3, 0.6))
    mesh_object(scene, "Ball", lambda bm: uv_sphere(bm, 0.25), diffuse("Pink", (0.8, 0.4, 0.5)),
                location=(-0.4, -0.1, 0.25), smooth=True)
    camera(scene)
    black_world(scene)
    settings(scene, res)


def make_point_caustic(scene, res):
    """A glass ball on the floor under a point lamp of radius 0: its caustic is a delta light seen
    through glass, which no camera path reaches (Cycles renders the floor under the ball black);
    the file renders it with the caustic photon map (docs/photons.md)."""
    room(scene, ceiling_light=False)
    # up on the left: the caustic lands on the floor to the right of the ball, in plain view
    light_object(scene, "Point lamp", "POINT", (-0.8, -0.2, 1.1), energy=20.0, shadow_soft_size=0.0,
                 color=(1.0, 0.9, 0.75))
    mesh_object(scene, "GlassBall", lambda bm: uv_sphere(bm, 0.35), glass("Glass", ior=1.5),
                location=(0.0, -0.2, 0.35), smooth=True)
    camera(scene, location=(0.0, -3.9, 1.3), target=(0.0, 0.0, 0.8))
    black_world(scene)
    settings(scene, res)
    if hasattr(scene, "tncg15"):
        scene.tncg15.caustics_method = "PHOTONS"


def make_sun_window(scene, res):
    """The Cornell room with a window in its left wall: a sun of 0.1 rad shines in and across the
    floor; no other light."""
    room(scene, ceiling_light=False)
    bpy.data.objects.remove(bpy.data.objects["Left"])
    red = bpy.data.materials["Red"]
    for name, corners in (("Left low", [(-1, -1, 0), (-1, 1, 0), (-1, 1, 0.6), (-1, -1, 0.6)]),
                          ("Left high", [(-1, -1, 1.4), (-1, 1, 1.4), (-1, 1, 2), (-1, -1, 2)]),
                          ("Left front", [(-1, -1, 0.6), (-1, -0.3, 0.6), (-1, -0.3, 1.4), (-1, -1, 1.4)]),
                          ("Left back", [(-1, 0.5, 0.6), (-1, 1, 0.6), (-1, 1, 1.4), (-1, 0.5, 1.4)])):
        plane(scene, name, corners, red)
    light_object(scene, "Sun", "SUN", (0.0, 0.0, 3.0), rotation=(0.0, math.radians(-55), 0.0), energy=4.0,
                 angle=0.1)
    mesh_object(scene, "Ball", lambda bm: uv_sphere(bm, 0.25), diffuse("Pink", (0.8, 0.4, 0.5)),
                location=(0.3, 0.0, 0.25), smooth=True)
    camera(scene)
    black_world(scene)
    settings(scene, res)


def make_spot_light(scene, res):
    """The room lit by a spot light from the ceiling's front-left corner aimed at the floor and
    back wall (its cone's edge and blend cross both), and a dim point light for the shadows."""
    room(scene, ceiling_light=False)
    light_object(scene, "Spot", "SPOT", (-0.6, -0.6, 1.9), rotation=(math.radians(35), 0.0, math.radians(-35)),
                 energy=150.0, spot_size=math.radians(30), spot_blend=0.3, shadow_soft_size=0.05,
                 color=(1.0, 0.95, 0.85))
    light_object(scene, "Bulb", "POINT", (0.6, 0.2, 1.7), energy=8.0, shadow_soft_size=0.1, color=(0.8, 0.9, 1.0))
    mesh_object(scene, "Box", lambda bm: cube(bm, 1.0), bpy.data.materials["White"], location=(0.2, 0.4, 0.3),
                rotation=(0, 0, math.radians(-15)), scale=(0.35, 0.35, 0.6))
    mesh_object(scene, "Ball", lambda bm: uv_sphere(bm, 0.22), diffuse("Pink", (0.8, 0.4, 0.5)),
                location=(-0.5, -0.25, 0.22), smooth=True)
    mesh_object(scene, "Mirror ball", lambda bm: uv_sphere(bm, 0.18), mirror("Mirror", (0.9, 0.9, 0.9)),
                location=(-0.1, 0.05, 0.18), smooth=True)
    camera(scene)
    black_world(scene)
    settings(scene, res)


def packed_image(name, width, height, texel, colorspace="sRGB"):
    """A generated image of texel(x, y) -> (r, g, b) (y = 0: the bottom row), packed into the .blend
    (a PNG inside the file: the scene needs no external file)."""
    img = bpy.data.images.new(name, width, height)
    pixels = []
    for y in range(height):
        for x in range(width):
            pixels.extend((*texel(x, y), 1.0))
    img.pixels.foreach_set(pixels)
    img.pack()
    img.colorspace_settings.name = colorspace
    return img


def image_material(name, kind, socket_name, image, interpolation="Linear", extension="REPEAT", uv_map=None, **kw):
    """A node_material whose input `socket_name` is fed by an Image Texture node (through a UV Map
    node reading `uv_map` when given)."""
    mat = node_material(name, kind, **kw)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    shader = next(n for n in nodes if n.bl_idname == kind)
    tex = nodes.new("ShaderNodeTexImage")
    tex.image, tex.interpolation, tex.extension = image, interpolation, extension
    links.new(tex.outputs["Color"], shader.inputs[socket_name])
    if uv_map is not None:
        uv = nodes.new("ShaderNodeUVMap")
        uv.uv_map = uv_map
        links.new(uv.outputs["UV"], tex.inputs["Vector"])
    return mat


def set_uvs(ob, layers):
    """UV maps {name: [uv of each corner of the one quad face]}; the first is the active render map."""
    me = ob.data
    for name, uvs in layers.items():
        layer = me.uv_layers.new(name=name)
        for loop, uv in zip(layer.data, uvs):
            loop.uv = uv
    me.uv_layers[0].active_render = True


def make_textured(scene, res):
    """The Cornell room with image textures (all packed in the file):
    * the floor: Diffuse Color <- a 16 x 16 sRGB checker of 4 x 4 squares, Linear, Repeat, its UVs
      running 0..2 across (two repeats): light squares, and dark ones red in the near half (v < 0.5)
      and blue in the far half, so that a flip in V shows;
    * the back wall: Principled Base Color <- a 4 x 2 Non-Color image, Closest, Extend, through a UV Map
      node reading the second UV map "Second" (u from -0.25 to 1.25: the edge texels extend);
    * the lamp: Emission Color <- a 2 x 2 sRGB warm / cool checker, Closest (strength 12)."""
    room(scene)
    light, dark_near, dark_far = (0.85, 0.85, 0.85), (0.75, 0.12, 0.08), (0.1, 0.2, 0.75)
    checker = packed_image("Checker", 16, 16, lambda x, y: light if (x // 4 + y // 4) % 2 else
                           (dark_near if y < 8 else dark_far))
    floor = bpy.data.objects["Floor"]
    floor.data.materials[0] = image_material("Checker floor", "ShaderNodeBsdfDiffuse", "Color", checker,
                                             Roughness=0.0)
    set_uvs(floor, {"UVMap": [(0, 0), (2, 0), (2, 1), (0, 1)]})
    stripes = [(0.7, 0.7, 0.2), (0.2, 0.6, 0.6), (0.6, 0.3, 0.6), (0.8, 0.8, 0.8),
               (0.3, 0.3, 0.3), (0.7, 0.4, 0.1), (0.1, 0.5, 0.2), (0.5, 0.5, 0.7)]
    tiles = packed_image("Tiles", 4, 2, lambda x, y: stripes[y * 4 + x], colorspace="Non-Color")
    back = bpy.data.objects["Back"]
    back.data.materials[0] = image_material("Tiled wall", "ShaderNodeBsdfPrincipled", "Base Color", tiles,
                                            interpolation="Closest", extension="EXTEND", uv_map="Second",
                                            Roughness=0.5, **{"Specular IOR Level": 0.0, "Specular": 0.0})
    set_uvs(back, {"UVMap": [(0, 0), (0, 1), (1, 1), (1, 0)],             # the wrong map: rotated
                   "Second": [(-0.25, 0), (1.25, 0), (1.25, 1), (-0.25, 1)]})
    warm_cool = packed_image("Lamp colours", 2, 2, lambda x, y: (1.0, 0.75, 0.45) if (x + y) % 2 else
                             (0.55, 0.8, 1.0))
    lamp = bpy.data.objects["Lamp"]
    lamp.data.materials[0] = image_material("Textured lamp", "ShaderNodeEmission", "Color", warm_cool,
                                            interpolation="Closest", Strength=12.0)
    set_uvs(lamp, {"UVMap": [(0, 0), (0, 1), (1, 1), (1, 0)]})
    mesh_object(scene, "Box", lambda bm: cube(bm, 1.0), bpy.data.materials["White"], location=(0.35, 0.3, 0.302),
                rotation=(0, 0, math.radians(20)), scale=(0.3, 0.3, 0.6))
    camera(scene)
    black_world(scene)
    settings(scene, res)


def make_smooth(scene, res):
    """Smooth shading: interpolated vertex normals on a subdivided Suzanne and on
    a coarse UV sphere, both Shade Smooth; lit by the ceiling lamp."""
    room(scene)

    def monkey(bm):
        bmesh.ops.create_monkey(bm)
    ob = mesh_object(scene, "Suzanne", monkey, diffuse("Clay", (0.75, 0.6, 0.45)), location=(-0.3, 0.15, 0.9),
                     rotation=(0, 0, math.radians(-25)), scale=(0.5, 0.5, 0.5), smooth=True)
    mod = ob.modifiers.new("Subdivision", "SUBSURF")
    mod.levels = mod.render_levels = 2
    mesh_object(scene, "LowPolyBall", lambda bm: uv_sphere(bm, 0.3, segments=12, rings=6),
                diffuse("Pink", (0.8, 0.4, 0.5)), location=(0.55, 0.1, 0.3), smooth=True)
    mesh_object(scene, "LowPolyMirror", lambda bm: uv_sphere(bm, 0.25, segments=12, rings=6),
                mirror("Mirror", (0.9, 0.9, 0.9)), location=(0.0, -0.4, 0.25), rotation=(0, 0, math.radians(10)),
                smooth=True)
    camera(scene)
    black_world(scene)
    settings(scene, res)


def make_sky_lit(scene, res):
    """No room and no lamp: a large floor, a box, a ball and a low wall under a light-blue sky of
    strength 1 (the world is the only light; the camera sees some sky above the horizon)."""
    white, red = diffuse("White", (0.73, 0.73, 0.73)), diffuse("Red", (0.65, 0.05, 0.05))
    plane(scene, "Floor", [(-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0)], white)
    mesh_object(scene, "Box", lambda bm: cube(bm, 1.0), red, location=(0.4, 0.5, 0.35),
                rotation=(0, 0, math.radians(25)), scale=(0.5, 0.5, 0.7))
    mesh_object(scene, "Ball", lambda bm: uv_sphere(bm, 0.3), diffuse("Pink", (0.8, 0.4, 0.5)),
                location=(-0.5, -0.1, 0.3), smooth=True)
    plane(scene, "Wall", [(-1.5, 1.2, 0), (1.5, 1.2, 0), (1.5, 1.2, 0.9), (-1.5, 1.2, 0.9)], white)
    camera(scene, lens=35.0, location=(0.0, -3.5, 1.3), target=(0.0, 0.3, 0.5))
    world_colour(scene, (0.55, 0.7, 1.0), 1.0)
    settings(scene, res)


def mix_material(name, fac, first, second):
    """A Mix Shader of two shader nodes made by first(nodes) / second(nodes); fac: a number, or
    factor(nodes, links) -> the output socket feeding the Fac."""
    mat, nodes, links, out = empty_material(name)
    mix = nodes.new("ShaderNodeMixShader")
    if callable(fac):
        links.new(fac(nodes, links), mix.inputs[0])
    else:
        mix.inputs[0].default_value = fac
    links.new(first(nodes).outputs[0], mix.inputs[1])
    links.new(second(nodes).outputs[0], mix.inputs[2])
    links.new(mix.outputs[0], out.inputs["Surface"])
    return mat


def bsdf_node(kind, **inputs):
    def build(nodes):
        node = nodes.new(kind)
        for key, value in inputs.items():
            node.inputs[key].default_value = value
        return node
    return build


# The glass box stands a hair above the floor: a bottom face in the floor's plane is a coincident-face
# case renderers answer differently (Cycles hits the floor from inside the glass and darkens the box's
# lowest pixel row; TNCG15 MC's offset rays see a thin gap: docs/materials.md "mix_shader's block"), and
# this scene is about the Mix Shader.  10^-4 is invisible at any sample resolution.
GLASS_BOX_LIFT = 1e-4


def make_mix_shader(scene, res):
    """Mix Shaders of different BSDFs in the Cornell room (mcrt_addon/export/shader_mix.py):
    * left ball: Diffuse red + Glossy (roughness 0.2) by a Layer Weight's Facing (blend 0.4);
    * middle ball: Diffuse blue + Glossy (roughness 0.1) by a Fresnel node (IOR 1.45);
    * right box: Glass (IOR 1.5) + Diffuse yellow at factor 0.5;
    * floor: Diffuse grey + Glossy (roughness 0.15) by an Image Texture (an 8 x 8 sRGB checker of
      2 x 2 squares, black / white, UVs 0..1)."""
    room(scene)

    def layer_weight(nodes, links):
        node = nodes.new("ShaderNodeLayerWeight")
        node.inputs["Blend"].default_value = 0.4
        return node.outputs["Facing"]

    def fresnel(nodes, links):
        node = nodes.new("ShaderNodeFresnel")
        node.inputs["IOR"].default_value = 1.45
        return node.outputs["Fac"]
    white_gloss = (0.9, 0.9, 0.9, 1.0)
    mesh_object(scene, "FacingBall", lambda bm: uv_sphere(bm, 0.22, 32, 16),
                mix_material("Facing mix", layer_weight, bsdf_node("ShaderNodeBsdfDiffuse", Color=(0.7, 0.1, 0.08, 1)),
                             bsdf_node("ShaderNodeBsdfGlossy", Color=white_gloss, Roughness=0.2)),
                location=(-0.5, 0.1, 0.22), smooth=True)
    mesh_object(scene, "FresnelBall", lambda bm: uv_sphere(bm, 0.22, 32, 16),
                mix_material("Fresnel mix", fresnel, bsdf_node("ShaderNodeBsdfDiffuse", Color=(0.1, 0.2, 0.7, 1)),
                             bsdf_node("ShaderNodeBsdfGlossy", Color=white_gloss, Roughness=0.1)),
                location=(0.0, 0.35, 0.22), smooth=True)
    mesh_object(scene, "GlassBox", lambda bm: cube(bm, 1.0),
                mix_material("Glass diffuse mix", 0.5, bsdf_node("ShaderNodeBsdfGlass", IOR=1.5, Roughness=0.0),
                             bsdf_node("ShaderNodeBsdfDiffuse", Color=(0.75, 0.65, 0.15, 1))),
                location=(0.5, -0.05, 0.25 + GLASS_BOX_LIFT), rotation=(0, 0, math.radians(25)), scale=(0.3, 0.3, 0.5))
    checker = packed_image("Mix checker", 8, 8, lambda x, y: (1.0, 1.0, 1.0) if (x // 2 + y // 2) % 2 else
                           (0.0, 0.0, 0.0))

    def texture(nodes, links):
        node = nodes.new("ShaderNodeTexImage")
        node.image, node.interpolation = checker, "Closest"
        return node.outputs["Color"]
    floor = bpy.data.objects["Floor"]
    floor.data.materials[0] = mix_material("Checker mix", texture,
                                           bsdf_node("ShaderNodeBsdfDiffuse", Color=(0.6, 0.6, 0.6, 1)),
                                           bsdf_node("ShaderNodeBsdfGlossy", Color=white_gloss, Roughness=0.15))
    set_uvs(floor, {"UVMap": [(0, 0), (1, 0), (1, 1), (0, 1)]})
    camera(scene)
PRINCIPLED_GRID_ROUGHNESS = (0.1, 0.3, 0.55, 0.8)
# Rows from the top: (label, base colour, metallic, the layer's sockets).
PRINCIPLED_GRID_ROWS = (
    ("Dielectric", (0.8, 0.25, 0.15), 0.0, {}),
    ("Metal", (0.95, 0.75, 0.45), 1.0, {}),
    ("Coat", (0.8, 0.8, 0.8), 0.0, {"Coat Weight": 1.0, "Coat Roughness": 0.05, "Coat Tint": (0.9, 0.55, 0.25, 1.0)}),
    ("Sheen", (0.04, 0.05, 0.12), 0.0, {"Sheen Weight": 1.0, "Sheen Roughness": 0.5}),
)


def make_principled_grid(scene, res):
    """Principled BSDF balls (Blender 4.0+'s v2 sockets; 3.x reads what it has): four columns of
    roughness, rows dielectric, metal, coated and sheen, lit by a 1.2 x 0.6 m Area light high in
    front; in the Cornell room without its lamp, seen through a 70 mm lens."""
    room(scene, ceiling_light=False)
    light_object(scene, "Softbox", "AREA", (0.0, -1.4, 1.85), rotation=(math.radians(55), 0.0, 0.0),
                 shape="RECTANGLE", size=1.2, size_y=0.6, energy=45.0, color=(1.0, 0.97, 0.92))
    for row, (label, base, metallic, layer) in enumerate(PRINCIPLED_GRID_ROWS):
        for col, roughness in enumerate(PRINCIPLED_GRID_ROUGHNESS):
            kw = {"Base Color": (*base, 1.0), "Metallic": metallic, "Roughness": roughness, **layer}
            mat = node_material(f"{label} {roughness:g}", "ShaderNodeBsdfPrincipled", **kw)
            mesh_object(scene, f"Ball {label} {roughness:g}", lambda bm: uv_sphere(bm, 0.16, 48, 24), mat,
                        location=(-0.63 + 0.42 * col, 0.0, 1.63 - 0.42 * row), smooth=True)
    camera(scene, lens=70.0)
    black_world(scene)
    settings(scene, res)


PRINCIPLED_GLASS_BALLS = (      # (name, base colour, transmission, roughness, x)
    ("Clear", (1.0, 1.0, 1.0), 1.0, 0.0, -0.6),
    ("Frosted", (1.0, 0.85, 0.6), 1.0, 0.3, 0.0),
    ("Half", (0.3, 0.5, 0.9), 0.5, 0.3, 0.6),
)


def make_principled_glass(scene, res):
    """Principled BSDF balls with transmission (both socket vocabularies: 'Transmission Weight' in
    4.0+, 'Transmission' in 3.x) on the floor of the Cornell room under its lamp: clear (transmission
    1, roughness 0), frosted and tinted (1, 0.3) and half transmissive, blue (0.5, 0.3); IOR 1.5,
    the node's other inputs at their defaults."""
    room(scene)
    for name, base, transmission, roughness, x in PRINCIPLED_GLASS_BALLS:
        kw = {"Base Color": (*base, 1.0), "Roughness": roughness, "IOR": 1.5,
              "Transmission Weight": transmission, "Transmission": transmission}
        mat = node_material(f"{name} glass", "ShaderNodeBsdfPrincipled", **kw)
        mesh_object(scene, f"Ball {name}", lambda bm: uv_sphere(bm, 0.3, 48, 24), mat,
                    location=(x, -0.2, 0.302), smooth=True)             # 2 mm above the floor
    camera(scene)
    black_world(scene)
    settings(scene, res)


ROUGHNESS_CHECKER = (0.1, 0.6)          # the roughness_map plate's two roughnesses


def make_roughness_map(scene, res):
    """Image textures on float inputs and a tangent from the UV map (mcrt_addon/export/materials.py):
    * a 0.8 m Glossy plate (GGX), tilted back by 45 degrees towards the Area light, its Roughness fed
      by a 4 x 4 checker of ROUGHNESS_CHECKER (Non-Color, Closest) over its UVs 0..1;
    * a ball (UV sphere, shade smooth) of anisotropic Glossy (GGX, roughness 0.2, anisotropy 0.9)
      whose Tangent input is a Tangent node in UV Map mode: the highlight stretches across the UV
      map's u direction (the sphere's meridians)."""
    room(scene, ceiling_light=False)
    area_light(scene)
    lo, hi = ROUGHNESS_CHECKER
    checker = packed_image("Roughness checker", 4, 4, lambda x, y: (hi,) * 3 if (x + y) % 2 else (lo,) * 3,
                           colorspace="Non-Color")
    # ShaderNodeBsdfAnisotropic: 3.4's Anisotropic BSDF, 4.0+'s Glossy BSDF (anisotropy 0: isotropic)
    plate_mat = image_material("Checker roughness", "ShaderNodeBsdfAnisotropic", "Roughness", checker,
                               interpolation="Closest", Color=(0.9, 0.9, 0.9, 1.0), Anisotropy=0.0)
    next(n for n in plate_mat.node_tree.nodes if n.bl_idname.startswith("ShaderNodeBsdf")).distribution = "GGX"
    s = 0.4

    def panel(bm):                      # a 0.8 m square in the XZ plane facing -Y (the camera)
        quad(bm, [(-s, 0, -s), (s, 0, -s), (s, 0, s), (-s, 0, s)])
    plate_ob = mesh_object(scene, "Plate", panel, plate_mat, location=(-0.45, 0.3, 0.55),
                           rotation=(math.radians(-45), 0, 0))
    set_uvs(plate_ob, {"UVMap": [(0, 0), (1, 0), (1, 1), (0, 1)]})
    ball_mat = node_material("Brushed", "ShaderNodeBsdfAnisotropic", Color=(0.9, 0.9, 0.9, 1.0), Roughness=0.2,
                             Anisotropy=0.9)
    bsdf = next(n for n in ball_mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfAnisotropic")
    bsdf.distribution = "GGX"
    tangent = ball_mat.node_tree.nodes.new("ShaderNodeTangent")
    tangent.direction_type, tangent.uv_map = "UV_MAP", "UVMap"
    ball_mat.node_tree.links.new(tangent.outputs["Tangent"], bsdf.inputs["Tangent"])

    def ball(bm):
        bm.loops.layers.uv.new("UVMap")
        bmesh.ops.create_uvsphere(bm, u_segments=48, v_segments=24, radius=0.4, calc_uvs=True)
    mesh_object(scene, "Ball", ball, ball_mat, location=(0.45, -0.2, 0.4), rotation=(0, 0, math.radians(30)),
                smooth=True)
    camera(scene)
    black_world(scene)
    settings(scene, res)


def environment_world(scene, image, strength=1.0, rotation_z=0.0):
    """An image world: Texture Coordinate (Generated) -> Mapping (rotation about Z) -> Environment
    Texture -> Background (strength) -> World Output."""
    black_world(scene)
    tree = scene.world.node_tree
    bg = next(n for n in tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Strength"].default_value = strength
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    coords = tree.nodes.new("ShaderNodeTexCoord")
    mapping = tree.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, rotation_z)
    tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    tree.links.new(env.outputs["Color"], bg.inputs["Color"])
    return env


def sky_world(scene, strength=0.03, elevation=25.0, rotation=40.0, kind="MULTIPLE_SCATTERING"):
    """A Sky Texture world (Blender 5.0's `kind`, 3.4's Nishita; sun disc on) -> Background (strength)."""
    black_world(scene)
    tree = scene.world.node_tree
    bg = next(n for n in tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Strength"].default_value = strength
    sky = tree.nodes.new("ShaderNodeTexSky")
    sky.sky_type = kind if bpy.app.version >= (5, 0, 0) else "NISHITA"
    sky.sun_elevation, sky.sun_rotation = math.radians(elevation), math.radians(rotation)
    tree.links.new(sky.outputs["Color"], bg.inputs["Color"])
    return sky


def make_sky(scene, res, kind="MULTIPLE_SCATTERING"):
    """A sky-lit object: a Principled ball and a box on a floor under a Sky Texture (5.0's default
    Multiple Scattering, or `kind`; sun 25 degrees up, turned 40 degrees) of strength 0.03; no lamp."""
    white = diffuse("White", (0.7, 0.7, 0.7))
    plane(scene, "Floor", [(-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0)], white)
    mesh_object(scene, "Ball", lambda bm: uv_sphere(bm, 0.45), principled("Ball", (0.8, 0.45, 0.2), roughness=0.4),
                location=(-0.35, 0.2, 0.45), smooth=True)
    mesh_object(scene, "Box", lambda bm: cube(bm, 1.0), white, location=(0.6, 0.5, 0.15),
                rotation=(0, 0, math.radians(20)), scale=(0.3, 0.3, 0.3))
    camera(scene, lens=35.0, location=(0.0, -3.6, 1.4), target=(0.0, 0.3, 0.5))
    sky_world(scene, kind=kind)
    settings(scene, res)


def sky_image():
    """The sample sky of scripts/make_sample_hdr.py as a float image packed into the .blend."""
    from scripts.make_sample_hdr import HEIGHT, WIDTH, sky_texel
    img = bpy.data.images.new("sky_sun", WIDTH, HEIGHT, float_buffer=True)
    pixels = []
    for y in range(HEIGHT):
        for x in range(WIDTH):
            pixels.extend((*sky_texel(x, y), 1.0))
    img.pixels.foreach_set(pixels)
    img.file_format = "OPEN_EXR"
    img.pack()
    return img


def make_hdri(scene, res):
    """An HDRI-lit object: a ball and a box on a floor under the sample sky (a gradient and a small,
    very bright sun) of strength 0.6, the image turned 30 degrees about Z by a Mapping node; no lamp."""
    white = diffuse("White", (0.7, 0.7, 0.7))
    plane(scene, "Floor", [(-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0)], white)
    mesh_object(scene, "Ball", lambda bm: uv_sphere(bm, 0.45), diffuse("Orange", (0.8, 0.45, 0.2)),
                location=(-0.35, 0.2, 0.45), smooth=True)
    mesh_object(scene, "Box", lambda bm: cube(bm, 1.0), white, location=(0.6, 0.5, 0.15),
                rotation=(0, 0, math.radians(20)), scale=(0.3, 0.3, 0.3))
    camera(scene, lens=35.0, location=(0.0, -3.6, 1.4), target=(0.0, 0.3, 0.5))
    environment_world(scene, sky_image(), 0.6, math.radians(30.0))
    settings(scene, res)



def normal_map_image():
    """The sample normal map of scripts/make_sample_normal_map.py, packed into the .blend (8-bit, Non-Color)."""
    from scripts.make_sample_normal_map import HEIGHT, WIDTH, normal_texel
    return packed_image("bumps", WIDTH, HEIGHT, normal_texel, colorspace="Non-Color")


def make_normal_map(scene, res):
    """A normal-mapped object: a smooth UV sphere (its UV map from bmesh) whose Principled BSDF's
    Normal is a tangent-space Normal Map (strength 1) of an Image Texture (the domes of
    scripts/make_sample_normal_map.py, Non-Color) at its UVs, on a floor, under a low sun and a dim
    uniform sky."""
    mat, nodes, links, out = empty_material("NormalMapped")
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (0.8, 0.5, 0.3, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.4
    tex, nmap = nodes.new("ShaderNodeTexImage"), nodes.new("ShaderNodeNormalMap")
    tex.image = normal_map_image()
    nmap.space, nmap.uv_map = "TANGENT", "UVMap"
    nmap.inputs["Strength"].default_value = 1.0
    links.new(tex.outputs["Color"], nmap.inputs["Color"])
    links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    links.new(bsdf.outputs[0], out.inputs["Surface"])

    def ball(bm):
        bm.loops.layers.uv.new("UVMap")
        bmesh.ops.create_uvsphere(bm, u_segments=64, v_segments=32, radius=0.5, calc_uvs=True)
    plane(scene, "Floor", [(-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0)], diffuse("Grey", (0.5, 0.5, 0.5)))
    mesh_object(scene, "Ball", ball, mat, location=(0.0, 0.0, 0.5), rotation=(0, 0, math.radians(20)), smooth=True)
    light_object(scene, "Sun", "SUN", (0.0, 0.0, 3.0), rotation=(math.radians(65), 0.0, math.radians(-50)),
                 energy=3.0, angle=math.radians(3.0))
    camera(scene, lens=50.0, location=(0.0, -3.2, 1.3), target=(0.0, 0.0, 0.45))
    world_colour(scene, (0.35, 0.4, 0.5), 0.3)
    settings(scene, res)

# -- node graphs (mcrt_addon/export/node_graph.py; tests/nodes/test_agreement_nodes.py) -----------------
NODE_ROOM_SCALE = (2.0, 2.0, 2.0)         # the floor's Mapping scale


def make_node_room(scene, res):
    mats = dict(white=diffuse("White", (0.73, 0.73, 0.73)), red=diffuse("Red", (0.65, 0.05, 0.05)),
                green=diffuse("Green", (0.12, 0.45, 0.15)), light=node_lamp_material())
    room(scene, mats, light_size=0.6)
    floor = bpy.data.objects["Floor"]
    floor.data.materials.clear()
    floor.data.materials.append(node_floor_material())
    mesh_object(scene, "Ball", lambda bm: uv_sphere(bm, 0.35), node_normal_material(), location=(0.2, 0.1, 0.5),
                smooth=True)
    camera(scene)
    black_world(scene)
    settings(scene, res)


def node_floor_material():
    mat, nodes, links, out = empty_material("NodeFloor")
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    coords = nodes.new("ShaderNodeTexCoord")
    mapping = nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = NODE_ROOM_SCALE
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(25))
    grid = bpy.data.images.new("Grid", 64, 64)
    grid.generated_type = "COLOR_GRID"
    tex, rough = nodes.new("ShaderNodeTexImage"), nodes.new("ShaderNodeTexImage")
    tex.image = rough.image = grid
    tex.interpolation = "Closest"
    links.new(coords.outputs["Object"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    links.new(coords.outputs["Generated"], rough.inputs["Vector"])
    links.new(rough.outputs["Color"], bsdf.inputs["Roughness"])
    links.new(bsdf.outputs[0], out.inputs["Surface"])
    return mat


def node_normal_material():
    mat, nodes, links, out = empty_material("NodeBall")
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    geo, mapping = nodes.new("ShaderNodeNewGeometry"), nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (0.5, 0.5, 0.5)
    mapping.inputs["Location"].default_value = (0.5, 0.5, 0.5)
    links.new(geo.outputs["Normal"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], bsdf.inputs["Color"])
    links.new(bsdf.outputs[0], out.inputs["Surface"])
    return mat


def node_lamp_material():
    mat, nodes, links, out = empty_material("NodeLamp")
    em, coords = nodes.new("ShaderNodeEmission"), nodes.new("ShaderNodeTexCoord")
    em.inputs["Strength"].default_value = 14.0
    links.new(coords.outputs["Generated"], em.inputs["Color"])
    links.new(em.outputs[0], out.inputs["Surface"])
    return mat


SCENES = {
    "cornell": lambda s, r: make_cornell(s, r),
    "sky": make_sky,
    "sky_single": lambda s, r: make_sky(s, r, "SINGLE_SCATTERING"),
    "suzanne_5k": lambda s, r: make_suzanne(s, r, 1),
    "suzanne_100k": lambda s, r: make_suzanne(s, r, 3),
    "mirror_glass": make_mirror_glass,
    "diffuse_room": make_diffuse_room,
    "principled": lambda s, r: make_cornell(s, r, principled_mats=True),
    "area_light": make_area_light,
    "nested_glass": make_nested_glass,
    "near_lamp": make_near_lamp,
    "caustic": make_caustic,
    "many_lights": make_many_lights,
    "area_mirror": make_area_mirror,
    "point_light": make_point_light,
    "point_caustic": make_point_caustic,
    "sun_window": make_sun_window,
    "spot_light": make_spot_light,
    "sky_lit": make_sky_lit,
    "textured": make_textured,
    "smooth": make_smooth,
    "glossy_plates": make_glossy_plates,
    "rough_diffuse": make_rough_diffuse,
    "rough_glass": make_rough_glass,
    "principled_default": make_principled_default,
    "mix_shader": make_mix_shader,
    "principled_balls": make_principled_balls,
    "principled_grid": make_principled_grid,
    "principled_glass": make_principled_glass,
    "roughness_map": make_roughness_map,
    "hdri": make_hdri,
    "normal_map": make_normal_map,
    "node_room": lambda s, r: make_node_room(s, r),
}


def use_tncg15(scene):
    """TNCG15 MC as the file's render engine (F12 renders with it): the add-on of this repository
    registered, in the bpy module or in a Blender binary (3.4's Python has no numpy: registration
    needs none)."""
    import mcrt_addon
    from mcrt_addon.headless import ensure_registered
    ensure_registered(mcrt_addon)
    scene.render.engine = mcrt_addon.ui.ENGINE_ID


def make(name, outdir, resolution=DEFAULT_RES):
    scene = reset()
    scene.name = name
    use_tncg15(scene)                  # first: settings() then finds scene.tncg15
    SCENES[name](scene, resolution)
    path = os.path.join(outdir, f"{name}.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, compress=True, check_existing=False)
    return path


def main(argv):
    import argparse
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--outdir", default=HERE)
    parser.add_argument("--only", nargs="*", choices=sorted(SCENES))
    parser.add_argument("--resolution", type=int, nargs=2, default=DEFAULT_RES)
    args = parser.parse_args(argv)
    os.makedirs(args.outdir, exist_ok=True)
    for name in args.only or SCENES:
        path = make(name, args.outdir, tuple(args.resolution))
        print(f"wrote {path} ({os.path.getsize(path) / 1024:.0f} KiB)")


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    if bpy.app.background and "--" not in sys.argv and any(a.endswith("make_samples.py") for a in argv[:1]):
        argv = argv[1:]
    main(argv)
