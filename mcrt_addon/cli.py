"""Command line: render a .blend headless with TNCG15 MC or a fair Cycles reference, and the
export benchmark.  Runs in the ``bpy`` module (Blender 5.0.1 as a Python package):

  python -m mcrt_addon render FILE.blend -o OUT.exr [--engine TNCG15_MC|CYCLES] [--samples N]
         [--shadow-rays N] [--max-depth N] [--accelerator NAME] [--fresnel schlick|exact]
         [--estimator report|solid-angle|mis] [--threads N] [--seed N] [--resolution W H]
         [--frame F] [--stats-json PATH]
  python -m mcrt_addon bench-export [--triangles N]
  python -m mcrt_addon bench-estimators [--scenes ...] [--resolution W H] [--samples N]
         [--reference-samples N] [--max-depth N] [--out docs/estimators.json]
         (light-sampling estimators vs Cycles; see mcrt_addon/bench_estimators.py)
"""
import argparse
import json
import os
import sys
import time

ESTIMATOR_CHOICES = ("report", "solid-angle", "mis")


def build_parser():
    parser = argparse.ArgumentParser(prog="python -m mcrt_addon",
                                     description="TNCG15 MC headless tools (bpy module)")
    sub = parser.add_subparsers(dest="command", required=True)
    r = sub.add_parser("render", help="render a .blend file to a linear EXR")
    r.add_argument("file", help=".blend file")
    r.add_argument("-o", "--output", required=True, help="output EXR path (linear, 32-bit float)")
    r.add_argument("--engine", default="TNCG15_MC", choices=("TNCG15_MC", "CYCLES"),
                   type=str.upper)
    r.add_argument("--samples", type=int)
    r.add_argument("--shadow-rays", type=int)
    r.add_argument("--max-depth", type=int)
    r.add_argument("--accelerator", choices=("auto", "embree", "octree", "brute"), type=str.lower)
    r.add_argument("--fresnel", choices=("schlick", "exact"), type=str.lower)
    r.add_argument("--estimator", choices=ESTIMATOR_CHOICES, type=str.lower,
                   help="direct-light estimator (TNCG15 MC only)")
    r.add_argument("--nested-dielectrics", action="store_true",
                   help="track nested glass media (TNCG15 MC only; Cycles has no such model)")
    r.add_argument("--threads", type=int)
    r.add_argument("--seed", type=int)
    r.add_argument("--resolution", type=int, nargs=2, metavar=("W", "H"))
    r.add_argument("--frame", type=int, help="frame to render (default: the file's current frame)")
    r.add_argument("--stats-json", help="write render statistics (JSON) here")
    r.add_argument("--png", help="also write an sRGB PNG of the render here")
    b = sub.add_parser("bench-export", help="time the exporter on a large mesh (prints figures)")
    b.add_argument("--triangles", type=int, default=1_000_000)
    b.add_argument("--instances", type=int, default=100)
    from .bench_estimators import add_arguments
    e = sub.add_parser("bench-estimators", help="light-sampling estimators vs Cycles: time, MSE, "
                       "efficiency (markdown table + JSON)")
    add_arguments(e)
    return parser


def _check_positive(parser, args):
    for name in ("samples", "threads"):
        value = getattr(args, name, None)
        if value is not None and value < (1 if name == "samples" else 0):
            parser.error(f"--{name.replace('_', '-')} must be {'>= 1' if name == 'samples' else '>= 0'}")
    for name in ("shadow_rays", "max_depth", "seed"):
        value = getattr(args, name, None)
        if value is not None and value < 0:
            parser.error(f"--{name.replace('_', '-')} must be >= 0")
    if getattr(args, "resolution", None) and min(args.resolution) < 1:
        parser.error("--resolution must be positive")


def apply_tncg15_settings(props, args):
    if args.samples is not None:
        props.samples = args.samples
    if args.shadow_rays is not None:
        props.shadow_rays = args.shadow_rays
    if args.max_depth is not None:
        props.max_depth = args.max_depth
    if args.accelerator is not None:
        props.accelerator = args.accelerator.upper()
    if args.fresnel is not None:
        props.fresnel = args.fresnel.upper()
    if getattr(args, "estimator", None) is not None:
        if hasattr(props, "estimator"):
            props.estimator = args.estimator.upper().replace("-", "_")   # REPORT, SOLID_ANGLE, MIS
        else:
            print("warning: this add-on has no estimator setting yet; --estimator ignored",
                  file=sys.stderr)
    if getattr(args, "nested_dielectrics", False):
        props.nested_dielectrics = True
    if args.threads is not None:
        props.threads = args.threads
    if args.seed is not None:
        props.seed = args.seed


def set_exr_output(scene, path):
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    settings.color_mode = "RGB"
    settings.exr_codec = "ZIP"
    scene.render.filepath = path
    scene.render.use_file_extension = False
    scene.render.use_compositing = False
    scene.render.use_sequencer = False


def render_file(args):
    import bpy
    import mcrt_addon
    from mcrt_addon import engine as engine_module
    from mcrt_addon.reference import setup_cycles_reference

    if not os.path.isfile(args.file):
        print(f"error: no such file: {args.file}", file=sys.stderr)
        return 2
    ensure_registered(mcrt_addon)
    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(args.file), load_ui=False)
    scene = bpy.context.scene
    if args.frame is not None:
        scene.frame_set(args.frame)
    if args.resolution:
        scene.render.resolution_x, scene.render.resolution_y = args.resolution
        scene.render.resolution_percentage = 100
    props = scene.tncg15
    apply_tncg15_settings(props, args)
    if args.engine == "CYCLES":
        setup_cycles_reference(scene, samples=props.samples, max_depth=props.max_depth, seed=props.seed,
                               threads=props.threads)
    else:
        scene.render.engine = "TNCG15_MC"
    out = os.path.abspath(args.output)
    os.makedirs(os.path.dirname(out) or ".", exist_ok=True)
    set_exr_output(scene, out)
    if os.path.exists(out):
        os.remove(out)
    engine_module.LAST_RENDER.clear()
    t0 = time.perf_counter()
    try:
        bpy.ops.render.render(write_still=True)
    except RuntimeError as exc:
        # Blender's own refusals ("Cannot render, no camera") arrive as "Error: ...\n"
        msg = engine_module.LAST_RENDER.get("error") or str(exc).strip().removeprefix("Error: ")
        print(f"error: {msg}", file=sys.stderr)
        return 1
    wall = time.perf_counter() - t0
    last = dict(engine_module.LAST_RENDER)
    if args.engine == "TNCG15_MC" and last.get("error"):
        print(f"error: {last['error']}", file=sys.stderr)
        return 1
    if not os.path.isfile(out):
        print("error: no image was written", file=sys.stderr)
        return 1
    stats = {}
    if args.engine == "TNCG15_MC":
        stats.update(last.get("stats") or {})
        stats["export"] = last.get("export")
        stats["warnings"] = last.get("warnings")
        stats["cancelled"] = last.get("cancelled")
        stats.setdefault("render_seconds", wall)
        for w in last.get("warnings") or []:
            print(f"warning: {w}", file=sys.stderr)
    else:
        stats.update(engine="CYCLES", render_seconds=wall, samples=scene.cycles.samples,
                     max_bounces=scene.cycles.max_bounces, seed=scene.cycles.seed,
                     blender=bpy.app.version_string)
    pct = scene.render.resolution_percentage / 100.0
    stats.setdefault("resolution", [int(scene.render.resolution_x * pct), int(scene.render.resolution_y * pct)])
    stats["wall_seconds"] = wall
    stats["file"] = os.path.abspath(args.file)
    stats["output"] = out
    print(f"{args.engine}: wrote {out} in {wall:.2f} s (render {stats['render_seconds']:.2f} s)")
    if args.png:
        from mcrt_addon import bridge
        film = bridge.module("film")
        os.makedirs(os.path.dirname(os.path.abspath(args.png)) or ".", exist_ok=True)
        film.write_png(args.png, film.read_image(out)[..., :3])
        print(f"{args.engine}: wrote {args.png}")
    if args.stats_json:
        with open(args.stats_json, "w") as fh:
            json.dump(stats, fh, indent=2, default=_json_default)
    return 0


def _json_default(value):
    try:
        import numpy as np
        if isinstance(value, np.generic):
            return value.item()
        if isinstance(value, np.ndarray):
            return value.tolist()
    except ImportError:
        pass
    if isinstance(value, (set, tuple)):
        return list(value)
    return str(value)


def ensure_registered(mcrt_addon):
    import bpy
    if not (hasattr(bpy.types.Scene, "tncg15") and mcrt_addon.engine.TNCG15RenderEngine.is_registered):
        mcrt_addon.register()


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    _check_positive(parser, args)
    if args.command == "render":
        return render_file(args)
    if args.command == "bench-estimators":
        from .bench_estimators import bench_estimators, check_arguments
        check_arguments(parser, args)
        return bench_estimators(args)
    if args.command == "bench-export":
        from .bench import bench_export
        return bench_export(args.triangles, args.instances)
    return 2
