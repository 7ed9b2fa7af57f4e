"""Viewport restart latencies in a big scene, through the bpy 5.0 module (prints figures; no targets).

    .venv/bin/python scripts/bench_viewport.py [--triangles 1000000] [--size 320 240] [--warm]

A room with one mesh of about N triangles and a point light; the viewport's view_update /
view_draw bodies are called as Blender calls them (mcrt_addon/viewport.py, stub engine and
context, the depsgraph of a depsgraph_update_post handler).  For entering Rendered mode, moving the
camera (view_draw: a new camera only), orbiting (--orbit views 30 ms apart, as a user drags),
moving the light (re-export without reading the mesh, workers rebuild) and editing the mesh (the
mesh read again) it prints the time spent on Blender's UI thread, the meshes read, and the time
until the workers' first frame of the change; for entering Rendered mode also the time to the
first full-resolution picture and the sample rate after it (samples of the whole frame per second,
until --samples are there) with the worker processes' CPU seconds (--threads: worker processes,
0 = one a core as the viewport starts them).  --warm: Rendered mode entered with the workers that
mcrt_addon/warm.py starts ahead (once they are idle), as in Blender's window; without it the
workers start when Rendered mode is entered.
"""
import argparse
import os
import sys
import time
from types import SimpleNamespace

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

import bpy  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--triangles", type=int, default=1_000_000)
    ap.add_argument("--size", type=int, nargs=2, default=(320, 240))
    ap.add_argument("--samples", type=int, default=16, help="the viewport's max samples")
    ap.add_argument("--threads", type=int, default=0, help="viewport worker processes (0: one a core)")
    ap.add_argument("--orbit", type=int, default=30, help="views of the orbit, 30 ms apart")
    ap.add_argument("--warm", action="store_true", help="enter Rendered with the workers started ahead "
                    "(mcrt_addon/warm.py, as Blender's timer starts them), once they are idle")
    args = ap.parse_args()
    import mcrt_addon
    from mcrt_addon.headless import ensure_registered
    ensure_registered(mcrt_addon)
    import mcrt_addon.export as export
    from mcrt_addon import viewport

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "TNCG15_MC"
    scene.tncg15.viewport_samples = args.samples
    scene.tncg15.threads = args.threads
    n = max(1, int((args.triangles / 2) ** 0.5))
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=n, y_subdivisions=n, size=4.0)
    grid = bpy.context.object
    grid.data.name = "Grid"
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    cam.location, cam.rotation_euler = (0.0, -6.0, 3.0), (1.1, 0.0, 0.0)
    scene.camera = cam
    light = bpy.data.objects.new("Bulb", bpy.data.lights.new("Bulb", "POINT"))
    light.data.energy = 500.0
    light.location = (0.0, 0.0, 2.0)
    scene.collection.objects.link(light)
    bpy.context.view_layer.update()
    tris = sum(len(p.vertices) - 2 for p in grid.data.polygons)
    w, h = args.size

    reads = []
    original = export.mesh_arrays
    export.mesh_arrays = lambda me: reads.append(me.name) or original(me)
    engine = SimpleNamespace(_readable=lambda exc: None, update_stats=lambda a, b: None, tag_update=lambda: None)

    def context(view_matrix=None):
        dg = bpy.context.evaluated_depsgraph_get()
        return SimpleNamespace(region=SimpleNamespace(width=w, height=h), space_data=None,
                               region_data=SimpleNamespace(window_matrix=cam.calc_matrix_camera(dg, x=w, y=h),
                                                           view_matrix=view_matrix or cam.matrix_world.inverted(),
                                                           view_perspective="PERSP"))

    def worker_cpu(st):
        """CPU seconds (user + system) the viewport's worker processes used so far."""
        total = 0.0
        for pid in st.workers.pids:
            try:
                fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
                total += (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
            except (OSError, IndexError, ValueError):
                pass
        return total

    def first_frame(st, timeout=300):
        t = time.perf_counter()
        while st.workers.first_frame_seconds is None and time.perf_counter() - t < timeout:
            time.sleep(0.002)
        return st.workers.first_frame_seconds

    def row(what, ui, st, n_reads):
        print(f"{what:<34} UI thread {1000 * ui:8.1f} ms   meshes read {n_reads}   first frame after "
              f"{1000 * first_frame(st):8.1f} ms")

    print(f"{tris:,} triangles, viewport {w}x{h}, {viewport.viewport_worker_count(scene.tncg15.to_settings(__import__('engine.core.settings', fromlist=['x']).RenderSettings))} worker(s), "
          f"load {os.getloadavg()[0]:.2f}")
    ahead = warm_ahead(scene) if args.warm else 0.0
    ctx = context()
    t, cpu = time.perf_counter(), time.process_time()
    viewport.view_update(engine, ctx, bpy.context.evaluated_depsgraph_get())
    st = engine.viewport_state
    row("enter Rendered (export)", time.perf_counter() - t, st, len(reads))
    print(f"{'':<34} CPU s until the first frame: this process {time.process_time() - cpu:.3f}, the workers "
          f"{worker_cpu(st) - ahead:.3f}" + (" (beyond their start ahead)" if args.warm else ""))
    try:
        full, samples = None, []                     # (time, samples) of every full-resolution picture
        while not st.workers.converged():
            snap = st.workers.snapshot()
            if snap[4] == 1 and (not samples or samples[-1][1] != snap[2]):
                samples.append((time.perf_counter(), snap[2]))
                full = full or samples[-1][0] - t
            time.sleep(0.002)
        end = time.perf_counter()
        n0, t0 = samples[0][1], samples[0][0]
        rate = (args.samples - n0) / max(end - t0, 1e-9)
        print(f"{'':<34} first full-resolution picture after {1000 * full:8.1f} ms, then "
              f"{rate:6.2f} samples/s ({n0} -> {args.samples} in {end - t0:.2f} s; {len(st.workers.pids)} "
              f"worker(s), {worker_cpu(st):.1f} CPU s in all, load {os.getloadavg()[0]:.2f})")
        # the orbit: a view every 30 ms about the room's centre, view_draw each time
        from mathutils import Matrix
        ui = []
        for i in range(args.orbit):
            turn = Matrix.Rotation(0.035 * (i + 1), 4, "Z")
            t = time.perf_counter()
            viewport.view_draw(engine, context((turn @ cam.matrix_world).inverted()), bpy.context.evaluated_depsgraph_get())
            ui.append(time.perf_counter() - t)
            time.sleep(max(0.0, 0.03 - ui[-1]))
        first = first_frame(st)                  # seconds after the last view was sent
        ui.sort()
        print(f"{'orbit (' + str(args.orbit) + ' views, view_draw)':<34} UI thread {1000 * ui[len(ui) // 2]:8.1f} ms "
              f"median, {1000 * ui[-1]:.1f} longest   first frame of the last view after {1000 * first:8.1f} ms")
        viewport.view_draw(engine, context(), bpy.context.evaluated_depsgraph_get())
        # the camera moves: view_draw sends only a camera
        cam.location.x += 0.3
        bpy.context.view_layer.update()
        ctx = context()
        n0 = len(reads)
        t = time.perf_counter()
        viewport.view_draw(engine, ctx, bpy.context.evaluated_depsgraph_get())
        row("move the camera (view_draw)", time.perf_counter() - t, st, len(reads) - n0)
        timings = {}

        def handler(scene_, dg):
            t0 = time.perf_counter()
            viewport.view_update(engine, ctx, dg)
            timings["ui"] = time.perf_counter() - t0

        bpy.app.handlers.depsgraph_update_post.append(handler)
        try:
            for what, edit in (("move the light (re-export)", lambda: setattr(light, "location", (1.0, 0.0, 2.0))),
                               ("edit the mesh (read again)", lambda: (grid.data.vertices[0].co.__setitem__(2, 0.1),
                                                                        grid.data.update()))):
                while not st.workers.converged():
                    time.sleep(0.01)
                n0 = len(reads)
                edit()
                bpy.context.view_layer.update()
                row(what, timings["ui"], st, len(reads) - n0)
        finally:
            bpy.app.handlers.depsgraph_update_post.remove(handler)
    finally:
        viewport.free(engine)


def warm_ahead(scene):
    """The pool mcrt_addon/warm.py keeps for a 3D view of this scene, started and waited for until
    its workers are idle (imports and numba's loads done: ViewportPool.warmed); their CPU seconds."""
    from mcrt_addon import warm, worker_python
    window = SimpleNamespace(scene=scene, screen=SimpleNamespace(areas=[SimpleNamespace(type="VIEW_3D")]))
    key = warm.wanted_key([window])
    t = time.perf_counter()
    warm.update(key, start=True)
    while warm.pool() is None:
        time.sleep(0.01)
    while not warm.pool().warmed():
        time.sleep(0.01)
    now = sum((int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK") for f in
              (open(f"/proc/{w.pid}/stat").read().rsplit(")", 1)[1].split() for w in warm.pool().workers))
    print(f"workers started ahead (mcrt_addon/warm.py): idle after {time.perf_counter() - t:.1f} s, "
          f"{now:.2f} CPU s ({worker_python.worker_python('')[0]})")
    return now


if __name__ == "__main__":
    main()
