"""Prints (does not assert) the worker-process figures (docs/performance.md): the sample Cornell box at
256x256, 64 spp, rendered through Blender (bpy 5.0: python -m mcrt_addon render) on 1 and 2
worker processes, and in Debian's Blender 3.4 from the legacy zip (installed as a user does).

  python scripts/bench_workers.py [--legacy-zip dist/tncg15_mc-<v>-legacy.zip] [--repeat 2]
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BLEND = os.path.join(REPO, "sample_blends", "cornell.blend")
SIZE, SAMPLES = 256, 64

BLENDER34 = r'''
import json, sys, bpy
zip_path, blend, out, stats_path, size, samples = sys.argv[sys.argv.index("--") + 1:]
bpy.ops.preferences.addon_install(filepath=zip_path)
bpy.ops.preferences.addon_enable(module="tncg15_mc")
bpy.ops.wm.open_mainfile(filepath=blend)
import tncg15_mc.render_engine as engine
sc = bpy.context.scene
sc.render.engine = "TNCG15_MC"
sc.render.resolution_x = sc.render.resolution_y = int(size)
sc.render.resolution_percentage = 100
sc.tncg15.samples, sc.tncg15.threads = int(samples), 2
sc.render.image_settings.file_format = "OPEN_EXR"
sc.render.filepath = out
with engine.capture_reports() as reports:
    bpy.ops.render.render(write_still=True)
json.dump(dict(reports[-1].stats, wall_seconds=reports[-1].wall_seconds), open(stats_path, "w"), default=str)
'''


def blend_for_both(tmp):
    """The sample Cornell box saved by Blender 3.4 (bpy 5.0 reads it; 3.4 cannot read 5.0's file)."""
    if not shutil.which("blender"):
        return BLEND
    subprocess.run([shutil.which("blender"), "-b", "--factory-startup", "--python",
                    os.path.join(REPO, "sample_blends", "make_samples.py"), "--", "--outdir", tmp, "--only", "cornell"],
                   check=True, capture_output=True)
    return os.path.join(tmp, "cornell.blend")


def bpy_render(tmp, threads):
    stats = os.path.join(tmp, f"bpy{threads}.json")
    subprocess.run([sys.executable, "-m", "mcrt_addon", "render", BLEND, "-o", os.path.join(tmp, "o.exr"),
                    "--resolution", str(SIZE), str(SIZE), "--samples", str(SAMPLES), "--threads", str(threads),
                    "--stats-json", stats], cwd=REPO, check=True, capture_output=True,
                   env=dict(os.environ, PYTHONPATH=REPO))
    with open(stats) as fh:
        return json.load(fh)


def blender34_render(tmp, legacy_zip):
    script, stats = os.path.join(tmp, "b34.py"), os.path.join(tmp, "b34.json")
    with open(script, "w") as fh:
        fh.write(BLENDER34)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.update(BLENDER_USER_SCRIPTS=os.path.join(tmp, "scripts"), BLENDER_USER_CONFIG=os.path.join(tmp, "config"))
    subprocess.run([shutil.which("blender"), "-b", "--factory-startup", "--python", script, "--", legacy_zip, BLEND,
                    os.path.join(tmp, "b34.exr"), stats, str(SIZE), str(SAMPLES)], check=True,
                   capture_output=True, env=env)
    if not os.path.exists(stats):
        raise SystemExit("Blender 3.4 wrote no stats")
    with open(stats) as fh:
        return json.load(fh)


def line(name, s):
    return (f"{name:34s} render {s['render_seconds']:6.2f} s  first tile {s['first_tile_seconds']:5.2f} s  "
            f"workers ready {s.get('workers_ready_seconds') or 0:5.2f} s  {s['accelerator']}, {s['parallelism']}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--legacy-zip")
    parser.add_argument("--repeat", type=int, default=2, help="best of N")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        global BLEND
        BLEND = blend_for_both(tmp)
        best = {}
        for threads in (1, 2):
            runs = [bpy_render(tmp, threads) for _ in range(args.repeat)]
            best[threads] = min(runs, key=lambda s: s["render_seconds"])
            print(line(f"bpy 5.0, {threads} worker(s)", best[threads]))
        print(f"1 -> 2 workers in Blender (bpy 5.0): {best[1]['render_seconds'] / best[2]['render_seconds']:.2f}x")
        if args.legacy_zip and shutil.which("blender"):
            runs = [blender34_render(tmp, os.path.abspath(args.legacy_zip)) for _ in range(args.repeat)]
            b34 = min(runs, key=lambda s: s["render_seconds"])
            print(line("Blender 3.4 (legacy zip), 2 workers", b34))
            print(f"Blender 3.4 / bpy 5.0 render time: {b34['render_seconds'] / best[2]['render_seconds']:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
