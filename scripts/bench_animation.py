"""Prints (does not assert) what an animation frame costs beyond its tracing (docs/performance.md
"Animation and Persistent Data"): a transform-only animation (one object moves) of a sample scene,
rendered as a user does, `blender -b FILE -E ENGINE -s 1 -e N -a` in Debian's Blender 3.4 and
`bpy.ops.render.render(animation=True)` in the bpy 5.0 module, with Persistent Data off and on, and
by Cycles at the same size and samples.

Per frame: the wall time from Blender's render_pre to its render_post handler (the frame's
depsgraph, export, workers, tracing, passes) against the tracer's own render_seconds (tracing), and
where the rest went: the add-on's export (workers started, scene exported and checked), the wait
for the first worker to be ready (prepare: the scene sent, the workers' scene checks and BVH), the
workers' own setup and BVH build seconds, what was left of the add-on's render() and Blender's share
(depsgraph, result). CPU seconds per frame: Blender's process (getrusage, all its threads) and the
kept workers (/proc/PID/stat, Persistent Data on only: the other runs start new workers per frame).
The machine is shared: every run is repeated and the run with the smallest frame / tracing ratio is
shown (the ratio is always measured within one run), with the load average around it.

  python scripts/bench_animation.py [--scene suzanne_100k] [--frames 4] [--size 128] [--samples 16]
                                    [--repeat 3] [--blender 3.4,5.0] [--cases off,on,cycles]
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

# Runs inside Blender (3.4: the blender binary; 5.0: the bpy module): animate the scene's last mesh
# object, time each frame through the handlers.
IN_BLENDER = r'''
import json, os, resource, sys, time, bpy
blend, frames, size, samples, engine, persistent, out = sys.argv[sys.argv.index("--") + 1:]
frames, size, samples = int(frames), int(size), int(samples)
if bpy.app.binary_path == "":                       # the bpy module: register the add-on here
    sys.path.insert(0, os.environ["BENCH_REPO"])
    import mcrt_addon
    from mcrt_addon.headless import ensure_registered
    ensure_registered(mcrt_addon)
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
TICK = os.sysconf("SC_CLK_TCK")
def cpu_of(pids):
    total = 0.0
    for pid in pids:
        try:
            with open(f"/proc/{pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            total += (int(fields[11]) + int(fields[12])) / TICK
        except OSError:
            pass
    return total
def own_cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime
marks, reports, pids = [], [], []
if engine == "TNCG15_MC":
    import mcrt_addon.render_engine as tncg
    def listen(r):
        pids[:] = r.stats.get("worker_pids") or []
        reports.append({"render_seconds": r.stats.get("render_seconds"), "wall": r.wall_seconds,
                        "export": r.stats.get("export_seconds"), "prepare": r.stats.get("prepare_seconds"),
                        "setup": r.stats.get("setup_seconds"), "build": r.stats.get("build_seconds"),
                        "setup_cpu": r.stats.get("setup_cpu_seconds"),
                        "meshes_read": (r.export or {}).get("meshes_read")})
    tncg.REPORT_LISTENERS.append(listen)
bpy.app.handlers.render_pre.append(lambda *a: marks.append(("pre", time.perf_counter(), own_cpu(), cpu_of(pids))))
bpy.app.handlers.render_post.append(lambda *a: marks.append(("post", time.perf_counter(), own_cpu(), cpu_of(pids))))
bpy.ops.render.render(animation=True)
pre = [m for m in marks if m[0] == "pre"]
post = [m for m in marks if m[0] == "post"]
json.dump({"frame_seconds": [b[1] - a[1] for a, b in zip(pre, post)],
           "blender_cpu": [b[2] - a[2] for a, b in zip(pre, post)],
           "worker_cpu": [b[3] - a[3] for a, b in zip(pre, post)], "reports": reports},
          open(out + "/times.json", "w"))
'''


def run(blender, blend, frames, size, samples, engine, persistent):
    with tempfile.TemporaryDirectory() as tmp:
        script = os.path.join(tmp, "bench.py")
        with open(script, "w") as f:
            f.write(IN_BLENDER)
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([REPO, sysconfig.get_paths()["purelib"]]), BENCH_REPO=REPO)
        args = ["--", blend, str(frames), str(size), str(samples), engine, persistent, tmp]
        if blender == "3.4":
            cmd = [BLENDER34, "-b", "--factory-startup", "--python-use-system-env", "--addons", "mcrt_addon",
                   "--python", script] + args
        else:
            cmd = [sys.executable, script] + args
        load = os.getloadavg()[0]
        r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=1200)
        path = os.path.join(tmp, "times.json")
        if not os.path.exists(path):
            sys.exit(f"{engine} run failed:\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}")
        with open(path) as f:
            t = json.load(f)
        t["load"] = (load, os.getloadavg()[0])
        return t


def mean(values):
    values = [v for v in values if v is not None]
    return sum(values) / len(values) if values else float("nan")


def summary(t):
    """Means over frames 2 on (the first starts the workers)."""
    later = slice(1, None)
    row = {"frame": mean(t["frame_seconds"][later]), "blender_cpu": mean(t["blender_cpu"][later]),
           "worker_cpu": mean(t["worker_cpu"][later]), "load": t["load"]}
    if t["reports"]:
        reps = t["reports"][later]
        for key in ("render_seconds", "wall", "export", "prepare", "setup", "build", "setup_cpu", "meshes_read"):
            row[key] = mean([r[key] for r in reps])
        row["ratio"] = row["frame"] / row["render_seconds"]
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="suzanne_100k")
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--repeat", type=int, default=3, help="runs of each case; the one of the smallest ratio is shown")
    ap.add_argument("--blender", default="3.4,5.0",
                    help="3.4 (the blender binary), 5.0 (the bpy module), or 3.4,5.0 (both, the default)")
    ap.add_argument("--cases", default="off,on,cycles", help="Persistent Data off, on, Cycles: which to run")
    a = ap.parse_args()
    blend = os.path.join(REPO, "sample_blends", a.scene + ".blend")
    print(f"{a.scene}.blend, {a.frames} frames, one object moving, {a.size}^2, {a.samples} spp, frames 2-{a.frames}, "
          f"best of {a.repeat}")
    head = (f"{'Blender':<8}{'run':<16}{'frame s':>8}{'tracing':>8}{'ratio':>7}{'export':>8}{'prepare':>8}"
            f"{'w.setup':>8}{'w.build':>8}{'w.cpu':>7}{'rest':>7}{'Blender':>8}{'read':>5}{'cpu B':>7}{'cpu W':>7}{'load':>11}")
    print(head)
    blenders = a.blender.split(",")
    if set(blenders) - {"3.4", "5.0"}:
        ap.error(f"--blender {a.blender}: expected 3.4, 5.0 or 3.4,5.0")
    for blender in blenders:
        cases = {"off": ("TNCG15_MC", "off"), "on": ("TNCG15_MC", "on"), "cycles": ("CYCLES", "off")}
        for engine, persistent in (cases[c] for c in a.cases.split(",")):
            rows = [summary(run(blender, blend, a.frames, a.size, a.samples, engine, persistent))
                    for _ in range(a.repeat if engine == "TNCG15_MC" else 1)]
            r = min(rows, key=lambda row: row.get("ratio", row["frame"]))
            name = f"PD {persistent}" if engine == "TNCG15_MC" else "Cycles"
            load = f"{r['load'][0]:.1f}-{r['load'][1]:.1f}"
            if "ratio" in r:
                rest = r["wall"] - r["export"] - (r["prepare"] if r["prepare"] == r["prepare"] else 0) - r["render_seconds"]
                prepare = "" if r["prepare"] != r["prepare"] else f"{r['prepare']:.3f}"
                print(f"{blender:<8}{name:<16}{r['frame']:>8.3f}{r['render_seconds']:>8.3f}{r['ratio']:>7.2f}"
                      f"{r['export']:>8.3f}{prepare:>8}{r['setup']:>8.3f}{r['build']:>8.3f}{r['setup_cpu']:>7.3f}{rest:>7.3f}"
                      f"{r['frame'] - r['wall']:>8.3f}{r['meshes_read']:>5.0f}{r['blender_cpu']:>7.2f}"
                      f"{r['worker_cpu'] if persistent == 'on' else float('nan'):>7.2f}{load:>11}")
            else:
                print(f"{blender:<8}{name:<16}{r['frame']:>8.3f}{'':>8}{'':>7}{'':>8}{'':>8}{'':>8}{'':>8}{'':>7}{'':>7}"
                      f"{'':>8}{'':>5}{r['blender_cpu']:>7.2f}{'':>7}{load:>11}")
            sys.stdout.flush()
    print("ratio = frame / tracing within one run; export: the add-on until the scene is exported and checked; "
          "prepare: until the first worker is ready (sent, the workers' checks and BVH); w.setup, w.build: the "
          "workers' own (wall); w.cpu: a worker's CPU seconds of its setup; rest: the add-on's render() after tracing (result, passes); Blender: frame minus "
          "the add-on's render() (PD off: rest also holds starting the workers and preparing them); read: meshes "
          "read from Blender per frame; cpu B / W: CPU seconds per frame of Blender's process and of the kept workers")


if __name__ == "__main__":
    main()
