"""Prints (does not assert) what an animation frame costs beyond its tracing (docs/performance.md
"Animation and Persistent Data"): a transform-only animation (one object moves) of a sample scene,
rendered as a user does, `blender -b FILE -E ENGINE -s 1 -e N -a` in Debian's Blender 3.4, with
Persistent Data off and on, and by Cycles at the same size and samples.

Per frame: the wall time from Blender's render_pre to its render_post handler (the frame's
depsgraph, export, workers, tracing, passes) against the tracer's own render_seconds (tracing).

  python scripts/bench_animation.py [--scene suzanne_100k] [--frames 4] [--size 128] [--samples 16]
"""
import argparse
import json
import os
import subprocess
import sys
import sysconfig
import tempfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BLENDER34 = os.environ.get("BLENDER_BIN", "/usr/bin/blender")

# Runs inside Blender: animate the scene's last mesh object, time each frame through the handlers.
IN_BLENDER = r'''
import json, sys, time, bpy
blend, frames, size, samples, engine, persistent, out = sys.argv[sys.argv.index("--") + 1:]
frames, size, samples = int(frames), int(size), int(samples)
bpy.ops.wm.open_mainfile(filepath=blend)
sc = bpy.context.scene
ob = sorted((o for o in sc.objects if o.type == "MESH"), key=lambda o: o.name)[-1]
for f in range(1, frames + 1):
    ob.location.x += 0.0 if f == 1 else 0.05
    ob.keyframe_insert("location", frame=f)
sc.frame_start, sc.frame_end = 1, frames
sc.render.engine = engine
sc.render.resolution_x = sc.render.resolution_y = size
sc.render.resolution_percentage = 100
sc.render.use_persistent_data = persistent == "on"
sc.render.image_settings.file_format = "PNG"
sc.render.filepath = out + "/frame_"
if engine == "CYCLES":
    sc.cycles.samples, sc.cycles.use_denoising, sc.cycles.use_adaptive_sampling = samples, False, False
    sc.cycles.device = "CPU"
else:
    sc.tncg15.samples = samples
marks, traced = [], []
if engine == "TNCG15_MC":
    import mcrt_addon.render_engine as tncg
    tncg.REPORT_LISTENERS.append(lambda r: traced.append(r.stats.get("render_seconds")))
bpy.app.handlers.render_pre.append(lambda *a: marks.append(["pre", time.perf_counter()]))
bpy.app.handlers.render_post.append(lambda *a: marks.append(["post", time.perf_counter()]))
bpy.ops.render.render(animation=True)
pre = [t for k, t in marks if k == "pre"]
post = [t for k, t in marks if k == "post"]
json.dump({"frame_seconds": [b - a for a, b in zip(pre, post)], "render_seconds": traced},
          open(out + "/times.json", "w"))
'''


def run(blend, frames, size, samples, engine, persistent):
    with tempfile.TemporaryDirectory() as tmp:
        script = os.path.join(tmp, "bench.py")
        with open(script, "w") as f:
            f.write(IN_BLENDER)
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([REPO, sysconfig.get_paths()["purelib"]]))
        cmd = [BLENDER34, "-b", "--factory-startup", "--python-use-system-env", "--addons", "mcrt_addon",
               "--python", script, "--", blend, str(frames), str(size), str(samples), engine, persistent, tmp]
        r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=1200)
        path = os.path.join(tmp, "times.json")
        if not os.path.exists(path):
            sys.exit(f"{engine} run failed:\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}")
        with open(path) as f:
            return json.load(f)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="suzanne_100k")
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--samples", type=int, default=16)
    a = ap.parse_args()
    blend = os.path.join(REPO, "sample_blends", a.scene + ".blend")
    print(f"{a.scene}.blend, {a.frames} frames, one object moving, {a.size}^2, {a.samples} spp, Blender 3.4 -a")
    print(f"{'run':<28}{'frame s (2nd on)':>18}{'tracing s':>11}{'frame/tracing':>15}")
    cycles = None
    for engine, persistent in (("TNCG15_MC", "off"), ("TNCG15_MC", "on"), ("CYCLES", "off")):
        t = run(blend, a.frames, a.size, a.samples, engine, persistent)
        later = t["frame_seconds"][1:]
        frame = sum(later) / len(later)
        name = f"{engine} persistent {persistent}" if engine == "TNCG15_MC" else "Cycles"
        if t["render_seconds"]:
            tracing = sum(t["render_seconds"][1:]) / len(later)
            print(f"{name:<28}{frame:>18.3f}{tracing:>11.3f}{frame / tracing:>15.2f}")
        else:
            cycles = frame
            print(f"{name:<28}{frame:>18.3f}{'':>11}{'':>15}")
    print(f"(first frame with Persistent Data on starts the workers; Cycles' frame: {cycles:.3f} s)")


if __name__ == "__main__":
    main()
