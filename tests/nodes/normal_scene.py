"""A lit scene for the Normal Map and Bump agreement tests (tests/nodes/test_agreement_normals.py),
built in the running bpy: a smooth UV sphere whose Diffuse BSDF's Normal comes from a Normal Map
(tangent space, its UV map) of a colour (x, x, 1), x a Wave Texture's Fac mapped into [0.25, 0.75], on a floor whose Principled BSDF's Normal
comes from a Bump of a Noise Texture, under a sun, seen by a perspective camera."""
import math


def _material(name):
    import bpy
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    for n in list(nodes):
        if n.bl_idname != "ShaderNodeOutputMaterial":
            nodes.remove(n)
    return mat, nodes, mat.node_tree.links, nodes["Material Output"]


def build(path, resolution=(64, 64), normal_map=True, bump=True, facing_away=False):
    """The scene saved as `path`; facing_away: the Wave Texture's colour itself into the Normal Map
    (its dark bands give normals pointing into the ball: Cycles' handling of normals facing away)."""
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.05, 0.05, 0.05, 1.0)
    scene.world = world

    # The ball: Wave colour -> Normal Map (tangent) -> Diffuse Normal.
    bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=1.0, location=(0.0, 0.0, 1.0))
    ball = bpy.context.object
    bpy.ops.object.shade_smooth()
    mat, nodes, links, out = _material("NormalBall")
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    links.new(bsdf.outputs[0], out.inputs["Surface"])
    if normal_map:
        wave = nodes.new("ShaderNodeTexWave")
        wave.inputs["Scale"].default_value = 2.0
        wave.inputs["Distortion"].default_value = 3.0
        coord = nodes.new("ShaderNodeTexCoord")
        links.new(coord.outputs["UV"], wave.inputs["Vector"])
        tilt = nodes.new("ShaderNodeMapRange")          # the wave's Fac into [0.25, 0.75]: tilts up to 27 deg
        tilt.inputs["To Min"].default_value, tilt.inputs["To Max"].default_value = 0.25, 0.75
        links.new(wave.outputs["Fac"], tilt.inputs["Value"])
        colour = nodes.new("ShaderNodeCombineXYZ")
        links.new(tilt.outputs["Result"], colour.inputs["X"])
        links.new(tilt.outputs["Result"], colour.inputs["Y"])
        colour.inputs["Z"].default_value = 1.0
        nmap = nodes.new("ShaderNodeNormalMap")
        nmap.inputs["Strength"].default_value = 1.0
        links.new((wave.outputs["Color"] if facing_away else colour.outputs["Vector"]), nmap.inputs["Color"])
        links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    ball.data.materials.append(mat)

    # The floor: Noise -> Bump -> Principled Normal.
    bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0.0, 0.0, 0.0))
    floor = bpy.context.object
    mat, nodes, links, out = _material("BumpFloor")
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (0.6, 0.5, 0.4, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.5
    links.new(bsdf.outputs[0], out.inputs["Surface"])
    if bump:
        noise = nodes.new("ShaderNodeTexNoise")
        noise.inputs["Scale"].default_value = 1.5
        noise.inputs["Detail"].default_value = 1.0
        bmp = nodes.new("ShaderNodeBump")
        bmp.inputs["Distance"].default_value = 1.0
        bmp.inputs["Strength"].default_value = 1.0
        links.new(noise.outputs["Fac"], bmp.inputs["Height"])
        links.new(bmp.outputs["Normal"], bsdf.inputs["Normal"])
    floor.data.materials.append(mat)

    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 3.0
    sun.angle = math.radians(5.0)
    sun_ob = bpy.data.objects.new("Sun", sun)
    sun_ob.rotation_euler = (math.radians(50.0), 0.0, math.radians(40.0))
    scene.collection.objects.link(sun_ob)

    cam = bpy.data.cameras.new("Camera")
    cam_ob = bpy.data.objects.new("Camera", cam)
    scene.collection.objects.link(cam_ob)
    cam_ob.location = (0.0, -5.0, 3.0)
    cam_ob.rotation_euler = (math.radians(62.0), 0.0, 0.0)
    scene.camera = cam_ob
    bpy.ops.wm.save_as_mainfile(filepath=path)
    return path
