"""The 3D viewport's Rendered mode: export on depsgraph updates, render in worker processes, draw.

Blender calls ``view_update`` and ``view_draw`` on its UI thread, so both only read Blender data
and hand it on: the tracer's progressive render (engine/pools/viewport.py ViewportRender) runs on
a thread of its own over the pool that ``make_pool("viewport:PYTHON")`` makes (worker processes
kept across views), merging the units into the film of a frame; a ``bpy.app.timers`` poller on
the UI thread tags the Rendered viewports for redraw whenever the picture changed (no Blender
object is touched from another thread, and the engine is not kept alive by us, so Blender frees
it and ``__del__`` stops the workers).

* ``view_update``: depsgraph updates sorted by ID type (docs/cluster-and-viewport.md §B1): camera
  objects and camera data change the view only; anything else re-exports the scene, reading
  meshes again only for objects and meshes whose geometry changed (a mesh cache across exports).
* ``view_draw``: the view (region size, view and projection matrices, render border) is compared
  with the last one; a change sends only the new camera to the workers (no BVH rebuild) and
  returns: nothing on the UI thread waits for the workers.  The latest picture is uploaded as a
  half-float texture when it changed and drawn with ``gpu_extras.presets.draw_texture_2d`` between
  ``bind_display_space_shader`` and ``unbind_display_space_shader`` (as Cycles): the film is
  scene-linear and Blender applies the view transform, look, exposure and gamma.  A picture is
  drawn only for the view it was rendered for (its tag, engine/pools/viewport.py Picture): after
  a rotation the old picture is not drawn against the new view; the new view's first coarse frame
  (Performance > Viewport: Start Pixels and Pixel Size, as Cycles) follows.  The header shows
  samples and the noise estimate.

What the UI thread pays is recorded (ViewportState.update_log and draw_log: the wall seconds
(perf_counter) and the UI thread's CPU seconds (thread_time) of every view_update and view_draw)
for tests/addon/test_viewport_blender34.py.  Its negative control sets TNCG15_VIEWPORT_CONTROL
(never set otherwise) to a comma list of what a blocking, stale viewport does: "export" (a view change exports the scene again, on the UI thread), "wait"
(the UI thread waits for the workers' first picture of each change), "stale" (the last picture
is drawn whatever view it was rendered for).
"""
import os
import threading
import time
import weakref

import bpy

from . import bridge, warm, worker_python

MAX_HALF = 65000.0              # half floats overflow above 65504
POLL_SECONDS = 0.02             # redraw poller (a version compare: costs microseconds)
LOG_LENGTH = 4000               # callbacks kept in ViewportState.update_log / draw_log
CONTROL = set(filter(None, os.environ.get("TNCG15_VIEWPORT_CONTROL", "").split(",")))   # a test's control only
CONTROL_WAIT = 10.0             # seconds the "wait" control waits for a picture
ACTIVE = weakref.WeakSet()      # the ViewportStates of live Rendered viewports (tests, diagnostics)
# GPU textures let go of on another thread (a state closed or collected there): a GPU object may only
# be freed where Blender's GL context is, the UI thread, so they wait here until its next callback.
GPU_ORPHANS = []


def on_ui_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def let_go_of_texture(texture) -> None:
    """Drop a GPUTexture: now on the UI thread, else at the UI thread's next viewport callback."""
    if texture is not None and not on_ui_thread():
        GPU_ORPHANS.append(texture)


def free_orphans() -> None:
    """UI thread: free the GPU textures let go of on other threads."""
    if GPU_ORPHANS and on_ui_thread():
        GPU_ORPHANS.clear()


# -- the view as a tracer camera -------------------------------------------------------------------
def camera_from_matrices(window_matrix, view_matrix, lens=50.0):
    """Tracer camera parameters (dict) of a perspective projection: sensor and shift such that
    the tracer's pinhole (engine/scene/camera_rays.py) sees what the viewport's projection shows.

    For Blender's projection P, x_ndc = (P00 x + P02 z) / -z, so at distance L the frame spans
    x in L (±1 + P02) / P00: sensor width 2L / P00, centre L P02 / P00 (shift_x = P02 / 2), and
    likewise y with P11, P12 (shift in units of the sensor width: P12 P00 / (2 P11))."""
    import numpy as np
    P = np.array(window_matrix, dtype=np.float64).reshape(4, 4)
    V = np.array(view_matrix, dtype=np.float64).reshape(4, 4)
    if abs(P[3, 3]) > 1e-9 or abs(P[3, 2] + 1.0) > 1e-6:
        return None                          # orthographic
    return dict(matrix=np.linalg.inv(V), lens=lens, sensor_width=2.0 * lens / P[0, 0],
                sensor_height=2.0 * lens / P[1, 1], sensor_fit="HORIZONTAL",
                shift_x=P[0, 2] / 2.0, shift_y=P[1, 2] * P[0, 0] / (2.0 * P[1, 1]))


def camera_frame_rect(scene, region, rv3d):
    """The scene camera's frame in region pixels (x0, y0, x1, y1) when looking through it, else None."""
    from bpy_extras.view3d_utils import location_3d_to_region_2d
    cam = scene.camera
    if rv3d is None or rv3d.view_perspective != "CAMERA" or cam is None or cam.type != "CAMERA":
        return None
    pts = [location_3d_to_region_2d(region, rv3d, cam.matrix_world @ c) for c in cam.data.view_frame(scene=scene)]
    if any(p is None for p in pts):
        return None
    xs, ys = [p.x for p in pts], [p.y for p in pts]
    return min(xs), min(ys), max(xs), max(ys)


def viewport_border(context, scene):
    """The part of the region to render (x0, y0, x1, y1), pixels from the bottom left, or None
    for all of it: the scene's render border in camera view (as Cycles), else the viewport's own
    render border (View > Clipping Region > Render Region)."""
    region, rv3d, space = context.region, context.region_data, context.space_data
    w, h = region.width, region.height
    frame = camera_frame_rect(scene, region, rv3d)
    if frame is not None:
        if not scene.render.use_border:
            return None
        r = scene.render
        fx0, fy0, fx1, fy1 = frame
        box = (fx0 + r.border_min_x * (fx1 - fx0), fy0 + r.border_min_y * (fy1 - fy0),
               fx0 + r.border_max_x * (fx1 - fx0), fy0 + r.border_max_y * (fy1 - fy0))
    elif space is not None and getattr(space, "use_render_border", False):
        box = (space.render_border_min_x * w, space.render_border_min_y * h,
               space.render_border_max_x * w, space.render_border_max_y * h)
    else:
        return None
    x0, y0 = max(0, int(round(box[0]))), max(0, int(round(box[1])))
    x1, y1 = min(w, int(round(box[2]))), min(h, int(round(box[3])))
    if x1 - x0 < 1 or y1 - y0 < 1:
        return (0, 0, 0, 0)
    return x0, y0, x1, y1


def view_key(context, scene):
    rv3d, region = context.region_data, context.region
    return (tuple(map(tuple, rv3d.window_matrix)), tuple(map(tuple, rv3d.view_matrix)),
            region.width, region.height, viewport_border(context, scene))


def view_camera(context, scene):
    """(tracer Camera, resolution, border) of the viewport, or (None, message, None)."""
    from .export.camera import crop_params
    params = camera_from_matrices(context.region_data.window_matrix, context.region_data.view_matrix)
    if params is None:
        return None, "orthographic views are not supported: switch to a perspective view (Numpad 5)", None
    w, h = context.region.width, context.region.height
    border = viewport_border(context, scene)
    if border == (0, 0, 0, 0):
        return None, "the render border is empty", None
    matrix = params.pop("matrix")
    if border is not None:
        params = crop_params(params, w, h, border)
        w, h = border[2] - border[0], border[3] - border[1]
    return bridge.scene_module().Camera(matrix=matrix, name="Viewport", **params), (w, h), border


# -- depsgraph updates -----------------------------------------------------------------------------
def classify(updates):
    """("none" | "view" | "scene", names of objects and meshes whose geometry changed).

    By ID type first (§B1): cameras (object or data) change the view only; a Mesh or an Object
    with its geometry flag invalidates its cached arrays; everything else (transforms of other
    objects, materials, node trees, worlds, lights, the scene's settings) re-exports."""
    kind, geometry = "none", set()
    for u in updates:
        id_ = u.id
        if isinstance(id_, bpy.types.Camera) or (isinstance(id_, bpy.types.Object) and id_.type == "CAMERA"):
            kind = "view" if kind == "none" else kind
            continue
        kind = "scene"
        if isinstance(id_, bpy.types.Mesh) and u.is_updated_geometry:
            geometry.add(id_.name)
        elif isinstance(id_, bpy.types.Object) and u.is_updated_geometry:
            geometry.add(id_.name)
    return kind, geometry


def forget_meshes(cache, names):
    """Drop cached arrays of these objects or meshes (their geometry changed)."""
    for key in [k for k in cache if k[0] in names or k[1] in names]:
        del cache[key]


# -- the state shared with the poller --------------------------------------------------------------
class ViewportState:
    """Plain Python (never a Blender object): the progressive render (`workers`: its pool's
    processes render), mesh cache, view and texture."""

    def __init__(self):
        self.workers = None
        self.mesh_cache = {}
        self.key = None
        self.message = "Starting"
        self.resolution = None
        self.border = None
        self.scene_sent = False
        self.texture = None
        self.texture_version = -1
        self.texture_tag = None               # the view the texture's picture was rendered for
        self.drawn_version = -1
        self.closed = False
        self.started = time.perf_counter()
        self.exports = 0
        self.last_export_seconds = None
        self.draw_seconds = []                # view_draw durations (UI thread), the last 200
        self.upload_seconds = []              # texture uploads among them
        self.update_log = []                  # (perf_counter at the start, seconds, kind, CPU seconds)
        self.draw_log = []                    # (perf_counter at the start, seconds, drawn, view changed, CPU seconds)
        self.view_changes = 0                 # views sent to the workers without an export
        ACTIVE.add(self)

    def start_workers(self, count):
        """The progressive render; its worker processes start on its own thread (the UI goes on)."""
        python, why = worker_python.worker_python(worker_python.preferred_python())
        if python is None:
            raise RuntimeError(f"the viewport needs render worker processes: {why}")
        extra = worker_python.extra_paths()

        def make_pool():           # the workers started ahead when they are the same (mcrt_addon/warm.py)
            return warm.take(python, count, extra) or bridge.module("api").make_pool(
                f"viewport:{python}", count, log=lambda *a: None, extra_paths=extra)
        denoiser = bridge.module("pools.denoiser")       # Viewport > Denoise: OIDN in a process of its own
        self.workers = denoiser.DenoisedView(bridge.module("pools.viewport").ViewportRender(make_pool=make_pool),
                                             lambda: denoiser.DenoiserProcess(python, extra))
        bpy.app.timers.register(self.poll, first_interval=POLL_SECONDS)

    def poll(self):
        """UI thread, every POLL_SECONDS: redraw Rendered viewports when a new frame arrived."""
        free_orphans()
        if self.closed:
            return None
        version = self.workers.version if self.workers is not None else -1
        if version != self.drawn_version:
            tag_rendered_viewports()
        return POLL_SECONDS

    def close(self):
        """Stop the render and its workers on a thread of their own: leaving Rendered mode never
        waits for a worker to stop."""
        self.closed = True
        if self.workers is not None:
            threading.Thread(target=self.workers.close, daemon=True, name="viewport close").start()
        texture, self.texture = self.texture, None
        let_go_of_texture(texture)

    def __del__(self):
        # collected on another thread (a cycle found by a collection that thread's allocations set off):
        # its texture still waits for the UI thread
        try:
            let_go_of_texture(self.__dict__.get("texture"))
        except TypeError:                    # at interpreter exit this module's names are None
            pass


def logged(log, entry):
    log.append(entry)
    if len(log) > LOG_LENGTH:
        del log[:len(log) - LOG_LENGTH]


def tag_rendered_viewports():
    wm = bpy.context.window_manager
    for window in (wm.windows if wm is not None else ()):
        for area in window.screen.areas:
            if area.type == "VIEW_3D" and area.spaces.active.shading.type == "RENDERED":
                area.tag_redraw()


# -- the callbacks (bodies of RenderEngine.view_update / view_draw) --------------------------------
def view_update(engine, context, depsgraph):
    st = getattr(engine, "viewport_state", None)
    if st is None:
        st = engine.viewport_state = ViewportState()
    t0, cpu0, kind = time.perf_counter(), time.thread_time(), "error"
    try:
        if worker_python.NUMPY_PROBLEM:
            raise ImportError(worker_python.NUMPY_PROBLEM)
        kind, geometry = classify(depsgraph.updates)
        forget_meshes(st.mesh_cache, geometry)
        if st.scene_sent and kind != "scene":
            return                           # the view is compared in view_draw
        export(engine, st, context, depsgraph)
        if "wait" in CONTROL:
            wait_for_picture(st)
    except Exception as exc:                 # noqa: BLE001 - in the header, never a traceback
        st.message = "Error: " + (engine._readable(exc) or f"{type(exc).__name__}: {exc}")
        st.scene_sent = False
    finally:
        logged(st.update_log, (t0, time.perf_counter() - t0, kind, time.thread_time() - cpu0))


def wait_for_picture(st):
    """The negative control's blocking UI thread ("wait"): wait for the workers' first picture of
    the request just sent."""
    t0 = time.perf_counter()
    while (st.workers is not None and st.workers.first_frame_seconds is None and st.workers.error is None
           and time.perf_counter() - t0 < CONTROL_WAIT):
        time.sleep(0.002)


def export(engine, st, context, depsgraph):
    from .export import export_scene
    scene = depsgraph.scene
    camera, resolution, border = view_camera(context, scene)
    if camera is None:
        st.message, st.scene_sent, st.key = resolution, False, view_key(context, scene)
        return
    props = scene.tncg15
    settings = props.to_settings(bridge.settings_class())
    t0 = time.perf_counter()
    exported = export_scene(depsgraph, resolution=resolution, view_camera=camera, mesh_cache=st.mesh_cache)
    settings.validate()                      # the scene is validated by the workers (errors come back)
    st.last_export_seconds = time.perf_counter() - t0
    st.exports += 1
    if st.workers is None:
        st.start_workers(viewport_worker_count(settings))
    st.workers.set_denoise(denoise_start(props))
    key = view_key(context, scene)
    st.workers.set_scene(exported.scene, settings, max(1, int(props.viewport_samples)), tag=key,
                         start_resolution=props.viewport_start_resolution,
                         pixel_size=pixel_size(engine, scene))
    st.key, st.resolution, st.border = key, resolution, border
    st.scene_sent, st.message = True, None


def pixel_size(engine, scene):
    """Performance > Viewport > Pixel Size: Blender's scene.render.preview_pixel_size as Cycles
    reads it (Automatic: the interface's pixel size)."""
    get = getattr(engine, "get_preview_pixel_size", None)
    try:
        return max(1, int(get(scene))) if get is not None else 1
    except (TypeError, ValueError, RuntimeError):
        return 1


def denoise_start(props):
    """Sampling > Viewport > Denoise: its Start Sample, or None when off.  Read at every draw too,
    so the picture shown follows the checkbox at the next redraw (engine/pools/denoiser.py)."""
    return props.viewport_denoise_start if props.use_preview_denoising else None


def viewport_worker_count(settings):
    """Threads setting, or one worker process a core (worker_python.viewport_worker_count)."""
    return worker_python.viewport_worker_count(settings.threads)


def view_draw(engine, context, depsgraph):
    free_orphans()
    st = getattr(engine, "viewport_state", None)
    if st is None:
        return
    scene = depsgraph.scene
    t0, cpu0 = time.perf_counter(), time.thread_time()
    drawn = changed = False
    try:
        key = view_key(context, scene)
        if not st.scene_sent:
            if key != st.key:                # e.g. orthographic -> perspective: export again
                st.key = key
                engine.tag_update()
        elif key != st.key:
            changed = True
            if "export" in CONTROL:          # the negative control: as a viewport without view-only updates
                export(engine, st, context, depsgraph)
            else:
                send_view(st, context, scene, key)
            if "wait" in CONTROL:
                wait_for_picture(st)
        if st.workers is None:
            engine.update_stats("", f"TNCG15 MC | {st.message or 'Starting'}")
            return
        st.workers.set_denoise(denoise_start(scene.tncg15))
        picture = st.workers.picture()
        st.drawn_version = picture.version
        if picture.rgba is not None and picture.version != st.texture_version and not bpy.app.background:
            t_upload = time.perf_counter()
            st.texture = upload(picture.rgba)
            st.texture_version, st.texture_tag = picture.version, picture.tag
            st.upload_seconds = (st.upload_seconds + [time.perf_counter() - t_upload])[-200:]
        if st.texture is not None and st.message is None and (st.texture_tag == st.key or "stale" in CONTROL):
            region = context.region          # only the picture of this view (never an old one)
            x0, y0, x1, y1 = st.border if st.border is not None else (0, 0, region.width, region.height)
            draw_texture(engine, scene, st.texture, x0, y0, x1 - x0, y1 - y0)
            drawn = True
        engine.update_stats("", header_text(st, *picture[2:6]))
        st.draw_seconds = (st.draw_seconds + [time.perf_counter() - t0])[-200:]
    except Exception as exc:                 # noqa: BLE001 - drawing must never raise into Blender
        engine.update_stats("", f"TNCG15 MC | Error: {type(exc).__name__}: {exc}")
    finally:
        logged(st.draw_log, (t0, time.perf_counter() - t0, drawn, changed, time.thread_time() - cpu0))


def send_view(st, context, scene, key):
    """The view changed: its camera to the workers (they rebuild nothing), and return."""
    camera, resolution, border = view_camera(context, scene)
    if camera is None:
        st.message = resolution
    else:
        st.workers.set_view(camera, resolution, tag=key)
        st.resolution, st.border, st.message = resolution, border, None
        st.view_changes += 1
    st.key = key


def header_text(st, samples, noise, level, error):
    if error:
        return f"TNCG15 MC | Error: {error}"
    if st.message:
        return f"TNCG15 MC | {st.message}"
    target = st.workers.target
    if level < 0:
        return "TNCG15 MC | " + ("Updating" if st.texture is not None else "Preparing scene")
    if level == 0:
        return f"Sample 0/{target} | Coarse pass"
    text = f"Sample {samples}/{target}"
    if noise is not None:
        text += f" | Noise ±{100 * noise:.1f} %"
    notice = st.workers.notice() if hasattr(st.workers, "notice") else None
    text += f" | {notice}" if notice else ""             # a worker died and was restarted
    note = getattr(st.workers, "note", None)              # Viewport > Denoise (engine/pools/denoiser.py)
    return text + (f" | {note()}" if note is not None and note() else "")


# -- drawing ---------------------------------------------------------------------------------------
def upload(rgba):
    """(h, w, 4) float32 linear RGBA, row 0 at the bottom -> a half-float GPUTexture."""
    import gpu
    import numpy as np
    h, w = rgba.shape[:2]
    data = np.ascontiguousarray(np.clip(rgba, 0.0, MAX_HALF), dtype=np.float32).ravel()
    buffer = gpu.types.Buffer("FLOAT", data.size, data)
    return gpu.types.GPUTexture((w, h), format="RGBA16F", data=buffer)


def draw_texture(engine, scene, texture, x, y, width, height):
    import gpu
    from gpu_extras.presets import draw_texture_2d
    gpu.state.blend_set("ALPHA_PREMULT")
    engine.bind_display_space_shader(scene)
    draw_texture_2d(texture, (x, y), width, height)
    engine.unbind_display_space_shader()
    gpu.state.blend_set("NONE")


def free(engine):
    """RenderEngine.__del__ (leaving Rendered mode, closing the viewport): stop the workers."""
    try:
        st = getattr(engine, "viewport_state", None)
    except ReferenceError:
        return
    if st is not None:
        st.close()
