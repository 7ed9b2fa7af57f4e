"""The denoiser (pyoidn, Intel Open Image Denoise) where the zip did not bring one: the preferences'
"Install Denoiser" button pip-installs it into a private directory of the add-on's user data, never
into a system Python (Debian's refuses: "externally managed"), and that directory is on the path of
the worker Python (worker_python.extra_paths) and of Blender's from registration on.

* The directory (worker_python.denoiser_dir): the extension's user directory
  (``bpy.utils.extension_path_user``, 4.2+) when installed as an extension, else
  ``<user scripts>/addons_data/tncg15_mc/denoiser`` (3.4's legacy add-on), and never created before
  the first install.
* The install: ``<worker Python> -m pip install --target DIR --no-deps --only-binary=:all: pyoidn
  cffi pycparser`` with the pins of the bundled wheels (scripts/build_extension.py DENOISER); numpy
  is the worker's own.  ``--target`` is not the environment's site-packages, which is what lets pip
  install on a Python that PEP 668 marks externally managed.
* Then the denoiser is tried in a process of its own (engine/film/denoise.py probe) and the operator
  reports what happened (self.report), so a broken library never loads into Blender.
"""
import os
import subprocess
import sys

import bpy

from . import bridge, worker_python

REQUIREMENTS = ("pyoidn==2.5.1.0", "cffi==2.1.1", "pycparser==3.12")    # scripts/build_extension.py DENOISER
INDEX_OPTIONS = ()                  # extra pip options (tests: --no-index --find-links DIR)
PIP_SECONDS = 900.0


def activate():
    """The private directory on Blender's path (after its own site-packages: Blender's cffi stays
    Blender's) and, through worker_python.extra_paths, first on the workers'."""
    path = worker_python.denoiser_dir_installed()
    if path and path not in sys.path:
        sys.path.append(path)
    return path


def pip_command(python, target, requirements=REQUIREMENTS):
    return [python, "-m", "pip", "install", "--target", target, "--no-deps", "--only-binary=:all:", "--upgrade",
            "--no-input", "--disable-pip-version-check", *INDEX_OPTIONS, *requirements]


def install(python, target):
    """pip-install the denoiser into `target` with `python`; (True, message) or (False, why)."""
    try:
        proc = subprocess.run(pip_command(python, target), capture_output=True, text=True, timeout=PIP_SECONDS,
                              env=dict(os.environ, PIP_NO_INPUT="1", PYTHONNOUSERSITE="1"))
    except (OSError, subprocess.TimeoutExpired) as exc:
        return False, f"pip could not run with {python}: {exc}"
    if proc.returncode != 0:
        lines = [line for line in (proc.stderr + proc.stdout).splitlines() if line.strip()]
        tail = lines[-1] if lines else f"exit code {proc.returncode}"
        if "No module named pip" in proc.stderr:
            tail = f"{python} has no pip (Debian: apt-get install python3-pip), or set 'Worker Python'"
        return False, f"installing the denoiser failed: {tail}"
    return True, f"installed into {target}"


def known_problem():
    """Why the denoiser does not work for the worker Python, from a cached trial (None: it works or
    it is still being tried); never waits (the panels call it while drawing)."""
    python = worker_python.worker_python(worker_python.preferred_python())[0]
    if python is None:
        return "no worker Python"
    try:
        done, problem = bridge.module("film.denoise").probe_cached(python, worker_python.extra_paths())
    except ImportError:
        return None
    return problem if done else None


class TNCG15_OT_install_denoiser(bpy.types.Operator):
    """Download Intel Open Image Denoise (pyoidn, about 88 MB) with pip into the add-on's own user
    directory, for the worker Python; the system Python is left as it is"""
    bl_idname = "tncg15.install_denoiser"
    bl_label = "Install Denoiser"
    bl_options = {"INTERNAL"}

    def execute(self, context):
        python, why = worker_python.worker_python(worker_python.preferred_python(context))
        if python is None:
            self.report({"ERROR"}, f"Install Denoiser: {why}")
            return {"CANCELLED"}
        target = worker_python.denoiser_dir(create=True)
        ok, message = install(python, target)
        if not ok:
            self.report({"ERROR"}, f"Install Denoiser: {message}")
            return {"CANCELLED"}
        activate()
        denoise = bridge.module("film.denoise")
        denoise.forget_probes()
        problem = denoise.probe(python, worker_python.extra_paths())
        if problem:
            self.report({"ERROR"}, f"Install Denoiser: {message}, but it does not work: {problem}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Denoiser {message}: Denoise works for {python}")
        return {"FINISHED"}


def register():
    bpy.utils.register_class(TNCG15_OT_install_denoiser)
    activate()


def unregister():
    bpy.utils.unregister_class(TNCG15_OT_install_denoiser)
