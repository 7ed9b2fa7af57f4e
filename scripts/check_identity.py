"""Proves that a change of the code leaves every rendered image bit-identical: renders a fixed
matrix of small cases through the two command lines only (``python -m engine render`` and
``python -m mcrt_addon render``), so it runs unchanged whatever the packages look like inside,
and records for each case the SHA-256 of the float32 pixels of every channel of its EXR (and of
its PNG where one is written) and its ``--stats-json`` without the fields that vary run to run.

  python scripts/check_identity.py --list [--only PATTERN ...]
  python scripts/check_identity.py record --out BASELINE.json [--only PATTERN ...]
  python scripts/check_identity.py compare --baseline BASELINE.json [--out NEW.json] [--only PATTERN ...]
  python scripts/check_identity.py diff OLD.json NEW.json [--only PATTERN ...]

record    renders every case and writes the JSON; the images are kept beside it in
          BASELINE.images/ (--images DIR elsewhere), so that compare can give the largest
          difference of a pixel.
compare   renders the cases again and prints one row per case: same pixels, same stats (and
          the keys that differ), the largest absolute pixel difference when the pixels differ.
          Exit code 1 when any case differs, failed, or is missing on either side.
diff      the same table for two recorded files, without rendering.
--only    fnmatch patterns (or plain substrings) of case names; repeatable.  --list prints the
          cases and their command lines.

Typical use around a refactor:

  python scripts/check_identity.py record --out /tmp/before.json        # on the old code
  ... refactor ...
  python scripts/check_identity.py compare --baseline /tmp/before.json  # on the new code

The Python is this script's interpreter (--python another), run with the repository
(--repo, default: this script's parent directory) as the working directory and first on
PYTHONPATH.  Uses the standard library, NumPy and OpenImageIO only.

What is hashed: the raw float32 bytes of each channel (OpenImageIO, every subimage), never
the file bytes (the EXR header carries a date and the render's own timing).  What is
volatile, found by recording the matrix twice (see VOLATILE_KEY below): every timing
(``*_seconds``, ``seconds_*``, ``rays_per_second``, the seconds of each round and unit in the
stopping rules' ``round_log``, formerly ``pass_log``) and the EXR header's ``DateTime`` and
``tncg15:seconds_to_target``; they are kept in the JSON under ``volatile`` for reference but not
compared.  Paths and addresses that depend on where the run happens are rewritten, not dropped:
the temporary output directory to ``<out>``, the repository to ``<repo>``, the interpreter to
``<python>``, ``tcp://host:port`` to ``tcp://<address>``.

The matrix (``--list``; build_cases): 40x40 pixels, 8 spp, seed 7 unless a case says otherwise.
engine/<builtin>/...: the four built-in scenes on 1 thread, 2 forked processes and a Dask
LocalCluster; each estimator, the random sampler, nested dielectrics, both Fresnel models, every
accelerator (brute force and the octree on tiny images), no Russian roulette, each pass alone and
all together (1, 2 workers, cluster), the noise target (adaptive, min samples, not adaptive),
max depth, shadow rays, tile size, PNG output, non-square frames, a tile's samples in two units,
the denoiser.  engine/scene-file/NAME: a scene file written by the script (scene_file_json).
addon/<blend>/...: every sample_blends/*.blend on 1 and 2 worker processes, and the add-on's own
options on a few of them (cluster, estimators, sampler, Fresnel, nested dielectrics,
accelerators, passes, noise target, PNG, denoise, non-square).  About 90 s on 2 cores.

Not in the matrix: ``--time-limit`` (where the render stops depends on the clock) and the
``threads`` pool with more than one thread (no command line chooses it: --threads N > 1 forks
processes outside Blender).  ``--denoise`` cases run only where pyoidn imports (else
recorded as skipped).

The record (JSON): the run (git commit, interpreter, where engine and mcrt_addon imported from,
the total seconds) and per case: ``command`` (as run), ``status`` (ok, failed: ..., skipped: ...),
``seconds``, ``pixels.channels`` ({"exr:<channel>": {shape, sha256}}), ``header`` (the EXR
attributes compared), ``stats`` (the compared stats), ``volatile`` (what was left out, with its
values), ``image`` (the kept EXR, relative to ``images``).
"""
from __future__ import annotations

import argparse
import datetime
import fnmatch
import glob
import hashlib
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FORMAT = 1

# The matrix: small and fixed.  Every case renders with this seed; most at this size and spp.
SIZE = (40, 40)
SAMPLES = 8
SEED = 7
BUILTINS = ("cornell", "near_lamp", "caustic", "many_lights")
ALL_PASSES = "albedo,normal,depth,samples,variance"

# Stats keys removed before comparing (at any depth): they are clocks, or rates and predictions
# computed from clocks.  Determined by recording the whole matrix twice; also the seconds inside
# the stopping rules' round_log (strip_pass_log).
VOLATILE_KEY = re.compile(r"(^|_)seconds($|_)|per_second|^(pid|pids|hostname|host|date|time|timestamp)$")
# EXR/PNG header attributes not compared: the write date and the timing-derived prediction.
VOLATILE_ATTRIBUTE = re.compile(r"^(DateTime|tncg15:seconds_to_target)$")
# Header attributes that only describe the file (not the render); not compared either.
IGNORED_ATTRIBUTE = re.compile(r"^(oiio:|openexr:lineOrder$|compression$|Software$)")
ADDRESS = re.compile(r"tcp://[^\s,)'\"]+")


def scene_file_json() -> dict:
    """A small scene in the documented file format (engine/scene/files.py, version 5), so that
    ``python -m engine render SCENE.json`` (the reader) is in the matrix too: a room of flat and
    smooth meshes open to the sky, glass in glass (different IORs: --nested-dielectrics changes it), a mirror
    ball, an emissive quad, an Area light, a spot light and a sun, on a grey background."""
    def box(x0, x1, y0, y1, z0, z1):
        v = [[x, y, z] for z in (z0, z1) for y in (y0, y1) for x in (x0, x1)]
        t = [[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
             [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]]
        return v, t
    room_v, room_t = box(-1.0, 1.0, -1.0, 1.0, 0.0, 2.0)
    room_t = room_t[:2] + room_t[4:]            # no ceiling: the sun and the background come in
    block_v, block_t = box(0.25, 0.75, 0.2, 0.7, 0.0, 0.6)
    # A smooth-shaded octahedron: one shading normal per triangle corner (the vertex direction).
    c, r = (-0.45, 0.45, 0.35), 0.3
    dirs = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
    octa_v = [[c[i] + r * d[i] for i in range(3)] for d in dirs]
    octa_t = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    octa_n = [dirs[i] for tri in octa_t for i in tri]
    return {
        "format": "tncg15-scene", "version": 5, "name": "check_identity", "resolution": [40, 40],
        "background": [0.05, 0.06, 0.08],
        "camera": {"look_at": {"position": [0.0, -0.95, 1.0], "target": [0.0, 0.3, 0.6], "up": [0, 0, 1]},
                   "lens": 24},
        "materials": [
            {"name": "White", "kind": "diffuse", "color": [0.75, 0.75, 0.75]},
            {"name": "Red", "kind": "diffuse", "color": [0.7, 0.15, 0.1]},
            {"name": "Glass", "kind": "glass", "color": [1, 1, 1], "ior": 1.5},
            {"name": "Water", "kind": "glass", "color": [0.9, 0.95, 1.0], "ior": 1.33},
            {"name": "Mirror", "kind": "mirror", "color": [0.9, 0.9, 0.9]},
            {"name": "Lamp", "kind": "diffuse", "color": [0, 0, 0], "emission": [6, 5.5, 5]}],
        "meshes": [
            {"name": "Room", "vertices": room_v, "triangles": room_t, "material": "White"},
            {"name": "Block", "vertices": block_v, "triangles": block_t, "material": "Red"},
            {"name": "Gem", "vertices": octa_v, "triangles": octa_t, "material": "White", "normals": octa_n,
             "smooth": [1, 1, 1, 1, 0, 0, 0, 0]}],
        "spheres": [
            {"name": "Outer glass", "center": [0.1, 0.2, 0.3], "radius": 0.3, "material": "Glass"},
            {"name": "Inner water", "center": [0.1, 0.2, 0.3], "radius": 0.15, "material": "Water"},
            {"name": "Mirror ball", "center": [0.55, 0.45, 0.85], "radius": 0.15, "material": "Mirror"}],
        "quads": [{"name": "Ceiling lamp", "corners": [[-0.25, 0.0, 1.99], [0.25, 0.0, 1.99], [0.25, 0.5, 1.99],
                                                      [-0.25, 0.5, 1.99]], "material": "Lamp"}],
        "lights": [{"name": "Area", "vertices": [[-0.95, -0.2, 0.6], [-0.95, 0.2, 0.6], [-0.95, 0.2, 1.0],
                                                 [-0.95, -0.2, 1.0]], "radiance": [2.0, 2.5, 3.0]}],
        "points": [{"name": "Spot", "position": [0.6, -0.6, 1.8], "intensity": [3, 3, 2.5], "radius": 0.05,
                    "spot_size": 0.9, "spot_blend": 0.3, "spot_direction": [-0.3, 0.5, -1.0]}],
        "suns": [{"name": "Sun", "direction": [0.3, 0.2, -1.0], "irradiance": [0.5, 0.5, 0.45], "angle": 0.05}],
    }


SCENE_FILE = "<scene>"          # in a case's arguments: the path of scene_file_json() written for the run


@dataclass
class Case:
    name: str
    cli: str                    # "engine" | "addon"
    args: list                  # after "render"; -o, --stats-json (and --png) are added
    png: bool = False           # also --png, hashed as 8-bit pixels
    needs: str | None = None    # an importable module the case needs (else: skipped)
    note: str = ""

    def command(self, python: str, out_dir: str, scene_file: str = SCENE_FILE) -> list:
        module = "engine" if self.cli == "engine" else "mcrt_addon"
        args = [scene_file if a == SCENE_FILE else str(a) for a in self.args]
        cmd = [python, "-m", module, "render", *args, "-o", os.path.join(out_dir, "image.exr"),
               "--stats-json", os.path.join(out_dir, "stats.json")]
        if self.png:
            cmd += ["--png", os.path.join(out_dir, "image.png")]
        return cmd


def size_args(size=SIZE, samples=SAMPLES, seed=SEED):
    return ["--resolution", size[0], size[1], "--samples", samples, "--seed", seed]


def engine_case(name, scene, *extra, threads=1, size=SIZE, samples=SAMPLES, **kw):
    return Case(f"engine/{scene}/{name}", "engine",
                ["--builtin", scene, *size_args(size, samples), "--threads", threads, "--quiet", *extra], **kw)


def addon_case(name, blend, *extra, threads=1, size=SIZE, samples=SAMPLES, **kw):
    """blend: relative to the repository (the working directory of the run)."""
    stem = os.path.splitext(os.path.basename(blend))[0]
    return Case(f"addon/{stem}/{name}", "addon", [blend, *size_args(size, samples), "--threads", threads, *extra],
                **kw)


def build_cases(repo=REPO) -> list:
    cases = []
    # Every built-in scene on one thread, on two forked worker processes, and on a Dask LocalCluster.
    for scene in BUILTINS:
        cases.append(engine_case("t1", scene, threads=1))
        cases.append(engine_case("t2", scene, threads=2))
        cases.append(engine_case("cluster", scene, "--cluster", "local", threads=2))
    # Other code paths on the built-ins.
    for scene in ("cornell", "many_lights"):
        for estimator in ("report", "solid-angle", "mis"):
            cases.append(engine_case(f"estimator-{estimator}", scene, "--estimator", estimator))
    cases.append(engine_case("estimator-report-t2", "many_lights", "--estimator", "report", threads=2))
    for scene in ("cornell", "caustic"):
        cases.append(engine_case("sampler-random", scene, "--sampler", "random"))
        cases.append(engine_case("nested-dielectrics", scene, "--nested-dielectrics"))
        for fresnel in ("schlick", "exact"):
            cases.append(engine_case(f"fresnel-{fresnel}", scene, "--fresnel", fresnel))
        cases.append(engine_case("no-russian-roulette", scene, "--no-russian-roulette"))
    cases.append(engine_case("sampler-random-t2", "cornell", "--sampler", "random", threads=2))
    cases.append(engine_case("nested-exact-t2", "caustic", "--nested-dielectrics", "--fresnel", "exact", threads=2))
    cases.append(engine_case("accel-embree", "cornell", "--accelerator", "embree"))
    cases.append(engine_case("accel-octree", "cornell", "--accelerator", "octree"))
    cases.append(engine_case("accel-octree", "near_lamp", "--accelerator", "octree", size=(24, 24), samples=4))
    cases.append(engine_case("accel-brute", "cornell", "--accelerator", "brute", size=(16, 16), samples=4,
                             note="tiny: brute force tests every triangle"))
    cases.append(engine_case("accel-brute", "many_lights", "--accelerator", "brute", size=(12, 12), samples=2,
                             note="tiny: brute force tests every triangle"))
    for p in ALL_PASSES.split(","):
        cases.append(engine_case(f"pass-{p}", "cornell", "--passes", p))
    cases.append(engine_case("passes-all", "cornell", "--passes", ALL_PASSES))
    cases.append(engine_case("passes-all-t2", "cornell", "--passes", ALL_PASSES, threads=2))
    cases.append(engine_case("passes-all-cluster", "cornell", "--passes", ALL_PASSES, "--cluster", "local",
                             threads=2))
    cases.append(engine_case("passes-all-t2", "many_lights", "--passes", ALL_PASSES, threads=2))
    cases.append(engine_case("noise-target", "cornell", "--noise-target", "0.3", samples=64))
    cases.append(engine_case("noise-target-t2", "cornell", "--noise-target", "0.3", samples=64, threads=2))
    cases.append(engine_case("noise-target-min-samples", "cornell", "--noise-target", "0.3", "--min-samples",
                             "16", samples=64, threads=2))
    cases.append(engine_case("noise-target-no-adaptive", "cornell", "--noise-target", "0.3", "--no-adaptive",
                             samples=64, threads=2))
    cases.append(engine_case("noise-target-passes-t2", "caustic", "--noise-target", "0.4", "--passes", ALL_PASSES,
                             samples=64, threads=2))
    cases.append(engine_case("max-depth-0", "cornell", "--max-depth", "0"))
    cases.append(engine_case("max-depth-2", "caustic", "--max-depth", "2"))
    cases.append(engine_case("shadow-rays-4", "near_lamp", "--shadow-rays", "4"))
    cases.append(engine_case("tile-16-t2", "cornell", "--tile-size", "16", threads=2))
    cases.append(engine_case("png", "cornell", png=True))
    # Not square: a transposed width and height would show.
    cases.append(engine_case("wide-t2", "cornell", size=(64, 24), threads=2))
    cases.append(engine_case("tall", "caustic", size=(24, 56)))
    # One tile of 16x16 pixels whose 1100 samples are two work units (1024 + 76): the film adds
    # sample chunks of a pixel, in whatever order the workers return them.
    for threads, extra in ((1, ()), (2, ()), (2, ("--cluster", "local"))):
        label = "cluster" if extra else f"t{threads}"
        cases.append(engine_case(f"chunks-{label}", "cornell", *extra, threads=threads, size=(16, 16),
                                 samples=1100))
    # The scene file reader (scene_file_json), on one and two workers, with nested dielectrics.
    for name, extra, threads in (("t1", (), 1), ("t2", (), 2), ("nested-dielectrics", ("--nested-dielectrics",), 1),
                                 ("passes-all-t2", ("--passes", ALL_PASSES), 2)):
        cases.append(Case(f"engine/scene-file/{name}", "engine",
                          [SCENE_FILE, *size_args(), "--threads", threads, "--quiet", *extra]))
    cases.append(engine_case("denoise", "cornell", "--denoise", needs="pyoidn"))
    cases.append(engine_case("denoise-passes-t2", "cornell", "--denoise", "--passes", ALL_PASSES, threads=2,
                             needs="pyoidn"))

    # Every sample .blend through the add-on (bpy; worker processes), on 1 and 2 workers.
    blends = sorted(os.path.relpath(p, repo) for p in glob.glob(os.path.join(repo, "sample_blends", "*.blend")))
    for blend in blends:
        cases.append(addon_case("t1", blend, threads=1))
        cases.append(addon_case("t2", blend, threads=2))
    # The add-on's own options on a few of them.
    def blend(stem):
        return os.path.join("sample_blends", stem + ".blend")
    if blends:
        cases.append(addon_case("cluster", blend("cornell"), "--cluster", "local", threads=2))
        cases.append(addon_case("cluster", blend("many_lights"), "--cluster", "local", threads=2))
        for estimator in ("report", "solid-angle", "mis"):
            cases.append(addon_case(f"estimator-{estimator}", blend("many_lights"), "--estimator", estimator))
        cases.append(addon_case("sampler-random", blend("cornell"), "--sampler", "random"))
        cases.append(addon_case("fresnel-exact", blend("mirror_glass"), "--fresnel", "exact"))
        cases.append(addon_case("nested-dielectrics", blend("nested_glass"), "--nested-dielectrics"))
        cases.append(addon_case("accel-octree", blend("area_light"), "--accelerator", "octree", size=(24, 24),
                                samples=4))
        cases.append(addon_case("accel-brute", blend("point_light"), "--accelerator", "brute", size=(12, 12),
                                samples=2))
        cases.append(addon_case("max-depth-1", blend("diffuse_room"), "--max-depth", "1"))
        cases.append(addon_case("shadow-rays-3", blend("spot_light"), "--shadow-rays", "3"))
        cases.append(addon_case("passes-all-t2", blend("cornell"), "--passes", ALL_PASSES, threads=2))
        cases.append(addon_case("passes-all-t2", blend("principled"), "--passes", ALL_PASSES, threads=2))
        cases.append(addon_case("noise-target-t2", blend("cornell"), "--noise-target", "0.3", samples=64, threads=2))
        cases.append(addon_case("noise-target-no-adaptive", blend("sky_lit"), "--noise-target", "0.3",
                                "--no-adaptive", samples=64, threads=2))
        cases.append(addon_case("png", blend("smooth"), png=True))
        cases.append(addon_case("wide-t2", blend("cornell"), size=(64, 24), threads=2))
        cases.append(addon_case("tall", blend("textured"), size=(24, 56)))
        cases.append(addon_case("denoise-t2", blend("cornell"), "--denoise", threads=2, needs="pyoidn"))
    return cases


def select(cases, patterns):
    if not patterns:
        return list(cases)
    def hit(name):
        return any(fnmatch.fnmatchcase(name, p) if any(c in p for c in "*?[") else p in name for p in patterns)
    return [c for c in cases if hit(c.name)]


# -- images ---------------------------------------------------------------------------------------
def read_layers(path: str, prefix: str) -> tuple[dict, dict]:
    """{prefix:[subimage/]channel: float32 (H, W) array} and the header attributes of an image."""
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise RuntimeError(f"cannot open {path}: {oiio.geterror()}")
    layers, attributes = {}, {}
    try:
        sub = 0
        while inp.seek_subimage(sub, 0):
            spec = inp.spec()
            pixels = inp.read_image(sub, 0, 0, spec.nchannels, "float")
            if pixels is None:
                raise RuntimeError(f"cannot read {path}: {inp.geterror()}")
            pixels = np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
            tag = f"{prefix}:" + (f"{sub}/" if sub else "")
            for c, name in enumerate(spec.channelnames):
                layers[tag + name] = np.ascontiguousarray(pixels[..., c])
            for attr in spec.extra_attribs:
                value = attr.value
                attributes[tag + attr.name] = value if isinstance(value, (int, float, str)) else str(value)
            sub += 1
    finally:
        inp.close()
    return layers, attributes


def image_record(layers: dict) -> dict:
    return {"channels": {name: {"shape": list(a.shape), "sha256": hashlib.sha256(a.tobytes()).hexdigest()}
                         for name, a in layers.items()}}


def max_abs_difference(old_layers: dict, new_layers: dict) -> str:
    """The largest |old - new| over the channels both have, as text (NaN/inf where they do not match)."""
    worst, notes = 0.0, []
    for name in sorted(set(old_layers) & set(new_layers)):
        a, b = old_layers[name].astype(np.float64), new_layers[name].astype(np.float64)
        if a.shape != b.shape:
            notes.append(f"{name}: shape {a.shape} -> {b.shape}")
            continue
        same = (a == b) | (np.isnan(a) & np.isnan(b))
        if same.all():
            continue
        both_finite = np.isfinite(a) & np.isfinite(b)
        if (~same & ~both_finite).any():
            notes.append(f"{name}: {int((~same & ~both_finite).sum())} non-finite mismatches")
        if (~same & both_finite).any():
            worst = max(worst, float(np.abs(a - b)[~same & both_finite].max()))
    text = f"{worst:.3g}" if worst else ("0" if not notes else "")
    return "; ".join([text] + notes if text else notes)


# -- stats ----------------------------------------------------------------------------------------
def normalise(value, replacements):
    """Rewrite the run's own paths and addresses inside strings (recursively)."""
    if isinstance(value, str):
        for old, new in replacements:
            value = value.replace(old, new)
        return ADDRESS.sub("tcp://<address>", value)
    if isinstance(value, list):
        return [normalise(v, replacements) for v in value]
    if isinstance(value, dict):
        return {k: normalise(v, replacements) for k, v in value.items()}
    return value


def strip_pass_log(log, path, volatile):
    """The stopping rules' round_log (pass_log before the rename; engine/rendering/stopping.py): per
    round (pixel-samples, seconds, [(tile, pixel-samples, seconds) per unit]); the samples are
    kept, the seconds are volatile.  Anything of another shape is kept whole (and so compared)."""
    def is_number(x):
        return isinstance(x, (int, float)) and not isinstance(x, bool)
    ok = isinstance(log, list) and all(
        isinstance(p, list) and len(p) == 3 and is_number(p[0]) and is_number(p[1]) and isinstance(p[2], list)
        and all(isinstance(u, list) and len(u) == 3 and all(map(is_number, u)) for u in p[2]) for p in log)
    if not ok:
        return log
    kept = []
    for i, (samples, seconds, units) in enumerate(log):
        volatile[f"{path}[{i}].seconds"] = seconds
        volatile[f"{path}[{i}].unit_seconds"] = [u[2] for u in units]
        kept.append([samples, [u[:2] for u in units]])
    return kept


def split_volatile(stats):
    """(stats without the volatile keys, the volatile keys as {dotted.key: value})."""
    volatile = {}

    def walk(value, path):
        if isinstance(value, dict):
            kept = {}
            for k, v in value.items():
                key = f"{path}.{k}" if path else k
                if VOLATILE_KEY.search(str(k)):
                    volatile[key] = v
                elif k in ("pass_log", "round_log"):       # round_log: the same log, renamed
                    kept[k] = strip_pass_log(v, key, volatile)
                else:
                    kept[k] = walk(v, key)
            return kept
        if isinstance(value, list):
            return [walk(v, f"{path}[{i}]") for i, v in enumerate(value)]
        return value
    return walk(stats, ""), volatile


def flatten(value, path="", out=None):
    out = {} if out is None else out
    if isinstance(value, dict) and value:
        for k, v in value.items():
            flatten(v, f"{path}.{k}" if path else str(k), out)
    elif isinstance(value, list) and value and any(isinstance(v, (dict, list)) for v in value):
        for i, v in enumerate(value):
            flatten(v, f"{path}[{i}]", out)
    else:
        out[path] = value
    return out


def differing_keys(old, new) -> list:
    a, b = flatten(old), flatten(new)
    keys = []
    for k in sorted(set(a) | set(b)):
        if k not in a:
            keys.append(f"+{k}")
        elif k not in b:
            keys.append(f"-{k}")
        elif json.dumps(a[k], sort_keys=True) != json.dumps(b[k], sort_keys=True):
            keys.append(k)
    return keys


# -- running --------------------------------------------------------------------------------------
def environment(repo):
    env = dict(os.environ)
    env.pop("PYTHONHOME", None)
    env["PYTHONPATH"] = os.pathsep.join([repo] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep)
                                                  if p and os.path.abspath(p) != repo])
    return env


def probe(python, repo) -> dict:
    """Where the two packages import from, and which optional modules import."""
    code = ("import json, importlib.util as u, engine, mcrt_addon; "
            "print(json.dumps({'engine': engine.__file__, 'mcrt_addon': mcrt_addon.__file__, "
            "'optional': {m: u.find_spec(m) is not None for m in ('pyoidn',)}}))")
    proc = subprocess.run([python, "-c", code], cwd=repo, env=environment(repo), check=False, capture_output=True,
                          text=True)
    if proc.returncode != 0:
        raise SystemExit(f"check_identity: {python} cannot import engine and mcrt_addon from {repo}:\n{proc.stderr}")
    info = json.loads(proc.stdout.strip().splitlines()[-1])
    for pkg in ("engine", "mcrt_addon"):
        if not os.path.abspath(info[pkg]).startswith(repo + os.sep):
            raise SystemExit(f"check_identity: {pkg} imports from {info[pkg]}, not from {repo}")
    if info["optional"].get("pyoidn"):      # importable is not enough: the native library must load
        ok = subprocess.run([python, "-c", "import pyoidn"], cwd=repo, env=environment(repo),
                            check=False, capture_output=True).returncode == 0
        info["optional"]["pyoidn"] = ok
    return info


def git_info(repo) -> dict:
    def git(*args):
        proc = subprocess.run(["git", "-C", repo, *args], check=False, capture_output=True, text=True)
        return proc.stdout.strip() if proc.returncode == 0 else None
    # The tree ids say which code was rendered even when the commit also holds other changes.
    return {"commit": git("rev-parse", "HEAD"), "branch": git("rev-parse", "--abbrev-ref", "HEAD"),
            "dirty": bool(git("status", "--porcelain", "--untracked-files=no")),
            "trees": {d: git("rev-parse", f"HEAD:{d}") for d in ("engine", "mcrt_addon", "sample_blends")}}


def run_case(case, python, repo, work, images_dir, optional, timeout) -> dict:
    out_dir = os.path.join(work, case.name.replace("/", "__"))
    os.makedirs(out_dir)
    scene_file = os.path.join(work, "scene.json")
    cmd = case.command(python, out_dir, scene_file)
    record = {"cli": case.cli, "command": [("<python>" if a == python else SCENE_FILE if a == scene_file
                                            else a.replace(out_dir, "<out>")) for a in cmd]}
    if case.note:
        record["note"] = case.note
    if case.needs and not optional.get(case.needs):
        record["status"] = f"skipped: {case.needs} does not import"
        return record
    start = time.perf_counter()
    try:
        proc = subprocess.run(cmd, cwd=repo, env=environment(repo), check=False, capture_output=True, text=True,
                              timeout=timeout)
    except subprocess.TimeoutExpired:
        record.update(status=f"failed: timed out after {timeout:g} s", seconds=time.perf_counter() - start)
        return record
    record["seconds"] = round(time.perf_counter() - start, 3)
    if proc.returncode != 0:
        tail = (proc.stderr.strip() or proc.stdout.strip() or "no output").splitlines()[-3:]
        record["status"] = f"failed: exit code {proc.returncode}: " + " | ".join(tail)
        return record
    replacements = [(out_dir, "<out>"), (python, "<python>"), (os.path.realpath(python), "<python>"),
                    (repo, "<repo>")]
    layers, attributes = read_layers(os.path.join(out_dir, "image.exr"), "exr")
    if case.png:
        png_layers, png_attributes = read_layers(os.path.join(out_dir, "image.png"), "png")
        layers.update(png_layers)
        attributes.update(png_attributes)
    with open(os.path.join(out_dir, "stats.json")) as fh:
        stats, volatile = split_volatile(normalise(json.load(fh), replacements))
    header = {k: v for k, v in attributes.items() if not IGNORED_ATTRIBUTE.search(k.split(":", 1)[1].split("/")[-1])}
    for k in [k for k in header if VOLATILE_ATTRIBUTE.search(k.split(":", 1)[1].split("/")[-1])]:
        volatile[k] = header.pop(k)
    record.update(status="ok", pixels=image_record(layers), header=header, stats=stats, volatile=volatile)
    if images_dir:
        base = os.path.join(images_dir, case.name.replace("/", "__"))
        shutil.copyfile(os.path.join(out_dir, "image.exr"), base + ".exr")
        record["image"] = os.path.basename(base) + ".exr"
        if case.png:
            shutil.copyfile(os.path.join(out_dir, "image.png"), base + ".png")
            record["png"] = os.path.basename(base) + ".png"
    return record


IMAGES_MARK = ".check_identity-images"


def fresh_images_dir(path):
    """An empty images directory: made, or emptied if this script made it (its mark file is
    there); any other directory with files in it is refused, never emptied."""
    if os.path.isdir(path) and os.listdir(path):
        if not os.path.isfile(os.path.join(path, IMAGES_MARK)):
            raise SystemExit(f"check_identity: {path} has files that are not this script's images; "
                             "give another --images DIR")
        shutil.rmtree(path)
    os.makedirs(path, exist_ok=True)
    with open(os.path.join(path, IMAGES_MARK), "w") as fh:
        fh.write("images of scripts/check_identity.py; emptied by its next run\n")


def run_matrix(cases, python, repo, out_path, images_dir, timeout, log) -> dict:
    info = probe(python, repo)
    if images_dir:
        fresh_images_dir(images_dir)
    result = {
        "tool": "scripts/check_identity.py", "format": FORMAT,
        "created": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "repo": repo, "git": git_info(repo), "python": python, "python_version": platform.python_version(),
        "imports": info, "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
        "matrix": {"size": list(SIZE), "samples": SAMPLES, "seed": SEED},
        "images": os.path.relpath(images_dir, os.path.dirname(os.path.abspath(out_path))) if images_dir and out_path
        else images_dir,
        "cases": {},
    }
    start = time.perf_counter()
    work = tempfile.mkdtemp(prefix="check-identity-")
    result["scene_file"] = scene_file_json()
    try:
        with open(os.path.join(work, "scene.json"), "w") as fh:
            json.dump(result["scene_file"], fh, indent=1)
        for i, case in enumerate(cases, 1):
            record = run_case(case, python, repo, work, images_dir, info["optional"], timeout)
            result["cases"][case.name] = record
            log(f"[{i:3d}/{len(cases)}] {case.name:48s} {record.get('seconds', 0):6.2f} s  {record['status']}")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    result["seconds"] = round(time.perf_counter() - start, 1)
    log(f"{len(cases)} cases in {result['seconds']:.1f} s")
    return result


def write_json(path, data):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        json.dump(data, fh, indent=1, sort_keys=False)
        fh.write("\n")
    os.replace(tmp, path)


def load_json(path):
    with open(path) as fh:
        data = json.load(fh)
    if data.get("tool") != "scripts/check_identity.py":
        raise SystemExit(f"check_identity: {path} is not a check_identity record")
    data["_dir"] = os.path.dirname(os.path.abspath(path))
    return data


def image_path(data, record, key="image"):
    if not record.get(key) or not data.get("images"):
        return None
    path = os.path.join(data["_dir"], data["images"], record[key])
    return path if os.path.isfile(path) else None


# -- comparing ------------------------------------------------------------------------------------
def rename_stats(record, renames):
    """The record with its cases' top-level stats keys renamed (OLD -> NEW): an intended rename
    of a stats key is then compared under its new name."""
    if not renames:
        return record
    record = json.loads(json.dumps(record))
    for case in record["cases"].values():
        stats = case.get("stats")
        if isinstance(stats, dict):
            case["stats"] = {renames.get(k, k): v for k, v in stats.items()}
    return record


def compare_records(old, new, names, out=sys.stdout, renames=None, accepted=()) -> int:
    """The table; exit code 1 if anything differs.  renames {OLD: NEW}: stats keys renamed on
    purpose; accepted: fnmatch patterns of stats keys whose change is intended (listed in the
    row's notes as 'accepted', not counted as a difference).  Pixels are never accepted."""
    old = rename_stats(old, renames or {})
    rows, bad = [], 0
    for name in names:
        a, b = old["cases"].get(name), new["cases"].get(name)
        if a is None or b is None:
            rows.append((name, "-", "-", "", "missing in " + ("the baseline" if a is None else "the new run")))
            bad += 1
            continue
        if a["status"] != "ok" or b["status"] != "ok":
            same = a["status"] == b["status"] and a["status"].startswith("skipped")
            rows.append((name, "-", "-", "", "" if same else f"baseline: {a['status']}; new: {b['status']}"))
            bad += not same
            continue
        pa, pb = a["pixels"]["channels"], b["pixels"]["channels"]
        same_pixels = pa == pb
        keys = differing_keys(a["stats"], b["stats"])
        keys += [f"header:{k}" for k in differing_keys(a["header"], b["header"])]
        allowed = [k for k in keys if any(fnmatch.fnmatchcase(k.lstrip("+-"), pat) for pat in accepted)]
        keys = [k for k in keys if k not in allowed]
        diff = ""
        if not same_pixels:
            changed = sorted(k for k in set(pa) | set(pb) if pa.get(k) != pb.get(k))
            paths = []
            for key, prefix in (("image", "exr"), ("png", "png")):
                if any(k.startswith(prefix + ":") for k in changed):
                    paths.append((image_path(old, a, key), image_path(new, b, key), prefix))
            parts = []
            for pa_path, pb_path, prefix in paths:
                if pa_path and pb_path:
                    parts.append(max_abs_difference(read_layers(pa_path, prefix)[0], read_layers(pb_path, prefix)[0]))
                else:
                    parts.append(f"{prefix}: no image kept")
            only = [k for k in changed if k not in pa or k not in pb]
            diff = "; ".join(p for p in parts if p)
            if only:
                diff += ("; " if diff else "") + "channels " + ", ".join(("+" if k not in pa else "-") + k
                                                                          for k in only)
        notes = ", ".join(keys[:12]) + (f" (+{len(keys) - 12} more)" if len(keys) > 12 else "")
        if allowed:
            notes += ("; " if notes else "") + "accepted: " + ", ".join(allowed)
        if not same_pixels:
            changed_here = [k for k in changed if k in pa and k in pb]
            if changed_here:
                notes += ("; " if notes else "") + "pixels differ in " + ", ".join(changed_here[:6]) + (
                    f" (+{len(changed_here) - 6} more)" if len(changed_here) > 6 else "")
        rows.append((name, "yes" if same_pixels else "NO", "yes" if not keys else "NO", diff, notes))
        bad += (not same_pixels) or bool(keys)
    width = max([len(r[0]) for r in rows] + [4])
    out.write(f"{'case':{width}s}  pixels  stats  max|diff|  stats keys that differ / notes\n")
    for name, px, st, diff, keys in rows:
        out.write(f"{name:{width}s}  {px:6s}  {st:5s}  {diff or '':9s}  {keys}\n")
    out.write(f"\n{len(rows)} cases, {bad} differ{'' if bad else ' (all identical)'}\n")
    notes = {"matrix": "the two records were made with other matrix settings (size, samples, seed)",
             "scene_file": "the two records rendered different scene files (scene_file_json): "
                           "the engine/scene-file cases cannot agree"}
    for key, note in notes.items():
        if old.get(key) != new.get(key):
            out.write(f"note: {note}\n")
    return 1 if bad else 0


def case_names(old, new, cases_wanted, patterns):
    """The names to compare, in the matrix's order: the selected cases either record has, then
    selected recorded ones the matrix no longer has."""
    recorded = list(old["cases"]) + [n for n in new["cases"] if n not in old["cases"]]
    names = [c.name for c in cases_wanted if c.name in recorded]
    return names + [c.name for c in select([Case(n, "", []) for n in recorded], patterns) if c.name not in names]


# -- command line ---------------------------------------------------------------------------------
def main(argv=None) -> int:
    only_help = "only the cases whose name matches (fnmatch, or a substring); repeatable"
    # --only before or after the mode (a subparser's values replace the main parser's: two dests).
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--only", action="append", dest="only_after", default=[], metavar="PATTERN", help=only_help)
    parser = argparse.ArgumentParser(prog="check_identity.py", description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--only", action="append", default=None, metavar="PATTERN", help=only_help)
    parser.add_argument("--list", action="store_true", help="print the cases and their command lines")
    sub = parser.add_subparsers(dest="mode")
    run_options = argparse.ArgumentParser(add_help=False)
    run_options.add_argument("--python", default=sys.executable, help="the interpreter to run (default: this one)")
    run_options.add_argument("--repo", default=REPO, help="the checkout to render with (default: %(default)s)")
    run_options.add_argument("--timeout", type=float, default=600.0, help="seconds per case (default 600)")
    run_options.add_argument("--images", metavar="DIR", help="keep the images here (default: OUT.images beside "
                             "the JSON; 'none' to keep none)")
    run_options.add_argument("--quiet", action="store_true", help="no progress lines")
    rec = sub.add_parser("record", parents=[common, run_options], help="render the matrix, write the JSON")
    rec.add_argument("--out", required=True, metavar="FILE.json")
    intended = argparse.ArgumentParser(add_help=False)     # compare and diff: intended stats changes
    intended.add_argument("--renamed", action="append", default=[], metavar="OLD=NEW",
                          help="a stats key renamed on purpose: the baseline's OLD is compared as NEW; repeatable")
    intended.add_argument("--accept", action="append", default=[], metavar="KEY",
                          help="a stats key (fnmatch pattern of the dotted key) whose change is intended: "
                               "listed, not counted; repeatable.  Pixels are never accepted")
    cmp_ = sub.add_parser("compare", parents=[common, run_options, intended],
                          help="render the matrix, compare with a record")
    cmp_.add_argument("--baseline", required=True, metavar="FILE.json")
    cmp_.add_argument("--out", metavar="NEW.json", help="also write the new record here")
    dif = sub.add_parser("diff", parents=[common, intended], help="compare two records (no rendering)")
    dif.add_argument("old", metavar="OLD.json")
    dif.add_argument("new", metavar="NEW.json")
    args = parser.parse_args(argv)
    args.only = (args.only or []) + getattr(args, "only_after", [])
    renames = {}
    for item in getattr(args, "renamed", []):
        old_key, sep, new_key = item.partition("=")
        if not sep or not old_key or not new_key:
            parser.error(f"--renamed wants OLD=NEW, got {item!r}")
        renames[old_key] = new_key

    repo = os.path.abspath(getattr(args, "repo", REPO))
    cases = select(build_cases(repo), args.only)
    if args.list or args.mode is None:
        if not args.list:
            parser.print_help()
            return 2
        for case in cases:
            cmd = case.command("python", "<out>")[1:]
            print(f"{case.name:48s} {' '.join(cmd)}" + (f"  [needs {case.needs}]" if case.needs else ""))
        print(f"{len(cases)} cases")
        return 0
    if not cases:
        print(f"check_identity: no case matches {args.only}", file=sys.stderr)
        return 2
    log = (lambda msg: None) if getattr(args, "quiet", False) else (lambda msg: print(msg, file=sys.stderr, flush=True))

    if args.mode == "diff":
        old, new = load_json(args.old), load_json(args.new)
        return compare_records(old, new, case_names(old, new, cases, args.only), renames=renames, accepted=args.accept)

    python = args.python

    def images_for(out):
        return None if args.images == "none" else os.path.abspath(args.images or os.path.splitext(out)[0] + ".images")
    if args.mode == "record":
        out = args.out
        images = images_for(out)
        write_json(out, run_matrix(cases, python, repo, out, images, args.timeout, log))
        log(f"wrote {out}" + (f" and {images}/" if images else ""))
        return 0

    old = load_json(args.baseline)
    if args.out and os.path.abspath(args.out) == os.path.abspath(args.baseline):
        print("check_identity: --out must not be the baseline itself", file=sys.stderr)
        return 2
    # The new images: kept with --out or --images, else in a temporary directory for the table only.
    scratch = not (args.out or args.images)
    images = tempfile.mkdtemp(prefix="check-identity-images-") if scratch else images_for(args.out)
    try:
        new = run_matrix(cases, python, repo, args.out, images, args.timeout, log)
        new["_dir"] = os.path.dirname(os.path.abspath(args.out)) if args.out else ""
        if images and not args.out:
            new["images"] = images                      # absolute
        code = compare_records(old, new, case_names(old, new, cases, args.only), renames=renames, accepted=args.accept)
        if args.out:
            write_json(args.out, {k: v for k, v in new.items() if not k.startswith("_")})
            log(f"wrote {args.out}")
        return code
    finally:
        if scratch:
            shutil.rmtree(images, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
