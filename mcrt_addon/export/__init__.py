"""Evaluated depsgraph -> tracer Scene.

One job per module: camera.py, mesh.py, materials.py, lights.py, world.py; this module walks
``depsgraph.object_instances`` (render-visible objects, instances from particles / geometry nodes /
collection instances) and assembles the Scene.  Nothing here writes to the user's data.
"""
import time
from dataclasses import dataclass, field

import bpy
import numpy as np

from .. import bridge
from .camera import export_camera
from .images import ImageTable
from .lights import export_area_light, export_point_light, export_sun_light
from .materials import MaterialTable
from .mesh import (bounding_sphere, corner_bitangent_signs, corner_colors, corner_tangents, corner_uvs, mesh_arrays, mesh_normals, sphere_fit,
                   terminator_offsets, transform_normals, transform_points, uniform_scale)
from .node_graph import attribute_names
from .unsupported import object_warnings, scene_warnings
from .util import ExportError
from .world import export_world

CONVERTIBLE_TYPES = {"CURVE", "SURFACE", "META", "FONT"}     # converted with to_mesh()
SKIPPED_TYPES = {"CURVES", "POINTCLOUD", "VOLUME", "GPENCIL", "GREASEPENCIL"}


class ExportCancelled(Exception):
    pass


@dataclass
class ExportResult:
    scene: object
    warnings: list = field(default_factory=list)
    info: dict = field(default_factory=dict)


def _sphere_mode(ob):
    # read the original object's setting: the evaluated copy is only refreshed on depsgraph updates
    original = ob.original if getattr(ob, "original", None) is not None else ob
    props = getattr(original, "tncg15", None)
    return props.implicit_sphere if props is not None else "AUTO"


def own_geometry(inst, ob) -> bool:
    """Is this instance the evaluated mesh of a curve, text, metaball or NURBS surface object (its
    original), which the depsgraph lists beside the object itself (Blender 3.0+)?  Then it is that
    object's geometry, taken once (as Cycles takes only the instances whose data is a mesh)."""
    original = getattr(ob, "original", None)
    return (inst.is_instance and ob.type == "MESH" and original is not None and original.type in CONVERTIBLE_TYPES
            and inst.parent is not None and inst.parent.original == original)


def instance_label(inst, ob):
    if not inst.is_instance or own_geometry(inst, ob):
        return ob.name
    return f"{ob.name} (instanced by {inst.parent.name})"


MIST_FALLOFF = {"QUADRATIC": 2.0, "LINEAR": 1.0, "INVERSE_QUADRATIC": 0.5}     # as Cycles' blender sync


def export_mist(world):
    """World > Mist Pass as the tracer's Scene.mist (start, depth, falloff exponent)."""
    if world is None:
        return (5.0, 25.0, 2.0)
    m = world.mist_settings
    return (float(m.start), float(m.depth), MIST_FALLOFF.get(m.falloff, 2.0))


def crypto_names(ob) -> dict:
    """Cryptomatte's names of an object (engine/film/cryptomatte.py): its own, and its topmost
    parent's for the asset (as Cycles' blender sync)."""
    top = ob.original if hasattr(ob, "original") else ob
    while top.parent is not None:
        top = top.parent
    return {"crypto_object": ob.name, "crypto_asset": top.name}


def finite_matrix(inst, ob):
    """The instance's world matrix as float64 (a copy); ExportError naming the object when it holds
    NaN or infinity (a NaN location, rotation or scale, or a driver gone wrong)."""
    matrix = np.array(inst.matrix_world, dtype=np.float64)
    if not np.isfinite(matrix).all():
        kind = "Light" if ob.type == "LIGHT" else "Object"
        raise ExportError(f"{kind} '{instance_label(inst, ob)}': transform has NaN or infinite values "
                          "(check its location, rotation and scale)")
    return matrix


def hash_string(text):
    """Cycles' hash_string (its util/hash.h): i = i * 37 + c over the UTF-8 bytes, 32 bits."""
    i = 0
    for c in text.encode("utf-8"):
        i = (i * 37 + c) & 0xFFFFFFFF
    return i


def hash_uint2(kx, ky):
    """Cycles' hash_uint2 (Bob Jenkins' lookup3 final mix), 32 bits."""
    m = 0xFFFFFFFF

    def rot(x, k):
        return ((x << k) | (x >> (32 - k))) & m
    a = b = c = (0xDEADBEEF + (2 << 2) + 13) & m
    b, a = (b + ky) & m, (a + kx) & m
    for x, y, k in (("c", "b", 14), ("a", "c", 11), ("b", "a", 25), ("c", "b", 16), ("a", "c", 4),
                    ("b", "a", 14), ("c", "b", 24)):
        v = {"a": a, "b": b, "c": c}
        v[x] = ((v[x] ^ v[y]) - rot(v[y], k)) & m
        a, b, c = v["a"], v["b"], v["c"]
    return c


def has_programs(materials):
    """Whether any of these tracer materials (or their mix leaves and factors) has a node program."""
    return any(getattr(m, "programs", None) or (getattr(m, "mix", None) is not None and any(
        leaf.material.programs or any(f.kind == "program" for f in leaf.factors) for leaf in m.mix.leaves))
        for m in materials)


def object_fields(ob, matrix, random_id, materials):
    """The object data node programs read (engine/scene/model.py TriangleMesh.object_matrix, texspace,
    object_random), for meshes with a material that has one; {} otherwise (scenes stay as they were)."""
    if not has_programs(materials):
        return {}
    if not random_id:                           # not an instance: Cycles hashes the object's name
        random_id = hash_uint2(hash_string(ob.name), 0)
    fields = {"object_matrix": np.asarray(matrix, dtype=np.float64),
              # Cycles' object random number: the instance's random id / 0xFFFFFFFF (float32).
              "object_random": float(np.float32(random_id & 0xFFFFFFFF) * np.float32(1.0 / 0xFFFFFFFF))}
    data = getattr(ob, "data", None)
    if data is not None and hasattr(data, "texspace_location"):
        fields["texspace"] = (tuple(float(c) for c in data.texspace_location),
                              tuple(float(c) for c in data.texspace_size))
    return fields


def export_scene(depsgraph, *, resolution, camera=None, crop=None, test_break=None, name=None,
                 view_camera=None, mesh_cache=None, uv_pass=False):
    """Build the tracer Scene.

    resolution: full-frame (width, height) in pixels (after the resolution percentage).
    crop: optional border (x0, y0, x1, y1) in full-frame pixels, y from the bottom; the exported
          scene then has the crop's resolution and a camera that sees exactly those pixels.
    view_camera: a tracer Camera to use instead of the scene's (the 3D viewport's view).
    mesh_cache: a dict kept across exports (the viewport): mesh arrays by (object, mesh, UV map), so a
          transform or material edit does not read meshes again (mcrt_addon/viewport.py empties it).
    uv_pass: the UV pass is on: every mesh with a UV map exports its active render map's UVs.
    Raises ExportError (user-facing message) or ExportCancelled.
    """
    t0 = time.perf_counter()
    sm = bridge.scene_module()
    warnings = []
    images = ImageTable(bridge.module("scene.textures"), warnings)
    table = MaterialTable(sm, warnings, images)
    scene = depsgraph.scene
    version = tuple(bpy.app.version)

    cam_obj = camera if camera is not None else scene.camera
    if cam_obj is not None:
        cam_obj = cam_obj.evaluated_get(depsgraph)
    width, height = int(resolution[0]), int(resolution[1])
    cam = view_camera if view_camera is not None else \
        export_camera(cam_obj, (width, height), crop, Camera=sm.Camera, warnings=warnings)
    out_res = (width, height) if crop is None else (int(crop[2] - crop[0]), int(crop[3] - crop[1]))

    warnings.extend(scene_warnings(scene, getattr(depsgraph, "view_layer", None)))
    meshes, spheres, lights, points, suns = [], [], [], [], []
    cache = {}
    flagged = set()
    n_instances = n_triangles = n_read = 0
    skipped = set()
    terminator_warned = set()
    def add_geometry(ob, otype, matrix, label, own=False, random_id=0):
        """One evaluated geometry (a mesh, or a convertible object through to_mesh()) as a
        triangle mesh or an implicit sphere; own: the evaluated mesh of a convertible object
        (own_geometry: never an implicit sphere, not kept in mesh_cache, as a converted one)."""
        nonlocal n_instances, n_triangles

        key = ob.data.as_pointer() if (otype == "MESH" and ob.data is not None) else None
        slot_ids = np.asarray(table.slot_indices(ob, matrix), dtype=np.int64)
        uv_map = table.uv_map(slot_ids)                 # None: no textured material, no UVs
        need = table.tangent_need(slot_ids)             # None: no anisotropic material with mesh tangents
        colours = attribute_names([table.materials[i] for i in slot_ids])     # Attribute nodes' colour attributes
        pass_uvs = uv_pass and uv_map is None               # UVs for the UV pass only (not for textures)
        arrays = cache.get((key, uv_map, need, colours, pass_uvs)) if key is not None else None
        kept = ((ob.name, ob.data.name, uv_map, need, colours, pass_uvs)
                if (mesh_cache is not None and key is not None and not own) else None)
        if arrays is None and kept is not None:
            arrays = mesh_cache.get(kept)

        def read(me):
            nonlocal n_read
            n_read += 1
            verts, tris, slots = mesh_arrays(me)
            # the triangles as the scene's validation keeps them (int64): a kept mesh's are not
            # converted again on every frame (2.2 MB of new memory for 93k triangles)
            base = verts, tris.astype(np.int64), slots
            read_map = "" if pass_uvs and len(me.uv_layers) else uv_map
            return base + (corner_uvs(me, read_map, label, warnings), mesh_normals(me),
                           corner_tangents(me, need, base[0], base[1], label, warnings),
                           corner_colors(me, colours, label, warnings), corner_bitangent_signs(me, need))
        if arrays is None:
            if otype == "MESH":
                arrays = read(ob.data)
            else:
                me = ob.to_mesh()
                try:
                    arrays = read(me) if me is not None else None
                finally:
                    ob.to_mesh_clear()
                if arrays is None:
                    return
            if key is not None:
                cache[(key, uv_map, need, colours, pass_uvs)] = arrays
            if kept is not None:
                mesh_cache[kept] = arrays
                mesh_cache.pop(kept + ("sphere_fit",), None)      # the fit of the arrays read before
        verts, tris, slots, uvs, shading, local_tangents, corner_colours, local_signs = arrays
        if len(tris) == 0:
            if otype == "MESH" and ob.name not in skipped:
                skipped.add(ob.name)
                warnings.append(f"Object '{ob.name}': mesh has no faces; skipped")
            return
        mat_ids = slot_ids[np.clip(slots, 0, len(slot_ids) - 1)]

        mode = (_sphere_mode(ob) if otype == "MESH" and uv_map is None and need is None and not own
                and not has_programs([table.materials[i] for i in slot_ids])
                else "NEVER")                       # spheres have no UVs, no tangents, no object for nodes
        if mode != "NEVER":
            # a function of the mesh arrays alone: kept with them (the cache forgets both together)
            fit_key = kept + ("sphere_fit",) if kept is not None else None
            if fit_key is not None and fit_key in mesh_cache:
                fit = mesh_cache[fit_key]
            else:
                fit = sphere_fit(verts, tris, slots)
                if fit_key is not None:
                    mesh_cache[fit_key] = fit
            scale = uniform_scale(matrix)
            if mode == "ALWAYS" and (fit is None or scale is None):
                if len(np.unique(mat_ids)) > 1:
                    warnings.append(f"Object '{label}': implicit sphere uses the first material only")
                if scale is None:
                    warnings.append(f"Object '{label}': non-uniform scale; implicit sphere uses "
                                    "the largest axis")
                centre, radius = bounding_sphere(verts)
                s = float(np.linalg.svd(matrix[:3, :3], compute_uv=False).max())
                fit, scale = (centre, radius), s
            if fit is not None and scale is not None:
                centre = transform_points(fit[0][None, :], matrix)[0]
                spheres.append(sm.Sphere(name=label, center=tuple(float(c) for c in centre),
                                         radius=fit[1] * scale, material_id=int(mat_ids[0]),
                                         pass_index=int(ob.pass_index), **crypto_names(ob)))
                n_instances += 1
                return
        world_verts = transform_points(verts, matrix)
        emissive = np.array([max(table.materials[i].emission) > 0 for i in slot_ids])[np.clip(slots, 0, len(slot_ids) - 1)]
        if emissive.any():
            v = world_verts[tris[emissive]]
            if not np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1).sum() > 0:
                raise ExportError(f"Object '{label}': emitter has zero area")
        mirrored = np.linalg.det(matrix[:3, :3]) <= 0
        tri_idx = tris[:, ::-1] if mirrored else tris
        if uvs is not None and mirrored:
            uvs = uvs[:, ::-1]
        if corner_colours and mirrored:
            corner_colours = {name: c[:, ::-1] for name, c in corner_colours.items()}
        tangents = None
        if local_tangents is not None:              # as Cycles' object_normal_transform
            tangents = transform_normals(local_tangents, matrix)
            tangents = tangents[:, ::-1] if mirrored else tangents
        signs = None
        if local_signs is not None and local_tangents is not None:     # world-space frame: a mirror flips B
            signs = -local_signs[:, ::-1] if mirrored else local_signs
        normals = smooth = None
        terminator = 0.1
        if shading is not None:                     # smooth faces: corner normals in world space
            normals = transform_normals(shading[0], matrix)
            normals, smooth = (normals[:, ::-1], shading[1]) if mirrored else (normals, shading[1])
            terminator, unmodelled = terminator_offsets(ob)
            if unmodelled and ob.name not in terminator_warned:
                terminator_warned.add(ob.name)
                warnings.append(f"Object '{ob.name}': shadow terminator {' and '.join(unmodelled)} not "
                                "supported (only the geometry offset); ignored")
        meshes.append(sm.TriangleMesh(name=label, vertices=world_verts, triangles=tri_idx,
                                      material_ids=mat_ids, uvs=uvs, normals=normals, smooth=smooth,
                                      terminator_offset=terminator, tangents=tangents, tangent_signs=signs,
                                      **object_fields(ob, matrix, random_id, [table.materials[i] for i in slot_ids]),
                                      **({"colors": corner_colours} if corner_colours else {}),
                                      pass_index=int(ob.pass_index), **crypto_names(ob)))
        n_instances += 1
        n_triangles += len(tris)

    convertible, converted = [], []       # convertible objects; (name, matrix) of their evaluated meshes
    for n, inst in enumerate(depsgraph.object_instances):
        if test_break is not None and n % 512 == 0 and test_break():
            raise ExportCancelled()
        ob = inst.object
        otype = ob.type
        if ob.name not in flagged:
            flagged.add(ob.name)
            warnings.extend(object_warnings(ob, ob.name))
        if otype == "LIGHT":
            kind = ob.data.type
            if kind in ("AREA", "POINT", "SPOT", "SUN"):
                matrix = finite_matrix(inst, ob)
                try:
                    if kind == "AREA":
                        lights.append(export_area_light(ob, matrix, version, AreaLight=sm.AreaLight,
                                                        warnings=warnings))
                    elif kind in ("POINT", "SPOT"):
                        points.append(export_point_light(ob, matrix, version, PointLight=sm.PointLight))
                    else:
                        suns.append(export_sun_light(ob, matrix, version, SunLight=sm.SunLight))
                except ValueError as exc:
                    raise ExportError(str(exc)) from None
            elif ob.name not in skipped:
                skipped.add(ob.name)
                warnings.append(f"Light '{ob.name}': {ob.data.type.lower()} lights are not supported "
                                "(use a point, spot, sun or area light, or an emissive mesh); ignored")
            continue
        if otype in SKIPPED_TYPES:
            if ob.name not in skipped:
                skipped.add(ob.name)
                warnings.append(f"Object '{ob.name}': {otype.lower()} objects are not supported; ignored")
            continue
        if otype != "MESH" and otype not in CONVERTIBLE_TYPES:
            continue
        if not inst.is_instance and not inst.show_self:
            continue                         # an instancer shown only by its instances (as in Cycles)
        matrix = finite_matrix(inst, ob)     # a copy: inst is transient
        if otype in CONVERTIBLE_TYPES:
            # Blender 3.0+ lists the evaluated mesh of a curve, text, metaball or NURBS surface as an
            # instance of its own (below): the object itself is converted only when none came
            convertible.append((ob, otype, matrix, instance_label(inst, ob), int(getattr(inst, "random_id", 0))))
            continue
        own = own_geometry(inst, ob)
        if own:
            converted.append((ob.original.name, matrix))
        add_geometry(ob, otype, matrix, instance_label(inst, ob), own, int(getattr(inst, "random_id", 0)))

    for ob, otype, matrix, label, random_id in convertible:
        if not any(name == ob.original.name and np.allclose(m, matrix) for name, m in converted):
            add_geometry(ob, otype, matrix, label, random_id=random_id)
    materials = table.materials or [sm.Material(name="(unused)")]
    for m in materials:                     # the IndexMA pass: Material > Settings > Pass Index
        source = bpy.data.materials.get(m.name)
        m.pass_index = int(source.pass_index) if source is not None else 0
    background, environment = export_world(scene.world, warnings, images, getattr(sm, "Environment", None),
                                          suns, getattr(sm, "SunLight", None))
    result = sm.Scene(camera=cam, materials=materials, meshes=meshes, spheres=spheres, quads=[],
                      background=background, environment=environment, resolution=out_res, name=name or scene.name,
                      lights=lights, points=points, suns=suns, textures=images.textures, cycles_version=version[:2],
                      mist=export_mist(scene.world))
    info = dict(export_seconds=time.perf_counter() - t0, objects=n_instances, triangles=n_triangles,
                spheres=len(spheres), meshes_shared=len(cache), meshes_read=n_read, materials=len(materials),
                textures=len(images.textures))
    return ExportResult(scene=result, warnings=warnings, info=info)
