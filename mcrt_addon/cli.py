"""Command line: render a .blend headless with TNCG15 MC or a fair Cycles reference, and the
export benchmark.  Runs in the ``bpy`` module (Blender 5.0.1 as a Python package):

  python -m mcrt_addon render FILE.blend -o OUT.exr|OUT.png [--png OUT.png] [--engine TNCG15_MC|CYCLES]
         [--resolution W H] [--frame F] [--stats-json PATH] [--cluster ADDRESS] [settings...]
  python -m mcrt_addon estimate FILE.blend --noise-target REL [--samples N] [--min-samples N] [--no-adaptive]
         [--threads N] [--seed N] [--resolution W H] [--pilot-samples N] [--json]
  python -m mcrt_addon bench-export [--triangles N] [--instances N]
  python -m mcrt_addon bench-estimators [--scenes ...] [--resolution W H] [--samples N]
         [--reference-samples N] [--max-depth N] [--out docs/estimators.json]
         (light-sampling estimators vs Cycles; see mcrt_addon/bench_estimators.py)
  python -m mcrt_addon bench-materials [--scenes ...] [--resolution W H] [--samples N]
         [--reference-samples N] [--max-depth N] [--out docs/materials-efficiency.json]
         [--tncg15-pool workers|threads]
         (the material sample scenes vs Cycles, TNCG15 MC timed as F12 renders on the add-on's
         worker processes, or on threads in Blender's process; see mcrt_addon/bench_materials.py)

The settings (--samples, --max-depth, --noise-target, ...) are the rows of the settings table
(engine/core/settings.py; listed in docs/settings.md); a flag not given keeps the file's value.
"""
import json
import os
import shutil
import sys
import tempfile
import time

from . import bridge, properties
from .headless import ensure_registered, set_exr_output
from .reference import LIGHT_PATHS

# The settings the Cycles reference render also takes (mcrt_addon/reference.py); the others are TNCG15 MC's.
CYCLES_REFERENCE = ("samples", "max_depth", "seed", "threads") + tuple(LIGHT_PATHS)
# The settings `estimate` takes besides --noise-target (the pilot render decides the others).
ESTIMATE_SETTINGS = ("samples", "min_samples", "adaptive", "threads", "seed")
PROG = "python -m mcrt_addon"
MAX_FRAME = 1048574                    # Blender's MAXFRAME
MAX_RESOLUTION = 65536                 # Blender's largest resolution_x / resolution_y
BLEND_MAGIC = (b"BLENDER", b"\x1f\x8b", b"\x28\xb5\x2f\xfd")   # plain, gzip, zstd


def build_parser():
    cli = bridge.module("cli.main")             # the tracer's: one-line errors
    args_of = bridge.module("cli.settings_args")   # the settings table's arguments
    table = bridge.settings_table()
    bounded_int = args_of.bounded_int
    parser = cli.OneLineParser(prog=PROG, description="TNCG15 MC headless tools (bpy module)")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=cli.OneLineParser)
    r = sub.add_parser("render", help="render a .blend file to a linear EXR")
    r.add_argument("file", help=".blend file")
    r.add_argument("-o", "--output", required=True,
                   help="output image: .exr (linear, 32-bit float) or .png (sRGB); '//' = beside the .blend")
    r.add_argument("--engine", default="TNCG15_MC", choices=("TNCG15_MC", "CYCLES"),
                   type=str.upper)
    r.add_argument("--cluster", metavar="ADDRESS",
                   help="render on a Dask cluster: its scheduler's tcp://HOST:PORT, or 'local' (TNCG15 MC only; "
                        "as the add-on's Render cluster preference)")
    bridge.module("cli.cluster_args").add_tls_options(r)
    r.add_argument("--resolution", type=bounded_int(1, MAX_RESOLUTION), nargs=2, metavar=("W", "H"))
    r.add_argument("--frame", type=bounded_int(-MAX_FRAME, MAX_FRAME),
                   help="frame to render (default: the file's current frame)")
    r.add_argument("--stats-json", help="write render statistics (JSON) here")
    r.add_argument("--png", help="also write an sRGB PNG of the render here")
    # A setting's flag not given keeps the .blend file's value (the Light Paths rows: the preset's).
    args_of.add_preset_argument(r, extra=("file",), note="; file: the .blend file's own values")
    args_of.add_setting_arguments(r, table.settings_for(table.ADDON_CLI), table_defaults=False, any_case=True,
                                  note=lambda s: "" if s.name in CYCLES_REFERENCE else " (TNCG15 MC only)")
    es = sub.add_parser("estimate", help="predict the render time to reach --noise-target from a short pilot render")
    es.add_argument("file", help=".blend file")
    es.add_argument("--noise-target", type=args_of.bounded_float(*table.SETTING["noise_target"].limits),
                    required=True, metavar="REL", help="the estimated relative error to reach, e.g. 0.01")
    args_of.add_setting_arguments(es, [table.SETTING[name] for name in ESTIMATE_SETTINGS], table_defaults=False)
    es.add_argument("--resolution", type=bounded_int(1, MAX_RESOLUTION), nargs=2, metavar=("W", "H"))
    es.add_argument("--pilot-samples", type=bounded_int(2, 4096), default=64)
    es.add_argument("--json", action="store_true", help="also print the prediction as JSON")
    b = sub.add_parser("bench-export", help="time the exporter on a large mesh (prints figures)")
    b.add_argument("--triangles", type=bounded_int(1, 100_000_000), default=1_000_000)
    b.add_argument("--instances", type=bounded_int(1, 1_000_000), default=100)
    from .bench_estimators import add_arguments
    e = sub.add_parser("bench-estimators", help="light-sampling estimators vs Cycles: time, MSE, "
                       "efficiency (markdown table + JSON)")
    add_arguments(e)
    from .bench_materials import add_arguments as add_material_arguments
    m = sub.add_parser("bench-materials", help="the material sample scenes vs Cycles: time, MSE, efficiency, "
                       "and the time against diffuse materials (markdown table + JSON)")
    add_material_arguments(m)
    return parser


def apply_tncg15_settings(props, args):
    """The settings given on the command line onto the scene's properties (mcrt_addon/properties.py);
    the others keep the file's values, but for the Light Paths rows of --preset (fair: the
    reference settings; file: the file's).  --passes is the view layer's (mcrt_addon/passes.py);
    --film-transparent is Blender's scene.render.film_transparent."""
    table = bridge.settings_table()
    preset = getattr(args, "preset", "file")
    if preset != "file":
        properties.apply_preset(props, preset)
    given = bridge.module("cli.settings_args").setting_values(args, properties.SCENE_SETTINGS, given_only=True)
    for name, value in given.items():
        props.set_setting(table.SETTING[name], value)
    if getattr(args, "film_transparent", False):     # Blender's own Film > Transparent
        props.id_data.render.film_transparent = True


def error(message, code=2):
    print(f"{PROG}: error: {message}", file=sys.stderr)
    return code


def blend_problem(path):
    """Why ``path`` cannot be a .blend file, or None (Blender's own error is three lines)."""
    if not os.path.isfile(path):
        return f"no such file: {path}"
    try:
        with open(path, "rb") as fh:
            head = fh.read(12)
    except OSError as exc:
        return f"cannot read '{path}': {exc.strerror}"
    if not head.startswith(BLEND_MAGIC):
        return f"'{path}' is not a .blend file"
    return None


def render_file(args):
    """Checks everything it can before Blender opens the file; renders into a private temporary
    directory (Blender's temp files and its EXR), then writes each output atomically."""
    output = bridge.module("film.output")
    if getattr(args, "cluster", None):
        if args.cluster != "local":           # a malformed address: one line before Blender opens the file
            try:
                bridge.module("pools.dask_cluster").scheduler_address(args.cluster)
            except bridge.module("core.errors").SceneError as exc:
                return error(exc)
        os.environ["TNCG15_CLUSTER"] = args.cluster      # read by worker_python.render_cluster()
    try:
        bridge.module("cli.cluster_args").use_tls_options(args)    # tls://: the certificates (TNCG15_TLS_*)
    except bridge.module("core.errors").SceneError as exc:
        return error(exc)
    blend = os.path.abspath(args.file)
    problem = blend_problem(blend)
    if problem:
        return error(problem)
    try:
        outputs = output.check_outputs([("-o", args.output, "image"), ("--png", args.png, "png"),
                                        ("--stats-json", args.stats_json, "json")],
                                       inputs=[(blend, "the .blend rendered")], base_dir=os.path.dirname(blend))
        if (args.passes or args.denoise) and args.engine != "TNCG15_MC":
            raise output.OutputError("--passes/--denoise are for --engine TNCG15_MC")
        bridge.module("cli.main").check_pass_outputs(args, outputs)
    except output.OutputError as exc:
        return error(exc)
    stop = bridge.module("cli.signals").StopRequest(PROG).install()
    private = tempfile.mkdtemp(prefix="tncg15-")       # 0700; Blender's quit.blend would land here
    try:
        return render_in(args, blend, outputs, stop, private)
    finally:
        shutil.rmtree(private, ignore_errors=True)


def open_blend(blend, private):
    """Open `blend` in Blender with the add-on registered and Blender's temporary files in
    `private`; None, or the one-line reason it could not be opened."""
    import bpy
    import mcrt_addon
    bpy.context.preferences.filepaths.temporary_directory = private
    ensure_registered(mcrt_addon)
    try:
        bpy.ops.wm.open_mainfile(filepath=blend, load_ui=False)
    except RuntimeError as exc:
        return str(exc).strip().removeprefix("Error: ").splitlines()[0]
    ensure_registered(mcrt_addon)
    return None


def files_read(blend):
    """(absolute path, what it is) of every file a render of the open `blend` reads: the .blend, its
    linked libraries, the files of its image textures (each tile of a UDIM image)."""
    import bpy
    files = [(blend, "the .blend rendered")]
    for lib in bpy.data.libraries:
        files.append((bpy.path.abspath(lib.filepath, library=lib.library), f"the library '{lib.name}' linked by the .blend"))
    for image in bpy.data.images:
        if not image.filepath or image.packed_file is not None or image.source not in ("FILE", "SEQUENCE", "TILED"):
            continue
        path = bpy.path.abspath(image.filepath, library=image.library)
        what = f"the file of image texture '{image.name}'"
        if image.source == "TILED" and "<UDIM>" in path:
            files.extend((path.replace("<UDIM>", str(tile.number)), what) for tile in image.tiles)
        else:
            files.append((path, what))
    return [(os.path.abspath(path), what) for path, what in files]


def render_in(args, blend, outputs, stop, private):
    import bpy
    from mcrt_addon import render_engine as engine_module
    from mcrt_addon.reference import setup_cycles_reference

    problem = open_blend(blend, private)
    if problem:
        return error(problem)
    try:
        bridge.module("film.output").refuse_inputs(outputs, files_read(blend))
    except bridge.module("film.output").OutputError as exc:
        return error(exc)
    scene = bpy.context.scene
    if args.frame is not None:
        scene.frame_set(args.frame)
    if args.resolution:
        scene.render.resolution_x, scene.render.resolution_y = args.resolution
        scene.render.resolution_percentage = 100
    props = scene.tncg15
    apply_tncg15_settings(props, args)
    if args.engine == "CYCLES":
        from mcrt_addon.reference import FilmSettings
        setup_cycles_reference(scene, samples=props.samples, max_depth=props.max_depth, seed=props.seed,
                               threads=props.threads,
                               film=FilmSettings.of(props.to_settings(bridge.settings_class())),
                               **{name: getattr(props, name) for name in LIGHT_PATHS})
    else:
        scene.render.engine = "TNCG15_MC"
    rendered = os.path.join(private, "render.exr")
    set_exr_output(scene, rendered)
    layered = bool(args.passes or args.denoise) and args.engine == "TNCG15_MC"
    if layered:
        from mcrt_addon.passes import apply_pass_options, set_multilayer_output
        apply_pass_options(scene, args.passes, args.denoise)
        set_multilayer_output(scene)
    if stop.requested():
        return stop.report_exit()
    engine_module.STOP_REQUESTS.append(stop.requested)
    t0 = time.perf_counter()
    try:
        with engine_module.capture_reports() as reports:
            bpy.ops.render.render(write_still=True)
    except RuntimeError as exc:
        # Blender's own refusals ("Cannot render, no camera") arrive as "Error: ...\n"
        msg = (reports[-1].error if reports else None) or str(exc).strip().removeprefix("Error: ")
        if not (reports and reports[-1].partial is not None):
            return error(msg, 1)
        return write_finished_tiles(args, scene, reports[-1], outputs, msg, time.perf_counter() - t0)
    finally:
        engine_module.STOP_REQUESTS.remove(stop.requested)
    wall = time.perf_counter() - t0
    last = reports[-1] if reports else engine_module.RenderReport()
    if args.engine == "TNCG15_MC" and last.error:
        return error(last.error, 1)
    if not os.path.isfile(rendered):
        return error("no image was written", 1) if not stop.requested() else stop.report_exit()
    stats = render_stats(args, scene, last, wall)
    stats["file"] = blend
    stats["output"] = [o.path for o in outputs if o.kind != "json"]
    try:
        if layered:
            from mcrt_addon.passes import passes_from_channels
            channels = bridge.module("film.passes").read_multilayer_exr(rendered)
            image, passes = passes_from_channels(channels, args.passes)
            if scene.render.film_transparent:           # premultiplied RGBA, as Blender wrote it
                import numpy as np
                image = np.concatenate([image, channels["ViewLayer.Combined.A"][..., None]], axis=-1)
            write_outputs(outputs, image, stats, passes)
        else:
            image = bridge.module("film.image_files").read_image(rendered)
            write_outputs(outputs, image[..., :4] if scene.render.film_transparent else image[..., :3], stats)
    except (bridge.module("film.output").OutputError, OSError) as exc:
        return error(exc, 1)
    print(f"{args.engine}: wrote {', '.join(o.path for o in outputs)} in {wall:.2f} s "
          f"(render {stats['render_seconds']:.2f} s)")
    return stop.report_exit()


def estimate_file(args):
    """`estimate FILE.blend --noise-target REL`: a pilot render and the predicted time."""
    blend = os.path.abspath(args.file)
    problem = blend_problem(blend)
    if problem:
        return error(problem)
    if args.noise_target <= 0:
        return error("--noise-target must be above 0, e.g. 0.01")
    private = tempfile.mkdtemp(prefix="tncg15-")
    try:
        import bpy
        from mcrt_addon.estimate import estimate_scene
        problem = open_blend(blend, private)
        if problem:
            return error(problem)
        scene = bpy.context.scene
        if args.resolution:
            scene.render.resolution_x, scene.render.resolution_y = args.resolution
            scene.render.resolution_percentage = 100
        apply_tncg15_settings(scene.tncg15, args)
        if scene.camera is None:
            return error(f"scene '{scene.name}' has no camera")
        try:
            result = estimate_scene(scene, bpy.context.evaluated_depsgraph_get(), args.noise_target,
                                    pilot_samples=args.pilot_samples)
        except Exception as exc:          # noqa: BLE001 - export and worker problems: one line
            return error(str(exc).strip().splitlines()[0], 1)
        print(bridge.module("rendering.estimate").describe(result))
        if args.json:
            print(json.dumps(result, default=_json_default))
        return 0
    finally:
        shutil.rmtree(private, ignore_errors=True)


def write_finished_tiles(args, scene, last, outputs, message, wall):
    """No worker left (engine/core/errors.py WorkersLost): Blender writes no image after an error,
    so the finished tiles (last.partial, the tracer's RenderResult) are written here; exit 1."""
    last.stats = dict(last.partial.stats)
    stats = render_stats(args, scene, last, wall)
    try:
        write_outputs(outputs, last.partial.image, stats)
    except (bridge.module("film.output").OutputError, OSError) as exc:
        return error(exc, 1)
    return error(f"{message} (wrote the finished tiles to {', '.join(o.path for o in outputs)})", 1)


def write_outputs(outputs, image, stats, passes=None):
    output = bridge.module("film.output")
    for target in outputs:
        if target.kind == "json":
            output.write_text(target, json.dumps(stats, indent=2, default=_json_default))
        elif passes is not None and target.option == "-o":
            output.write_multilayer(target, image, passes,       # the layers of python -m engine render
                                    bridge.module("cli.main").error_metadata(stats))
        else:
            output.write_image(target, image, bridge.module("cli.main").error_metadata(stats))


def render_stats(args, scene, last, wall):
    import bpy
    stats = {}
    if args.engine == "TNCG15_MC":
        stats.update(last.stats or {})
        stats["export"] = last.export
        stats["warnings"] = last.warnings
        stats["cancelled"] = last.cancelled
        stats.setdefault("render_seconds", wall)
        for w in last.warnings or []:
            print(f"warning: {w}", file=sys.stderr)
    else:
        stats.update(engine="CYCLES", render_seconds=wall, samples=scene.cycles.samples,
                     max_bounces=scene.cycles.max_bounces, seed=scene.cycles.seed,
                     blender=bpy.app.version_string, light_paths=cycles_light_paths(scene.cycles))
    pct = scene.render.resolution_percentage / 100.0
    stats.setdefault("resolution", [int(scene.render.resolution_x * pct), int(scene.render.resolution_y * pct)])
    stats["wall_seconds"] = wall
    return stats


def cycles_light_paths(cycles) -> dict:
    """Cycles' Light Paths settings of a render (the stats of --engine CYCLES)."""
    return {name: getattr(cycles, name) for name in ("diffuse_bounces", "glossy_bounces", "transmission_bounces",
                                                      "transparent_max_bounces", "sample_clamp_direct",
                                                      "sample_clamp_indirect", "blur_glossy", "caustics_reflective",
                                                      "caustics_refractive") if hasattr(cycles, name)}


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


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command == "render":
        return render_file(args)
    if args.command == "estimate":
        return estimate_file(args)
    if args.command == "bench-estimators":
        from .bench_estimators import bench_estimators, check_arguments
        check_arguments(parser, args)
        return bench_estimators(args)
    if args.command == "bench-materials":
        from .bench_materials import bench_materials, check_arguments
        check_arguments(parser, args)
        return bench_materials(args)
    if args.command == "bench-export":
        from .bench import bench_export
        return bench_export(args.triangles, args.instances)
    return 2
