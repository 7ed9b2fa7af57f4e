"""Exporter: the tracer Scene built from Blender data has the right numbers."""
import math

import bmesh
import bpy
import numpy as np
import pytest

from tests.addon.exporting import export
from mcrt_addon.export.camera import pixel_directions
from mcrt_addon.export.util import ExportError


# ------------------------------------------------------------------------------------------ camera
def test_camera_values_from_sample(samples, addon):
    bpy.ops.wm.open_mainfile(filepath=samples["cornell"])
    cam = export((128, 128)).scene.camera
    assert cam.lens == pytest.approx(50.0) and cam.sensor_width == pytest.approx(36.0)
    assert cam.sensor_fit == "AUTO"
    m = np.asarray(cam.matrix)
    np.testing.assert_allclose(m[:3, 3], [0, -3.9, 1], atol=1e-6)
    np.testing.assert_allclose(-m[:3, 2], [0, 1, 0], atol=1e-6)      # looks down local -Z = +Y
    np.testing.assert_allclose(m[:3, 1], [0, 0, 1], atol=1e-6)       # up
    np.testing.assert_allclose(m[:3, :3].T @ m[:3, :3], np.eye(3), atol=1e-9)


def blender_pixel_centres(cam_obj, width, height):
    """Where Blender's own projection (calc_matrix_camera) puts our pixel-centre directions."""
    dg = bpy.context.evaluated_depsgraph_get()
    proj = np.array(cam_obj.calc_matrix_camera(dg, x=width, y=height))
    return proj


@pytest.mark.parametrize("res,fit,shift", [((40, 24), "AUTO", (0.0, 0.0)), ((24, 40), "AUTO", (0.1, -0.05)),
                                           ((40, 24), "VERTICAL", (0.0, 0.2)),
                                           ((30, 30), "HORIZONTAL", (-0.15, 0.0))])
def test_camera_matches_blender_projection(scene, res, fit, shift):
    cam_obj = scene.camera
    cam_obj.data.sensor_fit = fit
    cam_obj.data.sensor_height = 20.0
    cam_obj.data.shift_x, cam_obj.data.shift_y = shift
    cam_obj.data.lens = 35.0
    cam_obj.scale = (2.0, 2.0, 2.0)                     # scale must not change the rays
    scene.render.resolution_x, scene.render.resolution_y = res
    bpy.context.view_layer.update()
    cam = export(res).scene.camera
    d = pixel_directions(cam, *res)                      # (H, W, 3) world
    proj = blender_pixel_centres(cam_obj, *res)
    view = np.linalg.inv(np.array(cam_obj.matrix_world.normalized()))
    p = np.concatenate([d * 5.0 + np.asarray(cam.matrix)[:3, 3], np.ones(d.shape[:2] + (1,))], axis=-1)
    clip = p @ (proj @ view).T
    ndc = clip[..., :2] / clip[..., 3:4]
    px = (ndc[..., 0] + 1) / 2 * res[0]
    py = (1 - (ndc[..., 1] + 1) / 2) * res[1]            # from the top
    xs, ys = np.meshgrid(np.arange(res[0]) + 0.5, np.arange(res[1]) + 0.5)
    np.testing.assert_allclose(px, xs, atol=1e-3)
    np.testing.assert_allclose(py, ys, atol=1e-3)
    # the tracer's own camera model agrees with this reference
    from mcrt_addon import bridge
    camera_rays = bridge.module("scene.camera_rays").camera_rays
    _, dirs = camera_rays(cam, res[0], res[1], xs.ravel(), ys.ravel())
    np.testing.assert_allclose(dirs.T.reshape(d.shape), d, atol=1e-9)


@pytest.mark.parametrize("crop", [(5, 3, 20, 11), (0, 0, 10, 24), (13, 7, 40, 24)])
def test_border_crop_camera_sees_the_same_pixels(scene, crop):
    cam_obj = scene.camera
    cam_obj.data.shift_x, cam_obj.data.shift_y = 0.07, -0.03
    res = (40, 24)
    full = export(res).scene.camera
    cropped = export(res, crop=crop)
    assert cropped.scene.resolution == (crop[2] - crop[0], crop[3] - crop[1])
    d_full = pixel_directions(full, *res)
    d_crop = pixel_directions(cropped.scene.camera, *cropped.scene.resolution)
    x0, y0, x1, y1 = crop                       # y from the bottom; rows of d_* from the top
    np.testing.assert_allclose(d_crop, d_full[res[1] - y1:res[1] - y0, x0:x1], atol=1e-9)


def test_no_camera_and_ortho_camera_are_errors(empty_scene, scene):
    scene.camera.data.type = "ORTHO"
    with pytest.raises(ExportError, match="Camera 'Camera': only perspective"):
        export()
    scene.camera = None
    with pytest.raises(ExportError, match="no active camera"):
        export()


# ----------------------------------------------------------------------------------------- spheres
def add(ms, scene, name, build, mat=None, **kw):
    return ms.mesh_object(scene, name, build, mat, **kw)


def test_uv_sphere_becomes_implicit_sphere(scene, ms):
    ob = add(ms, scene, "Ball", lambda bm: ms.uv_sphere(bm, 0.5, 32, 16), ms.diffuse("D", (0.5, 0.5, 0.5)),
             location=(1, 2, 3), scale=(2, 2, 2), rotation=(0.3, 0.2, 0.1))
    sc = export().scene
    assert len(sc.spheres) == 1 and not sc.meshes
    s = sc.spheres[0]
    assert s.name == "Ball"
    np.testing.assert_allclose(s.center, [1, 2, 3], atol=1e-6)
    assert s.radius == pytest.approx(1.0, rel=1e-5)
    assert sc.materials[s.material_id].name == "D"
    ob.tncg15.implicit_sphere = "NEVER"
    sc = export().scene
    assert not sc.spheres and len(sc.meshes) == 1


def test_icosphere_also_detected(scene, ms):
    add(ms, scene, "Ico", lambda bm: bmesh.ops.create_icosphere(bm, subdivisions=3, radius=0.7))
    sc = export().scene
    assert len(sc.spheres) == 1 and sc.spheres[0].radius == pytest.approx(0.7, rel=1e-5)


@pytest.mark.parametrize("case", ["cube", "nonuniform", "hemisphere", "lowpoly", "two_materials"])
def test_non_spheres_stay_meshes(scene, ms, case):
    if case == "cube":
        add(ms, scene, "X", lambda bm: ms.cube(bm, 1.0))
    elif case == "nonuniform":
        add(ms, scene, "X", lambda bm: ms.uv_sphere(bm, 0.5), scale=(1, 1, 1.5))
    elif case == "hemisphere":
        def half(bm):
            ms.uv_sphere(bm, 0.5)
            bmesh.ops.delete(bm, geom=[v for v in bm.verts if v.co.z < -1e-6], context="VERTS")
        add(ms, scene, "X", half)
    elif case == "lowpoly":
        add(ms, scene, "X", lambda bm: ms.uv_sphere(bm, 0.5, 6, 4))
    else:
        ob = add(ms, scene, "X", lambda bm: ms.uv_sphere(bm, 0.5), ms.diffuse("A", (1, 0, 0)))
        ob.data.materials.append(ms.diffuse("B", (0, 1, 0)))
        ob.data.polygons[0].material_index = 1
    sc = export().scene
    assert not sc.spheres and len(sc.meshes) == 1, case


def test_always_makes_bounding_sphere(scene, ms):
    ob = add(ms, scene, "Box", lambda bm: ms.cube(bm, 2.0), location=(0, 0, 1))
    ob.tncg15.implicit_sphere = "ALWAYS"
    sc = export().scene
    assert len(sc.spheres) == 1
    assert sc.spheres[0].radius == pytest.approx(math.sqrt(3), rel=1e-6)
    np.testing.assert_allclose(sc.spheres[0].center, [0, 0, 1], atol=1e-6)


# --------------------------------------------------------------------------------------- materials
def material_of(sc, name):
    return next(m for m in sc.materials if m.name == name)


def test_material_mapping(scene, ms):
    mats = [ms.diffuse("Diff", (0.2, 0.4, 0.6)), ms.mirror("Mir", (0.9, 0.8, 0.7)),
            ms.glass("Gla", (1, 1, 0.9), ior=1.33), ms.emission("Emi", (1.0, 0.5, 0.25), 4.0),
            ms.principled("PMetal", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.0),
            ms.principled("PGlass", (1, 1, 1), roughness=0.0, transmission=1.0, ior=1.45),
            ms.principled("PDiff", (0.3, 0.3, 0.3)),
            ms.principled("PEmit", (0, 0, 0), emission_rgb=(1.0, 0.8, 0.6), emission_strength=5.0)]
    for k, mat in enumerate(mats):
        add(ms, scene, f"O{k}", lambda bm: ms.quad(bm, [(0, 0, k), (1, 0, k), (1, 1, k), (0, 1, k)]), mat)
    res = export()
    sc = res.scene
    d = material_of(sc, "Diff")
    assert d.kind == "diffuse" and d.color == pytest.approx((0.2, 0.4, 0.6)) and max(d.emission) == 0
    m = material_of(sc, "Mir")
    assert m.kind == "mirror" and m.color == pytest.approx((0.9, 0.8, 0.7))
    g = material_of(sc, "Gla")
    assert g.kind == "glass" and g.ior == pytest.approx(1.33) and g.color == pytest.approx((1, 1, 0.9))
    e = material_of(sc, "Emi")
    assert e.kind == "diffuse" and e.color == (0, 0, 0) and e.emission == pytest.approx((4.0, 2.0, 1.0))
    pm = material_of(sc, "PMetal")        # Blender 4.0+: the principled kind (test_export_materials.py)
    assert pm.kind == "principled" and pm.principled.metallic == 1.0 and pm.roughness == 0.0
    pg = material_of(sc, "PGlass")        # 4.0+: the Principled's own glass closure (principled_glass.py)
    assert pg.kind == "principled" and pg.ior == pytest.approx(1.45)
    pd = material_of(sc, "PDiff")
    assert pd.kind == "principled" and pd.color == pytest.approx((0.3, 0.3, 0.3))
    assert pd.principled.metallic == 0.0 and pd.principled.specular_ior_level == 0.0
    pe = material_of(sc, "PEmit")
    assert pe.emission == pytest.approx((5.0, 4.0, 3.0)) and pe.color == pytest.approx((0, 0, 0))
    assert res.warnings == [], res.warnings        # Specular IOR Level 0 in the samples: nothing to warn


def test_unsupported_node_warns_and_becomes_diffuse(scene, ms):
    mat = ms.node_material("Toony", "ShaderNodeBsdfToon")
    add(ms, scene, "T", lambda bm: ms.quad(bm, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]), mat)
    res = export()
    t = material_of(res.scene, "Toony")
    assert t.kind == "diffuse"
    assert any("Material 'Toony'" in w and "ShaderNodeBsdfToon" in w for w in res.warnings), res.warnings


def test_object_without_material_is_cycles_default_grey(scene, ms):
    add(ms, scene, "Bare", lambda bm: ms.quad(bm, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]))
    sc = export().scene
    assert sc.materials[sc.meshes[0].material_ids[0]].color == pytest.approx((0.8, 0.8, 0.8))


def test_per_face_material_slots(scene, ms):
    ob = add(ms, scene, "TwoMat", lambda bm: ms.cube(bm, 1.0), ms.diffuse("A", (1, 0, 0)))
    ob.data.materials.append(ms.diffuse("B", (0, 1, 0)))
    ob.data.polygons[2].material_index = 1
    sc = export().scene
    ids = sc.meshes[0].material_ids
    names = [sc.materials[i].name for i in ids]
    assert names.count("B") == 2 and names.count("A") == 10     # one quad = two triangles


# ---------------------------------------------------------------------------------- lights, world
def test_area_light_radiance(scene):
    light = bpy.data.lights.new("L", "AREA")
    light.shape, light.size, light.size_y = "RECTANGLE", 2.0, 1.0
    light.energy, light.color = 100.0, (1.0, 0.5, 0.25)
    ob = bpy.data.objects.new("L", light)
    ob.scale = (2.0, 1.0, 1.0)
    scene.collection.objects.link(ob)
    res = export()
    assert res.scene.meshes == []                    # light-only: not geometry
    lamp = res.scene.lights[0]
    area = 4.0
    expected = 100.0 / (math.pi * area)            # Blender >= 4.0 (this test runs in 5.0)
    assert lamp.radiance == pytest.approx((expected, expected * 0.5, expected * 0.25))
    assert not lamp.two_sided                        # Cycles' area lights emit from the front only
    v = lamp.triangles()
    got_area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1).sum()
    assert got_area == pytest.approx(area)
    n = np.cross(v[0, 1] - v[0, 0], v[0, 2] - v[0, 0])
    assert n[2] < 0                                  # front face points down (-Z), like the lamp
    light.exposure = 1.0
    again = export().scene
    assert again.lights[0].radiance[0] == pytest.approx(2 * expected)
    light.exposure, light.shape, light.size = 0.0, "DISK", 1.0
    assert export().scene.lights[0].radiance[0] == pytest.approx(100.0 / (math.pi * math.pi * 0.25 * 2.0))


def test_area_light_radiance_34_convention():
    from mcrt_addon.export.lights import area_light_radiance

    class L:
        energy, color, exposure = 10.0, (1.0, 1.0, 1.0), 0.0
    assert area_light_radiance(L, 2.0, (3, 4, 1))[0] == pytest.approx(10.0 / (4 * 2.0))
    assert area_light_radiance(L, 2.0, (4, 0, 0))[0] == pytest.approx(10.0 / (math.pi * 2.0))


def _area_light(scene, name="Lamp"):
    ob = bpy.data.objects.new(name, bpy.data.lights.new(name, "AREA"))
    ob.location = (0.0, 0.0, 1.9)
    scene.collection.objects.link(ob)
    return ob


FLAGS = ("visible_camera", "visible_diffuse", "visible_glossy", "visible_transmission")


def test_area_light_visibility_defaults_are_cycles_defaults(scene, ms):
    """Cycles (5.0.1 and 3.4.1, measured): a new area light is not seen by camera rays, but is seen
    in mirrors and through glass, and lights diffuse surfaces; no warning about it."""
    _area_light(scene)
    ms.mesh_object(scene, "Ball", lambda bm: ms.uv_sphere(bm, 0.3), ms.mirror("M", (0.9, 0.9, 0.9)))
    res = export()
    lamp = res.scene.lights[0]
    assert [getattr(lamp, f) for f in FLAGS] == [False, True, True, True]
    assert not any("Lamp" in w or "area light" in w for w in res.warnings), res.warnings


@pytest.mark.parametrize("what,value,expected", [
    ("visible_camera", True, [True, True, True, True]),
    ("visible_diffuse", False, [False, False, True, True]),
    ("visible_glossy", False, [False, True, False, True]),
    ("visible_transmission", False, [False, True, True, False]),
    ("mis", False, [False, False, False, False]),       # MIS off: no ray kind reaches the lamp
])
def test_area_light_visibility_toggled(scene, what, value, expected):
    ob = _area_light(scene)
    if what == "mis":
        ob.visible_camera = True                        # even then: Cycles shows nothing without MIS
        ob.data.cycles.use_multiple_importance_sampling = value
    else:
        setattr(ob, what, value)
    res = export()
    lamp = res.scene.lights[0]
    assert [getattr(lamp, f) for f in FLAGS] == expected
    assert max(lamp.radiance) > 0
    # Diffuse visibility off: as in Cycles it lights no diffuse surface; MIS off still does.
    assert lamp.lights_diffuse == (what != "visible_diffuse")


def test_area_light_portal_emits_nothing(scene):
    ob = _area_light(scene)
    ob.data.cycles.is_portal = True
    res = export()
    lamp = res.scene.lights[0]
    assert tuple(lamp.radiance) == (0.0, 0.0, 0.0)
    assert not any(getattr(lamp, f) for f in FLAGS)
    assert any("Light 'Lamp'" in w and "portal" in w for w in res.warnings)


def test_area_light_visibility_pre_30_cycles_visibility():
    """Blender < 3.0 kept the flags in Object.cycles_visibility."""
    from types import SimpleNamespace as NS
    from mcrt_addon.export.lights import area_light_visibility
    ob = NS(data=NS(cycles=NS(use_multiple_importance_sampling=True)),
            cycles_visibility=NS(camera=True, diffuse=True, glossy=False, transmission=True))
    assert area_light_visibility(ob) == dict(lights_diffuse=True, visible_camera=True, visible_diffuse=True,
                                             visible_glossy=False, visible_transmission=True)


def test_point_and_sun_lights_are_exported_in_cycles_units(scene):
    import math
    bulb = bpy.data.lights.new("Bulb", "POINT")
    bulb.energy, bulb.color, bulb.shadow_soft_size = 100.0, (1.0, 0.5, 0.25), 0.2
    ob = bpy.data.objects.new("Bulb", bulb)
    ob.location = (1.0, 2.0, 3.0)
    scene.collection.objects.link(ob)
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy, sun.angle = 3.0, 0.5
    sob = bpy.data.objects.new("Sun", sun)
    sob.rotation_euler = (math.radians(90), 0, 0)          # local -Z points along +Y
    scene.collection.objects.link(sob)
    spot_light = bpy.data.lights.new("Spot", "SPOT")
    spot_light.spot_size, spot_light.spot_blend = math.radians(50), 0.25
    spot = bpy.data.objects.new("Spot", spot_light)
    spot.rotation_euler = (math.radians(90), 0, 0)         # the cone along +Y
    spot.visible_glossy = False                             # Object > Visibility > Ray Visibility
    scene.collection.objects.link(spot)
    res = export()
    point = next(p for p in res.scene.points if p.name == "Bulb")
    assert not point.is_spot
    assert point.position == pytest.approx((1.0, 2.0, 3.0)) and point.radius == pytest.approx(0.2)
    assert point.intensity == pytest.approx((100 / (4 * math.pi), 50 / (4 * math.pi), 25 / (4 * math.pi)))
    s = res.scene.suns[0]
    assert s.direction == pytest.approx((0.0, 1.0, 0.0), abs=1e-6) and s.angle == pytest.approx(0.5)
    assert not s.sky_disc                                   # a sun lamp, not a Sky Texture's disc
    factor = 1.0 if bpy.app.version >= (4, 0, 0) else 0.5 * (1 + math.cos(0.25))
    assert s.irradiance == pytest.approx((3.0 * factor,) * 3)
    cone = next(p for p in res.scene.points if p.name == "Spot")
    assert cone.spot_size == pytest.approx(math.radians(50)) and cone.spot_blend == pytest.approx(0.25)
    assert cone.spot_direction == pytest.approx((0.0, 1.0, 0.0), abs=1e-6)
    assert cone.spot_falloff == ("smoothstep" if bpy.app.version >= (4, 0, 0) else "cosine-smoothstep")
    assert (cone.visible_glossy, cone.visible_transmission, cone.lights_diffuse) == (False, True, True)
    assert (point.visible_glossy, s.visible_glossy) == (True, True)
    assert not res.warnings


def test_world_background(scene, ms):
    assert export().scene.background == (0, 0, 0)       # no world: black, as Cycles
    ms.black_world(scene)
    bg = scene.world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.5, 0.25, 1.0, 1.0)
    bg.inputs["Strength"].default_value = 2.0
    assert export().scene.background == pytest.approx((1.0, 0.5, 2.0))


# ------------------------------------------------------------------------------ instances, winding
def test_instances_share_mesh_data(scene, ms):
    src = add(ms, scene, "Src", lambda bm: ms.cube(bm, 1.0))
    coll = bpy.data.collections.new("Inst")
    scene.collection.children.link(coll)
    scene.collection.objects.unlink(src)
    coll.objects.link(src)
    coll.hide_render = False
    for k in range(3):
        empty = bpy.data.objects.new(f"E{k}", None)
        empty.instance_type = "COLLECTION"
        empty.instance_collection = coll
        empty.location = (3 * (k + 1), 0, 0)
        scene.collection.objects.link(empty)
    linked = bpy.data.objects.new("Linked", src.data)       # linked duplicate
    linked.location = (0, 5, 0)
    scene.collection.objects.link(linked)
    res = export()
    meshes = res.scene.meshes
    assert len(meshes) == 5                                  # source + 3 instances + linked duplicate
    assert res.info["meshes_shared"] == 1
    assert all(np.shares_memory(m.triangles, meshes[0].triangles) for m in meshes)
    xs = sorted(round(float(m.vertices[:, 0].mean()), 6) for m in meshes)
    assert xs == [0, 0, 3, 6, 9]


def test_negative_scale_flips_winding(scene, ms):
    ob = add(ms, scene, "P", lambda bm: ms.quad(bm, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]))
    n_before = normals(export().scene.meshes[0])
    ob.scale = (-1, 1, 1)
    n_after = normals(export().scene.meshes[0])
    np.testing.assert_allclose(n_before, n_after, atol=1e-9)   # still facing +Z after mirroring


def normals(mesh):
    v = mesh.vertices[mesh.triangles]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def test_animation_uses_frame_transforms(scene, ms):
    ob = add(ms, scene, "Mover", lambda bm: ms.cube(bm, 1.0))
    ob.location = (0, 0, 0)
    ob.keyframe_insert("location", frame=1)
    ob.location = (2, 0, 0)
    ob.keyframe_insert("location", frame=2)
    scene.frame_set(1)
    x1 = export().scene.meshes[0].vertices[:, 0].mean()
    scene.frame_set(2)
    x2 = export().scene.meshes[0].vertices[:, 0].mean()
    assert x1 == pytest.approx(0.0, abs=1e-6) and x2 == pytest.approx(2.0, abs=1e-6)


def test_modifiers_are_evaluated_and_user_data_untouched(samples, addon):
    bpy.ops.wm.open_mainfile(filepath=samples["suzanne_100k"])
    me = bpy.data.objects["Suzanne"].data
    before = (len(me.vertices), len(me.polygons), me.vertices[0].co.copy())
    res = export()
    suzanne = next(m for m in res.scene.meshes if m.name == "Suzanne")
    assert 80_000 < len(suzanne.triangles) < 110_000
    assert (len(me.vertices), len(me.polygons), me.vertices[0].co) == before


def test_zero_area_emitter_is_an_error_naming_the_object(scene, ms):
    add(ms, scene, "Lamp", lambda bm: ms.quad(bm, [(0, 0, 1), (1, 0, 1), (2, 0, 1), (3, 0, 1)]),
        ms.emission("E", (1, 1, 1), 5.0))
    with pytest.raises(ExportError, match="Object 'Lamp': emitter has zero area"):
        export()


@pytest.mark.parametrize("feature, expected", [
    ("holdout", "Object 'Q': holdout is not supported"),
    ("camera_ray", "Object 'Q': ray visibility is not supported (camera off)"),
    ("shadow_ray", "Object 'Q': ray visibility is not supported (shadow off)"),
    ("holdout_collection", "Collection 'Held': holdout is not supported"),
    ("motion_blur", "Motion blur is not rendered"),
    ("film_transparent_glass", "Film > Transparent Glass is not supported"),
    ("subsurface", "Material 'Skin', node 'Principled BSDF': input 'Subsurface Weight' 0.5 is rendered as diffuse"),
    ("transparent_bsdf", "Material 'Glassless', node 'Transparent BSDF': transparent shadows are not modelled"),
    ("holdout_node", "Material 'Hole', node 'Holdout': ShaderNodeHoldout is not supported"),
])
def test_unmodelled_blender_features_are_named_in_a_warning(scene, ms, feature, expected):
    mat = {"subsurface": lambda: ms.node_material("Skin", "ShaderNodeBsdfPrincipled", **{"Subsurface Weight": 0.5}),
           "transparent_bsdf": lambda: ms.node_material("Glassless", "ShaderNodeBsdfTransparent"),
           "holdout_node": lambda: ms.node_material("Hole", "ShaderNodeHoldout")}.get(feature, lambda: None)()
    ob = add(ms, scene, "Q", lambda bm: ms.quad(bm, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]), mat)
    if mat is None:                      # the plain quad exports without any of these warnings
        assert not any("not supported" in w or "not rendered" in w for w in export().warnings)
    if feature == "holdout":
        ob.is_holdout = True
    elif feature == "camera_ray":
        ob.visible_camera = False
    elif feature == "shadow_ray":
        ob.visible_shadow = False
    elif feature == "holdout_collection":
        scene.collection.children.link(bpy.data.collections.new("Held"))
        bpy.context.view_layer.layer_collection.children["Held"].holdout = True
    elif feature == "motion_blur":
        scene.render.use_motion_blur = True
    elif feature == "film_transparent_glass":
        scene.render.film_transparent = True
        scene.cycles.film_transparent_glass = True
    warnings = export().warnings
    assert any(expected in w for w in warnings), warnings


# ----------------------------------------------------------------------------------- smooth shading
def ellipsoid_normals(points, centre, radii):
    """True outward normals of the ellipsoid ((p - c) / r)^2 = 1 at `points`."""
    g = (points - centre) / np.asarray(radii) ** 2
    return g / np.linalg.norm(g, axis=-1, keepdims=True)


@pytest.mark.parametrize("scale", [(1.0, 1.0, 1.0), (2.0, 1.0, 0.5), (-1.5, 1.0, 1.0)])
def test_smooth_mesh_exports_world_space_corner_normals(scene, ms, scale):
    """A Shade Smooth UV sphere (as a mesh: implicit spheres off) under a rotation and a uniform,
    non-uniform or mirroring scale: the exported corner normals are the world-space normals of the
    ellipsoid (inverse transpose), in the corners' order after a mirror flips the winding, and on
    the outside (same side as the geometric normal)."""
    ob = add(ms, scene, "Ball", lambda bm: ms.uv_sphere(bm, 1.0, 48, 24), location=(1, 2, 3), scale=scale,
             rotation=(0.3, 0.2, 0.1), smooth=True)
    ob.tncg15.implicit_sphere = "NEVER"
    mesh = export().scene.meshes[0]
    assert mesh.normals is not None and mesh.normals.shape == (len(mesh.triangles), 3, 3) and mesh.smooth is None
    corners = mesh.vertices[mesh.triangles]                                   # (T, 3, 3) world positions
    m = np.array(ob.matrix_world)
    local = (corners - m[:3, 3]) @ np.linalg.inv(m[:3, :3]).T
    world_true = ellipsoid_normals(local, 0, 1) @ np.linalg.inv(m[:3, :3])   # n^T M^-1
    world_true /= np.linalg.norm(world_true, axis=-1, keepdims=True)
    n = mesh.normals / np.linalg.norm(mesh.normals, axis=-1, keepdims=True)
    assert np.einsum("tki,tki->tk", n, world_true).min() > 0.9999
    assert (np.einsum("tki,ti->tk", n, normals(mesh)) > 0).all()


def test_flat_mesh_exports_no_normals_and_mixed_mesh_flags_its_smooth_faces(scene, ms):
    ob = add(ms, scene, "Box", lambda bm: ms.cube(bm, 1.0))
    assert export().scene.meshes[0].normals is None
    ob.data.polygons[0].use_smooth = True                                     # 1 of 6 faces
    mesh = export().scene.meshes[0]
    assert mesh.normals is not None and mesh.smooth is not None and int(mesh.smooth.sum()) == 2
    assert export().warnings == []                                            # no "not supported" warning


def test_custom_split_normals_are_exported(scene, ms):
    """Custom normals (Blender's per-corner normals) reach the scene: a quad whose corners all
    point along (1, 0, 1)."""
    ob = add(ms, scene, "Plane", lambda bm: ms.quad(bm, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]), smooth=True)
    if hasattr(ob.data, "use_auto_smooth"):
        ob.data.use_auto_smooth = True                                        # Blender < 4.1
    target = np.array([1.0, 0.0, 1.0]) / np.sqrt(2)
    ob.data.normals_split_custom_set([tuple(target)] * len(ob.data.loops))
    mesh = export().scene.meshes[0]
    n = mesh.normals.reshape(-1, 3)
    np.testing.assert_allclose(n / np.linalg.norm(n, axis=1, keepdims=True), np.tile(target, (len(n), 1)), atol=1e-3)


def test_shadow_terminator_offsets_are_exported_and_the_rest_named(scene, ms):
    ob = add(ms, scene, "Ball", lambda bm: ms.uv_sphere(bm, 1.0, 12, 6), smooth=True)
    ob.shadow_terminator_geometry_offset = 0.4
    result = export()
    assert result.scene.meshes[0].terminator_offset == pytest.approx(0.4)
    assert not any("terminator" in w for w in result.warnings)
    ob.shadow_terminator_shading_offset = 0.2
    assert any("Object 'Ball': shadow terminator shading offset" in w for w in export().warnings)
