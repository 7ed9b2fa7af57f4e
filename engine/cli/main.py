"""The tracer's command line, `python -m engine`: render, estimate, bench, bench-cluster, study and
worker (docs/command-line.md).  The settings flags come from the settings table
(engine/cli/settings_args.py); a render goes through engine/api.py render."""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

from ..core.errors import SceneError, WorkersLost
from ..film.output import OutputError, check_outputs, refuse_inputs, write_image, write_text
from ..core.settings import ENGINE_CLI, INT32_MAX, PASSES, RenderSettings, preset_values, settings_for
from .settings_args import add_preset_argument, add_setting_arguments, bounded_int, setting_values
from .signals import StopRequest
from .cluster_args import add_tls_options, use_tls_options

PROG = "python -m engine"


class OneLineParser(argparse.ArgumentParser):
    """Bad arguments: one line on stderr, exit code 2."""

    def error(self, message):
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        raise SystemExit(2)


positive_int = bounded_int(1, INT32_MAX)
MAX_RESOLUTION = 65536


def add_settings_arguments(p):
    """Every setting of the table that this command line exposes (engine/cli/settings_args.py)."""
    add_preset_argument(p)
    add_setting_arguments(p, settings_for(ENGINE_CLI))


def error_metadata(stats) -> list:
    """EXR header attributes of the error estimate (docs/user-guide.md: Stopping rules)."""
    out = []
    for key in ("estimated_rel_error", "seconds_to_target", "target_rel_error"):
        value = stats.get(key)
        if isinstance(value, (int, float)) and value == value:
            out.append((f"tncg15:{key}", float(value)))
    return out


def settings_from_args(args) -> RenderSettings:
    """The settings of a command: the table's flags, and the passes the denoiser needs."""
    values = setting_values(args, settings_for(ENGINE_CLI), preset=preset_values(args.preset))
    values["passes"] = traced_passes(args)
    return RenderSettings(**values)


def traced_passes(args) -> tuple:
    """The passes to render: those asked for, plus albedo and normal for the denoiser."""
    wanted = set(args.passes) | ({"albedo", "normal"} if args.denoise else set())
    return tuple(p for p in PASSES if p in wanted)


def check_pass_outputs(args, outputs) -> None:
    """Passes are layers of an EXR: refused (one line) when -o is not an .exr; the denoiser must
    import before anything is rendered."""
    if (args.passes or args.denoise) and outputs and outputs[0].kind != "exr":
        raise OutputError(f"-o '{outputs[0].path}': --passes/--denoise need an .exr output (layers)")
    if args.denoise:
        from ..film.denoise import available
        problem = available()
        if problem:
            raise OutputError(problem)


def write_render_image(output, result, args, scene=None) -> None:
    """-o: a multi-layer EXR when passes or the denoiser are on (engine/film/passes.py), else as before."""
    from ..film.output import write_multilayer
    if output.kind == "exr" and (args.passes or args.denoise):
        from ..film.passes import cryptomatte_metadata
        write_multilayer(output, result.combined(), result.passes,
                         error_metadata(result.stats) + (cryptomatte_metadata(scene, args.passes or ()) if scene is not None else []))
    else:
        write_image(output, result.combined(), error_metadata(result.stats))


def progress_bar(stream=sys.stderr):
    start = time.perf_counter()

    def show(fraction, message):
        width = 30
        filled = int(round(fraction * width))
        elapsed = time.perf_counter() - start
        stream.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {fraction * 100:5.1f}%  "
                     f"{message}  {elapsed:6.1f}s")
        if fraction >= 1.0:
            stream.write("\n")
        stream.flush()
    return show


def scene_inputs(path):
    """The files a render reads: never to be written."""
    return [(path, "the scene file"), (os.path.splitext(path)[0] + ".npz", "the scene's arrays (NPZ)")] if path else []


def scene_and_settings(args):
    """The scene (a file or --builtin, at --resolution) and the validated settings of a command."""
    from ..scene.builtin import BUILTIN_SCENES
    from ..scene.files import load_scene
    if args.scene and args.builtin:
        raise SceneError("give a scene file or --builtin, not both")
    scene = load_scene(args.scene) if args.scene else BUILTIN_SCENES[args.builtin or "cornell"]()
    if args.resolution:
        scene.resolution = tuple(args.resolution)
    settings = settings_from_args(args)
    settings.validate()
    return scene, settings


def cmd_render(args) -> int:
    from ..rendering.memory import check_memory
    from ..api import make_pool, render
    from ..pools.dask_cluster import ConnectStopped

    stop = StopRequest(PROG).install()
    use_tls_options(args)
    outputs = check_outputs([("-o", args.output, "image"), ("--png", args.png, "png"),
                             ("--stats-json", args.stats_json, "json")], inputs=scene_inputs(args.scene),
                            base_dir=os.path.dirname(os.path.abspath(args.scene)) if args.scene else None)
    scene, settings = scene_and_settings(args)
    refuse_inputs(outputs, [(t.path, f"the file of the scene's texture '{t.name}'")
                            for t in scene.textures if getattr(t, "path", None)])
    check_pass_outputs(args, outputs)
    scene.validate()
    check_memory(scene, settings, pool=("workers" if args.cluster == "local" else "dask") if args.cluster else None)
    if stop.requested():
        return stop.report_exit()
    log = (lambda *a: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    try:
        pool = (make_pool(f"dask:{args.cluster}", settings.resolved_threads(), log=log, should_cancel=stop.requested)
                if args.cluster else None)
    except ConnectStopped:                      # Ctrl-C while connecting: nothing rendered, nothing written
        return stop.report_exit()
    try:
        result = render(scene, settings, pool=pool, on_progress=None if args.quiet else progress_bar(),
                        should_cancel=stop.requested, log=log)
    except WorkersLost as exc:                  # no worker left: one line, and the finished tiles written
        if exc.result is None:
            raise
        sys.stderr.write(f"\n{PROG}: error: {exc} (writing the finished tiles)\n")
        result, lost = exc.result, exc
    else:
        lost = None
    if args.denoise and not result.cancelled:
        from ..film.denoise import denoise_result
        denoise_result(result)
    stats = result.stats
    bad_pixels = int((~np.isfinite(result.image)).any(axis=-1).sum())
    if bad_pixels:
        log(f"warning: {bad_pixels} pixels are not finite (the values overflow float32)")
    try:
        for output in outputs:
            if output.kind == "json":
                write_text(output, json.dumps(stats, indent=1))
            elif output.option == "-o":
                write_render_image(output, result, args, scene)
            else:
                write_image(output, result.combined(), error_metadata(stats))
    except OutputError as exc:
        sys.stderr.write(f"{PROG}: error: {exc}\n")
        return 1
    if lost is not None:
        print(f"wrote {', '.join(o.path for o in outputs)}: finished tiles only")
        return 1
    rays = sum(stats["rays"].values())
    print(f"wrote {', '.join(o.path for o in outputs)}: {stats['render_seconds']:.2f} s, "
          f"{rays / 1e6:.2f} M rays ({stats['rays_per_second'] / 1e6:.2f} M rays/s), effects: "
          f"{', '.join(k for k, v in stats['effects'].items() if v)}, "
          f"non-finite samples: {stats['nonfinite_samples']}"
          + (" (stopped early: finished tiles only)" if result.cancelled else ""))
    if stats["estimated_rel_error"] is not None:
        print(f"estimated relative error {stats['estimated_rel_error'] * 100:.2f} % "
          f"({stats['error_estimate']}), mean {stats['samples_per_pixel']['mean']:.1f} spp"
          + (f", stopped by {stats['stopped_by']}" if "stopped_by" in stats else ""))
    if "photons" in stats:                      # the caustic photon passes (docs/photons.md)
        ph = stats["photons"]
        print(f"caustic photons: {ph['photon_passes']} passes (traced {ph['photon_passes_traced']} times over the workers), "
              f"{ph['photons_traced'] / 1e6:.2f} M traced, {ph['photons_stored'] / 1e6:.2f} M stored, radius "
              f"{ph['radius_first']:.4g} -> {ph['radius_last']:.4g}, trace {ph['trace_seconds']:.2f} s, "
              f"gather {ph['gather_seconds']:.2f} s (worker seconds)")
    return stop.report_exit()


def cmd_estimate(args) -> int:
    from ..rendering.estimate import describe, estimate
    from ..api import render
    if args.noise_target <= 0:
        raise SceneError("estimate needs --noise-target REL (e.g. 0.01)")
    scene, settings = scene_and_settings(args)
    scene.validate()
    result = estimate(scene, settings, args.noise_target, render, pilot_samples=args.pilot_samples,
                      log=lambda *a: None)
    print(describe(result))
    if args.json:
        print(json.dumps(result))
    return 0


def cmd_bench(args) -> int:
    from .bench import run_bench
    run_bench(resolution=tuple(args.resolution), samples=args.samples)
    return 0


def cmd_bench_memory(args) -> int:
    from .bench_memory import run_bench_memory
    run_bench_memory()
    return 0


def cmd_bench_cluster(args) -> int:
    from .bench import run_bench_cluster
    run_bench_cluster(resolution=tuple(args.resolution), samples=args.samples, workers=args.workers,
                      repeats=args.repeats)
    return 0


def cmd_study(args) -> int:
    from ..studies.accuracy import run_study
    mode = "full" if args.full else "quick"
    if args.stopping:
        from ..studies.stopping import run_stopping_study
        command = f"python -m engine study --stopping --{mode}" + (f" --out {args.out}" if args.out != "docs" else "")
        run_stopping_study(mode, args.out, command, log=lambda msg: print(msg, file=sys.stderr))
        return 0
    command = f"python -m engine study --{mode}" + (f" --out {args.out}" if args.out != "docs" else "")
    run_study(mode, args.out, command, log=lambda msg: print(msg, file=sys.stderr))
    return 0


def cmd_worker(args) -> int:
    from ..pools.processes import worker_main
    from ..pools.transport import exit_worker
    exit_worker(worker_main(args.parent_pid))


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog=PROG, description="TNCG15 MC tracer")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    r = sub.add_parser("render", help="render a scene file (or the built-in Cornell scene)")
    r.add_argument("scene", nargs="?", help="scene .json (default: a built-in scene, see --builtin)")
    r.add_argument("--builtin", choices=("cornell", "near_lamp", "caustic", "many_lights"),
                   help="built-in scene (engine/scene/builtin.py; default cornell)")
    r.add_argument("-o", "--output", required=True, help="output image (.exr linear or .png sRGB)")
    r.add_argument("--png", help="also write an sRGB PNG here")
    r.add_argument("--resolution", type=bounded_int(1, MAX_RESOLUTION), nargs=2, metavar=("W", "H"))
    r.add_argument("--stats-json", metavar="PATH")
    r.add_argument("--quiet", action="store_true")
    r.add_argument("--cluster", metavar="ADDRESS",
                   help="render the work units on a Dask cluster: its scheduler's tcp://HOST:PORT, or 'local' "
                        "to start a LocalCluster here (docs/command-line.md: Rendering on several machines)")
    add_tls_options(r)
    add_settings_arguments(r)
    r.set_defaults(func=cmd_render)
    e = sub.add_parser("estimate", help="predict the render time to reach --noise-target from a short pilot render")
    e.add_argument("scene", nargs="?", help="scene .json (default: a built-in scene, see --builtin)")
    e.add_argument("--builtin", choices=("cornell", "near_lamp", "caustic", "many_lights"))
    e.add_argument("--resolution", type=bounded_int(1, MAX_RESOLUTION), nargs=2, metavar=("W", "H"))
    e.add_argument("--pilot-samples", type=bounded_int(2, 4096), default=64)
    e.add_argument("--json", action="store_true", help="also print the prediction as JSON")
    add_settings_arguments(e)
    e.set_defaults(func=cmd_estimate)
    b = sub.add_parser("bench", help="rays/s, Embree share and thread speed-up on the built-in scene")
    b.add_argument("--resolution", type=bounded_int(1, MAX_RESOLUTION), nargs=2, default=(256, 256),
                   metavar=("W", "H"))
    b.add_argument("--samples", type=positive_int, default=64)
    b.set_defaults(func=cmd_bench)
    sub.add_parser("bench-memory", help="the memory estimate against the summed peak RSS of a few renders "
                   "(about 4 minutes on 2 cores)").set_defaults(func=cmd_bench_memory)
    bc = sub.add_parser("bench-cluster", help="the same render on the local pool and on a Dask cluster of "
                                              "worker processes started here: the time ratio")
    bc.add_argument("--resolution", type=bounded_int(1, MAX_RESOLUTION), nargs=2, default=(256, 256),
                    metavar=("W", "H"))
    bc.add_argument("--samples", type=positive_int, default=64)
    bc.add_argument("--workers", type=bounded_int(1, 256), default=os.cpu_count() or 1)
    bc.add_argument("--repeats", type=bounded_int(1, 100), default=3)
    bc.set_defaults(func=cmd_bench_cluster)
    st = sub.add_parser("study", help="error and time for every knob (docs/accuracy-vs-time.md)")
    group = st.add_mutually_exclusive_group()
    group.add_argument("--quick", action="store_true", help="small and fast (CI); the default")
    group.add_argument("--full", action="store_true", help="the committed figures (about 5 minutes on 2 cores)")
    st.add_argument("--out", default="docs", help="directory for the markdown and the plots")
    st.add_argument("--stopping", action="store_true",
                    help="only the stopping-rule rows: estimate calibration, adaptive vs uniform "
                         "(docs/accuracy-stopping.md)")
    st.set_defaults(func=cmd_study)
    w = sub.add_parser("worker", help="a render worker process (engine/pools/processes.py; started by the add-on)")
    w.add_argument("parent_pid", type=positive_int)
    w.set_defaults(func=cmd_worker)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (SceneError, OutputError) as exc:
        sys.stderr.write(f"{PROG}: error: {exc}\n")
        return 2
    except MemoryError:
        sys.stderr.write(f"{PROG}: error: out of memory (lower the resolution or the threads)\n")
        return 1
    except OSError as exc:
        sys.stderr.write(f"{PROG}: error: {exc}\n")
        return 2
    except KeyboardInterrupt:
        sys.stderr.write(f"{PROG}: interrupted\n")
        return 130
