"""Cryptomatte passes (CryptoObject, CryptoMaterial, CryptoAsset) as Cycles writes them, after the
Cryptomatte 1.0 specification: each name's id is MurmurHash3_32 (seed 0) of its UTF-8 bytes,
turned into a float32 by `hash_to_float` (exponent kept off 0 and 255, so never a NaN, an infinity
or a denormal); a pixel keeps up to DEPTH (id, coverage) pairs, coverage = the share of its samples
whose camera ray's first surface had that id, sorted by coverage (Cycles' film_write_cryptomatte_slots
and film_sort_cryptomatte_slots); LEVELS layers of 4 channels (id, coverage, id, coverage) each,
named CryptoObject00, CryptoObject01, ... and the manifest (name -> hash) goes into the image's
metadata under cryptomatte/<first 7 hex digits of the layer name's hash>/.

Ids: an object's is its Blender name (Cycles' ob->name), an asset's the name of its topmost parent
(itself without one), a material's its name.  Engine scenes without Blender names use the
TriangleMesh / Sphere / Quad name.
"""
from __future__ import annotations

import json
import struct

import numpy as np

KINDS = ("crypto_object", "crypto_material", "crypto_asset")
LAYER_NAME = {"crypto_object": "CryptoObject", "crypto_material": "CryptoMaterial", "crypto_asset": "CryptoAsset"}
DEPTH = 6                   # Blender's default View Layer > Cryptomatte > Levels
LEVELS = (DEPTH + 1) // 2   # layers of two (id, coverage) pairs


def murmur3_32(data: bytes, seed: int = 0) -> int:
    """MurmurHash3_x86_32 (Cycles' util_murmur_hash3)."""
    c1, c2, mask = 0xCC9E2D51, 0x1B873593, 0xFFFFFFFF
    h = seed & mask
    n = len(data) // 4
    for (k,) in struct.iter_unpack("<I", data[:4 * n]):
        k = (k * c1) & mask
        k = ((k << 15) | (k >> 17)) & mask
        k = (k * c2) & mask
        h ^= k
        h = ((h << 13) | (h >> 19)) & mask
        h = (h * 5 + 0xE6546B64) & mask
    tail, k = data[4 * n:], 0
    if len(tail) == 3:
        k ^= tail[2] << 16
    if len(tail) >= 2:
        k ^= tail[1] << 8
    if len(tail) >= 1:
        k ^= tail[0]
        k = (k * c1) & mask
        k = ((k << 15) | (k >> 17)) & mask
        k = (k * c2) & mask
        h ^= k
    h ^= len(data)
    h ^= h >> 16
    h = (h * 0x85EBCA6B) & mask
    h ^= h >> 13
    h = (h * 0xC2B2AE35) & mask
    h ^= h >> 16
    return h


def name_hash(name: str) -> int:
    return murmur3_32(name.encode("utf-8"))


def hash_to_float(h: int) -> float:
    """The spec's uint32_to_float32: the exponent clamped to [1, 254]."""
    exponent = min(max((h >> 23) & 0xFF, 1), 254)
    bits = (h & 0x80000000) | (exponent << 23) | (h & 0x7FFFFF)
    return struct.unpack("<f", struct.pack("<I", bits))[0]


def name_id(name: str) -> float:
    return hash_to_float(name_hash(name))


def object_names(scene, kind) -> list:
    """The id name of every primitive owner in engine/geometry/scene_geometry.py's slot order
    (meshes with triangles, spheres, quads), for `kind` crypto_object or crypto_asset."""
    def name(o):
        own = getattr(o, "crypto_object", "") or o.name
        return (getattr(o, "crypto_asset", "") or own) if kind == "crypto_asset" else own
    return ([name(m) for m in scene.meshes if len(m.triangles)], [name(s) for s in scene.spheres],
            [name(q) for q in scene.quads])


def primitive_ids(scene, geometry, kind) -> np.ndarray:
    """(slots,) float64 ids per primitive slot (geometry.kind_base + prim); 0 for light polygons."""
    meshes, spheres, quads = object_names(scene, kind)
    tri = [np.full(len(m.triangles), name_id(n)) for m, n in zip([m for m in scene.meshes if len(m.triangles)], meshes)]
    lights = geometry.lights.count if geometry.has_lights else 0
    return np.concatenate([np.zeros(1)] + tri + [np.array([name_id(n) for n in spheres]),
                                                 np.array([name_id(n) for n in quads]), np.zeros(lights)])


def material_ids(scene) -> np.ndarray:
    return np.array([name_id(m.name) for m in scene.materials])


def names(scene, kind) -> list:
    if kind == "crypto_material":
        return [m.name for m in scene.materials]
    meshes, spheres, quads = object_names(scene, kind)
    return meshes + spheres + quads


def layers(pixel, ids, count, shape) -> np.ndarray:
    """(H, W, 4 LEVELS) float32: per pixel the DEPTH ids of most coverage and their coverage (the
    share of the pixel's `count` samples), from one (frame pixel, id) entry per sample hit."""
    h, w = shape
    out = np.zeros((h * w, 2 * DEPTH), np.float32)
    if len(pixel):
        bits = np.asarray(ids, np.float32).view(np.uint32).astype(np.int64)
        key = np.asarray(pixel, np.int64) * (1 << 32) + bits
        uniq, hits = np.unique(key, return_counts=True)
        pix, idb = uniq >> 32, uniq & 0xFFFFFFFF
        order = np.lexsort((idb, -hits, pix))              # per pixel: most coverage first (ties: by id)
        pix, idb, hits = pix[order], idb[order], hits[order]
        first = np.searchsorted(pix, pix, side="left")
        rank = np.arange(len(pix)) - first
        keep = rank < DEPTH
        cov = hits / np.maximum(np.asarray(count, np.float64).reshape(-1)[pix], 1.0)
        p, r = pix[keep], rank[keep]
        out[p, 2 * r] = idb[keep].astype(np.uint32).view(np.float32)
        out[p, 2 * r + 1] = cov[keep]
    return out.reshape(h, w, 2 * DEPTH)


def manifest_metadata(scene, kind, layer="ViewLayer") -> dict:
    """{metadata key: value} of one Cryptomatte layer (the spec's cryptomatte/<key>/...)."""
    name = f"{layer}.{LAYER_NAME[kind]}"
    key = f"{name_hash(name):08x}"[:7]
    manifest = {n: f"{name_hash(n):08x}" for n in sorted(set(names(scene, kind)))}
    return {f"cryptomatte/{key}/name": name, f"cryptomatte/{key}/hash": "MurmurHash3_32",
            f"cryptomatte/{key}/conversion": "uint32_to_float32",
            f"cryptomatte/{key}/manifest": json.dumps(manifest, separators=(",", ":"))}
