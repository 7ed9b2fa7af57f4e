"""The world exporter (mcrt_addon/export/world.py) on the node patterns it reads, in bpy 5.0 (fast:
no render; the renders are tests/addon/test_agreement_world.py): an Environment Texture through a
Mapping node, Light Path "Is Camera Ray" between an image and a colour (either way round) or between
two strengths of one image, and the warnings (naming world and node) for what it does not read,
each falling back to the constant colour."""
import math

import numpy as np
import bpy
import pytest

from mcrt_addon import bridge
from mcrt_addon.export.images import ImageTable
from mcrt_addon.export.world import export_world


def world_with(ms, scene, image, rotation_z=0.0):
    ms.environment_world(scene, image, 2.0, rotation_z)
    return scene.world


def export(world):
    warnings = []
    images = ImageTable(bridge.module("scene.textures"), warnings)
    colour, env = export_world(world, warnings, images, bridge.scene_module().Environment)
    return colour, env, warnings, images


@pytest.fixture
def sky(empty_scene):
    img = bpy.data.images.new("sky", 8, 4, float_buffer=True)
    img.pixels.foreach_set([0.5] * (8 * 4 * 4))
    img.pack()
    return img


def camera_mix(world, camera_node_first=False):
    """Mix Shader(Is Camera Ray, the world's Background, a grey Background) -> output."""
    tree = world.node_tree
    bg = next(n for n in tree.nodes if n.type == "BACKGROUND")
    grey = tree.nodes.new("ShaderNodeBackground")
    grey.inputs["Color"].default_value = (0.2, 0.3, 0.4, 1.0)
    mix, path = tree.nodes.new("ShaderNodeMixShader"), tree.nodes.new("ShaderNodeLightPath")
    tree.links.new(path.outputs["Is Camera Ray"], mix.inputs[0])
    first, second = (grey, bg) if camera_node_first else (bg, grey)
    tree.links.new(first.outputs[0], mix.inputs[1])
    tree.links.new(second.outputs[0], mix.inputs[2])
    out = next(n for n in tree.nodes if n.type == "OUTPUT_WORLD")
    tree.links.new(mix.outputs[0], out.inputs["Surface"])
    return grey


def test_environment_texture_through_mapping(empty_scene, ms, sky):
    colour, env, warnings, images = export(world_with(ms, empty_scene, sky, math.radians(90)))
    assert warnings == [] and env.strength == 2.0 and env.projection == "equirectangular"
    assert env.matrix[0] == pytest.approx((0.0, -1.0, 0.0), abs=1e-7)
    assert images.textures[env.texture].is_float and env.camera_color is None and env.lighting


def test_camera_ray_mixes(empty_scene, ms, sky):
    world = world_with(ms, empty_scene, sky)
    camera_mix(world)
    _, env, warnings, _ = export(world)
    assert warnings == [] and env.lighting and env.camera_color == pytest.approx((0.2, 0.3, 0.4))
    world = world_with(ms, empty_scene, sky)
    camera_mix(world, camera_node_first=True)
    colour, env, warnings, _ = export(world)
    assert warnings == [] and not env.lighting and colour == pytest.approx((0.2, 0.3, 0.4))


def test_unsupported_worlds_warn_and_fall_back(empty_scene, ms, sky):
    world = world_with(ms, empty_scene, sky)
    tree = world.node_tree
    env = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeTexEnvironment")
    noise = tree.nodes.new("ShaderNodeTexNoise")
    tree.links.new(noise.outputs["Color"], env.inputs["Vector"])
    _, exported, warnings, _ = export(world)
    assert exported is not None and len(warnings) == 1 and "World 'World'" in warnings[0] and env.name in warnings[0]
    bg = next(n for n in tree.nodes if n.type == "BACKGROUND")
    sky_node = tree.nodes.new("ShaderNodeTexSky")
    sky_node.sky_type = "HOSEK_WILKIE"         # not ported (engine/lights/sky.py)
    tree.links.new(sky_node.outputs["Color"], bg.inputs["Color"])
    colour, exported, warnings, _ = export(world)
    assert exported is None and colour == pytest.approx((0.0, 0.0, 0.0)) and sky_node.name in warnings[0]
    assert "World 'World'" in warnings[0] and "HOSEK_WILKIE" in warnings[0]


def test_a_sky_is_baked_once_per_parameter_set(empty_scene, monkeypatch):
    """The viewport exports the world after every edit: the same Sky Texture is not baked again,
    another turbidity is (mcrt_addon/export/world.py _SKY_BAKES)."""
    import mcrt_addon.export.world as world_export
    sky = bridge.module("lights.sky")
    bakes = []

    class Counted(sky.PreethamSky):
        def bake(self, width=2048, height=1024):
            bakes.append(self.turbidity if hasattr(self, "turbidity") else None)
            return super().bake(16, 8)

    monkeypatch.setattr(sky, "PreethamSky", Counted)
    monkeypatch.setattr(world_export, "_SKY_BAKES", {})
    world = bpy.data.worlds.new("sky world")
    empty_scene.world = world
    world.use_nodes = True
    tree = world.node_tree
    node = tree.nodes.new("ShaderNodeTexSky")
    node.sky_type = "PREETHAM"
    bg = next(n for n in tree.nodes if n.type == "BACKGROUND")
    tree.links.new(node.outputs["Color"], bg.inputs["Color"])
    first, second = export(world), export(world)
    assert len(bakes) == 1 and first[1] is not None and second[1] is not None
    assert np.array_equal(first[3].textures[first[1].texture].pixels, second[3].textures[second[1].texture].pixels)
    node.turbidity = 3.0
    export(world)
    assert len(bakes) == 2                                     # control: another sky is baked
