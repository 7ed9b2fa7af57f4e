"""Run inside a Blender with a window (Debian's 3.4 under Xvfb; tests/addon/test_viewport_blender34.py):

    blender --factory-startup -p 0 0 W H --python viewport_gui_script.py -- ADDON_ZIP BLEND OUTDIR [MODE]

MODE "full" (the default): installs the add-on as a user does, renders a material preview, renders
the scene with F12 (PNG), switches the 3D viewport to Rendered through the scene camera, waits for
the viewport to reach its samples, screenshots the viewport area, moves the light and screenshots
until the picture changes, renders a border, then moves the camera and orbits the view as a user
does (`navigate`), leaves Rendered mode and checks that the viewport workers are gone.  MODE
"navigate": Rendered mode, the camera move and the orbit only; MODE "control": the same, run with
TNCG15_VIEWPORT_CONTROL=export,wait (mcrt_addon/viewport.py: a UI thread that exports and waits),
then one more orbit drawing stale pictures (the control "stale"), for the test's negative controls.

A 20 ms timer records the UI's responsiveness (the time of every call); the add-on logs what its
view_update / view_draw cost on the UI thread (mcrt_addon/viewport.py update_log, draw_log), and
every picture drawn is checked against the view being drawn (`draws`: a picture of another view is
stale).  Everything measured goes to OUTDIR/viewport.json; images are analysed by the test.  Waits
end when what they wait for has happened; their limits (HANG) only guard against a hang.
"""
import json
import math
import os
import sys
import time
import traceback

import bpy

args = sys.argv[sys.argv.index("--") + 1:]
zip_path, blend, outdir = args[:3]
MODE = args[3] if len(args) > 3 else "full"
ORBIT_STEPS, ORBIT_STEP_SECONDS, ORBIT_STEP_DEGREES = 30, 0.03, 2.0     # a user orbiting: 60° in 0.9 s
SAMPLES = 8                      # viewport (at 4 the 8-bit screenshot clips noisy pixels: ~2 % darker)
F12_SAMPLES = 64
HANG = 30.0                      # seconds: a wait that takes longer is reported as an error
out = {"steps": [], "ticks": [], "tick_times": [], "mode": MODE, "draws": []}


def log(msg):
    out["steps"].append(f"{time.perf_counter():.3f} {msg}")
    print("[viewport-test]", msg, flush=True)


def finish(error=None):
    out["error"] = error
    with open(os.path.join(outdir, "viewport.json"), "w") as fh:
        json.dump(out, fh, indent=1)
    bpy.ops.wm.quit_blender()


try:
    bpy.ops.preferences.addon_install(filepath=zip_path)
    bpy.ops.preferences.addon_enable(module="tncg15_mc")
    bpy.ops.wm.open_mainfile(filepath=blend)
    viewport = sys.modules["tncg15_mc.viewport"]
except Exception:                                    # noqa: BLE001 - reported, and Blender quits
    finish(traceback.format_exc())


def view3d():
    win = bpy.context.window_manager.windows[0]
    areas = [a for a in win.screen.areas if a.type == "VIEW_3D"]
    area = max(areas, key=lambda a: a.width * a.height)
    region = next(r for r in area.regions if r.type == "WINDOW")
    return win, area, region


def screenshot(name):
    win, area, region = view3d()
    path = os.path.join(outdir, name)
    with bpy.context.temp_override(window=win, screen=win.screen, area=area, region=region):
        bpy.ops.screen.screenshot_area(filepath=path)
    return path


def frame_in_area():
    """The camera frame in area pixels (x0, y0, x1, y1) from the bottom left."""
    win, area, region = view3d()
    space = area.spaces.active
    rect = viewport.camera_frame_rect(bpy.context.scene, region, space.region_3d)
    dx, dy = region.x - area.x, region.y - area.y
    return [rect[0] + dx, rect[1] + dy, rect[2] + dx, rect[3] + dy], [area.width, area.height]


def state():
    states = [s for s in viewport.ACTIVE if not s.closed]
    return states[0] if states else None


last_tick = [time.perf_counter()]


def cpu_seconds(pids):
    total = 0
    for p in pids:
        try:
            fields = open(f"/proc/{p}/stat").read().rsplit(")", 1)[1].split()
            total += int(fields[11]) + int(fields[12])
        except OSError:
            pass
    return total / os.sysconf("SC_CLK_TCK")


def warm_workers():
    """Wait for the viewport workers mcrt_addon/warm.py starts ahead (as a user who opened the file
    seconds before switching to Rendered): started, imports and loads done (ViewportPool.warmed)."""
    warm = sys.modules["tncg15_mc.warm"]
    t = time.perf_counter()
    while warm.pool() is None:
        if time.perf_counter() - t > HANG:
            raise RuntimeError("no viewport workers were started ahead (mcrt_addon/warm.py)")
        yield 0.1
    pids = [w.pid for w in warm.pool().workers]
    while not warm.pool().warmed():                 # imports and numba's loads done
        if time.perf_counter() - t > 3 * HANG:
            raise RuntimeError("the viewport workers started ahead never finished loading")
        yield 0.1
    out["warm_pids"], out["warm_wait_seconds"] = pids, time.perf_counter() - t
    before = cpu_seconds(pids)
    yield 1.0
    out["warm_idle_cpu"] = cpu_seconds(pids) - before
    log(f"warm workers {pids} ready after {out['warm_wait_seconds']:.1f} s; idle CPU {out['warm_idle_cpu']:.2f} s in 1 s")


def tick():
    now = time.perf_counter()
    out["ticks"].append(now - last_tick[0])
    out["tick_times"].append(now)
    last_tick[0] = now
    return None if out.get("done") else 0.02


def matrix_key(m):
    return [list(map(float, row)) for row in m]


def watch_draws():
    """Every picture the add-on draws: (time, fresh, texture version), fresh when the picture's
    view (its tag: window and view matrix) is the view being drawn."""
    original = viewport.draw_texture

    def draw_texture(engine, scene, texture, *rect):
        st, rv3d = state(), bpy.context.region_data
        tag = st.texture_tag if st is not None else None
        fresh = (tag is not None and rv3d is not None and tuple(map(tuple, rv3d.window_matrix)) == tag[0]
                 and tuple(map(tuple, rv3d.view_matrix)) == tag[1])
        out["draws"].append([time.perf_counter(), bool(fresh), st.texture_version if st else -1])
        return original(engine, scene, texture, *rect)
    viewport.draw_texture = draw_texture


def window_screenshot(name):
    win = bpy.context.window_manager.windows[0]
    path = os.path.join(outdir, name)
    with bpy.context.temp_override(window=win, screen=win.screen):
        bpy.ops.screen.screenshot(filepath=path)
    return path


def converged(st):
    return st.workers.converged() and st.drawn_version == st.workers.picture().version


def first_fresh_draw(after):
    return next((t - after for t, fresh, _ in out["draws"] if t > after and fresh), None)


def window_of(st, t0, t1):
    """What the UI paid between t0 and t1: timer gaps, view_draw and view_update durations."""
    ticks = [b - a for a, b in zip(out["tick_times"], out["tick_times"][1:]) if t0 <= b <= t1]
    return {"seconds": t1 - t0, "ticks": ticks,
            "draws": [d for d in st.draw_log if t0 <= d[0] <= t1],
            "updates": [u for u in st.update_log if t0 <= u[0] <= t1],
            "stale_draws": sum(1 for t, fresh, _ in out["draws"] if t0 <= t <= t1 and not fresh),
            "fresh_draws": sum(1 for t, fresh, _ in out["draws"] if t0 <= t <= t1 and fresh),
            "load": list(os.getloadavg())}


def orbit(area, rv3d, steps_at, sign=1.0):
    """ORBIT_STEPS rotations of the view about its pivot (world Z), one every ORBIT_STEP_SECONDS
    (their times appended to steps_at)."""
    from mathutils import Quaternion
    step = Quaternion((0.0, 0.0, 1.0), math.radians(sign * ORBIT_STEP_DEGREES))
    for _ in range(ORBIT_STEPS):
        rv3d.view_rotation = step @ rv3d.view_rotation
        area.tag_redraw()
        steps_at.append(time.perf_counter())
        yield ORBIT_STEP_SECONDS


def orbit_solid(space):
    """The same orbit in Solid mode (there and back): what Blender's own redraws cost on this
    machine, the baseline of the Rendered orbit's timer gaps."""
    win, area, region = view3d()
    rv3d = space.region_3d
    perspective = rv3d.view_perspective
    rv3d.view_perspective = "PERSP"
    steps_at = []
    yield from orbit(area, rv3d, steps_at)
    yield from orbit(area, rv3d, steps_at, -1.0)
    rv3d.view_perspective = perspective
    t0, t1 = steps_at[0], steps_at[-1] + ORBIT_STEP_SECONDS
    out["orbit_solid"] = {"seconds": t1 - t0, "steps": len(steps_at), "load": list(os.getloadavg()),
                          "ticks": [b - a for a, b in zip(out["tick_times"], out["tick_times"][1:]) if t0 <= b <= t1]}


def navigate(scene, space, st):
    """Move the camera (camera view), then orbit the free view as a user does: ORBIT_STEPS steps
    of ORBIT_STEP_DEGREES every ORBIT_STEP_SECONDS, from a timer.  For each: the UI's costs while
    it happens and until the new view's first picture, and when that picture was drawn."""
    from mathutils import Vector
    win, area, region = view3d()
    rv3d = space.region_3d
    scene.render.use_border = False
    rv3d.view_perspective = "CAMERA"
    area.tag_redraw()
    t = time.perf_counter()
    while not (st.border is None and converged(st)):
        if time.perf_counter() - t > HANG:
            raise RuntimeError(f"camera view never converged: {st.message}")
        yield 0.05
    t_idle = time.perf_counter()                    # converged: the workers idle
    yield 1.0
    out["idle"] = window_of(st, t_idle, time.perf_counter())
    # the camera object moves (camera view): a depsgraph update the add-on sorts as a view change
    cam = scene.camera
    exports = st.exports
    t_cam = time.perf_counter()
    cam.location.x += 0.15
    area.tag_redraw()
    while first_fresh_draw(t_cam) is None or time.perf_counter() - t_cam < 1.0:
        if time.perf_counter() - t_cam > HANG:
            raise RuntimeError(f"no picture {HANG:.0f} s after the camera moved: {st.message}")
        yield 0.01
    out["camera_move"] = dict(window_of(st, t_cam, time.perf_counter()), first_picture=first_fresh_draw(t_cam),
                              exports=st.exports - exports)
    log(f"camera moved: first picture after {first_fresh_draw(t_cam):.3f} s")
    cam.location.x -= 0.15
    # the free view, looking where the camera looks, converged; then the orbit about its pivot
    rv3d.view_perspective = "PERSP"
    rv3d.view_rotation = cam.matrix_world.to_quaternion()
    rv3d.view_distance = 3.0
    rv3d.view_location = cam.matrix_world.translation + cam.matrix_world.to_3x3() @ Vector((0.0, 0.0, -3.0))
    area.tag_redraw()
    t = time.perf_counter()
    yield 0.1
    while not converged(st):
        if time.perf_counter() - t > 3 * HANG:
            raise RuntimeError(f"free view never converged: {st.message}")
        yield 0.05
    yield 0.2
    out["orbit_before_shot"] = window_screenshot("orbit_before.png")
    exports, views = st.exports, st.view_changes
    steps_at = []
    yield from orbit(area, rv3d, steps_at)
    t_orbit, t_last = steps_at[0], steps_at[-1]
    out["orbit_after_shot"] = window_screenshot("orbit_after_0.png")   # right after the last step
    while first_fresh_draw(t_last) is None:
        if time.perf_counter() - t_last > HANG:
            raise RuntimeError(f"no picture {HANG:.0f} s after the orbit: {st.message}")
        yield 0.005
    t_picture = time.perf_counter()
    out["orbit_first_picture_shot"] = window_screenshot("orbit_first_picture.png")
    level_one = None
    while not converged(st):
        if level_one is None and st.workers.picture().level == 1:
            level_one = time.perf_counter() - t_last
        if time.perf_counter() - t_last > 3 * HANG:
            raise RuntimeError(f"orbited view never converged: {st.message}")
        yield 0.02
    out["orbit"] = dict(window_of(st, t_orbit, t_picture), steps=len(steps_at), step_seconds=ORBIT_STEP_SECONDS,
                        orbit_seconds=t_last - t_orbit, first_picture=first_fresh_draw(t_last),
                        first_full_resolution=level_one, converged=time.perf_counter() - t_last,
                        exports=st.exports - exports, views_sent=st.view_changes - views,
                        resolution=list(st.resolution), view_matrix=matrix_key(rv3d.view_matrix))
    out["orbit"]["during"] = window_of(st, t_orbit, t_last + ORBIT_STEP_SECONDS)
    if MODE == "control":                           # the stale-picture control: orbit back, drawing any picture
        viewport.CONTROL = {"stale"}
        steps_at = []
        yield from orbit(area, rv3d, steps_at, -1.0)
        t_back = time.perf_counter()
        while first_fresh_draw(steps_at[-1]) is None and time.perf_counter() - t_back < HANG:
            yield 0.01
        out["orbit_stale_control"] = window_of(st, steps_at[0], time.perf_counter())
        viewport.CONTROL = set()
    yield 0.2
    out["orbit_converged_shot"] = window_screenshot("orbit_converged.png")
    log(f"orbit: first picture {out['orbit']['first_picture']:.3f} s after the last step, "
        f"converged after {out['orbit']['converged']:.1f} s")


def steps():
    scene = bpy.context.scene
    scene.render.engine = "TNCG15_MC"
    watch_draws()
    if MODE in ("navigate", "control"):
        yield from navigate_only(scene)
        return
    # a material preview (bl_use_preview): Blender renders it with TNCG15 MC on a job thread
    engine_module = sys.modules["tncg15_mc.render_engine"]
    reports = []
    engine_module.REPORT_LISTENERS.append(reports.append)
    mat = bpy.data.materials["Pink"]
    t = time.perf_counter()
    mat.asset_generate_preview()
    while not reports and time.perf_counter() - t < HANG:
        yield 0.05
    out["preview_seconds"] = time.perf_counter() - t
    w, h = mat.preview.image_size
    centre = (h // 2) * w + w // 2
    while reports and time.perf_counter() - t < HANG:          # Blender copies the result in later
        yield 0.1
        if any(mat.preview.image_pixels_float[4 * centre:4 * centre + 3]):
            break
    engine_module.REPORT_LISTENERS.remove(reports.append)
    out["preview"] = {"reports": len(reports), "error": reports[0].error if reports else "no render",
                      "samples": reports[0].stats.get("samples") if reports else None, "size": [w, h],
                      "centre": list(mat.preview.image_pixels_float[4 * centre:4 * centre + 4])}
    scene.tncg15.samples = F12_SAMPLES
    scene.tncg15.viewport_samples = SAMPLES
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = os.path.join(outdir, "f12.png")
    t = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    log(f"F12 render {time.perf_counter() - t:.2f} s")
    yield 0.1
    win, area, region = view3d()
    space = area.spaces.active
    space.overlay.show_overlays = False
    space.show_gizmo = False
    for attr in ("show_region_header", "show_region_toolbar", "show_region_ui", "show_region_tool_header"):
        if hasattr(space, attr):
            setattr(space, attr, False)
    space.region_3d.view_perspective = "CAMERA"
    yield 0.2
    win, area, region = view3d()
    with bpy.context.temp_override(window=win, screen=win.screen, area=area, region=region):
        bpy.ops.view3d.view_center_camera()
    yield 0.2
    yield from warm_workers()
    out["ticks"].clear()
    last_tick[0] = time.perf_counter()
    bpy.app.timers.register(tick, first_interval=0.02)
    yield 1.0                                       # the timer in Solid mode: the baseline
    out["ticks_solid"] = list(out["ticks"])
    yield from orbit_solid(space)
    out["ticks"].clear()
    t_rendered = time.perf_counter()
    space.shading.type = "RENDERED"
    log("RENDERED")
    while state() is None or state().workers is None:
        if time.perf_counter() - t_rendered > HANG:
            raise RuntimeError("the viewport never started: " + str(state() and state().message))
        yield 0.05
    st = state()
    while not st.workers.pids:                      # the workers start on the render's thread
        if time.perf_counter() - t_rendered > HANG:
            raise RuntimeError("the viewport's workers never started: " + str(st.workers.error))
        yield 0.01
    out["pids"] = st.workers.pids
    first = None
    while True:
        version, rgba, samples, noise, level, error = st.workers.snapshot()
        if error or st.message:
            raise RuntimeError(f"viewport error: {error or st.message}")
        if first is None and rgba is not None:
            first = time.perf_counter() - t_rendered
            out["first_frame_seconds"] = first
            out["first_frame_level"] = level
        if st.workers.converged() and st.drawn_version == version:
            break
        if time.perf_counter() - t_rendered > 3 * HANG:
            raise RuntimeError(f"viewport stuck at {samples} samples (level {level})")
        yield 0.05
    out["converged_seconds"] = time.perf_counter() - t_rendered
    out["noise"] = noise
    out["viewport_resolution"] = list(st.resolution)
    out["frame"], out["area_size"] = frame_in_area()
    yield 0.3                                       # one more redraw of the final film
    out["before"] = screenshot("viewport.png")
    out["ticks_while_rendering"] = list(out["ticks"])
    out["draw_seconds"], out["upload_seconds"] = list(st.draw_seconds), list(st.upload_seconds)
    out["export_seconds"] = st.last_export_seconds
    out["exports_before_move"] = st.exports
    # move the light: the viewport restarts and shows it (how soon is measured and printed)
    light = next(ob for ob in scene.objects if ob.type == "LIGHT")
    gen = st.workers.gen
    t_move = time.perf_counter()
    light.location.x -= 0.6
    light.location.z -= 0.5
    out["moved"] = light.name
    while True:
        yield 0.005
        if "restart_seconds" not in out and st.workers.gen != gen:
            out["restart_seconds"] = time.perf_counter() - t_move       # re-exported, workers told
        if st.workers.gen != gen and st.workers.first_frame_seconds is not None:
            out["first_new_frame_seconds"] = time.perf_counter() - t_move
            new_version = st.workers.picture().version          # drawn when the texture is this one or newer
            break
        if time.perf_counter() - t_move > HANG:
            raise RuntimeError(f"no new frame {HANG:.0f} s after the light moved: {st.message}")
    shots = []                                       # until 2 s after the first new frame (2.5 s at least)
    until = max(2.5, out["first_new_frame_seconds"] + 2.0)
    while time.perf_counter() - t_move < until:
        yield 0.1
        shots.append([time.perf_counter() - t_move, screenshot(f"moved_{len(shots):02d}.png")])
    out["moved_shots"] = shots
    out["exports_after_move"] = st.exports
    out["light_move"] = dict(window_of(st, t_move, t_move + out["first_new_frame_seconds"] + 0.5),
                             first_picture=next((t - t_move for t, fresh, v in out["draws"]
                                                 if t > t_move and fresh and v >= new_version), None))
    # the light back where it was, and a render border in camera view: only its pixels are
    # rendered and drawn, and they show what the full view showed there
    light.location.x += 0.6
    light.location.z += 0.5
    r = scene.render
    r.use_border = True
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.25, 0.75, 0.3, 0.7
    t_border = time.perf_counter()
    while not (st.border is not None and st.workers.converged() and st.drawn_version == st.workers.snapshot()[0]):
        if time.perf_counter() - t_border > HANG:
            raise RuntimeError(f"border render stuck: {st.message} {st.workers.snapshot()[2:]}")
        yield 0.05
    yield 0.3
    win, area, region = view3d()
    dx, dy = region.x - area.x, region.y - area.y
    out["border"] = [st.border[0] + dx, st.border[1] + dy, st.border[2] + dx, st.border[3] + dy]
    out["border_resolution"] = list(st.resolution)
    out["border_shot"] = screenshot("border.png")
    # the camera moves, then the view orbits (what the UI pays, when the new view is drawn)
    yield from navigate(scene, space, st)
    # leave Rendered mode: the engine is freed and its workers stop
    space.shading.type = "SOLID"
    t_solid = time.perf_counter()
    yield 0.5
    import gc
    t_gc = time.perf_counter()
    gc.collect()                                    # the engine freed (its __del__ stops the workers)
    out["free_seconds"] = time.perf_counter() - t_gc
    yield 0.5
    out["leave_rendered_ticks"] = [b - a for a, b in zip(out["tick_times"], out["tick_times"][1:])
                                   if t_solid <= b <= time.perf_counter()]
    while any(os.path.exists(f"/proc/{p}") and open(f"/proc/{p}/stat").read().rsplit(")", 1)[1].split()[0] != "Z"
              for p in out["pids"]) and time.perf_counter() - t_solid < HANG:
        yield 0.1
    out["workers_alive_after_solid"] = [p for p in out["pids"] if os.path.exists(f"/proc/{p}")
                                        and open(f"/proc/{p}/stat").read().rsplit(")", 1)[1].split()[0] != "Z"]
    # Rendered again, then Blender quits while the viewport renders: the test checks these die too
    space.shading.type = "RENDERED"
    t_again = time.perf_counter()
    while (state() is None or state().workers is None) and time.perf_counter() - t_again < HANG:
        yield 0.05
    while (state() is None or not state().workers.pids) and time.perf_counter() - t_again < HANG:
        yield 0.05
    out["pids_at_quit"] = state().workers.pids if state() is not None and state().workers else []
    out["done"] = True


def navigate_only(scene):
    """MODE "navigate": Rendered through the camera, then navigate() (no preview, F12 or border)."""
    scene.tncg15.viewport_samples = SAMPLES
    win, area, region = view3d()
    space = area.spaces.active
    space.overlay.show_overlays = False
    space.show_gizmo = False
    space.region_3d.view_perspective = "CAMERA"
    yield 0.2
    last_tick[0] = time.perf_counter()
    bpy.app.timers.register(tick, first_interval=0.02)
    yield 1.0                                       # the timer in Solid mode: the baseline
    out["ticks_solid"] = list(out["ticks"])
    yield from orbit_solid(space)
    space.shading.type = "RENDERED"
    t = time.perf_counter()
    while state() is None or state().workers is None:
        if time.perf_counter() - t > HANG:
            raise RuntimeError("the viewport never started: " + str(state() and state().message))
        yield 0.05
    st = state()
    while not st.workers.pids:                      # the workers start on the render's thread
        if time.perf_counter() - t > HANG:
            raise RuntimeError("the viewport's workers never started: " + str(st.workers.error))
        yield 0.01
    out["pids"] = st.workers.pids
    yield from navigate(scene, space, st)
    out["done"] = True


def driver(gen=steps()):
    try:
        delay = next(gen)
    except StopIteration:
        finish()
        return None
    except Exception:                                # noqa: BLE001
        finish(traceback.format_exc())
        return None
    return delay


bpy.app.timers.register(driver, first_interval=1.0)
