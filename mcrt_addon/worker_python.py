"""Which Python runs the render workers, and what it needs on its path.

The tracer renders in worker processes (engine/pools/processes.py) of a Python that has numpy
and embreex, not in Blender's interpreter (only when there is no such Python at all does it run
on threads in Blender's process: render_engine.py).  That Python is

* the interpreter set in the add-on's Preferences ("Python for render workers"), when set;
* in the ``bpy`` module (Blender as a Python package): the Python running it, ``sys.executable``;
* in a Blender binary: Blender's own Python (``<prefix>/bin/pythonX.Y``; Blender 2.91+ also gives it
  as ``sys.executable``), with the wheels the add-on bundles (the legacy zip's ``vendor/``, the
  extension's installed wheels) on its path.  embreex then loads in the worker, away from the
  Embree 3 that Debian's Blender 3.4 links: that is what makes Embree work there.

``vendor/numpy`` (legacy zip only) is also what Blender's own process imports when its Python has
no numpy (Debian's Blender 3.4): the exporter needs numpy, never embreex (``vendor/worker``).
"""
import os
import sys

import bpy
from bpy.props import BoolProperty, StringProperty

ADDON_DIR = os.path.dirname(os.path.abspath(__file__))
VENDOR_NUMPY = os.path.join(ADDON_DIR, "vendor", "numpy")
VENDOR_WORKER = os.path.join(ADDON_DIR, "vendor", "worker")
DENOISER_FOLDER = "denoiser"      # in the add-on's user data: denoiser_dir()
INSTALL_HINT = ("install numpy for Blender's Python (e.g. apt-get install python3-numpy), or use the "
                "add-on's legacy zip for Linux x64, which bundles it")


NUMPY_PROBLEM = None      # what ensure_numpy() found: the message saying what to install, or None


def ensure_numpy():
    """Make numpy importable in Blender's process (bundled copy as a last resort); sets and
    returns NUMPY_PROBLEM."""
    global NUMPY_PROBLEM
    NUMPY_PROBLEM = _numpy_problem()
    return NUMPY_PROBLEM


def _numpy_problem():
    try:
        import numpy  # noqa: F401
        return None
    except ImportError:
        pass
    if os.path.isdir(VENDOR_NUMPY) and VENDOR_NUMPY not in sys.path:
        sys.path.append(VENDOR_NUMPY)
        try:
            import numpy  # noqa: F401,F811
            return None
        except ImportError as exc:
            sys.path.remove(VENDOR_NUMPY)
            return f"TNCG15 MC: the bundled numpy does not load here ({exc}): {INSTALL_HINT}"
    return f"TNCG15 MC needs numpy in Blender's Python: {INSTALL_HINT}"


def in_bpy_module() -> bool:
    return not getattr(bpy.app, "binary_path", "")


def candidates():
    if in_bpy_module():
        return [sys.executable]
    version = f"python{sys.version_info[0]}.{sys.version_info[1]}"
    return [os.path.join(sys.base_prefix, "bin", version), os.path.join(sys.prefix, "bin", version),
            os.path.join(sys.base_prefix, "bin", "python3"), sys.executable]


def worker_python(preferred: str = ""):
    """(path, None), or (None, why) when no interpreter is there."""
    if preferred:
        path = bpy.path.abspath(preferred)
        if os.path.isfile(path) and os.access(path, os.X_OK):
            return path, None
        return None, f"'Python for render workers' in the add-on's Preferences is not an executable file: {path}"
    for path in candidates():
        if path and os.path.isfile(path) and os.access(path, os.X_OK):
            return path, None
    return None, "no Python interpreter found next to Blender"


def denoiser_dir(create=False):
    """The private directory the preferences' "Install Denoiser" installs pyoidn into
    (denoiser_install.py); it need not exist."""
    package = __package__ or "tncg15_mc"
    if package.startswith("bl_ext.") and hasattr(bpy.utils, "extension_path_user"):
        return bpy.utils.extension_path_user(package, path=DENOISER_FOLDER, create=create)
    path = bpy.utils.user_resource("SCRIPTS", path=os.path.join("addons_data", package.rpartition(".")[2],
                                                                DENOISER_FOLDER))
    if create:
        os.makedirs(path, exist_ok=True)
    return path


def denoiser_dir_installed():
    """denoiser_dir() when it holds pyoidn, else None."""
    path = denoiser_dir()
    return path if path and os.path.isdir(os.path.join(path, "pyoidn")) else None


def extra_paths():
    """Bundled packages for the worker: numpy when Blender's own process uses the bundled copy
    (same numpy on both ends of the pipe), the denoiser the preferences' button installed
    (denoiser_install.py), embreex, OpenImageIO and the denoiser when bundled."""
    paths = [VENDOR_NUMPY] if VENDOR_NUMPY in sys.path else []
    installed = denoiser_dir_installed()
    paths += [installed] if installed else []
    return paths + ([VENDOR_WORKER] if os.path.isdir(VENDOR_WORKER) else [])


def render_cluster(context=None) -> str:
    """The Dask scheduler address set in the add-on's Preferences ('' = none); the add-on CLI's
    --cluster sets it for one run through TNCG15_CLUSTER."""
    if os.environ.get("TNCG15_CLUSTER"):
        return os.environ["TNCG15_CLUSTER"]
    context = context or bpy.context
    addon = context.preferences.addons.get(__package__)
    return getattr(addon.preferences, "render_cluster", "") if addon and addon.preferences else ""


def viewport_worker_count(threads: int) -> int:
    """The Rendered viewport's worker processes for a Threads setting: the setting, or one a core
    (as Cycles' viewport uses every thread: the UI thread only hands views on and draws,
    docs/performance.md "The Rendered viewport").  mcrt_addon/viewport.py starts them and
    mcrt_addon/warm.py starts them ahead: one rule, so that the two pools are the same."""
    return threads if threads > 0 else max(1, os.cpu_count() or 1)


def start_ahead(context=None) -> bool:
    """Whether viewport workers may be started ahead (mcrt_addon/warm.py): the preference, on by default."""
    context = context or bpy.context
    addon = context.preferences.addons.get(__package__)
    return bool(getattr(addon.preferences, "start_workers_ahead", True)) if addon and addon.preferences else True


def preferred_python(context=None) -> str:
    context = context or bpy.context
    addon = context.preferences.addons.get(__package__)
    return getattr(addon.preferences, "worker_python", "") if addon and addon.preferences else ""


class TNCG15Preferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    worker_python: StringProperty(
        name="Worker Python", subtype="FILE_PATH", default="",
        description="A Python with numpy and embreex that runs the tracer's worker processes "
                    "(empty: Blender's own Python with the bundled wheels)")
    render_cluster: StringProperty(
        name="Render Cluster", default="",
        description="Dask scheduler address (tcp://HOST:8786) whose workers render the work units; empty: "
                    "worker processes on this machine.  Blender's Python needs dask and distributed")
    start_workers_ahead: BoolProperty(
        name="Start Workers Ahead", default=True,
        description="While a 3D view shows a TNCG15 MC scene, keep the viewport's worker processes started "
                    "and idle (no CPU; the memory of one Python per worker), so that Rendered mode and F12 "
                    "begin at once")

    def draw(self, context):
        import textwrap
        layout = self.layout
        layout.use_property_split = True                # labels left, fields right: never cut short
        layout.prop(self, "worker_python")
        layout.prop(self, "render_cluster")
        layout.prop(self, "start_workers_ahead")
        path, why = worker_python(self.worker_python)
        col = layout.column(align=True)                 # a long path or reason wraps, not truncated
        for i, line in enumerate(textwrap.wrap(f"Workers run: {path}" if path else why, 70) or [""]):
            col.label(text=line, icon="INFO" if i == 0 else "BLANK1")
        draw_denoiser(layout, path)
        guide = documentation_path()
        if guide:
            layout.operator("wm.url_open", text="Documentation", icon="HELP").url = "file://" + guide


def draw_denoiser(layout, python):
    """Preferences: whether Denoise works for the worker Python (tried in a process of its own, in
    the background, cached), and the button that installs it into the add-on's private directory."""
    import textwrap
    from . import bridge
    col = layout.column(align=True)
    if python is None:
        status = "Denoiser: needs a worker Python"
    else:
        try:
            done, problem = bridge.module("film.denoise").probe_cached(python, extra_paths())
        except ImportError as exc:
            done, problem = True, str(exc)
        status = ("Denoiser: checking..." if not done else "Denoiser: works" if problem is None
                  else f"Denoiser: missing ({problem})")
    for i, line in enumerate(textwrap.wrap(status, 70)):
        col.label(text=line, icon=("CHECKMARK" if status.endswith("works") else "INFO") if i == 0 else "BLANK1")
    col.operator("tncg15.install_denoiser", icon="IMPORT")        # denoiser_install.py
    where = denoiser_dir_installed()
    if where:
        col.label(text=f"Installed in {where}", icon="BLANK1")


def documentation_path():
    """The user guide: docs/user-guide.md inside the add-on (the zips ship docs/*.md:
    scripts/build_extension.py) or beside it (a repository checkout), or None."""
    here = os.path.dirname(os.path.realpath(__file__))    # an add-on folder linked to a checkout too
    for guide in (os.path.join(here, "docs", "user-guide.md"),
                  os.path.join(os.path.dirname(here), "docs", "user-guide.md")):
        if os.path.isfile(guide):
            return guide
    return None


def register():
    bpy.utils.register_class(TNCG15Preferences)


def unregister():
    bpy.utils.unregister_class(TNCG15Preferences)
